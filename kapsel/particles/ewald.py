"""Periodic Ewald sum of point dipoles: energy, forces and the field at each dipole.

Gaussian-like units as the original (PHYSICS-EXTRA.md §4.3): the bare pair energy is
U = mu_i.mu_j / r^3 - 3 (mu_i.r)(mu_j.r) / r^5, no 4 pi epsilon.  For N dipoles in a periodic
orthorhombic box of volume V (splitting parameter alpha, standard dipolar Ewald, e.g. Allen &
Tildesley, "Computer Simulation of Liquids", 2nd ed., §6.2; de Leeuw, Perram & Smith, Proc.
R. Soc. Lond. A 373, 27 (1980)):

    U_real  = 1/2 sum_{i,j,n}' (mu_i.mu_j) B(r) - (mu_i.r)(mu_j.r) C(r), r = r_ij + n L, |r| < r_cut
    U_recip = (2 pi / V) sum_{k != 0} exp(-k^2/4 alpha^2) / k^2 |sum_j (mu_j.k) exp(i k.r_j)|^2
    U_self  = -(2 alpha^3 / 3 sqrt(pi)) sum_i |mu_i|^2
    U_surf  = 2 pi / ((2 eps' + 1) V) |sum_i mu_i|^2       (0 for tin-foil, eps' = inf)

with B = erfc(a r)/r^3 + g/r^2, C = 3 erfc(a r)/r^5 + g (2a^2 + 3/r^2)/r^2,
D = 15 erfc(a r)/r^7 + g (4a^4 + 10a^2/r^2 + 15/r^4)/r^2, g = (2a/sqrt(pi)) exp(-a^2 r^2)
(C = -B'/r, D = -C'/r).  The field at dipole i is E_i = -dU/dmu_i (so the torque is
mu_i x E_i) and the force F_i = -dU/dr_i.

Cost: the split is chosen by ``choose_parameters`` so that the real-space pairs (every periodic
image within r_cut, found by a k-d tree) and the reciprocal terms (direct sum over k vectors,
vectorised) take the same time, alpha = sqrt(pi) (c N / V^2)^(1/6) with c = COST_RATIO: both
then scale as N^1.5 at fixed density (bench/bench_ewald.py).  Accuracy: the neglected terms
of both sums are of relative size s^3 exp(-s^2) with s = alpha r_cut = k_cut / (2 alpha) from
``splitting_s(tol)``; tests/unit/test_ewald.py measures the energy, field and force errors against
a sum converged to 1e-15: they stay below ``tol`` (relative to |U|, the RMS field and the RMS
force) for tol = 1e-6 ... 1e-10.

Lees-Edwards (``strain`` g != 0): the periodic images form the sheared lattice a1 = (Lx, 0, 0),
a2 = (g Ly, Ly, 0), a3 = (0, 0, Lz) (the image across y = Ly displaced by g Ly along x, as the
pair forces of kapsel.particles.forces); the same sums run over its images and its
reciprocal lattice b_j (a_i . b_j = 2 pi delta_ij), of the same volume V.  g = 0 takes the
orthorhombic code unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import erfc

SQRT_PI = np.sqrt(np.pi)
# Time of one real-space pair over one (particle, k vector) term, measured (bench/bench_ewald.py):
# the split alpha^6 = pi^3 COST_RATIO N / V^2 makes both parts take the same time.
COST_RATIO = 20.0


@dataclass(frozen=True)
class EwaldParameters:
    """alpha (1/length), r_cut (real-space cutoff, any length), k_cut (reciprocal cutoff)."""
    alpha: float
    r_cut: float
    k_cut: float


def choose_parameters(box, n: int, tol: float = 1e-8) -> EwaldParameters:
    """Split for N dipoles in ``box`` with truncation errors of relative size ``tol``: balanced
    alpha = sqrt(pi) (COST_RATIO N/V^2)^(1/6), r_cut = s/alpha, k_cut = 2 alpha s, s from
    ``splitting_s``.  The real-space sum takes every periodic image within r_cut (r_cut may
    exceed the box)."""
    box = np.asarray(box, dtype=float)
    if not 0.0 < tol < 1.0:
        raise ValueError(f"Ewald tolerance must lie in (0, 1), not {tol}")
    s = splitting_s(tol)
    V = float(np.prod(box))
    alpha = SQRT_PI * (COST_RATIO * max(n, 1) / V ** 2) ** (1.0 / 6.0)
    r_cut = s / alpha
    return EwaldParameters(alpha=float(alpha), r_cut=float(r_cut), k_cut=float(2 * alpha * s))


def splitting_s(tol: float) -> float:
    """s = alpha r_cut = k_cut / (2 alpha) for a relative error ``tol``: the neglected terms
    are about s^3 exp(-s^2) (the Gaussian times the polynomial growth of the dipolar kernels
    and of the number of k shells), so s^2 = -ln tol + 3 ln s + 3 (fixed point; the margin
    3 is calibrated by tests/unit/test_ewald.py)."""
    s = np.sqrt(-np.log(tol))
    for _ in range(20):
        s = np.sqrt(-np.log(tol) + 3 * np.log(s) + 3)
    return float(s)


def tolerance_from_original(alpha: float, delta: float, converge: float) -> float:
    """The accuracy the original's EwaldParams reach (PHYSICS-EXTRA.md §4.3): its split
    eta = alpha / (2 r_c) at r_c = half the box leaves real-space terms of size
    exp(-(alpha/2)^2), and k^2_max = 4 eta^2 (-ln delta) converge leaves reciprocal terms
    of size delta^converge.  kapsel-py reaches the larger (worse) of the two with its own,
    cost-balanced split; a converged Ewald sum does not depend on the split.  The result is
    kept within [1e-15, 1e-2]."""
    real = np.exp(-(alpha / 2.0) ** 2)
    recip = float(delta) ** float(converge)
    tol = max(real, recip)
    return float(min(max(tol, 1e-15), 1e-2))


def reciprocal_vectors(box, k_cut: float) -> np.ndarray:
    """Wave vectors 2 pi (nx/Lx, ny/Ly, nz/Lz) with 0 < |k| < k_cut, one of each +-k pair."""
    box = np.asarray(box, dtype=float)
    nmax = np.floor(k_cut * box / (2 * np.pi)).astype(int)
    axes = [np.arange(-m, m + 1) for m in nmax]
    n = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    half = (n[:, 0] > 0) | ((n[:, 0] == 0) & ((n[:, 1] > 0) | ((n[:, 1] == 0) & (n[:, 2] > 0))))
    k = 2 * np.pi * n[half] / box
    k2 = np.einsum("ij,ij->i", k, k)
    return k[k2 < k_cut ** 2]


def lattice(box, strain: float = 0.0) -> np.ndarray:
    """Rows a1, a2, a3 of the (Lees-Edwards) periodic lattice; the x shift g Ly of a2 is
    taken modulo Lx into [-Lx/2, Lx/2) (the same lattice, the most compact cell)."""
    box = np.asarray(box, dtype=float)
    s = float(strain) * box[1]
    s -= box[0] * np.floor(s / box[0] + 0.5)
    return np.array([[box[0], 0.0, 0.0], [s, box[1], 0.0], [0.0, 0.0, box[2]]])


def _sheared_reciprocal_vectors(L, k_cut: float) -> np.ndarray:
    """k = n1 b1 + n2 b2 + n3 b3 with 0 < |k| < k_cut, one of each +-k pair (|n_j| <=
    k_cut |a_j| / 2 pi since n_j = k . a_j / 2 pi)."""
    B = 2 * np.pi * np.linalg.inv(L).T
    nmax = np.floor(k_cut * np.linalg.norm(L, axis=1) / (2 * np.pi)).astype(int)
    axes = [np.arange(-m, m + 1) for m in nmax]
    n = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    half = (n[:, 0] > 0) | ((n[:, 0] == 0) & ((n[:, 1] > 0) | ((n[:, 1] == 0) & (n[:, 2] > 0))))
    k = n[half] @ B
    k2 = np.einsum("ij,ij->i", k, k)
    return k[(k2 < k_cut ** 2) & (k2 > 0)]


def _sheared_ghosts(R, L, r_cut):
    """Positions wrapped into the cell spanned by L's rows, and their periodic copies with
    fractional coordinates within r_cut / h_j of the cell (h_j: the cell's height across
    face j), which holds every image within r_cut of a point of the cell:
    (Rw, G, original index, is the unshifted copy)."""
    inv = np.linalg.inv(L)
    f = np.mod(R @ inv, 1.0)
    f[f >= 1.0] = 0.0
    Rw = f @ L
    V = abs(np.linalg.det(L))
    h = V / np.linalg.norm(np.cross(L[[1, 2, 0]], L[[2, 0, 1]]), axis=1)
    m = r_cut / h
    nmax = np.ceil(m).astype(int)
    axes = [np.arange(-k, k + 1) for k in nmax]
    n = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    fg = (f[None, :, :] + n[:, None, :]).reshape(-1, 3)
    idx = np.tile(np.arange(len(R)), len(n))
    zero = np.repeat(np.all(n == 0, axis=1), len(R))
    keep = np.all((fg > -m) & (fg < 1.0 + m), axis=1)
    return Rw, fg[keep] @ L, idx[keep], zero[keep]


def _ghosts(Rw, box, r_cut):
    """Periodic copies of the wrapped positions within r_cut of the box: (G, original index)."""
    nmax = np.ceil(r_cut / box).astype(int)
    axes = [np.arange(-m, m + 1) for m in nmax]
    shifts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) * box
    G = (Rw[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    idx = np.tile(np.arange(len(Rw)), len(shifts))
    zero = np.repeat(np.all(shifts == 0, axis=1), len(Rw))
    keep = np.all((G > -r_cut) & (G < box + r_cut), axis=1)
    return G[keep], idx[keep], zero[keep]


def _real_space(R, mu, box, alpha, r_cut, chunk_pairs=1 << 20, strain=0.0, queries=None):
    """Sum over every periodic image within r_cut (any r_cut, also beyond half the box):
    each particle against the periodic copies around the box, found by a k-d tree, in
    chunks of particles of about ``chunk_pairs`` pairs.  ``queries``: only the first
    ``queries`` particles get their field and force (the others' rows stay 0; U then counts
    their pairs only)."""
    n = len(R)
    m = n if queries is None else int(queries)
    E = np.zeros((n, 3))
    F = np.zeros((n, 3))
    if strain:
        Rw, G, gi, zero = _sheared_ghosts(R, lattice(box, strain), r_cut)
    else:
        Rw = np.mod(R, box)
        Rw[Rw >= box] = 0.0                     # -1e-17 mod L rounds to L
        G, gi, zero = _ghosts(Rw, box, r_cut)
    tree = cKDTree(G)
    per = 4.0 / 3.0 * np.pi * r_cut ** 3 * n / float(np.prod(box)) + 1.0
    step = max(1, int(chunk_pairs / per))
    U = 0.0
    for s in range(0, m, step):
        near = tree.sparse_distance_matrix(cKDTree(Rw[s:min(s + step, m)]), r_cut,
                                           output_type="ndarray")
        i = near["j"].astype(np.int64) + s
        j = near["i"].astype(np.int64)
        keep = ~(zero[j] & (gi[j] == i))
        i, j = i[keep], j[keep]
        if len(i) == 0:
            continue
        d = Rw[i] - G[j]
        r2 = np.einsum("ij,ij->i", d, d)
        r = np.sqrt(r2)
        g = (2 * alpha / SQRT_PI) * np.exp(-(alpha * r) ** 2)
        ec = erfc(alpha * r)
        B = ec / (r2 * r) + g / r2
        C = 3 * ec / (r2 * r2 * r) + g * (2 * alpha ** 2 + 3 / r2) / r2
        D = 15 * ec / (r2 ** 3 * r) + g * (4 * alpha ** 4 + 10 * alpha ** 2 / r2
                                           + 15 / r2 ** 2) / r2
        mi, mj = mu[i], mu[gi[j]]
        mimj = np.einsum("ij,ij->i", mi, mj)
        mid = np.einsum("ij,ij->i", mi, d)
        mjd = np.einsum("ij,ij->i", mj, d)
        U += 0.5 * float(np.sum(mimj * B - mid * mjd * C))    # each pair seen from both ends
        Ei = -B[:, None] * mj + (C * mjd)[:, None] * d
        Fij = ((mimj * C - D * mid * mjd)[:, None] * d
               + C[:, None] * (mi * mjd[:, None] + mj * mid[:, None]))
        for c in range(3):
            E[:, c] += np.bincount(i, Ei[:, c], minlength=n)
            F[:, c] += np.bincount(i, Fij[:, c], minlength=n)
    return U, E, F


def _reciprocal(R, mu, box, alpha, k_cut, chunk_bytes=32 << 20, strain=0.0):
    n = len(R)
    V = float(np.prod(box))
    K = (_sheared_reciprocal_vectors(lattice(box, strain), k_cut) if strain
         else reciprocal_vectors(box, k_cut))
    E = np.zeros((n, 3))
    F = np.zeros((n, 3))
    U = 0.0
    step = max(1, int(chunk_bytes // (8 * 4 * max(n, 1))))
    for s in range(0, len(K), step):
        k = K[s:s + step]
        k2 = np.einsum("ij,ij->i", k, k)
        f = np.exp(-k2 / (4 * alpha ** 2)) / k2
        phase = R @ k.T
        c, sn = np.cos(phase), np.sin(phase)
        muk = mu @ k.T
        Mc = np.einsum("ik,ik->k", muk, c)
        Ms = np.einsum("ik,ik->k", muk, sn)
        U += (4 * np.pi / V) * float(np.sum(f * (Mc ** 2 + Ms ** 2)))
        E -= (8 * np.pi / V) * (((c * Mc + sn * Ms) * f) @ k)
        F += (8 * np.pi / V) * ((muk * (sn * Mc - c * Ms) * f) @ k)
    return U, E, F


def _reciprocal_owned(R, mu, own, queries, box, alpha, k_cut, reduce, chunk_bytes=32 << 20,
                      strain=0.0):
    """``_reciprocal`` of a distributed run: the structure sums M(k) of the ``own`` sources
    of every rank, summed over the ranks by ``reduce`` (one collective, fixed order), then
    the field and force of the first ``queries`` particles."""
    V = float(np.prod(box))
    K = (_sheared_reciprocal_vectors(lattice(box, strain), k_cut) if strain
         else reciprocal_vectors(box, k_cut))
    Ro, mo = R[own], mu[own]
    Rq, mq = R[:queries], mu[:queries]
    M = np.empty((2, len(K)))
    step = max(1, int(chunk_bytes // (8 * 4 * max(len(Ro), queries, 1))))
    for s in range(0, len(K), step):
        k = K[s:s + step]
        phase = Ro @ k.T
        muk = mo @ k.T
        M[0, s:s + step] = np.einsum("ik,ik->k", muk, np.cos(phase))
        M[1, s:s + step] = np.einsum("ik,ik->k", muk, np.sin(phase))
    M = reduce(M)
    E = np.zeros((queries, 3))
    F = np.zeros((queries, 3))
    for s in range(0, len(K), step):
        k = K[s:s + step]
        Mc, Ms = M[0, s:s + step], M[1, s:s + step]
        k2 = np.einsum("ij,ij->i", k, k)
        f = np.exp(-k2 / (4 * alpha ** 2)) / k2
        phase = Rq @ k.T
        c, sn = np.cos(phase), np.sin(phase)
        muk = mq @ k.T
        E -= (8 * np.pi / V) * (((c * Mc + sn * Ms) * f) @ k)
        F += (8 * np.pi / V) * ((muk * (sn * Mc - c * Ms) * f) @ k)
    return E, F


def dipolar_ewald_owned(R, mu, own, queries, box, params: EwaldParameters, reduce,
                        epsilon_surface: float = np.inf, strain: float = 0.0):
    """(F, E) of the first ``queries`` dipoles of a rank's sources (R, mu) in a distributed
    run (kapsel.particles.ownership): ``own`` (bool, len(R)) marks the sources this rank
    accounts for (each source is own on exactly one rank), the others are ghosts, present
    wherever they lie within r_cut of a queried dipole.  The real-space sum runs over the
    rank's sources, the reciprocal one over the structure sums of every rank's own sources
    and the surface term over their total moment (``reduce``: sum over the ranks, the same
    bits everywhere).  The same terms as ``dipolar_ewald``, summed in another order."""
    R = np.asarray(R, dtype=float)
    mu = np.asarray(mu, dtype=float)
    box = np.asarray(box, dtype=float)
    a = params.alpha
    _, E, F = _real_space(R, mu, box, a, params.r_cut, strain=strain, queries=queries)
    E, F = E[:queries], F[:queries]
    E_k, F_k = _reciprocal_owned(R, mu, own, queries, box, a, params.k_cut, reduce,
                                 strain=strain)
    E += E_k
    F += F_k
    self_c = 2 * a ** 3 / (3 * SQRT_PI)
    E += 2 * self_c * mu[:queries]
    if np.isfinite(epsilon_surface):
        V = float(np.prod(box))
        M = reduce(mu[own].sum(axis=0))
        w = 2 * np.pi / ((2 * epsilon_surface + 1) * V)
        E -= 2 * w * M
    return F, E


def dipolar_ewald(R, mu, box, params: EwaldParameters, epsilon_surface: float = np.inf,
                  strain: float = 0.0):
    """(U, F, E) of point dipoles ``mu`` (N, 3) at ``R`` (N, 3) in the periodic ``box``:
    the total energy, the force on each dipole (-dU/dR) and the field at each dipole
    (-dU/dmu, the torque being mu x E).  ``epsilon_surface``: the dielectric constant around
    the infinite periodic sphere (np.inf: tin-foil, no surface term).  ``strain``: the
    Lees-Edwards lattice (module docstring)."""
    R = np.asarray(R, dtype=float)
    mu = np.asarray(mu, dtype=float)
    box = np.asarray(box, dtype=float)
    a = params.alpha
    U_r, E, F = _real_space(R, mu, box, a, params.r_cut, strain=strain)
    U_k, E_k, F_k = _reciprocal(R, mu, box, a, params.k_cut, strain=strain)
    E += E_k
    F += F_k
    self_c = 2 * a ** 3 / (3 * SQRT_PI)
    U = U_r + U_k - self_c * float(np.sum(mu * mu))
    E += 2 * self_c * mu
    if np.isfinite(epsilon_surface):
        V = float(np.prod(box))
        M = mu.sum(axis=0)
        w = 2 * np.pi / ((2 * epsilon_surface + 1) * V)
        U += w * float(M @ M)
        E -= 2 * w * M
    return U, F, E


def bare_dipole_pair(r, mu1, mu2):
    """(U, F on dipole 1, E at dipole 1) of two dipoles in open space, r = r_1 - r_2."""
    r = np.asarray(r, dtype=float)
    d = np.linalg.norm(r)
    m12, m1r, m2r = mu1 @ mu2, mu1 @ r, mu2 @ r
    U = m12 / d ** 3 - 3 * m1r * m2r / d ** 5
    E = -mu2 / d ** 3 + 3 * m2r * r / d ** 5
    F = (3 / d ** 5) * (m12 * r + m1r * mu2 + m2r * mu1) - 15 * m1r * m2r * r / d ** 7
    return U, F, E
