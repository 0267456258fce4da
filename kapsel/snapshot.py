"""What a model offers the output writers at a snapshot: ``Model.snapshot() -> Snapshot``.

The clock, the particles and the frame strain are plain attributes; everything that costs
work to compute (fields in the rectangular frame, stresses, the kinetic energy, the shear
record) is a named *source*, computed on the first ``get`` and shared by every writer of the
snapshot.  A writer asks ``offers(name)`` before it relies on a name, so a type that cannot
provide something is found when the writers are built, not at the first snapshot.

Names (fields are float64 arrays indexed [x, y, z], rectangular frame, full flow: the imposed
shear flow of the sheared types included):

    u          fluid velocity (3, NX, NY, NZ)
    phi        particle profile (NX, NY, NZ)            (only with particles)
    psi        fluid order parameter (NX, NY, NZ)       (phase-field types)
    psi_all    total order parameter, particles' interiors included (phase-field types)
    flux       order-parameter flux psi u - kappa grad mu (3, NX, NY, NZ)
    pressure   fluid pressure (NX, NY, NZ)             (types that compute it)
    tau        viscous stress eta (d_i u_j + d_j u_i), (5, NX, NY, NZ): xx, xy, xz, yy, yz
    E          kinetic energy of the output record (float)
    record     further output.udf record items (dict, e.g. PSI)
    shear      {Shear_stress, Shear_strain, Shear_rate} (sheared types; computed once per
               snapshot: the stress is the mean since the previous snapshot)
    E_rot      rotational energy of every rigid body (array; rigid bodies only)
"""
from __future__ import annotations

from dataclasses import dataclass, field

TAU_COMPONENTS = ("xx", "xy", "xz", "yy", "yz")


@dataclass(eq=False)
class Snapshot:
    step: int
    time: float
    dt: float
    shape: tuple
    dx: float
    particles: object = None          # kapsel.particles.state.ParticleState
    strain: float = 0.0               # degree_oblique: strain of the oblique frame (0 if none)
    sheared: bool = False             # a Lees-Edwards / zigzag shear type
    sources: dict = field(default_factory=dict)
    # a distributed run whose h5py is built with MPI: ``h5_fields(tmp, datasets, attrs)``
    # writes the field datasets of one HDF5 file with every rank writing its block
    # (kapsel.models.common.Model.write_h5_fields); None: the fields are gathered
    h5_fields: object = None
    _cache: dict = field(default_factory=dict, repr=False)

    def offers(self, name: str) -> bool:
        return name in self.sources

    def get(self, name: str):
        """The value of ``name`` (computed once per snapshot)."""
        if name not in self._cache:
            if name not in self.sources:
                raise KeyError(f"this run offers no {name!r} "
                               f"(it offers {', '.join(sorted(self.sources))})")
            self._cache[name] = self.sources[name]()
        return self._cache[name]

    @property
    def n_particles(self) -> int:
        return 0 if self.particles is None else int(self.particles.n)
