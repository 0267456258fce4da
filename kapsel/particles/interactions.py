"""The particles' interactions as a list of force objects (HOOMD-blue's ``md.force``): each
gives the forces (and torques) on the rows of a particle table and its reach; the list
(:class:`Interactions`) sums them in a fixed order (the order fixes the round-off).

A force object has ``cutoff`` (length: the reach a distributed run's halos need) and
``compute(p, gid=None, weight=None, reduce=None) -> (F, T, ratio, stretch)``:
``p`` the table (positions R, radius, species, orientations q); ``gid`` the global ids of
its rows in a distributed run (owned first, then ghosts; None for the whole table);
``weight`` 1 for an owned row and 0 for a ghost (pairs counted once in the virial over the
ranks); ``reduce`` a sum over the ranks (the Ewald sum).  Any of F, T may be None (nothing),
``ratio`` is the closest pair's distance over the contact distance (or inf), ``stretch`` the
largest bond stretch over R0 (or 0).  ``local = False`` marks a force a distributed run does
not have (the walls).  Adding a force: its class and its factory here, and the factory's
line in :data:`FORCES`.

What the particle step sees is one object with ``__call__(p) -> (F, T)`` (the checks made),
``local``, ``check``, ``check_bonds``, ``virial`` and ``cutoff``: :class:`Interactions`, or
:class:`Callback` around a plain function ``p -> (F, T)`` (:func:`as_forces`).
"""
from __future__ import annotations

import numpy as np

from . import chains
from . import forces as pf

__all__ = ["Interactions", "Callback", "PairForce", "Gravity", "WallForce", "FENEBonds",
           "Electric", "FORCES", "OVERLAP_LIMIT", "as_forces", "make_forces"]

#: a run stops when the closest pair is nearer than this fraction of the contact distance
#: (a deep overlap would launch the particles across the box)
OVERLAP_LIMIT = 0.5


class PairForce:
    """The pair potential (LJ_powers, LJ_truncate; manual §3.3), not between beads of one
    rigid body; the Lees-Edwards minimum image with ``strain()``; adds to ``virial``."""

    local = True

    def __init__(self, inter, box, radius, group, strain, virial, sigma):
        self.inter, self.box, self.group = inter, box, group
        self.strain, self.virial, self.sigma = strain, virial, sigma
        # r_c / sigma: LJ_truncate OFF within half the box (the original's A_R_cutoff,
        # sigma 2A; kapsel.particles.forces.interaction_range)
        self.rc = pf.interaction_range(inter.LJ_powers, inter.LJ_truncate, min(box),
                                       2.0 * float(np.max(radius)))
        self.cutoff = self.rc * (2.0 * float(np.max(radius)) if sigma is None else sigma)

    def compute(self, p, gid=None, weight=None, reduce=None):
        inter, group = self.inter, self.group
        if gid is not None and group is not None:
            group = group[gid]
        kw = {} if weight is None else {"weight": weight}
        F, _, ratio = pf.pair_forces(p.R, self.box, p.radius, inter.LJ_powers, inter.EPSILON,
                                     inter.LJ_truncate, group=group,
                                     strain=self.strain() if self.strain is not None else 0.0,
                                     virial=self.virial, sigma=self.sigma, cutoff=self.rc,
                                     **kw)
        return F, None, ratio, 0.0


class Gravity:
    """Net gravity (buoyancy included) of each bead (kapsel.particles.forces.gravity_force);
    rigid bodies carry theirs themselves (kapsel.particles.rigid)."""

    local = True
    cutoff = 0.0

    def __init__(self, species, radius, species_of, rho, G, direction):
        self.ratios = np.array([s.MASS_RATIO for s in species])
        self.rho, self.G, self.direction = rho, G, direction
        self.whole = pf.gravity_force(radius, self.ratios[species_of], rho, G, direction)

    def compute(self, p, gid=None, weight=None, reduce=None):
        if gid is None:
            return self.whole, None, np.inf, 0.0
        return (pf.gravity_force(p.radius, self.ratios[p.species], self.rho, self.G,
                                 self.direction), None, np.inf, 0.0)


class WallForce:
    """The particle-wall repulsion of a flat wall (kapsel.particles.walls.FlatWall)."""

    local = False       # walls do not run distributed
    cutoff = 0.0

    def __init__(self, wall):
        self.wall = wall

    def compute(self, p, gid=None, weight=None, reduce=None):
        F, _, ratio = self.wall.forces(p.R, p.radius)
        return F, None, ratio, 0.0


class FENEBonds:
    """FENE bonds between consecutive beads of a chain (kapsel.particles.chains); on a
    rank's table the bonds whose two beads it holds (bead g bonds to g + 1 unless g + 1
    starts a chain)."""

    local = True

    def __init__(self, beads_per_chain, radius, epsilon, box, strain):
        self.bonds = chains.chain_bonds(beads_per_chain)
        self.starts = np.concatenate([np.cumsum(beads_per_chain), [0]])
        self.epsilon, self.box, self.strain = epsilon, box, strain
        self.cutoff = chains.FENE_R0 * 2.0 * float(np.max(radius))   # a bond is shorter

    def compute(self, p, gid=None, weight=None, reduce=None):
        strain = self.strain() if self.strain is not None else 0.0
        if gid is None:
            i, j = self.bonds
        else:
            order = np.argsort(gid)
            sg = gid[order]
            k = np.minimum(np.searchsorted(sg, gid + 1), max(len(sg) - 1, 0))
            i = np.flatnonzero(~np.isin(gid + 1, self.starts) & (sg[k] == gid + 1))
            j = order[k[i]]
        F, stretch = chains.fene_forces(p.R, self.box, p.radius, i, j, self.epsilon,
                                        strain=strain)
        return F, None, np.inf, stretch


class Electric:
    """Dipole forces and torques (Ewald) and the Quincke constraint torque
    (kapsel.particles.dipoles.make_electric)."""

    local = True

    def __init__(self, electric):
        self.electric = electric
        self.cutoff = float(electric.reach)        # the Ewald sum's real-space reach

    def compute(self, p, gid=None, weight=None, reduce=None):
        if gid is None:
            F, T = self.electric(p)
        else:
            F, T = self.electric.local(p, int(np.count_nonzero(weight)), reduce)
        return F, T, np.inf, 0.0


class Interactions:
    """The sum of a list of force objects, in their order: ``interactions(p) -> (F, T)`` on
    the whole table, after the checks (``check_bonds``: a bond stretched past
    chains.BOND_BREAK, ``check``: a pair closer than ``overlap_limit`` of contact, if set;
    both raise FloatingPointError), ``local(p, weight, gid, reduce) -> (F, T, ratio,
    stretch)`` on a rank's table (None when a force does not run distributed; the caller
    checks the minima over the ranks); ``virial`` the pair virial of the last call;
    ``cutoff`` the largest reach."""

    def __init__(self, forces, n, virial, overlap_limit=None):
        self.forces, self.virial = list(forces), virial
        self.overlap_limit = overlap_limit
        self._zeros = np.zeros((n, 3))
        self.cutoff = max([0.0] + [f.cutoff for f in self.forces])
        if not all(f.local for f in self.forces):
            self.local = None

    def _sum(self, p, zeros, gid=None, weight=None, reduce=None):
        F, T, ratio, stretch = None, zeros, np.inf, 0.0
        for f in self.forces:
            Fi, Ti, ri, si = f.compute(p, gid, weight, reduce)
            if isinstance(f, PairForce):
                F = Fi
            elif Fi is not None:
                F = (zeros.copy() if F is None else F) + Fi
            if Ti is not None:
                T = Ti
            ratio, stretch = min(ratio, ri), max(stretch, si)
        return (zeros.copy() if F is None else F), T, ratio, stretch

    @staticmethod
    def check_bonds(stretch) -> None:
        """FloatingPointError when a chain bond reached chains.BOND_BREAK of R0."""
        if stretch >= chains.BOND_BREAK:
            raise FloatingPointError(f"a chain bond stretched to {stretch:.3f} of the FENE "
                                     f"maximum R0 = {chains.FENE_R0} (2 A)")

    def check(self, ratio) -> None:
        """FloatingPointError when the closest pair is nearer than ``overlap_limit`` of the
        contact distance (no check without a limit)."""
        if self.overlap_limit is not None and ratio < self.overlap_limit:
            raise FloatingPointError(f"particles overlap deeply (closest pair at {ratio:.2f} "
                                     f"of the contact distance)")

    def __call__(self, p):
        F, T, ratio, stretch = self._sum(p, self._zeros)
        self.check_bonds(stretch)
        self.check(ratio)
        return F, T

    def local(self, p, weight, gid, reduce=None):
        """The forces of a rank's table (owned + ghosts; ``gid`` the global ids), complete
        on the owned rows; the virial counts each pair once over the ranks."""
        return self._sum(p, np.zeros((p.n, 3)), gid, weight, reduce)


class Callback:
    """The forces of a plain function ``fn(p) -> (F, T, ...)`` (tests, scripts, a model's
    sum of its interactions and a force of its own), on the whole table: no reach, no
    checks of its own (``fn`` makes them), not distributed; ``virial`` the one ``fn``'s
    pairs fill, if any."""

    cutoff = 0.0
    local = None

    def __init__(self, fn, virial=None):
        self.fn, self.virial = fn, virial

    def __call__(self, p):
        res = self.fn(p)
        return res[0], res[1]

    def check(self, ratio) -> None:
        pass

    def check_bonds(self, stretch) -> None:
        pass


def as_forces(forces):
    """The force object of the particle step: None (no forces), an :class:`Interactions`
    or a :class:`Callback`, or a plain function made a Callback."""
    if forces is None or isinstance(forces, (Interactions, Callback)):
        return forces
    return Callback(forces)


def _pairs(cfg, particles, strain, wall, virial):
    inter = cfg.interactions
    if inter.LJ_truncate == "NONE" or particles.n < 2 or inter.EPSILON <= 0:
        return None
    from ..typespec import sheared
    sigma = None
    if sheared(getattr(cfg, "type", None)):             # LJ_dia of the sheared types
        sigma = pf.sheared_lj_dia(inter.LJ_powers, cfg.particles.A, cfg.particles.A_XI)
        if sigma == 2.0 * cfg.particles.A:
            sigma = None
    return PairForce(inter, cfg.mesh.box, particles.radius,
                     getattr(particles.constraints, "body", None), strain, virial, sigma)


def _gravity(cfg, particles, strain, wall, virial):
    inter = cfg.interactions
    if inter.G == 0 or particles.n == 0 or \
            getattr(particles.constraints, "gravity", None) is not None:
        return None
    return Gravity(cfg.particles.species, particles.radius, particles.species, cfg.fluid.RHO,
                   inter.G, inter.G_direction)


def _wall(cfg, particles, strain, wall, virial):
    if wall is None or wall.truncate == "NONE" or particles.n == 0:
        return None
    return WallForce(wall)


def _bonds(cfg, particles, strain, wall, virial):
    if cfg.particles.object_type != "chain" or particles.n < 2:
        return None
    return FENEBonds([s.beads for s in cfg.particles.species for _ in range(s.number)],
                     particles.radius, cfg.interactions.EPSILON, cfg.mesh.box, strain)


def _electric(cfg, particles, strain, wall, virial):
    sw = getattr(cfg, "switches", None)
    quincke, dipoles = getattr(sw, "quincke", None), getattr(sw, "dipoles", None)
    if particles.n == 0 or (quincke is None and dipoles is None):
        return None
    from .dipoles import make_electric
    return Electric(make_electric(dipoles, quincke, cfg.mesh.box, particles.n, strain=strain))


#: the force factories, in the order their forces are summed:
#: ``factory(cfg, particles, strain, wall, virial) -> force object or None``
FORCES = [_pairs, _gravity, _wall, _bonds, _electric]


def make_forces(cfg, particles, strain=None, wall=None, overlap_limit=None):
    """The interactions of a run's particles (module docstring), or None when a scene has
    none: pair forces (skipped for LJ_truncate NONE), net gravity, the particle-wall force of
    ``wall`` (a kapsel.particles.walls.FlatWall), FENE bonds of chains, dipoles and the
    Quincke constraint (:data:`FORCES`).  ``strain()``: the Lees-Edwards frame strain of the
    sheared types (pairs and bonds by the Lees-Edwards minimum image).  ``overlap_limit``:
    a deep overlap stops the run (a run's models pass :data:`OVERLAP_LIMIT`)."""
    virial = np.zeros((3, 3))       # sum over pairs of f_a dr_b of the last call
    out = [f for f in (make(cfg, particles, strain, wall, virial) for make in FORCES)
           if f is not None]
    return Interactions(out, particles.n, virial, overlap_limit) if out else None
