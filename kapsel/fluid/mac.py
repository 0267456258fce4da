"""MAC solver of the Navier-Stokes equation on the semi-staggered Arakawa B grid (manual §5.1).

Velocities at the nodes, pressure at the cell centres (see kapsel.mesh.operators).

* ``explicit_scheme`` (eqs 20-21): explicit advection + diffusion, then the pressure Poisson
  equation (21) - keeping its ∇·u^n "cycle error self-adjustment" term - solved by FFT with
  the B-grid D∘G symbol, then the pressure correction.  Equivalent to projecting
  u^n + dt(-(u·∇)u + ν∇²u + f).
* ``implicit_scheme`` (eqs 23-26): Crank-Nicolson diffusion, advection u*·∇u^{n+1/2} with the
  Adams-Bashforth velocity u* = (3u^n - u^{n-1})/2 (eq 25), pressure from eq (26) solved first
  by FFT, then the linear system for u^{n+1} by BiCGSTAB, preconditioned by the FFT inverse
  of its constant-viscosity diffusion part (``preconditioner='fft'``, default; the original
  has none, ``preconditioner=None``): 64^3, 8 particles, dt auto: 5 -> 1 iterations per step
  at the same tolerance, step 126-132 -> 98-105 ms.  For constant viscosity the operator is
  applied by a compiled stencil sweep (kapsel.mesh.stencils), bit-identical to the CSR
  rows it replaces.  With ``eta_field`` the viscous term is ∇·η(∇u + ∇u^T)/ρ in the
  original's node form for ∇·u = 0, (η∇²u + ∇η·(∇u + ∇u^T))/ρ with central differences
  (operators.viscous_variable_nc; its CSR rows have the original's 11 entries: components
  coupled through ∂_i u_j), otherwise ν∇²u.

Choices, measured on this 2-core machine (shared, so +-30 %; ms, min of repeats):

* FFT: pyfftw (planned once, aligned buffers reused; the planner of kapsel.mesh.grid:
  FFTW_ESTIMATE up to 64^3 points, FFTW_MEASURE above with its plans kept on disk by
  kapsel.mesh.wisdom) vs scipy.fft, one
  Poisson solve (rfftn + scale + irfftn): 32^3 0.10 vs 0.34, 64^3 1.06 vs 3.36 -> pyfftw
  (scipy.fft kept as ``fft='scipy'``).
* BiCGSTAB operator: assembled CSR (fixed sparsity pattern, data refilled each step, 7 slots
  per row, 11 with variable eta) vs matrix-free LinearOperator over the numpy stencils:
    const eta  32^3: build 0.34, matvec 0.30 vs 1.06;  64^3: build 4.9, matvec 4.6 vs 5.9
    var eta    32^3: build 2.3,  matvec 0.82 vs 1.9;   64^3: build 38,  matvec 14 vs 33
               (11 slots, 2026-12-02, the other core busy)
  step (const eta, dt = RHO DX^2/(ETA pi^2)): 32^3 6.3 vs 11.0, 64^3 76 vs 95 -> CSR
  (``linear='matfree'`` kept).  With threads > 1 and 3N >= 500 000 the CSR rows are split in
  blocks applied in threads (sparsetools releases the GIL): matvec 64^3 4.5 -> 3.2 ms, but
  32^3 0.29 -> 0.38 ms, hence the size threshold.
* Jacobi preconditioning: no gain for constant eta (the diagonal is constant), at 32^3 and
  eta ratio 10 / 100 it saves 5 % / 13 % of the iterations (21 -> 20, 62 -> 54), and its
  non-constant scaling would break the exact momentum conservation below (the Krylov
  corrections of an unpreconditioned solve all have zero sum) -> not used.  The FFT
  preconditioner keeps it: its symbol is 1 at k = 0, so preconditioned corrections still
  have zero sum.

Advection is the original's non-conservative (u·∇)u ((u*·∇)u^{n+1/2} in the implicit scheme)
with central differences at the nodes, and so is the variable-viscosity term: total momentum
changes by their grid sums only (tests/unit/test_mac.py), the other terms sum to zero.
"""
import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator

from ..errors import SolverDidNotConverge, UnstableTimeStep
from ..mesh.linalg import solve_correction
from ..mesh.halo import Halo
from ..mesh import operators as op
from ..state import ModelState

try:  # pragma: no cover - import guard
    import pyfftw
except ImportError:  # pragma: no cover
    pyfftw = None
from ..mesh import compiled as _compiled


def _flat_alike(*arrays) -> bool:
    """The arrays are C-contiguous float64 of one shape (flat views of them line up)."""
    a0 = arrays[0]
    return all(a.shape == a0.shape and a.dtype == np.float64 and a.flags.c_contiguous
               for a in arrays)


__all__ = ["MACSolver", "SolverDidNotConverge", "UnstableTimeStep"]


class _Poisson:
    """Solves D G phi = r (B grid, cell arrays) by FFT on the layout (``ScalarSolve`` of
    kapsel.mesh.grid, or of a rank's block: kapsel.mesh.pencil); null modes -> 0."""

    def __init__(self, layout, dx, threads=1, backend="pyfftw"):
        self.fft = layout.scalar_solver(threads, backend)
        shape, block = layout.shape, layout.spec_range
        self.inv = self.fft.symbol(op.inverse_div_grad_b(shape, dx, block))   # D G phi = r
        self.inv_lap = self.fft.symbol(op.symbol_inverse_laplacian(shape, dx, block))  # lap p = r
        self.rhs = self.fft.rhs     # write the right-hand side here, then call solve()

    def symbol(self, m):
        """A symbol on the layout's Fourier block as ``solve`` takes it."""
        return self.fft.symbol(m)

    def solve(self, inv=None):
        """phi for the right-hand side stored in ``self.rhs`` (the symbol ``inv``, default
        the B-grid D G inverse); returns an internal buffer."""
        return self.fft.solve(self.inv if inv is None else inv)


class MACSolver:
    """MAC solver (manual §5.1, eqs 20-26) for node velocities u of shape (3, NX, NY, NZ).

    Parameters follow the input file: ``scheme`` is NS_solver ('explicit_scheme' |
    'implicit_scheme'); ``tolerance`` (relative residual) and ``maximum_iteration`` are the
    BiCGSTAB settings of implicit_scheme (table 2).  ``threads`` is passed to the FFTs.
    ``linear``: 'sparse' (assembled CSR, default, faster) or 'matfree' (LinearOperator);
    ``fft``: 'pyfftw' (default, faster) or 'scipy'.  ``layout``: the mesh's layout, which
    gives the shape and the spacing DX (kapsel.mesh.grid.Grid(shape, dx) for one process; a
    rank's block: kapsel.mesh.pencil.PencilGrid), whose
    halos, sums and transforms the solver uses (docs/distributed.md): on one process they
    are identities, on a block the stencils run on it widened by one ghost layer from the
    neighbour ranks (kapsel.mesh.halo), the same operations point by point as on one
    process; sums, dot products and maxima are over the ranks in a fixed order.
    Attributes: ``pressure`` (last p^{n+1}), ``u_old`` (u^{n-1}, settable for restarts),
    ``iterations`` / ``residual`` of the last BiCGSTAB solve (residual is NaN when converged).
    ``state``: the model's kapsel.state.ModelState, where ``pressure``, ``u_old`` and the
    explicit scheme's ``n_old`` live (a solver of its own by default).
    """

    def __init__(self, layout, rho, eta, dt, scheme="explicit_scheme", tolerance=1e-9,
                 maximum_iteration=1000, threads=1, fft="pyfftw", linear="sparse",
                 preconditioner="fft", state=None):
        if scheme not in ("explicit_scheme", "implicit_scheme"):
            raise ValueError("scheme must be 'explicit_scheme' or 'implicit_scheme', not %r"
                             % (scheme,))
        if linear not in ("sparse", "matfree"):
            raise ValueError("linear must be 'sparse' or 'matfree'")
        self.shape = tuple(int(n) for n in layout.shape)
        if len(self.shape) != 3 or min(self.shape) < 1:
            raise ValueError("shape must be (NX, NY, NZ)")
        self.dx, self.rho, self.eta, self.dt = float(layout.dx), float(rho), float(eta), float(dt)
        self.grid = layout
        self.fshape = tuple(self.grid.local_shape)   # the fields: the mesh or a rank's block
        self.halo = Halo(self.grid, 1)
        self._eta_pad = None        # (eta_field, eta_field widened) of this step
        self.nu = self.eta / self.rho
        self.scheme = scheme
        self.tolerance = float(tolerance)
        self.maximum_iteration = int(maximum_iteration)
        self.threads = int(threads)
        self.linear = linear
        if preconditioner not in (None, "fft"):
            raise ValueError("preconditioner must be None or 'fft'")
        self.preconditioner = preconditioner if pyfftw is not None else None
        self._helmholtz = None
        self.iterations = 0
        self.residual = 0.0
        # FFT threads only from 64^3 on: below, the plan gains little (32^3 0.10 -> 0.08 ms)
        # and a second thread stalls whenever the other core is busy (seen: 30 ms spikes)
        fft_threads = self.threads if np.prod(self.shape) >= 64 ** 3 else 1
        self._poisson = self._make_poisson(fft_threads, fft)
        vshape = (3,) + self.fshape
        self.state = ModelState() if state is None else state
        # p^{n+1} at the cell centres; u^{n-1} (held once a step or a restart set it)
        self.pressure = self.state.field("pressure", lambda: np.zeros(self.fshape))
        self._u_old = self.state.field("u_old", lambda: np.zeros(vshape), held=False)
        self._v1 = np.empty(vshape)
        self._v2 = np.empty(vshape)
        self._s = np.empty(self.fshape)
        self._n_old = None          # explicit: (u.grad)u - f of the last step (AB2, state n_old)
        self._wn = None
        self.step_count = 0         # steps done (a restart sets it): the original's jikan.ts
        self._pattern = None
        self._eta_grad = None       # D eta of the step's viscosity field (viscosity_change)
        self._thread_min_rows = 500_000        # threaded CSR matvec only above this size

    def _make_poisson(self, threads, fft):
        return _Poisson(self.grid, self.dx, threads, fft)

    # ------------------------------------------------------------------ reductions
    # (over the ranks of the layout: identities on one process)
    def _max(self, x):
        return self.grid.max(x)

    def mean(self, a):
        """The mean of a field over the mesh (switch.FIX_CELL)."""
        return self.grid.sum(float(np.sum(a))) / self.grid.size

    # ------------------------------------------------------------------ state
    @property
    def u_old(self):
        """u^{n-1} (restart U_OLD); equals u^n before the first step."""
        return self._u_old

    @u_old.setter
    def u_old(self, value):
        self._u_old[...] = value
        self.state.mark("u_old")

    @property
    def has_u_old(self) -> bool:
        """Whether u^{n-1} is set (a step was made, or a restart gave U_OLD)."""
        return self.state.holds("u_old")

    @property
    def advection_old(self):
        """The explicit scheme's AB2 history n^{n-1} = (u.grad)u - f of the last step, None
        before the first step."""
        return self.state.get("n_old")

    def _advection_history(self, like):
        """n^{n-1}'s array in the state (made on first use) and its scratch."""
        if self._n_old is None:
            self._n_old = self.state.field("n_old", lambda: np.empty_like(like), held=False)
            self._wn = np.empty_like(like)
        return self._n_old

    def restore_advection(self, n_old) -> None:
        """Set the AB2 history n^{n-1} (a restart's exact state)."""
        n_old = np.asarray(n_old)
        self._advection_history(n_old)[...] = n_old
        self.state.mark("n_old")

    def stable_dt(self, u=None, eta_field=None):
        """Largest stable dt: explicit diffusion (3D FTCS) DX^2 / (6 nu_max) and, when u is
        given, the advection-diffusion bound 2 nu / |u|^2_max; inf for implicit_scheme."""
        if self.scheme == "implicit_scheme":
            return np.inf
        nu = self.nu if eta_field is None else self._max(float(np.max(eta_field))) / self.rho
        lim = self.dx ** 2 / (6.0 * nu)
        if u is not None:
            u2 = self._max(float(np.max(np.sum(u * u, axis=0))))
            if u2 > 0:
                lim = min(lim, 2.0 * nu / u2)
        return lim

    def check_stability(self, u=None, eta_field=None):
        """Return stable_dt(); raise UnstableTimeStep if dt exceeds it."""
        lim = self.stable_dt(u, eta_field)
        if self.dt > lim:
            raise UnstableTimeStep(
                "time step dt = %g exceeds the stability limit %g of the explicit MAC scheme "
                "(nu dt / DX^2 <= 1/6); lower the time-increment factor or use implicit_scheme"
                % (self.dt, lim))
        return lim

    def kinetic_energy(self, u):
        """(rho/2) sum |u|^2 DX^3."""
        return 0.5 * self.rho * self.grid.sum(float(np.vdot(u, u))) * self.dx ** 3

    def momentum(self, u):
        """rho sum u DX^3 (3-vector)."""
        s = u.sum(axis=(1, 2, 3))
        return self.rho * np.array([self.grid.sum(x) for x in s]) * self.dx ** 3

    # ------------------------------------------------------------------ projection
    def _solve_phi(self, u):
        """phi with D G phi = D u (phi = dt p / rho); internal buffer."""
        self._div(u, out=self._poisson.rhs)
        return self._poisson.solve()

    def _pressure(self, u, n):
        """The pressure of the original's schemes (fdm.h Set_poisson_rhs_sub,
        Solve_poisson_dft): lap p = RHO/dt D u - RHO D n with the continuous Laplacian
        (-|k|^2; p of k = 0 is 0), D the B-grid divergence; into ``self.pressure``."""
        rhs = self._poisson.rhs
        self._div(u, out=rhs)
        rhs *= self.rho / self.dt
        d = self._div(n, out=self._s)
        d *= self.rho
        rhs -= d
        self.pressure[...] = self._poisson.solve(self._lap_inverse())
        return self.pressure

    def _lap_inverse(self):
        """The symbol -1/|k|^2 of the step's pressure solve (the oblique frame's: metric)."""
        return self._poisson.inv_lap

    def _grad_p(self, phi):
        """The pressure-gradient term G phi (B grid) into an internal buffer (the oblique
        solver raises its index with the metric)."""
        h = self.halo
        G = op.grad_b(h.pad(phi, key="phi"), self.dx, out=h.target(self._v1, (3,), "grad"),
                      work=h.work((2,), "w2"))
        return h.keep(G, self._v1)

    def project(self, u):
        """Make u discretely divergence-free on the B grid in place (eq 22); keeps the mean."""
        phi = self._solve_phi(u)
        g = self._grad_p(phi)
        u -= g
        return u

    def projection_pressure(self, du):
        """RHO/dt phi with D G phi = D du (cell centres): the pressure that removes the
        divergence of an increment du, e.g. the particles' force of a step (for output)."""
        return (self.rho / self.dt) * self._solve_phi(du).copy()

    def divergence(self, u, out=None):
        """B-grid divergence of u at the cell centres."""
        return self._div(u, out)

    def _div(self, u, out=None):
        h = self.halo
        D = op.div_b(h.pad(u), self.dx, out=h.target(out, (), "div"), work=h.work((2,), "w2"))
        return h.keep(D, out)

    # ------------------------------------------------------------------ step
    def step(self, u, force=None, eta_field=None):
        """Advance u (3, NX, NY, NZ) by one dt in place (u~^{n+1} of eqs 20 / 23).

        ``force``: body-force acceleration (3, NX, NY, NZ), e.g. -psi* grad(mu*)/rho of eq 23;
        ``eta_field``: node viscosity eta* (the caller passes the extrapolated or current
        field); None means the constant ETA.  After the explicit step D u = 0 to round-off;
        after the implicit one D u is O(dt x the AB extrapolation error) and is corrected at the
        next step by the D u^n term of eq 26.  Sets ``pressure`` (p^{n+1}, cell centres),
        ``iterations``; raises SolverDidNotConverge (implicit)."""
        if u.shape != (3,) + self.fshape or u.dtype != np.float64:
            raise ValueError("u must be float64 of shape %s" % (((3,) + self.fshape),))
        if not self.state.holds("u_old"):
            self._u_old[...] = u
            self.state.mark("u_old")
        self._eta_pad = None                  # eta_field is widened once per step
        self._eta_grad = None if eta_field is None else self._viscosity_gradient(eta_field)
        if self.scheme == "explicit_scheme":
            self._step_explicit(u, force, eta_field)
        else:
            self._step_implicit(u, force, eta_field)
        self.step_count += 1
        return u

    # the stencils, on the block widened by the halo (identities on one process)
    _u_pad = None           # (u, padded u) while a step or a product reads the same u twice
    _a_pad = None           # (u*, padded u*) during an implicit solve

    def _padded(self, u, key):
        if self._u_pad is not None and self._u_pad[0] is u:
            return self._u_pad[1]
        return self.halo.pad(u, key=key)

    def _viscous(self, u, eta_field, out):
        """(1/rho) div(eta (grad u + grad u^T)) in the original's node form
        (operators.viscous_variable_nc, with the step's D eta), or nu lap u when eta_field
        is None."""
        h = self.halo
        U = self._padded(u, "visc")
        V = h.target(out, (3,), "visc")
        if eta_field is None:
            op.laplacian(U, self.dx, out=V)
            V *= self.nu
        else:
            op.viscous_variable_nc(U, self._eta(eta_field), self.dx, out=V,
                                   grad_eta=self._eta_grad, work=h.work((11,), "visc_nc"))
            V *= 1.0 / self.rho
        return h.keep(V, out)

    def _advection(self, u, out):
        h = self.halo
        A = op.advection_nc(self._padded(u, "pad"), self.dx, out=h.target(out, (3,), "adv"))
        return h.keep(A, out)

    def _advection_linear(self, a, w, out):
        h = self.halo
        if self._a_pad is not None and self._a_pad[0] is a:
            Aa = self._a_pad[1]
        else:
            Aa = h.pad(a, key="lin_a")
        A = op.advection_nc_linear(Aa, self._padded(w, "lin_w"), self.dx,
                                   out=h.target(out, (3,), "adv_lin"))
        return h.keep(A, out)

    def _eta(self, eta_field):
        """eta_field widened by the halo, once per step."""
        if self._eta_pad is None or self._eta_pad[0] is not eta_field:
            self._eta_pad = (eta_field, self.halo.pad(eta_field, key="eta"))
        return self._eta_pad[1]

    def _viscosity_gradient(self, eta_field):
        """D eta (central, at the nodes) of the step's viscosity field, on the widened
        block."""
        return op.grad_central(self._eta(eta_field), self.dx)

    def _step_explicit(self, u, force, eta_field):
        """The original's explicit scheme (fdm.cxx NS_solver_slavedEuler_explicit, eqs
        20-21): n = (u.grad)u - f, u~ = u^n - dt n (the first two steps of a run) or
        - dt/2 (3 n - n_old) (Adams-Bashforth after), + dt nu lap u^n; the pressure from
        lap p = RHO/dt D u~ - RHO D (n - nu lap u^n), then u = u~ - dt/RHO G p.  (Eq 21 has
        D u^n where the original takes D u~, which counts D (n - nu lap) twice; the
        original's is kept: the final spectral projection of the SPM step removes nearly all
        of the difference, 3e-7 of max|u| per step on one settling sphere.)"""
        self._u_pad = (u, self.halo.pad(u, key="u"))     # advection and viscous term
        try:
            self._explicit(u, force, eta_field)
        finally:
            self._u_pad = None

    def _explicit(self, u, force, eta_field):
        dt = self.dt
        n = self._advection(u, out=self._v1)
        if force is not None:
            n -= force
        lap = self._viscous(u, eta_field, self._v2)
        n_old = self._advection_history(u)
        w = self._wn
        ab2 = self.step_count >= 2 and self.state.holds("n_old")
        K = _compiled.stencils
        flat = K is not None and _flat_alike(u, n, n_old, lap, w)
        if flat:                             # the same operations, one pass
            K.ab2_update(u.reshape(-1), n.reshape(-1), n_old.reshape(-1), lap.reshape(-1),
                         w.reshape(-1), float(dt), bool(ab2))
        else:
            if ab2:
                np.multiply(n, 1.5 * dt, out=w)
                w -= (0.5 * dt) * n_old
                u -= w
            else:
                u -= dt * n
            n_old[...] = n
            u += dt * lap
            np.subtract(n, lap, out=w)       # n - nu lap u^n
        self.state.mark("n_old")
        self._pressure(u, w)
        g = self._grad_p(self.pressure)
        if flat and _flat_alike(u, g):
            K.sub_scaled(u.reshape(-1), g.reshape(-1), float(dt / self.rho))
        else:
            u -= g * (dt / self.rho)

    # ------------------------------------------------------------------ implicit
    def _step_implicit(self, u, force, eta_field):
        """The original's implicit scheme (fdm.cxx NS_solver_slavedEuler_implicit,
        fdm_matrix_solver.cxx NS_MAC_solver_implicit; eqs 23-26): u* = (3 u^n - u^{n-1})/2;
        the pressure from lap p = RHO/dt D u^n - RHO D ((u*.grad)u* - V(u*) - f) (eq 26);
        then A u^{n+1} = u^n - dt/2 (u*.grad)u^n + dt/2 V(u^n) - dt/RHO G p + dt f with
        A = I + dt/2 (u*.grad) - dt/2 V (eqs 23-24), V = nu lap (or the variable-viscosity
        term), solved by BiCGSTAB to the input's tolerance.  At a run's first step
        u^{n-1} = u^n (the original's is 0 there: the same for a fluid at rest)."""
        dt = self.dt
        ustar = np.multiply(u, 1.5)
        ustar -= 0.5 * self._u_old               # eq 25
        A = self._operator(ustar, eta_field)
        n = self._advection(ustar, out=self._v1)
        n -= self._viscous(ustar, eta_field, self._v2)
        if force is not None:
            n -= force
        self._pressure(u, n)
        b = self._advection_linear(ustar, u, out=np.empty_like(u))
        b *= -0.5 * dt
        b += u
        b += (0.5 * dt) * self._viscous(u, eta_field, self._v2)
        b -= self._grad_p(self.pressure) * (dt / self.rho)
        if force is not None:
            b += dt * force
        x = self._bicgstab(A, b.ravel(), u.ravel().copy())
        self._a_pad = None
        self._u_old[...] = u
        u[...] = x.reshape(u.shape)

    def _bicgstab(self, A, b, x0):
        x, self.iterations, self.residual = solve_correction(
            A, b, x0, self.tolerance, self.maximum_iteration, M=self._precond(b.size),
            what="implicit Navier-Stokes solver (BiCGSTAB)", dot=self.grid.dots)
        return x

    def _precond(self, n):
        """The FFT preconditioner, or None: M^-1 v = FFT^-1[FFT(v) / (1 + dt/2 nu 4/DX^2
        sum_a sin^2(k_a DX/2))] per component, the exact inverse of the implicit operator's
        constant-viscosity diffusion part.  Its symbol is 1 at k = 0, so it keeps the sum of
        a vector (the momentum argument of the module docstring holds)."""
        if self.preconditioner is None:
            return None
        if self._helmholtz is None:
            fft_threads = self.threads if np.prod(self.shape) >= 64 ** 3 else 1
            lap = op.symbol_laplacian(self.shape, self.dx, self.grid.spec_range)  # -(4/DX^2) sum sin^2
            self._helmholtz = self.grid.fourier_diagonal(
                1.0 / (1.0 - 0.5 * self.dt * self.nu * lap), fft_threads)
        return LinearOperator((n, n), matvec=self._helmholtz.solve, dtype=np.float64)

    # ------------------------------------------------------------------ linear operator
    def _operator(self, ustar, eta_field):
        """A: the compiled stencil sweep (constant viscosity), the assembled CSR matrix
        (its rows wrap the whole periodic mesh: a layout of the whole mesh only), or the
        matrix-free stencils."""
        if self.linear == "sparse":
            if eta_field is None and _compiled.stencils is not None:
                return self._stencil_operator(ustar)
            if self.grid.whole_mesh:
                return self._assemble(ustar, eta_field)
        return self._matfree(ustar, eta_field)

    def _stencil_operator(self, ustar):
        """A of ``_assemble`` (constant viscosity) applied by a compiled stencil sweep
        (kapsel.mesh.stencils.implicit_matvec_nc): the same products summed in the same order
        as the CSR rows, so bit-identical, without assembling the matrix (64^3: 24 ms per
        step and 70 MB saved, matvec 15 -> 4 ms)."""
        hl = self.halo
        n3 = 3 * int(np.prod(self.fshape))
        shape = (3,) + self.fshape
        h = 0.5 * self.dt
        a = h / (2 * self.dx)
        c = h * self.nu / self.dx ** 2
        us = hl.pad(ustar, key="ustar")
        kernel = _compiled.stencils.implicit_matvec_nc

        def mv(x):
            out = hl.target(None, (3,), "mv")
            kernel(hl.pad(np.asarray(x).reshape(shape), key="mv"), us, a, c, out)
            return hl.keep(out).reshape(-1)
        return LinearOperator((n3, n3), matvec=mv, dtype=np.float64)

    def _matfree(self, ustar, eta_field):
        """A applied by the stencils (``_advection_linear``, ``_viscous``), each product's
        x and u* widened once."""
        n3 = 3 * int(np.prod(self.fshape))
        shape = (3,) + self.fshape
        h = 0.5 * self.dt
        tmp = np.empty(shape)
        self._a_pad = (ustar, self.halo.pad(ustar, key="ustar"))

        def mv(x):
            w = np.asarray(x).reshape(shape)
            self._u_pad = (w, self.halo.pad(w, key="mv"))
            try:
                out = self._advection_linear(ustar, w, np.empty(shape))
                out *= h
                out += w
                out -= h * self._viscous(w, eta_field, tmp)
            finally:
                self._u_pad = None
            return out.ravel()
        return LinearOperator((n3, n3), matvec=mv, dtype=np.float64)

    def _build_pattern(self, variable):
        """Column indices of the fixed stencil slots (row = component, node)."""
        nx, ny, nz = self.shape
        n = nx * ny * nz
        idx = np.arange(n).reshape(self.shape)

        def sh(s):  # index of node n + s (periodic), s a 3-tuple
            return np.roll(idx, tuple(-q for q in s), axis=(0, 1, 2)).ravel()
        e = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
        cols = []
        for i in range(3):
            c = [idx.ravel() + i * n]
            for j in range(3):
                c.append(sh(e[j]) + i * n)
                c.append(sh(tuple(-q for q in e[j])) + i * n)
            if variable:                # component j != i at n +- e_i (D_i u_j)
                for j in range(3):
                    if j == i:
                        continue
                    for si in (1, -1):
                        c.append(sh(tuple(si * q for q in e[i])) + j * n)
            cols.append(np.stack(c, axis=1))
        indices = np.concatenate(cols, axis=0).astype(np.int32)
        nslot = indices.shape[1]
        indptr = np.arange(0, 3 * n * nslot + 1, nslot, dtype=np.int32)
        return {"variable": variable, "indices": indices.ravel(), "indptr": indptr,
                "nslot": nslot, "data": np.empty((3, n, nslot)), "T": np.empty((nslot, n)),
                "adv": np.empty((6, n)) if variable else None}

    def _assemble(self, ustar, eta_field):
        """CSR matrix of A = I + dt/2 N(u*, .) - dt/2 V (fixed pattern, data refilled).

        Slots of row (component i, node n): n, n+e_x, n-e_x, n+e_y, ..., then (variable eta,
        the original's 11-entry rows of CHNS_MAC_solver_implicit_viscosity) component j != i
        at n + e_i, n - e_i: V_i = (eta lap u_i + sum_j D_j eta (D_j u_i + D_i u_j)) / rho
        (operators.viscous_variable_nc).  Filled slot-major in ``T`` and copied transposed
        into the row-major CSR data."""
        variable = eta_field is not None
        if self._pattern is None or self._pattern["variable"] != variable:
            self._pattern = self._build_pattern(variable)
        P = self._pattern
        n = int(np.prod(self.shape))
        data, T = P["data"], P["T"]
        dx, h = self.dx, 0.5 * self.dt
        if not variable:
            c = h * self.nu / dx ** 2
            T[0] = 1.0 + 6.0 * c
            for j in range(3):
                uj = ustar[j].reshape(-1)
                for k, s in ((1 + 2 * j, 1), (2 + 2 * j, -1)):
                    np.multiply(uj, s * h / (2 * dx), out=T[k])
                    T[k] -= c
            data[0] = T.T
            data[1] = data[0]
            data[2] = data[0]
        else:
            eta = eta_field.reshape(-1)
            ge = self._eta_grad if self._eta_grad is not None else \
                self._viscosity_gradient(eta_field)
            ge = ge.reshape(3, n)
            g = h / (self.rho * dx * dx)
            c1 = h / (2.0 * self.rho * dx)
            # advection - eta lap part of the 6 neighbour slots, shared by the components
            adv = P["adv"]
            for j in range(3):
                uj = ustar[j].reshape(-1)
                np.multiply(uj, h / (2 * dx), out=adv[2 * j])
                adv[2 * j] -= g * eta
                np.multiply(uj, -h / (2 * dx), out=adv[2 * j + 1])
                adv[2 * j + 1] -= g * eta
            for i in range(3):
                np.multiply(eta, 6.0 * g, out=T[0])
                T[0] += 1.0
                for j in range(3):
                    m = c1 * (2.0 if j == i else 1.0)
                    np.multiply(ge[j], -m, out=T[1 + 2 * j])
                    T[1 + 2 * j] += adv[2 * j]
                    np.multiply(ge[j], m, out=T[2 + 2 * j])
                    T[2 + 2 * j] += adv[2 * j + 1]
                k = 7
                for j in range(3):
                    if j == i:
                        continue
                    for si in (1, -1):
                        np.multiply(ge[j], -si * c1, out=T[k])
                        k += 1
                data[i] = T.T
        return self._csr(P)

    def _csr(self, P):
        """The CSR matrix, or for threads > 1 a LinearOperator running row blocks in threads
        (scipy's csr_matvec releases the GIL)."""
        n3 = P["indptr"].size - 1
        d = P["data"].reshape(-1)
        # threads pay only for large systems: matvec 64^3 const 4.5 -> 3.2 ms, 32^3 0.29 -> 0.38
        if self.threads <= 1 or n3 < self._thread_min_rows:
            return sp.csr_matrix((d, P["indices"], P["indptr"]), shape=(n3, n3))
        ns = P["nslot"]
        cuts = np.linspace(0, n3, self.threads + 1).astype(int)
        blocks = []
        for r0, r1 in zip(cuts[:-1], cuts[1:]):
            blocks.append(sp.csr_matrix((d[r0 * ns:r1 * ns], P["indices"][r0 * ns:r1 * ns],
                                         P["indptr"][:r1 - r0 + 1]), shape=(r1 - r0, n3)))
        pool = self._thread_pool()

        def mv(x):
            x = np.asarray(x).reshape(-1)
            futs = [pool.submit(B.dot, x) for B in blocks]
            return np.concatenate([f.result() for f in futs])
        return LinearOperator((n3, n3), matvec=mv, dtype=np.float64)

    def _thread_pool(self):
        if getattr(self, "_pool", None) is None:
            from concurrent.futures import ThreadPoolExecutor
            self._pool = ThreadPoolExecutor(self.threads)
        return self._pool
