"""Simple shear flow in the oblique (sheared) frame: the Lees-Edwards types (manual §5.1,
eqs 27-29; Kobayashi & Yamamoto 2011, Molina et al. 2016).

Imposed flow and frame
----------------------
The imposed flow is U = gamma_dot(t) (y - y0) e_x with the shear origin y0 = Ly/2 (the box
centre: a particle there does not translate).  ``ShearFlow``: DC gamma_dot(t) = Shear_rate;
AC gamma_dot(t) = Shear_rate cos(2 pi Frequency t) (Frequency in cycles per tau).  The applied
strain is Gamma(t) = int_0^t gamma_dot for DC; for AC the original's discrete one, the left sum
dt sum_{m<n} gamma_dot(m dt) after n steps, with the rate of a step's start for what follows it
(``_ObliqueFrame.strain_at``, ``rate_at``).

Oblique coordinates x^ = x - g (y - y0), y^ = y, z^ = z, with g the *frame strain*: Gamma(t)
minus the re-mappings done so far (the frame moves with U).  A grid point (i, j, k) of the
oblique grid sits at the physical point (i DX + g (j DX - y0), j DX, k DX).  Fields periodic in the oblique coordinates are exactly the
Lees-Edwards periodic ones (the image across the y boundary is displaced by g Ly along x).
Covariant basis e^_1 = e_x, e^_2 = g e_x + e_y, e^_3 = e_z; a vector has contravariant
components u^1 = u_x - g u_y, u^2 = u_y, u^3 = u_z; the metric G^ij is eq 29 (g for
gamma_dot t).  Oblique wavenumbers k^ (integer multiples of 2 pi / L of the oblique grid)
correspond to the physical wavevector K = (k^_1, k^_2 - g k^_1, k^_3) and
G^jk k^_j k^_k = |K|^2.

Re-mapping: when |g| exceeds s/2 (s = Lx / Ly, the strain at which the images line up
again) the frame is replaced by g -/+ s; the field is the same physical field, sampled on
the new oblique grid.  In Fourier space this is exact: mode (m1, m2) becomes (m1, m2 -/+ m1)
times the phase exp(+/- i k1 s y0) (for any aspect ratio); modes that would leave the
resolved band are dropped.  On a grid in
real space the rows shift by s j points: an exact permutation when Nx is a multiple of Ny,
else an interpolation along x (``OBL_INT``).

``ObliqueSpectralNS``: the deviation u^ = u - U in contravariant components, eq 27-28,

    d_t u^i + u^j d^_j u^i = -G^ij d^_j p / RHO + nu G^jk d^_j d^_k u^i - 2 gamma_dot u^2 delta_i1,
    d^_j u^j = 0,

pseudo-spectrally: u^j d^_j u^i in rotational form (physical u x omega, 2/3 rule in the
oblique index space), the pressure by the metric projection
P^G v = v - G k^ (k^.v) / (k^ G k^) (k^.v = K.v_cartesian: the projection is the Cartesian one
with K), the viscous term integrated exactly over the step with the time-averaged
|K|^2 of the step's start (as the original: first order in dt), the rest by the slaved Euler (ETD1) step of
``SpectralNS``.  Each step starts by truncating the state to the 2/3 band, as the
original's (operate_omega.cxx Zeta_k2advection_k_OBL truncates zeta before the advection;
the compiled step does it in the pass of the projection and update, the first to touch u^
off the band),
so the high modes the particles' rigidity increment puts into u^ (add_solenoidal: projected,
not truncated, as Solenoidal_uk_OBL) last until the next step only.  AC shear: the imposed flow is taken as quasi-static (no d_t U term, as the
original's oblique formulation).  The interface the SPM driver uses is the one of
``SpectralNS`` (``step``, ``velocity(out)``: Cartesian deviation on the oblique grid,
``add_solenoidal(du)``: Cartesian increment) plus the frame for the particles
(``frame_strain``, ``shear_rate_now``, ``background``, ``wrap_particles``).

Interpolation between oblique and rectangular grids (kapsel.mesh.regrid: ``to_rectangular``,
``to_oblique``, ``shift_rows``): along x per row, ``linear`` (2 points) or ``spline`` (periodic cubic
B-spline interpolant), ``switch.ns_solver.OBL_INT``.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..frame import ShearFlow, lees_edwards_wrap
from ..mesh.grid import Grid
from ..mesh.oblique import (_d11, _d12, cartesian, contravariant, oblique_gradient,
                            oblique_viscous_variable)
from ..mesh.regrid import INTERPOLATIONS, shift_rows, to_rectangular
from ..mesh.halo import Halo
from .mac import MACSolver
from .spectral import SpectralNS, cross_in_place, phi1
from ..mesh import compiled as _compiled

__all__ = ["ObliqueSpectralNS", "ObliqueMAC", "MetricProjector"]


# ---------------------------------------------------------------------------- frame
class _ObliqueFrame:
    """Clock and frame of a sheared solver: ``time``, the re-mapping count, the frame strain
    g and what the SPM driver asks of an oblique fluid."""

    oblique = True

    def _init_frame(self, shear, box, dt, t0=0.0, frame_strain0=None):
        self.shear = shear
        self.time = float(t0)
        self.frame_dt = float(dt)
        Lx, Ly = float(box[0]), float(box[1])
        self.s = Lx / Ly                       # strain of one re-mapping
        self.y0 = 0.5 * Ly
        self.Ly = Ly
        self.frame_box = np.array(box, dtype=float)
        self.max_frame_strain = 0.5 * self.s + abs(shear.rate0) * dt * 2 + 1e-12
        g = self.strain_at(self.time)
        if frame_strain0 is None:
            frame_strain0 = g - self.s * math.floor(g / self.s + 0.5)
        if abs(frame_strain0) > self.max_frame_strain:
            raise ValueError(f"frame strain {frame_strain0} outside [-s/2, s/2] (s = {self.s})")
        self.remaps = int(round((g - frame_strain0) / self.s))
        self.remap_count = 0

    def set_time(self, t, remaps=None):
        """Continue at time t (a restart): the frame of t as a run from 0 reaches it."""
        self.time = float(t)
        if remaps is None:
            g = self.strain_at(self.time)
            remaps = int(math.floor(g / self.s + 0.5))
        self.remaps = int(remaps)

    # The strain and rate of the frame.  DC: Gamma(t) = gamma_dot t.  AC: the original's
    # discrete strain (sp_3d_ns.cxx Time_evolution_hydro_OBL[_fdm]: after the fluid step of
    # step ts it sets Shear_rate_eff = Shear_rate cos(omega dt ts) and adds Shear_rate_eff dt
    # to degree_oblique), so after n steps Gamma_n = dt sum_{m<n} gamma_dot(m dt), the left
    # sum, not the integral; the rate of the frame after step m (the particles' images and
    # wrap, the imposed flow, and the next fluid step's Coriolis term and metric) is
    # gamma_dot(m dt), the rate at the start of that step.
    def _steps(self, t) -> int:
        return int(round(t / self.frame_dt))

    def strain_at(self, t) -> float:
        """Applied strain of the frame at time t (DC: Gamma(t); AC: the original's sum
        Gamma_n = Shear_rate dt sum_{m=0}^{n-1} cos(omega m dt), n = t / dt, in the closed
        form sin(n a/2) cos((n - 1) a/2) / sin(a/2), a = omega dt)."""
        sh = self.shear
        if sh.kind != "AC":
            return sh.strain(t)
        n = self._steps(t)
        h = 0.5 * sh.omega * self.frame_dt
        sh_ = math.sin(h)
        total = float(n) if sh_ == 0.0 else math.sin(n * h) * math.cos((n - 1) * h) / sh_
        return sh.rate0 * self.frame_dt * total

    def rate_at(self, t) -> float:
        """Shear rate of the frame at time t (DC: gamma_dot; AC: that of the last step's
        strain increment, gamma_dot(t - dt), and gamma_dot(0) at the start)."""
        sh = self.shear
        if sh.kind != "AC":
            return sh.rate(t)
        n = max(self._steps(t) - 1, 0)
        return sh.rate(n * self.frame_dt)

    @property
    def frame_strain(self) -> float:
        """g of the current oblique grid (the restart's oblique.degree_oblique)."""
        return self.strain_at(self.time) - self.remaps * self.s

    @property
    def applied_strain(self) -> float:
        return self.strain_at(self.time)

    @property
    def shear_rate_now(self) -> float:
        return self.rate_at(self.time)

    @property
    def image_offset(self) -> float:
        """x displacement of the image across the y boundary, g Ly."""
        return self.frame_strain * self.Ly

    def background(self, R):
        """U at the positions R (N, 3): gamma_dot (y - y0) e_x."""
        U = np.zeros_like(np.asarray(R, dtype=float))
        U[:, 0] = self.shear_rate_now * (R[:, 1] - self.y0)
        return U

    def wrap_particles(self, p):
        """Positions p.R (moved by one step from inside the box) into the box through the
        Lees-Edwards images; x velocities shifted for a crossing of the y boundary."""
        lees_edwards_wrap(p.R, p.v, self.frame_box, self.image_offset,
                          self.shear_rate_now, p.v_old)

    def _frames_to_drop(self):
        g = self.frame_strain
        half = 0.5 * self.s
        if -half <= g < half:
            return 0
        return int(math.floor(g / self.s + 0.5))


# ---------------------------------------------------------------------------- fluid
class ObliqueSpectralNS(_ObliqueFrame, SpectralNS):
    """Deviation from the imposed shear flow in the oblique frame (module docstring).

    ``u_hat`` holds the rfftn of the contravariant components u^i on the oblique grid.
    shear : ShearFlow;  t0 : time of the initial state;  frame_strain0 : the frame strain at
    t0 (restart: oblique.degree_oblique), by default Gamma(t0) reduced into [-s/2, s/2).
    """

    def __init__(self, grid: Grid, rho, eta, dt, shear: ShearFlow, fix_cell=(False,) * 3,
                 advection=True, t0=0.0, frame_strain0=None, state=None):
        super().__init__(grid, rho, eta, dt, fix_cell=fix_cell, scheme="etd1",
                         advection=advection, state=state)
        self._init_frame(shear, grid.box, dt, t0, frame_strain0)
        # scratch of this solver's own step: a third complex scalar beside _s and _t (the
        # truncated u^ / N and the vorticity are made and transformed a component at a time)
        self._c3 = grid.empty_complex(None)
        k = grid
        self._k11 = k.kx * k.kx
        self._k12 = k.kx * k.ky
        self._k22 = k.ky * k.ky + k.kz * k.kz      # k2^2 + k3^2
        self._m1 = np.rint(k.kx.ravel() * grid.box[0] / (2 * np.pi)).astype(np.int64)
        self._m2 = np.rint(k.ky.ravel() * grid.box[1] / (2 * np.pi)).astype(np.int64)
        self._K2 = self._invK2 = None     # the numpy passes' metric (the compiled kernels
        self._gK = None                   # make |K|^2 at each mode: no field of it)

    def _metric(self, g):
        """|K|^2 and 1/|K|^2 (0 at k = 0) of the frame strain g into _K2, _invK2."""
        if self._K2 is None:
            self._K2 = np.empty(self.grid.local_cshape)
            self._invK2 = np.empty(self.grid.local_cshape)
        K2 = self._K2
        np.multiply(self._k11, 1.0 + g * g, out=K2)
        K2 -= (2.0 * g) * self._k12
        K2 += self._k22
        np.divide(1.0, K2, out=self._invK2, where=K2 > 0)
        self._invK2[K2 <= 0] = 0.0
        self._gK = g
        return K2

    def project_metric(self, vh, g, rate=0.0, masked=False, add=False):
        """P^G (v - 2 rate u^2 e_1) = v' - G k^ (k^.v') / (k^ G k^), in place
        (contravariant components; the rate term only if rate != 0).  ``masked``: of
        (v - 2 rate u^2 e_1) times the 2/3 mask, 0 off it whatever u_hat holds there (the
        compiled pass does not read v or u_hat there).  ``add``: u_hat += the projection
        (v is left as it was by the compiled pass, projected by the numpy passes)."""
        K = _compiled.spectral
        if K is not None:
            K.project_oblique(vh, self.u_hat, 2.0 * rate, g, *self._k1,
                              *self.grid.dealias_box, masked, add)
            return vh
        if self._gK != g:
            self._metric(g)
        if rate != 0.0:
            vh[0] -= (2.0 * rate) * self.u_hat[1]
        if masked:
            vh *= self.grid.dealias_f
        k = self.grid
        s, t = self._s, self._t
        k.k_dot(vh, s, t)
        s *= self._invK2
        # (G k^)^1 = (1 + g^2) k1 - g k2, (G k^)^2 = k2 - g k1, (G k^)^3 = k3
        np.multiply(s, (1.0 + g * g) * k.kx - g * k.ky, out=t)
        vh[0] -= t
        np.multiply(s, k.ky - g * k.kx, out=t)
        vh[1] -= t
        np.multiply(s, k.kz, out=t)
        vh[2] -= t
        if add:
            self.u_hat += vh
        return vh

    # ------------------------------------------------------------------ state
    def set_velocity(self, u):
        """u^ <- P^G of the Cartesian deviation u (3, NX, NY, NZ) on the oblique grid."""
        g = self.frame_strain
        self.grid.forward(contravariant(np.asarray(u, dtype=float), g), out=self.u_hat)
        self.project_metric(self.u_hat, g)

    def set_contravariant_hat(self, u_hat):
        np.copyto(self.u_hat, u_hat)

    def velocity(self, out=None):
        """Cartesian deviation velocity on the oblique grid."""
        if out is None:
            out = self.grid.empty_real()
        gr, s, t, inv = self.grid, self._s, self._t, 1.0 / self.grid.size
        K = _compiled.spectral
        if K is not None:
            return self._transform_components(K, out, self.frame_strain)
        np.multiply(self.u_hat[0], inv, out=s)
        np.multiply(self.u_hat[1], inv, out=t)
        s += np.multiply(t, self.frame_strain, out=self._c3)   # u_1 = u^1 + g u^2
        gr.backward_scalar_raw(s, out[0])
        gr.backward_scalar_raw(t, out[1])
        np.multiply(self.u_hat[2], inv, out=s)
        gr.backward_scalar_raw(s, out[2])
        return out

    def _cartesian_hat(self, c, g, out, tmp):
        """Component c of the truncated Cartesian u^ / N (u_1 = u^1 + g u^2) into ``out``
        (``tmp``: scratch for c = 0)."""
        np.multiply(self.u_hat[c], self._mask_n, out=out)
        if c == 0:
            np.multiply(self.u_hat[1], self._mask_n, out=tmp)
            tmp *= g                    # g u^2 (no temporary: the same products)
            out += tmp
        return out

    def velocity_rectangular(self, method="linear"):
        """Full velocity U + u^ (Cartesian) on the rectangular grid (for field output)."""
        u = to_rectangular(self.velocity(), self.frame_strain, method,
                           self.y0 / self.grid.dx)
        y = self.grid.coordinates()[1]
        u[0] += self.shear_rate_now * (y - self.y0)
        return u

    # ------------------------------------------------------------------ step
    def _nonlinear_oblique(self, g, rate):
        """P^G[contravariant(u x omega) - 2 gamma_dot u^2 e_1] into _nl (2/3 rule on the
        advection part only)."""
        if self.advection:
            return self.project_metric(self._advection(g), g, rate, masked=True)
        self._nl[...] = 0.0
        return self.project_metric(self._nl, g, rate)

    def _advection(self, g):
        """FFT(contravariant(u x omega)) into _nl, exact on the 2/3 mask only (the mode
        k = 0 zero): u and omega are truncated fields, transformed with the lines of zeros
        skipped (kapsel.mesh.grid); only u^'s 2/3 box is read."""
        gr = self.grid
        nl = self._nl
        a, b, wc = self._s, self._t, self._c3     # complex scalars
        u, w = self._u, self._w
        K = _compiled.spectral
        if K is not None:
            box, inv = gr.dealias_box, self._inv_n    # u and omega in one sweep (nl is
            K.velocity_vorticity(self.u_hat, *box, inv, g, *self._k1, nl, a, b, wc)
            for c in range(3):                         # free until u x omega's transform)
                gr.backward_scalar_truncated(nl[c], u[c])
            for c, x in enumerate((a, b, wc)):
                gr.backward_scalar_truncated(x, w[c])
            K.cross_contravariant(u, w, g)
            n = w
        else:
            cart = self._cartesian_hat
            for c in range(3):                    # u: the truncated Cartesian velocity
                gr.backward_scalar_truncated(cart(c, g, a, b), u[c])
            Ky = gr.ky - g * gr.kx                # physical K_y
            ik = (self._ikx, 1j * Ky, self._ikz)
            for c in range(3):                    # w_c = i k_p u_q - i k_q u_p
                p, q = (c + 1) % 3, (c + 2) % 3
                np.multiply(ik[p], cart(q, g, a, b), out=wc)
                np.multiply(ik[q], cart(p, g, a, b), out=b)
                wc -= b
                gr.backward_scalar_truncated(wc, w[c])
            n = cross_in_place(u, w, self._n)
            n[0] -= g * n[1]                      # contravariant
        gr.forward_truncated(n, nl)
        if self._k0:
            nl[:, 0, 0, 0] = 0.0
        return nl

    def step(self, force=None, velocity=None):
        """Advance u^ by dt (eq 27): u^ <- E u^ + dt phi1 P^G[N + f], then re-map the frame
        if its strain left [-s/2, s/2].  ``velocity``: the new Cartesian deviation u is
        put there (``velocity(out=...)`` after the step)."""
        t0, dt = self.time, self.dt
        g0 = self.frame_strain
        rate = self.rate_at(t0)
        K = _compiled.spectral
        fused = K is not None and self.advection and force is None  # truncation, projection
        if not fused:                             # and update in one pass (on the 2/3 mask
            self.truncate()                       # only: project_oblique_etd1)
        # the original's metric of the step's start (Update_K2_OBL after the last step's
        # strain increment; AC with its discrete strain, _ObliqueFrame.strain_at): the
        # viscous factor is first order in dt, as the original's
        if K is not None:          # (a step's own: no field kept; fused: on the 2/3 box only)
            cx, cy, ix, jy, nk = self._box_rows if fused else (None, None, *self._all_rows)
            z = np.empty((ix.size, jy.size, nk))
            K.viscous_exponent(*self._k1, ix, jy, g0, -self.nu * dt, z)
        else:
            if self._gK != g0:
                self._metric(g0)
            z = np.multiply(self._K2, -self.nu * dt)
        w1 = phi1(z, scale=dt)
        E = np.exp(z, out=z)
        uh = self.u_hat
        tmp = self._c3
        made = False               # the new u / N (Cartesian) in _nl, made by the update
        if fused and velocity is not None:      # the frame after the step (no re-mapping)
            g1 = self.strain_at(t0 + dt) - self.remaps * self.s
            K.project_oblique_etd1_velocity(self._advection(g0), uh, 2.0 * rate, g0,
                                            *self._k1, cx, cy, nk, E, w1, g1, self._inv_n)
            made = True
        elif fused:
            K.project_oblique_etd1(self._advection(g0), uh, 2.0 * rate, g0, *self._k1, cx, cy,
                                   nk, E, w1)
        else:
            nl = self._nonlinear_oblique(g0, rate)
            if K is not None:
                K.etd1_update(uh, nl, E, w1)
            else:
                uh *= E
                for c in range(3):
                    np.multiply(nl[c], w1, out=tmp)
                    uh[c] += tmp
        if force is not None:
            fh = self._nl                             # free from here on
            self.grid.forward(self._contravariant(force, g0), out=fh)
            self.project_metric(fh, g0)
            for c in range(3):
                np.multiply(fh[c], w1, out=tmp)
                uh[c] += tmp
        self.time = t0 + dt
        self.apply_fix_cell()
        self.step_index += 1
        if self._maybe_remap() or not made:
            if velocity is not None:
                self.velocity(out=velocity)
            return
        self._velocity_from_nl(velocity, True, g1)     # (0 off the mask's box)

    def apply_fix_cell(self):
        """Zero the mean Cartesian velocity along the flagged axes."""
        g = self.frame_strain
        if not self._k0:
            return
        m = self.u_hat[:, 0, 0, 0]
        if self.fix_cell[1]:
            m[1] = 0.0
        if self.fix_cell[2]:
            m[2] = 0.0
        if self.fix_cell[0]:
            m[0] = -g * m[1]          # u_x mean = u^1 + g u^2 = 0

    def _maybe_remap(self):
        """Re-map the frame if its strain left [-s/2, s/2]; returns whether it did."""
        n = self._frames_to_drop()
        if n:
            self.remap_fourier(n)
        return bool(n)

    def remap_fourier(self, n):
        """Replace the frame g by g - n s (module docstring): contravariant components
        u^1 += n s u^2 and mode (m1, m2) -> (m1, m2 - n m1); modes leaving the band are
        dropped."""
        if self._dist:
            return self._remap_distributed(n)
        uh = self.u_hat
        uh[0] += (n * self.s) * uh[1]
        ny = self.grid.shape[1]
        m1, m2 = self._m1[:, None], self._m2[None, :]
        new_m2 = m2 - n * m1                                   # (NX, NY)
        keep = (new_m2 >= -((ny - 1) // 2)) & (new_m2 <= (ny - 1) // 2)
        src_i, src_j = np.nonzero(keep)
        dst_j = new_m2[src_i, src_j] % ny
        out = np.zeros_like(uh)
        out[:, src_i, dst_j] = uh[:, src_i, src_j]
        out *= np.exp(1j * self.grid.kx * (n * self.s * self.y0))
        np.copyto(uh, out)
        self.remaps += n
        self.remap_count += 1
        self._gK = None

    def _remap_distributed(self, n):
        """remap_fourier on a distributed grid (kapsel.mesh.pencil): the mode shift runs
        along k_y, split over the ranks of a column, so each column gathers its
        (NX, NY, z block) slab, shifts it as above and keeps its own block again (a re-mapping
        happens once per strain Lx/Ly: rare)."""
        g = self.grid
        (y0, y1), nzb = g.spec_range[1], self.u_hat.shape[3]
        parts = g.comm_x.allgather((y0, y1, self.u_hat))
        ny = g.shape[1]
        uh = np.empty((3, g.shape[0], ny, nzb), dtype=complex)
        for a, b, blk in parts:
            uh[:, :, a:b] = blk
        uh[0] += (n * self.s) * uh[1]
        m2 = np.fft.fftfreq(ny, 1.0 / ny)
        if ny % 2 == 0:
            m2[ny // 2] = ny // 2
        m1, m2 = self._m1[:, None], np.rint(m2).astype(np.int64)[None, :]
        new_m2 = m2 - n * m1
        keep = (new_m2 >= -((ny - 1) // 2)) & (new_m2 <= (ny - 1) // 2)
        src_i, src_j = np.nonzero(keep)
        dst_j = new_m2[src_i, src_j] % ny
        out = np.zeros_like(uh)
        out[:, src_i, dst_j] = uh[:, src_i, src_j]
        out *= np.exp(1j * g.kx * (n * self.s * self.y0))
        np.copyto(self.u_hat, out[:, :, y0:y1])
        self.remaps += n
        self.remap_count += 1
        self._gK = None

    def truncate(self):
        """u^ <- T u^, the 2/3 rule (each step starts with it: module docstring)."""
        K = _compiled.spectral
        if K is not None:
            K.truncate(self.u_hat, *self.grid.dealias_box)
            return
        self.u_hat *= self.grid.dealias_f

    @functools.cached_property
    def _box_rows(self):
        """The 2/3 mask's box (Grid.dealias_box) as rows: (cx, cy, ix, jy, kz_end), cx[i]
        the place of i among the box's rows ix along x (-1 off the box), cy, jy along y."""
        mx, my, kz_end = self.grid.dealias_box
        ix, jy = np.flatnonzero(mx), np.flatnonzero(my)
        cx = np.full(mx.size, -1, dtype=np.int64)
        cy = np.full(my.size, -1, dtype=np.int64)
        cx[ix] = np.arange(ix.size)
        cy[jy] = np.arange(jy.size)
        return cx, cy, ix.astype(np.int64), jy.astype(np.int64), kz_end

    @functools.cached_property
    def _all_rows(self):
        """Every mode as ``_box_rows``'s (ix, jy, kz_end)."""
        n = self.grid.local_cshape
        return np.arange(n[0], dtype=np.int64), np.arange(n[1], dtype=np.int64), n[2]

    @functools.cached_property
    def _n(self):
        """A real vector field of scratch, made on first use: N of the numpy passes, the
        contravariant force and increments (the compiled step and the SPM's increment,
        made contravariant in its own buffer, do not use it)."""
        return self.grid.empty_real()

    def _contravariant(self, u, g):
        """The contravariant components of a Cartesian field u into the scratch _n."""
        K = _compiled.spectral
        u = np.asarray(u, dtype=float)
        if K is not None and u.shape == self._n.shape:
            K.contravariant(u, g, self._n)
            return self._n
        return contravariant(u, g, out=self._n)

    def add_solenoidal(self, du, project=True, overwrite=False):
        """u^ += P^G[FFT(contravariant(du))] for a Cartesian increment du on the oblique grid
        (not truncated, as the original's Solenoidal_uk_OBL).  ``overwrite``: du is the
        caller's scratch, made contravariant in place (one component written instead of a
        copy of three; the same numbers)."""
        g = self.frame_strain
        d = self._nl          # free between steps
        K = _compiled.spectral
        if overwrite and K is not None and du.shape == self._u.shape and du.flags.c_contiguous:
            K.contravariant_in_place(du, g)
            self.grid.forward(du, out=d)
        else:
            self.grid.forward(self._contravariant(du, g), out=d)
        if project:
            self.project_metric(d, g, add=True)
        else:
            self.u_hat += d

    # ------------------------------------------------------------------ diagnostics
    def uxuy_sum(self) -> float:
        """sum over this block's modes of w (Re u_x Re u_y + Im u_x Im u_y), w the half
        spectrum's weights (Grid.half_weight), u the Cartesian deviation: N^2 times the
        mean of u_x u_y over the grid (Parseval), for the Reynolds stress.  Compiled: the
        terms in one pass into the free scratch _n (between steps), summed by numpy as the
        numpy passes' temporary is (the same bits)."""
        uh, g, w = self.u_hat, self.frame_strain, self.grid.half_weight
        K = _compiled.spectral
        if K is not None:
            shape = uh.shape[1:]
            out = self._n.reshape(-1)[:int(np.prod(shape))].reshape(shape)
            K.reynolds_terms(uh, g, w.reshape(-1), out)
            return float(np.sum(out))
        ux = uh[0] + g * uh[1]
        uy = uh[1]
        return float(np.sum(w * (ux.real * uy.real + ux.imag * uy.imag)))

    def momentum(self):
        """RHO DX^3 sum u (Cartesian deviation)."""
        m = self._mean_mode().real.copy()
        m[0] += self.frame_strain * m[1]
        return self.rho * self.grid.dx ** 3 * m

    def mean_velocity(self):
        return self.momentum() / (self.rho * self.grid.dx ** 3 * self.grid.size)

    def kinetic_energy(self):
        """1/2 RHO DX^3 sum |u^|^2 of the deviation (Cartesian)."""
        u = self.velocity()
        e = float(np.sum(u * u))
        if self._dist:
            e = self.grid.sum(e)
        return 0.5 * self.rho * self.grid.dx ** 3 * e

    def divergence_max(self):
        k = self.grid
        d = 1j * (k.kx * self.u_hat[0] + k.ky * self.u_hat[1] + k.kz * self.u_hat[2])
        return float(np.abs(np.fft.irfftn(d, s=k.shape, axes=(0, 1, 2))).max())

    def viscous_stress_xy(self):
        """Mean viscous shear stress ETA <d_y u_x + d_x u_y> of the full flow: ETA gamma_dot
        (the deviation is periodic, its mean gradient vanishes)."""
        return self.eta * self.shear_rate_now


# ---------------------------------------------------------------------------- MAC
class ObliqueMAC(_ObliqueFrame, MACSolver):
    """The MAC schemes (explicit eqs 20-21, implicit eqs 23-26) in the oblique frame: eq 27
    on the B grid for the contravariant deviation u^i.

    * advection in divergence form d^_j (u^j u^i) (the oblique coordinates are affine: no
      Christoffel terms), the unchanged ``operators.advection`` on contravariant components;
    * viscous term nu G^jk d^_j d^_k u^i = nu (lap + g^2 D_xx - 2 g D_xy) u^i (7-point
      Laplacian, second and mixed central differences);
    * -2 gamma_dot u^2 delta_i1 with the known u^n (explicit in both schemes);
    * with a viscosity field (viscosity_change) the full div(eta (grad u + grad u^T)) / RHO
      of the deviation (physical central differences) plus the force of the imposed flow
      gamma_dot (d_y eta, d_x eta, 0) / RHO, which vanishes only for a uniform eta;
    * pressure: contravariant gradient G^ij d^_j p (B-grid gradient, index raised by the
      metric) and the Poisson equation D_j G^jk G_k phi = D_j w^j solved by FFT with the
      B-grid symbol -sum G^jk S_j conj(S_k) (S the div_b symbols; same null modes);
    * the implicit scheme's linear operator is applied matrix-free (``linear='matfree'``:
      the mixed derivative would widen the assembled stencil), with the metric at mid-step.

    The driver passes Cartesian deviation velocities on the oblique grid (as for the
    rectangular MACSolver: ``step(u)``, ``project(u)``); they are converted to contravariant
    components here.  The frame is re-mapped after a step when |g| > s/2: a row shift on the
    grid (exact for Nx a multiple of Ny, else ``interpolation`` = OBL_INT along x) of u,
    u^{n-1} and the pressure; ``take_remap()`` tells the caller (once) by how many frames,
    so that it shifts its scalar fields (psi, psi_old) alike (``shift_scalar``).

    On a rank's block (``layout`` a PencilGrid; docs/distributed.md) the metric pieces run
    on the block widened by the halo (the variable-viscosity term, reach 2, by two layers:
    ``halo2``), the metric Poisson symbol on the local Fourier block, and the re-mapping's
    row shift along x on the rows gathered over the ranks of the x split (``shift_rows``
    of the whole row, this block kept); on the oblique grid the Lees-Edwards fields are
    plainly periodic, so the halo is the periodic one.
    """

    def __init__(self, layout, rho, eta, dt, shear: ShearFlow, scheme="explicit_scheme",
                 tolerance=1e-9, maximum_iteration=1000, threads=1, interpolation="linear",
                 t0=0.0, frame_strain0=None, state=None):
        MACSolver.__init__(self, layout, rho, eta, dt, scheme=scheme, tolerance=tolerance,
                           maximum_iteration=maximum_iteration, threads=threads,
                           linear="matfree", state=state)
        try:                          # the variable-viscosity term (reach 2)
            self.halo2 = Halo(self.grid, 2)
        except ValueError:            # blocks of one point: refused by the model
            self.halo2 = None
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"OBL_INT must be one of {INTERPOLATIONS}")
        self.interpolation = interpolation
        box = np.array(self.shape, dtype=float) * self.dx
        self._init_frame(shear, box, dt, t0, frame_strain0)
        from ..mesh import operators as op
        block = self.grid.spec_range
        S = op.symbol_div_b(self.shape, self.dx, block)
        self._SS = {(a, b): np.real(S[a] * np.conj(S[b])) for a in range(3) for b in range(a, 3)}
        self._null = op.b_grid_null_modes(self.shape, block)
        self._g_op = self.frame_strain
        self._g_inv = None
        self._w = np.empty((3,) + self.fshape)
        self._t1 = np.empty(self.fshape)
        self.remap_fields = 0

    # ------------------------------------------------------------------ metric pieces
    def _poisson_inverse(self, g):
        if self._g_inv == g:
            return
        SS = self._SS
        sym = -((1 + g * g) * SS[0, 0] + SS[1, 1] + SS[2, 2] - 2 * g * SS[0, 1])
        sym = np.where(self._null, 1.0, sym)
        inv = 1.0 / sym
        inv[self._null] = 0.0
        self._poisson.inv = self._scaled_inverse(inv)
        self._g_inv = g

    def _scaled_inverse(self, inv):
        """The Poisson symbol's inverse as the layout's transform pair wants it."""
        return self._poisson.symbol(inv)

    def _lap_inverse(self):
        """-1/|K|^2 of the oblique frame at the step's metric (fdm.h Update_K2_OBL /
        _OBL_hdt: K = (k1, k2 - g k1, k3)), for the original's pressure solve."""
        g = self._g_op
        if getattr(self, "_g_lap", None) != g:
            from ..mesh import operators as op
            kx, ky, kz = op.wavenumbers(self.shape, self.dx, self.grid.spec_range)
            K2 = kx * kx + (ky - g * kx) ** 2 + kz * kz
            inv = np.zeros(np.broadcast_shapes(kx.shape, ky.shape, kz.shape))
            np.divide(-1.0, K2, out=inv, where=K2 > 0)
            self._inv_lap = self._scaled_inverse(inv)
            self._g_lap = g
        return self._inv_lap

    def _solve_phi(self, u):
        self._poisson_inverse(self._g_op)
        return MACSolver._solve_phi(self, u)

    def _grad_p(self, phi):
        gp = MACSolver._grad_p(self, phi)
        g = self._g_op
        t = self._t1
        np.multiply(gp[1], -g, out=t)           # (G grad)^1 = (1 + g^2) G1 - g G2
        gp[1] -= g * gp[0]                      # (G grad)^2 = G2 - g G1
        gp[0] *= 1 + g * g
        gp[0] += t
        return gp

    def _viscous(self, u, eta_field, out):
        g = self._g_op
        if eta_field is not None:     # contravariant u -> Cartesian, div(eta (...)), back
            h = self.halo2
            v = oblique_viscous_variable(h.pad(cartesian(u, g), key="u"),
                                         h.pad(eta_field, key="eta"), self.dx, g)
            contravariant(h.keep(v), g, out=out)
            out *= 1.0 / self.rho
            return out
        MACSolver._viscous(self, u, None, out)   # nu lap u
        if g:
            h = self.halo
            U = self._padded(u, "visc")
            T = h.target(self._v2 if out is not self._v2 else None, (3,), "obl")
            _d11(U, self.dx, T)
            out += (self.nu * g * g) * h.interior(T)
            _d12(U, self.dx, T, work=h.work((3,), "obl2"))
            out -= (2.0 * self.nu * g) * h.interior(T)
        return out

    # ------------------------------------------------------------------ driver interface
    def project(self, u):
        """Cartesian u on the oblique grid made divergence-free (metric projection)."""
        g = self.frame_strain
        self._g_op = g
        w = contravariant(u, g, out=self._w)
        phi = self._solve_phi(w)
        w -= self._grad_p(phi)
        cartesian(w, g, out=u)
        return u

    def divergence(self, u, out=None):
        return MACSolver.divergence(self, contravariant(u, self.frame_strain), out)

    def projection_pressure(self, du):
        """MACSolver.projection_pressure of a Cartesian increment on the oblique grid."""
        self._g_op = self.frame_strain
        return MACSolver.projection_pressure(self, contravariant(du, self.frame_strain))

    def stable_dt(self, u=None, eta_field=None):
        """The rectangular limit with the largest metric factor of the frame: explicit
        diffusion nu (1 + g^2/2 + |g|) ... bounded by nu (2 + s^2 / 4) / DX^2 per axis pair."""
        lim = MACSolver.stable_dt(self, u, eta_field)
        g = self.max_frame_strain
        return lim / (1.0 + (g * g + 2 * g) / 3.0)

    def step(self, u, force=None, eta_field=None):
        """Advance the Cartesian deviation u (on the oblique grid) by dt in place."""
        t0, dt = self.time, self.dt
        g0 = self.frame_strain
        rate = self.rate_at(t0)
        w = contravariant(u, g0, out=self._w)
        if eta_field is not None and rate:
            # the imposed flow is not force-free where eta varies: div(eta (grad U + grad U^T))
            # = gamma_dot (d_y eta, d_x eta, 0)
            ge = self._gradient(eta_field, g0)
            fu = np.zeros_like(w)
            fu[0] = ge[1]
            fu[1] = ge[0]
            fu *= rate / self.rho
            force = fu if force is None else force + fu
        f = np.zeros_like(w) if force is None else contravariant(force, g0)
        f[0] -= 2.0 * rate * w[1]
        if self.scheme == "implicit_scheme":
            self._g_op = self.mid_step_strain(t0)
        else:
            self._g_op = g0
        MACSolver.step(self, w, f, eta_field)
        self.time = t0 + dt
        cartesian(w, self.frame_strain, out=u)
        n = self._frames_to_drop()
        if n:
            self._remap(u, n)
        return u

    def mid_step_strain(self, t0):
        """The frame strain of the implicit step's operators from t0 (the original's
        gt = degree_oblique + Shear_rate_eff dt / 2, fdm.cxx / fdm_matrix_solver.cxx):
        DC Gamma(t0 + dt/2); AC the discrete strain plus half a step at the frame's rate."""
        if self.shear.kind == "AC":
            return self.frame_strain + self.rate_at(t0) * (0.5 * self.dt)
        return self.shear.strain(t0 + 0.5 * self.dt) - self.remaps * self.s

    def _gradient(self, f, g):
        """The physical central gradient of a node field (``oblique_gradient``)."""
        h = self.halo
        G = oblique_gradient(h.pad(f, key="ograd"), self.dx, g, h.target(None, (3,), "ograd"))
        return h.keep(G)

    # ------------------------------------------------------------------ re-mapping
    def row_shift(self, n):
        """Row shifts (grid points) taking a field on the frame g to the frame g - n s."""
        ny = self.shape[1]
        return n * self.s * (np.arange(ny) - self.y0 / self.dx)

    def _shift(self, f, shift):
        """shift_rows of a block: the rows gathered along x over the layout's x split,
        shifted whole, this block cut out; ``shift`` over the whole mesh's y."""
        g = self.grid
        (x0, x1), (y0, y1), _ = g.real_range
        out = shift_rows(g.gather_rows(f), np.asarray(shift)[y0:y1], self.interpolation)
        return np.ascontiguousarray(out[..., x0:x1, :, :])

    def shift_scalar(self, f, n):
        return self._shift(f, self.row_shift(n))

    def _remap(self, u, n):
        g_old = self.frame_strain + n * self.s
        g_new = self.frame_strain
        sh = self.row_shift(n)
        u[...] = self._shift(u, sh)
        uo = cartesian(self._u_old, g_old)
        self._u_old[...] = contravariant(self._shift(uo, sh), g_new)
        n_old = self.state.get("n_old")
        if n_old is not None:         # the explicit scheme's advection history alike
            no = cartesian(n_old, g_old)
            n_old[...] = contravariant(self._shift(no, sh), g_new)
        self.pressure[...] = self._shift(self.pressure, sh + 0.5 * n * self.s)  # cell centres
        self.remaps += n
        self.remap_count += 1
        self.remap_fields = n

    def take_remap(self) -> int:
        """The frames the last re-mapping dropped (0: none since the last call); the caller
        shifts its scalar fields by as many (``shift_scalar``)."""
        n, self.remap_fields = self.remap_fields, 0
        return n


class MetricProjector:
    """u <- P_K u in place for the Cartesian deviation u (3, NX, NY, NZ) on the oblique grid
    of ``fluid`` (its current frame strain g): the spectral projection with the physical
    wavevector K = (k1, k2 - g k1, k3), v - K (K.v)/|K|^2, mean kept, no truncation: the
    original's final projection of the Lees-Edwards FDM types (sp_3d_ns.cxx
    Time_evolution_hydro_OBL_fdm: Solenoidal_uk_OBL of the contravariant field, the same
    projection in other components).  ``truncate``: with the 2/3 rule too (the sheared
    types' start, imposed by the original's unsheared routines).  ``grid``: a
    kapsel.mesh.grid.Grid (or this rank's PencilGrid)."""

    def __init__(self, grid, fluid):
        self.grid, self.fluid = grid, fluid
        self._c = grid.empty_complex()
        self._s = grid.empty_complex(None)
        self._t = grid.empty_complex(None)
        self._g = None

    def __call__(self, u, truncate=False):
        gr, g = self.grid, self.fluid.frame_strain
        if self._g != g:
            Ky = gr.ky - g * gr.kx
            K2 = gr.kx * gr.kx + Ky * Ky + gr.kz * gr.kz
            self._inv = np.zeros(np.broadcast_shapes(K2.shape, self._s.shape))
            np.divide(1.0, K2, out=self._inv, where=K2 > 0)
            self._Ky, self._g = Ky, g
        c, s, t = self._c, self._s, self._t
        gr.forward(u, out=c)
        np.multiply(c[0], gr.kx, out=s)
        np.multiply(c[1], self._Ky, out=t)
        s += t
        np.multiply(c[2], gr.kz, out=t)
        s += t
        s *= self._inv
        for comp, k in enumerate((gr.kx, self._Ky, gr.kz)):
            np.multiply(s, k, out=t)
            c[comp] -= t
        c *= 1.0 / gr.size
        if truncate:
            c *= gr.dealias_f
        gr.backward_raw(c, u)
        return u
