"""The pseudo-spectral type ``Navier_Stokes`` (manual §4.1, eqs 1-14): particles in a periodic
incompressible fluid by the Smoothed Profile Method (kapsel.particles.spm.SPM on a
kapsel.fluid.spectral.SpectralNS).  Writes output.udf records; no field files (the original
writes HDF5 fields only for the FDM types)."""
from __future__ import annotations

import numpy as np

from ..config import RunConfig
from ..simulation import register
from .common import (kinetic_energy, make_forces, make_noise, make_particles, overlap_guard,
                     random_seed, time_step)


class SpectralModel:
    def __init__(self, cfg: RunConfig, args):
        from ..fluid.spectral import SpectralNS
        from ..grid import Grid
        from ..particles.spm import SPM
        self.cfg = cfg
        f = cfg.fluid
        self.dt = time_step(cfg)
        self.time = 0.0
        self.step_index = 0
        seed = random_seed(args)
        self.rng = np.random.default_rng(seed)
        self.grid = Grid(cfg.mesh.shape, cfg.mesh.DX, threads=getattr(args, "threads", 1))
        self.fluid = SpectralNS(self.grid, f.RHO, f.ETA, self.dt, fix_cell=cfg.switches.fix_cell)
        self.particles = make_particles(cfg, self.rng)
        self.spm = SPM(self.fluid, self.particles, cfg.particles.A, cfg.particles.A_XI, f.RHO,
                       cfg.mesh.DX, self.dt, rotation=cfg.switches.ROTATION,
                       forces=overlap_guard(make_forces(cfg, self.particles)),
                       noise=make_noise(cfg, self.particles, seed))

    def advance(self):
        self.spm.step()
        self.step_index += 1
        self.time = self.step_index * self.dt

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
