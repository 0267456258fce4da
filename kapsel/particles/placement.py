"""Initial particle positions and orientations (switch.INIT_distribution /
switch.INIT_orientation, table 7).  Lengths in the box's unit (radius A DX, box N DX);
returned positions lie in [0, L).  Spheres i, j overlap when their minimum-image
distance is below a_i + a_j.

What each placement does with overlaps, as the original's Init_Particle
(init_particle.cxx) does:

* ``uniform_random``: random sequential addition; a candidate closer than 1.05 (a_i + a_j)
  to a placed sphere is drawn again (the original's ``overlap_length = 1.05 SIGMA``).  The
  original draws for ever when the box is too full; here the placement stops after
  ``max_rounds`` rounds and says so.
* ``FCC``: the original's lattice (``fcc_sites``: its cell counts and site order), refused
  only when a lattice constant is below 2 sqrt(2) a (its "beyond closed packing" exit),
  then relaxed as the original relaxes it: every centre moved 0.001 a in a random
  direction, then 0.05 a along its repulsive pair force (``relax``).  Neighbours closer
  than 2a are kept (an odd number of z layers puts the first and last layer sqrt(2) closer
  than the others); the pair repulsion of the run separates them.
* ``BCC``: the original's lattice (``bcc_sites``), never refused (the original has no
  check there); overlapping neighbours are kept.
* ``random_walk``: the FCC start, then ``iterations`` sweeps of a 0.025 a move in a random
  direction and a 0.05 a move along the repulsive pair force, without rejection (as the
  original's Random_Walk / Steepest_descent).  The original adds each sweep's force to the
  sum of the previous sweeps' (its force array is not cleared between sweeps); here each
  sweep moves along its own force.

The placements do not refuse a volume fraction: kapsel.config refuses more than 1 (the
original's limit, Init_Particle).  ``overlapping_pairs`` tells a caller what a placement
left overlapping.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from . import quaternion as quat
from .cells import minimum_image, pairs_within, wrap

__all__ = ["uniform_random", "random_walk", "fcc", "bcc", "lattice", "fcc_sites", "bcc_sites",
           "relax", "repulsion", "orientations", "volume_fraction", "overlapping_pairs",
           "overlap_note", "UNIFORM_GAP"]

MAX_VOLUME_FRACTION = 0.74  # close packing pi / sqrt(18) = 0.7405: random addition never
UNIFORM_GAP = 1.05          # uniform_random: no two centres within 1.05 (a_i + a_j)
KICK_FCC, KICK_WALK, DESCENT = 1e-3, 0.025, 0.05   # the original's moves, in units of a


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


def uniform_random(n, radius, box, rng=None, max_rounds=200, batch=4096, gap=UNIFORM_GAP):
    """n spheres at uniformly random positions, no two centres within gap (a_i + a_j)
    ('uniform_random'; the original's gap is 1.05, module docstring).

    Vectorised random sequential addition: each round every pending particle gets
    k candidate positions (k * pending >= batch); the first candidate clear of
    already placed spheres is kept, and among kept candidates too close to each
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
            ic, ip, d = _cross_close(cand, R[pidx], L, gap * (a[owner].max() + amax))
            hit = d <= gap * (a[owner[ic]] + a[pidx[ip]])
            ok[ic[hit]] = False
        # first valid candidate of each pending particle
        okr = ok.reshape(len(pending), k)
        has = okr.any(axis=1)
        first = np.argmax(okr, axis=1)
        chosen_p = pending[has]
        chosen = cand.reshape(len(pending), k, 3)[has, first[has]]
        if len(chosen) > 1:
            i, j, dr = pairs_within(chosen, L, 2.0 * gap * amax)
            r = np.sqrt(np.einsum("ij,ij->i", dr, dr))
            clash = r <= gap * (a[chosen_p[i]] + a[chosen_p[j]])
            keep = np.ones(len(chosen), dtype=bool)
            keep[j[clash]] = False                          # i < j: drop the later one
        else:
            keep = np.ones(len(chosen), dtype=bool)
        R[chosen_p[keep]] = chosen[keep]
        placed[chosen_p[keep]] = True
    if placed.all():
        return R
    raise ValueError(
        f"uniform_random: could only place {int(placed.sum())} of {n} particles {gap:g} x "
        f"their contact distance apart at volume fraction {volume_fraction(a, L):.4f} after "
        f"{max_rounds} rounds (random sequential placement jams near "
        f"{0.38 / gap ** 3:.2f} with that gap; use FCC/BCC or random_walk)")


def _unit_vectors(rng, n):
    """n random directions, uniform on the sphere (normalised 3D Gaussians)."""
    g = rng.standard_normal((n, 3))
    norm = np.sqrt(np.einsum("ij,ij->i", g, g))
    norm[norm == 0] = 1.0
    return g / norm[:, None]


def repulsion(box, radius, kind="12:6", cutoff=None, sigma=None):
    """forces(R) -> (N, 3): the pair force of LJ_powers ``kind`` (kapsel.particles.forces)
    between centres closer than ``cutoff`` sigma (default: the law's minimum, where its
    repulsion ends), sigma = a_i + a_j or the given LJ diameter: what the original's
    placement relaxes along (Steepest_descent; only the directions are used)."""
    from . import forces as pf
    L = np.asarray(box, dtype=float).reshape(3)
    rc = pf.interaction_range(kind, "ON") if cutoff is None else float(cutoff)

    def forces(R):
        n = len(R)
        a = np.broadcast_to(np.asarray(radius, dtype=float), (n,))
        F = np.zeros((n, 3))
        if n < 2 or rc <= 0:
            return F
        smax = 2.0 * float(a.max()) if sigma is None else float(sigma)
        i, j, dr = pairs_within(R, L, rc * smax)
        if len(i) == 0:
            return F
        r = np.sqrt(np.einsum("ij,ij->i", dr, dr))
        s = a[i] + a[j] if sigma is None else np.full(len(i), float(sigma))
        keep = (r < rc * s) & (r > 0)
        i, j, dr, r, s = i[keep], j[keep], dr[keep], r[keep], s[keep]
        with np.errstate(over="ignore", invalid="ignore"):
            g = pf.pair_force_magnitude(r, s, kind, 1.0, "OFF") / r   # r < rc s < 2.5 s
        f = g[:, None] * dr                                          # on j, away from i
        for k in range(3):
            F[:, k] = np.bincount(j, f[:, k], minlength=n) - np.bincount(i, f[:, k],
                                                                         minlength=n)
        return F
    return forces


def relax(R, radius, box, rng, forces, kick, sweeps=1, descent=DESCENT):
    """The original's relaxation of a lattice start (init_particle.cxx, FCC and random_walk
    branches; fluct.h Random_Walk and Steepest_descent), ``sweeps`` times: every centre
    moves ``kick`` a in a random direction, then ``descent`` a along its force
    ``forces(R)`` (centres without force stay), wrapped into the box.  Vectorised: the
    moves of one stage are made all at once, as the original's are from one force
    evaluation."""
    L = np.asarray(box, dtype=float).reshape(3)
    R = np.array(R, dtype=float)
    a = np.broadcast_to(np.asarray(radius, dtype=float), (len(R),))[:, None]
    for _ in range(int(sweeps)):
        R = wrap(R + kick * a * _unit_vectors(rng, len(R)), L)
        if forces is None:
            continue
        F = forces(R)
        norm = np.sqrt(np.einsum("ij,ij->i", F, F))
        move = np.isfinite(norm) & (norm > 0)
        step = np.zeros_like(F)
        step[move] = F[move] / norm[move, None]
        R = wrap(R + descent * a * step, L)
    return R


def fcc_sites(n, box):
    """The original's FCC sites and lattice constants (init_particle.cxx, Init_Particle, FCC
    branch): the cell counts nn_d = nn ceil(L_d / L_min), nn of floor / ceil of
    (n / (4 prod(L_d / L_min)))^(1/3) whichever gives the rounder in-plane and z site
    densities; unless n = 4 nn_x nn_y nn_z, nz = ceil(n / (2 nn_x nn_y)) layers along z.
    Site i: ix = i mod nn_x, iy = (i mod 2 nn_x nn_y) div nn_x, iz = i div (2 nn_x nn_y) at
    (ix + ((iy + iz) mod 2) / 2, iy / 2, iz / 2) lattice constants from a quarter of one.
    Returns (R (n, 3), lattice constants (3,))."""
    L = np.asarray(box, dtype=float).reshape(3)
    if n == 0:
        return np.zeros((0, 3)), L.copy()
    lr = L / L.min()
    base = (n / (4.0 * lr[0] * lr[1] * lr[2])) ** (1.0 / 3.0)
    up, low = int(math.ceil(base)), int(base)
    ixy = int(lr[0]) * int(lr[1])              # the original truncates here, ceils below

    def layers(nb):
        nxny = 2 * nb * nb * ixy
        return nxny, (int(math.ceil(n / nxny)) if nxny > 0 else 0)
    nxny_up, nz_up = layers(up)
    nxny_low, nz_low = layers(low)
    nb = up
    if nxny_low > 0 and nz_low > 0:
        def skew(nxny, nz):
            return abs(math.sqrt(nxny / (L[0] * L[1])) / (nz / L[2]) - 1.0)
        if skew(nxny_low, nz_low) <= skew(nxny_up, nz_up):
            nb = low
    nn = np.array([nb * int(math.ceil(x)) for x in lr])
    lattice = L / nn
    if n != 4 * int(np.prod(nn)):
        nz = int(math.ceil(n / (2 * nn[0] * nn[1])))
        lattice[2] = L[2] / (0.5 * nz)
    i = np.arange(n)
    layer = 2 * nn[0] * nn[1]
    ix, iy, iz = i % nn[0], (i % layer) // nn[0], i // layer
    R = np.stack([ix * lattice[0] + 0.5 * lattice[0] * ((iy + iz) % 2),
                  iy * lattice[1] / 2.0, iz * lattice[2] / 2.0], axis=1) + 0.25 * lattice
    return wrap(R, L), lattice


def bcc_sites(n, box):
    """The original's BCC sites (init_particle.cxx, Init_Particle, BCC branch): nn =
    ceil((n / 2)^(1/3)) cells of L / nn per axis; site i: ix = i mod nn, iy = (i mod nn^2)
    div nn, iz = i div nn^2 at (ix, iy, iz / 2) cells from a quarter cell, the odd z layers
    shifted by half a cell in x and y.  (The original shifts y by half the x cell, the same
    in a cubic box; here by half the y cell, so that a non-cubic box gets a BCC lattice and
    no site leaves the box.)"""
    L = np.asarray(box, dtype=float).reshape(3)
    if n == 0:
        return np.zeros((0, 3))
    nn = int(math.ceil((n / 2.0) ** (1.0 / 3.0)))     # as the original rounds it: 54 -> 4
    while 2 * nn ** 3 < n:                    # (a cube root rounded down: never seen)
        nn += 1
    c = L / nn
    i = np.arange(n)
    ix, iy, iz = i % nn, (i % (nn * nn)) // nn, i // (nn * nn)
    R = np.stack([ix * c[0], iy * c[1], iz * c[2] / 2.0], axis=1) + 0.25 * c
    odd = (iz % 2) == 1
    R[odd, 0] += 0.5 * c[0]
    R[odd, 1] += 0.5 * c[1]
    return wrap(R, L)


def fcc(n, radius, box, rng=None, forces=None, name="FCC"):
    """'FCC': the original's sites (``fcc_sites``), refused when a lattice constant is
    below 2 sqrt(2) a (the original's exit), then one ``relax`` sweep (kick 0.001 a, one
    descent along ``forces``, e.g. ``repulsion``; none when None).  ``name``: the
    placement the messages name."""
    L, a = _setup(n, radius, box)
    if n == 0:
        return np.zeros((0, 3))
    if 2.0 * a.max() > L.min():
        raise ValueError(f"particle diameter {2 * a.max():g} is larger than the box {_dims(L)}")
    R, lat = fcc_sites(n, L)
    need = 2.0 * math.sqrt(2.0) * a.max()
    short = np.flatnonzero(lat < need)
    if short.size:
        d = int(short[0])
        raise ValueError(f"{name}: the lattice constant along {'xyz'[d]} is {lat[d]:.4g}, below "
                         f"2 sqrt(2) A = {need:.4g} (beyond close packing, as the original "
                         f"refuses it): A must be at most {lat[d] / (2 * math.sqrt(2)):.4g} "
                         f"for {n} particles in {_dims(L)}")
    return relax(R, a, L, _rng(rng), forces, KICK_FCC)


def bcc(n, radius, box):
    """'BCC': the original's sites (``bcc_sites``), accepted however close (as the
    original: no check)."""
    L, a = _setup(n, radius, box)
    if n and 2.0 * a.max() > L.min():
        raise ValueError(f"particle diameter {2 * a.max():g} is larger than the box {_dims(L)}")
    return bcc_sites(n, L)


def random_walk(n, radius, box, iterations, rng=None, forces=None):
    """'random_walk': the FCC start (``fcc``, with its refusal), then ``iterations`` sweeps
    of ``relax`` with a 0.025 a kick (the original's Random_Walk default) and a 0.05 a
    descent along ``forces`` (the original uses the 12:6 law's cutoff 2^(1/6) sigma here);
    nothing is rejected, as in the original."""
    rng = _rng(rng)
    R = fcc(n, radius, box, rng, forces, name="random_walk (its FCC start)")
    if n == 0:
        return R
    L, a = _setup(n, radius, box)
    return relax(R, a, L, rng, forces, KICK_WALK, sweeps=iterations)


def lattice(kind, n, radius, box, rng=None, forces=None):
    """'FCC' (``fcc``) or 'BCC' (``bcc``)."""
    kind = str(kind).upper()
    if kind == "FCC":
        return fcc(n, radius, box, rng, forces)
    if kind == "BCC":
        return bcc(n, radius, box)
    raise ValueError(f"lattice must be FCC or BCC, got {kind!r}")


def overlap_note(kind, R, radius, box) -> str | None:
    """One line saying how many pairs a placement left closer than a_i + a_j and the
    closest, or None."""
    i, j, r = overlapping_pairs(R, radius, box)
    if not len(i):
        return None
    a = np.broadcast_to(np.asarray(radius, dtype=float), (len(R),))
    ratio = r / (a[i] + a[j])
    k = int(np.argmin(ratio))
    return (f"{kind} left {len(i)} pair(s) closer than the contact distance 2A "
            f"(closest: particles {int(i[k])} and {int(j[k])} at {ratio[k]:.3f} of it), as the "
            f"original places them")


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
