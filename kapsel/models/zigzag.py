"""``Shear_Navier_Stokes``: the zigzag shear flow (manual table 1) as the original makes it.

The Navier_Stokes model (kapsel.models.spectral) whose fluid has its x velocity pinned after
the update of every step, before FIX_CELL and the particles (the original's
NS_solver_slavedEuler_Shear_PBC, fluid_solver.cxx; here the ``after_update`` hook of
kapsel.fluid.spectral.SpectralNS):

* DC (Mean_shear_sustaining_yforce_PBC): on the two planes j1 = NY/4 and j2 = 3NY/4 (integer
  division) u_x = -gamma_dot Ly/4 and +gamma_dot Ly/4 at every (x, z); the rest of the fluid
  develops from rest by viscosity, towards the zigzag U_x = gamma_dot (y - Ly/2) on
  [Ly/4, 3Ly/4] and -gamma_dot y, gamma_dot (Ly - y) below and above it;
* AC (Mean_shear_sustaining_kforce_PBC): u_x = Z(y) cos(w n dt) at every point, Z that
  zigzag for gamma_dot, n the index of the step being made, w the input's ``Frequency`` taken
  as an angular frequency (the original's cos(Shear_frequency ts dt); its start-up message
  gives the strain amplitude as Shear_rate / Frequency).

The change delta of u_x is made solenoidal and added (the original converts the pinned field
back to its vorticity variables: the same projection; the mean of delta is kept), and the
velocity is truncated by the 2/3 rule (Truncate_two_third_rule right after the fluid step,
sp_3d_ns.cxx Time_evolution_hydro), so the pinned planes hold the truncated profile.

Start-up (a new run): the fluid at rest plus the rigidity of the particles at their input
velocities (the Navier_Stokes start), then the particles' v_x and omega_z set to 0
(init_particle.cxx Show_parameter, for every sheared type).

Console table (stderr, a row after every step; sp_3d_ns.h Update_strain, Mean_shear_stress,
fluid_solver.h Calc_shear_stress), the original's signs:

    shear_rate_temporal   = -(2/N) sum_{x, NY/4 <= j < 3NY/4} d_y u_x   (spectral d_y)
    shear_strain_temporal = the sum of shear_rate_temporal dt over the run's steps
    shear_stress_temporal = -(DX^3 / (V dt)) sum_x y (rho delta - <rho delta>),  y = j DX
    viscosity (DC)        = shear_stress_temporal / shear_rate_temporal
    AC: shear_inertia_stress_temporal = (DX^3 / (V dt)) (M^n - M^(n-1)),
        M = sum_x y rho u_x at the end of the step (M = 0 before the first step);
        apparent_shear_stress = shear_stress_temporal + shear_inertia_stress_temporal

with rho = RHO + sum_i (MASS_RATIO_i - 1) RHO phi_i the density field at the particles'
positions after the step.  In the developed DC flow the measured rate is -gamma_dot and the
stress -ETA gamma_dot (the slope of the zigzag around y = 0), the viscosity ETA.

Where kapsel-py differs from the original on purpose: for DX != 1 the original pins
+-gamma_dot Ly DX / 4 and chooses the AC zigzag's pieces by comparing j with Ly / 4, and its
inertia term lacks DX^3: kapsel-py uses gamma_dot Ly / 4, y = j DX and DX^3 (the same numbers
for DX = 1); the AC header lists all six labels (the original's lists five); a continued run
continues the strain and the inertia moment (the original restarts both from 0).

Records (``Shear_stress``, ``Shear_strain``, ``Shear_rate`` when the define file declares
them) and ``shear_stress.dat``: the mean of shear_stress_temporal (AC: of
apparent_shear_stress) over the steps since the previous record, the strain and the
measured rate of the table.
"""
from __future__ import annotations

import numpy as np

from ..config import RunConfig
from ..typespec import register
from .spectral import SpectralModel

# the original's table labels (sp_3d_ns.h Mean_shear_stress)
TABLE_DC = ("time", "shear_rate_temporal", "shear_strain_temporal", "shear_stress_temporal",
            "viscosity")
TABLE_AC = ("time", "shear_rate_temporal", "shear_strain_temporal", "shear_stress_temporal",
            "shear_inertia_stress_temporal", "apparent_shear_stress")


def zigzag_profile(ny: int, dx: float, rate: float) -> np.ndarray:
    """The zigzag u_x(j) the AC pin sets before its factor cos(w n dt) (fluid_solver.cxx
    Mean_shear_sustaining_kforce_PBC): -rate y on [0, Ly/4), rate (Ly - y) on [3Ly/4, Ly),
    rate (y - Ly/2) between, y = j DX."""
    Ly = ny * dx
    y = np.arange(ny) * dx
    quarter = np.floor(y / (0.25 * Ly))
    return np.where(quarter == 0, -rate * y,
                    np.where(quarter == 3, rate * Ly - rate * y, -rate * (0.5 * Ly) + rate * y))


class ZigzagPin:
    """The pin of u_x after the fluid's update (module docstring), as the fluid's
    ``after_update(u_hat)``; keeps delta (the real-space change of u_x, the original's
    Shear_force) for the stress.  ``step_of()`` gives the index of the step being made."""

    def __init__(self, fluid, kind: str, rate: float, frequency: float, step_of):
        g = fluid.grid
        self.grid, self.fluid = g, fluid
        self.kind, self.rate, self.omega = kind, float(rate), float(frequency)
        self.step_of = step_of
        nx, ny, nz = g.shape
        (y0, y1) = g.real_range[1] if hasattr(g, "real_range") else (0, ny)   # rank's rows
        j1, j2 = ny // 4, 3 * ny // 4
        a = self.rate * (0.25 * ny * g.dx)
        self.planes = [(j - y0, v) for j, v in ((j1, -a), (j2, a)) if y0 <= j < y1]
        self.profile = zigzag_profile(ny, g.dx, self.rate)[y0:y1].reshape(1, -1, 1)
        self.delta = None                      # real (local) field, made on first use
        self._dh = self._s = None

    def _buffers(self):
        g = self.grid
        self.delta = g.zeros_real(None)
        self._dh = g.empty_complex(None)
        self._s = g.empty_complex(None)

    def target_factor(self) -> float:
        """cos(w n dt) of the AC pin (1 for DC)."""
        if self.kind != "AC":
            return 1.0
        return float(np.cos(self.omega * (self.step_of() * self.fluid.dt)))

    def __call__(self, u_hat):
        g = self.grid
        if self.delta is None:
            self._buffers()
        d = g.irfft_scalar(u_hat[0], out=self.delta)          # u_x in real space
        if self.kind == "AC":
            np.subtract(self.target_factor() * self.profile, d, out=d)
        else:
            kept = [(j, v - d[:, j, :]) for j, v in self.planes]
            d[...] = 0.0
            for j, dj in kept:
                d[:, j, :] = dj
        dh = g.rfft_scalar(d, out=self._dh)
        s = self._s                                           # P (delta, 0, 0): k . delta / k^2
        np.multiply(dh, g.kx, out=s)
        s *= g.inv_k2
        u_hat[0] += dh
        for c, k in enumerate((g.kx, g.ky, g.kz)):
            np.multiply(s, k, out=dh)
            u_hat[c] -= dh
        u_hat *= g.dealias_f                                  # the 2/3 rule


class ZigzagStress:
    """The measured rate, strain and stress of the original's table (module docstring),
    computed after each step from the pin's delta, the fluid and the particles' profiles."""

    def __init__(self, pin: ZigzagPin, rho: float, mass_ratio, dt: float, heavy: bool):
        g = pin.grid
        nx, ny, nz = g.shape
        self.pin, self.grid, self.rho, self.dt = pin, g, float(rho), float(dt)
        self.drho_species = np.asarray(mass_ratio, dtype=float) * self.rho - self.rho
        self.heavy = bool(heavy)        # particles denser or lighter than the fluid
        self.n_points = g.size
        self.norm = g.dx ** 3 / (g.volume * self.dt)
        (y0, y1) = g.real_range[1]
        self.y = np.arange(y0, y1) * g.dx                    # this rank's y = j DX
        self.y_sum = nx * nz * g.dx * ny * (ny - 1) / 2.0    # sum_x y over the whole mesh
        # c = u_x^(0, k_y, 0), the modes of this rank (when it holds k_z = 0): the sum of u_x
        # over a plane j is ifft_y(c)[j], so sum_j w_j(k_y) c(k_y) gives the sum over the
        # middle half of d_y u_x (w_rate) and sum_x y u_x (w_moment)
        self.column = g.spec_range[2][0] == 0
        m0, m1 = g.spec_range[1]
        ky = np.asarray(g.ky).reshape(-1)
        j = np.arange(ny)
        mid = j[(j >= ny // 4) & (j < 3 * ny // 4)]
        yy = j * g.dx
        e = lambda jj: np.exp(1j * np.outer(ky, jj * g.dx))        # noqa: E731
        self.w_rate = (1j * ky * e(mid).sum(axis=1)) / ny
        self.w_moment = (e(j) * yy[None, :]).sum(axis=1) / ny
        assert len(self.w_rate) == m1 - m0
        self.rate = 0.0
        self.strain = 0.0
        self.stress = 0.0
        self.inertia = 0.0
        self.moment_old = 0.0         # M of the previous step (0 before the first: rhop = 0)
        self.sum, self.n = 0.0, 0     # the record's mean since the previous record
        self._ux = None               # u_x in real space (AC with heavy particles)

    def _sum(self, values):
        return self.grid.sums(values)

    def _at_profiles(self, spm, field):
        """(sum_i drho_i sum_s phi_is f_s, sum_i drho_i sum_s phi_is y_s f_s) over the
        particles' stencil points of this rank."""
        if not self.heavy or not spm.p.n:
            return 0.0, 0.0
        p = spm.p
        drho = spm.of_rows(self.drho_species[p.species])
        idx = spm.idx
        ny_l, nz = field.shape[1], field.shape[2]
        f = np.take(field.reshape(-1), idx)
        w = spm.phi_i * drho[:, None] * f
        ys = self.y[(idx // nz) % ny_l]
        return float(w.sum()), float((w * ys).sum())

    def measure(self, spm, u_hat):
        """After a step: this step's rate, strain, stress (and AC inertia)."""
        pin = self.pin
        d = pin.delta
        c = u_hat[0, 0, :, 0] if self.column else None
        rate = float(np.real(np.dot(self.w_rate, c))) if self.column else 0.0
        moment_u = float(np.real(np.dot(self.w_moment, c))) if self.column else 0.0
        prof = d.sum(axis=(0, 2))
        rd, ryd = self._at_profiles(spm, d)
        local = [rate, self.rho * float(prof.sum()) + rd,
                 self.rho * float(np.dot(self.y, prof)) + ryd]
        ac = pin.kind == "AC"
        if ac:
            local.append(self.rho * moment_u)
            if self.heavy:         # (a collective when distributed: on every rank)
                if self._ux is None:
                    self._ux = self.grid.empty_real(None)
                ux = self.grid.irfft_scalar(u_hat[0], out=self._ux)
                local.append(self._at_profiles(spm, ux)[1])
            else:
                local.append(0.0)
        tot = self._sum(local)
        self.rate = -2.0 * tot[0] / self.n_points
        self.strain += self.rate * self.dt
        s0, s1 = tot[1], tot[2]
        self.stress = -self.norm * (s1 - s0 / self.n_points * self.y_sum)
        value = self.stress
        if ac:
            m = tot[3] + tot[4]
            self.inertia = self.norm * (m - self.moment_old)
            self.moment_old = m
            value = self.stress + self.inertia
        self.sum += value
        self.n += 1

    def take(self) -> float:
        """The mean since the last call (0 before any step)."""
        if self.n == 0:
            return 0.0
        s = self.sum / self.n
        self.sum, self.n = 0.0, 0
        return s

    def state(self) -> list:
        return [self.sum, self.n, self.strain, self.moment_old, self.rate]

    def set_state(self, values) -> None:
        self.sum, self.n, self.strain, self.moment_old, self.rate = values
        self.n = int(self.n)


class ZigzagModel(SpectralModel):
    """Shear_Navier_Stokes: the Navier_Stokes model with the zigzag pin (module docstring)."""

    sheared = True
    shear_table_stream = "stderr"

    def __init__(self, cfg: RunConfig, args):
        super().__init__(cfg, args)
        sh = cfg.shear
        self.pin = ZigzagPin(self.fluid, sh.kind, sh.shear_rate, sh.frequency,
                             lambda: self.step_index)
        self.fluid.after_update = self.pin
        ratios = [s.MASS_RATIO for s in cfg.particles.species] or [1.0]
        heavy = any(s.MASS_RATIO != 1.0 and s.particles for s in cfg.particles.species)
        self.zz = ZigzagStress(self.pin, cfg.fluid.RHO, ratios, self.dt, heavy)
        p = self.particles
        if p.n and not getattr(p.constraints, "place_beads", None):
            p.v[:, 0] = 0.0                  # Show_parameter: v_x, omega_z of the sheared types
            p.omega[:, 2] = 0.0

    def advance(self):
        self.spm.step()
        self.zz.measure(self.spm, self.fluid.u_hat)
        self.tick()

    @property
    def shear_table(self):
        return TABLE_AC if self.pin.kind == "AC" else TABLE_DC

    def shear_table_row(self) -> list:
        """This step's row of the original's table (module docstring)."""
        z = self.zz
        if self.pin.kind == "AC":
            return [self.time, z.rate, z.strain, z.stress, z.inertia, z.stress + z.inertia]
        return [self.time, z.rate, z.strain, z.stress,
                z.stress / z.rate if z.rate else float("nan")]

    def shear_record(self) -> dict:
        z = self.zz
        return {"Shear_stress": z.take(), "Shear_strain": z.strain, "Shear_rate": z.rate}

    # ------------------------------------------------------------------ restart
    def accumulators(self) -> dict:
        return {"zigzag": self.zz.state()}

    def set_accumulators(self, values: dict) -> None:
        self.zz.set_state(values["zigzag"])


@register("Shear_Navier_Stokes")
def make_zigzag(cfg, args, doc):
    return ZigzagModel(cfg, args)


__all__ = ["ZigzagModel", "ZigzagPin", "ZigzagStress", "zigzag_profile", "TABLE_DC", "TABLE_AC"]
