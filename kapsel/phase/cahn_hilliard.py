"""Cahn-Hilliard equation of the binary fluid with particles (manual §4.2, §5.3).

    d psi/dt + div(psi u) = kappa lap mu                                    (16, 30)
    mu = dF/dpsi,  F = sum DX^3 [f(psi) + alpha/2 |grad psi|^2 + w xi |grad phi|^2 psi
                                 + d (psi - psi_bar)^2 phi]                 (17)

Decisions on eq 17 (documented in the report)
---------------------------------------------
* Wetting: as printed, ``w xi |grad phi|^2`` does not depend on psi and would drop out of mu.
  It is read as the surface field of Model H with particles (Tanaka & Araki): F contains
  ``w xi |grad phi|^2 psi``, so mu gets the psi-independent term ``w xi |grad phi|^2``, located
  on the particle surfaces (|grad phi|^2 ~ 1/xi^2 over a shell of thickness xi, hence the
  factor xi makes the surface energy xi-independent).  w < 0 (sample input) makes the
  surfaces prefer psi > 0 (the A-rich phase).  xi = A_XI.
* Particle interior: ``d (psi - psi_bar)^2 phi`` gives mu += 2 d (psi - psi_bar) phi, pulling
  psi inside particles to the neutral composition psi_bar: 0 for Landau, the critical
  composition sqrt(NB)/(sqrt(NA)+sqrt(NB)) for Flory-Huggins (see potentials.py).  It does not
  depend on composition_ratio (override with ``psi_bar=``).

Discretisation (periodic grid, nodes, spacing DX)
-------------------------------------------------
* lap: 7-point Laplacian, symbol -K^2 with K^2 = sum (2/DX)^2 sin^2(k DX/2) (max 12/DX^2).
* |grad psi|^2 in F: forward differences, so dF/dpsi_i / DX^3 = f' - alpha lap psi + ... is
  exact on the lattice; |grad phi|^2 and grad mu: central differences at the nodes.
* div(psi u): central differences of the flux psi u (conservative: sums to zero).
* explicit_scheme (eq 30): Euler with u as given (u^n).
* implicit_scheme (eq 31): BDF2 with the Adams-Bashforth potential 2f'(psi^n) - f'(psi^{n-1});
  implicit are -alpha lap psi^{n+1}, div(psi^{n+1} u) (u as given: u^{n+1}) and the linear
  particle term 2 d phi psi^{n+1}; the wetting term w xi |grad phi|^2 is a known field.  Both
  f' evaluations use the phi passed to the step.  The first step (no psi_old) is an implicit
  Euler step with f'(psi^n).  The linear system is solved by BiCGSTAB (no preconditioner by
  default, as in the original; 'jacobi' and 'fft' are available).
* Conservation: the column sums of the system matrix are exactly c0 (= 3/2 or 1), so the mean
  of psi^{n+1} is known exactly; BiCGSTAB solves for the zero-mean remainder (its Krylov space
  then has zero mean) and ``tolerance`` is the relative residual of that remainder system.
  The mean of psi is thus conserved to round-off by both schemes, with or without particles.
"""
import math

import numpy as np
from scipy.sparse.linalg import LinearOperator

from .potentials import make_potential

from ..fluid import operators as ops
from ..linalg import SolverDidNotConverge, UnstableTimeStep, solve_correction  # noqa: F401

__all__ = ["CahnHilliard", "chemical_potential", "free_energy", "capillary_force",
           "discrete_k2", "SolverDidNotConverge", "UnstableTimeStep"]


# --------------------------------------------------------------------------- FD helpers
# (the periodic shifts and the 7-point Laplacian are the MAC solver's: kapsel.fluid.operators)
def _lap(f, dx, out):
    """7-point Laplacian (out must not alias f)."""
    return ops.laplacian(f, dx, out)


def _div_flux(psi, u, dx, out, work):
    """div(psi u) with central differences of the flux (conservative)."""
    out[...] = 0.0
    for ax in range(3):
        np.multiply(psi, u[ax], out=work)
        ops.cdiff_acc(out, work, ax)
    out *= 0.5 / dx
    return out


def _grad(f, dx, out):
    """Central gradient (3, NX, NY, NZ) at the nodes."""
    for ax in range(3):
        out[ax] = 0.0
        ops.cdiff_acc(out[ax], f, ax)
    out *= 0.5 / dx
    return out


def _grad_sq(f, dx):
    """|grad f|^2 with central differences."""
    g = _grad(f, dx, np.empty((3,) + f.shape))
    return np.einsum("i...,i...->...", g, g)


def discrete_k2(shape, dx):
    """K^2 = sum_a (2/DX)^2 sin^2(k_a DX/2) of every mesh mode (full FFT order), -symbol of
    the 7-point Laplacian; max 12/DX^2 for even N."""
    parts = []
    for a, n in enumerate(shape):
        k = 2.0 * np.pi * np.fft.fftfreq(n, d=dx)
        s = (2.0 / dx) ** 2 * np.sin(0.5 * k * dx) ** 2
        sh = [1, 1, 1]
        sh[a] = n
        parts.append(s.reshape(sh))
    return parts[0] + parts[1] + parts[2]


# --------------------------------------------------------------------------- free functions
def _psi_bar(pot, psi_bar):
    return pot.psi_bar if psi_bar is None else float(psi_bar)


def chemical_potential(psi, phi, params, out=None, *, dx=1.0, xi=1.0, psi_bar=None, kBT=1.0,
                       potential=None, lap=None, grad_sq=None):
    """mu = dF/dpsi of eq 17 at the nodes:
    f'(psi) - alpha lap psi + w xi |grad phi|^2 + 2 d (psi - psi_bar) phi.

    ``phi`` may be None (no particles); ``xi`` is A_XI; ``out`` must not alias psi.
    ``lap(f, out)`` / ``grad_sq(f)``: other operators (the oblique frame's metric ones)."""
    pot = make_potential(params, kBT) if potential is None else potential
    out = pot.df(psi, out=out)
    lap = (lambda f, o: _lap(f, dx, o)) if lap is None else lap
    grad_sq = (lambda f: _grad_sq(f, dx)) if grad_sq is None else grad_sq
    out -= params.alpha * lap(psi, np.empty_like(psi))
    if phi is not None:
        if params.w != 0.0:
            out += (params.w * xi) * grad_sq(phi)
        if params.d != 0.0:
            out += (2.0 * params.d) * (psi - _psi_bar(pot, psi_bar)) * phi
    return out


def free_energy(psi, phi, params, *, dx=1.0, xi=1.0, psi_bar=None, kBT=1.0, potential=None):
    """Discrete F of eq 17 (forward-difference |grad psi|^2), whose exact gradient
    dF/dpsi_i / DX^3 is ``chemical_potential``."""
    pot = make_potential(params, kBT) if potential is None else potential
    dens = np.array(pot.f(psi), dtype=np.float64)
    g2 = np.zeros_like(dens)
    for ax in range(3):
        df = np.empty_like(dens)
        df[...] = -psi
        ops.shift_add(df, psi, 1, ax)
        g2 += df * df
    dens += (0.5 * params.alpha / (dx * dx)) * g2
    if phi is not None:
        if params.w != 0.0:
            dens += (params.w * xi) * _grad_sq(phi, dx) * psi
        if params.d != 0.0:
            dens += params.d * (psi - _psi_bar(pot, psi_bar)) ** 2 * phi
    return float(dens.sum()) * dx ** 3


def capillary_force(psi, mu, rho, dx=1.0, out=None, grad=None):
    """-(psi/rho) grad mu (eq 15) at the nodes, central differences; (3, NX, NY, NZ).
    ``grad(f, out)``: another gradient (the oblique frame's)."""
    if out is None:
        out = np.empty((3,) + psi.shape)
    if grad is None:
        _grad(mu, dx, out)
    else:
        grad(mu, out)
    out *= -1.0 / rho
    out *= psi
    return out


# --------------------------------------------------------------------------- solver
class CahnHilliard:
    """Cahn-Hilliard solver (eqs 16-17, 30-31) for psi of shape (NX, NY, NZ).

    ``params`` is a ``kapsel.config.PhaseField`` (ch_solver, tolerance, maximum_iteration,
    potential and its parameters); ``xi`` = A_XI (wetting term); ``psi_bar`` overrides the
    neutral composition; ``kBT`` is the Flory-Huggins energy unit (1, see potentials.py);
    ``preconditioner``: None (original), 'jacobi' or 'fft' (exact inverse of the
    constant-coefficient part c0 + dt kappa alpha K^4); ``threads`` for the FFTs.
    """

    def __init__(self, shape, dx, params, dt, threads=1, *, xi=1.0, psi_bar=None, kBT=1.0,
                 preconditioner=None):
        self.shape = tuple(int(n) for n in shape)
        if len(self.shape) != 3 or min(self.shape) < 1:
            raise ValueError("shape must be (NX, NY, NZ)")
        if params.ch_solver not in ("explicit_scheme", "implicit_scheme"):
            raise ValueError("ch_solver must be 'explicit_scheme' or 'implicit_scheme', not %r"
                             % (params.ch_solver,))
        if preconditioner not in (None, "jacobi", "fft"):
            raise ValueError("preconditioner must be None, 'jacobi' or 'fft'")
        self.dx, self.dt = float(dx), float(dt)
        self.params = params
        self.scheme = params.ch_solver
        self.tolerance = float(params.tolerance)
        self.maximum_iteration = int(params.maximum_iteration)
        self.kappa, self.alpha = float(params.kappa), float(params.alpha)
        self.xi = float(xi)
        self.threads = int(threads)
        self.preconditioner = preconditioner
        self.potential = make_potential(params, kBT)
        self.psi_bar = _psi_bar(self.potential, psi_bar)
        self.psi_old = None          # psi^{n-1} (restart PSI_OLD); None before the first step
        self.iterations = 0
        self.residual = 0.0
        self._k2 = discrete_k2(self.shape, self.dx)
        self._a = np.empty(self.shape)
        self._b = np.empty(self.shape)
        self._c = np.empty(self.shape)

    # ------------------------------------------------------------------ fields
    def initial_field(self, rng):
        """composition_ratio + initial_fluctuation * U(-1, 1) at every node (table 3).

        Landau: psi is the order parameter itself (the sample's 0.0 is the symmetric quench);
        Flory-Huggins: psi is the volume fraction of A, composition_ratio in (0, 1)."""
        p = self.params
        psi = rng.uniform(-1.0, 1.0, size=self.shape)
        psi *= p.initial_fluctuation
        psi += p.composition_ratio
        return psi

    def chemical_potential(self, psi, phi=None, out=None):
        """mu of eq 17 (see ``chemical_potential``)."""
        return chemical_potential(psi, phi, self.params, out=out, dx=self.dx, xi=self.xi,
                                  psi_bar=self.psi_bar, potential=self.potential,
                                  lap=self._lap, grad_sq=self._grad_sq)

    def free_energy(self, psi, phi=None):
        return free_energy(psi, phi, self.params, dx=self.dx, xi=self.xi,
                           psi_bar=self.psi_bar, potential=self.potential)

    def capillary_force(self, psi, mu, rho, out=None):
        """-(psi/rho) grad mu for the Navier-Stokes equation (eq 15), (3, NX, NY, NZ)."""
        return capillary_force(psi, mu, rho, self.dx, out, grad=self._grad)

    def conserving_force(self, psi, mu, rho, out=None):
        """-(psi/rho) grad mu with its local part in exact gradient form (eq 15):
        psi grad f'(psi) = grad(psi f'(psi) - f(psi)), so

            F = -(1/rho) [grad(psi f' - f) + psi grad(mu - f')].

        Equal to ``capillary_force`` in the continuum; on the grid its sum vanishes to
        round-off without particles (the central gradient of a field sums to zero, and
        sum psi grad(lap psi) = 0 for any antisymmetric difference and symmetric Laplacian
        that commute), where -psi grad f'(psi) alone leaves a net force from the cubic term
        that drove the whole box (issue 12).  The particle terms of mu keep their net force:
        ``particle_force`` gives it, and the model hands its reaction to the particles."""
        pot = self.potential
        fp = pot.df(psi, out=self._a)
        nonlocal_mu = np.subtract(mu, fp, out=self._b)
        out = self._grad(nonlocal_mu, np.empty((3,) + psi.shape) if out is None else out)
        out *= psi
        np.multiply(psi, fp, out=self._c)
        self._c -= pot.f(psi)
        grad_p = self._grad(self._c, np.empty_like(out))
        out += grad_p
        out *= -1.0 / rho
        return out

    def particle_force(self, psi, phi, rho):
        """-(psi/rho) grad mu_p, mu_p = w xi |grad phi|^2 + 2 d (psi - psi_bar) phi: the force
        the particles' terms of eq 17 exert on the fluid (nonzero within two nodes of the
        particle profiles)."""
        p = self.params
        mu_p = np.zeros(psi.shape)
        if p.w != 0.0:
            mu_p += (p.w * self.xi) * self._grad_sq(phi)
        if p.d != 0.0:
            mu_p += (2.0 * p.d) * (psi - self.psi_bar) * phi
        out = self._grad(mu_p, np.empty((3,) + psi.shape))
        out *= psi
        out *= -1.0 / rho
        return out

    # operators (overridden by the oblique frame's CH, kapsel.fluid.oblique)
    def _lap(self, f, out):
        return _lap(f, self.dx, out)

    def _grad(self, f, out):
        return _grad(f, self.dx, out)

    def _grad_sq(self, f):
        return _grad_sq(f, self.dx)

    def _div_flux(self, psi, u, out, work):
        return _div_flux(psi, u, self.dx, out, work)

    def total(self, psi):
        """sum psi DX^3 (conserved)."""
        return float(np.sum(psi)) * self.dx ** 3

    # ------------------------------------------------------------------ stability
    def growth_rate(self, k2, fpp):
        """omega(K) = -kappa K^2 (f'' + alpha K^2) of the linearised equation."""
        return -self.kappa * k2 * (fpp + self.alpha * k2)

    def _fpp_max(self, psi, phi):
        if psi is None:
            try:
                pts = np.array(self.potential.equilibrium())
            except ValueError:              # one-phase parameters: the mean composition
                pts = np.array([self.params.composition_ratio])
            fpp = float(np.max(self.potential.d2f(pts)))
        else:
            fpp = float(np.max(self.potential.d2f(psi)))
        if phi is not None and self.params.d > 0:
            fpp += 2.0 * self.params.d * float(np.max(phi))
        return fpp

    def stable_dt(self, psi=None, phi=None):
        """Largest dt with |G| <= 1 for every decaying mode of the linearised scheme (mesh
        K^2; frozen coefficients with the largest f''(psi) (+ 2 d phi) of the field, or of
        the bulk values when psi is None).  explicit: G = 1 + dt omega, i.e.
        dt <= 2 / (kappa K^2 (f'' + alpha K^2)); implicit: roots of the BDF2/AB2 recurrence
        (``amplification``).  Advection is not included (central differences)."""
        fpp = self._fpp_max(psi, phi)
        k2 = np.unique(self._k2)
        k2 = k2[k2 > 0]
        om = self.growth_rate(k2, fpp)
        dec = om < 0
        if not dec.any():
            return math.inf
        if self.scheme == "explicit_scheme":
            return float(np.min(-2.0 / om[dec]))
        k2 = k2[dec]

        def ok(dt):
            return np.all(np.max(np.abs(self.amplification(k2, fpp, dt)), axis=0)
                          <= 1.0 + 1e-12)
        hi = 1.0
        if ok(hi):
            while ok(hi) and hi < 1e12:
                hi *= 2.0
            if hi >= 1e12:
                return math.inf
            lo = hi / 2.0
        else:
            lo = hi
            while not ok(lo):
                lo /= 2.0
            hi = 2.0 * lo
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if ok(mid):
                lo = mid
            else:
                hi = mid
        return lo

    def amplification(self, k2, fpp, dt=None):
        """Per-step amplification factors of a Fourier mode (u = 0, phi = 0):
        explicit: 1 + dt omega (array like k2); implicit: the two roots (2, ...) of
        (3/2 - dt li) G^2 - (2 + 2 dt le) G + (1/2 + dt le) = 0, with
        le = -kappa K^2 f'' (AB2, explicit) and li = -kappa alpha K^4 (implicit)."""
        dt = self.dt if dt is None else dt
        k2 = np.asarray(k2, dtype=np.float64)
        if self.scheme == "explicit_scheme":
            return 1.0 + dt * self.growth_rate(k2, fpp)
        le = -self.kappa * k2 * fpp
        li = -self.kappa * self.alpha * k2 * k2
        A = 1.5 - dt * li
        B = -(2.0 + 2.0 * dt * le)
        C = 0.5 + dt * le
        disc = np.sqrt(B * B - 4.0 * A * C + 0j)
        return np.stack([(-B + disc) / (2.0 * A), (-B - disc) / (2.0 * A)])

    def check_stability(self, psi=None, phi=None):
        """Return stable_dt(); raise UnstableTimeStep if dt exceeds it."""
        lim = self.stable_dt(psi, phi)
        if self.dt > lim:
            raise UnstableTimeStep(
                "time step dt = %g exceeds the stability limit %g of the Cahn-Hilliard %s "
                "(kappa K^2 (f'' + alpha K^2) dt <= 2); lower the time increment, sub-step "
                "or use implicit_scheme" % (self.dt, lim, self.scheme))
        return lim

    # ------------------------------------------------------------------ step
    def step(self, psi, u=None, phi=None):
        """Advance psi (NX, NY, NZ) by dt in place; u (3, NX, NY, NZ) node velocity (u^n for
        the explicit, u^{n+1} for the implicit scheme) or None; phi the particle profile or
        None.  psi_old becomes the incoming psi."""
        if psi.shape != self.shape or psi.dtype != np.float64:
            raise ValueError("psi must be float64 of shape %s" % (self.shape,))
        if u is not None and u.shape != (3,) + self.shape:
            raise ValueError("u must have shape %s" % (((3,) + self.shape),))
        if phi is not None and phi.shape != self.shape:
            raise ValueError("phi must have shape %s" % (self.shape,))
        old = psi.copy()
        if self.scheme == "explicit_scheme":
            self._step_explicit(psi, u, phi)
        else:
            self._step_implicit(psi, u, phi)
        self.psi_old = old
        return psi

    def _step_explicit(self, psi, u, phi):
        mu = self.chemical_potential(psi, phi, out=self._a)
        rhs = self._lap(mu, self._b)
        rhs *= self.kappa
        if u is not None:
            rhs -= self._div_flux(psi, u, self._a, self._c)
        rhs *= self.dt
        psi += rhs

    # ---- implicit (eq 31)
    def _apply(self, x, c0, u, dphi, out):
        """A x = c0 x + dt div(x u) + dt kappa alpha lap lap x - dt kappa lap(2 d phi x)."""
        la = self._lap(x, self._a)
        if dphi is not None:
            t = np.multiply(dphi, x, out=self._c)
            la *= self.alpha
            la -= t
            self._lap(la, out)
        else:
            self._lap(la, out)
            out *= self.alpha
        out *= self.dt * self.kappa
        if c0 == 1.0:
            out += x
        else:
            out += c0 * x
        if u is not None:
            out += self.dt * self._div_flux(x, u, self._a, self._c)
        return out

    def _step_implicit(self, psi, u, phi):
        pot, p, dt = self.potential, self.params, self.dt
        n = psi.size
        dphi = None
        if phi is not None and p.d != 0.0:
            dphi = (2.0 * p.d) * phi
        # explicit part g of mu (AB2 extrapolated f', known wetting and psi_bar fields)
        if self.psi_old is None:           # first step: implicit Euler
            c0 = 1.0
            g = pot.df(psi)
            rhs = psi.copy()
            guess = psi.copy()
        else:
            c0 = 1.5
            g = pot.df(psi)
            g *= 2.0
            g -= pot.df(self.psi_old)
            rhs = 2.0 * psi - 0.5 * self.psi_old
            guess = 2.0 * psi - self.psi_old
        if phi is not None:
            if p.w != 0.0:
                g += (p.w * self.xi) * self._grad_sq(phi)
            if dphi is not None:
                g -= dphi * self.psi_bar
        rhs += (dt * self.kappa) * self._lap(g, np.empty(self.shape))
        # mean of the solution is exact (column sums of A are c0); solve for the rest
        m = float(np.sum(rhs)) / (c0 * n)
        shape = self.shape
        ones_img = self._apply(np.full(shape, m), c0, u, dphi, np.empty(shape))
        b = (rhs - ones_img).ravel()
        y0 = guess.ravel() - m
        y0 -= np.mean(y0)
        tmp = np.empty(shape)

        def mv(v):
            return self._apply(v.reshape(shape), c0, u, dphi, tmp).ravel().copy()
        A = LinearOperator((n, n), matvec=mv, dtype=np.float64)
        y = self._bicgstab(A, b, y0, c0, dphi)
        x = y.reshape(shape) + m
        x += m - float(np.mean(x))          # round-off cleanup of the exact mean
        psi[...] = x

    def _precond(self, c0, dphi, n):
        if self.preconditioner is None:
            return None
        if self.preconditioner == "jacobi":
            dg = np.full(self.shape, c0 + self.dt * self.kappa * self.alpha * 42.0
                         / self.dx ** 4)
            if dphi is not None:
                dg += (6.0 * self.dt * self.kappa / self.dx ** 2) * dphi
            inv = (1.0 / dg).ravel()
            return LinearOperator((n, n), matvec=lambda v: inv * v, dtype=np.float64)
        sym = c0 + self.dt * self.kappa * self.alpha * self._k2 ** 2
        half = 1.0 / sym[:, :, : self.shape[2] // 2 + 1]
        key = (float(c0), self.dt)
        if getattr(self, "_fourier_key", None) != key:      # plans once, symbol per c0
            from ..linalg import FourierDiagonal
            self._fourier = FourierDiagonal(self.shape, half, self.threads)
            self._fourier_key = key
        return LinearOperator((n, n), matvec=self._fourier.solve, dtype=np.float64)

    def _bicgstab(self, A, b, x0, c0, dphi):
        x, self.iterations, self.residual = solve_correction(
            A, b, x0, self.tolerance, self.maximum_iteration,
            M=self._precond(c0, dphi, b.size),
            what="implicit Cahn-Hilliard solver (BiCGSTAB)")
        return x
