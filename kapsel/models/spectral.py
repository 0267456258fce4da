"""The pseudo-spectral type ``Navier_Stokes`` (manual §4.1, eqs 1-14): particles in a periodic
incompressible fluid by the Smoothed Profile Method (kapsel.particles.spm.SPM on a
kapsel.fluid.spectral.SpectralNS).  Writes output.udf records; no field files (the original
writes HDF5 fields only for the FDM types)."""
from __future__ import annotations

from ..config import RunConfig
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

    def fields(self) -> dict:
        return {}


@register("Navier_Stokes")
def make_navier_stokes(cfg, args, doc):
    return SpectralModel(cfg, args)
