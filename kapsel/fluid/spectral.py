"""Pseudo-spectral incompressible Navier-Stokes solver on the periodic box (the original's
``Navier_Stokes`` type; eqs 7-8 of manual §4.1 without the particle force, which the SPM
driver adds as a solenoidal increment).

    du/dt = u x omega - grad(p/RHO + |u|^2/2) + nu lap u + f,   div u = 0,   nu = ETA/RHO

State: u_hat (3, NX, NY, NZ//2+1), the unnormalised rfftn of u (``kapsel.mesh.grid``).  One step:

1. u and omega = curl u in real space from the 2/3-rule truncated u_hat (6 c2r FFTs);
2. N = u x omega (rotational form), back to Fourier space (3 r2c FFTs); the k = 0 mode of
   u x omega is set to its exact value 0 (the advection term is a divergence), so the mean
   flow (total momentum RHO DX^3 sum u = RHO DX^3 Re u_hat(k=0)) changes only by the
   body force f, a constant that is integrated exactly: + dt phi1(z) P[f];
3. solenoidal projection P N = N - k (k.N)/k^2 (removes the pressure and |u|^2/2 gradients)
   and the 2/3-rule truncation of N;
4. exact integration of the viscous term (exponential time differencing, z = -nu k^2 dt):

   ETD1 (slaved Euler, the original's):  u^{n+1} = e^z u^n + dt phi1(z) P[N^n]
   ETD2 (Cox & Matthews 2002):           u^{n+1} = e^z u^n + dt [(phi1 + phi2) P[N^n]
                                                                 - phi2 P[N^{n-1}]]

   phi1(z) = (e^z - 1)/z, phi2(z) = (e^z - 1 - z)/z^2 (Taylor series for |z| < 0.1: no
   cancellation; phi1(0) = 1, phi2(0) = 1/2, so the k = 0 mode is Euler / AB2), i.e.
   dt phi1 = (1 - e^{-nu k^2 dt})/(nu k^2), and dt at k = 0.  Both integrate the viscous
   decay exactly for any dt and a constant force exactly.  ETD1 is the default
   (``scheme='etd1'``, the original's slaved Euler); ETD2 is second order for the nonlinear
   term (tests/unit/test_spectral.py measures the orders); its first step, and a step after
   ``set_velocity``, is ETD1.  The stability of the advection term is bounded by the usual
   CFL-type limit.

   A body force (acceleration) f, ``step(force)`` per step or ``set_force`` constant, enters
   as dt phi1(z) P[f_hat] (not truncated: it is not a product computed on the grid here; the
   k = 0 mode, f's mean, changes the momentum by RHO V <f> dt).
5. ``fix_cell`` (switch.FIX_CELL): the k = 0 mode of the flagged components is zeroed after
   the step (no mean flow along those axes).

No full-grid array is allocated per step: all transforms and products go through buffers
made once (SIMD-aligned, used in place by the FFTW plans of ``Grid``).
"""
from __future__ import annotations

import functools
import time

import numpy as np

from ..mesh.grid import Grid
from ..mesh import compiled as _compiled
from ..state import ModelState

_compiled.provide("spectral", __name__.rsplit(".", 1)[0] + ".spectral_kernels")

__all__ = ["SpectralNS", "SpectralProjector", "phi1", "phi2"]

# the projection kernels chosen for a half-spectrum shape (``projection_kernels``)
_PROJECTIONS: dict = {}
TIME_BELOW = 32 << 20   # bytes of a complex vector field below which the two forms are timed


def projection_kernels(K, grid):
    """(project_etd1, project_etd2, project_add, project_euler, project_set_scaled,
    project_etd1_velocity) of the compiled kernels ``K``
    in the form that is faster at this grid's half-spectrum shape: the point-by-point sweep or the
    sweep by blocks of rows, which give the same bits (kapsel.fluid.spectral_kernels).
    Timed once per shape and process, on two scratch fields, when a complex vector field
    is under ``TIME_BELOW`` bytes (where the fields stay in the caches and the point sweep
    can be several times slower); larger, memory-bound fields take the point sweep."""
    shape = tuple(grid.local_cshape)
    if shape not in _PROJECTIONS:
        forms = ((K.project_etd1, K.project_etd2, K.project_add, K.project_euler,
                  K.project_set_scaled, K.project_etd1_velocity),
                 (K.project_etd1_rows, K.project_etd2_rows, K.project_add_rows,
                  K.project_euler_rows, K.project_set_scaled_rows,
                  K.project_etd1_velocity_rows))
        best = 0
        if 3 * 16 * int(np.prod(shape)) < TIME_BELOW:
            d, u = grid.zeros_complex(), grid.zeros_complex()
            d[...] = 1.0
            u[...] = 0.0
            w = np.ones(shape)
            mask = np.ascontiguousarray(grid.dealias_f)   # the modes the passes skip too
            k = [np.ones(n) for n in shape]
            times = [[], []]
            for _ in range(3):
                for i, form in enumerate(forms):
                    t0 = time.perf_counter()
                    form[2](d, u, mask, *k, w)
                    times[i].append(time.perf_counter() - t0)
            best = int(min(times[1]) < min(times[0]))
        _PROJECTIONS[shape] = forms[best]
    return _PROJECTIONS[shape]


def cross_in_place(u, w, n):
    """n = u x w for real (3, ...) arrays without temporaries: n[2] is scratch until the
    end and u[0] is overwritten (the caller no longer needs u)."""
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
    return n


def _real_view(c, grid, ncomp=None):
    """A real scalar field of ``grid`` (this rank's block; ``ncomp``: a vector field of
    ncomp components) in the memory of the complex field ``c`` of as many components
    (2 (NZ/2 + 1) >= NZ numbers per row: it fits), or a new array if it does not (a
    distributed block of another size)."""
    shape = tuple(grid.local_shape) if ncomp is None else (ncomp,) + tuple(grid.local_shape)
    n = int(np.prod(shape))
    flat = c.reshape(-1).view(np.float64)
    if flat.size >= n:
        return flat[:n].reshape(shape)
    return grid.empty_real(ncomp)


def phi1(z, scale=None):
    """(e^z - 1)/z, 1 at z = 0; times ``scale`` when given (one pass less than the
    product after).  Whole-array passes, no gather of the z != 0: each value gets the
    same expm1 and quotient as gathered."""
    z = np.asarray(z, dtype=float)
    out = np.expm1(z)
    zero = z == 0
    np.divide(out, z, out=out, where=~zero)
    np.copyto(out, 1.0, where=zero)
    if scale is not None:
        out *= scale
    return out


def phi2(z):
    """(e^z - 1 - z)/z^2, 1/2 at z = 0 (series below |z| = 0.1)."""
    z = np.asarray(z, dtype=float)
    out = np.empty_like(z)
    small = np.abs(z) < 0.1
    zs = z[small]
    # sum_{j>=0} z^j / (j+2)!, truncated after z^8 (error < 1e-17 for |z| < 0.1)
    acc = np.zeros_like(zs)
    for j in range(8, -1, -1):
        acc = acc * zs + 1.0 / _factorial(j + 2)
    out[small] = acc
    zl = z[~small]
    out[~small] = (np.expm1(zl) - zl) / (zl * zl)
    return out


def _factorial(n):
    f = 1.0
    for i in range(2, n + 1):
        f *= i
    return f


class SpectralNS:
    """Pseudo-spectral NS solver (module docstring) on ``grid`` (a ``kapsel.mesh.grid.Grid``).

    rho, eta : RHO, ETA;  dt : time step (``kapsel.timestep.auto_dt``);  fix_cell :
    switch.FIX_CELL, (bool, bool, bool) per axis or one bool for all;  scheme : 'etd1'
    (default, eq 8 by slaved Euler) | 'etd2';
    force : optional constant body
    force per unit mass (acceleration) f, real (3, NX, NY, NZ) or a 3-vector (uniform);
    advection : False drops u x omega (unsteady Stokes).
    """

    def __init__(self, grid: Grid, rho, eta, dt, fix_cell=(False, False, False), scheme="etd1",
                 force=None, advection=True, state=None):
        if scheme not in ("etd1", "etd2"):
            raise ValueError("scheme must be 'etd1' or 'etd2'")
        self.grid = grid
        self.rho, self.eta, self.dt = float(rho), float(eta), float(dt)
        if not (self.rho > 0 and self.eta > 0 and self.dt > 0):
            raise ValueError("rho, eta and dt must be positive")
        self.nu = self.eta / self.rho
        self.scheme = scheme
        if np.ndim(fix_cell) == 0:
            fix_cell = (fix_cell,) * 3
        self.fix_cell = tuple(bool(f) for f in fix_cell)
        if len(self.fix_cell) != 3:
            raise ValueError("fix_cell must have 3 flags")
        self.advection = bool(advection)
        g = grid
        # u_hat lives in the model's state (kapsel.state.ModelState), as ETD2's N^{n-1}
        self.state = ModelState() if state is None else state
        self.u_hat = self.state.field("u_hat", g.zeros_complex)
        # scratch: N^n, N^{n-1} (complex vectors); u, omega (real vectors: omega becomes
        # u x omega in place in the compiled pass); two complex scalars (each component of
        # the truncated u_hat and of omega passes through one on its way to real space) and
        # two real scalars in the complex scalars' memory (the numpy pass's u x omega, made
        # when the scalars are free).  u and omega are free between steps (``scratch_real``).
        # 11.2 float64 per grid point with ETD1 (issue 25), 20.3 when every stage had its
        # own vector buffer.
        self._nl = g.empty_complex()
        self._nl_old = g.empty_complex() if scheme == "etd2" else None
        self._u = g.empty_real()
        self._w = g.empty_real()
        self._s = g.empty_complex(None)
        self._t = g.empty_complex(None)
        self._r = (_real_view(self._s, g), _real_view(self._t, g))
        self._fh = None                 # FFT of a per-step force (``step(force)``), on use
        self.step_index = 0

        self._ikx = 1j * g.kx
        self._iky = 1j * g.ky
        self._ikz = 1j * g.kz
        # k as contiguous 1-d arrays for the compiled passes (kapsel.mesh.compiled)
        self._k1 = g.k_axes
        self.force_hat = None
        # after_update(u_hat): applied in step() after the update, before FIX_CELL (the
        # zigzag pin of Shear_Navier_Stokes, kapsel.models.zigzag)
        self.after_update = None
        # a distributed grid (kapsel.mesh.pencil) holds the k = 0 mode on one rank only
        self._k0 = getattr(g, "has_k0", True)
        self._dist = hasattr(g, "comm")
        if force is not None:
            self.set_force(force)

    # ------------------------------------------------------------------ ETD weights
    @functools.cached_property
    def _weights(self) -> dict:
        """The ETD weights of eq 8 (z = -nu k^2 dt), made on first use: a fluid built for
        ``kapsel-py --check`` never steps.  E = e^z; a1 = dt phi1 mask (ETD1 / first step); a2 = dt (phi1 + phi2) mask and
        b2 = dt phi2 mask (ETD2 weights of N^n and N^{n-1}).  A step of its own (the
        Electrolyte's explicit Euler) never makes them."""
        g = self.grid
        z = -self.nu * g.k2 * self.dt
        p1 = phi1(z)
        mask = g.dealias_f
        w = {"E": np.exp(z), "a1": self.dt * p1 * mask}
        if self.scheme == "etd2":
            p2 = phi2(z)
            w["a2"] = self.dt * (p1 + p2) * mask
            w["b2"] = self.dt * p2 * mask
        return w

    _E = property(lambda self: self._weights["E"])
    @functools.cached_property
    def _f1(self):
        """dt phi1(z) of a body force (not truncated), made when a force first acts."""
        return self.dt * phi1(-self.nu * self.grid.k2 * self.dt)

    _a1 = property(lambda self: self._weights["a1"])
    _a2 = property(lambda self: self._weights["a2"])
    _b2 = property(lambda self: self._weights["b2"])
    @functools.cached_property
    def _mask_n(self):
        """mask / N: the 2/3 truncation and the 1/N of the c2r, made on first use (by the
        numpy passes: the compiled ones take the mask and ``_inv_n``, the same numbers
        without a field of their own)."""
        return self.grid.dealias_f / self.grid.size

    _inv_n = property(lambda self: 1.0 / self.grid.size)

    # ------------------------------------------------------------------ state
    def set_force(self, force):
        """Constant body force per unit mass: 3-vector (uniform) or real (3, NX, NY, NZ)."""
        if force is None:
            self.force_hat = None
            return
        f = np.asarray(force, dtype=float)
        fh = self.grid.empty_complex()
        if f.shape == (3,):
            fh[...] = 0.0
            if self._k0:
                fh[:, 0, 0, 0] = f * self.grid.size
        else:
            self.grid.forward(f, out=fh)
            self.grid.project(fh, tmp=(self._s, self._t))  # only its solenoidal part acts
        self.force_hat = fh

    def set_velocity(self, u):
        """u_hat <- P[FFT(u)] (real (3, NX, NY, NZ)); restarts ETD2 with an ETD1 step."""
        self.grid.forward(np.asarray(u, dtype=float), out=self.u_hat)
        self.grid.project(self.u_hat, tmp=(self._s, self._t))
        self.state.put("nl_old", None)

    def set_velocity_hat(self, u_hat):
        np.copyto(self.u_hat, u_hat)
        self.state.put("nl_old", None)

    def velocity(self, out=None, truncated=False):
        """u in real space: into ``out`` (returned) or a new array.  ``truncated``: T u, the
        2/3-truncated u (the same u where u_hat is 0 off the mask, as the Electrolyte's
        after its Euler step), its transforms skipping the lines of zeros.  Without it a
        component that is 0 off the mask is transformed so too (kapsel.mesh.grid: the same
        bits with FFTW_ESTIMATE plans, the same to round-off with measured ones)."""
        if out is None:
            out = self.grid.empty_real()
        if truncated:
            self._truncated_u(out)
            return out
        s, g = self._s, self.grid
        K = _compiled.spectral
        if K is not None:
            return self._transform_components(K, out, 0.0)
        for c in range(3):
            np.multiply(self.u_hat[c], 1.0 / g.size, out=s)
            g.backward_scalar_raw(s, out[c])
        return out

    def _transform_components(self, K, out, strain):
        """out[c] <- the c2r of component c of u_hat / N in the frame of ``strain`` g (u_1 =
        u^1 + g u^2: the Lees-Edwards frame's Cartesian components; 0 here), each made by a
        compiled pass that also tells whether it is 0 off the 2/3 mask, and then transformed
        with the lines of zeros skipped (a state with modes off the mask, e.g. under a body
        force or after add_solenoidal, is transformed whole)."""
        g, s = self.grid, self._s
        for c in range(3):
            if K.frame_component(self.u_hat, *g.dealias_box, self._inv_n, strain, c, False, s):
                g.backward_scalar_truncated(s, out[c])
            else:
                g.backward_scalar_raw(s, out[c])
        return out

    def scratch_real(self):
        """Two real vector fields (3, NX, NY, NZ) this solver only uses inside ``step``:
        free for a caller between steps (the SPM's u* and its increment), overwritten by the
        next step."""
        return self._u, self._w

    def scratch_between_steps(self):
        """(nl, s, t): a real vector field (3, NX, NY, NZ) in the memory of N^n (ETD1 and the
        Euler step only: ETD2 keeps N^{n-1} there) and the two complex scalars, which this
        solver only uses inside its own calls (``step``, ``euler_step``, ``velocity``,
        ``truncated_velocity``, ``add_solenoidal``): free for a caller in between, e.g. the
        Electrolyte's ions (their potential gradient and transform scratch; issue 25)."""
        if self.scheme != "etd1":
            raise ValueError("N^n is kept between ETD2 steps")
        return _real_view(self._nl, self.grid, 3), self._s, self._t

    def truncated_velocity(self):
        """T u in real space (the 2/3-truncated u_hat transformed) into the solver's scratch
        ``scratch_real()[0]``, which the next ``euler_step(u_ready=True)`` takes as the u of
        its u x omega (the original's Zeta_k2u after Truncate_two_third_rule,
        fluid_solver.cxx Rhs_NS_solute: the same u for the ions and the fluid)."""
        self._truncated_u()
        return self._u

    def _truncated_u(self, u=None):
        """u (default the scratch) <- T u_hat / N transformed, a component at a time through
        a complex scalar."""
        g, s = self.grid, self._s
        u = self._u if u is None else u
        K = _compiled.spectral
        for c in range(3):
            if K is not None:
                K.truncated_component(self.u_hat, *g.dealias_box, self._inv_n, c, s)
            else:
                np.multiply(self.u_hat[c], self._mask_n, out=s)   # truncated, 1/N folded in
            g.backward_scalar_truncated(s, u[c])   # destroys s

    # ------------------------------------------------------------------ step
    def _nonlinear(self, u_ready=False):
        """P[u x omega] in _nl: in the compiled pass exact on the 2/3 mask only (off it the
        r2c's partial sums, which the ETD passes do not read: their weights carry the
        truncation; the projection is theirs), truncated and projected in the numpy pass.  Each component of the
        truncated u_hat / N and of its curl is made in a complex scalar and transformed to
        real space in turn (the scalar plans of a vector transform: the same bits).
        ``u_ready``: T u is in the scratch already (``truncated_velocity``)."""
        g = self.grid
        nl = self._nl
        if not self.advection:
            nl[...] = 0.0
            return nl
        u, w, s, t = self._u, self._w, self._s, self._t
        if not u_ready:
            self._truncated_u()
        K = _compiled.spectral
        if K is not None:
            for c in range(3):
                K.vorticity_component(self.u_hat, *g.dealias_box, self._inv_n, *self._k1, c,
                                      s)
                g.backward_scalar_truncated(s, w[c])
            K.cross_into(u, w)                          # w <- u x omega
            g.forward_truncated(w, nl)                  # (the ETD weights are masked)
            if self._k0:
                nl[:, 0, 0, 0] = 0.0   # exact: mean of (u.grad)u is 0; projected by step()
            return nl
        ik = (self._ikx, self._iky, self._ikz)
        mask = self._mask_n
        for c in range(3):                               # omega_c = i k_p u_q - i k_q u_p
            p, q = (c + 1) % 3, (c + 2) % 3
            np.multiply(self.u_hat[q], mask, out=s)
            np.multiply(ik[p], s, out=s)
            np.multiply(self.u_hat[p], mask, out=t)
            np.multiply(ik[q], t, out=t)
            s -= t
            g.backward_scalar_truncated(s, w[c])
        self._cross_forward(u, w, nl)                    # N = u x omega -> Fourier space
        if self._k0:
            nl[:, 0, 0, 0] = 0.0            # exact: mean of (u.grad)u is 0
        g.project(nl, tmp=(self._s, self._t))
        return nl

    def euler_step(self, u_ready=False):
        """u_hat <- T[u_hat + dt (P[u x omega] - nu k^2 u_hat)]: the explicit Euler step of the
        Electrolyte type (fluid_solver.cxx NSsolute_solver_Euler), instead of ``step``.  The
        same bits whether the compiled kernels are loaded or not: the compiled
        ``_nonlinear`` leaves the projection to a fused pass, here ``project_euler``
        (projection and update in one sweep).  ``u_ready``: T u of this state is in the
        scratch (``truncated_velocity``, untouched since)."""
        nl = self._nonlinear(u_ready)
        K = _compiled.spectral
        if K is not None:                    # fused: projection + update, one pass
            projection_kernels(K, self.grid)[3](nl, self.u_hat, self.grid.k2, self.nu,
                                                self.dt, self.grid.dealias_f, *self._k1,
                                                self.grid.inv_k2, self.advection)
        else:
            uh, s = self.u_hat, self._s
            for c in range(3):               # nl -= nu k^2 u_hat, a component at a time
                np.multiply(self._nu_k2, uh[c], out=s)
                nl[c] -= s
            nl *= self.dt
            uh += nl
            uh *= self.grid.dealias_f
        self.apply_fix_cell()
        self.step_index += 1

    @functools.cached_property
    def _nu_k2(self):
        """nu k^2 (the viscous rate of each mode), made on first use (``euler_step``)."""
        return self.nu * self.grid.k2

    def _cross_forward(self, u, w, nl):
        """nl = FFT(u x w), each component transformed as soon as it is made (one real
        scalars of scratch; u and w are destroyed), the products of ``cross``."""
        g, (r, r2) = self.grid, self._r
        np.multiply(u[1], w[2], out=r)
        np.multiply(u[2], w[1], out=r2)
        r -= r2
        g.rfft_scalar_truncated(r, nl[0])
        np.multiply(u[2], w[0], out=r)
        np.multiply(u[0], w[2], out=u[2])                # u[2], w[2] are not needed again
        r -= u[2]
        g.rfft_scalar_truncated(r, nl[1])
        np.multiply(u[0], w[1], out=r)
        np.multiply(u[1], w[0], out=w[2])
        r -= w[2]
        g.rfft_scalar_truncated(r, nl[2])

    def step(self, force=None, velocity=None):
        """Advance u_hat by dt (eq 8 without the particle term; module docstring, steps 1-5).

        force : optional real-space acceleration (3, NX, NY, NZ) acting during this step,
        added as dt phi1(z) P[FFT(force)] (on top of a constant ``set_force``).
        velocity : optional real (3, NX, NY, NZ) array: the new u in real space is put
        there (``velocity(out=...)`` after the step, the same bits).  With the compiled
        kernels and the slaved Euler step (no force, no ``after_update``) the update's own
        sweep also leaves u_hat / N in nl, which is transformed from there
        (``project_etd1_velocity``: one sweep over the field fewer).
        """
        nl = self._nonlinear()
        uh = self.u_hat
        K = _compiled.spectral
        made = None              # u_hat / N in nl: whether it is 0 off the mask (or None)
        if self.advection and K is not None:    # fused: projection + ETD update
            kernels = projection_kernels(K, self.grid)
            etd1, etd2 = kernels[:2]
            if self.scheme == "etd2" and self.state.holds("nl_old"):
                etd2(nl, self._nl_old, uh, self._E, self._a2, self._b2, *self._k1,
                     self.grid.inv_k2)
            elif (velocity is not None and self.scheme == "etd1" and force is None
                  and self.force_hat is None and self.after_update is None):
                made = kernels[5](nl, uh, self._E, self._a1, *self._k1, self.grid.inv_k2,
                                  *self.grid.dealias_box, self._inv_n)
            else:
                etd1(nl, uh, self._E, self._a1, *self._k1, self.grid.inv_k2,
                     self.scheme == "etd2")
        elif self.scheme == "etd2" and self.state.holds("nl_old"):
            uh *= self._E
            self._add_weighted(nl, self._a2)
            self._add_weighted(self._nl_old, self._b2, sign=-1)
        else:
            uh *= self._E
            self._add_weighted(nl, self._a1)
        if self.force_hat is not None:  # constant force: exact, dt phi1(z) P f
            self._add_weighted(self.force_hat, self._f1)
        if force is not None:
            if self._fh is None:
                self._fh = self.grid.empty_complex()
            fh = self._fh
            self.grid.forward(force, out=fh)
            self.grid.project(fh, tmp=(self._s, self._t))
            self._add_weighted(fh, self._f1)
        if self.scheme == "etd2":
            self._nl, self._nl_old = self._nl_old, self._nl
            self.state.put("nl_old", self._nl_old)      # N^{n-1} of the next step
        if self.after_update is not None:
            self.after_update(uh)
        self.apply_fix_cell()
        self.step_index += 1
        if velocity is None:
            return
        if made is None:
            self.velocity(out=velocity)
        else:
            self._velocity_from_nl(velocity, made)

    def _velocity_from_nl(self, out, truncated, strain=0.0):
        """out <- the c2r of the u_hat / N an update's sweep left in nl
        (``project_etd1_velocity``, ``project_oblique_etd1_velocity``: Cartesian in the
        frame of ``strain``), with the lines of zeros skipped if ``truncated``; the mean
        mode made again from u_hat where FIX_CELL set it after the sweep (the products of
        ``frame_component``)."""
        nl, g = self._nl, self.grid
        if self._k0 and any(self.fix_cell):
            uh, inv = self.u_hat, self._inv_n
            z1 = uh[1, 0, 0, 0]
            for c in range(3):
                z = uh[c, 0, 0, 0]
                if c == 0 and strain != 0.0:
                    nl[0, 0, 0, 0] = complex(z.real * inv + (z1.real * inv) * strain,
                                             z.imag * inv + (z1.imag * inv) * strain)
                else:
                    nl[c, 0, 0, 0] = complex(z.real * inv, z.imag * inv)
        transform = g.backward_scalar_truncated if truncated else g.backward_scalar_raw
        for c in range(3):
            transform(nl[c], out[c])

    def _add_weighted(self, vh, weight, sign=1):
        """u_hat += sign weight vh, component by component through a complex scalar."""
        s = self._s
        for c in range(3):
            np.multiply(vh[c], weight, out=s)
            if sign > 0:
                self.u_hat[c] += s
            else:
                self.u_hat[c] -= s

    def run(self, nsteps):
        for _ in range(int(nsteps)):
            self.step()

    def zero_mean(self):
        """u_hat(k = 0) <- 0: no mean flow."""
        if self._k0:
            self.u_hat[:, 0, 0, 0] = 0.0

    def apply_fix_cell(self):
        """switch.FIX_CELL: zero the mean velocity along the flagged axes."""
        for c, on in enumerate(self.fix_cell):
            if on and self._k0:
                self.u_hat[c, 0, 0, 0] = 0.0

    def add_solenoidal(self, du, project=True):
        """u_hat += P T[FFT(du)] for a real increment du (3, NX, NY, NZ) (e.g. the SPM body
        force phi f_p dt), T the 2/3-rule truncation: the state stays truncated, as the
        original's (operate_omega.h Solenoidal_u); the k = 0 mode (mean, momentum) of du is
        kept.  ``du`` may be ``grid.real_buf`` or any array; it is not modified."""
        d = self._nl          # free between steps (ETD2: the older of the two, overwritten next)
        self.grid.forward_truncated(du, d)     # used on the 2/3 mask only
        K = _compiled.spectral
        if project and K is not None:
            projection_kernels(K, self.grid)[2](d, self.u_hat, self.grid.dealias_f, *self._k1,
                                               self.grid.inv_k2)
            return
        d *= self.grid.dealias_f
        if project:
            self.grid.project(d, tmp=(self._s, self._t))
        self.u_hat += d

    # ------------------------------------------------------------------ diagnostics
    def momentum(self):
        """Total fluid momentum RHO DX^3 sum_x u (from the k = 0 mode), (3,)."""
        return self.rho * self.grid.dx ** 3 * self._mean_mode().real.copy()

    def _mean_mode(self):
        """u_hat at k = 0 (3,) (from its rank when distributed)."""
        return self.grid.k0(self.u_hat) if self._dist else self.u_hat[:, 0, 0, 0]

    def mean_velocity(self):
        return self._mean_mode().real / self.grid.size

    def kinetic_energy(self):
        """1/2 RHO DX^3 sum_x |u|^2 (Parseval over the half spectrum)."""
        g = self.grid
        e = np.sum(g.half_weight * (self.u_hat.real ** 2 + self.u_hat.imag ** 2))
        if self._dist:
            e = g.sum(e)
        return 0.5 * self.rho * g.dx ** 3 * float(e) / g.size

    def divergence_max(self):
        """max |div u| in real space (spectral derivative), for checks."""
        d = self.grid.divergence_hat(self.u_hat)
        if self._dist:        # this rank's block, then the max over the ranks
            return self.grid.max(np.abs(self.grid.irfft_scalar(np.ascontiguousarray(d))).max())
        return float(np.abs(np.fft.irfftn(d, s=self.grid.shape, axes=(0, 1, 2))).max())


class SpectralProjector:
    """u <- P T u in place for a real field u (3, NX, NY, NZ): FFT, 2/3-rule truncation,
    solenoidal projection (continuous wavenumbers), inverse FFT; the mean is kept.  The
    original applies it to the whole velocity of the FDM types after the particles' force of
    every step (operate_omega.h Solenoidal_u, sp_3d_ns.cxx Time_evolution_hydro_fdm).
    ``grid``: a kapsel.mesh.grid.Grid (or a distributed PencilGrid: u is then this rank's block)."""

    def __init__(self, grid):
        self.grid = grid
        self._c = grid.empty_complex()
        self._s = grid.empty_complex(None)
        self._t = grid.empty_complex(None)
        self._mask_n = grid.dealias_f / grid.size

    def __call__(self, u):
        g = self.grid
        g.forward_truncated(u, self._c)         # exact on the mask, which is all that is kept
        self._c *= self._mask_n
        g.project(self._c, tmp=(self._s, self._t))
        g.backward_truncated(self._c, u)
        return u
