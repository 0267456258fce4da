"""Bead-spring chains (object_type ``chain``, ``Chain_spec[]``): bonds and initial placement.

Topology: species by species, chain by chain, the beads of a chain are consecutive particles;
bead k of a chain is bonded to bead k + 1.  The manual (table 5) gives only Beads_number,
Chain_number and MASS_RATIO; the bond is the one of the original KAPSEL, a Kremer-Grest FENE
spring between bonded neighbours on top of the excluded volume (the LJ pair forces of
kapsel.particles.forces act between *all* beads, bonded ones included):

    U_FENE(r) = -1/2 K R0^2 ln(1 - (r / R0)^2),      r < R0
    K  = 30 EPSILON / sigma^2,   R0 = 1.5 sigma,     sigma = a_i + a_j (= 2 A)

(force on bead j of the bond i-j: -K (R_j - R_i) / (1 - r^2 / R0^2), its opposite on i).
With the WCA repulsion (LJ_truncate ON, 12:6) the bond length at rest is 0.961 sigma; the
spring diverges at R0, so a bond can never stretch to 1.5 sigma: a run whose bond reaches
``BOND_BREAK`` R0 stops (FloatingPointError) instead of continuing with a broken chain.
Chains therefore need EPSILON > 0 and LJ_truncate ON or OFF (config.py refuses the rest).
Tolerance: for kBT <= EPSILON the bonds stay within 0.9 .. 1.1 sigma (measured 0.933 ..
1.016 sigma over 500 steps at kBT = EPSILON = 1, A = 4; tests/unit/test_chains.py).

Initial placement: every chain a self-avoiding random walk of bond length sigma (beads closer
than sigma to any placed bead are rejected), in the periodic box; or the user_specify
positions, whose bonds must be shorter than R0 (``check_bonds``).
"""
from __future__ import annotations

import numpy as np

from .cells import minimum_image

__all__ = ["FENE_K", "FENE_R0", "BOND_BREAK", "chain_bonds", "bond_vectors", "fene_forces", "fene_energy",
           "random_walk_chains", "bond_lengths", "check_bonds"]

FENE_K = 30.0      # K sigma^2 / EPSILON
FENE_R0 = 1.5      # R0 / sigma
BOND_BREAK = 0.99  # stop when a bond reaches this fraction of R0


def chain_bonds(beads_per_chain) -> tuple:
    """(i, j) bond index arrays of consecutive chains of the given bead counts."""
    n = np.asarray(beads_per_chain, dtype=np.int64)
    chain = np.repeat(np.arange(len(n)), n)
    i = np.flatnonzero(chain[:-1] == chain[1:])
    return i, i + 1


def bond_vectors(R, box, i, j, strain=0.0) -> np.ndarray:
    """Minimum-image bond vectors R_j - R_i; with ``strain`` g the Lees-Edwards minimum
    image (the image across y = Ly displaced by g Ly along x, PHYSICS-EXTRA.md §7), so a
    bond straddling the y boundary keeps its length."""
    R = np.asarray(R, dtype=float)
    box = np.asarray(box, dtype=float)
    if not strain:
        return minimum_image(R[j] - R[i], box)
    from ..frame import lees_edwards_displacement
    return lees_edwards_displacement(R[j] - R[i], box, strain * box[1])


def bond_lengths(R, box, i, j, strain=0.0) -> np.ndarray:
    """Minimum-image lengths of the bonds (i, j) (``strain``: Lees-Edwards images)."""
    return np.linalg.norm(bond_vectors(R, box, i, j, strain), axis=1)


def fene_forces(R, box, radius, i, j, epsilon, strain=0.0) -> tuple:
    """FENE bond forces (N, 3) and the largest r / R0 over the bonds (0 without bonds);
    ``strain`` g: bonds by the Lees-Edwards minimum image (``bond_vectors``)."""
    R = np.asarray(R, dtype=float)
    F = np.zeros_like(R)
    if len(i) == 0:
        return F, 0.0
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (len(R),))
    dr = bond_vectors(R, box, i, j, strain)
    r2 = np.einsum("bk,bk->b", dr, dr)
    sigma = radius[i] + radius[j]
    R0 = FENE_R0 * sigma
    x2 = r2 / R0 ** 2
    k = FENE_K * epsilon / sigma ** 2
    with np.errstate(divide="ignore"):
        f = (-k / (1.0 - x2))[:, None] * dr          # force on j
    n = len(R)
    for a in range(3):
        F[:, a] = np.bincount(j, f[:, a], minlength=n) - np.bincount(i, f[:, a], minlength=n)
    return F, float(np.sqrt(x2.max()))


def fene_energy(r, sigma, epsilon) -> np.ndarray:
    """U_FENE(r) of bonds of length r (inf at and beyond R0)."""
    r = np.asarray(r, dtype=float)
    R0 = FENE_R0 * np.asarray(sigma, dtype=float)
    K = FENE_K * epsilon / np.asarray(sigma, dtype=float) ** 2
    x2 = (r / R0) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(x2 < 1.0, -0.5 * K * R0 ** 2 * np.log1p(-np.minimum(x2, 1.0)), np.inf)


def check_bonds(R, box, radius, beads_per_chain):
    """ValueError naming the first bond of given positions that is at least BOND_BREAK R0
    long (the FENE spring could not hold it)."""
    i, j = chain_bonds(beads_per_chain)
    r = bond_lengths(R, box, i, j)
    bad = np.flatnonzero(r >= BOND_BREAK * FENE_R0 * 2.0 * float(radius))
    if len(bad):
        k = bad[0]
        raise ValueError(f"the bond between beads {i[k]} and {j[k]} is {r[k]:g} long; FENE "
                         f"bonds must be shorter than R0 = {FENE_R0 * 2.0 * float(radius):g} "
                         f"(1.5 x 2 A)")


def _random_units(rng, m):
    v = rng.normal(size=(m, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


def random_walk_chains(beads_per_chain, radius, box, rng, candidates=64, attempts=200):
    """Positions (N, 3) in [0, L) of self-avoiding random-walk chains, bond length 2 A.

    Beads are placed one after the other (the walk is sequential); each new bead tries
    ``candidates`` random directions at once and takes the first whose distance to every
    placed bead is at least 2 A (minimum image).  A chain that gets stuck is restarted;
    ValueError after ``attempts`` restarts of one chain (the box is too crowded).
    """
    L = np.asarray(box, dtype=float).reshape(3)
    a = float(radius)
    sigma = 2.0 * a
    if sigma >= 0.5 * L.min():
        raise ValueError(f"bond length {sigma:g} (2 A) must be below half the box "
                         f"{' x '.join(f'{float(x):g}' for x in np.ravel(L))}")
    counts = [int(c) for c in beads_per_chain]
    out = np.empty((sum(counts), 3))
    placed = 0
    limit = sigma * (1.0 - 1e-9)
    for nb in counts:
        for _ in range(attempts):
            pos = placed
            ok = True
            for k in range(nb):
                if k == 0:
                    cand = rng.random((candidates, 3)) * L
                else:
                    cand = out[pos - 1] + sigma * _random_units(rng, candidates)
                if pos:
                    d = np.linalg.norm(minimum_image(cand[:, None, :] - out[None, :pos, :], L),
                                       axis=2)
                    free = np.flatnonzero((d >= limit).all(axis=1))
                else:
                    free = np.arange(candidates)
                if len(free) == 0:
                    ok = False
                    break
                out[pos] = np.mod(cand[free[0]], L)
                pos += 1
            if ok:
                placed = pos
                break
        else:
            raise ValueError(f"could not place a chain of {nb} beads of radius {a:g} without "
                             f"overlap in the box "
                             f"{' x '.join(f'{float(x):g}' for x in np.ravel(L))} (too crowded)")
    return out
