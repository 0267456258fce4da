"""Simple shear flow in the oblique (sheared) frame: the Lees-Edwards types (manual §5.1,
eqs 27-29; Kobayashi & Yamamoto 2011, Molina et al. 2016).

Imposed flow and frame
----------------------
The imposed flow is U = gamma_dot(t) (y - y0) e_x with the shear origin y0 = Ly/2 (the box
centre: a particle there does not translate).  ``ShearFlow``: DC gamma_dot(t) = Shear_rate;
AC gamma_dot(t) = Shear_rate cos(2 pi Frequency t) (Frequency in cycles per tau).  The applied
strain is Gamma(t) = int_0^t gamma_dot.

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
|K(t)|^2 (Simpson's rule, exact for DC), the rest by the slaved Euler (ETD1) step of
``SpectralNS``.  AC shear: the imposed flow is taken as quasi-static (no d_t U term, as the
original's oblique formulation).  The interface the SPM driver uses is the one of
``SpectralNS`` (``step``, ``velocity(out)``: Cartesian deviation on the oblique grid,
``add_solenoidal(du)``: Cartesian increment) plus the frame for the particles
(``frame_strain``, ``shear_rate_now``, ``background``, ``wrap_particles``).

Interpolation between oblique and rectangular grids (``to_rectangular``, ``to_oblique``,
``shift_rows``): along x per row, ``linear`` (2 points) or ``spline`` (periodic cubic
B-spline interpolant), ``switch.ns_solver.OBL_INT``.
"""
from __future__ import annotations

import math

import numpy as np

from ..grid import Grid
from .spectral import SpectralNS, phi1

__all__ = ["ShearFlow", "ObliqueSpectralNS", "shift_rows", "to_rectangular", "to_oblique",
           "contravariant", "cartesian", "lees_edwards_wrap", "lees_edwards_displacement",
           "INTERPOLATIONS"]

INTERPOLATIONS = ("linear", "spline")


class ShearFlow:
    """gamma_dot(t) and the applied strain Gamma(t) of a DC or AC shear (table 4)."""

    def __init__(self, kind="DC", rate=0.0, frequency=0.0):
        if kind not in ("DC", "AC"):
            raise ValueError(f"shear kind must be DC or AC, got {kind!r}")
        self.kind, self.rate0, self.frequency = kind, float(rate), float(frequency)
        self.omega = 2.0 * math.pi * self.frequency

    @classmethod
    def from_config(cls, shear):
        return cls(shear.kind, shear.shear_rate, shear.frequency)

    def rate(self, t: float) -> float:
        if self.kind == "AC":
            return self.rate0 * math.cos(self.omega * t)
        return self.rate0

    def strain(self, t: float) -> float:
        if self.kind == "AC" and self.omega > 0:
            return self.rate0 * math.sin(self.omega * t) / self.omega
        return self.rate0 * t


# ---------------------------------------------------------------------------- components
def contravariant(u, g, out=None):
    """Cartesian (3, ...) -> contravariant components of the frame with strain g."""
    out = np.array(u, dtype=float, copy=True) if out is None else out
    if out is not u:
        np.copyto(out, u)
    out[0] -= g * u[1]
    return out


def cartesian(u, g, out=None):
    """Contravariant (3, ...) -> Cartesian components."""
    out = np.array(u, dtype=float, copy=True) if out is None else out
    if out is not u:
        np.copyto(out, u)
    out[0] += g * u[1]
    return out


# ---------------------------------------------------------------------------- interpolation
def shift_rows(f, shift, method="linear"):
    """g[i, j, ...] = f(x_i - shift_j) along axis 0, periodic; ``shift`` (NY,) in grid points.

    f: (NX, NY, ...) or (c, NX, NY, ...) with a leading component axis (then ``f.ndim == 4``).
    Integer shifts are exact permutations for both methods.
    """
    if method not in INTERPOLATIONS:
        raise ValueError(f"OBL_INT must be one of {INTERPOLATIONS}, got {method!r}")
    f = np.asarray(f, dtype=float)
    if f.ndim == 4:
        return np.stack([shift_rows(c, shift, method) for c in f])
    nx, ny = f.shape[0], f.shape[1]
    shift = np.asarray(shift, dtype=float).reshape(ny)
    base = np.floor(shift)
    frac = shift - base                      # g_i = f(i - base - frac)
    i = np.arange(nx)[:, None]
    j = np.arange(ny)[None, :]
    b = base.astype(np.int64)[None, :]
    w = frac[None, :]
    extra = (slice(None),) * 0
    if method == "linear":
        # f(i - b - w) = (1 - w) f[i - b] + w f[i - b - 1]
        f0 = f[(i - b) % nx, j]
        f1 = f[(i - b - 1) % nx, j]
        wb = w.reshape(w.shape + (1,) * (f.ndim - 2))
        return (1.0 - wb) * f0 + wb * f1
    from scipy.ndimage import spline_filter1d
    c = spline_filter1d(f, order=3, axis=0, mode="grid-wrap")
    # point x = i - b - w = (i - b - 1) + (1 - w): cubic B-spline weights at t = 1 - w
    t = (1.0 - w).reshape(w.shape + (1,) * (f.ndim - 2))
    w0 = (1.0 - t) ** 3 / 6.0
    w1 = (3 * t ** 3 - 6 * t ** 2 + 4) / 6.0
    w2 = (-3 * t ** 3 + 3 * t ** 2 + 3 * t + 1) / 6.0
    w3 = t ** 3 / 6.0
    p = i - b - 1
    out = w0 * c[(p - 1) % nx, j]
    out += w1 * c[p % nx, j]
    out += w2 * c[(p + 1) % nx, j]
    out += w3 * c[(p + 2) % nx, j]
    del extra
    return out


def _ny(f):
    return np.shape(f)[2] if np.ndim(f) == 4 else np.shape(f)[1]


def to_rectangular(f, g, method="linear", origin=0.0):
    """A field on the oblique grid of strain g -> the rectangular grid (same shape):
    rect[i, j] = f at oblique x^ = i - g (j - origin) (grid units; origin = y0 / DX)."""
    return shift_rows(f, g * (np.arange(_ny(f)) - origin), method)


def to_oblique(f, g, method="linear", origin=0.0):
    """Inverse of ``to_rectangular``: obl[i, j] = rect at x = i + g (j - origin)."""
    return shift_rows(f, -g * (np.arange(_ny(f)) - origin), method)


# ---------------------------------------------------------------------------- particles
def lees_edwards_wrap(R, v, box, offset, rate, v_old=None):
    """Wrap positions into the box with Lees-Edwards images: a particle leaving through
    y = Ly re-enters at y = 0 displaced by -offset along x (offset = g Ly, the image shift)
    with its x velocity lowered by rate Ly (and the reverse through y = 0); then x and z are
    wrapped periodically.  R, v (and v_old) are changed in place."""
    L = np.asarray(box, dtype=float)
    n = np.floor(R[:, 1] / L[1])
    if np.any(n):
        R[:, 0] -= n * offset
        R[:, 1] -= n * L[1]
        v[:, 0] -= n * rate * L[1]
        if v_old is not None:
            v_old[:, 0] -= n * rate * L[1]
    np.mod(R, L, out=R)
    R[R >= L] = 0.0


def lees_edwards_displacement(dr, box, offset):
    """Minimum-image displacement under Lees-Edwards images (y first, then x, z)."""
    L = np.asarray(box, dtype=float)
    dr = np.array(dr, dtype=float, copy=True)
    n = np.round(dr[..., 1] / L[1])
    dr[..., 0] -= n * offset
    dr[..., 1] -= n * L[1]
    dr[..., 0] -= np.round(dr[..., 0] / L[0]) * L[0]
    dr[..., 2] -= np.round(dr[..., 2] / L[2]) * L[2]
    return dr


# ---------------------------------------------------------------------------- fluid
class ObliqueSpectralNS(SpectralNS):
    """Deviation from the imposed shear flow in the oblique frame (module docstring).

    ``u_hat`` holds the rfftn of the contravariant components u^i on the oblique grid.
    shear : ShearFlow;  t0 : time of the initial state;  frame_strain0 : the frame strain at
    t0 (restart: oblique.degree_oblique), by default Gamma(t0) reduced into [-s/2, s/2).
    """

    oblique = True

    def __init__(self, grid: Grid, rho, eta, dt, shear: ShearFlow, fix_cell=(False,) * 3,
                 advection=True, t0=0.0, frame_strain0=None):
        super().__init__(grid, rho, eta, dt, fix_cell=fix_cell, scheme="etd1",
                         advection=advection)
        self.shear = shear
        self.time = float(t0)
        Lx, Ly = grid.box[0], grid.box[1]
        self.s = Lx / Ly                       # strain of one re-mapping
        self.y0 = 0.5 * Ly
        self.max_frame_strain = 0.5 * self.s + abs(shear.rate0) * dt * 2 + 1e-12
        g = shear.strain(self.time)
        if frame_strain0 is None:
            frame_strain0 = g - self.s * math.floor(g / self.s + 0.5)
        self.remaps = int(round((g - frame_strain0) / self.s))
        self._check_frame(frame_strain0)
        self.remap_count = 0
        k = grid
        self._k11 = k.kx * k.kx
        self._k12 = k.kx * k.ky
        self._k22 = k.ky * k.ky + k.kz * k.kz      # k2^2 + k3^2
        self._m1 = np.rint(k.kx.ravel() * grid.box[0] / (2 * np.pi)).astype(np.int64)
        self._m2 = np.rint(k.ky.ravel() * grid.box[1] / (2 * np.pi)).astype(np.int64)
        self._K2 = np.empty(grid.cshape)
        self._invK2 = np.empty(grid.cshape)
        self._gK = None

    def _check_frame(self, g):
        if abs(g) > self.max_frame_strain:
            raise ValueError(f"frame strain {g} outside [-s/2, s/2] (s = {self.s})")

    # ------------------------------------------------------------------ frame
    @property
    def frame_strain(self) -> float:
        """g of the current oblique grid (the restart's oblique.degree_oblique)."""
        return self.shear.strain(self.time) - self.remaps * self.s

    @property
    def applied_strain(self) -> float:
        return self.shear.strain(self.time)

    @property
    def shear_rate_now(self) -> float:
        return self.shear.rate(self.time)

    @property
    def image_offset(self) -> float:
        """x displacement of the image across the y boundary, g Ly."""
        return self.frame_strain * self.grid.box[1]

    def background(self, R):
        """U at the positions R (N, 3): gamma_dot (y - y0) e_x."""
        U = np.zeros_like(np.asarray(R, dtype=float))
        U[:, 0] = self.shear_rate_now * (R[:, 1] - self.y0)
        return U

    def wrap_particles(self, p):
        """Positions p.R (moved by one step from inside the box) into the box through the
        Lees-Edwards images; x velocities shifted for a crossing of the y boundary."""
        lees_edwards_wrap(p.R, p.v, self.grid.box, self.image_offset, self.shear_rate_now,
                          p.v_old)

    def _metric(self, g):
        """|K|^2 and 1/|K|^2 (0 at k = 0) of the frame strain g into _K2, _invK2."""
        K2 = self._K2
        np.multiply(self._k11, 1.0 + g * g, out=K2)
        K2 -= (2.0 * g) * self._k12
        K2 += self._k22
        np.divide(1.0, K2, out=self._invK2, where=K2 > 0)
        self._invK2[K2 <= 0] = 0.0
        self._gK = g
        return K2

    def project_metric(self, vh, g):
        """P^G v = v - G k^ (k^.v) / (k^ G k^), in place (contravariant components)."""
        if self._gK != g:
            self._metric(g)
        k = self.grid
        s, t = self._s, self._t
        np.multiply(vh[0], k.kx, out=s)
        np.multiply(vh[1], k.ky, out=t)
        s += t
        np.multiply(vh[2], k.kz, out=t)
        s += t
        s *= self._invK2
        # (G k^)^1 = (1 + g^2) k1 - g k2, (G k^)^2 = k2 - g k1, (G k^)^3 = k3
        np.multiply(s, (1.0 + g * g) * k.kx - g * k.ky, out=t)
        vh[0] -= t
        np.multiply(s, k.ky - g * k.kx, out=t)
        vh[1] -= t
        np.multiply(s, k.kz, out=t)
        vh[2] -= t
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
        uh = self._uh
        np.multiply(self.u_hat, 1.0 / self.grid.size, out=uh)
        uh[0] += self.frame_strain * uh[1]
        return self.grid.backward_raw(uh, out)

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
        gr = self.grid
        nl = self._nl
        if self.advection:
            uh, wh, t = self._uh, self._wh, self._t
            np.multiply(self.u_hat, self._mask_n, out=uh)
            uh[0] += g * uh[1]                       # Cartesian components
            Ky = gr.ky - g * gr.kx                    # physical K_y
            ikx, iky, ikz = self._ikx, 1j * Ky, self._ikz
            np.multiply(iky, uh[2], out=wh[0])
            np.multiply(ikz, uh[1], out=t)
            wh[0] -= t
            np.multiply(ikz, uh[0], out=wh[1])
            np.multiply(ikx, uh[2], out=t)
            wh[1] -= t
            np.multiply(ikx, uh[1], out=wh[2])
            np.multiply(iky, uh[0], out=t)
            wh[2] -= t
            u, w, n = self._u, self._w, self._n
            gr.backward_raw(uh, u)
            gr.backward_raw(wh, w)
            tmp = n[2]
            np.multiply(u[1], w[2], out=n[0])
            np.multiply(u[2], w[1], out=tmp)
            n[0] -= tmp
            np.multiply(u[2], w[0], out=n[1])
            np.multiply(u[0], w[2], out=tmp)
            n[1] -= tmp
            np.multiply(u[0], w[1], out=n[2])
            np.multiply(u[1], w[0], out=u[0])
            n[2] -= u[0]
            n[0] -= g * n[1]                          # contravariant
            gr.forward(n, out=nl)
            nl[:, 0, 0, 0] = 0.0
            nl *= gr.dealias_f
        else:
            nl[...] = 0.0
        if rate != 0.0:
            nl[0] -= (2.0 * rate) * self.u_hat[1]
        return self.project_metric(nl, g)

    def step(self, force=None):
        """Advance u^ by dt (eq 27): u^ <- E u^ + dt phi1 P^G[N + f], then re-map the frame
        if its strain left [-s/2, s/2]."""
        t0, dt = self.time, self.dt
        g0 = self.frame_strain
        rate = self.shear.rate(t0)
        nl = self._nonlinear_oblique(g0, rate)
        # frame strains at t0, t0 + dt/2, t0 + dt (same re-mapping count): Simpson means
        off = self.remaps * self.s
        gs = [self.shear.strain(t0 + a * dt) - off for a in (0.0, 0.5, 1.0)]
        gm = (gs[0] + 4 * gs[1] + gs[2]) / 6.0
        g2m = (gs[0] ** 2 + 4 * gs[1] ** 2 + gs[2] ** 2) / 6.0
        K2 = np.multiply(self._k11, 1.0 + g2m, out=np.empty(self.grid.cshape))
        K2 -= (2.0 * gm) * self._k12
        K2 += self._k22
        z = K2
        z *= -self.nu * dt
        w1 = dt * phi1(z)
        E = np.exp(z, out=z)
        uh = self.u_hat
        uh *= E
        tmp = self._uh
        np.multiply(nl, w1, out=tmp)
        uh += tmp
        if force is not None:
            fh = self._wh
            self.grid.forward(contravariant(np.asarray(force, dtype=float), g0), out=fh)
            self.project_metric(fh, g0)
            np.multiply(fh, w1, out=tmp)
            uh += tmp
        self.time = t0 + dt
        self.apply_fix_cell()
        self.step_index += 1
        self._maybe_remap()

    def apply_fix_cell(self):
        """Zero the mean Cartesian velocity along the flagged axes."""
        g = self.frame_strain
        m = self.u_hat[:, 0, 0, 0]
        if self.fix_cell[1]:
            m[1] = 0.0
        if self.fix_cell[2]:
            m[2] = 0.0
        if self.fix_cell[0]:
            m[0] = -g * m[1]          # u_x mean = u^1 + g u^2 = 0

    def _maybe_remap(self):
        g = self.frame_strain
        half = 0.5 * self.s
        if -half <= g < half:
            return
        n = int(math.floor(g / self.s + 0.5))         # frames to drop
        self.remap_fourier(n)

    def remap_fourier(self, n):
        """Replace the frame g by g - n s (module docstring): contravariant components
        u^1 += n s u^2 and mode (m1, m2) -> (m1, m2 - n m1); modes leaving the band are
        dropped."""
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

    def add_solenoidal(self, du, project=True):
        """u^ += P^G[FFT(contravariant(du))] for a Cartesian increment du on the oblique grid."""
        g = self.frame_strain
        d = self._wh
        self.grid.forward(contravariant(np.asarray(du, dtype=float), g), out=d)
        if project:
            self.project_metric(d, g)
        self.u_hat += d

    # ------------------------------------------------------------------ diagnostics
    def momentum(self):
        """RHO DX^3 sum u (Cartesian deviation)."""
        m = self.u_hat[:, 0, 0, 0].real.copy()
        m[0] += self.frame_strain * m[1]
        return self.rho * self.grid.dx ** 3 * m

    def mean_velocity(self):
        return self.momentum() / (self.rho * self.grid.dx ** 3 * self.grid.size)

    def kinetic_energy(self):
        """1/2 RHO DX^3 sum |u^|^2 of the deviation (Cartesian)."""
        u = self.velocity()
        return 0.5 * self.rho * self.grid.dx ** 3 * float(np.sum(u * u))

    def divergence_max(self):
        k = self.grid
        d = 1j * (k.kx * self.u_hat[0] + k.ky * self.u_hat[1] + k.kz * self.u_hat[2])
        return float(np.abs(np.fft.irfftn(d, s=k.shape, axes=(0, 1, 2))).max())

    def viscous_stress_xy(self):
        """Mean viscous shear stress ETA <d_y u_x + d_x u_y> of the full flow: ETA gamma_dot
        (the deviation is periodic, its mean gradient vanishes)."""
        return self.eta * self.shear_rate_now
