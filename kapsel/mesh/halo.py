"""Halo exchange of real-space blocks: the stencils of the finite-difference types on a
distributed grid (kapsel.mesh.pencil.PencilGrid: x split over px ranks, y over py, z
whole).

``Halo(grid, width).pad(a)`` returns the block ``a`` (..., nx, ny, nz) widened by ``width``
ghost layers on both sides of every split direction, filled from the periodic neighbour
ranks: x first (MPI_Sendrecv with the left and right ranks of the column, preallocated
contiguous buffers), then y on the x-widened array, so that the corner ghosts come along.
A direction held by one rank is not widened: the periodic kernels wrap it locally, so on
one process (kapsel.mesh.grid.Grid, px = py = 1) ``pad`` and ``keep`` are identities.

The stencil operators of the serial solvers (kapsel.mesh.stencils, kapsel.mesh.operators:
periodic by index wrap or shifted copies) then run unchanged on the padded block and
``interior`` keeps the block's points: a point within ``width`` of the block's edge sees the
neighbour's values where the serial run sees them, so for operators of reach <= width the
interior is computed by the same floating-point operations in the same order as in the
serial run (bit-identical values).  The ghost points themselves hold wrapped garbage and are
dropped.  Every operator of the MAC solver and of the Cahn-Hilliard solver has reach 1 (the
B-grid divergence and gradient, the central and compact differences, the cross terms of
the variable viscosity), composed operators are padded again in between.
"""
from __future__ import annotations

import time

import numpy as np

__all__ = ["Halo", "WholeFields"]


class WholeFields:
    """The halo of fields that are the whole periodic mesh, without a layout (an operator
    mixin used alone): ``pad`` and ``keep`` return the field, ``target`` the caller's
    array, ``work`` None (the kernels make their own scratch)."""

    trivial = True

    def pad(self, a, key="pad"):
        return a

    def target(self, out, lead=(), key="out"):
        return out

    def keep(self, a, out=None):
        return a

    def work(self, lead=(), key="work"):
        return None

    def interior(self, a):
        return a


class Halo:
    """Ghost layers of width ``width`` for the real-space blocks of ``grid`` (module
    docstring).  ``pad`` / ``interior`` / ``work``; buffers made once per (shape, key)."""

    def __init__(self, grid, width=1):
        self.grid = grid
        self.width = int(width)
        self.lshape = tuple(grid.local_shape)
        nx, ny, _ = self.lshape
        self.hx = self.width if grid.px > 1 else 0
        self.hy = self.width if grid.py > 1 else 0
        if (self.hx and nx < self.width) or (self.hy and ny < self.width):
            raise ValueError(f"a block of {nx} x {ny} points is thinner than the halo width "
                             f"{self.width}: use fewer ranks along x or y")
        self.pshape = (nx + 2 * self.hx, ny + 2 * self.hy, self.lshape[2])
        self._interior = (slice(self.hx, self.hx + nx), slice(self.hy, self.hy + ny),
                          slice(None))
        # neighbours: comm_x holds one column (rank = cx), comm_y one row (rank = cy)
        self.x_nb = ((grid.cx - 1) % grid.px, (grid.cx + 1) % grid.px)
        self.y_nb = ((grid.cy - 1) % grid.py, (grid.cy + 1) % grid.py)
        self._bufs = {}
        self._comm = {}
        self.exchanges = 0             # pad calls and their wall time (bench/bench_mpi.py)
        self.seconds = 0.0

    def work(self, lead=(), key="work"):
        """A padded scratch array (lead + pshape), made once per (lead, key)."""
        k = ("w", tuple(lead), key)
        b = self._bufs.get(k)
        if b is None:
            b = self._bufs[k] = np.empty(tuple(lead) + self.pshape)
        return b

    @property
    def trivial(self) -> bool:
        """No direction is split: ``pad`` returns the block itself (the kernels wrap)."""
        return not (self.hx or self.hy)

    def target(self, out, lead=(), key="out"):
        """Where a stencil on padded arrays writes a result meant for ``out`` (lead +
        block): ``out`` itself on a trivial halo (a new array for None), else a padded
        scratch of (lead, key); ``keep`` then gives the block's points."""
        if self.trivial:
            return np.empty(tuple(lead) + self.lshape) if out is None else out
        return self.work(lead, key)

    def keep(self, a, out=None):
        """The interior of ``a`` (from ``target``) in ``out`` (None: a new array); ``a``
        itself on a trivial halo."""
        if self.trivial:
            return a
        if out is None:
            return np.array(self.interior(a))
        out[...] = self.interior(a)
        return out

    def interior(self, a):
        """The view of a padded array's points that belong to this rank's block."""
        return a[(Ellipsis,) + self._interior]

    def pad(self, a, key="pad"):
        """``a`` (..., nx, ny, nz) widened by the ghost layers of the split directions, in a
        buffer kept per (leading shape, key) (overwritten by the next pad of that kind);
        ``a`` itself when no direction is split (read it, do not write it)."""
        lead = a.shape[:-3]
        if a.shape[-3:] != self.lshape:
            raise ValueError(f"pad: block of shape {a.shape[-3:]}, expected {self.lshape}")
        if not (self.hx or self.hy) and a.flags.c_contiguous and a.dtype == np.float64:
            return a                  # one rank: nothing to widen (the kernels wrap)
        t0 = time.perf_counter()
        P = self.work(lead, ("pad", key))
        self.interior(P)[...] = a
        self.exchanges += 1
        if self.hx:
            self._exchange(P, 0, lead)
        if self.hy:
            self._exchange(P, 1, lead)
        self.seconds += time.perf_counter() - t0
        return P

    def _buffers(self, P, axis, lead):
        k = (axis, lead)
        b = self._comm.get(k)
        if b is None:
            h = self.hx if axis == 0 else self.hy
            sh = list(P.shape)
            sh[len(lead) + axis] = h
            b = self._comm[k] = [np.empty(sh) for _ in range(4)]   # send lo/hi, recv lo/hi
        return b

    def _exchange(self, P, axis, lead):
        """Fill the ghost layers of P along ``axis`` (0: x over comm_x, 1: y over comm_y)
        from the neighbours' edge layers; y runs over the x-widened array (corners)."""
        g = self.grid
        h = self.hx if axis == 0 else self.hy
        n = self.lshape[axis]
        comm = g.comm_x if axis == 0 else g.comm_y
        lo_nb, hi_nb = self.x_nb if axis == 0 else self.y_nb
        ax = len(lead) + axis
        idx = [slice(None)] * P.ndim
        if axis == 0:                 # x first: the block's y range only
            idx[len(lead) + 1] = slice(self.hy, self.hy + self.lshape[1])

        def sl(a, b):
            i = list(idx)
            i[ax] = slice(a, b)
            return tuple(i)
        send_lo, send_hi, recv_lo, recv_hi = self._buffers(P, axis, lead) if axis == 1 else \
            self._xbuffers(P, lead)
        np.copyto(send_lo, P[sl(h, 2 * h)])              # my first layers -> lower rank
        np.copyto(send_hi, P[sl(n, n + h)])              # my last layers -> upper rank
        comm.Sendrecv(send_lo, dest=lo_nb, sendtag=1, recvbuf=recv_hi, source=hi_nb, recvtag=1)
        comm.Sendrecv(send_hi, dest=hi_nb, sendtag=2, recvbuf=recv_lo, source=lo_nb, recvtag=2)
        P[sl(n + h, n + 2 * h)] = recv_hi
        P[sl(0, h)] = recv_lo

    def _xbuffers(self, P, lead):
        k = ("x", lead)
        b = self._comm.get(k)
        if b is None:
            sh = list(P.shape)
            sh[len(lead)] = self.hx
            sh[len(lead) + 1] = self.lshape[1]
            b = self._comm[k] = [np.empty(sh) for _ in range(4)]
        return b
