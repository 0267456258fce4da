"""The ``Electrolyte`` type (PHYSICS-EXTRA §6): charged particles in an electrolyte, on the
pseudo-spectral fluid of ``Navier_Stokes`` with the ions of kapsel.fluid.ions.

One step, as the original's (sp_3d_ns.cxx Time_evolution_hydro with
fluid_solver.cxx NSsolute_solver_Euler):

1. at R^n: Psi of rho_e (2/3-truncated), grad Psi_tot = grad Psi - E(t); the ions'
   Nernst-Planck step c_s += dt div J_s with the 2/3-truncated fluid velocity T u^n (the
   u of the fluid's u x omega too), and the fluid's
   plain explicit Euler step u += dt P T[u x omega - nu k^2 u] (not the integrating-factor
   step of Navier_Stokes), both from the state of step n;
2. the particles move (kapsel.particles.spm), their profiles at R^{n+1}; c_s rescaled so
   that each species' number in the fluid keeps its initial value (``Ions.rescale``);
3. the Coulomb force density of the ions, rho_ion (E(t) - grad Psi) with rho_ion =
   sum_s z_s c_s (1 - phi) and Psi (not truncated) of rho_e = rho_surf + rho_ion at
   R^{n+1}, acts on the fluid: u += P T[dt rho_ion (E - grad Psi) / RHO]; the force on
   each particle's own surface charge, F_i = DX^3 sum_x rho_surf,i (E - grad Psi) (and its
   torque), acts on the particle (``Ions.particle_force``) in the velocity update;
4. the SPM step from its hydrodynamic force on: the particles' velocities, the rigidity
   increment.

Differences from the original, on purpose (docs/physics-electrolyte.md): the Coulomb force
on a particle's own charge acts on the particle (the original adds it to the fluid of the
interface shell, and its electrophoretic velocity falls 12-25 % short of Henry's); the
Poisson-Boltzmann start of salt-free or several particles is the canonical equilibrium at
fixed ion numbers (kapsel.fluid.ions; not yet the original's relaxation); ``saltfree`` +
``Uniform`` starts neutral; ``kBT`` 0 is refused.  No thermal noise (the original skips the
thermostat for Electrolyte).
"""
from __future__ import annotations

import numpy as np

from ..config import ConfigError
from ..typespec import register
from ..particles.interactions import OVERLAP_LIMIT, Callback
from .common import make_forces, make_particles
from .spectral import SpectralModel


def external_field(el, t: float) -> np.ndarray:
    """E(t): E (DC) or E sin(2 pi f t) (AC); zero when the field is OFF."""
    E = np.asarray(el.E, dtype=float)
    if el.field_kind == "AC":
        return E * np.sin(2.0 * np.pi * el.frequency * t)
    if el.field_kind == "DC":
        return E.copy()
    return np.zeros(3)


def ion_numbers(el, charges, free_volume: float, kBT: float) -> np.ndarray:
    """N_s of every species (PHYSICS-EXTRA §6.4): salt-free, the counterions -sum Z / z_c;
    with salt, the bulk n_s,inf times the free volume plus the counterions of the
    particles of the other sign (|Z| / |z_s|)."""
    Z = np.asarray(charges, dtype=float)
    if not el.salt:
        return np.array([-Z.sum() / el.valency[0]])
    from ..fluid.ions import bulk_densities
    zp, zn = el.valency
    np_, nn = bulk_densities(el.valency, el.debye_length, el.dielectric, kBT)
    return np.array([np_ * free_volume - Z[Z < 0].sum() / zp,
                     nn * free_volume + Z[Z > 0].sum() / (-zn)])


class _IonSPM:
    """The SPM step of the Electrolyte type (module docstring): the fluid's step is
    ``model.fluid_and_ions`` and the Coulomb force reaches the fluid just before the
    hydrodynamic force is taken.  Mixed into kapsel.particles.spm.SPM."""
    model = None

    def _fluid_step(self):
        self.model.fluid_and_ions()
        if not self.n_global:                   # no hydrodynamic force to wait for
            self.model.coulomb_on_fluid()       # (else u* is made by _hydro_sums, after it)

    def _hydro_sums(self):
        self.model.coulomb_on_fluid()
        # u_hat is truncated: the Euler step truncates it, the Coulomb force is added P T
        self.fluid.velocity(out=self.u, truncated=True)
        return super()._hydro_sums()


class ElectrolyteModel(SpectralModel):
    def __init__(self, cfg, args):
        from ..fluid.ions import Ions
        from ..fluid.spectral import SpectralNS
        from ..models.common import Model
        from ..particles.spm import SPM
        Model.__init__(self, cfg, args)
        f, el = cfg.fluid, cfg.electrolyte
        self.el = el
        self.grid = self.make_grid(cfg)
        self.fluid = SpectralNS(self.grid, f.RHO, f.ETA, self.dt, fix_cell=cfg.switches.fix_cell,
                                state=self.state)
        self.particles = make_particles(cfg, self.rng)
        spm_class = type("IonSPM", (_IonSPM, SPM), {"model": self})
        self.spm = spm_class(self.fluid, self.particles, self.spm_radius(), cfg.particles.A_XI,
                             f.RHO, cfg.mesh.DX, self.dt, rotation=cfg.switches.ROTATION,
                             forces=self._with_charge_force(make_forces(
                                 cfg, self.particles, overlap_limit=OVERLAP_LIMIT)), noise=None,
                             dry=self.dry)    # --check: no profiles
        p = self.particles
        self.charges = np.array([cfg.particles.species[s].surface_charge for s in p.species],
                                dtype=float)
        # the ions' flux, grad Psi and transform scratch in the fluid's buffers that are
        # free between its calls (72 bytes per point less; issue 25)
        nl, s, t = self.fluid.scratch_between_steps()
        self.ions = Ions(self.grid, el.valency, el.onsager, el.dielectric, f.kBT, self.dt,
                         state=self.state, scratch=(self.fluid.scratch_real()[1], nl, t, s))
        self._dt_limit = self._ion_limit()
        if self.dry:      # --check: no profiles, no ion densities; the signs of the ion
            vfree = self.grid.volume    # numbers do not depend on the free volume
        else:
            self._geometry()
            vfree = float(np.sum(1.0 - self.ions.phi)) * self.ions.dv
        counts = ion_numbers(el, self.charges, vfree, f.kBT)
        if np.any(counts < 0):
            raise ConfigError("the particle charges need a negative number of ions",
                              path="object_type", value=list(self.charges))
        if self.dry:
            return
        if el.init_profile == "Poisson_Boltzmann":
            try:
                if el.salt and p.n == 1:        # the original's one-particle salt start
                    if el.valency[0] != -el.valency[1]:
                        raise ConfigError(
                            "the Poisson-Boltzmann start of one particle in salt needs "
                            "Valency_positive_ion = -Valency_negative_ion (as the original)",
                            path="constitutive_eq.Electrolyte.Add_salt.salt",
                            value=list(el.valency))
                    from ..fluid.ions import bulk_densities
                    self.pb_iterations = self.ions.init_poisson_boltzmann_bulk(
                        bulk_densities(el.valency, el.debye_length, el.dielectric, f.kBT),
                        float(self.charges.sum()))
                else:
                    self.pb_iterations = self.ions.init_poisson_boltzmann(counts)
            except FloatingPointError as e:
                raise ConfigError(str(e), path="constitutive_eq.Electrolyte.INIT_profile",
                                  value=el.init_profile) from None
        else:
            self.ions.init_uniform(counts)

    _charge_force = None                         # (F, T) on the particles' own charge

    def _with_charge_force(self, forces):
        """The particles' other forces plus the Coulomb force on their own charge of this
        step (``Ions.particle_force``, set by ``coulomb_on_fluid``)."""
        def total(p):
            F, T = (np.zeros((p.n, 3)), np.zeros((p.n, 3))) if forces is None else forces(p)
            if self._charge_force is not None:
                F = F + self._charge_force[0]
                T = T + self._charge_force[1]
            return F, T
        return Callback(total, virial=None if forces is None else forces.virial)

    def _geometry(self):
        p, cfg = self.particles, self.cfg
        if p.n:
            self.ions.set_particles(self.spm.idx, self.spm.phi_i, self.spm.r, self.charges,
                                    cfg.particles.A, cfg.particles.A_XI)
        else:
            self.ions.no_particles()

    def field_now(self) -> np.ndarray:
        return external_field(self.el, self.time)

    def advance(self):
        self.spm.step()
        self.tick()

    def fluid_and_ions(self):
        """Step 1 of the module docstring: the ions' and the fluid's explicit Euler steps
        from the state at t^n (fluid_solver.cxx NSsolute_solver_Euler)."""
        ions, fl = self.ions, self.fluid
        ions.potential(truncate=True)
        u = fl.truncated_velocity()          # T u^n, the u of the ions' advection and of
        ions.step(u, self.field_now())       # the fluid's u x omega (as the original's
        fl.euler_step(u_ready=True)          # Rhs_NS_solute): ions first, then the fluid
        if self.dt > 2 * self._dt_limit:         # past the ion step's limit: name it first
            what = self._ions_broke()
            if what is not None:
                from ..errors import InstabilityError
                raise InstabilityError(what)

    def coulomb_on_fluid(self):
        """Steps 2-3 of the module docstring at the particles' new positions: the ions
        rescaled, then u += P T[dt rho_e (E - grad Psi) / RHO] (sp_3d_ns.cxx
        Time_evolution_hydro, operate_electrolyte.cxx Make_Coulomb_force_x_on_fluid)."""
        self._geometry()
        ions = self.ions
        ions.rescale()
        ions.potential()
        E = self.field_now()
        force = ions.coulomb_force(E, scale=self.dt / self.cfg.fluid.RHO)
        self._charge_force = ions.particle_force(E) if self.particles.n else None
        self.fluid.add_solenoidal(force)

    def _ion_limit(self) -> float:
        from ..timestep import kmax2
        return 1.0 / (self.cfg.fluid.kBT * max(self.el.onsager)
                      * kmax2(self.cfg.mesh.DX, self.cfg.mesh.shape))

    def _ions_broke(self) -> str | None:
        """The message naming the ion step when the ion densities are not finite, or negative
        with dt past twice the explicit step's limit; else None."""
        lim = self._dt_limit
        c = self.ions.c
        if not np.isfinite(c).all() or (self.dt > 2 * lim and c.min() < 0):
            return (f"the ion densities are not finite or negative; the explicit "
                    f"ion step is stable for dt <= 1 / (kBT L_max KMAX2) = {lim:.6g}, "
                    f"dt is {self.dt:.6g}")
        return None

    def stability(self):
        """The CFL check of every type, and finite ion densities (an explicit ion step past
        its limit 1 / (kBT L_max K2max), e.g. with a manual dt, blows them up first)."""
        what = self._ions_broke()
        if what is not None:
            return 2.0, what
        return super().stability()

    # ------------------------------------------------------------------ diagnostics
    def ion_numbers(self) -> np.ndarray:
        return self.ions.fluid_counts()

    def total_charge(self) -> float:
        return self.ions.total_charge()

    def free_energy(self) -> dict:
        """Free-energy terms (FORMAT-OUTPUT.md §1.5): ideal gas kBT sum c (ln c - 1) over
        the fluid, electrostatic 1/2 sum rho_e Psi, and the total ionic charge and the ion
        numbers."""
        ions = self.ions
        ions.potential()
        free = 1.0 - ions.phi
        ideal = 0.0
        for s in range(ions.S):
            c = np.maximum(ions.c[s], 1e-300)
            ideal += float(np.sum(free * c * (np.log(c) - 1.0)))
        ideal *= ions.kBT * ions.dv
        psi = ions.potential_real()
        elec = 0.5 * float(np.sum(ions.charge_density() * psi)) * ions.dv
        liquid = float(np.sum(ions.ionic_charge())) * ions.dv
        return {"total": ideal + elec, "ideal_gas": ideal, "electrostatic": elec,
                "liquid_charge": liquid, "numbers": ions.fluid_counts()}

    def field_sources(self) -> dict:
        src = super().field_sources()
        ions = self.ions

        def potential():
            ions.potential()
            return ions.potential_real().copy()
        area = 4.0 * np.pi * self.cfg.particles.A ** 2 if self.particles.n else 0.0
        # the original writes rho_surf 4 pi a^2 (output.cxx Output_charge_field_data)
        src["surface_charge"] = lambda: ions.rho_surf * area
        src["solute_charge"] = ions.ionic_charge
        src["e_potential"] = potential
        src["concentration"] = lambda: ions.c.copy()
        src["free_energy"] = self.free_energy
        return src

    # ------------------------------------------------------------------ restart
    def restart_fields(self) -> dict:
        """Zeta, uk_dc and Concentration[n][i][j][k] {ck}: the unnormalised r2c transform of
        every c_s (the ions' c_hat), (re, im) pairs along k (k < NZ + 2), FORMAT-OUTPUT.md
        §6.2."""
        out = super().restart_fields()
        g = self.grid
        out["Concentration"] = self.ions.c_hat.view(np.float64).reshape(
            (self.ions.S,) + g.shape[:2] + (2 * g.cshape[2],))
        return out

    def exact_state(self) -> dict:
        st = super().exact_state()
        st["ion_c"] = self.ions.c          # written at once (no copy: issue 25)
        st["ion_c_hat"] = self.ions.c_hat
        st["ion_counts"] = self.ions.counts.copy()
        st["ion_banded"] = np.array(self.ions.banded)
        return st

    def load_fields(self, fields: dict, exact) -> None:
        super().load_fields(fields, exact)
        self._geometry()
        g, ions = self.grid, self.ions
        where = f"resume.{self.cfg.resume.calculation}.Saved_Data.Concentration[]"
        if exact and "ion_c" in exact:
            if exact["ion_c"].shape != ions.c.shape:
                raise ConfigError(f"the restart's ion densities have shape "
                                  f"{exact['ion_c'].shape}, the run needs {ions.c.shape}",
                                  path=where, value="shape")
            ions.c[...] = exact["ion_c"]
            if "ion_c_hat" in exact:            # (a state file of before 2026-12-05: c only)
                ions.c_hat[...] = exact["ion_c_hat"]
                ions.banded = bool(exact["ion_banded"])
            else:
                ions.densities_set()
            ions.counts = np.asarray(exact["ion_counts"], dtype=float).copy()
            return
        ck = fields.get("Concentration")
        want = (ions.S,) + g.shape[:2] + (2 * g.cshape[2],)
        if ck is None or ck.shape != want:
            raise ConfigError(f"the restart's Concentration has shape "
                              f"{None if ck is None else list(ck.shape)}, the run needs "
                              f"{list(want)} (species, NX, NY, NZ + 2)", path=where,
                              value="shape")
        for s in range(ions.S):
            ions.c_hat[s] = np.ascontiguousarray(ck[s]).view(np.complex128).reshape(g.cshape)
            ions.c[s] = g.irfft_scalar(ions.c_hat[s])
        ions.banded = False                     # the first step truncates it, as the original
        ions.counts = ions.fluid_counts()


@register("Electrolyte")
def make_electrolyte(cfg, args, doc):
    return ElectrolyteModel(cfg, args)
