"""The sheared types (manual table 1, table 4; §5.1 eqs 27-29).

``Shear_Navier_Stokes_Lees_Edwards``: the pseudo-spectral SPM model (kapsel.models.spectral)
on the oblique-frame solver kapsel.fluid.oblique.ObliqueSpectralNS: the fluid holds the
deviation from U = gamma_dot(t) (y - Ly/2) e_x, particles see Lees-Edwards images (profiles on
the sheared grid, positions and x velocities shifted across the y boundary, R_raw unwrapped,
pair forces and chain bonds by the Lees-Edwards minimum image; rigid bodies wrap their
centres and each bead through the images, kapsel.particles.rigid.RigidBodies.use_lees_edwards).

Shear stress (each record, and the text log ``shear_stress.dat`` next to output.udf):

    sigma_xy = ETA gamma_dot + sigma^p_xy,
    sigma^p_ab = -(RHO DX^3 / (dt V)) 1/2 sum_i sum_x (du_a r_b + du_b r_a)

the viscous stress of the whole (periodic-deviation) flow plus the first moment of the SPM
force density RHO du / dt the particles exert on the fluid (du the rigidity increment of a
step, r = x - R_i; Batchelor's particle stress).  The value of a record is the mean over the
steps since the previous record (the instantaneous ETA gamma_dot at step 0).  The Reynolds
stress of the deviation is not included.  The applied strain is int gamma_dot dt (AC: the original's sum of gamma_dot dt over the steps).

The define.udf of the original has no record item for these; they go into a record only
when the define file declares record items ``Shear_stress`` / ``Shear_strain`` /
``Shear_rate`` (floats), and always into ``shear_stress.dat`` (t, strain, rate, stress).
"""
from __future__ import annotations

import numpy as np

from ..config import ConfigError, RunConfig
from ..typespec import register
from ..particles.interactions import OVERLAP_LIMIT
from .common import Model, make_forces, make_noise, make_particles
from .spectral import SpectralModel


def shear_flow(cfg: RunConfig):
    from ..frame import ShearFlow
    return ShearFlow.from_config(cfg.shear)


def check_interpolation(cfg: RunConfig) -> str:
    from ..mesh.regrid import INTERPOLATIONS
    m = cfg.switches.OBL_INT
    if m not in INTERPOLATIONS:
        raise ConfigError(f"must be one of {', '.join(INTERPOLATIONS)}",
                          path="switch.ns_solver.OBL_INT", value=m)
    return m


# The original's shear-stress table (FORMAT-OUTPUT.md §1.4): a header on stdout at the start,
# a row after every step.  Lees-Edwards types (rows on stdout):
LE_TABLE = ("time", "shear_rate", "degree_oblique", "shear_strain_temporal",
            "lj_dev_stress_temporal", "shear_stress_temporal_old",
            "shear_stress_temporal_new", "reynolds_stress", "fluid_stress",
            "interfacial_stress", "apparent_stress", "viscosity")
# (Shear_Navier_Stokes: kapsel.models.zigzag, rows on stderr)


def le_table_row(time, rate, frame_strain, strain, lj, particle, reynolds, fluid,
                 interfacial) -> list:
    """One row of the Lees-Edwards table: apparent = particle + reynolds + lj + fluid +
    interfacial, viscosity = apparent / rate.  kapsel-py has one hydrodynamic particle
    stress per step (the first moment of the SPM force), written in both the _old and
    _new columns (the original's two integrator stages)."""
    apparent = particle + reynolds + lj + fluid + interfacial
    visc = apparent / rate if rate else float("nan")
    return [time, rate, frame_strain, strain, lj, particle, particle, reynolds, fluid,
            interfacial, apparent, visc]


def lj_stress_xy(forces, volume) -> float:
    """-(1/V) sum over pairs of (f_x dr_y + f_y dr_x) / 2 of the last force evaluation
    (0 without pair forces)."""
    w = None if forces is None else forces.virial
    if w is None:
        return 0.0
    return -0.5 * float(w[0, 1] + w[1, 0]) / volume


class ShearStress:
    """Accumulates the particle stress moment of the SPM steps between records."""

    def __init__(self, volume, rho, dx, dt, eta):
        self.scale = -rho * dx ** 3 / (dt * volume)
        self.eta = eta
        self.sum = 0.0
        self.rate_sum = 0.0
        self.n = 0
        self.last = 0.0

    def add(self, moment, rate):
        self.last = 0.5 * self.scale * (moment[0, 1] + moment[1, 0])   # this step's
        self.sum += self.last
        self.rate_sum += rate
        self.n += 1

    def take(self, rate_now):
        """Mean sigma_xy since the last call (ETA gamma_dot now if no step was made)."""
        if self.n == 0:
            return self.eta * rate_now
        s = self.eta * self.rate_sum / self.n + self.sum / self.n
        self.sum, self.rate_sum, self.n = 0.0, 0.0, 0
        return s


class ShearLEModel(SpectralModel):
    """Shear_Navier_Stokes_Lees_Edwards (module docstring)."""

    def __init__(self, cfg: RunConfig, args):
        from ..fluid.oblique import ObliqueSpectralNS
        from ..particles.spm import SPM
        Model.__init__(self, cfg, args)
        f, seed = cfg.fluid, self.seed
        self.interpolation = check_interpolation(cfg)
        self.grid = self.make_grid(cfg)
        self.fluid = ObliqueSpectralNS(self.grid, f.RHO, f.ETA, self.dt, shear_flow(cfg),
                                       fix_cell=cfg.switches.fix_cell, state=self.state)
        self.particles = make_particles(cfg, self.rng)
        fluid = self.fluid
        forces = make_forces(cfg, self.particles, strain=lambda: fluid.frame_strain,
                             overlap_limit=OVERLAP_LIMIT)
        self.spm = SPM(self.fluid, self.particles, self.spm_radius(), cfg.particles.A_XI, f.RHO,
                       cfg.mesh.DX, self.dt, rotation=cfg.switches.ROTATION,
                       forces=forces, noise=make_noise(cfg, self.particles, seed),
                       impose=False, dry=self.dry)
        self.spm.interpolation = self.interpolation       # (OBL_INT)
        self.spm.start_sheared(impose=not self.dry)    # as the original (SPM.start_sheared)
        self.stress = ShearStress(self.grid.volume, f.RHO, cfg.mesh.DX, self.dt, f.ETA)

    def advance(self):
        self.spm.step()
        self.stress.add(self.spm.moment, self.fluid.shear.rate(self.fluid.time - self.dt))
        self.tick()

    def kinetic_energy(self) -> float:
        """E of the full flow U + u^ (fluid outside the particles) plus the particles."""
        from .common import kinetic_energy
        u = self.spm.velocity().copy()      # (the solver's scratch holds a snapshot's u)
        y = self.grid.coordinates()[1]
        u[0] += self.fluid.shear_rate_now * (y - self.fluid.y0)
        phi = self.spm.phi() if self.particles.n else None
        return kinetic_energy(self.cfg.fluid.RHO, self.cfg.mesh.DX, u, phi,
                              self.spm.owned_particles(),
                              reduce=self.grid.sum,
                              owned=self._partial_particles())

    sheared = True

    def frame_strain(self) -> float:
        return float(self.fluid.frame_strain)

    def field_sources(self) -> dict:
        """u (full flow) and phi in the rectangular frame (OBL_INT interpolation), tau of the
        full flow (spectral Cartesian derivatives on the oblique grid; d_y U_x = gamma_dot
        added to xy), the pressure (kapsel.fluid.diagnostics.spectral_pressure with the
        shear terms).  The oblique-grid fields (a rank's blocks along x and y) are gathered
        to rank 0 (one rank: the fields themselves), which interpolates them to the
        rectangular frame along x and derives tau and the pressure there."""
        from ..fluid.diagnostics import spectral_pressure, viscous_stress_spectral
        from ..mesh.regrid import to_rectangular
        from ..mesh.pencil import Gathered
        g0 = self.fluid.y0 / self.cfg.mesh.DX

        def rect(f):
            return to_rectangular(f, self.fluid.frame_strain, self.interpolation, g0)

        g, fl, f, dx = self.grid, self.fluid, self.cfg.fluid, self.cfg.mesh.DX
        root = self.dist.root
        memo = {}

        def deviation():          # gathered once per snapshot (None off rank 0)
            if "u" not in memo:
                memo["u"] = g.gather_real(self.spm.velocity())
            return memo["u"]

        def u():
            d = deviation()
            if not root:
                return Gathered(None)
            out = rect(d)
            y = (np.arange(g.shape[1]) * dx)[None, :, None]
            out[0] += fl.shear_rate_now * (y - fl.y0)
            return Gathered(out)

        def tau():
            d = deviation()
            if not root:
                return Gathered(None)
            t = viscous_stress_spectral(d, dx, f.ETA, fl.frame_strain)
            t[1] += f.ETA * fl.shear_rate_now
            return Gathered(rect(t))

        def pressure():
            d, du = deviation(), g.gather_real(self.spm.last_increment())
            if not root:
                return Gathered(None)
            return Gathered(rect(spectral_pressure(d, du, f.RHO, self.dt, dx,
                                                   fl.shear_rate_now, fl.frame_strain)))

        src = {"u": u, "tau": tau, "pressure": pressure}
        if self.particles.n:
            def phi():
                p = g.gather_real(self.spm.phi())
                return Gathered(rect(p) if root else None)
            src["phi"] = phi
        return src

    shear_table = LE_TABLE
    shear_table_stream = "stdout"

    def shear_table_row(self) -> list:
        """This step's row of the original's table (FORMAT-OUTPUT.md §1.4)."""
        fl, g = self.fluid, self.fluid.frame_strain
        n = self.grid.size
        uxuy = self.grid.sum(fl.uxuy_sum())          # Cartesian deviation, Fourier
        reynolds = -self.cfg.fluid.RHO * uxuy / (n * n)   # Parseval: sum_x = sum_k / N
        rate = fl.shear.rate(self.time - self.dt)
        return le_table_row(self.time, rate, g, fl.applied_strain,
                            lj_stress_xy(self.spm.forces, self.grid.volume), self.stress.last,
                            reynolds, self.cfg.fluid.ETA * rate, 0.0)

    def shear_record(self) -> dict:
        """Shear_stress (mean since the last record), Shear_strain, Shear_rate."""
        rate = self.fluid.shear_rate_now
        return {"Shear_stress": self.stress.take(rate),
                "Shear_strain": self.fluid.applied_strain, "Shear_rate": rate}

    # ------------------------------------------------------------------ restart
    def exact_state(self) -> dict:
        """The velocity, the re-mapping count and the fluid's own clock (accumulated
        t += dt: the frame strain is a function of it, so a continuation takes it exact)."""
        return {"u_hat": self.global_u_hat().copy(), "remaps": int(self.fluid.remaps),
                "fluid_time": float(self.fluid.time)}

    def accumulators(self) -> dict:
        st = self.stress
        return {"stress": [st.sum, st.rate_sum, st.n]}

    def set_accumulators(self, values: dict) -> None:
        st = self.stress
        st.sum, st.rate_sum, st.n = values["stress"]

    def _covariant(self, u_hat):
        """Covariant components u_1 = u^1 + g u^2, u_2 = g u^1 + (1 + g^2) u^2, u_3 = u^3."""
        g = self.fluid.frame_strain
        cov = u_hat.copy()
        cov[0] += g * u_hat[1]
        cov[1] += g * u_hat[0] + g * g * u_hat[1]
        return cov

    def restart_fields(self) -> dict:
        """Zeta / uk_dc of the covariant components in the oblique frame (FORMAT.md), and
        oblique.degree_oblique the frame strain."""
        from ..io.restart import pack_zeta
        zeta, dc = pack_zeta(self._covariant(self.global_u_hat()), self.cfg.mesh.DX,
                             sheared=True)
        return {"Zeta": zeta, "uk_dc": [float(c) for c in dc],
                "oblique": [float(self.fluid.frame_strain)]}

    def load_fields(self, fields: dict, exact) -> None:
        """The state file's u_hat, or else Zeta / uk_dc (covariant, oblique frame) back to
        contravariant components, metric-projected, in the frame of degree_oblique."""
        if exact and "u_hat" in exact:
            want = (3,) + tuple(self.grid.cshape)
            if exact["u_hat"].shape != want:
                raise ConfigError(f"the restart's velocity has shape {exact['u_hat'].shape}, "
                                  f"the mesh needs {want}",
                                  path="resume.CONTINUE.Saved_Data.Zeta[]", value="shape")
            self.fluid.set_time(exact.get("fluid_time", self.time), exact.get("remaps"))
            self.fluid.set_contravariant_hat(self.local(exact["u_hat"]))
        else:
            fl = self.fluid
            g_saved = float((fields.get("oblique") or [0.0])[0])
            fl.set_time(self.time, int(round((fl.strain_at(self.time) - g_saved) / fl.s)))
            w = self._zeta_velocity(fields)           # covariant
            g = fl.frame_strain
            u = w.copy()                              # contravariant: G w
            u[0] = (1.0 + g * g) * w[0] - g * w[1]
            u[1] = w[1] - g * w[0]
            dc = u[:, 0, 0, 0].copy()
            u = np.ascontiguousarray(self.local(u))
            fl.project_metric(u, g)
            if getattr(self.grid, "has_k0", True):
                u[:, 0, 0, 0] = dc
            fl.set_contravariant_hat(u)
        self.spm.refresh()


@register("Shear_Navier_Stokes_Lees_Edwards")
def make_shear_le(cfg, args, doc):
    return ShearLEModel(cfg, args)




# ----------------------------------------------------------------------------- FDM types
from .fdm import FDMModel  # noqa: E402


class ShearFDMModel(FDMModel):
    """Shear_Navier_Stokes_Lees_Edwards_FDM and Shear_NS_LE_CH_FDM: the FDM model (MAC
    explicit / implicit, Model H with both Cahn-Hilliard schemes and viscosity_change) in the
    oblique frame (kapsel.fluid.oblique.ObliqueMAC, eq 32 by kapsel.phase.oblique).

    u (and psi, phi) live on the oblique grid: u is the Cartesian deviation from
    U = gamma_dot (y - Ly/2) e_x.  A re-mapping of the frame shifts psi and psi^{n-1} with u.
    Field files and the PSI record are in the rectangular frame (OBL_INT interpolation along
    x; the velocity with U added).  The restart holds the oblique-frame state (U, U_OLD,
    PSI, ...: deviation on the oblique grid) and oblique.degree_oblique, the frame strain.

    Shear stress (mean over the steps since the previous record):
    sigma_xy = <eta (d_y u_x + d_x u_y)> of the full flow (eta the local viscosity with
    viscosity_change; central differences, so a periodic deviation adds nothing for constant
    eta) - alpha <d_x psi d_y psi> (interfacial stress of the phase field) + the particle
    stress of kapsel.models.shear (first moment of the SPM force density).
    """

    sheared_start = True

    def __init__(self, cfg: RunConfig, args):
        self.interpolation = check_interpolation(cfg)
        super().__init__(cfg, args)
        if cfg.fluid.viscosity_change and self.mac.halo2 is None:
            raise ConfigError("viscosity_change in the oblique frame needs blocks of at "
                              "least 2 mesh points along the split directions (its viscous "
                              "term reaches 2 points): use fewer ranks along x or y (-X, -Y)",
                              path="mesh", value="process grid")
        self.stress = ShearStress(float(np.prod(cfg.mesh.box)), cfg.fluid.RHO, cfg.mesh.DX,
                                  self.dt, cfg.fluid.ETA)
        self.field_stress_sum = 0.0

    def _make_fluid(self, cfg):
        from ..fluid.oblique import ObliqueMAC
        f = cfg.fluid
        return ObliqueMAC(self.grid, f.RHO, f.ETA, self.dt, shear_flow(cfg),
                          scheme=f.ns_solver, tolerance=f.tolerance,
                          maximum_iteration=f.maximum_iteration, threads=self.threads,
                          interpolation=self.interpolation, state=self.state)

    def _fix_cell(self, cfg):
        """The original forces FIX_CELL.y ON for the sheared types (PHYSICS-EXTRA §1.2)."""
        x, _, z = cfg.switches.fix_cell
        return (x, True, z)

    def _make_ch(self, dt):
        from ..phase.oblique import make_oblique_cahn_hilliard
        mac = self.mac
        return make_oblique_cahn_hilliard(lambda: mac.frame_strain, mac.max_frame_strain,
                                          self.grid, self.cfg.phase, dt, **self.ch_kwargs)

    # ------------------------------------------------------------------ the implicit step's
    # capillary force: the original's NS_solver_slavedEuler_Shear_OBL_implicit (fdm.cxx)
    # evaluates mu and the force psi* G grad mu* / RHO with the frame of the step's middle,
    # gt = degree_oblique + Shear_rate_eff dt / 2 (Calc_cp_OBL, Cp2stress_OBL with gt), of
    # psi* = (3 psi^n - psi^(n-1)) / 2 and phi* its Make_phi_s_OBL (fdm.h): the particles
    # at the extrapolated positions R^n + (R^n - R^(n-1)) / 2 on the rectangular grid
    # (wrapped by PBC_OBL_half with gt, the stencil's images across y by the frame's own
    # degree_oblique, min(phi_sum, 1)), then to the oblique grid (A2a_oblique, linear).
    def _implicit(self):
        return self.ch is not None and self.cfg.fluid.ns_solver == "implicit_scheme"

    def _capillary_force(self):
        if not self._implicit():
            return super()._capillary_force()
        mac, ch = self.mac, self.ch
        g0, gt = mac.frame_strain, mac.mid_step_strain(mac.time)
        frame = ch.frame
        ch.frame = lambda: gt
        try:
            raw = super()._capillary_force()
        finally:
            ch.frame = frame
        # the MAC step takes a Cartesian force to contravariant components in its frame g0;
        # the original's are those of the frame gt: F^1 = F_x - gt F_y
        raw[0] -= (gt - g0) * raw[1]
        return raw

    def _extrapolated_phi(self):
        """phi* (above): every Lees-Edwards run couples on the rectangular grid (SPM.rect),
        distributed ones too (without particles: phi itself).  The step's displacement
        is that of the unwrapped positions (the original's (3 x - x_previous) / 2 of the
        wrapped ones lands half a box away in the step after a particle crosses a
        boundary); the first step, and the first after a restart without the exact state,
        take R^n (the original's ts 0 and its restart's x_previous = x)."""
        spm = self.spm
        if self.phi is None:
            return self.phi
        mac = self.mac
        p = spm.p
        xp = np.array(p.R, dtype=float)
        if self._dR is not None and self.step_index > 0:
            xp += 0.5 * self._dR[spm.owned.gid[:p.n]]     # the table's rows (their ids)
        L = spm.box
        gt = mac.mid_step_strain(mac.time)
        n = np.floor(xp[:, 1] / L[1])                # PBC_OBL_half
        xp[:, 1] -= n * L[1]
        xp[:, 0] -= n * gt * L[1]
        np.mod(xp, L, out=xp)
        xp[xp >= L] = 0.0
        return spm.phi_at(xp)

    _dR = None      # the particles' displacement over the last step, by particle id
    #                 (n_global, 3; rect phi*)

    def _unwrapped_positions(self):
        """R_raw of every particle by its id (n_global, 3), the same on every rank: the
        owned rows' positions summed over the ranks (the table's rows change as particles
        migrate between blocks)."""
        spm = self.spm
        o, p = spm.owned, spm.p
        R = np.zeros((spm.n_global, 3))
        R[o.gid[:o.n_own]] = p.R_raw[:o.n_own]
        (R,) = self.grid.reduce(R)
        return np.asarray(R, dtype=float).reshape(-1, 3)

    _R_end = None   # _unwrapped_positions() at the end of the last step (the next start)

    def advance(self):
        keep = self._implicit() and self.particles.n
        before = (self._R_end if self._R_end is not None else self._unwrapped_positions()) \
            if keep else None
        super().advance()
        if keep:
            self._R_end = self._unwrapped_positions()
            self._dR = self._R_end - before

    def _after_fluid(self):
        n = self.mac.take_remap()
        if n:
            if self.psi is not None:
                self.psi[...] = self.mac.shift_scalar(self.psi, n)
                if self.ch.psi_old is not None:
                    self.ch.psi_old = self.mac.shift_scalar(self.ch.psi_old, n)
                if self.eta_field is not None:
                    self._update_viscosity()
        self.stress.add(self.spm.moment, 0.0)
        self._last_fields = self._field_stresses()
        self.field_stress_sum += sum(self._last_fields)

    shear_table = LE_TABLE
    shear_table_stream = "stdout"

    def shear_table_row(self) -> list:
        """This step's row of the original's table (FORMAT-OUTPUT.md §1.4)."""
        mac = self.mac
        viscous, interfacial = getattr(self, "_last_fields", None) or self._field_stresses()
        reynolds = -self.rho * float(self.mac.mean(self.u[0] * self.u[1]))
        return le_table_row(self.time, mac.shear.rate(self.time - self.dt), mac.frame_strain,
                            mac.applied_strain,
                            lj_stress_xy(self.spm.forces, float(np.prod(self.cfg.mesh.box))),
                            self.stress.last, reynolds, viscous, interfacial)

    def _field_stress(self) -> float:
        return sum(self._field_stresses())

    def _field_stresses(self) -> tuple:
        """(viscous, interfacial) sigma_xy of the current fields (module docstring)."""
        mac = self.mac
        g = mac.frame_strain
        rate = mac.shear_rate_now
        gr = np.empty((3,) + self.u.shape[1:])
        grad = self._oblique_gradient
        grad(self.u[0], g, gr)
        s = gr[1].copy()                                  # d_y u_x
        grad(self.u[1], g, gr)
        s += gr[0]                                        # + d_x u_y
        s += rate                                         # + gamma_dot (imposed flow)
        eta = self.eta_field if self.eta_field is not None else self.cfg.fluid.ETA
        sig = float(mac.mean(eta * s))
        inter = 0.0
        if self.psi is not None:
            grad(self.psi, g, gr)
            inter = -self.cfg.phase.alpha * float(mac.mean(gr[0] * gr[1]))
        return sig, inter

    def _oblique_gradient(self, f, g, out):
        """kapsel.mesh.oblique.oblique_gradient of a field (of this rank's block: on the
        block widened by the halo)."""
        from ..mesh.oblique import oblique_gradient
        h = self.mac.halo
        G = oblique_gradient(h.pad(f, key="stress"), self.dx, g, h.target(out, (3,), "stress"))
        return h.keep(G, out)

    def shear_record(self) -> dict:
        rate = self.mac.shear_rate_now
        n = self.stress.n
        if n:
            stress = self.field_stress_sum / n + self.stress.sum / n
        else:
            stress = self._field_stress()
        self.stress.take(rate)
        self.field_stress_sum = 0.0
        return {"Shear_stress": stress, "Shear_strain": self.mac.applied_strain,
                "Shear_rate": rate}

    # ------------------------------------------------------------------ rectangular output
    def _rect(self, f):
        from ..mesh.regrid import to_rectangular
        return to_rectangular(f, self.mac.frame_strain, self.interpolation,
                              self.mac.y0 / self.dx)

    def record_items(self) -> dict:
        return {"PSI": self._rect(self.psi)} if self.psi is not None else {}

    def field_sources(self) -> dict:
        """The FDM fields in the rectangular frame (OBL_INT interpolation), u with the imposed
        flow; tau of the full flow (Cartesian derivatives on the oblique grid, then
        interpolated; d_y U_x = gamma_dot added to xy); no flux (the original writes
        flux_<n>.h5 for Navier_Stokes_Cahn_Hilliard_FDM only)."""
        from ..fluid.diagnostics import pressure_at_nodes
        from ..mesh.pencil import Gathered
        g = self.grid                 # from the fields gathered to rank 0, computed there

        def on_root(fn, *parts):
            def gathered():
                whole = [g.gather_real(p()) for p in parts]
                return Gathered(fn(*whole) if g.is_root else None)
            return gathered
        src = {"u": on_root(self._u_rect, lambda: self.u),
               "pressure": on_root(lambda p: self._rect(pressure_at_nodes(p)),
                                   self._pressure_cells),
               "tau": (on_root(self._tau, lambda: self.u, lambda: self.eta_field)
                       if self.eta_field is not None else on_root(self._tau, lambda: self.u))}
        if self.particles.n:
            src["phi"] = on_root(self._rect, lambda: self.phi)
        if self.psi is not None:
            src["psi"] = on_root(self._rect, lambda: self.psi)
            src["psi_all"] = src["psi"]
        return src

    def _gathered_source(self, name):
        """The record's PSI in the rectangular frame, from the gathered psi."""
        if name == "record" and self.psi is not None:
            psi = self.grid.gather_real(self.psi)
            return {"PSI": self._rect(psi) if self.grid.is_root else None}
        return super()._gathered_source(name)

    def _u_rect(self, u=None):
        u = self._rect(self.u if u is None else u)
        y = (np.arange(self.shape[1]) * self.dx)[None, :, None]
        u[0] += self.mac.shear_rate_now * (y - self.mac.y0)
        return u

    def _tau(self, u=None, eta=None):
        from ..fluid.diagnostics import stress_from_gradient, velocity_gradient_central
        from ..mesh.oblique import oblique_gradient
        g, dx = self.mac.frame_strain, self.dx
        grad = velocity_gradient_central(self.u if u is None else u, dx,
                                         gradient=lambda f, out: oblique_gradient(f, dx, g, out))
        grad[0, 1] += self.mac.shear_rate_now
        tau = stress_from_gradient(grad, self._eta() if eta is None else eta)
        return self._rect(tau)

    sheared = True

    def frame_strain(self) -> float:
        return float(self.mac.frame_strain)

    def kinetic_energy(self) -> float:
        from .common import kinetic_energy
        u = self.u.copy()
        y = (np.arange(*self.grid.real_range[1]) * self.dx)[None, :, None]   # this block's rows
        u[0] += self.mac.shear_rate_now * (y - self.mac.y0)
        return kinetic_energy(self.rho, self.dx, u, self.phi, self.spm.owned_particles(),
                              reduce=self.grid.sum,
                              owned=self._partial_particles())

    # ------------------------------------------------------------------ restart
    def restart_fields(self) -> dict:
        d = super().restart_fields()
        d["oblique"] = [float(self.mac.frame_strain)]
        return d

    def exact_state(self) -> dict:
        st = super().exact_state()
        st["remaps"] = int(self.mac.remaps)
        st["fluid_time"] = float(self.mac.time)     # the frame's clock (ShearLEModel)
        if self._dR is not None:
            st["dR_last"] = np.array(self._dR)          # phi* of the implicit step
        return st

    def accumulators(self) -> dict:
        st = self.stress
        return {"stress": [st.sum, st.rate_sum, st.n], "field": self.field_stress_sum}

    def set_accumulators(self, values: dict) -> None:
        st = self.stress
        st.sum, st.rate_sum, st.n = values["stress"]
        self.field_stress_sum = values["field"]

    def load_fields(self, fields: dict, exact) -> None:
        exact = exact or {}
        self.mac.set_time(exact.get("fluid_time", self.time), exact.get("remaps"))
        super().load_fields(fields, exact)
        dR = exact.get("dR_last")
        self._dR = None if dR is None else np.array(dR, dtype=float).reshape(-1, 3)
        self._R_end = None          # the positions were set from the restart


@register("Shear_Navier_Stokes_Lees_Edwards_FDM")
def make_shear_le_fdm(cfg, args, doc):
    return ShearFDMModel(cfg, args)


@register("Shear_NS_LE_CH_FDM")
def make_shear_le_ch_fdm(cfg, args, doc):
    return ShearFDMModel(cfg, args)


__all__ = ["ShearLEModel", "ShearFDMModel", "ShearStress", "shear_flow", "check_interpolation"]
