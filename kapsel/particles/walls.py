"""Flat walls (``switch.wall`` FLAT; PHYSICS-EXTRA.md §2): two parallel solid slabs normal to
one axis, held at rest by the same SPM rigidity as the particles.

Geometry (§2.1): along the wall axis, with L the box length and DH the total solid
thickness in grid points, lo = DH DX / 2 and hi = L - lo.  The fluid lies between lo and hi;
the solid is x < lo together with x > hi, one slab across the periodic boundary.  The gap
between the two solid faces (the planes phi_wall = 1/2) is h = hi - lo = L - DH DX.

Profile fields (§2.2), built once:

* ``phi``: phi_wall(r) = g(r; lo) for r < L/2 and 1 - g(r; hi) for r >= L/2, with g the
  particle profile of eqs 1-3 as a function of the distance r along the axis (1 inside the
  solid, the particles' tanh-like interface of width XI centred on lo and hi).
  The Cahn-Hilliard wall terms (kapsel.phase.cahn_hilliard) use phi_wall and its gradient.

Every profile is computed from the node coordinate r = index DX along the wall's own axis,
for X, Y and Z walls and any DX.  (The original decides "lower half" for the sign of its
wall gradient by comparing the z index with L/2, which is right only for a Z wall at DX = 1.)

Fluid (§2.3): the walls are a body at rest in the SPM step (kapsel.particles.spm.SPM, as
the original's phi_sum starts from phi_wall): the rigidity increment holds
-(phi_wall / max(phi_sum, 1)) u*, made solenoidal together with the particles'; the
projection leaves a little velocity in the solid (about 0.5 % of max|u| in a Poiseuille
flow, 5 % next to settling particles, as in the original).

Particle-wall force (§2.4): each particle sees a mirror particle of each wall along the
axis: with x its coordinate and sigma = 2a (a its radius), h_lo = x - lo + a and
h_hi = hi - x + a are the distances to the mirror particles, and the force along the axis
is -dV/dh (h_lo) - (-dV/dh)(h_hi) with V the particle pair law (kapsel.particles.forces) of
the wall's LJ parameters: a particle whose surface touches the solid face feels the force of
a particle pair at contact.  AUTO: the particles' EPSILON and LJ_powers, truncation ON;
MANUAL: the wall's EPSILON, powers and truncate.  The per-bead forces enter rigid bodies
like every other bead force (body force = sum, torque = sum of r_k x F_k on top of the
other torques; the original assigns GRvec[I] x F instead, losing the LJ torque).
"""
from __future__ import annotations

import numpy as np

from . import forces as pf
from .profile import g

__all__ = ["FlatWall", "AXES"]

AXES = {"X": 0, "Y": 1, "Z": 2}


class FlatWall:
    """A FLAT wall pair normal to ``axis`` (0, 1, 2) on a mesh ``shape`` with spacing ``dx``;
    ``DH`` solid points, profile interface ``xi`` (A_XI, length units as the particles'),
    LJ law ``powers`` / ``epsilon`` / ``truncate`` (kapsel.particles.forces)."""

    def __init__(self, axis, DH, shape, dx, xi, powers="12:6", epsilon=1.0, truncate="ON"):
        self.axis = int(axis)
        self.shape = tuple(int(n) for n in shape)
        self.dx, self.xi = float(dx), float(xi)
        self.DH = int(DH)
        n = self.shape[self.axis]
        self.L = n * self.dx
        self.lo = 0.5 * self.DH * self.dx
        self.hi = self.L - self.lo
        self.gap = self.hi - self.lo
        self.powers = pf._check_powers(powers)
        self.truncate = pf._truncate_key(truncate)
        self.epsilon = float(epsilon)
        r = np.arange(n) * self.dx
        self.r = r
        half = r < 0.5 * self.L
        self.profile = np.where(half, g(r, self.lo, self.xi, self.dx),
                                1.0 - g(r, self.hi, self.xi, self.dx))
        self._phi = None

    # ------------------------------------------------------------------ fields
    def _field(self, prof):
        sh = [1, 1, 1]
        sh[self.axis] = len(prof)
        return np.ascontiguousarray(np.broadcast_to(prof.reshape(sh), self.shape))

    @property
    def phi(self) -> np.ndarray:
        """phi_wall on the mesh (NX, NY, NZ), built once."""
        if self._phi is None:
            self._phi = self._field(self.profile)
            self._phi.setflags(write=False)
        return self._phi

    def grad_phi_sq(self) -> np.ndarray:
        """|grad phi_wall|^2 on the mesh: central differences along the wall's axis (the
        particles' |grad phi|^2 of the Cahn-Hilliard potential is taken the same way)."""
        d = (np.roll(self.profile, -1) - np.roll(self.profile, 1)) / (2.0 * self.dx)
        return self._field(d * d)

    def solid(self, threshold=1.0 - 1e-12) -> np.ndarray:
        """Boolean mask of the nodes inside the solid (phi_wall = 1)."""
        return self.phi >= threshold

    # ------------------------------------------------------------------ particle forces
    def distances(self, R, radius):
        """(h_lo, h_hi): distances of each particle to its mirror particles in the lower and
        upper solid faces, sigma = 2 a apart at contact."""
        x = np.mod(np.asarray(R, dtype=float).reshape(-1, 3)[:, self.axis], self.L)
        a = np.broadcast_to(np.asarray(radius, dtype=float), x.shape)
        return x - self.lo + a, self.hi - x + a

    def forces(self, R, radius):
        """(F (N, 3), U, min_ratio): the wall forces on the particles, their potential
        energy and the smallest h / sigma within the cutoff (inf if none)."""
        R = np.asarray(R, dtype=float).reshape(-1, 3)
        F = np.zeros((len(R), 3))
        if self.truncate == "NONE" or not len(R):
            return F, 0.0, np.inf
        sigma = 2.0 * np.broadcast_to(np.asarray(radius, dtype=float), (len(R),))
        h_lo, h_hi = self.distances(R, 0.5 * sigma)
        args = (sigma, self.powers, self.epsilon, self.truncate)
        F[:, self.axis] = (pf.pair_force_magnitude(h_lo, *args)
                           - pf.pair_force_magnitude(h_hi, *args))
        U = float(np.sum(pf.pair_potential(h_lo, *args) + pf.pair_potential(h_hi, *args)))
        rc = pf.interaction_range(self.powers, self.truncate) * sigma
        h = np.concatenate([h_lo[h_lo < rc] / sigma[h_lo < rc],
                            h_hi[h_hi < rc] / sigma[h_hi < rc]])
        return F, U, float(h.min()) if h.size else np.inf

    def energy(self, R, radius) -> float:
        return self.forces(R, radius)[1]


def clear_slab(cfg):
    """(axis, lowest, highest) centre coordinate of a particle clear of the walls' force
    range (centre further than A_R_cutoff sigma - a from a face, and at least a), or None
    without walls."""
    w = getattr(cfg.switches, "wall", None)
    if w is None:
        return None
    A = cfg.particles.A
    lo = 0.5 * w.DH * cfg.mesh.DX
    hi = cfg.mesh.box[w.axis] - lo
    clear = A
    if w.truncate != "NONE":
        clear = max(pf.interaction_range(w.powers, w.truncate) * 2 * A - A, A)
    return w.axis, lo + clear, hi - clear


def make_wall(cfg):
    """The FlatWall of a configuration (``cfg.switches.wall``), or None."""
    w = getattr(cfg.switches, "wall", None)
    if w is None:
        return None
    return FlatWall(w.axis, w.DH, cfg.mesh.shape, cfg.mesh.DX, cfg.particles.A_XI,
                    w.powers, w.EPSILON, w.truncate)
