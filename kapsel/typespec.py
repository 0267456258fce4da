"""The ``constitutive_eq.type`` values: one :class:`TypeSpec` each, the single place that says
what a type is (its grid, whether it carries an order parameter, a shear, ions; what the
original allows with it).  Everything that asks "which types ..." asks here (:func:`spec`,
:func:`names`); a type's model registers its factory here with :func:`register`
(``SOLVERS``: type name -> ``make(cfg, args, input_doc) -> model``).

Adding a type: one ``TypeSpec`` line below and the module of its model (its
``@register(name)`` factory), plus the type's block in define.udf.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["TypeSpec", "TYPES", "SOLVERS", "register", "spec", "names", "sheared"]


@dataclass(frozen=True)
class TypeSpec:
    """What one constitutive_eq.type is (manual §2, §4.1)."""
    name: str
    grid: str                     # "spectral" (Fourier collocation) or "fdm" (staggered MAC)
    phase: bool = False           # a Cahn-Hilliard order parameter psi (§2.3)
    sheared: bool = False         # an imposed shear flow (zigzag or Lees-Edwards, §2.4)
    ions: bool = False            # electrolyte ions and the Poisson-Boltzmann start (§2.5)
    walls: bool = False           # switch.wall FLAT accepted (as the original)
    self_propelled: bool = False  # TUMBLER / SQUIRMER janus particles accepted (§3.1)
    distributed: bool = True      # runs on more than one MPI rank
    surface_z: bool = False       # the Cahn-Hilliard surface term z is read (PHYSICS-EXTRA §1.3)
    psi_file: str | None = None   # the dataset of psi in orderparam_<n>.h5 (FDM CH types)
    flux_file: bool = False       # flux_<n>.h5 and flux_field.xmf (the original's CH flux)
    # peak memory per mesh point (bytes; the run's peak RSS less the program's own, measured
    # with /usr/bin/time on 64^3 and 128^3 runs of samples/input.udf 2026-12-02, ~10 % added),
    # and what particles add per point (their dense fields) besides their stencils
    # (kapsel.config.memory_estimate); Electrolyte's and Lees-Edwards' from 2026-12-04, after
    # their steps were trimmed (kapsel.config: the runs behind PROGRAM_BYTES; Electrolyte
    # 380 -> 360 after its restart's peak was trimmed: 128^3, 1000 particles, 831 MB peak;
    # 360 -> 270 on 2026-12-05 after its ions took the fluid's free buffers: 128^3 with
    # 1000 particles 652 MB peak, estimated 718; 256^3 with 8000, 4274 MB, estimated 4.85 GB;
    # after its ions held c_hat and lost their own rho_e and scratch buffers: 633 MB at 128^3)
    bytes_per_point: int = 180
    bytes_per_point_particles: int = 16

    @property
    def fdm(self) -> bool:
        return self.grid == "fdm"


TYPES = {s.name: s for s in (
    TypeSpec("Navier_Stokes", "spectral", walls=True, self_propelled=True),
    TypeSpec("Shear_Navier_Stokes", "spectral", sheared=True, self_propelled=True,
             bytes_per_point=200),
    TypeSpec("Shear_Navier_Stokes_Lees_Edwards", "spectral", sheared=True,
             bytes_per_point=280),
    TypeSpec("Electrolyte", "spectral", ions=True, distributed=False, bytes_per_point=270),
    TypeSpec("Navier_Stokes_FDM", "fdm", walls=True, bytes_per_point=400,
             bytes_per_point_particles=64),
    TypeSpec("Navier_Stokes_Cahn_Hilliard_FDM", "fdm", phase=True, walls=True, surface_z=True,
             psi_file="PSI_ALL", flux_file=True, bytes_per_point=800,
             bytes_per_point_particles=64),
    TypeSpec("Shear_Navier_Stokes_Lees_Edwards_FDM", "fdm", sheared=True,
             bytes_per_point=540, bytes_per_point_particles=64),
    TypeSpec("Shear_NS_LE_CH_FDM", "fdm", phase=True, sheared=True, surface_z=True,
             psi_file="PSI", bytes_per_point=950, bytes_per_point_particles=64),
)}


def spec(name: str) -> TypeSpec:
    """The TypeSpec of a type name (KeyError for a name that is no type)."""
    return TYPES[name]


def sheared(name) -> bool:
    """Whether ``name`` is a sheared type (False for a name that is no type)."""
    return name in TYPES and TYPES[name].sheared


def names(**flags) -> tuple[str, ...]:
    """The type names whose TypeSpec has every given attribute value, in the order above,
    e.g. ``names(sheared=True)``."""
    return tuple(n for n, s in TYPES.items()
                 if all(getattr(s, k) == v for k, v in flags.items()))


SOLVERS: dict = {}      # type name -> the factory of its model (kapsel.models registers them)


def register(type_name: str):
    """Decorator: make ``factory(cfg, args, doc) -> model`` the model of a type."""
    def deco(factory):
        SOLVERS[type_name] = factory
        return factory
    return deco
