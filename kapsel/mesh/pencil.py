"""Pencil-decomposed real-to-complex FFTs over MPI: the distributed ``kapsel.mesh.grid.Grid``.

Layout (fields indexed [x, y, z], z fastest, as in kapsel.mesh.grid), on a px x py process grid
(the original's ``-X px -Y py``; rank = cx py + cy):

    real space      (NX / px, NY / py, NZ)      x split over px, y over py, z whole
    Fourier space   (NX, NY / px, NZ//2+1 / py) x whole, y split over px, z split over py

(N / p: a block of the split, the first N mod p blocks one larger).  A forward transform is
an r2c FFT along z, a transpose within the py ranks of one row (z split, y whole), a c2c FFT
along y, a transpose within the px ranks of one column (y split, x whole) and a c2c FFT along
x; the backward transform runs the same way back.  The transposes are single
``MPI_Alltoallv`` calls on blocks packed by numpy (``_Transfer``), the local FFTs FFTW
plans (pyfftw) on buffers made once.  px = P, py = 1 is a slab decomposition (one transpose).

Why not mpi4py-fft: it builds its FFTW wrappers from source and needs the FFTW headers and
libraries of the system (``pip install mpi4py-fft`` stops with "No FFTW libraries found"
without Debian's libfftw3-dev), so it cannot install from PyPI alone, which ``make test`` on
a fresh machine requires; the pyFFTW wheels carry FFTW inside (as do no other PyPI parallel
FFT packages: pfft-python builds PFFT and FFTW from source with mpicc).  This module is the
same algorithm as mpi4py-fft's ``Pencil`` / ``Transfer`` (global transposes between pencil
orientations, local 1-d FFTs) in ~250 lines on mpi4py and pyfftw, both installed from
wheels.

The Fourier fields keep the serial axis order, so every whole-array operation of the
spectral solver (products with kx, ky, kz, k^2, the 2/3 mask, the ETD weights) runs on the
local block unchanged: the wavenumber arrays are the serial ones sliced to the block.
"""
from __future__ import annotations

import math

import numpy as np
import pyfftw

from . import wisdom
from .grid import Grid, auto_planner

__all__ = ["Gathered", "PencilDiagonal", "PencilGrid", "PencilScalarSolve", "block",
           "stencil_meets"]


class Gathered:
    """A value a distributed source already gathered to rank 0 (None on the others)."""

    def __init__(self, value):
        self.value = value


def block(n: int, parts: int, i: int) -> tuple[int, int]:
    """[start, stop) of block i when n points are split into ``parts`` blocks."""
    q, r = divmod(n, parts)
    start = i * q + min(i, r)
    return start, start + q + (1 if i < r else 0)


def _meets(start, width, blocks, n):
    """(N, len(blocks)) bool: the periodic interval [start, start + width) (N starts and
    widths) meets block [a0, a1) of ``blocks`` (k, 2)."""
    start = np.mod(start, n)[:, None]
    width = np.broadcast_to(width, start.shape[:1])[:, None]
    a0, a1 = blocks[None, :, 0], blocks[None, :, 1]
    return (width >= n) | (np.mod(a0 - start, n) < width) | (np.mod(start - a0, n) < a1 - a0)


def stencil_meets(s, lo, width, xblocks, yblocks, shape, image):
    """(N, kx, ky) bool: the stencil boxes of the particles at grid coordinates ``s``
    (N, >= 2: R / DX) on the rectangular grid under Lees-Edwards images meet the blocks
    xblocks (kx, 2) x yblocks (ky, 2).  A box spans [b + lo, b + lo + width) along x and y
    (b = floor(s)); its part beyond the y boundary (image k = +-1, ...: the floor division
    of the unwrapped y index by NY) lies at the x base floor(s_x - k image), ``image`` the
    x displacement of the image across y = Ly in grid units (g Ly / DX), as
    kapsel.particles.profile.lees_edwards_profiles places the points."""
    nx, ny = int(shape[0]), int(shape[1])
    s = np.asarray(s, dtype=float)
    with np.errstate(invalid="ignore"):
        by = np.floor(s[:, 1]).astype(np.int64)
    start = by + int(lo[1])
    end = start + int(width[1])
    out = np.zeros((len(s), len(xblocks), len(yblocks)), dtype=bool)
    ok = np.isfinite(s[:, 0]) & np.isfinite(s[:, 1])    # (NaN: caught by the run's checks)
    if not ok.any():
        return out
    for k in range(int(np.floor_divide(start[ok], ny).min()),
                   int(np.floor_divide(end[ok] - 1, ny).max()) + 1):
        a = np.maximum(start, k * ny)
        w = np.minimum(end, (k + 1) * ny) - a
        my = _meets(a, w, yblocks, ny) & (w > 0)[:, None]
        with np.errstate(invalid="ignore"):
            bq = np.floor(s[:, 0] - k * float(image)).astype(np.int64)
        mx = _meets(bq + int(lo[0]), int(width[0]), xblocks, nx)
        out |= mx[:, :, None] & my[:, None, :]
    return out


class _Transfer:
    """All-to-all within ``comm`` between two distributions of a (c, n0, n1, n2) array:
    ``whole`` axis complete and ``split`` axis local (A) <-> ``whole`` axis split and
    ``split`` axis complete (B).  Axes count the leading component axis.

    The blocks are packed into contiguous buffers by numpy and sent by one
    ``MPI_Alltoallv``: measured 1.7x faster than ``MPI_Alltoallw`` over subarray datatypes
    (mpi4py-fft's way) for a 64^3 vector field on 2 ranks (4.1-4.4 ms against 6.7-8.0 ms,
    MPICH 5 shared memory, busy 2-core machine)."""

    def __init__(self, comm, shape_a, shape_b, whole, split):
        self.comm = comm
        m = comm.Get_size()
        self.trivial = m == 1
        if self.trivial:
            return
        self.whole, self.split = whole, split
        self.wb = [block(shape_a[whole], m, j) for j in range(m)]   # blocks of A's whole axis
        self.sb = [block(shape_b[split], m, j) for j in range(m)]   # blocks of B's split axis
        na = int(np.prod(shape_a)) // shape_a[whole]
        nb = int(np.prod(shape_b)) // shape_b[split]
        self.ca = [na * (b - a) for a, b in self.wb]                 # A-side counts
        self.cb = [nb * (b - a) for a, b in self.sb]                 # B-side counts
        self.da = [sum(self.ca[:j]) for j in range(m)]
        self.db = [sum(self.cb[:j]) for j in range(m)]
        self.shape_a, self.shape_b = tuple(shape_a), tuple(shape_b)
        self.buf_a = np.empty(sum(self.ca), dtype=complex)
        self.buf_b = np.empty(sum(self.cb), dtype=complex)

    @staticmethod
    def _piece(shape, axis, ab):
        sh = list(shape)
        sh[axis] = ab[1] - ab[0]
        return tuple(sh)

    def _slices(self, axis, ab):
        idx = [slice(None)] * 4
        idx[axis] = slice(*ab)
        return tuple(idx)

    def forward(self, a, b):
        if self.trivial:          # one rank along this direction (e.g. -X1 -Y2)
            np.copyto(b, a)
            return
        self._exchange(a, b, (self.buf_a, self.ca, self.da, self.shape_a, self.whole, self.wb),
                       (self.buf_b, self.cb, self.db, self.shape_b, self.split, self.sb))

    def backward(self, b, a):
        if self.trivial:
            np.copyto(a, b)
            return
        self._exchange(b, a, (self.buf_b, self.cb, self.db, self.shape_b, self.split, self.sb),
                       (self.buf_a, self.ca, self.da, self.shape_a, self.whole, self.wb))

    def _exchange(self, src, dst, send, recv):
        """Pack the blocks of ``src`` (cut along the send side's axis), all-to-all, unpack
        into ``dst`` (along the receive side's axis).  ``send`` / ``recv``: (buffer, counts,
        displacements, local shape, axis, ranges)."""
        if self.trivial:
            np.copyto(dst, src)
            return
        sbuf, sc, sd, sshape, saxis, sranges = send
        rbuf, rc, rd, rshape, raxis, rranges = recv
        for j, ab in enumerate(sranges):
            sbuf[sd[j]:sd[j] + sc[j]].reshape(
                self._piece(sshape, saxis, ab))[...] = src[self._slices(saxis, ab)]
        self.comm.Alltoallv([sbuf, (sc, sd)], [rbuf, (rc, rd)])
        for j, ab in enumerate(rranges):
            dst[self._slices(raxis, ab)] = rbuf[rd[j]:rd[j] + rc[j]].reshape(
                self._piece(rshape, raxis, ab))


class _Pipeline:
    """Buffers, FFTW plans and transposes of the transforms of ``ncomp``-component fields."""

    def __init__(self, g: "PencilGrid", ncomp: int):
        with wisdom.planning((g.planner,)):   # every rank's plans from one wisdom file
            self._build(g, ncomp)

    def _build(self, g, ncomp):
        c = (ncomp,)
        nx, ny, nz = g.shape
        nzh = nz // 2 + 1
        (x0, x1), (y0, y1) = g.real_range[0], g.real_range[1]
        zc0, zc1 = g.spec_range[2]
        # fewer, larger local transforms where a transpose is trivial: one 3-d plan on one
        # rank, a 2-d (y, z) plan for slabs (Y = 1; FFTW's multi-dimensional plans are
        # faster than the same 1-d transforms in turn); only the buffers a mode uses
        self.mode = ("one" if g.px == 1 and g.py == 1 else "slab" if g.py == 1 else "pencil")
        empty = pyfftw.empty_aligned
        self.R = empty(c + g.local_shape, dtype="float64")
        self.C = empty(c + g.local_cshape, dtype="complex128")
        self.D = empty(c + g.local_cshape, dtype="complex128")
        flags = (g.planner,)
        F, Bk = "FFTW_FORWARD", "FFTW_BACKWARD"
        destroy = flags + ("FFTW_DESTROY_INPUT",)
        self._align = pyfftw.simd_alignment
        if self.mode == "one":
            self.f3 = pyfftw.FFTW(self.R, self.D, axes=(1, 2, 3), direction=F, flags=flags)
            self.b3 = pyfftw.FFTW(self.C, self.R, axes=(1, 2, 3), direction=Bk, flags=destroy)
            return
        self.B = empty(c + (x1 - x0, ny, zc1 - zc0), dtype="complex128")
        # out of place at the ends, so that the callers' aligned arrays are used directly
        self.fx = pyfftw.FFTW(self.C, self.D, axes=(1,), direction=F, flags=flags)
        self.bx = pyfftw.FFTW(self.D, self.C, axes=(1,), direction=Bk, flags=flags)
        self.tx = _Transfer(g.comm_x, self.B.shape, self.C.shape, 2, 1)
        if self.mode == "slab":
            self.fyz = pyfftw.FFTW(self.R, self.B, axes=(2, 3), direction=F, flags=flags)
            self.byz = pyfftw.FFTW(self.B, self.R, axes=(2, 3), direction=Bk, flags=destroy)
            return
        self.A = empty(c + (x1 - x0, y1 - y0, nzh), dtype="complex128")
        self.fz = pyfftw.FFTW(self.R, self.A, axes=(3,), direction=F, flags=flags)
        self.bz = pyfftw.FFTW(self.A, self.R, axes=(3,), direction=Bk, flags=destroy)
        self.fy = pyfftw.FFTW(self.B, self.B, axes=(2,), direction=F, flags=flags)
        self.by = pyfftw.FFTW(self.B, self.B, axes=(2,), direction=Bk, flags=flags)
        self.ty = _Transfer(g.comm_y, self.A.shape, self.B.shape, 3, 2)

    def _fits(self, x, like):
        return (x.shape == like.shape and x.dtype == like.dtype and x.strides == like.strides
                and x.ctypes.data % self._align == 0)

    def _input(self, a, buf):
        """``a`` when it has ``buf``'s layout (used in place), else ``buf`` holding a copy."""
        if self._fits(a, buf):
            return a
        np.copyto(buf, a)
        return buf

    def _run(self, plan, src, out, buf):
        """Execute ``plan`` from ``src`` into ``out`` (through ``buf`` when ``out`` does not
        have its layout); returns ``out``."""
        o = out if self._fits(out, buf) else buf
        plan.update_arrays(src, o)
        plan.execute()
        if o is not out:
            np.copyto(out, o)
        return out

    def forward(self, u, out):
        if self.mode == "one":
            return self._run(self.f3, self._input(u, self.R), out, self.D)
        if self.mode == "slab":
            self.fyz.update_arrays(self._input(u, self.R), self.B)
            self.fyz.execute()
            self.tx.forward(self.B, self.C)
            return self._run(self.fx, self.C, out, self.D)
        self.fz.update_arrays(self._input(u, self.R), self.A)
        self.fz.execute()
        self.ty.forward(self.A, self.B)
        self.fy.execute()
        self.tx.forward(self.B, self.C)
        return self._run(self.fx, self.C, out, self.D)

    def backward(self, c, out):
        """Unnormalised c2r of ``c`` (not modified) into ``out``."""
        if self.mode == "one":
            np.copyto(self.C, c)
            return self._run(self.b3, self.C, out, self.R)
        self.bx.update_arrays(self._input(c, self.D), self.C)
        self.bx.execute()
        self.tx.backward(self.C, self.B)
        if self.mode == "slab":
            return self._run(self.byz, self.B, out, self.R)
        self.by.execute()
        self.ty.backward(self.B, self.A)
        return self._run(self.bz, self.A, out, self.R)


class PencilScalarSolve:
    """``kapsel.mesh.grid.ScalarSolve`` on a distributed grid: this rank's block in ``rhs``, the
    symbol cut to this rank's Fourier block with the c2r's 1/N folded in (``symbol``), the
    pencil FFTs."""

    def __init__(self, grid):
        self.grid = grid
        self.rhs = grid.empty_real(1)[0]
        self._c = grid.empty_complex(1)
        self._o = grid.empty_real(1)

    def symbol(self, m):
        return m / self.grid.size

    def solve(self, m):
        g = self.grid
        g.forward(self.rhs[None], self._c)
        np.multiply(self._c[0], m, out=self._c[0])
        g.backward_raw(self._c, self._o)
        return self._o[0]


class PencilDiagonal:
    """``kapsel.mesh.linalg.FourierDiagonal`` on a distributed grid: v -> FFT^-1[m(k) FFT(v)] for
    v holding one or more fields of this rank's block (flattened), ``m`` on this rank's
    Fourier block (``local=True``) or on the whole half spectrum (NX, NY, NZ//2 + 1)."""

    def __init__(self, grid, m, local=False):
        self.grid = grid
        self.lshape = tuple(grid.local_shape)
        if not local:
            m = grid.local_complex(np.broadcast_to(m, grid.cshape))
        self.m = np.ascontiguousarray(np.broadcast_to(m, grid.local_cshape)) / grid.size
        self._c = {}

    def solve(self, v):
        g = self.grid
        v = np.asarray(v).reshape((-1,) + self.lshape)
        n = v.shape[0]
        c = self._c.get(n)
        if c is None:
            c = self._c[n] = (g.empty_complex(n), g.empty_real(n))
        ch, out = c
        g.forward(np.ascontiguousarray(v), ch)
        ch *= self.m
        g.backward_raw(ch, out)
        return out.reshape(-1).copy()


class PencilGrid(Grid):
    """``kapsel.mesh.grid.Grid`` distributed over ``comm`` on a px x py process grid (module
    docstring).  ``shape``, ``size``, ``box`` are global; arrays (``empty_real``,
    ``empty_complex``, ``kx`` ... ``dealias``) are this rank's blocks; ``forward`` /
    ``backward`` are collective (every rank calls them in the same order)."""

    whole_mesh = False

    def __init__(self, shape, dx, comm, dims, threads=1, planner="auto"):
        self.shape = tuple(int(n) for n in shape)
        self.dx = float(dx)
        self.threads = 1
        self.comm = comm
        self.px, self.py = (int(d) for d in dims)
        if self.px * self.py != comm.Get_size():
            raise ValueError(f"process grid {self.px} x {self.py} != {comm.Get_size()} ranks")
        nx, ny, nz = self.shape
        nzh = nz // 2 + 1
        if nx < self.px or ny < self.px or ny < self.py or nzh < self.py:
            raise ValueError(f"mesh {nx} x {ny} x {nz} is too small for a {self.px} x "
                             f"{self.py} process grid (NX, NY >= X; NY, NZ/2+1 >= Y)")
        rank = comm.Get_rank()
        self.rank, self.ranks, self.is_root = rank, comm.Get_size(), rank == 0
        self.cx, self.cy = divmod(rank, self.py)
        self.comm_x = comm.Split(self.cy, self.cx)     # one column: varying cx
        self.comm_y = comm.Split(self.cx, self.cy)     # one row: varying cy
        self.real_range = (block(nx, self.px, self.cx), block(ny, self.py, self.cy), (0, nz))
        self.spec_range = ((0, nx), block(ny, self.px, self.cx), block(nzh, self.py, self.cy))
        self.local_shape = tuple(b - a for a, b in self.real_range)
        self.local_cshape = tuple(b - a for a, b in self.spec_range)
        self.cshape = (nx, ny, nzh)
        self.size = nx * ny * nz
        self.box = np.array(self.shape, dtype=float) * self.dx
        self.volume = float(np.prod(self.box))
        self.k_max = math.pi / self.dx

        m = [np.fft.fftfreq(nx, 1.0 / nx), np.fft.fftfreq(ny, 1.0 / ny),
             np.fft.rfftfreq(nz, 1.0 / nz)]
        for mi, n in zip(m[:2], (nx, ny)):
            if n % 2 == 0:
                mi[n // 2] = n // 2
        m = [mi[a:b] for mi, (a, b) in zip(m, self.spec_range)]
        k = [2.0 * np.pi * mi / (n * self.dx) for mi, n in zip(m, self.shape)]
        self.kx = k[0].reshape(-1, 1, 1)
        self.ky = k[1].reshape(1, -1, 1)
        self.kz = k[2].reshape(1, 1, -1)
        self.k2 = self.kx ** 2 + self.ky ** 2 + self.kz ** 2
        self.inv_k2 = np.zeros(self.local_cshape)
        np.divide(1.0, self.k2, out=self.inv_k2, where=self.k2 > 0)
        self.trunc = tuple((n - 1) // 3 for n in self.shape)
        masks = [np.abs(mi) <= K for mi, K in zip(m, self.trunc)]
        self.dealias = (masks[0].reshape(-1, 1, 1) & masks[1].reshape(1, -1, 1)
                        & masks[2].reshape(1, 1, -1))
        self.dealias_f = self.dealias.astype(float)
        self.k_trunc = max(2.0 * np.pi * K / (n * self.dx) for K, n in zip(self.trunc, self.shape))
        z0, z1 = self.spec_range[2]
        w = np.full(nzh, 2.0)
        w[0] = 1.0
        if nz % 2 == 0:
            w[-1] = 1.0
        self.half_weight = w[z0:z1].reshape(1, 1, -1)
        # the k = 0 mode lives on the rank holding the first y and z blocks of Fourier space
        self.has_k0 = self.spec_range[1][0] == 0 and self.spec_range[2][0] == 0
        self.k0_rank = 0
        self.planner = auto_planner(self.size) if planner == "auto" else planner
        self.per_component = False
        self._pipes = {}
        self._ptmp = None
        self._real_buf = self._complex_buf = None
        self._vshape = (3,) + self.local_shape
        self._vcshape = (3,) + self.local_cshape

    # ------------------------------------------------------------------ arrays
    def empty_real(self, n=3):
        shape = self.local_shape if n is None else (n,) + self.local_shape
        return pyfftw.empty_aligned(shape, dtype="float64")

    def empty_complex(self, n=3):
        shape = self.local_cshape if n is None else (n,) + self.local_cshape
        return pyfftw.empty_aligned(shape, dtype="complex128")

    def coordinates(self):
        (x0, x1), (y0, y1), (_, nz) = self.real_range
        return (np.arange(x0, x1).reshape(-1, 1, 1) * self.dx,
                np.arange(y0, y1).reshape(1, -1, 1) * self.dx,
                np.arange(nz).reshape(1, 1, -1) * self.dx)

    # ------------------------------------------------------------------ FFT
    def _pipe(self, n):
        p = self._pipes.get(n)
        if p is None:
            p = self._pipes[n] = _Pipeline(self, n)
        return p

    def forward(self, u=None, out=None):
        u = self.real_buf if u is None else u
        out = self.complex_buf if out is None else out
        return self._pipe(u.shape[0]).forward(u, out)

    def backward_raw(self, c, out=None):
        out = self.real_buf if out is None else out
        return self._pipe(c.shape[0]).backward(c, out)

    def rfft_scalar(self, f, out=None):
        if out is None:
            out = self.empty_complex(None)
        self._pipe(1).forward(f[None], out[None])
        return out

    def backward_scalar_raw(self, c, out):
        """Unnormalised c2r of this rank's scalar block ``c`` -> ``out`` (``Grid``'s)."""
        self._pipe(1).backward(c[None], out[None])
        return out

    # the truncated transforms: a rank's pipeline makes the whole ones (the same numbers on
    # the mask; a serial run's skipped lines are 0 there).  Each rank chooses between the
    # whole and the truncated form from its own block (SpectralNS.velocity and the oblique
    # one): both must stay the same collective, as they are here.
    def backward_scalar_truncated(self, c, out):
        return self.backward_scalar_raw(c, out)

    def rfft_scalar_truncated(self, f, out):
        return self.rfft_scalar(f, out)

    def forward_truncated(self, u, out):
        return self.forward(u, out)

    def backward_truncated(self, c, out):
        return self.backward_raw(c, out)

    def irfft_scalar(self, f_hat, out=None):
        if out is None:
            out = self.empty_real(None)
        c = np.multiply(f_hat, 1.0 / self.size)
        self._pipe(1).backward(c[None], out[None])
        return out

    # ------------------------------------------------------------------ gather / scatter
    def k0(self, a_hat):
        """a_hat[:, 0, 0, 0] (the k = 0 mode) of a local (c, ...) Fourier array, on every rank."""
        v = a_hat[:, 0, 0, 0].copy() if self.has_k0 else None
        owner = self.comm.allreduce(self.comm.Get_rank() if self.has_k0 else -1, op=_max())
        return self.comm.bcast(v, root=owner)

    def sum(self, x) -> float:
        """Sum over the ranks of a local float, in rank order (the same on every rank)."""
        return float(sum(self.comm.allgather(float(x))))

    def sums(self, values) -> list:
        """Sums over the ranks of several local floats in one collective (an MPI_Allgather
        of them), each added in rank order: the same bits on every rank, run after run."""
        v = np.asarray(values, dtype=float).reshape(-1)
        buf = np.empty((self.comm.Get_size(), v.size))
        self.comm.Allgather(v, buf)
        return [float(sum(col)) for col in buf.T.tolist()]

    # the particle table of this layout (kapsel.particles.ownership.TABLES): the particles
    # owned by the ranks' blocks, with their ghosts
    particle_table = "blocks"

    def near_rows(self, R, offsets, dx, strain=0.0, origin=0.0, images=0.0):
        """The rows of the particles at ``R`` whose stencil (``offsets``, (S, 3) grid
        steps) meets this rank's block (x and y are split; an oblique frame of ``strain``
        about the height ``origin`` shears x; ``images`` != 0: the rectangular grid under
        Lees-Edwards images displaced by ``images`` along x, ``stencil_meets``)."""
        s = np.asarray(R, dtype=float) / dx
        if images:
            lo = offsets[:, :2].min(axis=0)
            width = offsets[:, :2].max(axis=0) - lo + 1
            blocks = [np.array([r]) for r in self.real_range[:2]]
            near = stencil_meets(s, lo, width, blocks[0], blocks[1], self.shape,
                                 float(images) / dx)
            return np.flatnonzero(near[:, 0, 0])
        if strain:
            s[:, 0] = (R[:, 0] - strain * (R[:, 1] - origin)) / dx
        with np.errstate(invalid="ignore"):
            b = np.floor(s).astype(np.int64)
        near = np.ones(len(s), dtype=bool)
        for axis in (0, 1):
            n = self.shape[axis]
            a0, a1 = self.real_range[axis]
            o = offsets[:, axis]
            lo, width = int(o.min()), int(o.max() - o.min()) + 1
            start = np.mod(b[:, axis] + lo, n)
            if width < n:
                near &= (np.mod(a0 - start, n) < width) | (np.mod(start - a0, n) < a1 - a0)
        return np.flatnonzero(near)

    def cut_stencils(self, idx, phi):
        """Stencils cut to this rank's block: (idx, phi, on) with ``idx`` flat indices into
        the local block (0 off the block), ``phi`` 0 off the block (so every sum over
        stencil points is this rank's part of it), ``on`` (N, S) the points on the block."""
        nx, ny, nz = self.shape
        (x0, x1), (y0, y1), _ = self.real_range
        ix, rest = np.divmod(idx, ny * nz)
        iy, iz = np.divmod(rest, nz)
        ix -= x0
        iy -= y0
        on = (ix >= 0) & (ix < x1 - x0) & (iy >= 0) & (iy < y1 - y0)
        ix *= (y1 - y0)
        ix += iy
        ix *= nz
        ix += iz
        return np.where(on, ix, 0), np.where(on, phi, 0.0), on

    def reduce(self, *arrays):
        """Sums over the ranks of per-particle arrays, the same bits on every rank (MPI
        Reduce to rank 0 in MPI's fixed order for this number of ranks, then Bcast)."""
        from mpi4py import MPI
        buf = np.concatenate([np.asarray(a, dtype=float).reshape(-1) for a in arrays])
        out = np.empty_like(buf)
        self.comm.Reduce(buf, out, op=MPI.SUM, root=0)
        self.comm.Bcast(out, root=0)
        res, i = [], 0
        for a in arrays:
            a = np.asarray(a)
            res.append(out[i:i + a.size].reshape(a.shape))
            i += a.size
        return tuple(res)

    def dots(self, *pairs) -> list:
        """The dot products a.b of pairs of local blocks, summed over the ranks (``sums``):
        the Krylov solver's (kapsel.mesh.linalg.bicgstab_dot)."""
        return self.sums([float(np.dot(a, b)) for a, b in pairs])

    def scalar_solver(self, threads=1, backend=None):
        return PencilScalarSolve(self)

    def fourier_diagonal(self, m, threads=1):
        """``PencilDiagonal`` of the symbol ``m`` on this rank's Fourier block."""
        return PencilDiagonal(self, m, local=True)

    def max(self, x) -> float:
        """Max over the ranks of a local float (NaN counts as infinity)."""
        x = float(x)
        return float(self.comm.allreduce(math.inf if x != x else x, op=_max()))

    def gather_real(self, a, root=0):
        """The global (..., NX, NY, NZ) field of local blocks ``a`` on ``root`` (else None)."""
        parts = self.comm.gather((self.real_range, np.ascontiguousarray(a)), root=root)
        if parts is None:
            return None
        out = np.empty(a.shape[:-3] + self.shape, dtype=a.dtype)
        for (xr, yr, _), blk in parts:
            out[..., xr[0]:xr[1], yr[0]:yr[1], :] = blk
        return out

    def gather_complex(self, a, root=0):
        """The global (..., NX, NY, NZ//2+1) Fourier field of local blocks ``a`` on ``root``."""
        parts = self.comm.gather((self.spec_range, np.ascontiguousarray(a)), root=root)
        if parts is None:
            return None
        out = np.empty(a.shape[:-3] + self.cshape, dtype=a.dtype)
        for (_, yr, zr), blk in parts:
            out[..., :, yr[0]:yr[1], zr[0]:zr[1]] = blk
        return out

    def gather_rows(self, f):
        """The whole x rows of this rank's y range: the blocks of ``f`` (..., nx, ny, nz)
        of the ranks of this column (comm_x), joined along x."""
        parts = self.comm_x.allgather(np.ascontiguousarray(f))
        return np.concatenate(parts, axis=f.ndim - 3)

    def to_rectangular(self, f, g, method="linear", origin=0.0, out=None):
        """This rank's block of a field (c, NX, NY, NZ) of the oblique grid of strain g
        re-gridded onto the rectangular grid: kapsel.mesh.regrid.to_rectangular of the
        whole field, cut to the block (the same bits).  The x shift of a row needs the whole
        row: each component's blocks of this rank's column (comm_x) are gathered along x
        (one (NX, NY / py, NZ) slab at a time), shifted and cut to the block again."""
        return self._shift_rows(f, g * (np.arange(self.shape[1]) - origin), method, out)

    def to_oblique(self, f, g, method="linear", origin=0.0, out=None):
        """The inverse re-gridding, rectangular -> oblique (kapsel.mesh.regrid.to_oblique),
        as ``to_rectangular``."""
        return self._shift_rows(f, -g * (np.arange(self.shape[1]) - origin), method, out)

    def _shift_rows(self, f, shift, method, out=None):
        """``out`` (not ``f``): the block written there, a component at a time."""
        from .regrid import shift_rows
        f = np.asarray(f, dtype=float)
        if f.ndim == 4:
            if out is None:
                return np.stack([self._shift_rows(c, shift, method) for c in f])
            for c in range(f.shape[0]):
                self._shift_rows(f[c], shift, method, out[c])
            return out
        (x0, x1), (y0, y1), _ = self.real_range
        return shift_rows(self._x_rows(f), shift[y0:y1], method, rows=slice(x0, x1), out=out)

    def _x_rows(self, f):
        """The whole x rows (NX, NY / py, NZ) of this rank's column of a scalar block ``f``:
        x is the leading axis, so the column's blocks in rank (x) order are one contiguous
        array, filled by one MPI_Allgatherv (``gather_rows`` without the pickling)."""
        from mpi4py import MPI
        c = self.comm_x
        if c.Get_size() == 1:
            return f
        if self._rows_layout is None:
            plane = f.shape[1] * f.shape[2]
            counts = [(b - a) * plane for a, b in
                      (block(self.shape[0], self.px, j) for j in range(self.px))]
            displ = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int).tolist()
            self._rows_layout = (counts, displ)
        rows = np.empty((self.shape[0],) + f.shape[1:])
        c.Allgatherv(np.ascontiguousarray(f), [rows, self._rows_layout, MPI.DOUBLE])
        return rows

    _rows_layout = None

    def local_complex(self, a):
        """This rank's block of a global Fourier field (every rank holds ``a``)."""
        (_, _), (y0, y1), (z0, z1) = self.spec_range
        return a[..., :, y0:y1, z0:z1]

    def local_real(self, a):
        (x0, x1), (y0, y1), _ = self.real_range
        return a[..., x0:x1, y0:y1, :]

    def __repr__(self):
        return (f"PencilGrid(shape={self.shape}, dx={self.dx}, ranks={self.px} x {self.py}, "
                f"rank ({self.cx}, {self.cy}))")


def _max():
    from mpi4py import MPI
    return MPI.MAX
