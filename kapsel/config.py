"""The run configuration: the input UDF read into typed, validated, frozen dataclasses.

Every value is read by its UDF path (manual §6.1, tables 1-7).  A bad value raises
``ConfigError`` naming the file position, the path and the value; options the program does
not implement raise ``ConfigError`` naming the option (never a silent fallback).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

import udf
from udf import UDFError

SPECTRAL_TYPES = ("Navier_Stokes", "Shear_Navier_Stokes", "Shear_Navier_Stokes_Lees_Edwards",
                  "Electrolyte")
FDM_TYPES = ("Navier_Stokes_FDM", "Navier_Stokes_Cahn_Hilliard_FDM",
             "Shear_Navier_Stokes_Lees_Edwards_FDM", "Shear_NS_LE_CH_FDM")
PHASE_TYPES = ("Navier_Stokes_Cahn_Hilliard_FDM", "Shear_NS_LE_CH_FDM")
SHEAR_TYPES = ("Shear_Navier_Stokes", "Shear_Navier_Stokes_Lees_Edwards",
               "Shear_Navier_Stokes_Lees_Edwards_FDM", "Shear_NS_LE_CH_FDM")


class ConfigError(Exception):
    """An invalid or unsupported input value: one line for the user."""

    def __init__(self, message: str, where: str = "", path: str = "", value=None):
        self.path, self.value, self.where = path, value, where
        text = ""
        if where:
            text += where + ": "
        if path:
            text += path + (f" = {value!r}" if value is not None else "") + ": "
        super().__init__(text + message)


@dataclass(frozen=True)
class Mesh:
    NPX: int
    NPY: int
    NPZ: int
    DX: float

    @property
    def shape(self) -> tuple:
        return (2 ** self.NPX, 2 ** self.NPY, 2 ** self.NPZ)

    @property
    def box(self) -> np.ndarray:
        return np.array(self.shape, dtype=float) * self.DX


@dataclass(frozen=True)
class Shear:
    kind: str             # 'DC' | 'AC'
    shear_rate: float
    frequency: float = 0.0


@dataclass(frozen=True)
class Fluid:
    RHO: float
    ETA: float
    kBT: float
    alpha_v: float
    alpha_o: float
    ns_solver: str = "spectral"     # 'spectral' | 'explicit_scheme' | 'implicit_scheme'
    tolerance: float = 1e-9         # BiCGSTAB relative residual (10**exponent of the file)
    maximum_iteration: int = 1000
    viscosity_change: bool = False
    ETA_A: float = 0.0
    ETA_B: float = 0.0

    @property
    def nu(self) -> float:
        return self.ETA / self.RHO


@dataclass(frozen=True)
class PhaseField:
    ch_solver: str                 # 'explicit_scheme' | 'implicit_scheme'
    tolerance: float
    maximum_iteration: int
    potential: str                 # 'Landau' | 'Flory_Huggins'
    composition_ratio: float
    initial_fluctuation: float
    d: float
    w: float
    alpha: float
    kappa: float
    a: float = 0.0
    b: float = 0.0
    na: float = 0.0
    nb: float = 0.0
    chi: float = 0.0
    z: float = 0.0                 # gradient penalty in the solids: (alpha/2 + z phi)|grad psi|^2
    w_wall: float = 0.0            # wetting of the walls' faces
    psi_0_p: float = 0.0           # psi preferred inside the particles (Landau)
    psi_0_wall: object = 0.0       # psi preferred inside the walls: a number or (N1, N2) map


@dataclass(frozen=True)
class Species:
    """One Particle_spec / Chain_spec / Rigid_spec entry."""
    number: int                    # particles, or chains / bodies
    beads: int                     # beads per chain or body (1 for spheres)
    MASS_RATIO: float
    surface_charge: float = 0.0
    rigid_motion: str = "free"
    rigid_velocity: tuple = (0.0, 0.0, 0.0)
    rigid_omega: tuple = (0.0, 0.0, 0.0)

    @property
    def particles(self) -> int:
        return self.number * self.beads


@dataclass(frozen=True)
class Particles:
    object_type: str               # 'spherical_particle' | 'chain' | 'rigid'
    species: tuple
    A: float
    A_XI: float

    @property
    def count(self) -> int:
        return sum(s.particles for s in self.species)


@dataclass(frozen=True)
class Interactions:
    EPSILON: float
    LJ_powers: str                 # '12:6' | '24:12' | '36:18' | 'macro_vdw'
    LJ_truncate: str               # 'ON' | 'OFF' | 'NONE'
    G: float
    G_direction: str               # '-X' | '-Y' | '-Z'


@dataclass(frozen=True)
class Wall:
    """switch.wall FLAT (PHYSICS-EXTRA.md §2): axis 0/1/2, DH solid points, the wall's LJ law
    (AUTO: the particles' EPSILON and LJ_powers with truncation ON)."""
    axis: int
    DH: int
    powers: str
    EPSILON: float
    truncate: str
    LJ_Params: str = "AUTO"


@dataclass(frozen=True)
class Switches:
    ROTATION: bool
    init_distribution: str
    random_walk_iterations: int
    user_particles: np.ndarray = field(compare=False)   # (n, 13): R, v, q, omega
    init_orientation: str = "space_align"
    fix_cell: tuple = (False, False, False)
    pin: tuple = ()
    pin_rot: tuple = ()
    free_rigid: tuple = ()         # ((spec_id, (vx,vy,vz), (ox,oy,oz)), ...) of bools
    OBL_INT: str = "linear"
    wall: Wall | None = None


@dataclass(frozen=True)
class TimeIncrement:
    kind: str                      # 'auto' | 'manual'
    factor: float = 1.0
    delta_t: float = 0.0


@dataclass(frozen=True)
class FieldOutput:
    """output.AVS ON: ``Out_dir``, ``Out_name``, ``FileType`` (BINARY / ASCII: legacy AVS;
    EXTENDED: one HDF5 trajectory), and for EXTENDED the Print_field switches and the crop
    (``slabs``: ((start, count, stride) per axis) or None for the full grid)."""
    Out_dir: str
    Out_name: str
    FileType: str
    slabs: tuple | None = None
    Vel: bool = True
    Phi: bool = True
    Charge: bool = False
    Pressure: bool = True
    Tau: bool = True


@dataclass(frozen=True)
class Output:
    GTS: int
    Num_snap: int
    UDF: bool
    AVS: bool = False
    fields: FieldOutput | None = None

    @property
    def total_steps(self) -> int:
        return self.GTS * self.Num_snap


@dataclass(frozen=True)
class Resume:
    calculation: str               # 'NEW' | 'CONTINUE' | 'CONTINUE_ORIGINAL' | 'CONTINUE_FDM' | ...


@dataclass(frozen=True)
class RunConfig:
    type: str                      # constitutive_eq.type
    mesh: Mesh
    fluid: Fluid
    particles: Particles
    interactions: Interactions
    switches: Switches
    time: TimeIncrement
    output: Output
    resume: Resume
    phase: PhaseField | None = None
    shear: Shear | None = None
    input_path: str = ""

    @property
    def is_fdm(self) -> bool:
        return self.type in FDM_TYPES

    @property
    def has_phase_field(self) -> bool:
        return self.type in PHASE_TYPES


# ---------------------------------------------------------------------------------------
class _Reader:
    """Reads values by path and remembers where they came from for messages."""

    def __init__(self, doc: udf.UDFManager):
        self.doc = doc

    def where(self, path: str) -> str:
        return self.doc.where(path.split(".")[0].split("[")[0])

    def get(self, path: str):
        top = path.split(".")[0].split("[")[0]
        if self.doc.path and top not in self.doc.common_where:
            raise ConfigError("is missing from the input (its \\begin{data} block has no "
                              f"{top})",
                              self.doc.path, path)
        try:
            return self.doc.get(path)
        except UDFError as e:
            raise ConfigError(f"missing or unreadable in this input ({e.message})",
                              self.where(path), path) from None

    def has(self, path: str) -> bool:
        try:
            self.doc.get(path)
            return True
        except UDFError:
            return False

    def fail(self, path, value, message):
        raise ConfigError(message, self.where(path), path, value)

    def positive(self, path):
        v = self.get(path)
        if not v > 0 or not math.isfinite(v):
            self.fail(path, v, "must be a positive number")
        return v

    def non_negative(self, path):
        v = self.get(path)
        if not v >= 0 or not math.isfinite(v):
            self.fail(path, v, "must be zero or positive")
        return v

    def finite(self, path):
        v = self.get(path)
        if not math.isfinite(v):
            self.fail(path, v, "must be a finite number")
        return v


def load(input_path: str) -> RunConfig:
    """Read and validate ``input_path``; raises UDFError (syntax) or ConfigError (values)."""
    doc = udf.UDFManager(input_path)
    return from_document(doc, input_path)


def from_document(doc: udf.UDFManager, input_path: str = "") -> RunConfig:
    r = _Reader(doc)
    _check_is_input(doc, input_path)
    eq_type = r.get("constitutive_eq.type")
    base = f"constitutive_eq.{eq_type}"
    if eq_type == "Electrolyte":
        r.fail("constitutive_eq.type", eq_type,
               "the Electrolyte type (charged particles) is not supported by kapsel-py")

    # ---- mesh ------------------------------------------------------------------------
    nps = []
    for ax in ("NPX", "NPY", "NPZ"):
        p = f"mesh.{ax}"
        v = r.get(p)
        if v < 1:
            r.fail(p, v, "must be at least 1 (the mesh has 2^NP points per direction)")
        if v > 12:
            r.fail(p, v, "is too large (2^NP > 4096 points per direction)")
        nps.append(v)
    mesh = Mesh(*nps, DX=r.positive(f"{base}.DX"))

    # ---- fluid -----------------------------------------------------------------------
    fl = dict(RHO=r.positive(f"{base}.RHO"), ETA=r.positive(f"{base}.ETA"),
              kBT=r.non_negative(f"{base}.kBT"), alpha_v=r.non_negative(f"{base}.alpha_v"),
              alpha_o=r.non_negative(f"{base}.alpha_o"))
    if eq_type in FDM_TYPES:
        sp = f"{base}.NS_solver"
        fl["ns_solver"] = r.get(f"{sp}.type")
        if fl["ns_solver"] == "implicit_scheme":
            tol = r.finite(f"{sp}.implicit_scheme.tolerance")
            _check_tolerance(r, f"{sp}.implicit_scheme.tolerance", tol)
            fl["tolerance"] = 10.0 ** tol
            it = r.get(f"{sp}.implicit_scheme.maximum_iteration")
            if it < 1:
                r.fail(f"{sp}.implicit_scheme.maximum_iteration", it, "must be at least 1")
            fl["maximum_iteration"] = it
            vc = f"{sp}.implicit_scheme.viscosity_change"
            if eq_type in PHASE_TYPES and r.has(vc) and r.get(vc) == "ON":
                fl["viscosity_change"] = True
                fl["ETA_A"] = r.positive(f"{vc.rsplit('.', 1)[0]}.ON.ETA_A")
                fl["ETA_B"] = r.positive(f"{vc.rsplit('.', 1)[0]}.ON.ETA_B")
    fluid = Fluid(**fl)

    # ---- shear -----------------------------------------------------------------------
    shear = None
    if eq_type in SHEAR_TYPES:
        ef = f"{base}.External_field"
        kind = r.get(f"{ef}.type")
        rate = r.finite(f"{ef}.{kind}.Shear_rate")
        freq = r.non_negative(f"{ef}.AC.Frequency") if kind == "AC" else 0.0
        shear = Shear(kind, rate, freq)

    # ---- phase field -----------------------------------------------------------------
    phase = None
    if eq_type in PHASE_TYPES:
        cp = f"{base}.CH_solver"
        ch = r.get(f"{cp}.type")
        tol, it = 1e-9, 1000
        if ch == "implicit_scheme":
            t = r.finite(f"{cp}.implicit_scheme.tolerance")
            _check_tolerance(r, f"{cp}.implicit_scheme.tolerance", t)
            tol = 10.0 ** t
            it = r.get(f"{cp}.implicit_scheme.maximum_iteration")
            if it < 1:
                r.fail(f"{cp}.implicit_scheme.maximum_iteration", it, "must be at least 1")
        pot = r.get(f"{base}.Potential.type")
        pp = f"{base}.Potential.{pot}"
        common = dict(composition_ratio=r.finite(f"{pp}.composition_ratio"),
                      initial_fluctuation=r.non_negative(f"{pp}.initial_fluctuation"),
                      d=r.finite(f"{pp}.d"), w=r.finite(f"{pp}.w"),
                      alpha=r.non_negative(f"{pp}.alpha"), kappa=r.positive(f"{pp}.kappa"))
        for extra in ("k", "psi_dry"):  # k: never read by the original; psi_dry: dry walls
            if r.has(f"{pp}.{extra}") and r.get(f"{pp}.{extra}") != 0:
                r.fail(f"{pp}.{extra}", r.get(f"{pp}.{extra}"),
                       "is not supported by kapsel-py (set it to 0)")
        common.update(_surface_terms(r, pp, eq_type, mesh))
        if pot == "Landau":
            phase = PhaseField(ch, tol, it, pot, a=r.finite(f"{pp}.a"), b=r.finite(f"{pp}.b"),
                               **common)
        else:
            phase = PhaseField(ch, tol, it, pot, na=r.positive(f"{pp}.na"),
                               nb=r.positive(f"{pp}.nb"), chi=r.finite(f"{pp}.chi"), **common)
            c = phase.composition_ratio
            if not 0 < c < 1:
                r.fail(f"{pp}.composition_ratio", c,
                       "must lie strictly between 0 and 1 for the Flory-Huggins potential "
                       "(psi is a volume fraction)")

    # ---- particles -------------------------------------------------------------------
    obj = r.get("object_type.type")
    A = r.positive("A")
    A_XI = r.positive("A_XI")
    species = []
    if obj == "spherical_particle":
        sp = "object_type.spherical_particle.Particle_spec"
        for i in range(doc.size(f"{sp}[]")):
            p = f"{sp}[{i}]"
            n = r.get(f"{p}.Particle_number")
            if n < 0:
                r.fail(f"{p}.Particle_number", n, "must be zero or positive")
            for opt, off in (("janus_axis", "NONE"), ("janus_propulsion", "OFF")):
                if r.has(f"{p}.{opt}") and r.get(f"{p}.{opt}") != off and n > 0:
                    r.fail(f"{p}.{opt}", r.get(f"{p}.{opt}"),
                           f"self-propelled (janus) particles are not supported by kapsel-py; "
                           f"set it to {off}")
            species.append(Species(n, 1, r.positive(f"{p}.MASS_RATIO"),
                                   r.get(f"{p}.Surface_charge")))
    elif obj == "chain":
        sp = "object_type.chain.Chain_spec"
        for i in range(doc.size(f"{sp}[]")):
            p = f"{sp}[{i}]"
            nb, nc = r.get(f"{p}.Beads_number"), r.get(f"{p}.Chain_number")
            if nb < 1 or nc < 0:
                r.fail(f"{p}", [nb, nc], "Beads_number must be >= 1 and Chain_number >= 0")
            if r.has(f"{p}.janus_axis") and r.get(f"{p}.janus_axis") != "NONE" and nc > 0:
                r.fail(f"{p}.janus_axis", r.get(f"{p}.janus_axis"),
                       "self-propelled (janus) chain beads are not supported by kapsel-py; "
                       "set it to NONE")
            species.append(Species(nc, nb, r.positive(f"{p}.MASS_RATIO"),
                                   r.get(f"{p}.Surface_charge")))
    else:
        sp = "object_type.rigid.Rigid_spec"
        for i in range(doc.size(f"{sp}[]")):
            p = f"{sp}[{i}]"
            nb, nc = r.get(f"{p}.Beads_number"), r.get(f"{p}.Chain_number")
            if nb < 1 or nc < 0:
                r.fail(f"{p}", [nb, nc], "Beads_number must be >= 1 and Chain_number >= 0")
            species.append(Species(nc, nb, r.positive(f"{p}.MASS_RATIO"),
                                   r.get(f"{p}.Surface_charge"),
                                   rigid_motion=r.get(f"{p}.Rigid_motion"),
                                   rigid_velocity=tuple(r.get(f"{p}.Rigid_velocity")),
                                   rigid_omega=tuple(r.get(f"{p}.Rigid_omega"))))
    particles = Particles(obj, tuple(species), A, A_XI)
    check_memory(r, mesh, eq_type, particles.count)
    box = mesh.box
    if particles.count:
        if 2 * A >= box.min():
            r.fail("A", A, f"a particle of diameter {2 * A:g} does not fit in the box "
                           f"{' x '.join(f'{x:g}' for x in box)}")
        fraction = particles.count * (4 / 3) * math.pi * A ** 3 / math.prod(box.tolist())
        if fraction > 0.74:
            r.fail("object_type", particles.count,
                   f"{particles.count} particles of radius {A:g} cannot fit in the box "
                   f"(volume fraction {fraction:.2f} > 0.74, the densest packing)")

    # ---- interactions ----------------------------------------------------------------
    inter = Interactions(EPSILON=r.non_negative("EPSILON"), LJ_powers=r.get("LJ_powers"),
                         LJ_truncate=r.get("switch.LJ_truncate"), G=r.finite("gravity.G"),
                         G_direction=r.get("gravity.G_direction"))
    if obj == "chain" and particles.count:
        # FENE bonds (kapsel.particles.chains) scale with EPSILON and need the LJ repulsion
        if inter.EPSILON <= 0:
            r.fail("EPSILON", inter.EPSILON, "chains need EPSILON > 0 (the FENE bond constant "
                                             "is 30 EPSILON / (2 A)^2)")
        if inter.LJ_truncate == "NONE":
            r.fail("switch.LJ_truncate", "NONE", "chains need the excluded volume of the LJ "
                                                 "forces (ON or OFF)")

    # ---- switches ----------------------------------------------------------------------
    dist = r.get("switch.INIT_distribution.type")
    rw = r.get("switch.INIT_distribution.random_walk.iteration")
    if dist == "random_walk" and rw < 0:
        r.fail("switch.INIT_distribution.random_walk.iteration", rw, "must be zero or positive")
    user = np.asarray(doc.getArray("switch.INIT_distribution.user_specify.Particles[]"),
                      dtype=float).reshape(-1, 13)
    if obj != "spherical_particle" and dist in ("FCC", "BCC") and particles.count:
        r.fail("switch.INIT_distribution.type", dist,
               f"lattice placement is for spherical particles; {obj} objects are placed by "
               f"uniform_random / random_walk (random, non-overlapping) or user_specify")
    if dist == "user_specify" and particles.count and len(user) < particles.count:
        r.fail("switch.INIT_distribution.user_specify.Particles[]", len(user),
               f"user_specify needs one entry per particle ({particles.count} particles)")
    if dist == "user_specify" and particles.count:
        _check_user_positions(r, user[:particles.count], box, A)
    pin, pin_rot = (), ()
    if r.has("switch.pin.type") and r.get("switch.pin.type") == "YES":
        pin = tuple(r.get("switch.pin.YES.pin[]"))
        pin_rot = tuple(r.get("switch.pin.YES.pin_rot[]"))
        for p_, ids in (("switch.pin.YES.pin[]", pin), ("switch.pin.YES.pin_rot[]", pin_rot)):
            bad = [i for i in ids if not 0 <= i < particles.count]
            if bad and not particles.count:
                r.fail(p_, bad, "pins particles but the input has none (Particle_number 0); "
                                "set switch.pin to NO")
            if bad:
                r.fail(p_, bad, f"particle ids must lie in 0..{particles.count - 1}")
        if obj == "rigid" and (pin or pin_rot):
            r.fail("switch.pin.type", "YES", "pinning is for spherical particles and chain "
                                             "beads; hold rigid bodies with Rigid_motion fix "
                                             "or switch.free_rigid")
    free_rigid = ()
    if r.has("switch.free_rigid.type") and r.get("switch.free_rigid.type") == "YES":
        if obj != "rigid":
            r.fail("switch.free_rigid.type", "YES", "free_rigid applies to object_type rigid "
                                                    "only; set it to NO")
        rows = []
        for k, dof in enumerate(r.get("switch.free_rigid.YES.DOF[]")):
            sid, vel, om = dof
            if not 0 <= sid < len(species):
                r.fail(f"switch.free_rigid.YES.DOF[{k}].spec_id", sid,
                       f"must be a Rigid_spec index, 0..{len(species) - 1}")
            rows.append((sid, tuple(x == "YES" for x in vel), tuple(x == "YES" for x in om)))
        free_rigid = tuple(rows)
    wall = _wall(r, eq_type, mesh, A, inter)
    for opt, off in (("switch.quincke.type", "OFF"), ("switch.multipole.type", "OFF")):
        if r.has(opt) and r.get(opt) != off:
            r.fail(opt, r.get(opt), f"is not supported by kapsel-py; set it to {off}")
    fix = tuple(r.get(f"switch.FIX_CELL.{ax}") == "ON" for ax in "xyz")
    switches = Switches(ROTATION=r.get("switch.ROTATION") == "ON", init_distribution=dist,
                        random_walk_iterations=rw, user_particles=user,
                        init_orientation=r.get("switch.INIT_orientation"), fix_cell=fix,
                        pin=pin, pin_rot=pin_rot, free_rigid=free_rigid,
                        OBL_INT=r.get("switch.ns_solver.OBL_INT"), wall=wall)

    # ---- time, output, resume --------------------------------------------------------
    kind = r.get("time_increment.type")
    if kind == "auto":
        time = TimeIncrement("auto", factor=r.positive("time_increment.auto.factor"))
    else:
        time = TimeIncrement("manual", delta_t=r.positive("time_increment.manual.delta_t"))
    _check_time_step(r, time, fluid, mesh)
    gts, nsnap = r.get("output.GTS"), r.get("output.Num_snap")
    if gts < 1:
        r.fail("output.GTS", gts, "must be at least 1 (steps between snapshots)")
    if nsnap < 1:
        r.fail("output.Num_snap", nsnap, "must be at least 1 (the run is GTS x Num_snap steps)")
    avs = r.get("output.AVS") == "ON"
    output = Output(gts, nsnap, r.get("output.UDF") == "ON", avs,
                    _field_output(r, mesh) if avs else None)
    resume = Resume(r.get("resume.Calculation"))
    return RunConfig(type=eq_type, mesh=mesh, fluid=fluid, particles=particles,
                     interactions=inter, switches=switches, time=time, output=output,
                     resume=resume, phase=phase, shear=shear, input_path=input_path)


def _surface_terms(r: _Reader, pp: str, eq_type: str, mesh: Mesh) -> dict:
    """The Cahn-Hilliard items of newer define.udf files (PHYSICS-EXTRA.md §1.3), each 0 when
    absent: z, w_wall, psi_0_p, psi_0_wall (uniform, or user_specify: one value per node of
    the wall plane, the same through the wall)."""
    out = {}
    for name in ("z", "w_wall", "psi_0_p"):
        if r.has(f"{pp}.{name}"):
            out[name] = r.finite(f"{pp}.{name}")
    if out.get("z", 0.0) != 0 and eq_type != "Navier_Stokes_Cahn_Hilliard_FDM":
        r.fail(f"{pp}.z", out["z"], f"is supported for Navier_Stokes_Cahn_Hilliard_FDM only, "
                                    f"not {eq_type} (set it to 0)")
    w = f"{pp}.psi_0_wall"
    if r.has(f"{w}.type"):
        kind = r.get(f"{w}.type")
        if kind == "uniform":
            out["psi_0_wall"] = r.finite(f"{w}.uniform.psi_0_wall")
        elif kind == "user_specify":
            rows = r.get(f"{w}.user_specify.psi_0_wall[]")
            try:
                grid = np.array([[v[0] if isinstance(v, (list, tuple)) else v for v in row]
                                 for row in rows], dtype=float)
            except (TypeError, ValueError):
                grid = np.zeros((0, 0))
            if grid.ndim != 2 or not np.isfinite(grid).all():
                r.fail(f"{w}.user_specify.psi_0_wall[]", "...",
                       "must be a table of numbers psi_0_wall[i][j]")
            out["psi_0_wall"] = grid
    return out


WALL_TYPES = ("Navier_Stokes", "Navier_Stokes_FDM", "Navier_Stokes_Cahn_Hilliard_FDM")


def _wall(r: _Reader, eq_type: str, mesh: Mesh, A: float, inter: Interactions):
    """switch.wall (optional, NONE if absent): FLAT walls for the types the original allows
    them in, with XI < DH DX < L - 2 A (solid thicker than the interface, room for a
    particle between the walls)."""
    if not r.has("switch.wall.type") or r.get("switch.wall.type") == "NONE":
        return None
    if eq_type not in WALL_TYPES:
        r.fail("switch.wall.type", r.get("switch.wall.type"),
               f"FLAT walls are available for {', '.join(WALL_TYPES)} only (as in the "
               f"original), not {eq_type}; set it to NONE")
    f = "switch.wall.FLAT"
    axis = {"X": 0, "Y": 1, "Z": 2}[r.get(f"{f}.axis")]
    DH = r.get(f"{f}.DH")
    L = mesh.box[axis]
    xi = r.get("A_XI")
    if not xi < DH * mesh.DX < L - 2 * A:
        r.fail(f"{f}.DH", DH, f"the solid thickness DH DX = {DH * mesh.DX:g} must exceed the "
                              f"interface XI = {xi:g} and leave a gap wider than a particle "
                              f"(DH DX < L - 2A = {L - 2 * A:g})")
    kind = r.get(f"{f}.LJ_Params") if r.has(f"{f}.LJ_Params") else "AUTO"
    if kind == "MANUAL":
        m = f"{f}.MANUAL"
        return Wall(axis, DH, r.get(f"{m}.powers"), r.non_negative(f"{m}.EPSILON"),
                    r.get(f"{m}.truncate"), "MANUAL")
    return Wall(axis, DH, inter.LJ_powers, inter.EPSILON, "ON", "AUTO")


def _field_output(r: _Reader, mesh: Mesh) -> FieldOutput:
    """output.ON (FORMAT-OUTPUT.md §2.1, §3.1): the crop is checked as the original does
    (0 <= start < N, 0 < stride < N, 0 < count <= N, start + (count-1) stride < N).
    Charge is forced off (the original does so for every type but Electrolyte)."""
    on = "output.ON"
    out_dir, name, kind = r.get(f"{on}.Out_dir"), r.get(f"{on}.Out_name"), r.get(f"{on}.FileType")
    if not name or "/" in name:
        r.fail(f"{on}.Out_name", name, "must be a non-empty file name prefix (no '/')")
    if not out_dir:
        r.fail(f"{on}.Out_dir", out_dir, "must name a directory")
    if kind != "EXTENDED":
        return FieldOutput(out_dir, name, kind)
    ext = f"{on}.EXTENDED"
    if r.has(f"{ext}.Driver.Format") and r.get(f"{ext}.Driver.Format") != "HDF5":
        r.fail(f"{ext}.Driver.Format", r.get(f"{ext}.Driver.Format"), "must be HDF5")
    pf = f"{ext}.Print_field"
    yes = {k: r.get(f"{pf}.{k}") == "YES" for k in ("Vel", "Phi", "Charge", "Pressure", "Tau")}
    slabs = None
    if r.get(f"{pf}.Crop") == "YES":
        slabs = []
        for ax, n in zip("xyz", mesh.shape):
            path = f"{pf}.YES.Slab_{ax}"
            v = r.get(path)
            start, count, stride = (int(x) for x in (v if isinstance(v, (list, tuple)) else
                                    (r.get(f"{path}.start"), r.get(f"{path}.count"),
                                     r.get(f"{path}.stride"))))
            if not (0 <= start < n and 0 < stride < n and 0 < count <= n
                    and start + (count - 1) * stride < n):
                r.fail(path, [start, count, stride],
                       f"needs 0 <= start < {n}, 0 < stride < {n}, 0 < count <= {n} and "
                       f"start + (count-1) stride < {n} (N{ax.upper()} = {n})")
            slabs.append((start, count, stride))
        slabs = tuple(slabs)
    return FieldOutput(out_dir, name, kind, slabs, yes["Vel"], yes["Phi"], False,
                       yes["Pressure"], yes["Tau"])


# ---------------------------------------------------------------------------------------
# Checks of the whole input, before anything is built or written.

# Peak memory per mesh point, measured on 64^3 and 128^3 runs (fields, solver work arrays,
# restart text) with a margin; and per particle (state, records, SPM profile bookkeeping).
BYTES_PER_POINT = {"phase": 1200, "fluid": 600}
BYTES_PER_PARTICLE = 4000
MEMORY_ENV = "KAPSEL_PY_MEMORY_LIMIT_GB"


def memory_limit() -> float:
    """Bytes a run may use: the machine's physical memory, or ``$KAPSEL_PY_MEMORY_LIMIT_GB``."""
    env = os.environ.get(MEMORY_ENV)
    if env:
        try:
            gb = float(env)
        except ValueError:
            gb = float("nan")
        if not gb > 0 or not math.isfinite(gb):
            raise ConfigError("must be a positive number of gigabytes", "environment",
                              MEMORY_ENV, env)
        return gb * 2 ** 30
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return float("inf")


def _size(nbytes: float) -> str:
    for unit, scale in (("TB", 2 ** 40), ("GB", 2 ** 30), ("MB", 2 ** 20)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes / 2 ** 10:.3g} kB"


def check_memory(r: _Reader, mesh: Mesh, eq_type: str, n_particles: int) -> None:
    """Refuse a mesh (or particle count) whose run would not fit in memory: a typo such as
    NPX = 12 must not start a run that swaps for hours."""
    points = float(np.prod(mesh.shape, dtype=float))
    need = points * BYTES_PER_POINT["phase" if eq_type in PHASE_TYPES else "fluid"] \
        + float(n_particles) * BYTES_PER_PARTICLE
    limit = memory_limit()
    if need > limit:
        nx, ny, nz = mesh.shape
        r.fail("mesh", [mesh.NPX, mesh.NPY, mesh.NPZ],
               f"a {nx} x {ny} x {nz} mesh" + (f" with {n_particles} particles"
                                              if n_particles * BYTES_PER_PARTICLE > need / 2
                                              else "")
               + f" needs about {_size(need)} of memory for {eq_type}, more than the "
               f"{_size(limit)} available (physical memory, or ${MEMORY_ENV})")


def _check_is_input(doc: udf.UDFManager, input_path: str) -> None:
    where = input_path or doc.path or ""
    if doc.schema.item("constitutive_eq")[0] is None:
        raise ConfigError("is not a KAPSEL input: it neither defines nor includes the KAPSEL "
                          "schema (\\include{\"define.udf\"})", where)
    if doc.path and not doc.common_where:
        raise ConfigError("holds no input values (no \\begin{data} ... \\end{data} block)",
                          where)


def _check_user_positions(r: _Reader, user: np.ndarray, box: np.ndarray, A: float) -> None:
    """user_specify rows must be finite and the particles must not overlap deeply (closer
    than half the contact distance 2A, where the run's overlap guard would stop it)."""
    path = "switch.INIT_distribution.user_specify.Particles[]"
    bad = np.flatnonzero(~np.isfinite(user).all(axis=1))
    if bad.size:
        r.fail(path, user[bad[0]].tolist(), f"entry {bad[0]} is not finite")
    R = user[:, 0:3]
    for i in range(len(R) - 1):
        d = R[i + 1:] - R[i]
        d -= box * np.round(d / box)
        r2 = np.einsum("ij,ij->i", d, d)
        j = int(np.argmin(r2))
        if r2[j] < A * A:
            r.fail(path, [R[i].tolist(), R[i + 1 + j].tolist()],
                   f"particles {i} and {i + 1 + j} are {math.sqrt(r2[j]):.3g} apart, less than "
                   f"half the contact distance 2A = {2 * A:g} (they overlap)")


def _check_tolerance(r: _Reader, path: str, exponent: float) -> None:
    """The BiCGSTAB tolerance is 10^exponent: below 1 and reachable in double precision."""
    if exponent >= 0:
        r.fail(path, exponent, "is a base-10 exponent and must be negative (e.g. -9 for 1e-9)")
    if exponent < -15:
        r.fail(path, exponent, "is a base-10 exponent below -15: a relative residual under "
                               "1e-15 is out of reach in double precision (e.g. -9 for 1e-9)")


def _check_time_step(r: _Reader, time: TimeIncrement, fluid: Fluid, mesh: Mesh) -> None:
    """The time step the run would take must be a positive finite number."""
    if time.kind == "manual":
        return
    from .timestep import auto_dt
    try:
        dt = auto_dt(time.factor, fluid.RHO, fluid.ETA, mesh.DX)
    except (ZeroDivisionError, OverflowError):
        dt = float("nan")
    if not (dt > 0 and math.isfinite(dt)):
        r.fail("time_increment.auto.factor", time.factor,
               f"the automatic time step factor * RHO / (ETA (pi/DX)^2) with RHO = {fluid.RHO:g}, "
               f"ETA = {fluid.ETA:g}, DX = {mesh.DX:g} is not a finite positive time step")
