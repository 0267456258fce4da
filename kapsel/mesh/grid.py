"""Periodic mesh, wavenumbers and FFT plans of the pseudo-spectral solver.

Fields are float64 arrays indexed [x, y, z] (C order, z fastest) of shape (NX, NY, NZ);
vector fields (3, NX, NY, NZ).  Grid point (i, j, k) is at (i DX, j DX, k DX); the box is
L = N DX per axis.  Fourier fields are rfftn over the last axis: shape (NX, NY, NZ//2 + 1),
vector fields (3, NX, NY, NZ//2 + 1).

Normalisation (numpy's): ``forward`` is unnormalised, u_hat(k) = sum_x u(x) e^{-i k.x}, so
the k = 0 mode is sum_x u = N u_mean; ``backward`` divides by N = NX NY NZ, so that
``backward(forward(u)) == u``.

FFT plans: one scalar pyfftw.FFTW plan per direction, applied to each component of the
aligned (3, ...) buffers (``per_component``; bit-identical to one batched (3, N, N, N) plan,
3-10 % faster per spectral step at 32^3-64^3 in A/B runs on the shared machine, and cheaper
to plan with FFTW_MEASURE), built once per Grid (FFTW keeps its wisdom for the process, so a
second Grid of the same shape plans at once), on first use: a grid that is never
transformed (``kapsel-py --check``) plans nothing.  A batched plan is used when a component of
the buffers would not be SIMD-aligned (odd sizes).  FFTW_MEASURE against
FFTW_ESTIMATE, measured on the shared 2-core machine (3 components, forward + backward,
1 thread, the two plans timed interleaved; bench/bench_spectral.py --planners):

    32^3:   MEASURE 0.31 ms / pair, plan 0.2 s;  ESTIMATE 0.29 ms, plan < 0.01 s
    64^3:   MEASURE 5.8 ms / pair,  plan 0.4 s;  ESTIMATE 6.2 ms,  plan 0.05 s
    128^3:  MEASURE 99 ms / pair,   plan 2.9 s;  ESTIMATE 129 ms,  plan 0.6 s
    (an earlier quieter measurement: 128^3 MEASURE 70 ms, ESTIMATE 118 ms)

Equal up to 64^3, MEASURE 25-40 % faster at 128^3 for a ~3 s plan that a run repays within
~100 steps (a step is 9 component transforms).  But MEASURE picks its algorithm by timing,
so two processes may get different plans and results that differ at round-off (seen at
64^3: 2 hashes of u_hat after 3 steps in 3 runs; ESTIMATE always gave the same).  Hence the
default ``planner='auto'``: FFTW_ESTIMATE (deterministic, no planning cost) up to 64^3 =
262144 points, FFTW_MEASURE above, its plans kept on disk (kapsel.mesh.wisdom: measured
once per machine and shape, then the same plan, and so the same bits, in every process;
where no wisdom file can be kept, not bitwise reproducible across processes).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from . import wisdom

try:  # pragma: no cover - import guard
    import pyfftw
except ImportError:  # pragma: no cover
    pyfftw = None

__all__ = ["FourierDiagonal", "Grid", "LazyPlan", "ScalarSolve"]


class LazyPlan:
    """A pyfftw.FFTW plan of ``a`` -> ``b`` made on its first use, on scratch arrays of the
    same layout (FFTW_MEASURE overwrites the arrays it plans with) and then pointed at ``a``
    and ``b``: an object that is built but never transforms (``kapsel-py --check``) costs
    no planning.  ``execute()``, ``update_arrays(a, b)`` and ``__call__()`` as pyfftw's."""

    def __init__(self, a, b, **kwargs):
        self.a, self.b, self.kwargs = a, b, kwargs
        self._plan = None

    @property
    def plan(self):
        if self._plan is None:
            sa = pyfftw.empty_aligned(self.a.shape, dtype=self.a.dtype)
            sb = pyfftw.empty_aligned(self.b.shape, dtype=self.b.dtype)
            with wisdom.planning(self.kwargs.get("flags", ())):
                self._plan = pyfftw.FFTW(sa, sb, **self.kwargs)
            self._plan.update_arrays(self.a, self.b)
            self.a = self.b = None
        return self._plan

    def execute(self):
        self.plan.execute()

    def update_arrays(self, a, b):
        self.plan.update_arrays(a, b)

    def __call__(self, *args, **kwargs):
        return self.plan(*args, **kwargs)



def auto_planner(size: int, threads: int = 1) -> str:
    """The FFTW planner of 'auto': FFTW_ESTIMATE (deterministic across processes, no planning
    cost, and the same bits as a distributed run's transforms) for one thread up to 64^3
    points, FFTW_MEASURE above or with threads: ESTIMATE's threaded plans are slow
    (measured 2026-11-29, idle 2-core VM, r2c of 64^3: 1 thread 0.79 ms, 2 threads 1.76 ms
    ESTIMATE / 0.54 ms MEASURE; 128^3: 12.6 / 6.3 / 5.3 ms).  Measured plans are kept on
    disk (kapsel.mesh.wisdom), so every process takes the same ones.  Measured plans at 64^3
    (MEASURE, PATIENT) made the step 3-7 % faster but gave other bits than the distributed
    run's transforms (tests/distributed: a serial run and its 2-rank run agree bit for bit
    with ESTIMATE), 2026-12-05."""
    return "FFTW_MEASURE" if size > Grid.MEASURE_ABOVE or threads > 1 else "FFTW_ESTIMATE"


class ScalarSolve:
    """f -> FFT^-1[m(k) FFT(f)] of one scalar field of the whole mesh: write f into ``rhs``,
    call ``solve(m)`` with ``m = symbol(...)`` on the half spectrum (NX, NY, NZ//2 + 1);
    returns an internal buffer.  pyfftw plans made on first use (pyfftw normalises the
    inverse, so the symbol is taken as is), or scipy.fft (``backend='scipy'``)."""

    def __init__(self, shape, threads=1, backend="pyfftw"):
        self.shape = tuple(shape)
        self.threads = int(threads)
        self.backend = backend if (backend != "pyfftw" or pyfftw is not None) else "scipy"
        if self.backend == "pyfftw":
            cshape = self.shape[:2] + (self.shape[2] // 2 + 1,)
            self._r = pyfftw.empty_aligned(self.shape, dtype="float64")
            self._c = pyfftw.empty_aligned(cshape, dtype="complex128")
            self._o = pyfftw.empty_aligned(self.shape, dtype="float64")
            flags = (auto_planner(int(np.prod(self.shape)), self.threads),)
            self._fwd = LazyPlan(self._r, self._c, axes=(0, 1, 2), direction="FFTW_FORWARD",
                                 flags=flags, threads=self.threads)
            self._bwd = LazyPlan(self._c, self._o, axes=(0, 1, 2), direction="FFTW_BACKWARD",
                                 flags=flags + ("FFTW_DESTROY_INPUT",), threads=self.threads)
            self.rhs = self._r
        else:
            self.rhs = np.empty(self.shape)

    @staticmethod
    def symbol(m):
        """``m`` as ``solve`` takes it (the transform pair normalises itself)."""
        return m

    def solve(self, m):
        if self.backend == "pyfftw":
            self._fwd()
            np.multiply(self._c, m, out=self._c)
            self._bwd()             # normalised by pyfftw
            return self._o
        import scipy.fft
        c = scipy.fft.rfftn(self.rhs, workers=self.threads)
        c *= m
        return scipy.fft.irfftn(c, s=self.shape, workers=self.threads)


class FourierDiagonal:
    """v -> FFT^-1[m(k) FFT(v)] for v holding one or more periodic scalar fields of ``shape``
    (flattened), with pyfftw plans made once (FFTW_ESTIMATE up to 64^3 points, MEASURE
    above, as Grid): the FFT preconditioners of the implicit solves.  ``m`` is given
    on the rfftn half spectrum (NX, NY, NZ//2 + 1).  4-5x faster than scipy.fft's rfftn /
    irfftn pair at 64^3 (measured in the Cahn-Hilliard preconditioner: 9.4 -> ~2 ms)."""

    def __init__(self, shape, m, threads=1):
        self.shape = tuple(int(n) for n in shape)
        size = int(np.prod(self.shape))
        cshape = self.shape[:2] + (self.shape[2] // 2 + 1,)
        self.m = np.ascontiguousarray(np.broadcast_to(m, cshape) / size)   # c2r's 1/N folded in
        self._r = pyfftw.empty_aligned(self.shape, dtype="float64")
        self._c = pyfftw.empty_aligned(cshape, dtype="complex128")
        flags = (auto_planner(size, threads),)
        self._fwd = LazyPlan(self._r, self._c, axes=(0, 1, 2), direction="FFTW_FORWARD",
                                flags=flags, threads=threads)
        self._bwd = LazyPlan(self._c, self._r, axes=(0, 1, 2), direction="FFTW_BACKWARD",
                                flags=flags + ("FFTW_DESTROY_INPUT",), threads=threads)

    def solve(self, v):
        v = np.asarray(v).reshape((-1,) + self.shape)
        out = np.empty(v.shape)
        for c in range(v.shape[0]):
            self._r[...] = v[c]
            self._fwd.execute()
            self._c *= self.m
            self._bwd.execute()
            out[c] = self._r
        return out.reshape(-1)


def _aligned_zeros(shape, dtype, align: int) -> np.ndarray:
    """A zeroed array aligned to ``align`` bytes, from np.zeros (calloc: large blocks come
    as untouched zero pages, so memory is taken only where the array is written)."""
    dtype = np.dtype(dtype)
    nbytes = int(np.prod(shape)) * dtype.itemsize
    buf = np.zeros(nbytes + align, dtype=np.uint8)
    off = (-buf.ctypes.data) % align
    return buf[off:off + nbytes].view(dtype).reshape(shape)


class Grid:
    """Mesh of shape (NX, NY, NZ) with spacing ``dx``, its wavenumbers and FFT plans; the
    layout of a run on one process (kapsel.mesh.pencil.PencilGrid: over MPI ranks),
    whose sums, maxima, gathers and local blocks are identities.

    Attributes
    ----------
    shape, cshape : real and complex (rfftn) field shapes
    size : NX NY NZ;  box : (Lx, Ly, Lz) = N DX
    kx, ky, kz : wavenumbers 2 pi m / L, broadcastable (NX,1,1), (1,NY,1), (1,1,NZ//2+1)
    k2 : |k|^2 (cshape);  inv_k2 : 1/|k|^2 with 0 at k = 0
    dealias : 2/3-rule mask (cshape, bool): keeps |m_a| <= (N_a - 1) // 3 on every axis
        (``dealias_f``: the same as float 0/1)
    k_max : pi / DX, the Nyquist wavenumber;  k_trunc : largest
        wavenumber along one axis kept by the 2/3 rule
    volume : Lx Ly Lz
    """

    MEASURE_ABOVE = 64 ** 3

    # the layout of one process (PencilGrid: this rank's place in the process grid)
    rank, ranks, is_root = 0, 1, True
    px = py = 1
    cx = cy = 0
    has_k0 = True
    whole_mesh = True   # the arrays are the whole periodic mesh (not a pipeline's blocks)
    dots = None         # Krylov dot products over the ranks; None: of the whole vectors

    def __init__(self, shape, dx=1.0, threads=1, planner="auto"):
        """``planner``: an FFTW planner flag, or 'auto' (module docstring): ESTIMATE up to
        64^3 points, MEASURE above."""
        self.shape = tuple(int(n) for n in shape)
        if len(self.shape) != 3 or min(self.shape) < 1:
            raise ValueError(f"shape must be (NX, NY, NZ), got {shape!r}")
        self.dx = float(dx)
        if not self.dx > 0:
            raise ValueError("dx must be positive")
        self.threads = max(1, int(threads))
        nx, ny, nz = self.shape
        self.cshape = (nx, ny, nz // 2 + 1)
        # this process's part of the fields: all of them (kapsel.mesh.pencil: a block)
        self.local_shape, self.local_cshape = self.shape, self.cshape
        self.real_range = tuple((0, n) for n in self.shape)
        self.spec_range = tuple((0, n) for n in self.cshape)
        self.size = nx * ny * nz
        self.box = np.array(self.shape, dtype=float) * self.dx

        # mode numbers 0..N/2, then negative: the N/2 (Nyquist) mode counted positive, as
        # the original does (its derivatives and projection, and the restart's Zeta packing)
        m = [np.fft.fftfreq(nx, 1.0 / nx), np.fft.fftfreq(ny, 1.0 / ny),
             np.fft.rfftfreq(nz, 1.0 / nz)]
        for mi, n in zip(m[:2], (nx, ny)):
            if n % 2 == 0:
                mi[n // 2] = n // 2
        k = [2.0 * np.pi * mi / (n * self.dx) for mi, n in zip(m, self.shape)]
        self.kx = k[0].reshape(-1, 1, 1)
        self.ky = k[1].reshape(1, -1, 1)
        self.kz = k[2].reshape(1, 1, -1)
        # 2/3 rule: a product of modes |m| <= K does not alias back onto |m| <= K iff 3K < N
        self.trunc = tuple((n - 1) // 3 for n in self.shape)
        self._modes = m
        self.k_trunc = max(2.0 * np.pi * K / (n * self.dx) for K, n in zip(self.trunc, self.shape))
        self.k_max = math.pi / self.dx
        self.volume = float(np.prod(self.box))

        # rfft weights for Parseval sums over the half spectrum
        w = np.full(self.cshape[2], 2.0)
        w[0] = 1.0
        if nz % 2 == 0:
            w[-1] = 1.0
        self.half_weight = w.reshape(1, 1, -1)

        if planner == "auto":
            planner = auto_planner(self.size, self.threads)
        self.planner = planner
        self._sfwd = self._sbwd = None
        self._fwd = self._bwd = None
        self._ptmp = None
        self._plans()

    # full-size wavenumber arrays, made on first use (a grid built for ``kapsel-py --check``
    # never needs them)
    @functools.cached_property
    def k2(self):
        return self.kx ** 2 + self.ky ** 2 + self.kz ** 2

    @functools.cached_property
    def k_axes(self):
        """(kx, ky, kz) as contiguous 1-d arrays: the wavenumbers the compiled kernels take."""
        return tuple(np.ascontiguousarray(k.ravel()) for k in (self.kx, self.ky, self.kz))

    @functools.cached_property
    def inv_k2(self):
        out = np.zeros(self.cshape)
        np.divide(1.0, self.k2, out=out, where=self.k2 > 0)
        return out

    @functools.cached_property
    def dealias(self):
        masks = [np.abs(mi) <= K for mi, K in zip(self._modes, self.trunc)]
        return (masks[0].reshape(-1, 1, 1) & masks[1].reshape(1, -1, 1)
                & masks[2].reshape(1, 1, -1))

    @functools.cached_property
    def dealias_f(self):
        return self.dealias.astype(float)

    @functools.cached_property
    def dealias_box(self):
        """The 2/3 mask of this block as a box, for the compiled passes that skip the rows
        off it: (mx, my, kz_end), the mask being mx[i] my[j] (floats 0 or 1) for
        k < kz_end and 0 beyond (m_z >= 0 runs up from the block's first z: a prefix of
        it is kept)."""
        d = self.dealias
        mx, my, mz = d.any(axis=(1, 2)), d.any(axis=(0, 2)), d.any(axis=(0, 1))
        kz_end = int(mz.sum())
        if not (mz[:kz_end].all() and np.array_equal(
                d, mx[:, None, None] & my[None, :, None] & mz[None, None, :])):
            raise AssertionError("the 2/3 mask is not a box with a prefix along z")
        return (np.ascontiguousarray(mx, dtype=float), np.ascontiguousarray(my, dtype=float),
                kz_end)

    # ------------------------------------------------------------------ FFT
    def _plans(self):
        vshape, vcshape = (3,) + self.shape, (3,) + self.cshape
        self._vshape, self._vcshape = vshape, vcshape
        self._align = pyfftw.simd_alignment if pyfftw is not None else 1
        self._real_buf = self._complex_buf = None
        if pyfftw is None:  # pragma: no cover
            self.per_component = False
            return
        # per-component plans when every component of an aligned (3, ...) buffer is aligned
        # too (the scalar plans are made for aligned arrays); else one batched plan
        a = self._align
        self.per_component = (self.size * 8) % a == 0 and (int(np.prod(self.cshape)) * 16) % a == 0
        # the plans are made on first use (``_scalar_plans`` / ``_batched_plans``): a grid
        # that never transforms (``kapsel-py --check``) costs no planning

    @property
    def real_buf(self):
        """Aligned (3, NX, NY, NZ) scratch (zeroed), made on first use: the per-component
        plans work on the callers' aligned arrays and never need it (48 bytes per grid point
        with ``complex_buf``)."""
        if self._real_buf is None:
            self._real_buf = self.empty_real()
            self._real_buf[...] = 0.0
        return self._real_buf

    @property
    def complex_buf(self):
        """Aligned (3, cshape) complex scratch (zeroed), made on first use."""
        if self._complex_buf is None:
            self._complex_buf = self.empty_complex()
            self._complex_buf[...] = 0.0
        return self._complex_buf

    def _batched_plans(self):
        """One FFTW plan over the last three axes of the (3, ...) buffers."""
        if self._fwd is not None:
            return
        flags = (self.planner,)
        axes = (1, 2, 3)
        with wisdom.planning(flags):
            self._fwd = pyfftw.FFTW(self.real_buf, self.complex_buf, axes=axes,
                                    direction="FFTW_FORWARD", flags=flags, threads=self.threads)
            self._bwd = pyfftw.FFTW(self.complex_buf, self.real_buf, axes=axes,
                                    direction="FFTW_BACKWARD",
                                    flags=flags + ("FFTW_DESTROY_INPUT",), threads=self.threads)

    def _aligned(self, a, shape, dtype):
        return (a.shape == shape and a.dtype == dtype and a.flags.c_contiguous
                and a.ctypes.data % self._align == 0)

    def forward(self, u=None, out=None):
        """u_hat = sum_x u e^{-ik.x} of a vector field (3, NX, NY, NZ) -> (3, cshape).

        ``u`` is not modified; ``u=None`` transforms what the caller wrote into
        ``real_buf``.  The result goes into ``out`` (returned); ``out=None`` returns the
        internal ``complex_buf``, valid until the next transform.  SIMD-aligned contiguous
        ``u`` / ``out`` (``empty_real`` / ``empty_complex``) are used in place, others copied.
        """
        u = self.real_buf if u is None else u
        out = self.complex_buf if out is None else out
        if pyfftw is None:  # pragma: no cover
            out[...] = np.fft.rfftn(u, axes=(1, 2, 3))
            return out
        ui = u if self._aligned(u, self._vshape, np.float64) else None
        if ui is None:
            np.copyto(self.real_buf, u)
            ui = self.real_buf
        oi = out if self._aligned(out, self._vcshape, np.complex128) else self.complex_buf
        if self.per_component:
            if self._sfwd is None:
                self._scalar_plans()
            for c in range(3):
                self._sfwd.update_arrays(ui[c], oi[c])
                self._sfwd.execute()
        else:
            self._batched_plans()
            self._fwd.update_arrays(ui, oi)
            self._fwd.execute()
        if oi is not out:
            np.copyto(out, oi)
        return out

    def backward(self, u_hat=None, out=None, scale=1.0):
        """u = (scale/N) sum_k u_hat e^{ik.x} -> (3, NX, NY, NZ); ``u_hat`` is preserved.

        ``u_hat=None`` transforms what the caller wrote into ``complex_buf``, which must then
        already include the factor scale/N.  ``out=None`` returns the internal ``real_buf``,
        valid until the next transform.
        """
        if u_hat is not None:
            np.multiply(u_hat, scale / self.size, out=self.complex_buf)
        return self.backward_raw(self.complex_buf, out)

    def backward_raw(self, c, out=None):
        """Unnormalised c2r transform sum_k c e^{ik.x} of (3, cshape) ``c`` -> ``out``.

        Destroys ``c`` (FFTW c2r).  The hot path: callers fold 1/N into the coefficients
        that produce ``c``.
        """
        out = self.real_buf if out is None else out
        if pyfftw is None:  # pragma: no cover
            out[...] = np.fft.irfftn(c, s=self.shape, axes=(1, 2, 3)) * self.size
            return out
        ci = c if self._aligned(c, self._vcshape, np.complex128) else None
        if ci is None:
            np.copyto(self.complex_buf, c)
            ci = self.complex_buf
        oi = out if self._aligned(out, self._vshape, np.float64) else self.real_buf
        if self.per_component:
            if self._sbwd is None:
                self._scalar_plans()
            for c in range(3):
                self._sbwd.update_arrays(ci[c], oi[c])
                self._sbwd.execute()
        else:
            self._batched_plans()
            self._bwd.update_arrays(ci, oi)
            self._bwd.execute()
        if oi is not out:
            np.copyto(out, oi)
        return out

    # public names (normalised pair: irfft(rfft(f)) == f; inputs preserved)
    def rfft(self, real_vec, out=None):
        """rfftn of a vector field (3, NX, NY, NZ) -> (3, cshape), unnormalised (k = 0 mode =
        sum_x u).  ``out=None`` returns a new aligned array."""
        if out is None:
            out = self.empty_complex()
        return self.forward(real_vec, out=out)

    def irfft(self, complex_vec, out=None):
        """Inverse of ``rfft`` (divides by N): (3, cshape) -> (3, NX, NY, NZ), input kept.
        ``out=None`` returns a new aligned array."""
        if out is None:
            out = self.empty_real()
        return self.backward(complex_vec, out=out)

    def _scalar_plans(self):
        if self._sfwd is not None or pyfftw is None:
            return
        # planned on arrays of their own (FFTW_MEASURE writes them), released at the first
        # execution: every use points a plan at its arrays (update_arrays) first
        r = pyfftw.empty_aligned(self.shape, dtype="float64")
        c = pyfftw.empty_aligned(self.cshape, dtype="complex128")
        flags = (self.planner,)
        with wisdom.planning(flags):
            self._sfwd = pyfftw.FFTW(r, c, axes=(0, 1, 2),
                                     direction="FFTW_FORWARD", flags=flags, threads=self.threads)
            self._sbwd = pyfftw.FFTW(c, r, axes=(0, 1, 2),
                                     direction="FFTW_BACKWARD",
                                     flags=flags + ("FFTW_DESTROY_INPUT",), threads=self.threads)

    @functools.cached_property
    def real_buf_s(self):
        """Aligned scalar scratch, made on first use (a transform of an unaligned array)."""
        return pyfftw.empty_aligned(self.shape, dtype="float64")

    @functools.cached_property
    def complex_buf_s(self):
        """Aligned complex scalar scratch, made on first use (``irfft_scalar``, unaligned
        arrays)."""
        return pyfftw.empty_aligned(self.cshape, dtype="complex128")

    def rfft_scalar(self, f, out=None):
        """rfftn of a scalar field (NX, NY, NZ) -> cshape (unnormalised); plans made on
        first use."""
        if out is None:
            out = self.empty_complex(None)
        if pyfftw is None:  # pragma: no cover
            out[...] = np.fft.rfftn(f)
            return out
        self._scalar_plans()
        return self._run_scalar(self._sfwd, f, (self.shape, np.float64, "real_buf_s"),
                                out, (self.cshape, np.complex128, "complex_buf_s"))

    def backward_scalar_raw(self, c, out):
        """Unnormalised c2r of a scalar ``c`` (cshape) -> ``out`` (NX, NY, NZ); destroys ``c``
        (FFTW c2r).  The plan of ``backward_raw``'s components: a vector field transformed
        component by component through one scalar scratch gives the same bits."""
        if pyfftw is None:  # pragma: no cover
            out[...] = np.fft.irfftn(c, s=self.shape) * self.size
            return out
        self._scalar_plans()
        return self._run_scalar(self._sbwd, c, (self.cshape, np.complex128, "complex_buf_s"),
                                out, (self.shape, np.float64, "real_buf_s"))

    def _run_scalar(self, plan, a, a_kind, out, out_kind):
        """Execute a scalar plan from ``a`` into ``out``, each used in place when aligned,
        else through the scratch named in its kind (shape, dtype, scratch attribute).
        pyfftw's update_arrays checks shape, strides, dtype and alignment itself (a
        ValueError when one does not fit): the arrays are tried first (3 us less a
        transform than checking them here, 41 -> 38 us at 32^3).  Its alignment rule is
        FFTW's (the plans ask for 16 bytes, ``_aligned`` for pyfftw.simd_alignment = 32
        here); an array 16 but not 32 bytes aligned gives the same bits in place as through
        the aligned scratch (r2c and c2r at 16^3, 32^3, 64^3, 2026-12-05)."""
        try:
            plan.update_arrays(a, out)
        except ValueError:
            pass
        else:
            plan.execute()
            return out
        if not self._aligned(a, *a_kind[:2]):
            buf = getattr(self, a_kind[2])
            np.copyto(buf, a)
            a = buf
        o = out if self._aligned(out, *out_kind[:2]) else getattr(self, out_kind[2])
        plan.update_arrays(a, o)
        plan.execute()
        if o is not out:
            np.copyto(out, o)
        return out

    def irfft_scalar(self, f_hat, out=None):
        """Inverse of ``rfft_scalar`` (divides by N), input kept."""
        if out is None:
            out = self.empty_real(None)
        if pyfftw is None:  # pragma: no cover
            out[...] = np.fft.irfftn(f_hat, s=self.shape)
            return out
        self._scalar_plans()
        np.multiply(f_hat, 1.0 / self.size, out=self.complex_buf_s)
        oi = out if self._aligned(out, self.shape, np.float64) else self.real_buf_s
        self._sbwd.update_arrays(self.complex_buf_s, oi)
        self._sbwd.execute()
        if oi is not out:
            np.copyto(out, oi)
        return out

    # ------------------------------------------------------------------ truncated fields
    # A 2/3-truncated field is 0 outside |m_a| <= K_a (``dealias``): of the 1-D transforms a
    # 3-D c2r makes (along x, then y, then z) those of lines that hold only zeros can be
    # skipped, and of an r2c whose result is used on the mask only, those of lines that end
    # outside it.  Along x only the (y, z) lines with |m_y| <= K_y, m_z <= K_z (4/9 of them),
    # along y only the lines with m_z <= K_z (2/3); the lines along z are all needed.
    # A fifth to a quarter of a transform's time (CPU ms, 1 thread, 2026-12-05 12:56 UTC, load
    # 0.9, bench/fft_floor.py --pruned): c2r 32^3 0.038 -> 0.033, 64^3 0.396 -> 0.317, 128^3
    # 4.50 -> 3.26; r2c 0.037 -> 0.032, 0.409 -> 0.328, 4.83 -> 3.56.  With FFTW_ESTIMATE (up
    # to 64^3) the 3-D plan makes the same 1-D transforms in the same order: the same bits
    # (tests/unit/test_spectral.py checks it); measured plans agree to round-off.

    @functools.cached_property
    def _pruned(self):
        """The stage plans of the truncated transforms, made on first use on scratch arrays
        (MEASURE writes them) and pointed at the caller's arrays at each use:
        (backward stages, forward stages), each a list of (plan, view of a complex field)
        in the order they run, the c2r / r2c along z given by None."""
        ny = self.cshape[1]
        ky, kz = self.trunc[1], min(self.trunc[2] + 1, self.cshape[2])
        yx = [slice(0, ky + 1)] + ([slice(ny - ky, ny)] if ky > 0 and ny - ky > ky + 1 else [])

        def along_x(c):
            return [c[:, ys, :kz] for ys in yx]

        def along_y(c):
            return c[:, :, :kz]
        self._pruned_views = (along_x, along_y)
        c = pyfftw.empty_aligned(self.cshape, dtype="complex128")
        r = pyfftw.empty_aligned(self.shape, dtype="float64")
        flags = (self.planner,)
        plans = {}
        with wisdom.planning(flags):
            for d in ("FFTW_BACKWARD", "FFTW_FORWARD"):
                plans[d] = ([pyfftw.FFTW(v, v, axes=(0,), direction=d, flags=flags,
                                         threads=self.threads) for v in along_x(c)],
                            pyfftw.FFTW(along_y(c), along_y(c), axes=(1,), direction=d,
                                        flags=flags, threads=self.threads))
            z_b = pyfftw.FFTW(c, r, axes=(2,), direction="FFTW_BACKWARD",
                              flags=flags + ("FFTW_DESTROY_INPUT",), threads=self.threads)
            z_f = pyfftw.FFTW(r, c, axes=(2,), direction="FFTW_FORWARD", flags=flags,
                              threads=self.threads)
        return plans["FFTW_BACKWARD"], plans["FFTW_FORWARD"], z_b, z_f

    _x_stages_on = None      # the array the backward stages along x and y point at

    def backward_scalar_truncated(self, c, out):
        """``backward_scalar_raw`` of a scalar ``c`` that is 0 outside the 2/3 mask (the
        caller's promise; the result is wrong otherwise): the same numbers (the same bits
        with FFTW_ESTIMATE plans, to round-off with measured ones), with the transforms of
        the lines of zeros skipped (see above).  Destroys ``c``."""
        if pyfftw is None:  # pragma: no cover
            return self.backward_scalar_raw(c, out)
        (xs, y), _, z, _ = self._pruned
        try:
            if c is not self._x_stages_on:        # (the callers' scratch is the same
                along_x, along_y = self._pruned_views     # array step after step: the
                self._x_stages_on = None                  # stages along x and y, in place
                for p, v in zip(xs, along_x(c)):          # on it, stay pointed at it)
                    p.update_arrays(v, v)
                v = along_y(c)
                y.update_arrays(v, v)
                self._x_stages_on = c
            z.update_arrays(c, out)
        except ValueError:           # not aligned as planned: the whole transform
            return self.backward_scalar_raw(c, out)
        for p in xs:
            p.execute()
        y.execute()
        z.execute()
        return out

    def rfft_scalar_truncated(self, f, out):
        """``rfft_scalar`` of ``f`` into ``out``, exact on the 2/3 mask only: outside it
        ``out`` holds partial sums (finite), for callers that multiply the result by the
        mask (the nonlinear term, the particles' increment).  ``f`` is kept."""
        if pyfftw is None:  # pragma: no cover
            return self.rfft_scalar(f, out)
        _, (xs, y), _, z = self._pruned
        along_x, along_y = self._pruned_views
        try:
            z.update_arrays(f, out)
            v = along_y(out)
            y.update_arrays(v, v)
            for p, v in zip(xs, along_x(out)):
                p.update_arrays(v, v)
        except ValueError:
            return self.rfft_scalar(f, out)
        z.execute()
        y.execute()
        for p in xs:
            p.execute()
        return out

    def backward_truncated(self, c, out):
        """``backward_raw`` of a vector field that is 0 outside the 2/3 mask
        (``backward_scalar_truncated`` of each component).  Destroys ``c``."""
        for k in range(c.shape[0]):
            self.backward_scalar_truncated(c[k], out[k])
        return out

    def forward_truncated(self, u, out):
        """``forward`` of a vector field, exact on the 2/3 mask only
        (``rfft_scalar_truncated`` of each component)."""
        for c in range(u.shape[0]):
            self.rfft_scalar_truncated(u[c], out[c])
        return out

    def empty_real(self, n=3):
        """SIMD-aligned uninitialised (n, NX, NY, NZ) float64 array (n=None: scalar field)."""
        shape = self.shape if n is None else (n,) + self.shape
        if pyfftw is None:  # pragma: no cover
            return np.empty(shape)
        return pyfftw.empty_aligned(shape, dtype="float64")

    def zeros_real(self, n=3):
        """``empty_real`` filled with zeros, its pages given by the system as they are first
        written (calloc): nothing is touched until used."""
        shape = self.local_shape if n is None else (n,) + self.local_shape
        return _aligned_zeros(shape, np.float64, self._zeros_align())

    def zeros_complex(self, n=3):
        """``empty_complex`` filled with zeros, untouched until used (``zeros_real``)."""
        shape = self.local_cshape if n is None else (n,) + self.local_cshape
        return _aligned_zeros(shape, np.complex128, self._zeros_align())

    def _zeros_align(self) -> int:
        """The SIMD alignment of this grid's arrays (a distributed grid keeps pyfftw's)."""
        return getattr(self, "_align", None) or (pyfftw.simd_alignment if pyfftw else 1)

    def empty_complex(self, n=3):
        """SIMD-aligned uninitialised (n, cshape) complex128 array (n=None: scalar)."""
        shape = self.cshape if n is None else (n,) + self.cshape
        if pyfftw is None:  # pragma: no cover
            return np.empty(shape, dtype=complex)
        return pyfftw.empty_aligned(shape, dtype="complex128")

    # ------------------------------------------------------------------ layout
    def sum(self, x) -> float:
        """The sum over the ranks of a local float: itself."""
        return float(x)

    def sums(self, values) -> list:
        return [float(v) for v in np.asarray(values, dtype=float).reshape(-1)]

    def max(self, x) -> float:
        return float(x)

    def reduce(self, *arrays):
        """Sums over the ranks of per-particle arrays: ``arrays``."""
        return arrays

    # the particle table of this layout (kapsel.particles.ownership.TABLES): on one process
    # the whole table, every row owned here
    particle_table = "whole"

    def near_rows(self, R, offsets, dx, strain=0.0, origin=0.0, images=0.0):
        """The rows of the particles at ``R`` whose stencil (``offsets``, (S, 3) grid
        steps) meets this process's block: all of them."""
        n = len(R)
        if self._all_rows is None or len(self._all_rows) != n:
            self._all_rows = np.arange(n)
        return self._all_rows

    _all_rows = None

    def cut_stencils(self, idx, phi):
        """Stencils (flat indices ``idx``, profiles ``phi`` (N, S)) cut to this process's
        block: (idx, phi, on) with ``on`` (N, S) the points on the block: all of them."""
        if self._all_on is None or self._all_on.shape != idx.shape:
            self._all_on = np.ones(idx.shape, dtype=bool)
        return idx, phi, self._all_on

    _all_on = None

    def k0(self, a_hat):
        """a_hat[:, 0, 0, 0] (the k = 0 mode) of a (c, ...) Fourier array."""
        return a_hat[:, 0, 0, 0].copy()

    def gather_real(self, a, root=0):
        """The whole field of the local blocks ``a``: ``a``."""
        return a

    def gather_complex(self, a, root=0):
        return a

    def to_rectangular(self, f, g, method="linear", origin=0.0, out=None, lines=None,
                       zero=True):
        """This process's block of a field (c, NX, NY, NZ) of the oblique grid of strain g,
        re-gridded onto the rectangular grid (kapsel.mesh.regrid.to_rectangular), into
        ``out`` (not ``f``) if given, on ``lines`` only (kapsel.mesh.regrid.shift_rows)."""
        from .regrid import to_rectangular
        return to_rectangular(f, g, method, origin, out=out, lines=lines, zero=zero)

    def to_oblique(self, f, g, method="linear", origin=0.0, out=None, lines=None, zero=True):
        """The inverse re-gridding, rectangular -> oblique (kapsel.mesh.regrid.to_oblique)."""
        from .regrid import to_oblique
        return to_oblique(f, g, method, origin, out=out, lines=lines, zero=zero)

    def gather_rows(self, f):
        """The whole x rows of the blocks of ``f`` (..., nx, ny, nz) along the x split: ``f``."""
        return f

    def local_real(self, a):
        """This process's block of a whole field: ``a``."""
        return a

    def local_complex(self, a):
        return a

    def scalar_solver(self, threads=1, backend="pyfftw"):
        """A ``ScalarSolve`` (FFT-diagonal solve of one scalar field) on this mesh."""
        return ScalarSolve(self.shape, threads, backend)

    def fourier_diagonal(self, m, threads=1):
        """``FourierDiagonal`` of the symbol ``m`` (half spectrum) on this mesh."""
        return FourierDiagonal(self.shape, m, threads)

    # ------------------------------------------------------------------ operators
    def k_dot(self, v_hat, out, tmp):
        """out = k . v_hat (complex cshape; ``tmp`` scratch of the same shape)."""
        np.multiply(v_hat[0], self.kx, out=out)
        np.multiply(v_hat[1], self.ky, out=tmp)
        out += tmp
        np.multiply(v_hat[2], self.kz, out=tmp)
        out += tmp
        return out

    def project(self, v_hat, out=None, tmp=None):
        """Solenoidal projection P v = v - k (k.v)/k^2 (in place unless ``out``); k = 0 kept.

        ``tmp``: optional two complex (cshape) scratch arrays (default: two owned by the grid).
        """
        if out is None:
            out = v_hat
        elif out is not v_hat:
            np.copyto(out, v_hat)
        if tmp is None:
            if self._ptmp is None:
                self._ptmp = (self.empty_complex(None), self.empty_complex(None))
            s, t = self._ptmp
        else:
            s, t = tmp
        self.k_dot(out, s, t)
        s *= self.inv_k2
        for c, k in enumerate((self.kx, self.ky, self.kz)):
            np.multiply(s, k, out=t)
            out[c] -= t
        return out

    def divergence_hat(self, v_hat):
        """i k . v_hat (cshape)."""
        return 1j * (self.kx * v_hat[0] + self.ky * v_hat[1] + self.kz * v_hat[2])

    def coordinates(self):
        """(x, y, z) broadcastable coordinate arrays i DX."""
        nx, ny, nz = self.shape
        return (np.arange(nx).reshape(-1, 1, 1) * self.dx,
                np.arange(ny).reshape(1, -1, 1) * self.dx,
                np.arange(nz).reshape(1, 1, -1) * self.dx)

    # ------------------------------------------------------------------ time step
    def auto_dt(self, factor, rho, eta):
        """Automatic time step (manual §5.5), ``kapsel.timestep.auto_dt`` on this mesh:
        dt = factor RHO / (ETA KMAX2) (FORMAT.md)."""
        from ..timestep import auto_dt
        return auto_dt(factor, rho, eta, self.dx, self.shape)

    def __repr__(self):
        return f"Grid(shape={self.shape}, dx={self.dx}, threads={self.threads})"


def _measure_planners(shapes=((32, 32, 32), (64, 64, 64)), repeat=20):  # pragma: no cover
    """Timing behind the module docstring's MEASURE / ESTIMATE choice."""
    import time
    for shape in shapes:
        for planner in ("FFTW_MEASURE", "FFTW_ESTIMATE"):
            t0 = time.perf_counter()
            g = Grid(shape, planner=planner)
            plan = time.perf_counter() - t0
            u = np.random.default_rng(0).normal(size=(3,) + g.shape)
            uh = np.empty((3,) + g.cshape, complex)
            best = math.inf
            for _ in range(repeat):
                t0 = time.perf_counter()
                g.forward(u, out=uh)
                g.backward(uh)
                best = min(best, time.perf_counter() - t0)
            print(f"{shape} {planner}: {best * 1e3:.2f} ms / pair, plan {plan:.2f} s")


if __name__ == "__main__":  # pragma: no cover
    _measure_planners()
