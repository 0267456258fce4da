"""The finite-difference types: ``Navier_Stokes_FDM`` and ``Navier_Stokes_Cahn_Hilliard_FDM``.

One step (manual §5.1, §5.3, eqs 15-31):

1. chemical potential mu(psi*, phi*) and capillary force -psi* grad(mu*) / RHO (eq 15), the
   original's (FDMModel._capillary_force: the state psi^n, phi^n or its extrapolation);
2. MAC step of the fluid with that force (explicit eqs 20-21 or implicit eqs 23-26), with
   the viscosity field of ``viscosity_change`` (linear in composition, ETA_A .. ETA_B);
3. particles (SPM, eqs 6, 9-12): momentum exchange with the fluid after the step, new
   velocities, the rigidity force phi (u_p - u) made divergence-free (eq 22), new positions;
4. Cahn-Hilliard step of psi with the new velocity (eq 30 explicit / eq 31 BDF2).

The explicit Cahn-Hilliard scheme is only stable for dt below its linear limit (fourth
derivative); when the fluid dt exceeds it, psi is advanced in equal sub-steps below the
limit and the run says so once.
"""
from __future__ import annotations

import math
import sys

import numpy as np

from ..config import ConfigError, RunConfig
from ..typespec import register
from ..particles.spm import SPM
from ..particles.interactions import OVERLAP_LIMIT
from .common import Model, kinetic_energy, make_forces, make_noise, make_particles


class _ModelH_SPM(SPM):
    """SPM whose MAC fluid step takes the capillary force and the viscosity field (eq 15),
    followed, as in the original, by switch.FIX_CELL: the mean (k = 0) velocity of each
    flagged direction is removed right after the fluid step."""
    fix_cell = (False, False, False)

    def _fluid_step(self, force=None, eta_field=None):
        self.fluid.step(self.u, force=force, eta_field=eta_field)
        for c, on in enumerate(self.fix_cell):
            if on:
                self.u[c] -= self.fluid.mean(self.u[c])


class FDMModel(Model):
    sheared_start = False       # the sheared types' start of the particles (ShearFDMModel)

    def __init__(self, cfg: RunConfig, args):
        from ..errors import UnstableTimeStep
        super().__init__(cfg, args)
        threads, seed = self.threads, self.seed
        shape, dx = cfg.mesh.shape, cfg.mesh.DX
        f = cfg.fluid
        self.rho, self.dx, self.shape = f.RHO, dx, shape
        self.grid = self._make_grid(cfg)
        self.mac = self._make_fluid(cfg)
        try:
            self.mac.check_stability()
        except UnstableTimeStep as e:
            raise ConfigError(str(e), path="time_increment", value=self.dt) from None

        # particles (SPM on the MAC grid; the step hook adds the Model-H force)
        from ..particles.walls import make_wall
        self.particles = make_particles(cfg, self.rng)
        self.wall = make_wall(cfg)
        self.spm = _ModelH_SPM(self.mac, self.particles, self.spm_radius(), cfg.particles.A_XI,
                               f.RHO, dx, self.dt, rotation=cfg.switches.ROTATION,
                               forces=make_forces(
                                   cfg, self.particles, strain=self._pair_strain(),
                                   wall=self.wall, overlap_limit=OVERLAP_LIMIT),
                               noise=make_noise(cfg, self.particles, seed), wall=self.wall,
                               u=self.state.field("u", lambda: np.zeros((3,) + self.mac.fshape)),
                               impose=not self.sheared_start, dry=self.dry)
        self.spm.interpolation = getattr(self, "interpolation", "linear")   # (OBL_INT)
        if self.sheared_start:
            self.spm.start_sheared(impose=not self.dry)    # as the original (SPM.start_sheared)
        self.spm.fix_cell = self._fix_cell(cfg)
        self.u = self.spm.u
        self.phi = self.spm.phi() if self.particles.n and not self.dry else None

        # phase field (psi, psi^{n-1}, the capillary force of the last step and the profile
        # at its start: in the state)
        self.ch = None
        self.psi = None
        self.last_force = None
        self._phi_prev = None
        self.eta_field = None
        if cfg.has_phase_field:
            ph = cfg.phase
            # FFT preconditioner: exact inverse of the linear part; 3-5x fewer BiCGSTAB
            # iterations than none (the original's choice) at the same tolerance
            self.ch_kwargs = dict(threads=threads, xi=cfg.particles.A_XI, preconditioner="fft",
                                  state=self.state)
            self.ch = self._make_ch(self.dt)
            self.psi = self.state.field("psi", lambda: self.ch.initial_field(self.phi))
            self.substeps = 1
            if ph.ch_solver == "explicit_scheme":
                limit = self.ch.stable_dt(self.psi, self.phi)
                if self.dt > 0.9 * limit:
                    self.substeps = math.ceil(self.dt / (0.9 * limit))
                    self.ch = self._make_ch(self.dt / self.substeps)
                    if not self.quiet and not self.dry:   # dry: phi not built
                        print(f"#explicit Cahn-Hilliard: dt = {self.dt:.4g} exceeds its "
                              f"stability limit {limit:.4g}; psi advances in {self.substeps} "
                              f"sub-steps per step", file=sys.stderr)
            if f.viscosity_change:
                self.eta_field = np.empty(self.psi.shape)
                self._update_viscosity()

    def _make_grid(self, cfg):
        """The mesh's layout (kapsel.parallel.make_layout; a distributed run: this rank's
        blocks) and the collective rank 0's writers call (the whole fields of the restart)."""
        from ..parallel import make_layout
        try:
            # one FFT thread: the SPM's projection, as before (the MAC solver's FFTs take
            # the run's threads themselves)
            grid = make_layout(cfg.mesh.shape, cfg.mesh.DX, self.dist, 1)
        except ValueError as e:
            raise ConfigError(str(e), path="mesh", value="process grid") from None
        self.collectives.register("whole",
                                  lambda name: grid.gather_real(self._restart_field(name)))
        return grid

    def _make_fluid(self, cfg):
        """The MAC solver of the type (the sheared types: kapsel.fluid.oblique.ObliqueMAC)
        on the layout (a distributed run: this rank's block)."""
        from ..fluid.mac import MACSolver
        f = cfg.fluid
        return MACSolver(self.grid, f.RHO, f.ETA, self.dt, scheme=f.ns_solver,
                         tolerance=f.tolerance, maximum_iteration=f.maximum_iteration,
                         threads=self.threads, state=self.state)

    def _make_ch(self, dt):
        """The Cahn-Hilliard solver of the type with time step dt, on the layout."""
        from ..phase import CahnHilliard
        try:
            return CahnHilliard(self.grid, self.cfg.phase, dt, wall=self.wall,
                                **self.ch_kwargs)
        except ValueError as e:
            raise ConfigError(str(e), path=f"constitutive_eq.{self.cfg.type}.Potential."
                              f"Landau.psi_0_wall.user_specify.psi_0_wall[]") from None

    @property
    def last_force(self):
        """The raw capillary force of the last step (the state's ``capillary_force``; the
        restart's STRESS_OLD, of the other sign)."""
        return self.state.get("capillary_force")

    @last_force.setter
    def last_force(self, value):
        self.state.put("capillary_force", value)

    @property
    def _phi_prev(self):
        """The particle profile at the start of the last step (the state's ``phi_prev``)."""
        return self.state.get("phi_prev")

    @_phi_prev.setter
    def _phi_prev(self, value):
        self.state.put("phi_prev", value)

    def _after_fluid(self):
        """Hook between the fluid-particle step and the Cahn-Hilliard step."""

    def _fix_cell(self, cfg):
        """switch.FIX_CELL flags (x, y, z) the fluid step applies."""
        return tuple(cfg.switches.fix_cell)

    def _capillary_force(self):
        """The Model-H force of the fluid step, as the original computes it (fdm.cxx
        NS_solver_slavedEuler_explicit / _implicit: Calc_cp, Cp2stress):
        -psi* grad(mu(psi*, phi*)) / RHO at the nodes (central gradient), on the fluid only.

        explicit_scheme: psi* = psi^n, phi* = phi^n; the force is returned as it is: the
        MAC step takes it into its explicit term n = (u.grad)u - F, whose Adams-Bashforth
        combination 3/2 n^n - 1/2 n^(n-1) from the third step on gives the original's
        Update_u_stress_ab2, and whose Poisson right-hand side holds the raw F^n as the
        original's Set_poisson_rhs_ps (combining F here as well would extrapolate it twice).
        implicit_scheme: psi* = (3 psi^n - psi^(n-1)) / 2 and phi* the profile at the
        extrapolated positions (3 R^n - R^(n-1)) / 2 (its Calc_ab2_val, Make_phi_s); with
        viscosity_change the viscosity field of psi* (Psi2eta).  The first step takes psi^n
        and R^n (the original reads a psi^(n-1) it never set there: zero, so 3/2 psi^n).

        The particles feel the force through the fluid (their momentum exchange), as in the
        original; its discretisation leaves a small net force (a periodic sum of psi grad mu
        is not zero on the grid): switch.FIX_CELL removes the mean flow."""
        ch = self.ch
        implicit = self.cfg.fluid.ns_solver == "implicit_scheme"
        if implicit:
            psi = self.psi
            if self.ch.psi_old is not None:
                psi = 1.5 * self.psi - 0.5 * self.ch.psi_old
            phi = self._extrapolated_phi()
        else:
            psi, phi = self.psi, self.phi
        mu = ch.chemical_potential(psi, phi)
        raw = ch.capillary_force(psi, mu, self.rho)
        if self.eta_field is not None:
            self._update_viscosity(psi)
        self.last_force = raw
        return raw

    def _extrapolated_phi(self):
        """phi* of the original's implicit fluid step, the profile at the extrapolated
        positions (3 R^n - R^(n-1)) / 2 (its Make_phi_s), here (3 phi^n - phi^(n-1)) / 2
        clipped to [0, 1]: the same to second order in the step's displacement d (measured:
        3e-9 for d = 4e-5 DX, 8 particles at 32^3) and computed alike on every block of a
        distributed run.  phi^n on the first step, without particles, and in an oblique
        frame (whose re-mappings move the grid under phi^(n-1))."""
        if (self._phi_prev is None or self.phi is None
                or getattr(self.mac, "oblique", False)):
            return self.phi
        phi = self.phi * 1.5
        phi -= 0.5 * self._phi_prev
        return np.clip(phi, 0.0, 1.0, out=phi)

    def _pair_strain(self):
        """Lees-Edwards strain for the pair forces of a sheared fluid, else None."""
        if getattr(self.mac, "oblique", False):
            return lambda: self.mac.frame_strain
        return None

    # ------------------------------------------------------------------ phase field
    def _update_viscosity(self, psi=None):
        """eta = ETA_B + (ETA_A - ETA_B) s, s = (1 + psi) / 2 (Landau) or psi (Flory-Huggins)
        clipped to [0, 1], the fraction of the A phase (the original's Psi2eta), of psi
        (default the current field)."""
        fl = self.cfg.fluid
        psi = self.psi if psi is None else psi
        if self.cfg.phase.potential == "Landau":
            s = np.clip(0.5 * (1.0 + psi), 0.0, 1.0)
        else:
            s = np.clip(psi, 0.0, 1.0)
        np.multiply(s, fl.ETA_A - fl.ETA_B, out=self.eta_field)
        self.eta_field += fl.ETA_B

    # ------------------------------------------------------------------ the step
    def advance(self):
        force = None
        if self.ch is not None:
            force = self._capillary_force()
        phi = self.phi.copy() if self.phi is not None else None
        self.spm.step(force=force, eta_field=self.eta_field)
        self._phi_prev = phi
        self._after_fluid()
        if self.particles.n:
            self.phi = self.spm.phi()
        if self.ch is not None:
            for _ in range(self.substeps):      # implicit Euler on the first two (the original's)
                self.ch.step(self.psi, self.u, self.phi, euler=self.step_index < 2)
        self.tick()

    def stability(self):
        """The CFL number, and for the explicit MAC scheme its advection-diffusion bound
        dt <= 2 nu / max|u|^2 (kapsel.fluid.mac.MACSolver.stable_dt)."""
        ratio, what = super().stability()
        if self.cfg.fluid.ns_solver == "explicit_scheme" and np.isfinite(ratio):
            lim = self.mac.stable_dt(self.u, self.eta_field)
            if self.dt / lim > ratio:
                ratio, what = self.dt / lim, (f"dt = {self.dt:.4g} exceeds {lim:.4g}, the "
                                              f"advection-diffusion limit 2 nu / max|u|^2 of "
                                              f"the explicit MAC scheme")
        return ratio, what

    # ------------------------------------------------------------------ outputs
    def phi_total(self):
        """phi of the output: particles and walls, min(phi_sum, 1) (PHYSICS-EXTRA.md §2.3)."""
        if self.wall is None:
            return self.phi
        if self.phi is None:
            return np.array(self.wall.phi)
        return np.minimum(self.phi + self.wall.phi, 1.0)

    def kinetic_energy(self) -> float:
        return kinetic_energy(self.rho, self.dx, self.u, self.phi_total(),
                              self.spm.owned_particles(),
                              reduce=self.grid.sum,
                              owned=self._partial_particles())

    def record_items(self) -> dict:
        return {"PSI": self.psi} if self.psi is not None else {}

    def _gathered_source(self, name):
        """Model._gathered_source; the record's PSI gathered too."""
        if name == "record" and self.psi is not None:
            return {"PSI": self.grid.gather_real(self.psi)}
        return super()._gathered_source(name)

    # ------------------------------------------------------------------ whole fields
    # a restart's field -> the state's (N_OLD: the explicit scheme's last advection, AB2)
    _RESTART_FIELDS = {"U": "u", "U_OLD": "u_old", "PSI": "psi", "PHI_PREV": "phi_prev",
                       "N_OLD": "n_old"}

    def _restart_field(self, name):
        """This rank's block of a field of the restart (all of it in a plain run), from the
        state."""
        st = self.state
        if name == "PSI_OLD":           # psi^n before the first step
            return st.get("psi_old") if st.holds("psi_old") else st["psi"]
        if name == "STRESS_OLD":     # the original's sign: +psi grad mu / RHO
            f = st.get("capillary_force")
            return -f if f is not None else np.zeros_like(st["u"])
        return st[self._RESTART_FIELDS[name]]

    def _whole(self, name):
        """The whole field ``name`` (_restart_field): in a distributed run gathered to rank
        0 (a collective rank 0's writers call)."""
        return self.collectives.call("whole", name)

    def _local(self, a):
        """This rank's block of a whole field (itself on one process)."""
        return np.ascontiguousarray(self.grid.local_real(a))

    @property
    def restart_kind(self):
        return "CONTINUE_FDM_PHASE_SEPARATION" if self.ch is not None else "CONTINUE_FDM"

    def restart_fields(self) -> dict:
        """Saved_Data fields: U, U_OLD (+ PSI, PSI_OLD, STRESS_OLD with a phase field)."""
        from ..io.restart import vector_field
        w = self._whole
        fields = {"U": vector_field(w("U")), "U_OLD": vector_field(w("U_OLD"))}
        if self.ch is not None:
            fields.update(PSI=w("PSI"), PSI_OLD=w("PSI_OLD"),
                          STRESS_OLD=vector_field(w("STRESS_OLD")))
        return fields

    def exact_state(self) -> dict:
        st = {"have_u_old": bool(self.mac.has_u_old)}
        if self.mac.scheme == "explicit_scheme" and self.mac.advection_old is not None:
            st["n_old"] = np.array(self._whole("N_OLD"))   # AB2 history of the advection
        if self.ch is not None:
            st.update(have_psi_old=self.ch.psi_old is not None, substeps=self.substeps,
                      have_stress_old=self.last_force is not None)
            if self._phi_prev is not None:
                st["PHI_prev"] = self._whole("PHI_PREV")
        return st

    def load_fields(self, fields: dict, exact) -> None:
        from ..io.restart import component_field
        base = f"resume.{self.restart_kind}.Saved_Data"
        exact = exact or {}
        for name in ("U", "U_OLD") + (("PSI", "PSI_OLD") if self.ch is not None else ()):
            want = self.shape + ((3,) if name.startswith("U") else ())
            if name not in fields or fields[name].shape != want:
                got = fields[name].shape if name in fields else "nothing"
                raise ConfigError(f"{name} of the restart has shape {got}, the mesh needs "
                                  f"{want}", path=f"{base}.{name}[]", value=got)
        local = self._local
        self.u[...] = local(component_field(fields["U"]))
        if exact.get("have_u_old", self.step_index > 0):
            self.mac.u_old = local(component_field(fields["U_OLD"]))
        # the MAC step's clock; without the exact state the explicit scheme's first step
        # after the restart is Euler (as the original's, whose advection history is
        # recomputed from the restored velocity)
        self.mac.step_count = self.step_index
        if "n_old" in exact and self.mac.scheme == "explicit_scheme":
            self.mac.restore_advection(local(exact["n_old"]))
        if self.particles.n:
            self.spm.refresh()
            self.phi = self.spm.phi()
        if self.ch is not None:
            subs = int(exact.get("substeps", self.substeps))
            if subs != self.substeps:
                self.substeps = subs
                self.ch = self._make_ch(self.dt / subs)
            self.psi[...] = local(fields["PSI"])
            if exact.get("have_psi_old", self.step_index > 0):
                self.ch.psi_old = local(fields["PSI_OLD"]).copy()
            if self.eta_field is not None:
                self._update_viscosity()
            self._phi_prev = None
            if "PHI_prev" in exact and self.phi is not None:
                self._phi_prev = local(np.asarray(exact["PHI_prev"], dtype=float)).copy()
            S = fields.get("STRESS_OLD")
            if exact.get("have_stress_old") and S is not None and S.shape == self.shape + (3,):
                self.last_force = -local(component_field(S))
            elif self.step_index > 0:     # the original: the force of the restored state
                mu = self.ch.chemical_potential(self.psi, self.phi)
                self.last_force = self.ch.capillary_force(self.psi, mu, self.rho)

    # ------------------------------------------------------------------ snapshot
    def field_sources(self) -> dict:
        """u, pressure (at the nodes, the particles' force included), tau; phi with particles; psi, psi_all (psi is defined
        inside the particles too, so it is the total order parameter) and flux with a phase
        field (kapsel.snapshot)."""
        from ..mesh.pencil import Gathered
        g = self.grid                 # pressure, tau: from the gathered fields, on rank 0

        def pressure():
            from ..fluid.diagnostics import pressure_at_nodes
            p = g.gather_real(self._pressure_cells())
            return Gathered(pressure_at_nodes(p) if g.is_root else None)

        def tau():
            from ..fluid.diagnostics import stress_from_gradient, velocity_gradient_central
            u = g.gather_real(self.u)
            eta = (g.gather_real(self.eta_field) if self.eta_field is not None
                   else self.cfg.fluid.ETA)
            return Gathered(stress_from_gradient(velocity_gradient_central(u, self.dx), eta)
                            if g.is_root else None)
        src = {"u": lambda: self.u, "pressure": pressure, "tau": tau}
        if self.particles.n or self.wall is not None:
            src["phi"] = self.phi_total
        if self.psi is not None:
            src.update(psi=lambda: self.psi, psi_all=lambda: self.psi, flux=self._flux)
        return src

    def _pressure_cells(self):
        """The fluid step's pressure plus the part that balances the particles' force of
        the step (the projection of their rigidity increment), at the cell centres."""
        p = self.mac.pressure.copy()
        if (self.particles.n or self.wall is not None) and self.step_index > 0:
            p += self.mac.projection_pressure(self.spm.last_increment())
        return p

    def _eta(self):
        return self.eta_field if self.eta_field is not None else self.cfg.fluid.ETA

    def _flux(self):
        """Order-parameter flux psi u - kappa grad mu of the current state (eq 16)."""
        mu = self.ch.chemical_potential(self.psi, self.phi)
        flux = np.empty((3,) + self.psi.shape)
        self.ch.gradient(mu, flux)
        flux *= -self.ch.kappa
        flux += self.psi * self.u
        return flux


@register("Navier_Stokes_FDM")
def make_ns_fdm(cfg, args, doc):
    return FDMModel(cfg, args)


@register("Navier_Stokes_Cahn_Hilliard_FDM")
def make_ns_ch_fdm(cfg, args, doc):
    return FDMModel(cfg, args)
