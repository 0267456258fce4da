"""Ions of the ``Electrolyte`` type (PHYSICS-EXTRA §6.2): densities c_s of the ion species,
the particles' surface charge, Poisson's equation and the Nernst-Planck step.

Units: elementary charge e = 1, lengths and times as the fluid's.  Per species s: valence
z_s, Onsager coefficient L_s (diffusion coefficient D_s = kBT L_s).  phi = sum_i phi_i.

    rho_surf = s sum_i Z_i g(|r - R_i|),  g(r) = (pi / 2 xi) cos(pi (A - r) / xi) for
               |r - A| < xi / 2 (the compact sine slope), one factor s for all particles:
               DX^3 sum_x |rho_surf| = sum_i |Z_i|   (operate_electrolyte.cxx
               Make_phi_qq_particle)
    rho_e    = rho_surf + sum_s z_s c_s (1 - phi)                 (charge density)
    eps lap Psi = -rho_e:  Psi_k = rho_e,k / (eps k^2), Psi_0 = 0  (spectral, periodic)
    dc_s/dt  = div J_s,  J_s = P[L_s (kBT grad c_s + z_s c_s grad Psi_tot)] - c_s u,
    grad Psi_tot = grad Psi - E(t)

P removes the normal component of the diffusive-migrative flux where the surface normal
n = sum_i (r - R_i) / |r - R_i| over the particles' shells |r - R_i| - A| < xi / 2
(make_phi.cxx Make_surface_normal) is non-zero: J <- J - n (J.n)/|n|^2 (impermeable
particle surfaces; solute_rhs.cxx Solute_impermeability).
The divergence is spectral, its k = 0 mode exactly 0, so sum_x c_s is conserved to
round-off by the step; the 2/3 rule truncates c_s, Psi (of the flux, not of the Coulomb
force) and div J (the state stays band-limited).  The ions in the fluid, N_s = DX^3 sum_x
(1 - phi) c_s, change when particles move (the profile covers or uncovers fluid);
``rescale`` multiplies c_s by N_s(0) / N_s after each move so that every N_s stays at its
initial value to round-off (the original's ``Rescale_solute``).

The step is explicit Euler (the original's); stable under the time step limit of §6.5,
dt <= 1 / (kBT L_max K2max) (kapsel.timestep.electrolyte_dt).

Initial profiles (``init_uniform``, ``init_poisson_boltzmann``): see their docstrings.
"""
from __future__ import annotations

import numpy as np

from ..mesh import compiled as _compiled
from ..state import ModelState

_compiled.provide("ions", __name__.rsplit(".", 1)[0] + ".ions_kernels")

__all__ = ["Ions", "bulk_densities"]


def bulk_densities(valency, debye_length, eps, kBT):
    """Salt: n_+inf, n_-inf of the electroneutral bulk with e^2 sum z^2 n / (eps kBT) =
    1 / lambda_D^2 (PHYSICS-EXTRA §6.4)."""
    zp, zn = valency
    rho = kBT * eps / debye_length ** 2
    return rho / (zp * (zp - zn)), -rho / (zn * (zp - zn))


class Ions:
    """Ion densities c (S, NX, NY, NZ) on ``grid`` and the electrostatics of the particles.

    The densities are held twice: in real space (``c``) and as their r2c transforms
    (``c_hat``, unnormalised: the original's Concentration), so that a step transforms
    neither from the other (the original holds only c_hat and transforms it back wherever
    it needs c).  ``c`` is c_hat's c2r (times the rescale factors since, which scale both);
    ``banded``: c_hat is 2/3-truncated (after a step; not after an initial profile or a
    restart of the original's, whose first step truncates it as the original's does).
    Whoever writes ``c`` (an initial profile, a restart) calls ``densities_set()``.

    valency, onsager : per species;  eps : Dielectric_cst;  kBT;  dt;  state : the model's
    kapsel.state.ModelState, which holds c and c_hat (``ion_c``, ``ion_c_hat``);
    scratch : (J, grad_psi, ch, cs), two real vector fields and two complex scalars lent by
    the fluid (its buffers free between its own calls: SpectralNS.scratch_real,
    scratch_between_steps), or None (new ones).  J is written by ``step``,
    ``coulomb_force``, ``charge_density`` (its first component) and ``fluid_counts``, grad_psi
    by ``potential`` (read by ``step``, ``coulomb_force``, ``particle_force``), ch and cs by
    ``step``, ``potential`` and the gradients: the lender's calls must not fall between a
    ``potential`` and the calls reading its grad Psi.
    Call ``set_particles(idx, phi_i, r, Z, A, xi)`` whenever the particles moved (SPM
    stencil arrays), then ``potential()``, ``step(u, E)``, ``coulomb_force(E)``.
    """

    def __init__(self, grid, valency, onsager, eps, kBT, dt, state=None, scratch=None):
        self.grid = g = grid
        self.z = np.asarray(valency, dtype=float)
        self.L = np.asarray(onsager, dtype=float)
        self.S = len(self.z)
        self.eps, self.kBT, self.dt = float(eps), float(kBT), float(dt)
        self.dv = g.dx ** 3
        # the densities live in the model's state (kapsel.state.ModelState)
        self.state = ModelState() if state is None else state
        # SIMD-aligned, so that the transforms read each species in place (no copy)
        self.c = self.state.field("ion_c", lambda: g.zeros_real(self.S))
        self.c_hat = self.state.field("ion_c_hat", lambda: g.zeros_complex(self.S))
        self.banded = False
        self.counts = np.zeros(self.S)           # N_s held fixed by rescale
        self.phi = np.zeros(g.shape)
        self.rho_surf = np.zeros(g.shape)
        self._no_normal()
        # buffers: scalar complex scratch (Psi_hat shares ch: ``step`` does not use Psi_hat),
        # one vector field (the flux J, the Coulomb force, and rho_e in its first component
        # until transformed) and grad Psi; the transforms go component by component through
        # them (no buffer of rho_e or a real scalar of its own: issue 25)
        if scratch is None:
            scratch = (g.empty_real(), g.empty_real(), g.empty_complex(None),
                       g.empty_complex(None))
        self._J, self.grad_psi, self._ch, self._cs = scratch
        self.psi_hat = self._ch
        self._mask = g.dealias_f
        self._idx = self._q = self._r = None      # particles' stencil, charges, offsets
        self._ik = (1j * g.kx, 1j * g.ky, 1j * g.kz)
        self._k0 = getattr(g, "has_k0", True)     # this block holds k = 0 (distributed)

    # ------------------------------------------------------------------ particles
    def set_particles(self, idx, phi_i, r, Z, A, xi):
        """phi, rho_surf and the surface normal from the particles' stencil arrays (idx, phi_i,
        r: kapsel.particles.spm), as the original's Make_phi_qq_particle and
        Make_surface_normal (operate_electrolyte.cxx, make_phi.cxx):
        rho_surf = s sum_i Z_i g(|r|), g the compact sine slope (pi / 2 xi) cos(pi (A - |r|)
        / xi) for | |r| - A | < xi / 2, with one factor s for all particles making
        DX^3 sum_x |rho_surf| = sum_i |Z_i|; n = sum_i r / |r| over the same shells."""
        g, size = self.grid, self.grid.size
        K = _compiled.ions
        fast = (K is not None and idx.ndim == 2 and idx.dtype == np.int64
                and idx.flags.c_contiguous and self.phi.flags.c_contiguous
                and self.rho_surf.flags.c_contiguous)

        def binned(w, out):          # out <- the sums of w over the points (np.bincount's)
            if fast:
                K.bin_sum(idx, np.ascontiguousarray(w, dtype=float), out)
            else:
                out[...] = np.bincount(idx.ravel(), weights=w.ravel(),
                                       minlength=size).reshape(g.shape)
        binned(phi_i, self.phi)
        dist = np.sqrt(np.einsum("nsc,nsc->ns", r, r))
        shell = np.abs(A - dist) < 0.5 * xi
        slope = np.where(shell, 0.5 * np.pi / xi * np.cos(np.pi * (A - dist) / xi), 0.0)
        Z = np.asarray(Z, dtype=float)
        binned(Z[:, None] * slope, self.rho_surf)
        total = float(np.abs(self.rho_surf, out=self._J[0]).sum()) * self.dv
        scale = float(np.abs(Z).sum()) / total
        self.rho_surf *= scale
        self._idx, self._r = idx, r
        self._q = (scale * Z)[:, None] * slope            # each particle's own charge
        # n summed over the shell points only, in the stencils' order (the sums of the
        # whole-mesh bincount but for its added zeros), kept where |n|^2 > 0
        on = idx[shell]
        with np.errstate(invalid="ignore", divide="ignore"):
            rhat = r[shell] / dist[shell][:, None]
        at, slot = np.unique(on, return_inverse=True)
        normal = np.stack([np.bincount(slot, weights=rhat[:, c], minlength=at.size)
                           for c in range(3)])
        n2 = np.einsum("cp,cp->p", normal, normal)
        keep = n2 > 0.0
        self._normal_at, self._normal = at[keep], np.ascontiguousarray(normal[:, keep])
        self._inv_n2 = 1.0 / n2[keep]

    def no_particles(self):
        self._idx = self._q = self._r = None
        self.phi[...] = 0.0
        self.rho_surf[...] = 0.0
        self._no_normal()

    def _no_normal(self):
        """The surface normal is kept where it is not zero (the particles' shells): flat
        indices, n (3, P) and 1 / |n|^2 there; none of them without particles."""
        self._normal_at = np.zeros(0, dtype=np.intp)
        self._normal = np.zeros((3, 0))
        self._inv_n2 = np.zeros(0)

    @property
    def normal(self):
        """The surface normal n (3, NX, NY, NZ) on the whole mesh (a new array; zero off
        the particles' shells)."""
        out = np.zeros((3, self.grid.size))
        out[:, self._normal_at] = self._normal
        return out.reshape((3,) + self.grid.shape)

    # ------------------------------------------------------------------ charges
    def fluid_counts(self, c=None):
        """N_s = DX^3 sum_x (1 - phi) c_s, (S,) (through J's buffer)."""
        c = self.c if c is None else c
        w = np.subtract(1.0, self.phi, out=self._J[1])
        t = self._J[2]
        return np.array([float(np.sum(np.multiply(w, c[s], out=t)))
                         for s in range(self.S)]) * self.dv

    def ionic_charge(self, c=None):
        """sum_s z_s c_s (1 - phi)."""
        c = self.c if c is None else c
        out = np.zeros(self.grid.shape)
        for s in range(self.S):
            out += self.z[s] * c[s]
        out *= 1.0 - self.phi
        return out

    def charge_density(self, c=None):
        """rho_e = rho_surf + sum_s z_s c_s (1 - phi), into J's first component (valid until
        the next call writing J)."""
        rho = self._J[0]
        c = self.c if c is None else c
        K = _compiled.ions
        if K is not None and c.flags.c_contiguous:          # the same operations, one pass
            K.charge_density(c, self.z, self.phi, self.rho_surf, rho)
            return rho
        np.copyto(rho, self.ionic_charge(c))
        rho += self.rho_surf
        return rho

    def total_charge(self):
        return float(np.sum(self.charge_density())) * self.dv

    def potential(self, c=None, truncate=False):
        """Psi_hat of the charge density (2/3-truncated with ``truncate``: the original's
        for the ions' flux, fluid_solver.cxx Rhs_NS_Nernst_Planck; not for the Coulomb
        force, operate_electrolyte.cxx Make_Coulomb_force_x_on_fluid), and grad Psi in real
        space (``self.grad_psi``, without the external field).  Returns Psi_hat."""
        g = self.grid
        if truncate:                    # used on the 2/3 mask only
            g.rfft_scalar_truncated(self.charge_density(c), self.psi_hat)
        else:
            g.rfft_scalar(self.charge_density(c), out=self.psi_hat)
        K = _compiled.ions
        if K is not None:                                   # the same operations, one pass
            K.scale_potential(self.psi_hat, g.inv_k2, self.eps, self._mask, bool(truncate))
        else:
            self.psi_hat *= g.inv_k2
            self.psi_hat /= self.eps
            if truncate:
                self.psi_hat *= self._mask
        self._gradient(self.psi_hat, self.grad_psi, truncated=truncate)
        return self.psi_hat

    def _gradient(self, f_hat, out, *, truncated):
        """out = grad f (3, NX, NY, NZ) of f_hat, each component i k_d f_hat / N made in a
        scalar scratch and transformed (the bits of the vector transform); ``truncated``:
        f_hat is 0 outside the 2/3 mask (kapsel.mesh.grid's truncated transforms)."""
        g, s = self.grid, self._cs
        backward = g.backward_scalar_truncated if truncated else g.backward_scalar_raw
        K = _compiled.ions
        for d in range(3):
            if K is not None:
                K.gradient_component(f_hat, g.k_axes[d], d, 1.0 / g.size, s)
            else:
                np.multiply(f_hat, self._ik[d], out=s)
                s *= 1.0 / g.size
            backward(s, out[d])

    def potential_real(self):
        """Psi in real space (of the last ``potential``; Psi_hat shares the scratch of
        ``step`` and of the lender's calls: call it right after ``potential``)."""
        return self.grid.irfft_scalar(self.psi_hat)

    # ------------------------------------------------------------------ dynamics
    def step(self, u, E=(0.0, 0.0, 0.0)):
        """c_s += dt div J_s (module docstring) with the fluid velocity u (3, ...) or None,
        grad Psi of the last ``potential`` and the external field E: on c_hat, c its c2r.
        c_hat is first 2/3-truncated and c made of it anew when it is not ``banded`` (the
        first step; the original truncates its Concentration at every step, a no-op after
        the first: its div J is truncated)."""
        g = self.grid
        E = np.asarray(E, dtype=float)
        J = self._J
        K = _compiled.ions
        inv_n = 1.0 / g.size
        for s in range(self.S):
            c, ch = self.c[s], self.c_hat[s]
            if not self.banded:                      # c_s truncated, as the original's
                if K is not None:                    # (Rhs_NS_solute): ch masked, cs =
                    K.mask_scaled(ch, self._mask, inv_n, self._cs)       # ch / N: one pass
                    g.backward_scalar_truncated(self._cs, c)
                else:
                    ch *= self._mask
                    g.irfft_scalar(ch, out=c)
            self._gradient(ch, J, truncated=True)    # grad c (c_hat is truncated)
            a, b = self.L[s] * self.kBT, self.L[s] * self.z[s]
            if K is not None and (u is None or u.flags.c_contiguous):
                # migration, impermeable surfaces and advection in one pass
                K.flux(J, self.grad_psi, E, c, a, b, J if u is None else u, u is not None,
                       self._normal_at, self._normal, self._inv_n2)
                for d in range(2):                   # ch = i k . FFT(J), masked: c_hat +=
                    g.rfft_scalar_truncated(J[d], self._cs)  # dt ch, cs = c_hat / N
                    K.divergence_accumulate(self._cs, g.k_axes[d], d, self._ch)
                g.rfft_scalar_truncated(J[2], self._cs)
                K.divergence_euler(self._cs, g.k_axes[2], self._ch, self._mask, self.dt,
                                   inv_n, self._k0, ch)
                g.backward_scalar_truncated(self._cs, c)
                continue
            t = np.empty(g.shape)
            for d in range(3):
                J[d] *= a
                np.subtract(self.grad_psi[d], E[d], out=t)
                t *= c
                t *= b
                J[d] += t
            # impermeable surfaces: J <- J - n (J.n)/|n|^2 where n is not zero
            at, n = self._normal_at, self._normal
            if at.size:
                Jf = J.reshape(3, -1)
                Jn = Jf[:, at]
                tn = Jn[0] * n[0]
                tn += Jn[1] * n[1]
                tn += Jn[2] * n[2]
                tn *= self._inv_n2
                for d in range(3):
                    Jf[d, at] = Jn[d] - tn * n[d]
            if u is not None:
                for d in range(3):
                    np.multiply(c, u[d], out=t)
                    J[d] -= t
            for d in range(3):                       # ch = i k . FFT(J), masked below
                g.rfft_scalar_truncated(J[d], self._cs)
                if d == 0:
                    np.multiply(self._cs, self._ik[0], out=self._ch)
                else:
                    self._cs *= self._ik[d]
                    self._ch += self._cs
            self._ch *= self._mask
            if self._k0:
                self._ch[0, 0, 0] = 0.0                     # exact: the mean of div J is 0
            self._ch *= self.dt
            ch += self._ch
            np.multiply(ch, inv_n, out=self._cs)
            g.backward_scalar_truncated(self._cs, c)
        self.banded = True

    def densities_set(self):
        """After ``c`` was written (an initial profile, a restart without its state file):
        c_hat its r2c, not yet truncated (the original's A2a_k of its initial profile)."""
        for s in range(self.S):
            self.grid.rfft_scalar(self.c[s], out=self.c_hat[s])
        self.banded = False

    def rescale(self):
        """c_s *= N_s(0) / N_s: the ions in the fluid keep their initial numbers."""
        now = self.fluid_counts()
        for s in range(self.S):
            if now[s] > 0:
                f = self.counts[s] / now[s]
                self.c[s] *= f
                self.c_hat[s] *= f

    def coulomb_force(self, E=(0.0, 0.0, 0.0), out=None, scale=1.0):
        """Coulomb force density of the ions' charge, sum_s z_s c_s (1 - phi) (E - grad Psi),
        (3, NX, NY, NZ), times ``scale``, with grad Psi and rho_e (J[0]) of the last
        ``potential`` (no call writing J between); the particles' own charge gets its force
        from ``particle_force``."""
        out = self._J if out is None else out         # J is free between steps
        rho_e = self._J[0]
        K = _compiled.ions
        if K is not None:                             # the same operations, one pass (rho_e
            K.coulomb_force(np.asarray(E, dtype=float), self.grad_psi, rho_e,   # read at
                            self.rho_surf, float(scale), out)           # each point first)
            return out
        rho = rho_e - self.rho_surf                   # (a new array: out may be J)
        for d in range(3):
            np.subtract(E[d], self.grad_psi[d], out=out[d])
            out[d] *= rho
            if scale != 1.0:
                out[d] *= scale
        return out

    def particle_force(self, E=(0.0, 0.0, 0.0)):
        """Force and torque (N, 3) on each particle's own surface charge,
        F_i = DX^3 sum_x rho_surf,i (E - grad Psi), T_i = DX^3 sum_x r x rho_surf,i (E -
        grad Psi), with grad Psi of the last ``potential`` (r from the particle centre)."""
        if self._idx is None:
            return np.zeros((0, 3)), np.zeros((0, 3))
        idx, q, r = self._idx, self._q, self._r
        f = np.empty((3,) + idx.shape)
        for d in range(3):
            f[d] = q * (E[d] - self.grad_psi[d].reshape(-1)[idx])
        F = f.sum(axis=2).T * self.dv
        T = np.stack([(r[..., 1] * f[2] - r[..., 2] * f[1]).sum(axis=1),
                      (r[..., 2] * f[0] - r[..., 0] * f[2]).sum(axis=1),
                      (r[..., 0] * f[1] - r[..., 1] * f[0]).sum(axis=1)], axis=1) * self.dv
        return F, T

    # ------------------------------------------------------------------ initial profiles
    def init_uniform(self, counts):
        """c_s = N_s / (DX^3 sum_x (1 - phi)) everywhere (inside the particles too; the
        (1 - phi) of rho_e and of the counts removes it there)."""
        self.counts = np.asarray(counts, dtype=float).copy()
        vfree = float(np.sum(1.0 - self.phi)) * self.dv
        for s in range(self.S):
            self.c[s] = self.counts[s] / vfree
        self.densities_set()

    def init_poisson_boltzmann_bulk(self, bulk, Z_total, tol=1e-4, mix=0.01, max_iter=99999):
        """The original's Poisson-Boltzmann start of one particle in a symmetric salt
        (operate_electrolyte.cxx Set_Poisson_Boltzmann_ion_charge_density_salt): bulk
        densities n_s (``bulk``) held, c_+ = n_+ e^{-z_+ Psi / kBT} nu, c_- = n_- e^{-z_- Psi
        / kBT} / nu with nu the root of z_+ n_+ P nu^2 + Z nu + z_- n_- M = 0 (P, M =
        DX^3 sum (1 - phi) e^{-z Psi / kBT}: the ions neutralise the particle charge Z);
        Psi <- Psi + mix (Psi[rho_e(c)] - Psi) from Psi = 0 until sum |dPsi| / sum |Psi|
        < tol, c of the last Psi before the update.  The ion numbers held from then on
        are those of this state.  Returns the number of iterations."""
        g = self.grid
        n = np.asarray(bulk, dtype=float)
        free = 1.0 - self.phi
        psi = np.zeros(g.shape)
        psi_h = g.empty_complex(None)
        for it in range(1, max_iter + 1):
            b = [np.exp(-self.z[s] / self.kBT * psi) for s in range(2)]
            P, M = (float(np.sum(free * b[s])) * self.dv for s in range(2))
            qa, qb, qc = self.z[0] * n[0] * P, float(Z_total), self.z[1] * n[1] * M
            nu = (-qb + np.sqrt(qb * qb - 4.0 * qa * qc)) / (2.0 * qa)
            self.c[0] = n[0] * b[0] * nu
            self.c[1] = n[1] * b[1] / nu
            g.rfft_scalar(self.charge_density(), out=psi_h)
            psi_h *= g.inv_k2
            psi_h /= self.eps
            dpsi = g.irfft_scalar(psi_h)
            dpsi -= psi
            dpsi *= mix
            psi += dpsi
            if float(np.abs(dpsi).sum()) / float(np.abs(psi).sum()) < tol:
                self.counts = self.fluid_counts()
                self.densities_set()
                return it
        raise FloatingPointError(f"the Poisson-Boltzmann iteration of the initial ion "
                                 f"profile did not converge in {max_iter} iterations")

    def init_poisson_boltzmann(self, counts, tol=1e-10, max_iter=2000):
        """The Poisson-Boltzmann equilibrium at fixed ion numbers N_s (canonical):
        c_s = N_s exp(-z_s Psi / kBT) / (DX^3 sum_x (1 - phi) exp(-z_s Psi / kBT)) with
        eps lap Psi = -rho_e(Psi).  Solved for Psi by the screened iteration
        Psi <- Psi + w (eps lap Psi + rho_e(Psi))_k / (eps (k^2 + kappa^2)),
        kappa^2 = sum_s z_s^2 <c_s> / (eps kBT) (a Newton step with the Jacobian replaced by
        its mean; w halves when the residual grows), until max |dPsi| < tol kBT.
        Returns the number of iterations.  Raises FloatingPointError if it does not
        converge."""
        g = self.grid
        self.init_uniform(counts)
        vfree = float(np.sum(1.0 - self.phi)) * self.dv
        kappa2 = float(np.sum(self.z ** 2 * self.counts / vfree)) / (self.eps * self.kBT)
        precond = 1.0 / (self.eps * (g.k2 + kappa2))
        if kappa2 == 0:
            precond = g.inv_k2 / self.eps
        psi = np.zeros(g.shape)
        res_h = g.empty_complex(None)
        w, last = 1.0, np.inf
        free = 1.0 - self.phi

        def boltzmann(psi):
            c = np.empty_like(self.c)
            for s in range(self.S):
                x = -self.z[s] * psi / self.kBT
                x -= x.max()
                b = np.exp(x)
                c[s] = self.counts[s] * b / (float(np.sum(free * b)) * self.dv)
            return c

        for it in range(1, max_iter + 1):
            c = boltzmann(psi)
            g.rfft_scalar(psi, out=res_h)
            res_h *= -self.eps * g.k2
            res_h += g.rfft_scalar(self.charge_density(c))
            res_h[0, 0, 0] = 0.0
            norm = float(np.abs(res_h).max())
            if norm > last:
                w *= 0.5
            last = norm
            res_h *= precond
            res_h *= w
            dpsi = g.irfft_scalar(res_h)
            psi += dpsi
            if float(np.abs(dpsi).max()) < tol * self.kBT:
                self.c[...] = boltzmann(psi)
                self.densities_set()
                return it
        raise FloatingPointError(f"the Poisson-Boltzmann iteration of the initial ion "
                                 f"profile did not converge in {max_iter} iterations")
