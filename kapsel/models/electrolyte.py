"""The ``Electrolyte`` type (PHYSICS-EXTRA §6): charged particles in an electrolyte, on the
pseudo-spectral fluid of ``Navier_Stokes`` with the ions of kapsel.fluid.ions.

One step (§6.3, with the differences below):

1. Psi and grad Psi of the charge density rho_e at the current state;
2. Nernst-Planck: c_s += dt div J_s with the current u and particle positions;
3. fluid and particles by the SPM step (kapsel.particles.spm) with the Coulomb force
   density of the ions, rho_ion (E(t) - grad Psi) / RHO, rho_ion = sum_s z_s c_s (1 - phi),
   as the fluid's body force of this step, and the Coulomb force on each particle's own
   surface charge, F_i = DX^3 sum_x rho_surf,i (E(t) - grad Psi) (and its torque), as a
   force on the particle (``Ions.particle_force``);
4. new profiles; c_s rescaled so that each species' number in the fluid stays at its
   initial value (``Ions.rescale``).

Differences from the original, on purpose (docs/physics-electrolyte.md):
* the fluid step is the integrating-factor (slaved) step of Navier_Stokes, exact for the
  viscous decay, not the original's plain explicit Euler for zeta, and the Coulomb force
  enters that step rather than a separate Euler fractional step;
* the Coulomb force on a particle's own charge acts on the particle; the original adds
  it to the fluid of the interface shell, where only the phi-weighted part reaches the
  particle through the SPM exchange: a sphere so pushed (A = 4, 32^3, dt = 0.0715) moved
  about 9 % slower than under the same force on the particle, and so did its
  electrophoresis (kappa a = 0.5: 0.805 against 0.892 of Henry's uncorrected velocity);
* each particle's surface charge is normalised to carry exactly its Z_i (the original
  scales all particles by one common factor, so identical particles at different sub-grid
  positions carry slightly different charges);
* the Poisson-Boltzmann initial profile is the canonical equilibrium at fixed ion numbers
  for every case (salt-free or salt, one or several particles), solved by a screened
  Newton-like iteration (kapsel.fluid.ions); with a field on, the run starts from it;
* the surface-charge output field is the charge density rho_surf itself (DX^3 sum =
  sum_i Z_i), not rho_surf 4 pi a^2.

No thermal noise (the original skips the thermostat for Electrolyte).
"""
from __future__ import annotations

import numpy as np

from ..config import ConfigError
from ..simulation import register
from .common import make_forces, make_particles, overlap_guard
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


class ElectrolyteModel(SpectralModel):
    def __init__(self, cfg, args):
        from ..fluid.ions import Ions
        from ..fluid.spectral import SpectralNS
        from ..grid import Grid
        from ..models.common import Model
        from ..particles.spm import SPM
        Model.__init__(self, cfg, args)
        f, el = cfg.fluid, cfg.electrolyte
        self.el = el
        self.grid = Grid(cfg.mesh.shape, cfg.mesh.DX, threads=self.threads)
        self.fluid = SpectralNS(self.grid, f.RHO, f.ETA, self.dt, fix_cell=cfg.switches.fix_cell)
        self.particles = make_particles(cfg, self.rng)
        self._charge_force = None                  # (F, T) on the particles' own charge
        self.spm = SPM(self.fluid, self.particles, self.spm_radius(), cfg.particles.A_XI, f.RHO,
                       cfg.mesh.DX, self.dt, rotation=cfg.switches.ROTATION,
                       forces=self._with_charge_force(
                           overlap_guard(make_forces(cfg, self.particles))), noise=None,
                       dry=self.dry)    # --check: no profiles
        p = self.particles
        self.charges = np.array([cfg.particles.species[s].surface_charge for s in p.species],
                                dtype=float)
        self.ions = Ions(self.grid, el.valency, el.onsager, el.dielectric, f.kBT, self.dt)
        self._force_hat = self.grid.empty_complex()
        self._dt_limit = self._ion_limit()
        self._u = self.grid.empty_real()
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
                self.pb_iterations = self.ions.init_poisson_boltzmann(counts)
            except FloatingPointError as e:
                raise ConfigError(str(e), path="constitutive_eq.Electrolyte.INIT_profile",
                                  value=el.init_profile) from None
        else:
            self.ions.init_uniform(counts)

    def _with_charge_force(self, forces):
        """The particles' other forces plus the Coulomb force on their own charge of this
        step (``Ions.particle_force``, set by ``advance``)."""
        def total(p):
            F, T = (np.zeros((p.n, 3)), np.zeros((p.n, 3))) if forces is None else forces(p)
            if self._charge_force is not None:
                F = F + self._charge_force[0]
                T = T + self._charge_force[1]
            return F, T
        total.virial = getattr(forces, "virial", None)
        return total

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
        E = self.field_now()
        ions = self.ions
        ions.potential()
        self.fluid.velocity(out=self._u)
        # rho_e of the state before the ion step: the ions' charge forces the fluid, the
        # particles' own charge forces the particles
        force = ions.coulomb_force(E, surface=False)
        self._charge_force = ions.particle_force(E) if self.particles.n else None
        force /= self.cfg.fluid.RHO
        fh = self._force_hat
        self.grid.forward(force, out=fh)
        self.grid.project(fh)
        ions.step(self._u, E)
        if self.dt > 2 * self._dt_limit:         # past the ion step's limit: name it first
            what = self._ions_broke()
            if what is not None:
                from ..simulation import InstabilityError
                raise InstabilityError(what)
        self.fluid.force_hat = fh
        try:
            self.spm.step()
        finally:
            self.fluid.force_hat = None
        self._geometry()
        ions.rescale()
        self.tick()

    def _ion_limit(self) -> float:
        from ..timestep import kmax2
        return 1.0 / (self.cfg.fluid.kBT * max(self.el.onsager)
                      * kmax2(self.cfg.mesh.DX, self.cfg.mesh.shape))

    def _ions_broke(self) -> str | None:
        """The message naming the ion step when the ion densities are not finite, or negative
        with dt past twice the explicit step's limit; else None."""
        lim = self._ion_limit()
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
        src["surface_charge"] = lambda: ions.rho_surf.copy()
        src["solute_charge"] = ions.ionic_charge
        src["e_potential"] = potential
        src["concentration"] = lambda: ions.c.copy()
        src["free_energy"] = self.free_energy
        return src

    # ------------------------------------------------------------------ restart
    def restart_fields(self) -> dict:
        """Zeta, uk_dc and Concentration[n][i][j][k] {ck}: the unnormalised r2c transform of
        every c_s, (re, im) pairs along k (k < NZ + 2), FORMAT-OUTPUT.md §6.2."""
        out = super().restart_fields()
        g = self.grid
        ck = np.empty((self.ions.S,) + g.shape[:2] + (2 * g.cshape[2],))
        for s in range(self.ions.S):
            h = g.rfft_scalar(self.ions.c[s])
            ck[s] = h.view(np.float64).reshape(ck.shape[1:])
        out["Concentration"] = ck
        return out

    def exact_state(self) -> dict:
        st = super().exact_state()
        st["ion_c"] = self.ions.c.copy()
        st["ion_counts"] = self.ions.counts.copy()
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
            h = np.ascontiguousarray(ck[s]).view(np.complex128).reshape(g.cshape)
            ions.c[s] = g.irfft_scalar(h)
        ions.counts = ions.fluid_counts()


@register("Electrolyte")
def make_electrolyte(cfg, args, doc):
    return ElectrolyteModel(cfg, args)
