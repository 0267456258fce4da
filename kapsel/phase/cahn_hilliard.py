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
  psi inside particles to the neutral composition psi_bar: 0 for Landau, 0.5 for
  Flory-Huggins (the original's values, see potentials.py).  It does not
  depend on composition_ratio (override with ``psi_bar=``).

Surface terms of the newer define.udf (PHYSICS-EXTRA.md §1.3, §2.5), all 0 by default
-----------------------------------------------------------------------------------------
F gains ``z phi_s |grad psi|^2`` (phi_s = min(phi + phi_wall, 1), the solids),
``w_wall xi |grad phi_wall|^2 psi`` (wetting of the walls' faces) and
``d (psi - psi_n,wall)^2 phi_wall`` (the wall's interior), so

    mu = f'(psi) - div((alpha + 2 z phi_s) grad psi) + w xi |grad phi|^2
         + w_wall xi |grad phi_wall|^2 + 2 d (psi - psi_n) phi + 2 d (psi - psi_n,wall) phi_wall

with the neutral values of the original (Landau) psi_n = [a psi_0^3 - (b - 2 d) psi_0] / (2 d)
for psi_0 = psi_0_p (particles) and psi_0_wall (walls), which make f'(psi_0) + 2 d (psi_0 -
psi_n) = 0: psi relaxes to psi_0 inside the solids.  (Flory-Huggins: psi_bar for both.)
Differences from the original, on purpose: it writes -(alpha + 2 z phi) lap psi - 2 z
grad phi_p . grad psi, with the walls in the first phi and not in the second, which is the
variational derivative of no free energy; here the z term is the exact derivative
-div(2 z phi_s grad psi) (face-centred: the derivative of the forward-difference |grad psi|^2
with phi_s averaged on each face); the original's implicit matrix discretises the same
lap(div(phi grad psi)) by a 25-point stencil whose column sums are not zero, so its mean psi
drifts whenever z != 0 (measured: a pinned sphere, z = -0.1, 32^3: the mean of PSI_ALL
-2.1028e-4 at step 10, -2.1615e-4 at step 100; constant to round-off with z = 0), and it
scales z there by xi = sqrt(alpha / 2b) (``z_width``, kept here in the implicit scheme: the
strength of the original's implicit z term), not in its mu.  The original holds psi only in the half of the wall
solid next to lo (its phi'_wall) and leaves the other half free, so an interface can run
through the solid at the upper face; here the whole solid is held at psi_0_wall.  psi_dry
(dry walls) is refused.

Wetting angle: Young's law, cos theta_A = (gamma_BW - gamma_AW) / gamma_AB for the angle in
the A (psi > 0) phase, with gamma_XW the excess free energy per unit area of the bulk phase
X = A (+psi_eq) or B (-psi_eq), psi_eq = sqrt(b/a), against a wall face, and gamma_AB that
of the A-B interface (continuum Landau value (4/3) sqrt(alpha a / 2) psi_eq^3).  For a weak
field the wall term adds H psi_s per unit face area, H = w_wall xi integral |d phi_wall/dn|^2
dn, psi_s the composition where |grad phi_wall| is large; psi_s is not psi_eq but about half
of it, since psi falls to psi_0_wall inside the solid across the same interface: the
estimate -2 H psi_eq / gamma_AB would give 120 degrees where the free energy gives 103
degrees.  ``wetting_angle`` therefore evaluates the three tensions exactly on the mesh, from
one-dimensional profiles relaxed to their free-energy minimum (F of this module).

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
  Euler step with f'(psi^n), and so is the second in a run (the model passes ``euler``: the
  original's jikan.ts < 2).  The linear system is solved by BiCGSTAB (no preconditioner by
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

from ..mesh import operators as ops
from ..mesh.grid import Grid
from ..mesh.halo import Halo
from ..errors import SolverDidNotConverge, UnstableTimeStep  # noqa: F401
from ..mesh.linalg import solve_correction  # noqa: F401
from ..state import ModelState

__all__ = ["CahnHilliard", "chemical_potential", "free_energy", "capillary_force",
           "discrete_k2", "div_coef_grad", "neutral_value", "wetting_angle", "SolverDidNotConverge", "UnstableTimeStep"]


# --------------------------------------------------------------------------- FD helpers
# (the periodic shifts and the 7-point Laplacian are the MAC solver's: kapsel.mesh.operators)
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


def discrete_k2(shape, dx, block=None):
    """K^2 = sum_a (2/DX)^2 sin^2(k_a DX/2) of every mesh mode (full FFT order), -symbol of
    the 7-point Laplacian; max 12/DX^2 for even N.  ``block``: ((x0, x1), (y0, y1), (z0,
    z1)), the modes of a distributed run's Fourier block only (the same values, cut)."""
    parts = []
    for a, n in enumerate(shape):
        k = 2.0 * np.pi * np.fft.fftfreq(n, d=dx)
        if block is not None:
            k = k[block[a][0]:block[a][1]]
        n = k.size
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


def div_coef_grad(c, f, dx):
    """div(c grad f) with face-centred differences: c averaged on the faces (the exact
    derivative of sum c_face (f_{i+1} - f_i)^2 / 2, up to the sign)."""
    out = np.zeros_like(f)
    for ax in range(3):
        df = np.roll(f, -1, axis=ax) - f
        df *= 0.5 * (c + np.roll(c, -1, axis=ax))
        out += df
        out -= np.roll(df, 1, axis=ax)
    out *= 1.0 / (dx * dx)
    return out


def neutral_value(params, psi0, psi_bar):
    """psi_n with f'(psi0) + 2 d (psi0 - psi_n) = 0 (Landau; the original's formula), or
    psi_bar (Flory-Huggins, or d = 0)."""
    if params.potential != "Landau" or params.d == 0:
        return psi_bar if np.ndim(psi0) == 0 else np.full(np.shape(psi0), psi_bar)
    psi0 = np.asarray(psi0, dtype=float)
    out = (params.a * psi0 ** 3 - (params.b - 2.0 * params.d) * psi0) / (2.0 * params.d)
    return float(out) if out.ndim == 0 else out


def _relaxed_energy(ch, psi, phi=None, iterations=20000, tol=1e-13):
    """F at a local minimum reached from psi by the non-conserved gradient flow
    psi <- psi - tau mu (tau below the flow's stability limit)."""
    tau = 0.5 / (12.0 * (ch.alpha + 2.0 * abs(ch.z)) / ch.dx ** 2 + 3.0 * abs(ch.params.b)
                 + 2.0 * abs(ch.params.d) + 3.0 * abs(ch.params.a))
    for _ in range(iterations):
        mu = ch.chemical_potential(psi, phi)
        psi -= tau * mu
        if np.abs(mu).max() < tol:
            break
    return ch.free_energy(psi, phi)


def wetting_angle(params, wall, xi):
    """Young's contact angle (degrees, in the A phase psi > 0) of the walls' wetting free
    energy for the Landau potential: cos theta = (gamma_BW - gamma_AW) / gamma_AB, each
    surface tension the excess free energy per unit area of a relaxed one-dimensional
    profile on the same mesh and wall (module docstring)."""
    n = wall.shape[wall.axis]
    shape = (1, 1, n)
    w1 = type(wall)(2, wall.DH, shape, wall.dx, wall.xi)
    psi_eq = math.sqrt(params.b / params.a)
    F = {}
    for phase, sign in (("A", 1.0), ("B", -1.0)):
        ch = CahnHilliard(Grid(shape, wall.dx), params, 1.0, xi=xi, wall=w1)
        F[phase] = _relaxed_energy(ch, np.full(shape, sign * psi_eq))
    ch = CahnHilliard(Grid(shape, wall.dx), params, 1.0, xi=xi)
    r = np.arange(n)
    strip = np.where((r >= n // 4) & (r < 3 * n // 4), psi_eq, -psi_eq).reshape(shape)
    flat = ch.free_energy(np.full(shape, psi_eq))
    gamma_ab = (_relaxed_energy(ch, strip.astype(float)) - flat) / 2.0
    area = wall.dx ** 2                              # one mesh column, two faces
    cos_t = (F["B"] - F["A"]) / (2.0 * area) / gamma_ab
    return math.degrees(math.acos(max(-1.0, min(1.0, cos_t))))


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

    ``layout``: the mesh's layout, which gives the shape and the spacing DX
    (kapsel.mesh.grid.Grid(shape, dx) for one process; a rank's block:
    kapsel.mesh.pencil.PencilGrid, docs/distributed.md).  ``shape`` is then the block,
    ``global_shape`` the mesh; the stencils run on the block widened by the halo (one
    layer; the implicit operator by two in one exchange, ``halo2``, when the blocks are
    thick enough), sums, means and maxima are over the ranks in a fixed order, BiCGSTAB
    takes the layout's dot products and the FFT preconditioner its transforms: on one
    process all of these are identities.  Walls need a layout of the whole mesh.
    """

    def __init__(self, layout, params, dt, threads=1, *, xi=1.0, psi_bar=None, kBT=1.0,
                 preconditioner=None, wall=None, state=None):
        shape = tuple(int(n) for n in layout.shape)
        if len(shape) != 3 or min(shape) < 1:
            raise ValueError("shape must be (NX, NY, NZ)")
        dx = layout.dx
        self.grid = layout
        if wall is not None and not self.grid.whole_mesh:
            raise ValueError("walls do not run distributed")
        self.global_shape = tuple(self.grid.shape)
        self.shape = tuple(self.grid.local_shape)
        self.halo = Halo(self.grid, 1)
        try:                  # the implicit operator in one exchange (reach 2), if it fits
            self.halo2 = Halo(self.grid, 2)
        except ValueError:
            self.halo2 = None
        self._step_pads = None
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
        psi_0_p = float(getattr(params, "psi_0_p", 0.0))
        if psi_bar is None and psi_0_p != 0.0:
            self.psi_bar = neutral_value(params, psi_0_p, self.psi_bar)
        self.z = float(getattr(params, "z", 0.0))
        # the original's implicit scheme takes z xi, xi = sqrt(alpha / 2b) the interface
        # width (fdm_matrix_solver.cxx, ps.xi of Init_phase_separation); its chemical
        # potential (capillary force, explicit scheme) takes z.  Flory-Huggins: 1 (the
        # original's b is unset there, its xi not finite)
        self.z_width = 1.0
        if self.scheme == "implicit_scheme" and params.potential == "Landau" and params.b > 0:
            self.z_width = math.sqrt(0.5 * self.alpha / params.b)
        self.wall = wall
        self._wall_pen = self._wall_static = None
        if wall is not None:
            self._set_wall(wall)
        # psi^{n-1} (restart PSI_OLD) in the model's state (kapsel.state.ModelState); None
        # before the first step
        self.state = ModelState() if state is None else state
        self.psi_old = None
        self.iterations = 0
        self.residual = 0.0
        # the modes of this process's block of the half spectrum (which holds every value
        # of K^2): the preconditioner's symbol, this process's part of stable_dt
        self._k2 = discrete_k2(self.global_shape, self.dx, self.grid.spec_range)
        self._a = np.empty(self.shape)
        self._b = np.empty(self.shape)
        self._c = np.empty(self.shape)

    def _set_wall(self, wall):
        """Static wall fields: 2 d phi_wall and w_wall xi |grad phi_wall|^2 - 2 d phi_wall
        psi_n,wall (module docstring)."""
        p = self.params
        static = np.zeros(self.shape)
        w_wall = float(getattr(p, "w_wall", 0.0))
        if w_wall != 0.0:
            static += (w_wall * self.xi) * wall.grad_phi_sq()
        if p.d != 0.0:
            pen = (2.0 * p.d) * np.asarray(wall.phi)
            psi0 = np.asarray(getattr(p, "psi_0_wall", 0.0), dtype=float)
            if psi0.ndim == 2:
                plane = [n for a, n in enumerate(self.shape) if a != wall.axis]
                if psi0.shape[0] < plane[0] or psi0.shape[1] < plane[1]:
                    raise ValueError(f"psi_0_wall user_specify has {psi0.shape[0]} x "
                                     f"{psi0.shape[1]} values; the wall plane has "
                                     f"{plane[0]} x {plane[1]} nodes")
                # [i][j] of the in-plane nodes; a larger table's extra rows and columns are
                # not used (the original reads only the entries it needs)
                psi0 = np.expand_dims(psi0[:plane[0], :plane[1]], wall.axis)
            static -= pen * neutral_value(p, psi0, self.psi_bar)
            self._wall_pen = pen
        self._wall_static = static

    def _solids(self, phi):
        """phi_s = min(phi + phi_wall, 1), or None."""
        if self.wall is None:
            return phi
        if phi is None:
            return np.asarray(self.wall.phi)
        return np.minimum(phi + self.wall.phi, 1.0)

    def _div_coef_grad(self, c, f):
        """div(c grad f) of the z term (face-centred: ``div_coef_grad``)."""
        h = self.halo
        return h.keep(div_coef_grad(h.pad(c, key="chc"), h.pad(f, key="chf"), self.dx))

    def _z_density(self, s, psi):
        """z phi_s |grad psi|^2 per node, the discrete density whose derivative is the z
        term of mu (forward differences, phi_s averaged on the faces)."""
        dens = np.zeros(self.shape)
        for ax in range(3):
            df = np.roll(psi, -1, axis=ax) - psi
            dens += (0.5 * (s + np.roll(s, -1, axis=ax))) * df * df
        dens *= self.z / self.dx ** 2
        return dens

    def _surface_mu(self, psi, phi, out):
        """Adds the z and wall terms of mu (module docstring) to out."""
        if self.z != 0.0:
            s = self._solids(phi)
            if s is not None:
                out -= (2.0 * self.z) * self._div_coef_grad(s, psi)
        if self.wall is not None:
            out += self._wall_static
            if self._wall_pen is not None:
                out += self._wall_pen * psi
        return out

    # ------------------------------------------------------------------ fields
    def initial_field(self, phi=None):
        """The original's initial psi (kapsel.phase.fluctuation): composition_ratio +
        initial_fluctuation U(-1, 1) at every node (table 3) from its fixed-seed generator,
        times (1 - phi) inside the particles (+ phi psi_bar for Flory-Huggins), + psi_0_p
        phi (Landau: the original's psi_all = psi + psi_0_p phi_p).

        Landau: psi is the order parameter itself (the sample's 0.0 is the symmetric quench);
        Flory-Huggins: psi is the volume fraction of A, composition_ratio in (0, 1)."""
        return self._initial(self.global_shape, phi, self.grid.local_real)

    def _initial(self, shape, phi, local):
        from .fluctuation import initial_composition
        psi = np.ascontiguousarray(local(initial_composition(shape, self.params)))
        if phi is not None:
            p = self.params
            psi *= 1.0 - phi
            if p.potential != "Landau":
                psi += self.psi_bar * phi
            else:
                psi += float(getattr(p, "psi_0_p", 0.0)) * phi
        return psi

    def chemical_potential(self, psi, phi=None, out=None):
        """mu of eq 17 (see ``chemical_potential``) with the surface terms."""
        out = chemical_potential(psi, phi, self.params, out=out, dx=self.dx, xi=self.xi,
                                 psi_bar=self.psi_bar, potential=self.potential,
                                 lap=self._lap, grad_sq=self._grad_sq)
        return self._surface_mu(psi, phi, out)

    def free_energy(self, psi, phi=None):
        """Discrete F whose exact gradient / DX^3 is ``chemical_potential``."""
        F = free_energy(psi, phi, self.params, dx=self.dx, xi=self.xi,
                        psi_bar=self.psi_bar, potential=self.potential)
        dens = np.zeros(self.shape)
        if self.z != 0.0:
            s = self._solids(phi)
            if s is not None:
                dens += self._z_density(s, psi)
        if self.wall is not None:
            dens += self._wall_static * psi
            if self._wall_pen is not None:
                dens += 0.5 * self._wall_pen * psi * psi
        return F + float(dens.sum()) * self.dx ** 3

    def capillary_force(self, psi, mu, rho, out=None):
        """-(psi/rho) grad mu for the Navier-Stokes equation (eq 15), (3, NX, NY, NZ)."""
        return capillary_force(psi, mu, rho, self.dx, out, grad=self._grad)

    # operators on the block widened by the halo (overridden by the oblique frame's CH,
    # kapsel.fluid.oblique)
    def _lap(self, f, out):
        h = self.halo
        L = _lap(h.pad(f, key="ch"), self.dx, h.target(out, f.shape[:-3], "chlap"))
        return h.keep(L, out)

    def _grad(self, f, out):
        h = self.halo
        G = _grad(h.pad(f, key="ch"), self.dx, h.target(out, (3,), "chgrad"))
        return h.keep(G, out)

    def gradient(self, f, out):
        """The central gradient of ``f`` (the frame's: physical components in an oblique
        one) into ``out`` (3, ...)."""
        return self._grad(f, out)

    def _grad_sq(self, f):
        g = self._grad(f, np.empty((3,) + f.shape))
        return np.einsum("i...,i...->...", g, g)

    def _div_flux(self, psi, u, out, work):
        h = self.halo
        D = _div_flux(h.pad(psi, key="chpsi"), h.pad(u, key="chu"), self.dx,
                      h.target(out, (), "chdiv"), h.target(work, (), "chwork"))
        return h.keep(D, out)

    def total(self, psi):
        """sum psi DX^3 (conserved)."""
        return self._sum(psi) * self.dx ** 3

    # reductions over the ranks of the layout (identities on one process)
    def _sum(self, a):
        return self.grid.sum(float(np.sum(a)))

    def _mean(self, a):
        return self._sum(a) / self.grid.size

    def _max(self, x):
        return self.grid.max(x)

    def _count(self, a):
        return self.grid.size

    # ------------------------------------------------------------------ stability
    def growth_rate(self, k2, fpp):
        """omega(K) = -kappa K^2 (f'' + alpha K^2) of the linearised equation."""
        return -self.kappa * k2 * (fpp + (self.alpha + 2.0 * max(self.z, 0.0)) * k2)

    def _fpp_max(self, psi, phi):
        if psi is None:
            try:
                pts = np.array(self.potential.equilibrium())
            except ValueError:              # one-phase parameters: the mean composition
                pts = np.array([self.params.composition_ratio])
            fpp = float(np.max(self.potential.d2f(pts)))
        else:
            fpp = self._max(float(np.max(self.potential.d2f(psi))))
        if (phi is not None or self.wall is not None) and self.params.d > 0:
            fpp += 2.0 * self.params.d * self._max(float(np.max(self._solids(phi))))
        return fpp

    def stable_dt(self, psi=None, phi=None):
        """Largest dt with |G| <= 1 for every decaying mode of the linearised scheme (mesh
        K^2; frozen coefficients with the largest f''(psi) (+ 2 d phi) of the field, or of
        the bulk values when psi is None).  explicit: G = 1 + dt omega, i.e.
        dt <= 2 / (kappa K^2 (f'' + alpha K^2)); implicit: roots of the BDF2/AB2 recurrence
        (``amplification``).  Advection is not included (central differences).  Over the
        ranks: the smallest of their limits over their Fourier blocks (each an interval of
        stable dt)."""
        return -self.grid.max(-self._stable_dt(psi, phi))

    def _stable_dt(self, psi, phi):
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

    @property
    def psi_old(self):
        """psi^{n-1}, the state's ``psi_old`` (None before the first step)."""
        return self.state.get("psi_old")

    @psi_old.setter
    def psi_old(self, value):
        self.state.put("psi_old", value)

    # ------------------------------------------------------------------ step
    def step(self, psi, u=None, phi=None, euler=False):
        """Advance psi (NX, NY, NZ) by dt in place; u (3, NX, NY, NZ) node velocity (u^n for
        the explicit, u^{n+1} for the implicit scheme) or None; phi the particle profile or
        None.  psi_old becomes the incoming psi.  ``euler``: the implicit scheme takes an
        implicit Euler step even with psi_old (the original's first two steps, sp_3d_ns.cxx
        Time_evolution_hydro_fdm: jikan.ts < 2)."""
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
            self._step_implicit(psi, u, phi, euler)
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
        """A x = c0 x + dt div(x u) + dt kappa alpha lap lap x - dt kappa lap(2 d phi x);
        during a step with ``halo2``, on x widened by two ghost layers (the Laplacian of
        the Laplacian has reach 2): the same operations point by point, one exchange."""
        pads = self._step_pads
        if pads is None:
            return self._operator(x, c0, u, dphi, out, self._lap, self._div_flux,
                                  self._a, self._c, self._a, self._c)
        h = self.halo2
        D = None
        if dphi is not None:
            src, D = pads["dphi"]
            if src is not dphi:
                D = h.pad(dphi, key="dphi")
                pads["dphi"] = (dphi, D)
        dx = self.dx
        o = self._operator(h.pad(x, key="x"), c0, None if u is None else pads["u"], D,
                           h.target(out, (), "o"), lambda f, w: _lap(f, dx, w),
                           lambda f, v, w, w2: _div_flux(f, v, dx, w, w2),
                           h.work((), "la"), h.work((), "t"), h.work((), "df"),
                           h.work((), "dfw"))
        return h.keep(o, out)

    def _operator(self, x, c0, u, dphi, out, lap, div_flux, la, t, df, dfw):
        """``_apply`` with the stencils ``lap(f, out)``, ``div_flux(psi, u, out, work)`` and
        the work arrays la, t (df, dfw: those of div_flux, may be la, t)."""
        la = lap(x, la)
        if dphi is not None:
            t = np.multiply(dphi, x, out=t)
            la *= self.alpha
            la -= t
            lap(la, out)
        else:
            lap(la, out)
            out *= self.alpha
        out *= self.dt * self.kappa
        if c0 == 1.0:
            out += x
        else:
            out += c0 * x
        if u is not None:
            out += self.dt * div_flux(x, u, df, dfw)
        return out

    def _step_implicit(self, psi, u, phi, euler=False):
        h = self.halo2
        if h is None:
            return self._implicit(psi, u, phi, euler)
        # u and the particle term padded once for the solve (kept with their source)
        self._step_pads = {"u": None if u is None else h.pad(u, key="u"), "dphi": (None, None)}
        try:
            return self._implicit(psi, u, phi, euler)
        finally:
            self._step_pads = None

    def _implicit(self, psi, u, phi, euler):
        pot, p, dt = self.potential, self.params, self.dt
        n = psi.size
        dphi = dphi_p = None
        if phi is not None and p.d != 0.0:
            dphi = dphi_p = (2.0 * p.d) * phi
        if self._wall_pen is not None:
            dphi = self._wall_pen if dphi is None else dphi + self._wall_pen
        # explicit part g of mu (AB2 extrapolated f', known wetting and psi_bar fields)
        if self.psi_old is None or euler:   # first step(s): implicit Euler
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
            if dphi_p is not None:
                g -= dphi_p * self.psi_bar
        if self.wall is not None:
            g += self._wall_static
        if self.z != 0.0:               # explicit, extrapolated like f' (linear in psi)
            s = self._solids(phi)
            if s is not None:
                g -= (2.0 * self.z * self.z_width) * self._div_coef_grad(s, guess)
        rhs += (dt * self.kappa) * self._lap(g, np.empty(self.shape))
        # mean of the solution is exact (column sums of A are c0); solve for the rest
        m = self._sum(rhs) / (c0 * self._count(rhs))
        shape = self.shape
        ones_img = self._apply(np.full(shape, m), c0, u, dphi, np.empty(shape))
        b = (rhs - ones_img).ravel()
        y0 = guess.ravel() - m
        y0 -= self._mean(y0)
        tmp = np.empty(shape)

        def mv(v):
            return self._apply(v.reshape(shape), c0, u, dphi, tmp).ravel().copy()
        A = LinearOperator((n, n), matvec=mv, dtype=np.float64)
        y = self._bicgstab(A, b, y0, c0, dphi)
        x = y.reshape(shape) + m
        x += m - float(self._mean(x))       # round-off cleanup of the exact mean
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
            self._fourier = self.grid.fourier_diagonal(half, self.threads)
            self._fourier_key = key
        return LinearOperator((n, n), matvec=self._fourier.solve, dtype=np.float64)

    def _bicgstab(self, A, b, x0, c0, dphi):
        x, self.iterations, self.residual = solve_correction(
            A, b, x0, self.tolerance, self.maximum_iteration,
            M=self._precond(c0, dphi, b.size),
            what="implicit Cahn-Hilliard solver (BiCGSTAB)", dot=self.grid.dots)
        return x
