"""The pseudo-spectral type ``Navier_Stokes`` (manual §4.1, eqs 1-14): particles in a periodic
incompressible fluid by the Smoothed Profile Method (kapsel.particles.spm.SPM on a
kapsel.fluid.spectral.SpectralNS).  Offers u, phi, tau and the pressure to the field writers
(output.AVS); the per-snapshot HDF5 files are the FDM types' only, as in the original."""
from __future__ import annotations

import numpy as np

from ..config import ConfigError, RunConfig
from ..typespec import register
from ..particles.interactions import OVERLAP_LIMIT
from .common import Model, kinetic_energy, make_forces, make_noise, make_particles


class SpectralModel(Model):
    def __init__(self, cfg: RunConfig, args):
        from ..fluid.spectral import SpectralNS
        from ..particles.spm import SPM
        super().__init__(cfg, args)
        f, seed = cfg.fluid, self.seed
        self.grid = self.make_grid(cfg)
        self.fluid = SpectralNS(self.grid, f.RHO, f.ETA, self.dt, fix_cell=cfg.switches.fix_cell,
                                state=self.state)
        from ..particles.walls import make_wall
        self.particles = make_particles(cfg, self.rng)
        self.wall = make_wall(cfg)
        self.spm = SPM(self.fluid, self.particles, self.spm_radius(), cfg.particles.A_XI, f.RHO,
                       cfg.mesh.DX, self.dt, rotation=cfg.switches.ROTATION,
                       forces=make_forces(cfg, self.particles, wall=self.wall,
                                          overlap_limit=OVERLAP_LIMIT),
                       noise=make_noise(cfg, self.particles, seed), wall=self.wall,
                       dry=self.dry)

    def make_grid(self, cfg):
        """The mesh's layout (kapsel.parallel.make_layout: a ``kapsel.mesh.grid.Grid``, or in a
        distributed run this rank's blocks of it)."""
        from ..parallel import make_layout
        try:
            grid = make_layout(cfg.mesh.shape, cfg.mesh.DX, self.dist, self.threads)
        except ValueError as e:
            raise ConfigError(str(e), path="mesh", value="process grid") from None
        self.collectives.register("u_hat", lambda: grid.gather_complex(self.fluid.u_hat))
        return grid

    def local(self, a):
        """This rank's block of a whole Fourier field (itself on one process)."""
        return self.grid.local_complex(a)

    def advance(self):
        self.spm.step()
        self.tick()

    def phi_total(self):
        """phi of the output: particles and walls, min(phi_sum, 1) (PHYSICS-EXTRA.md §2.3)."""
        phi = self.spm.phi()
        if self.wall is not None:
            phi = np.minimum(phi + self.wall.phi, 1.0)
        return phi

    def kinetic_energy(self) -> float:
        phi = self.phi_total() if self.particles.n or self.wall is not None else None
        return kinetic_energy(self.cfg.fluid.RHO, self.cfg.mesh.DX, self.spm.velocity(), phi,
                              self.spm.owned_particles(),
                              reduce=self.grid.sum,
                              owned=self._partial_particles())

    def global_u_hat(self):
        """The whole u_hat: gathered to rank 0 in a distributed run (None on the others)."""
        return self.collectives.call("u_hat")

    def record_items(self) -> dict:
        return {}

    # ------------------------------------------------------------------ restart
    restart_kind = "CONTINUE"

    def restart_fields(self) -> dict:
        """Zeta and uk_dc: the fluid's u_hat in the original's packing (kapsel.io.restart)."""
        from ..io.restart import pack_zeta
        zeta, dc = pack_zeta(self.global_u_hat(), self.cfg.mesh.DX)
        return {"Zeta": zeta, "uk_dc": [float(c) for c in dc], "oblique": [0.0]}

    def exact_state(self) -> dict:
        return {"u_hat": self.global_u_hat()}       # written at once (no copy: issue 25)

    checkpoint_complete = False

    def checkpoint_fields(self) -> dict:
        """A checkpoint continues from u_hat (exact_state): the Zeta packing, an FFT and a
        third of the checkpoint's cost at 64^3, is only written into restart.udf."""
        return {}

    def _zeta_velocity(self, fields: dict):
        """u_hat of a restart's Zeta / uk_dc (a restart without its state file, e.g. one
        written by the original), checked against the mesh."""
        from ..io.restart import unpack_zeta
        where = f"resume.{self.cfg.resume.calculation}.Saved_Data"
        if "Zeta" not in fields:
            raise ConfigError("the restart holds no Zeta (the spectral velocity) and no "
                              "state file goes with it", path=f"{where}.Zeta[]", value="(empty)")
        want = self.grid.shape[:2] + (self.grid.shape[2] + 2, 2)
        if fields["Zeta"].shape != want:
            raise ConfigError(f"Zeta has shape {list(fields['Zeta'].shape)}, the mesh needs "
                              f"{list(want)} (NX, NY, NZ + 2, 2)", path=f"{where}.Zeta[]",
                              value="shape")
        dc = fields.get("uk_dc", (0.0, 0.0, 0.0))
        return unpack_zeta(fields["Zeta"], dc, self.cfg.mesh.DX,
                           sheared=getattr(self.fluid, "oblique", False))

    def load_fields(self, fields: dict, exact) -> None:
        """The state file's u_hat (bit-identical continuation) or else Zeta / uk_dc."""
        local = self.local
        if exact and "u_hat" in exact:
            want = (3,) + tuple(self.grid.cshape)
            if exact["u_hat"].shape != want:
                raise ConfigError(f"the restart's velocity has shape {exact['u_hat'].shape}, "
                                  f"the mesh needs {want}",
                                  path=f"resume.{self.cfg.resume.calculation}.Saved_Data.Zeta[]",
                                  value="shape")
            self.fluid.set_velocity_hat(local(exact["u_hat"]))
        else:
            self.fluid.set_velocity_hat(local(self._zeta_velocity(fields)))
        self.spm.refresh()

    def field_sources(self) -> dict:
        """u, phi (with particles), tau (spectral derivatives) and the pressure
        (kapsel.fluid.diagnostics.spectral_pressure: advection and the particles' body force
        of the last step)."""
        from ..fluid.diagnostics import spectral_pressure, viscous_stress_spectral
        dx, f = self.cfg.mesh.DX, self.cfg.fluid
        memo = {}

        def u():                  # the snapshot's velocity, transformed once
            if "u" not in memo:
                memo["u"] = self.spm.velocity()
            return memo["u"]

        from ..mesh.pencil import Gathered
        g = self.grid

        def on_root(fn):            # tau, pressure: from the gathered fields, on rank 0
            def gathered():
                args = [g.gather_real(a()) for a in fn[1:]]
                return Gathered(fn[0](*args) if g.is_root else None)
            return gathered
        src = {"u": u,
               "tau": on_root((lambda U: viscous_stress_spectral(U, dx, f.ETA), u)),
               "pressure": on_root((lambda U, D: spectral_pressure(U, D, f.RHO, self.dt, dx),
                                    u, self.spm.last_increment))}
        if self.particles.n or self.wall is not None:
            src["phi"] = self.phi_total
        return src


@register("Navier_Stokes")
def make_navier_stokes(cfg, args, doc):
    return SpectralModel(cfg, args)
