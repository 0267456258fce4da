"""Particles owned by ranks: ownership, halos, migration, reverse sums, gather.

A layout names its particle table (``particle_table``; :func:`owned_table`): the whole mesh
on one process (kapsel.mesh.grid.Grid) has a ``WholeTable``, whose every operation below is
an identity; the ranks' blocks (kapsel.mesh.pencil.PencilGrid) have ``Owned``.

A particle is *owned* by the rank whose real-space block (kapsel.mesh.pencil: x split
over PX, y over PY, z whole) holds the base point of its profile stencil, floor(R / DX) (the
particles couple on the rectangular grid, the Lees-Edwards types too: kapsel.particles.spm),
so ownership is unambiguous.  Each rank holds its owned particles and *ghosts*: copies of
particles owned elsewhere whose stencil, widened by the pair-force cutoff, meets its block.
The test is made for every rank, not only the neighbours, so blocks thinner than the halo
work (a particle goes to every rank whose widened block holds it).  With lo..hi the
stencil's offsets and h = ceil(r_c / DX) + 1 cells (r_c the pair cutoff), a particle goes to
the ranks whose block meets [b + lo - h, b + hi + h] along x and y (b its base point): this
holds every particle whose profile meets the block and every pair partner (|b_i - b_j| <=
ceil(r_c / DX)) of every owned particle.  Under Lees-Edwards images (``images``: the x
displacement g Ly of the image across y = Ly) the part of that box beyond the y boundary
lies displaced along x, at the base floor((R_x -+ g Ly) / DX) (pencil.stencil_meets), where
kapsel.particles.profile.lees_edwards_profiles puts the stencil's points there and where the
pair partners across the boundary are (their minimum-image displacement is x-shifted alike).

Rigid bodies (``bodies``: the body of every bead, the first bead of every body) are owned
whole: all the beads of a body by the owner of its first bead's base point (one point per
body, as unambiguous as a sphere's; the body migrates at once, with all its beads, when that
point crosses a block boundary); the body's state (kapsel.particles.rigid
``bead_records``: centre, velocities, quaternion, summed forces, and the bead's
Lees-Edwards image count) travels as ``extra`` columns of its beads' records.  A bead's
ghosts go to the ranks its own widened stencil meets, as for any particle; the pair cutoff
of the halo is widened by the largest distance of a bead from its body's first bead
(``span``), so the pair partners of every bead of a body reach the body's owner.

The local table (one ``ParticleState``) keeps the owned rows first, in global-id order,
then the ghosts by (owner, global id).  Per step (kapsel.particles.spm, ``SPM.step``):

* ``reverse_sum``: the ghosts' partial coupling sums (force, torque over this rank's part
  of their stencils) go to their owners, which add the contributions of the ranks in rank
  order (own included at its place): the run is bit-for-bit repeatable;
* ``refresh``: the owners' new velocities go to the ghosts (the rigidity increment on a
  rank's block needs them);
* ``exchange``: after the motion each owner sends the whole record of each particle it
  owned to every rank that holds it now (its new owner included): migration and the new
  halo in one ``MPI_Alltoallv``.

Records are rows of float64 (``COLUMNS``), packed and unpacked by whole-array numpy, sent by
``Alltoallv`` / ``Gatherv`` on numpy buffers (no pickling, no loop over particles).
``gather`` brings the owned rows to rank 0 in global-id order (the output writers and the
restart see the table of a plain run); ``scatter`` keeps a rank's rows of a whole table
held by every rank (the start of a run, a restart).
"""
from __future__ import annotations

import math

import numpy as np

from .state import VECTOR_FIELDS, ParticleState
from ..mesh.pencil import block, stencil_meets

__all__ = ["Owned", "WholeTable", "owned_table", "COLUMNS", "pack", "unpack", "release",
           "restore"]

COLUMNS = ([(name, 3) for name in VECTOR_FIELDS] + [("q", 4), ("q_old", 4)]
           + [("species", 1), ("radius", 1), ("mass", 1), ("inertia", 1)])
_WIDTH = sum(w for _, w in COLUMNS)
GID, OWNER = _WIDTH, _WIDTH + 1            # global id and owner rank: the last two columns
WIDTH = _WIDTH + 2


def pack(p: ParticleState, rows, gid, owner, extra=None) -> np.ndarray:
    """Records (len(rows), WIDTH + k) of the rows of ``p`` (``extra`` (len(rows), k): more
    columns carried along, e.g. the state of a rigid body with each of its beads)."""
    k = 0 if extra is None else extra.shape[1]
    out = np.empty((len(rows), WIDTH + k))
    c = 0
    for name, w in COLUMNS:
        a = getattr(p, name)[rows]
        out[:, c:c + w] = a.reshape(len(rows), w)
        c += w
    out[:, GID] = gid
    out[:, OWNER] = owner
    if k:
        out[:, WIDTH:] = extra
    return out


def unpack(rec: np.ndarray, constraints=None) -> tuple[ParticleState, np.ndarray, np.ndarray]:
    """(ParticleState, global ids, owners) of records."""
    kw, c = {}, 0
    n = len(rec)
    for name, w in COLUMNS:
        a = rec[:, c:c + w]
        if name == "species":
            kw[name] = a[:, 0].astype(np.int64)
        elif w == 1:
            kw[name] = a[:, 0].copy()
        else:
            kw[name] = np.ascontiguousarray(a)
        c += w
    p = ParticleState(n=n, constraints=constraints, **kw)
    return p, rec[:, GID].astype(np.int64), rec[:, OWNER].astype(np.int64)


def view(p: ParticleState, n: int) -> ParticleState:
    """The first n rows of ``p`` as a ParticleState of views (updates write through)."""
    kw = {name: getattr(p, name)[:n] for name, _ in COLUMNS}
    return ParticleState(n=n, **kw)


def release(p: ParticleState) -> None:
    """Drop the rows of a whole table a rank no longer needs (``n`` is kept: the particle
    count of the run); ``restore`` gives them back (zeros) to read a restart into."""
    for name, w in COLUMNS:
        a = getattr(p, name)
        setattr(p, name, np.empty((0,) + a.shape[1:], dtype=a.dtype))


def restore(p: ParticleState) -> None:
    for name, w in COLUMNS:
        a = getattr(p, name)
        if a.shape[0] != p.n:
            shape = (p.n,) + a.shape[1:]
            b = np.zeros(shape, dtype=a.dtype)
            if name in ("q", "q_old"):
                b[:, 0] = 1.0
            setattr(p, name, b)


def _meets(b, lo, width, blocks, n):
    """(N, len(blocks)) bool: the periodic interval [b + lo, b + lo + width) meets block
    [a0, a1) (the test of kapsel.particles.spm ``_near``)."""
    if width >= n:
        return np.ones((len(b), len(blocks)), dtype=bool)
    start = np.mod(b + lo, n)[:, None]
    a0, a1 = blocks[None, :, 0], blocks[None, :, 1]
    return (np.mod(a0 - start, n) < width) | (np.mod(start - a0, n) < a1 - a0)


class Owned:
    """Ownership and halos of the particles on the blocks of ``grid`` (a PencilGrid or any
    object with ``comm``, ``shape``, ``px``, ``py``), for a stencil ``offsets`` (S, 3) in
    cells, a pair cutoff ``cutoff`` (DX units of length), ``images()`` -> the x
    displacement g Ly of the Lees-Edwards image across y = Ly (None: periodic)."""

    partial = True          # a rank's part of the run's table (its sums over the ranks)

    def __init__(self, grid, offsets, dx, cutoff=0.0, images=None, bodies=None,
                 extra_width=0):
        from mpi4py import MPI
        # rigid bodies: (body of every bead, first bead of every body) (global ids); a body
        # and all its beads are owned by the owner of its first bead's base point
        self.group, self.lead = (None, None) if bodies is None else bodies
        self.extra_width = int(extra_width)
        self.extra = np.zeros((0, self.extra_width))
        self.MPI = MPI
        self.comm = grid.comm
        self.me, self.P = self.comm.Get_rank(), self.comm.Get_size()
        self.shape = tuple(grid.shape)
        self.px, self.py = int(grid.px), int(grid.py)
        self.dx = float(dx)
        self.images = images
        self.blocks = [np.array([block(self.shape[a], parts, i) for i in range(parts)])
                       for a, parts in ((0, self.px), (1, self.py))]
        self.lo, self.width = [], []
        for axis in (0, 1):
            o = np.asarray(offsets)[:, axis]
            h = int(math.ceil(cutoff / self.dx)) + 1 if cutoff > 0 else 0
            lo, hi = int(o.min()), int(o.max())
            self.lo.append(lo - h)
            self.width.append(hi - lo + 1 + 2 * h)
        self.halo_cells = self.width
        self.n_own = 0
        self.gid = np.zeros(0, dtype=np.int64)
        self.owner = np.zeros(0, dtype=np.int64)

    # ------------------------------------------------------------------ geometry
    def base(self, R):
        """Base points (N, 2) (x, y cells, in [0, n)) of the stencils at R."""
        s = np.asarray(R, dtype=float)[:, :2] / self.dx
        with np.errstate(invalid="ignore"):
            b = np.floor(s).astype(np.int64)
        b[:, 0] = np.mod(b[:, 0], self.shape[0])
        b[:, 1] = np.mod(b[:, 1], self.shape[1])
        return b

    def owners(self, b):
        cx = np.searchsorted(self.blocks[0][:, 0], b[:, 0], side="right") - 1
        cy = np.searchsorted(self.blocks[1][:, 0], b[:, 1], side="right") - 1
        return cx * self.py + cy

    def _body_owners(self, owner, gid):
        """Rigid bodies: the owner of every bead (rows of global ids ``gid``, sorted, whole
        bodies) is that of its body's first bead; else ``owner`` unchanged."""
        if self.group is None:
            return owner
        return owner[np.searchsorted(gid, self.lead[self.group[gid]])]

    def destinations(self, b, R):
        """(N, P) bool: the ranks whose widened block holds each particle (base points
        ``b`` of the positions ``R``); under Lees-Edwards images the parts of the widened
        box beyond the y boundary at their x-shifted places (``stencil_meets``)."""
        if self.images is not None:
            return stencil_meets(np.asarray(R, dtype=float)[:, :2] / self.dx, self.lo,
                                 self.width, self.blocks[0], self.blocks[1], self.shape,
                                 float(self.images()) / self.dx).reshape(len(b), self.P)
        mx = _meets(b[:, 0], self.lo[0], self.width[0], self.blocks[0], self.shape[0])
        my = _meets(b[:, 1], self.lo[1], self.width[1], self.blocks[1], self.shape[1])
        return (mx[:, :, None] & my[:, None, :]).reshape(len(b), self.P)

    # ------------------------------------------------------------------ layout
    def _arrange(self, rec, constraints=None):
        """The local table of received records: owned by global id, then ghosts by
        (owner, global id); send lists of the owned rows to the ranks holding them."""
        gid, owner = rec[:, GID], rec[:, OWNER]
        key = np.where(owner == self.me, -1.0, owner)
        order = np.lexsort((gid, key))
        rec = rec[order]
        p, self.gid, self.owner = unpack(rec, constraints)
        self.extra = np.ascontiguousarray(rec[:, WIDTH:])
        self.n_own = int(np.count_nonzero(owner == self.me))
        n = self.n_own
        # where the owned rows are ghosts (the senders computed the same from the same bits)
        dest = self.destinations(self.base(p.R[:n]), p.R[:n])
        dest[:, self.me] = False
        r, i = np.nonzero(dest.T)                     # by rank, then row (global id)
        self.send_rows = i
        self.send_counts = np.bincount(r, minlength=self.P).astype(np.int64)
        self.ghost_counts = np.bincount(self.owner[n:], minlength=self.P).astype(np.int64)
        # the order of a reverse sum: the contributions of the ranks in rank order
        starts = np.concatenate([[0], np.cumsum(self.send_counts)])
        self._sum_rows = np.concatenate([self.send_rows[:starts[self.me]], np.arange(n),
                                         self.send_rows[starts[self.me]:]])
        self._own_at = int(starts[self.me])
        return p

    def release(self, whole: ParticleState) -> None:
        """Drop the whole table's rows on the ranks other than 0 (``release``): from the
        first step on only rank 0 keeps them (for its writers)."""
        if self.me != 0:
            release(whole)

    def scatter(self, whole: ParticleState, constraints=None, extra=None) -> ParticleState:
        """This rank's table (owned + ghosts) of a whole table held alike by every rank
        (``extra`` (N, extra_width): the further columns of every row, kept in ``extra``)."""
        b = self.base(whole.R)
        owner = self._body_owners(self.owners(b), np.arange(whole.n))
        dest = self.destinations(b, whole.R)
        dest[np.arange(whole.n), owner] = True
        rows = np.flatnonzero(dest[:, self.me])
        ex = None if extra is None else np.asarray(extra)[rows]
        return self._arrange(pack(whole, rows, rows, owner[rows], ex), constraints)

    # ------------------------------------------------------------------ communication
    def _alltoallv(self, send, scounts, rcounts, width):
        sc = [int(c) * width for c in scounts]
        rc = [int(c) * width for c in rcounts]
        sd = np.concatenate([[0], np.cumsum(sc)[:-1]]).astype(int).tolist()
        rd = np.concatenate([[0], np.cumsum(rc)[:-1]]).astype(int).tolist()
        recv = np.empty((sum(rc) // width if width else 0, width))
        D = self.MPI.DOUBLE
        self.comm.Alltoallv([np.ascontiguousarray(send), (sc, sd), D], [recv, (rc, rd), D])
        return recv

    def exchange(self, p: ParticleState, constraints=None, extra=None) -> ParticleState:
        """Migration and new halos after the owners moved their particles: the new local
        table (the ghosts of ``p`` are dropped, the owned rows sent to every rank that
        holds them now, with their ``extra`` columns (n_own, extra_width))."""
        n = self.n_own
        b = self.base(p.R[:n])
        owner = self._body_owners(self.owners(b), self.gid[:n])
        dest = self.destinations(b, p.R[:n])
        dest[np.arange(n), owner] = True
        r, i = np.nonzero(dest.T)
        rec = pack(p, i, self.gid[i], owner[i], None if extra is None else extra[i])
        scounts = np.bincount(r, minlength=self.P).astype(np.int64)
        rcounts = np.empty_like(scounts)
        self.comm.Alltoall(scounts, rcounts)
        return self._arrange(self._alltoallv(rec, scounts, rcounts,
                                             WIDTH + self.extra_width), constraints)

    def reverse_sum(self, values: np.ndarray) -> np.ndarray:
        """Totals (n_own, k) of per-particle partial sums ``values`` (n_local, k) of every
        rank: the ghosts' rows go to their owners, added in rank order."""
        values = np.asarray(values, dtype=float)
        k = values.shape[1]
        n = self.n_own
        recv = self._alltoallv(values[n:], self.ghost_counts, self.send_counts, k)
        a = self._own_at
        parts = np.concatenate([recv[:a], values[:n], recv[a:]])
        total = np.zeros((n, k))
        np.add.at(total, self._sum_rows, parts)
        return total

    def refresh(self, *arrays) -> None:
        """The owners' rows of ``arrays`` (n_local, ...) copied into the ghost rows."""
        n = self.n_own
        for a in arrays:
            w = int(np.prod(a.shape[1:]))
            recv = self._alltoallv(a[self.send_rows].reshape(-1, w), self.send_counts,
                                   self.ghost_counts, w)
            a[n:] = recv.reshape((-1,) + a.shape[1:])

    # ------------------------------------------------------------------ the owned rows
    def owned_view(self, p: ParticleState) -> ParticleState:
        """The owned rows of the local table ``p`` (views: updates write through)."""
        return view(p, self.n_own)

    def local_constraints(self, bodies, pins):
        """The constraints of the owned rows: the rigid bodies they make up whole (of the
        run's ``bodies``, their state from the records' ``extra`` columns), or the owned
        pinned rows (of the run's motion.Pinned ``pins``), or None."""
        n = self.n_own
        gid = self.gid[:n]
        if bodies is not None:
            return bodies.local(gid, self.extra[:n])
        if pins is not None:
            from .motion import Pinned
            return Pinned(np.flatnonzero(np.isin(gid, pins.pin)),
                          np.flatnonzero(np.isin(gid, pins.pin_rot)))
        return None

    def local_janus(self, janus):
        """The self-propulsion of the table's rows (a subset of the run's Janus), or None."""
        return None if janus is None else janus.subset(self.gid)

    def own_rows(self, a):
        """This rank's owned rows of an array over all particles (N, ...) (by global id)."""
        return a[self.gid[:self.n_own]]

    def sum_to_owners(self, full, F, T):
        """(F, T) (n_own, 3) totals of the partial sums (F, T) of the coupled rows
        (``full``: those rows onto the local table, zeros elsewhere) over the ranks."""
        FT = self.reverse_sum(full(np.concatenate([F, T], axis=1)))
        return FT[:, :3], FT[:, 3:]

    def other_forces(self, forces, p: ParticleState, reduce):
        """(F, T) (n_own, 3) of the non-hydrodynamic forces of the owned rows
        (kapsel.particles.interactions ``local``: pairs with ghosts, the virial counting
        each pair once over the ranks, ``reduce`` its sum); the overlap and bond-stretch
        checks on the minima over the ranks (the same on every rank)."""
        n = self.n_own
        weight = np.zeros(p.n)
        weight[:n] = 1.0
        F_o, T_o, ratio, stretch = forces.local(p, weight, self.gid,
                                                reduce=lambda a: reduce(a)[0])
        ratio, stretch = self.allmin(ratio, -stretch)      # the same on every rank
        forces.check_bonds(-stretch)
        forces.check(ratio)
        virial = forces.virial
        if virial is not None:
            virial[...] = reduce(virial)[0]
        return F_o[:n], T_o[:n]

    def allmin(self, *x):
        """The minima over the ranks of local floats (one collective)."""
        a = np.array(x, dtype=float)
        out = np.empty_like(a)
        self.comm.Allreduce(a, out, op=self.MPI.MIN)
        return tuple(float(v) for v in out)

    def gather(self, p: ParticleState, whole: ParticleState | None, everyone=False,
               extra=None):
        """The owned rows of every rank into ``whole`` on rank 0 (global-id order); with
        ``everyone`` on every rank (``whole`` then full-sized everywhere).  ``extra``
        (n_own, extra_width): further columns of the owned rows, returned (N, extra_width)
        in global-id order where ``whole`` is filled (None elsewhere)."""
        n = self.n_own
        W = WIDTH if extra is None else WIDTH + extra.shape[1]
        rec = pack(p, np.arange(n), self.gid[:n], self.me, extra).reshape(-1)
        D = self.MPI.DOUBLE
        if everyone:
            counts = self.comm.allgather(n * W)
        else:
            counts = self.comm.gather(n * W, root=0)
            if self.me != 0:
                self.comm.Gatherv(rec, None, root=0)
                return None
        buf = np.empty(sum(counts))
        displ = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int).tolist()
        if everyone:
            self.comm.Allgatherv(rec, [buf, (counts, displ), D])
        else:
            self.comm.Gatherv(rec, [buf, (counts, displ), D], root=0)
        rec = buf.reshape(-1, W)
        gid = rec[:, GID].astype(np.int64)
        c = 0
        for name, w in COLUMNS:
            a = getattr(whole, name)
            if name == "species":
                a[gid] = rec[:, c].astype(a.dtype)
            else:
                a[gid] = rec[:, c:c + w].reshape((len(gid),) + a.shape[1:])
            c += w
        if extra is None:
            return None
        out = np.empty((len(gid), W - WIDTH))
        out[gid] = rec[:, WIDTH:]
        return out


def owned_table(layout, offsets, dx, cutoff=0.0, images=None, bodies=None, extra_width=0):
    """The particle table of ``layout`` (its ``particle_table``): ``offsets`` the profile
    stencil's (S, 3) grid steps, ``cutoff`` the pair forces' range, ``images`` the
    Lees-Edwards image shift, ``bodies`` (body of every bead, first beads) for rigid bodies
    owned whole, ``extra_width`` their per-bead record columns."""
    return TABLES[layout.particle_table](layout, offsets, dx, cutoff, images, bodies=bodies,
                                         extra_width=extra_width)


class WholeTable:
    """The particle table of a run on one process, as kapsel.particles.ownership.Owned is a
    rank's (same methods): every row is owned here, in global-id order, and there are no
    ghosts, so the table is the whole table; migration, halos, reverse sums to the owners
    and gathers are identities, the minima over the ranks are the local values, this
    process's rows of a per-particle array (the thermal impulses) are all of them, and the
    constraints and self-propulsion of the owned rows are the whole table's."""

    me, P = 0, 1
    partial = False         # the table is the whole one (its sums need no sum over ranks)

    def __init__(self, layout=None, offsets=None, dx=None, cutoff=0.0, images=None,
                 bodies=None, extra_width=0):
        self.n_own = 0
        self.gid = np.zeros(0, dtype=np.int64)
        self._whole = None

    def scatter(self, whole, constraints=None, extra=None):
        """This process's table of the whole table: ``whole`` itself."""
        self.n_own = whole.n
        self.gid = np.arange(whole.n, dtype=np.int64)
        self._whole = whole
        return whole

    def release(self, whole):
        """The whole table stays whole (it is this process's own)."""

    def exchange(self, p, constraints=None, extra=None):
        """Migration and new halos after the move: none (``p`` itself)."""
        return p

    def owned_view(self, p):
        """The owned rows of the table: all of them (``p``)."""
        return p

    def local_constraints(self, bodies, pins):
        """The rigid bodies / pins of the owned rows: the whole table's constraints as they
        are now (RigidBodies or motion.Pinned, None without)."""
        return getattr(self._whole, "constraints", None)

    def local_janus(self, janus):
        """The self-propulsion (kapsel.particles.janus.Janus) of the table's rows: ``janus``."""
        return janus

    def own_rows(self, a):
        """This process's rows of an array over all particles (N, ...): ``a``."""
        return a

    def reverse_sum(self, values):
        """Totals of the owned rows of per-particle partial sums: ``values``."""
        return values

    def sum_to_owners(self, full, F, T):
        """(F, T) of the coupled rows summed on their owners: (F, T) (``full``: the map of
        the coupled rows onto the table, not needed)."""
        return F, T

    def refresh(self, *arrays) -> None:
        """The owners' rows copied into the ghosts: there are none."""

    def allmin(self, *x):
        return tuple(float(v) for v in x)

    def gather(self, p, whole, everyone=False, extra=None):
        """The owned rows into the whole table: ``p`` is the whole table (nothing to do; the
        rigid bodies' state is the whole table's: None)."""
        return None

    def other_forces(self, forces, p, reduce):
        """(F, T) of the non-hydrodynamic forces of the owned rows: ``forces(p)``."""
        res = forces(p)
        return res[0], res[1]


TABLES = {"whole": WholeTable, "blocks": Owned}
