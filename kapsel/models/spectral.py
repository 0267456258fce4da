"""The pseudo-spectral type ``Navier_Stokes`` (manual §4.1, eqs 1-14): particles in a periodic
incompressible fluid by the Smoothed Profile Method (kapsel.particles.spm.SPM on a
kapsel.fluid.spectral.SpectralNS).  Writes output.udf records; no field files (the original
writes HDF5 fields only for the FDM types)."""
from __future__ import annotations

from ..config import ConfigError, RunConfig
from ..simulation import register
from .common import (Model, kinetic_energy, make_forces, make_noise, make_particles,
                     overlap_guard)


class SpectralModel(Model):
    def __init__(self, cfg: RunConfig, args):
        from ..fluid.spectral import SpectralNS
        from ..grid import Grid
        from ..particles.spm import SPM
        super().__init__(cfg, args)
        f, seed = cfg.fluid, self.seed
        self.grid = Grid(cfg.mesh.shape, cfg.mesh.DX, threads=self.threads)
        self.fluid = SpectralNS(self.grid, f.RHO, f.ETA, self.dt, fix_cell=cfg.switches.fix_cell)
        self.particles = make_particles(cfg, self.rng)
        self.spm = SPM(self.fluid, self.particles, cfg.particles.A, cfg.particles.A_XI, f.RHO,
                       cfg.mesh.DX, self.dt, rotation=cfg.switches.ROTATION,
                       forces=overlap_guard(make_forces(cfg, self.particles)),
                       noise=make_noise(cfg, self.particles, seed))

    def advance(self):
        self.spm.step()
        self.tick()

    def kinetic_energy(self) -> float:
        phi = self.spm.phi() if self.particles.n else None
        return kinetic_energy(self.cfg.fluid.RHO, self.cfg.mesh.DX, self.spm.velocity(), phi,
                              self.particles)

    def record_items(self) -> dict:
        return {}

    # ------------------------------------------------------------------ restart
    restart_kind = "CONTINUE"

    def restart_fields(self) -> dict:
        """Zeta (omega_x, omega_z in Fourier space) and uk_dc (kapsel.io.restart)."""
        from ..io.restart import zeta_from_velocity
        zeta, dc = zeta_from_velocity(self.spm.velocity(), self.cfg.mesh.DX)
        return {"Zeta": zeta, "uk_dc": [float(c) for c in dc], "oblique": [0.0]}

    def exact_state(self) -> dict:
        return {"u_hat": self.fluid.u_hat.copy()}

    checkpoint_complete = False

    def checkpoint_fields(self) -> dict:
        """A checkpoint continues from u_hat (exact_state): the Zeta packing, an FFT and a
        third of the checkpoint's cost at 64^3, is only written into restart.udf."""
        return {}

    def load_fields(self, fields: dict, exact) -> None:
        if not exact or "u_hat" not in exact:
            from ..io.restart import state_path
            raise ConfigError(
                f"a CONTINUE restart is continued together with its state file "
                f"{state_path(self.cfg.input_path)} (missing, damaged, or written for other data): "
                f"the Zeta packing alone does not determine the velocity",
                path=f"resume.{self.cfg.resume.calculation}.Saved_Data.Zeta[]", value="(without state file)")
        if exact["u_hat"].shape != self.fluid.u_hat.shape:
            raise ConfigError(f"the restart's velocity has shape {exact['u_hat'].shape}, the "
                              f"mesh needs {self.fluid.u_hat.shape}",
                              path=f"resume.{self.cfg.resume.calculation}.Saved_Data.Zeta[]", value="shape")
        self.fluid.set_velocity_hat(exact["u_hat"])
        self.spm.refresh()

    def fields(self) -> dict:
        return {}


@register("Navier_Stokes")
def make_navier_stokes(cfg, args, doc):
    return SpectralModel(cfg, args)
