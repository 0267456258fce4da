"""Initial particle positions and orientations (switch.INIT_distribution /
switch.INIT_orientation, table 7).  Lengths in DX, periodic box L = (Lx, Ly, Lz);
returned positions lie in [0, L).  Spheres i, j overlap when their minimum-image
distance is below a_i + a_j.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from . import quaternion as quat
from .cells import minimum_image, pairs_within, wrap

__all__ = ["uniform_random", "random_walk", "fcc", "bcc", "lattice", "orientations",
           "volume_fraction", "overlapping_pairs"]

MAX_VOLUME_FRACTION = 0.74  # close packing pi / sqrt(18) = 0.7405


def _rng(rng):
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def _setup(n, radius, box):
    L = np.asarray(box, dtype=float).reshape(3)
    a = np.broadcast_to(np.asarray(radius, dtype=float), (n,)).copy()
    if n < 0:
        raise ValueError("number of particles must be >= 0")
    if np.any(a <= 0):
        raise ValueError("particle radii must be positive")
    return L, a


def volume_fraction(radius, box, n=None) -> float:
    """Sum of sphere volumes / box volume."""
    a = np.asarray(radius, dtype=float)
    if n is not None:
        a = np.broadcast_to(a, (n,))
    return float(np.sum(4.0 / 3.0 * np.pi * a ** 3) / np.prod(np.asarray(box, dtype=float)))


def _check_feasible(L, a):
    if len(a) == 0:
        return
    if 2.0 * a.max() > L.min():
        raise ValueError(f"particle diameter {2 * a.max():g} is larger than the box {_dims(L)}")
    phi = volume_fraction(a, L)
    if phi > MAX_VOLUME_FRACTION:
        raise ValueError(f"volume fraction {phi:.4f} exceeds close packing {MAX_VOLUME_FRACTION}: "
                         "spheres cannot be placed without overlap")


def overlapping_pairs(R, radius, box):
    """(i, j, r) of overlapping pairs (r < a_i + a_j)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3)
    a = np.broadcast_to(np.asarray(radius, dtype=float), (len(R),))
    if len(R) < 2:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
    i, j, dr = pairs_within(R, box, 2.0 * a.max())
    r = np.sqrt(np.einsum("ij,ij->i", dr, dr))
    bad = r < a[i] + a[j]
    return i[bad], j[bad], r[bad]


def _cross_close(A, B, L, rcut):
    """Pairs (ia, ib, d) with minimum-image |A[ia] - B[ib]| <= rcut."""
    if len(A) == 0 or len(B) == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
    if np.any(rcut > 0.5 * L):
        ia, ib = np.meshgrid(np.arange(len(A)), np.arange(len(B)), indexing="ij")
        ia, ib = ia.ravel(), ib.ravel()
        d = np.linalg.norm(minimum_image(B[ib] - A[ia], L), axis=1)
        keep = d <= rcut
        return ia[keep], ib[keep], d[keep]
    ta = cKDTree(wrap(A, L), boxsize=L)
    tb = cKDTree(wrap(B, L), boxsize=L)
    m = ta.sparse_distance_matrix(tb, rcut, output_type="ndarray")
    return m["i"].astype(int), m["j"].astype(int), m["v"]


def uniform_random(n, radius, box, rng=None, max_rounds=200, batch=4096):
    """n non-overlapping spheres at uniformly random positions ('uniform_random').

    Vectorised random sequential addition: each round every pending particle gets
    k candidate positions (k * pending >= batch); the first candidate free of
    already placed spheres is kept, and among kept candidates that overlap each
    other only the lowest index survives.  Raises ValueError (naming the volume
    fraction) if the particles are not all placed after max_rounds rounds.
    Polydisperse systems are placed largest first (each round handles the pending
    particles with radius >= 0.9 x the largest pending radius), which jams later.
    """
    L, a = _setup(n, radius, box)
    _check_feasible(L, a)
    rng = _rng(rng)
    R = np.zeros((n, 3))
    placed = np.zeros(n, dtype=bool)
    amax = a.max() if n else 0.0
    for _ in range(max_rounds):
        unplaced = np.flatnonzero(~placed)
        if len(unplaced) == 0:
            return R
        pending = unplaced[a[unplaced] >= 0.9 * a[unplaced].max()]
        k = max(1, min(1000, -(-batch // len(pending))))
        owner = np.repeat(pending, k)                       # candidate -> particle
        cand = rng.random((len(owner), 3)) * L
        ok = np.ones(len(owner), dtype=bool)
        if placed.any():
            pidx = np.flatnonzero(placed)
            ic, ip, d = _cross_close(cand, R[pidx], L, a[owner].max() + amax)
            hit = d < a[owner[ic]] + a[pidx[ip]]
            ok[ic[hit]] = False
        # first valid candidate of each pending particle
        okr = ok.reshape(len(pending), k)
        has = okr.any(axis=1)
        first = np.argmax(okr, axis=1)
        chosen_p = pending[has]
        chosen = cand.reshape(len(pending), k, 3)[has, first[has]]
        if len(chosen) > 1:
            i, j, dr = pairs_within(chosen, L, 2.0 * amax)
            r = np.sqrt(np.einsum("ij,ij->i", dr, dr))
            clash = r < a[chosen_p[i]] + a[chosen_p[j]]
            keep = np.ones(len(chosen), dtype=bool)
            keep[j[clash]] = False                          # i < j: drop the later one
        else:
            keep = np.ones(len(chosen), dtype=bool)
        R[chosen_p[keep]] = chosen[keep]
        placed[chosen_p[keep]] = True
    if placed.all():
        return R
    raise ValueError(
        f"uniform_random: could only place {int(placed.sum())} of {n} particles without overlap "
        f"at volume fraction {volume_fraction(a, L):.4f} after {max_rounds} rounds "
        f"(random sequential placement jams near 0.38; use FCC/BCC or random_walk)")


def _sc_counts(n, L):
    """Simple cubic lattice counts (nx, ny, nz) with nx ny nz >= n and maximal spacing."""
    if n == 0:
        return np.array([1, 1, 1])
    k = np.arange(1, n + 1)
    s = np.unique((L[:, None] / k[None, :]).ravel())[::-1]   # candidate spacings, decreasing
    counts = np.floor(L[None, :] / s[:, None] * (1 + 1e-12)).astype(np.int64)
    feasible = np.prod(np.maximum(counts, 1), axis=1) >= n
    c = np.maximum(counts[np.argmax(feasible)], 1)
    return c


def random_walk(n, radius, box, iterations, rng=None, step=None):
    """'random_walk': simple cubic lattice filling the box, then `iterations` sweeps
    of random displacements (uniform in [-step, step]^3, default step = min radius / 2)
    rejecting overlaps.

    Per sweep all particles propose a move at once; a move of i is accepted if its
    new position overlaps neither the old nor the proposed positions of any other
    particle, which guarantees an overlap-free result whatever else is accepted.
    """
    L, a = _setup(n, radius, box)
    _check_feasible(L, a)
    rng = _rng(rng)
    if n == 0:
        return np.zeros((0, 3))
    c = _sc_counts(n, L)
    idx = np.stack(np.unravel_index(np.arange(n), tuple(c)), axis=1)
    R = (idx + 0.5) * (L / c)
    bi, bj, _ = overlapping_pairs(R, a, L)
    if len(bi):
        raise ValueError(f"random_walk: simple cubic start lattice {_dims(c)} (spacing "
                         f"{_dims(L / c)}) overlaps spheres at volume fraction "
                         f"{volume_fraction(a, L):.4f}")
    step = 0.5 * a.min() if step is None else float(step)
    amax = a.max()
    for _ in range(int(iterations)):
        new = wrap(R + rng.uniform(-step, step, size=(n, 3)), L)
        both = np.concatenate([R, new])
        who = np.concatenate([np.arange(n), np.arange(n)])
        is_new = np.concatenate([np.zeros(n, bool), np.ones(n, bool)])
        i, j, dr = pairs_within(both, L, 2.0 * amax)
        r = np.sqrt(np.einsum("ij,ij->i", dr, dr))
        clash = (r < a[who[i]] + a[who[j]]) & (who[i] != who[j]) & (is_new[i] | is_new[j])
        reject = np.zeros(n, dtype=bool)
        reject[who[i[clash & is_new[i]]]] = True
        reject[who[j[clash & is_new[j]]]] = True
        R = np.where(reject[:, None], R, new)
    return wrap(R, L)


_BASIS = {"FCC": np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]),
          "BCC": np.array([[0, 0, 0], [0.5, 0.5, 0.5]])}


def lattice(kind, n, radius, box):
    """First n sites of the smallest m^3-cell cubic FCC/BCC lattice with >= n sites,
    cells scaled to L/m (fills the box), offset by a quarter cell."""
    kind = kind.upper()
    L, a = _setup(n, radius, box)
    basis = _BASIS[kind]
    if n == 0:
        return np.zeros((0, 3))
    m = 1
    while len(basis) * m ** 3 < n:
        m += 1
    cells = np.stack(np.unravel_index(np.arange(m ** 3), (m, m, m)), axis=1)
    sites = (cells[:, None, :] + basis[None, :, :] + 0.25).reshape(-1, 3)[:n]
    R = wrap(sites * (L / m), L)
    bi, bj, br = overlapping_pairs(R, a, L)
    if len(bi):
        raise ValueError(f"{kind}: {m}^3-cell lattice in box {_dims(L)} puts spheres at "
                         f"distance {br.min():.4g} < a_i + a_j (volume fraction "
                         f"{volume_fraction(a, L):.4f})")
    return R


def fcc(n, radius, box):
    """'FCC' placement (see lattice)."""
    return lattice("FCC", n, radius, box)


def bcc(n, radius, box):
    """'BCC' placement (see lattice)."""
    return lattice("BCC", n, radius, box)


def orientations(kind, n, rng=None, user_q=None):
    """Initial quaternions (n, 4) for switch.INIT_orientation.

    'user_specify': given q normalised, zero rows -> identity; if user_q is None
    (INIT_distribution is not user_specify) it behaves like 'space_align'.
    'random': uniform random rotations (normalised 4D Gaussian, Haar measure).
    'space_align': all identity.
    """
    k = str(kind).strip().lower()
    if k == "space_align" or (k == "user_specify" and user_q is None):
        return quat.identity(n)
    if k == "user_specify":
        q = np.asarray(user_q, dtype=float)
        if q.shape != (n, 4):
            raise ValueError(f"user_specify orientations need shape ({n}, 4), got {q.shape}")
        return quat.normalise(q)
    if k == "random":
        q = _rng(rng).standard_normal((n, 4))
        return quat.normalise(q)
    raise ValueError(f"INIT_orientation must be user_specify, random or space_align, got {kind!r}")


def _dims(v) -> str:
    """'32 x 32 x 64': plain numbers for messages."""
    return " x ".join(f"{float(x):.4g}" for x in np.ravel(v))
