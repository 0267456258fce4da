"""The run configuration: the input UDF read into typed, validated, frozen dataclasses.

Every value is read by its UDF path (manual §6.1, tables 1-7).  A bad value raises
``ConfigError`` naming the file position, the path and the value; options the program does
not implement raise ``ConfigError`` naming the option (never a silent fallback).
"""
from __future__ import annotations

import math
import os
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

import udf
from udf import UDFError

from .particles.janus import read_spec as read_janus

from .typespec import TYPES, names, spec



def plain(value):
    """``value`` with numpy scalars and arrays turned into Python numbers and lists, so
    messages say 256, not np.float64(256.0)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return type(value)(plain(v) for v in value)
    return value


class ConfigError(Exception):
    """An invalid or unsupported input value: one line for the user."""

    def __init__(self, message: str, where: str = "", path: str = "", value=None):
        value = plain(value)
        self.path, self.value, self.where = path, value, where
        text = ""
        if where:
            text += where + ": "
        if path:
            text += path + (f" = {value!r}" if value is not None else "") + ": "
        super().__init__(text + message)


class InputErrors(ConfigError):
    """Every problem of an input, found before anything is built or written: str() is one
    line per problem."""

    def __init__(self, problems: list):
        self.problems = list(problems)
        first = self.problems[0]
        self.path, self.value, self.where = first.path, first.value, first.where
        Exception.__init__(self, "\n".join(str(p) for p in self.problems))


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
class Electrolyte:
    """constitutive_eq.Electrolyte (PHYSICS-EXTRA §6.1): ion species (one counterion species
    salt-free, or positive and negative ions with salt), their valences z_s and Onsager
    coefficients L_s, the dielectric constant, the initial ion profile and the external
    field E(t) = E (DC) or E sin(2 pi f t) (AC)."""
    dielectric: float
    init_profile: str              # 'Uniform' | 'Poisson_Boltzmann'
    salt: bool
    valency: tuple                 # z_s
    onsager: tuple                 # L_s
    debye_length: float = 0.0      # lambda_D (salt only), length units
    field_kind: str = "OFF"        # 'OFF' | 'DC' | 'AC'
    E: tuple = (0.0, 0.0, 0.0)
    frequency: float = 0.0


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
    janus: object = None           # kapsel.particles.janus.JanusSpec (spheres)

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
    quincke: object = None         # kapsel.particles.dipoles.Quincke (switch.quincke ON)
    dipoles: object = None         # kapsel.particles.dipoles.Dipoles (switch.multipole ON)
    SLIP_tol: float = 1e-3         # squirmer slip iteration (kapsel.particles.janus)
    SLIP_iter: int = 4
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
    electrolyte: Electrolyte | None = None
    input_path: str = ""

    @property
    def spec(self):
        """The type's kapsel.typespec.TypeSpec."""
        return spec(self.type)

    @property
    def is_fdm(self) -> bool:
        return self.spec.fdm

    @property
    def has_phase_field(self) -> bool:
        return self.spec.phase


# ---------------------------------------------------------------------------------------
# the sizes a parameter read by _Reader.positive / non_negative / finite may have (or 0)
SMALLEST, LARGEST = 1e-30, 1e30


class _Reader:
    """Reads values by path, remembers where they came from for messages, and collects the
    problems of the input so that the user gets all of them at once.

    ``fail`` raises (the check that found it cannot go on); ``block()`` catches it and
    records it, so the next, independent part of the input is still checked; ``report``
    records and goes on; ``unsupported`` collects features kapsel-py does not have, named
    together in one message by ``finish``."""

    def __init__(self, doc: udf.UDFManager):
        self.doc = doc
        self.problems: list = []
        self.unsupported: list = []     # (what, path, value, how to switch it off)

    def where(self, path: str) -> str:
        """'file:line:col' of the value at ``path`` itself (of the item holding it when the
        value cannot be located more closely)."""
        try:
            at = self.doc.value_where(path)
        except UDFError:
            at = None
        if at is not None:
            return f"{at[0]}:{at[1]}:{at[2]}"
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
            if e.line is not None:      # a bad value of the file (a select outside its choices)
                raise ConfigError(e.message, f"{e.file}:{e.line}:{e.column}") from None
            raise ConfigError(f"missing or unreadable in this input ({e.message})",
                              self.where(path), path) from None

    def has(self, path: str) -> bool:
        """Whether the input's schema (its define.udf version) has ``path``: sections newer
        than the define file are optional, as in the original (PHYSICS-EXTRA §1.2)."""
        try:
            self.doc.get(path)
            return True
        except UDFError as e:
            return e.line is not None   # present but bad: get() will say so

    def optional(self, path: str, default):
        return self.get(path) if self.has(path) else default

    def fail(self, path, value, message):
        raise ConfigError(message, self.where(path), path, value)

    def report(self, path, value, message) -> None:
        self.problems.append(ConfigError(message, self.where(path), path, value))

    def unsupported_feature(self, what: str, path: str, value, off: str) -> None:
        self.unsupported.append((what, path, plain(value), off))

    @contextmanager
    def block(self):
        try:
            yield
        except ConfigError as e:
            self.problems.append(e)

    def finish(self) -> None:
        """Raise every problem found (unsupported features first, in one line)."""
        problems = list(self.problems)
        if self.unsupported:
            what, path, value, off = self.unsupported[0]
            parts = []
            for what, path, value, off in self.unsupported:
                at = self.where(path)
                parts.append(f"{what} ({path} = {value!r} at {':'.join(at.split(':')[-2:])}; "
                             f"{off})")
            problems.insert(0, ConfigError(
                "not supported by kapsel-py (docs/running.md, 'Not supported'): " + "; ".join(parts),
                self.where(self.unsupported[0][1])))
        if len(problems) == 1:
            raise problems[0]
        if problems:
            raise InputErrors(problems)

    def positive(self, path):
        v = self.get(path)
        if not v > 0 or not math.isfinite(v):
            self.fail(path, v, "must be a positive number")
        return self._in_range(path, v)

    def non_negative(self, path):
        v = self.get(path)
        if not v >= 0 or not math.isfinite(v):
            self.fail(path, v, "must be zero or positive")
        return self._in_range(path, v)

    def finite(self, path):
        v = self.get(path)
        if not math.isfinite(v):
            self.fail(path, v, "must be a finite number")
        return self._in_range(path, v)

    def _in_range(self, path, v):
        """A parameter's size within [SMALLEST, LARGEST] (or 0): no physical input comes
        near the limits, and beyond them the set-up's arithmetic (a stencil's volume, the
        Debye length's ion densities, 1 / RHO ...) overflows or divides by zero."""
        if v != 0 and not SMALLEST <= abs(v) <= LARGEST:
            self.fail(path, v, f"must be 0 or between {SMALLEST:g} and {LARGEST:g} in size "
                               f"(beyond, the run's arithmetic overflows)")
        return v


def load(input_path: str) -> RunConfig:
    """Read and validate ``input_path``; raises UDFError (syntax) or ConfigError (values;
    InputErrors when there are several)."""
    doc = udf.UDFManager(input_path)
    return from_document(doc, input_path)


def from_document(doc: udf.UDFManager, input_path: str = "") -> RunConfig:
    """The run configuration of an input document.  Every check that needs no mesh or
    particle arrays is done here, cheap ones first; all problems are raised together
    (InputErrors), unsupported features named in one line."""
    r = _Reader(doc)
    _check_is_input(doc, input_path)
    eq_type = r.get("constitutive_eq.type")
    if eq_type not in TYPES:
        r.fail("constitutive_eq.type", eq_type, f"is not implemented in kapsel-py "
                                                f"(implemented: {', '.join(TYPES)})")
    base = f"constitutive_eq.{eq_type}"
    mesh, DX = _read_mesh(r, base)
    fluid = _read_fluid(r, base, eq_type)
    shear = _read_shear(r, base) if spec(eq_type).sheared else None
    electrolyte = None
    if spec(eq_type).ions:
        with r.block():
            electrolyte = _electrolyte(r, base)

    # ---- phase field -----------------------------------------------------------------
    phase = None
    if spec(eq_type).phase:
        with r.block():
            phase = _phase_field(r, base, eq_type, mesh)
    obj, species, particles, count = _read_particles(r, mesh, eq_type, DX, fluid)
    if electrolyte is not None and obj is not None:
        _check_electrolyte_objects(r, electrolyte, species, obj)
    inter = _read_interactions(r, obj, count)

    # ---- switches ----------------------------------------------------------------------
    switches = None
    if obj is not None:
        with r.block():
            switches = _switches(r, obj, species, mesh, particles, eq_type, inter)
    time = _read_time(r, fluid, mesh)
    output = _read_output(r, mesh, eq_type)
    resume = None
    with r.block():
        resume = Resume(r.get("resume.Calculation"))
    r.finish()
    return RunConfig(type=eq_type, mesh=mesh, fluid=fluid, particles=particles,
                     interactions=inter, switches=switches, time=time, output=output,
                     resume=resume, phase=phase, shear=shear, electrolyte=electrolyte,
                     input_path=input_path)


def _read_mesh(r: _Reader, base: str):
    """mesh.NP* and the type's DX: (Mesh or None, DX or None)."""
    nps, DX = [], None
    for ax in ("NPX", "NPY", "NPZ"):
        with r.block():
            p = f"mesh.{ax}"
            v = r.get(p)
            if v < 1:
                r.fail(p, v, "must be at least 1 (the mesh has 2^NP points per direction)")
            if v > 12:
                r.fail(p, v, "is too large (2^NP > 4096 points per direction)")
            nps.append(v)
    with r.block():
        DX = r.positive(f"{base}.DX")
    mesh = Mesh(*nps, DX=DX) if len(nps) == 3 and DX is not None else None
    return mesh, DX


def _read_fluid(r: _Reader, base: str, eq_type: str):
    """The type's fluid parameters (and NS_solver of the FDM types): Fluid or None."""
    fluid = None
    with r.block():
        fl = {}
        for name, check in (("RHO", r.positive), ("ETA", r.positive), ("kBT", r.non_negative),
                            ("alpha_v", r.non_negative), ("alpha_o", r.non_negative)):
            with r.block():
                fl[name] = check(f"{base}.{name}")
        if spec(eq_type).fdm:
            sp = f"{base}.NS_solver"
            fl["ns_solver"] = r.get(f"{sp}.type")
            if fl["ns_solver"] == "implicit_scheme":
                with r.block():
                    tol = r.finite(f"{sp}.implicit_scheme.tolerance")
                    _check_tolerance(r, f"{sp}.implicit_scheme.tolerance", tol)
                    fl["tolerance"] = 10.0 ** tol
                with r.block():
                    it = r.get(f"{sp}.implicit_scheme.maximum_iteration")
                    if it < 1:
                        r.fail(f"{sp}.implicit_scheme.maximum_iteration", it,
                               "must be at least 1")
                    fl["maximum_iteration"] = it
                vc = f"{sp}.implicit_scheme.viscosity_change"
                if spec(eq_type).phase and r.has(vc) and r.get(vc) == "ON":
                    fl["viscosity_change"] = True
                    fl["ETA_A"] = r.positive(f"{vc.rsplit('.', 1)[0]}.ON.ETA_A")
                    fl["ETA_B"] = r.positive(f"{vc.rsplit('.', 1)[0]}.ON.ETA_B")
        if spec(eq_type).ions and fl.get("kBT") == 0:
            # the Bjerrum length e^2 / (4 pi eps kBT) and the ions' Boltzmann factors
            # divide by kBT (PHYSICS-EXTRA §6)
            r.fail(f"{base}.kBT", 0.0, "must be positive for Electrolyte: the Bjerrum length "
                                       "and the ions' Boltzmann factors divide by kBT")
        if all(k in fl for k in ("RHO", "ETA", "kBT", "alpha_v", "alpha_o")):
            fluid = Fluid(**fl)

    return fluid


def _read_shear(r: _Reader, base: str):
    """External_field of the sheared types: Shear or None."""
    shear = None
    with r.block():
        ef = f"{base}.External_field"
        kind = r.get(f"{ef}.type")
        rate = r.finite(f"{ef}.{kind}.Shear_rate")
        freq = r.non_negative(f"{ef}.AC.Frequency") if kind == "AC" else 0.0
        shear = Shear(kind, rate, freq)
    return shear


def _read_particles(r: _Reader, mesh, eq_type: str, DX, fluid):
    """object_type, A, A_XI and the species, with the memory, fit and mass checks:
    (obj, species, Particles or None, number of particles).  A, A_XI and the positions are
    in units of DX: radius = A DX."""
    obj = None
    with r.block():
        obj = r.get("object_type.type")
    A = A_XI = None
    with r.block():
        A = r.positive("A")
    with r.block():
        A_XI = r.positive("A_XI")
    species = []
    if obj is not None:
        with r.block():
            species = _species(r, obj)
    scale = DX if DX is not None else 1.0
    particles = None
    if A is not None and A_XI is not None and obj is not None:
        particles = Particles(obj, tuple(species), A * scale, A_XI * scale)
    count = sum(s.particles for s in species)
    if mesh is not None:
        with r.block():     # before anything else about the mesh: a typo may ask for TBs
            check_memory(r, mesh, eq_type, count, *((particles.A, particles.A_XI)
                                                    if particles is not None else ()))
    if mesh is not None and particles is not None and count:
        with r.block():
            _check_particles_fit(r, mesh, particles)
        if fluid is not None:
            with r.block():
                _check_masses(r, obj, species, particles, fluid.RHO)
    return obj, species, particles, count


def _check_electrolyte_objects(r: _Reader, electrolyte, species, obj) -> None:
    """The charges, and what the original refuses with Electrolyte (PHYSICS-EXTRA §6.1):
    walls and janus propulsion."""
    with r.block():
        _check_charges(r, electrolyte, species, obj)
    # the original refuses walls and janus propulsion with Electrolyte (PHYSICS-EXTRA §6.1)
    if r.optional("switch.wall.type", "NONE") != "NONE":
        r.report("switch.wall.type", r.get("switch.wall.type"),
                 "walls are not allowed with Electrolyte (as in the original)")
    if obj == "spherical_particle":
        sp = "object_type.spherical_particle.Particle_spec"
        for i, s_ in enumerate(species):
            prop = r.optional(f"{sp}[{i}].janus_propulsion", "OFF")
            # TUMBLER / SQUIRMER: refused for every type but NS / SNS by janus.check_types
            if prop == "OBSTACLE" and s_.particles:
                r.report(f"{sp}[{i}].janus_propulsion", prop, "self-propelled particles "
                                                              "are not allowed with "
                                                              "Electrolyte (as in the "
                                                              "original)")


def _read_interactions(r: _Reader, obj, count):
    """EPSILON, LJ_powers, LJ_truncate and gravity (and what chains need): Interactions or
    None."""
    inter = None
    with r.block():
        lj = r.get("LJ_powers")
        inter = Interactions(EPSILON=r.non_negative("EPSILON"), LJ_powers=lj,
                             LJ_truncate=r.get("switch.LJ_truncate"), G=r.finite("gravity.G"),
                             G_direction=r.get("gravity.G_direction"))
        if obj == "chain" and count:
            # FENE bonds (kapsel.particles.chains) scale with EPSILON and need the LJ repulsion
            if inter.EPSILON <= 0:
                r.report("EPSILON", inter.EPSILON, "chains need EPSILON > 0 (the FENE bond "
                                                   "constant is 30 EPSILON / (2 A)^2)")
            if inter.LJ_truncate == "NONE":
                r.report("switch.LJ_truncate", "NONE", "chains need the excluded volume of the "
                                                       "LJ forces (ON or OFF)")
    return inter


def _read_time(r: _Reader, fluid, mesh):
    """time_increment (and its stability check): TimeIncrement or None."""
    time = None
    with r.block():
        kind = r.get("time_increment.type")
        if kind == "auto":
            time = TimeIncrement("auto", factor=r.positive("time_increment.auto.factor"))
        else:
            time = TimeIncrement("manual", delta_t=r.positive("time_increment.manual.delta_t"))
        if fluid is not None and mesh is not None:
            _check_time_step(r, time, fluid, mesh)
    return time


def _read_output(r: _Reader, mesh, eq_type: str):
    """output (GTS, Num_snap, UDF, AVS and its fields): Output or None."""
    output = None
    with r.block():
        gts, nsnap = r.get("output.GTS"), r.get("output.Num_snap")
        if gts < 1:
            r.report("output.GTS", gts, "must be at least 1 (steps between snapshots)")
        if nsnap < 1:
            r.report("output.Num_snap", nsnap,
                     "must be at least 1 (the run is GTS x Num_snap steps)")
        avs = r.get("output.AVS") == "ON"
        fields = _field_output(r, mesh, eq_type) if avs and mesh is not None else None
        output = Output(gts, nsnap, r.get("output.UDF") == "ON", avs, fields)
    return output


def _electrolyte(r: _Reader, base: str) -> Electrolyte:
    """constitutive_eq.Electrolyte (PHYSICS-EXTRA §6.1); alpha_v, alpha_o are not used."""
    eps = r.positive(f"{base}.Dielectric_cst")
    init = r.get(f"{base}.INIT_profile")
    salt = r.get(f"{base}.Add_salt.type") == "salt"
    kw = {}
    if salt:
        sp = f"{base}.Add_salt.salt"
        zp, zn = r.get(f"{sp}.Valency_positive_ion"), r.get(f"{sp}.Valency_negative_ion")
        if not zp > 0:
            r.report(f"{sp}.Valency_positive_ion", zp, "must be positive")
        if not zn < 0:
            r.report(f"{sp}.Valency_negative_ion", zn, "must be negative")
        valency = (float(zp), float(zn))
        onsager = (r.positive(f"{sp}.Onsager_coeff_positive_ion"),
                   r.positive(f"{sp}.Onsager_coeff_negative_ion"))
        kw["debye_length"] = r.positive(f"{sp}.Debye_length")
    else:
        sp = f"{base}.Add_salt.saltfree"
        z = r.get(f"{sp}.Valency_counterion")
        if z == 0 or not math.isfinite(z):
            r.report(f"{sp}.Valency_counterion", z, "must be a non-zero number")
        valency = (float(z),)
        onsager = (r.positive(f"{sp}.Onsager_coeff_counterion"),)
    ef = f"{base}.Electric_field"
    if r.get(f"{ef}.type") == "ON":
        kind = r.get(f"{ef}.ON.type")
        kw["field_kind"] = kind
        kw["E"] = tuple(float(r.finite(f"{ef}.ON.{kind}.E{ax}")) for ax in "xyz")
        if kind == "AC":
            kw["frequency"] = r.positive(f"{ef}.ON.AC.Frequency")
    return Electrolyte(eps, init, salt, valency, onsager, **kw)


def _check_charges(r: _Reader, el: Electrolyte, species: list, obj: str) -> None:
    """Surface_charge Z per species (PHYSICS-EXTRA §6.1): Z = 0 is refused (the original
    exits); salt-free, all particle charges have one sign, opposite to the counterions'."""
    spec = {"spherical_particle": "Particle_spec", "chain": "Chain_spec",
            "rigid": "Rigid_spec"}[obj]
    signs = set()
    for i, s in enumerate(species):
        if not s.particles:
            continue
        path = f"object_type.{obj}.{spec}[{i}].Surface_charge"
        if s.surface_charge == 0 or not math.isfinite(s.surface_charge):
            r.report(path, s.surface_charge, "must be non-zero for Electrolyte (the charge of "
                                             "one particle in units of e)")
            continue
        signs.add(s.surface_charge > 0)
        if not el.salt and s.surface_charge * el.valency[0] > 0:
            r.report(path, s.surface_charge, f"has the sign of the counterions (valency "
                                             f"{el.valency[0]:g}): salt-free, the counterions "
                                             f"must neutralise the particles")
    if not el.salt and len(signs) > 1:
        r.report(f"object_type.{obj}", "Surface_charge", "salt-free, all particle charges "
                                                         "must have one sign")


def _phase_field(r: _Reader, base: str, eq_type: str = "", mesh=None) -> PhaseField:
    cp = f"{base}.CH_solver"
    ch = r.get(f"{cp}.type")
    tol, it = 1e-9, 1000
    if ch == "implicit_scheme":
        with r.block():
            t = r.finite(f"{cp}.implicit_scheme.tolerance")
            _check_tolerance(r, f"{cp}.implicit_scheme.tolerance", t)
            tol = 10.0 ** t
        with r.block():
            it = r.get(f"{cp}.implicit_scheme.maximum_iteration")
            if it < 1:
                r.fail(f"{cp}.implicit_scheme.maximum_iteration", it, "must be at least 1")
    pot = r.get(f"{base}.Potential.type")
    pp = f"{base}.Potential.{pot}"
    common = dict(composition_ratio=r.finite(f"{pp}.composition_ratio"),
                  initial_fluctuation=r.non_negative(f"{pp}.initial_fluctuation"),
                  d=r.finite(f"{pp}.d"), w=r.finite(f"{pp}.w"),
                  alpha=r.non_negative(f"{pp}.alpha"), kappa=r.positive(f"{pp}.kappa"))
    # the surface terms the original reads when the define declares them (PHYSICS-EXTRA
    # §1.3); `k` of the shipped define.udf is never read by the original, nor here
    if r.has(f"{pp}.psi_dry") and r.get(f"{pp}.psi_dry") != 0:
        r.unsupported_feature("dry walls", f"{pp}.psi_dry", r.get(f"{pp}.psi_dry"),
                              "set it to 0")
    common.update(_surface_terms(r, pp, eq_type, mesh))
    if pot == "Landau":
        return PhaseField(ch, tol, it, pot, a=r.finite(f"{pp}.a"), b=r.finite(f"{pp}.b"),
                          **common)
    phase = PhaseField(ch, tol, it, pot, na=r.positive(f"{pp}.na"),
                       nb=r.positive(f"{pp}.nb"), chi=r.finite(f"{pp}.chi"), **common)
    c = phase.composition_ratio
    if not 0 < c < 1:
        r.fail(f"{pp}.composition_ratio", c,
               "must lie strictly between 0 and 1 for the Flory-Huggins potential "
               "(psi is a volume fraction)")
    return phase


def _species(r: _Reader, obj: str) -> list:
    """The species of the object type in use (the other types' specs are not read)."""
    doc = r.doc
    species = []
    if obj == "spherical_particle":
        sp = "object_type.spherical_particle.Particle_spec"
        for i in range(doc.size(f"{sp}[]")):
            p = f"{sp}[{i}]"
            with r.block():
                n = r.get(f"{p}.Particle_number")
                if n < 0:
                    r.fail(f"{p}.Particle_number", n, "must be zero or positive")
                species.append(Species(n, 1, r.positive(f"{p}.MASS_RATIO"),
                                       r.get(f"{p}.Surface_charge"),
                                       janus=read_janus(r, p, n)))
    elif obj == "chain":       # chains: the original forces janus propulsion OFF
        sp = "object_type.chain.Chain_spec"
        for i in range(doc.size(f"{sp}[]")):
            p = f"{sp}[{i}]"
            with r.block():
                nb, nc = r.get(f"{p}.Beads_number"), r.get(f"{p}.Chain_number")
                if nb < 1 or nc < 0:
                    r.fail(f"{p}", [nb, nc], "Beads_number must be >= 1 and Chain_number >= 0")
                species.append(Species(nc, nb, r.positive(f"{p}.MASS_RATIO"),
                                       r.get(f"{p}.Surface_charge")))
    else:
        sp = "object_type.rigid.Rigid_spec"
        for i in range(doc.size(f"{sp}[]")):
            p = f"{sp}[{i}]"
            with r.block():
                nb, nc = r.get(f"{p}.Beads_number"), r.get(f"{p}.Chain_number")
                if nb < 1 or nc < 0:
                    r.fail(f"{p}", [nb, nc], "Beads_number must be >= 1 and Chain_number >= 0")
                species.append(Species(nc, nb, r.positive(f"{p}.MASS_RATIO"),
                                       r.get(f"{p}.Surface_charge"),
                                       rigid_motion=r.get(f"{p}.Rigid_motion"),
                                       rigid_velocity=tuple(r.get(f"{p}.Rigid_velocity")),
                                       rigid_omega=tuple(r.get(f"{p}.Rigid_omega"))))
    return species


def _check_particles_fit(r: _Reader, mesh: Mesh, particles: Particles) -> None:
    """Particles of radius A DX must fit in the box N DX, and their volume fraction
    N 4/3 pi A^3 / V must not exceed 1 (the original's limit, init_particle.cxx
    Init_Particle; it lets rigid bodies and OBSTACLE spheres exceed it, whose beads or
    places may overlap by design).  How close a placement may put them is the placement's
    business (kapsel.particles.placement).  (Checked on the numbers alone: nothing is
    allocated.)"""
    box = mesh.box
    a = particles.A
    n = particles.count
    if n and particles.A <= particles.A_XI / 2:
        r.fail("A", r.get("A"), f"must exceed A_XI / 2 = {r.get('A_XI') / 2:g}: the smoothed "
                                f"profile (eqs 1-3) is 1 within A - A_XI/2 of the centre")
    if 2 * a >= box.min():
        r.fail("A", r.get("A"), f"a particle of diameter 2 A DX = {2 * a:g} does not fit in "
                                f"the box {_dims(box)}")
    fraction = n * (4 / 3) * math.pi * math.prod(a / L for L in box.tolist())
    may_overlap = particles.object_type == "rigid" or any(
        getattr(s.janus, "propulsion", "OFF") == "OBSTACLE" for s in particles.species)
    if fraction > 1 and not may_overlap:
        r.fail("object_type", n, f"{n} particles of radius A DX = {a:g} cannot fit in the box "
                                 f"{_dims(box)} (volume fraction {fraction:.3g} > 1, refused "
                                 f"as the original refuses it)")


def _check_masses(r: _Reader, obj: str, species: list, particles: Particles, rho) -> None:
    """Each bead's mass MASS_RATIO RHO 4/3 pi A^3 and moment of inertia 2/5 M A^2 must be
    finite numbers: they enter the particles' equations of motion and the energy E of
    every record (an infinite mass makes E NaN: an unreadable output.udf)."""
    if not particles.A < 1e100:
        return                          # refused already: it does not fit in the box
    unit = rho * (4.0 / 3.0) * math.pi * particles.A ** 3
    kind = {"spherical_particle": "Particle_spec", "chain": "Chain_spec",
            "rigid": "Rigid_spec"}.get(obj, "Particle_spec")
    for i, s in enumerate(species):
        mass = s.MASS_RATIO * unit
        inertia = 0.4 * mass * particles.A ** 2
        if not (math.isfinite(mass) and math.isfinite(inertia)):
            r.fail(f"object_type.{obj}.{kind}[{i}].MASS_RATIO", s.MASS_RATIO,
                   f"gives a particle mass MASS_RATIO RHO 4/3 pi A^3 = {mass:g} (moment of "
                   f"inertia {inertia:g}) that is not a finite number")


def _dims(box) -> str:
    return " x ".join(f"{float(x):g}" for x in box)


def _switches(r: _Reader, obj: str, species: list, mesh, particles, eq_type: str = "",
              inter=None) -> Switches:
    doc = r.doc
    count = sum(s.particles for s in species)
    box = mesh.box if mesh is not None else None
    dist = r.get("switch.INIT_distribution.type")
    rw = r.get("switch.INIT_distribution.random_walk.iteration")
    if dist == "random_walk" and rw < 0:
        r.report("switch.INIT_distribution.random_walk.iteration", rw,
                 "must be zero or positive")
    user = np.asarray(doc.getArray("switch.INIT_distribution.user_specify.Particles[]"),
                      dtype=float).reshape(-1, 13)
    user_path = "switch.INIT_distribution.user_specify.Particles[]"
    if obj != "spherical_particle" and dist in ("FCC", "BCC") and count:
        r.report("switch.INIT_distribution.type", dist,
                 f"lattice placement is for spherical particles; {obj} objects are placed by "
                 f"uniform_random / random_walk (random, non-overlapping) or user_specify")
    if dist == "user_specify" and count and len(user) < count:
        r.report(user_path, len(user),
                 f"user_specify needs one entry per particle ({count} particles)")
    elif dist == "user_specify" and count and box is not None and particles is not None:
        with r.block():
            groups = None
            if obj == "rigid":     # beads of one body may overlap by design (ex10)
                groups = np.repeat(np.arange(sum(s.number for s in species)),
                                   [s.beads for s in species for _ in range(s.number)])
            _check_user_positions(r, user[:count], box, particles.A, groups)
    if obj == "rigid" and count and box is not None and particles is not None:
        with r.block():
            _check_bodies_fit(r, species, user[:count] if dist == "user_specify" and
                              len(user) >= count else None, box, particles.A,
                              r.get("switch.INIT_orientation"))
    pin, pin_rot = (), ()
    if r.optional("switch.pin.type", "NO") == "YES":
        pin = tuple(r.get("switch.pin.YES.pin[]"))
        pin_rot = tuple(r.get("switch.pin.YES.pin_rot[]"))
        for p_, ids in (("switch.pin.YES.pin[]", pin), ("switch.pin.YES.pin_rot[]", pin_rot)):
            bad = [i for i in ids if not 0 <= i < count]
            if bad and not count:
                r.report(p_, bad, "pins particles but the input has none (Particle_number 0); "
                                  "set switch.pin to NO")
            elif bad:
                r.report(p_, bad, f"particle ids must lie in 0..{count - 1}")
        if obj == "rigid" and (pin or pin_rot):
            r.report("switch.pin.type", "YES", "pinning is for spherical particles and chain "
                                               "beads; hold rigid bodies with Rigid_motion fix "
                                               "or switch.free_rigid")
    free_rigid = ()
    if obj == "rigid" and r.optional("switch.free_rigid.type", "NO") == "YES":
        # read for spheres and chains too by the original, but only acting on rigid bodies
        rows = []
        for k, dof in enumerate(r.get("switch.free_rigid.YES.DOF[]")):
            sid, vel, om = dof
            if not 0 <= sid < len(species):
                r.report(f"switch.free_rigid.YES.DOF[{k}].spec_id", sid,
                         f"must be a Rigid_spec index, 0..{len(species) - 1}")
                continue
            rows.append((sid, tuple(x == "YES" for x in vel), tuple(x == "YES" for x in om)))
        free_rigid = tuple(rows)
    wall = _wall(r, eq_type, mesh, particles, inter)
    quincke, dipoles = _electric(r, obj, species, mesh)
    fix = tuple(r.get(f"switch.FIX_CELL.{ax}") == "ON" for ax in "xyz")
    if spec(eq_type).sheared:       # the original forces FIX_CELL.y ON for all four
        fix = (fix[0], True, fix[2])
    obl = r.optional("switch.ns_solver.OBL_INT", "linear")
    slip = _slip_switches(r, species)
    return Switches(ROTATION=r.get("switch.ROTATION") == "ON", init_distribution=dist,
                    random_walk_iterations=rw, user_particles=user,
                    init_orientation=r.get("switch.INIT_orientation"), fix_cell=fix,
                    pin=pin, pin_rot=pin_rot, free_rigid=free_rigid, OBL_INT=obl,
                    quincke=quincke, dipoles=dipoles, wall=wall, **slip)


def _slip_switches(r: _Reader, species) -> dict:
    """switch.SLIP_tol / SLIP_iter (read when present, required with squirmers) and the
    types and ROTATION self-propelled particles need (kapsel.particles.janus)."""
    from .particles.janus import check_types
    specs = [s.janus for s in species]
    check_types(r, r.get("constitutive_eq.type"), r.get("switch.ROTATION") == "ON", specs,
                [s.number for s in species], "object_type.spherical_particle.Particle_spec")
    squirm = any(j is not None and j.propulsion == "SQUIRMER" and s.number > 0
                 for j, s in zip(specs, species))
    out = {}
    for key, check in (("SLIP_tol", lambda v: v >= 0), ("SLIP_iter", lambda v: v >= 1)):
        path = f"switch.{key}"
        if r.has(path):
            v = r.get(path)
            if squirm and not check(v):
                r.fail(path, v, "must be >= 0" if key == "SLIP_tol" else "must be >= 1")
            if check(v):
                out[key] = v
        elif squirm:
            r.fail(path, None, "squirmers need it (the slip iteration); add it to switch")
    return out


def _surface_terms(r: _Reader, pp: str, eq_type: str, mesh: Mesh) -> dict:
    """The Cahn-Hilliard items of newer define.udf files (PHYSICS-EXTRA.md §1.3), each 0 when
    absent: z, w_wall, psi_0_p, psi_0_wall (uniform, or user_specify: one value per node of
    the wall plane, the same through the wall)."""
    out = {}
    for name in ("z", "w_wall", "psi_0_p"):
        if r.has(f"{pp}.{name}"):
            out[name] = r.finite(f"{pp}.{name}")
    if out.get("z", 0.0) != 0 and not spec(eq_type).surface_z:
        r.fail(f"{pp}.z", out["z"], f"is read by the original for "
                                    f"{' and '.join(names(surface_z=True))} only, not {eq_type} "
                                    f"(set it to 0)")
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


def _wall(r: _Reader, eq_type: str, mesh: Mesh, particles, inter: Interactions):
    """switch.wall (optional, NONE if absent): FLAT walls for the types the original allows
    them in, with XI < DH DX < L - 2 A (solid thicker than the interface, room for a
    particle between the walls)."""
    if not r.has("switch.wall.type") or r.get("switch.wall.type") == "NONE":
        return None
    if not spec(eq_type).walls:
        r.fail("switch.wall.type", r.get("switch.wall.type"),
               f"FLAT walls are available for {', '.join(names(walls=True))} only (as in the "
               f"original), not {eq_type}; set it to NONE")
    f = "switch.wall.FLAT"
    axis = {"X": 0, "Y": 1, "Z": 2}[r.get(f"{f}.axis")]
    DH = r.get(f"{f}.DH")
    L = mesh.box[axis]
    if particles is None:      # A or A_XI invalid (reported already): nothing to check
        A = xi = None
    else:
        A, xi = particles.A, particles.A_XI          # A DX, A_XI DX
    if A is not None and not xi < DH * mesh.DX < L - 2 * A:
        r.fail(f"{f}.DH", DH, f"the solid thickness DH DX = {DH * mesh.DX:g} must exceed the "
                              f"interface XI = {xi:g} and leave a gap wider than a particle "
                              f"(DH DX < L - 2A = {L - 2 * A:g})")
    kind = r.get(f"{f}.LJ_Params") if r.has(f"{f}.LJ_Params") else "AUTO"
    if kind == "MANUAL":
        m = f"{f}.MANUAL"
        return Wall(axis, DH, r.get(f"{m}.powers"), r.non_negative(f"{m}.EPSILON"),
                    r.get(f"{m}.truncate"), "MANUAL")
    return Wall(axis, DH, inter.LJ_powers, inter.EPSILON, "ON", "AUTO")


def _field_output(r: _Reader, mesh: Mesh, eq_type: str = "") -> FieldOutput:
    """output.ON (FORMAT-OUTPUT.md §2.1, §3.1): the crop is checked as the original does
    (0 <= start < N, 0 < stride < N, 0 < count <= N, start + (count-1) stride < N).
    Charge is forced off for every type but Electrolyte, which forces Pressure and Tau off
    (as the original, FORMAT-OUTPUT.md §3.1)."""
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
    el = spec(eq_type).ions
    return FieldOutput(out_dir, name, kind, slabs, yes["Vel"], yes["Phi"], el and yes["Charge"],
                       yes["Pressure"] and not el, yes["Tau"] and not el)


# ---------------------------------------------------------------------------------------
# Checks of the whole input, before anything is built or written.

# Peak memory of a run (fields, solver work arrays, restart writing): per mesh point by type
# (kapsel.typespec TypeSpec.bytes_per_point, bytes_per_point_particles), per particle and
# per point of its stencil below, plus the program itself (the interpreter and libraries).
# Measured 2026-12-02 with /usr/bin/time on 20-step runs of samples/input.udf (a restart
# written): Navier_Stokes 128^3 431 MB without particles, 494 / 597 MB with 1000 / 4000
# particles of A = 2 DX (184-point stencils), 586 MB with 1000 of A = 4 (720 points): each
# stencil point about 172 B, each particle 2.7 kB besides, the dense fields 14 B per point;
# an 8^3 run 92 MB (the program).  With a margin of about 10 %.  A run long enough for the
# compiled kernels (kapsel.mesh.compiled) also holds numba and its code generator, about
# 100 MB more: 2026-12-04, 20-step runs with KAPSEL_PY_COMPILED=1 at 128^3 with 1000
# particles of A = 2 (bench_vs_original.py): Navier_Stokes 592 MB (estimate 628), zigzag 657
# (668), Lees-Edwards 788 (828), Electrolyte 969 (1030).  With the kernels built ahead of
# time (no numba in the process; later the same day): Navier_Stokes 493 MB (estimate 538),
# zigzag 556 (578), Lees-Edwards 687 (738), Electrolyte 831 (896).
BYTES_PER_STENCIL_POINT = 190
BYTES_PER_PARTICLE = 3000           # state and records, besides the stencil
PROGRAM_BYTES = 200 * 2 ** 20       # the interpreter, numpy, scipy, h5py, pyFFTW, numba (RSS)
PROGRAM_BYTES_AOT = 110 * 2 ** 20   # the same with the kernels built ahead of time: no numba


def program_bytes() -> float:
    """The program's own resident memory: without numba and its code generator when the
    kernels are built ahead of time (kapsel.mesh.compiled.aot_slots; 2026-12-04, 128^3 with
    1000 particles: Navier_Stokes 592 -> 493 MB peak)."""
    from .mesh import compiled
    return PROGRAM_BYTES_AOT if compiled.aot_slots() else PROGRAM_BYTES
MEMORY_ENV = "KAPSEL_PY_MEMORY_LIMIT_GB"


def cgroup_memory_limit(proc_cgroup="/proc/self/cgroup", root="/sys/fs/cgroup") -> float:
    """The memory limit of this process's control group (a batch system's job, a container),
    the smallest over the group and its ancestors: cgroup v2 ``memory.max``, v1
    ``memory.limit_in_bytes``; inf when there is none or it cannot be read."""
    limit = float("inf")
    try:
        with open(proc_cgroup, encoding="ascii", errors="replace") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return limit
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        hid, controllers, path = parts
        if hid == "0" and controllers == "":
            base, name = root, "memory.max"                  # v2 (unified)
        elif "memory" in controllers.split(","):
            base, name = os.path.join(root, "memory"), "memory.limit_in_bytes"     # v1
        else:
            continue
        rel = path.strip("/")
        seen = set()
        while True:             # the group and its ancestors (a container shows its root)
            f = os.path.join(base, rel, name) if rel else os.path.join(base, name)
            if f not in seen:
                seen.add(f)
                try:
                    with open(f, encoding="ascii") as fh:
                        text = fh.read().strip()
                    if text and text != "max":
                        v = float(text)
                        if 0 < v < 2.0 ** 60:            # v1 says "no limit" by ~2^63
                            limit = min(limit, v)
                except (OSError, ValueError):
                    pass
            if not rel:
                break
            rel = os.path.dirname(rel)
    return limit


def memory_limit() -> float:
    """Bytes a run may use: ``$KAPSEL_PY_MEMORY_LIMIT_GB`` if set, else the machine's
    physical memory or, if smaller, the limit of the process's control group (cgroup_memory_limit:
    on a cluster node or in a container the job's limit, not the machine's)."""
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
        phys = float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        phys = float("inf")
    return min(phys, cgroup_memory_limit())


def _size(nbytes: float) -> str:
    for unit, scale in (("TB", 2 ** 40), ("GB", 2 ** 30), ("MB", 2 ** 20)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes / 2 ** 10:.3g} kB"


def memory_estimate(mesh: Mesh, eq_type: str, n_particles: int, A=None, xi=None,
                    program: bool = True) -> float:
    """Peak bytes of a run (the type's bytes per point and the per-particle figures above),
    with the program's own (``program``; without: the arrays alone); ``A``, ``xi``: the
    particles' radius and interface width (lengths), for their stencil size."""
    points = float(np.prod(mesh.shape, dtype=float))
    t = spec(eq_type)
    per_point = t.bytes_per_point + (t.bytes_per_point_particles if n_particles else 0)
    return (program_bytes() if program else 0.0) + points * per_point + float(n_particles) * (
        BYTES_PER_PARTICLE + BYTES_PER_STENCIL_POINT * _stencil_points(A, xi, mesh.DX))


def _stencil_points(A, xi, dx) -> int:
    """Grid points of one particle's profile stencil (kapsel.particles.profile.Stencil); a
    typical 720 (A = 4, XI = 2 cells) when the particles are not known or not valid."""
    if A is None or xi is None or not (A > 0.5 * xi > 0) or not dx or dx <= 0 \
            or not A + xi < 1e4 * dx:    # beyond any box: refused by _check_particles_fit
        return 720
    from .particles.profile import Stencil
    return Stencil(A, xi, dx).size


def check_memory(r: _Reader, mesh: Mesh, eq_type: str, n_particles: int, A=None,
                 xi=None) -> None:
    """Refuse a mesh (or particle count) whose run would not fit in memory: a typo such as
    NPX = 12 must not start a run that swaps for hours."""
    need = memory_estimate(mesh, eq_type, n_particles, A, xi)
    limit = memory_limit()
    if need > limit:
        nx, ny, nz = mesh.shape
        r.fail("mesh", [mesh.NPX, mesh.NPY, mesh.NPZ],
               f"a {nx} x {ny} x {nz} mesh" + (f" with {n_particles} particles"
                                              if need - memory_estimate(mesh, eq_type, 0)
                                              > need / 2
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


def _check_user_positions(r: _Reader, user: np.ndarray, box: np.ndarray, A: float,
                          groups=None) -> None:
    """user_specify rows must be finite and the particles must not overlap deeply (closer
    than half the contact distance 2A, where the run's overlap guard would stop it).
    ``groups``: the body of each bead (rigid bodies): beads of one body may overlap."""
    path = "switch.INIT_distribution.user_specify.Particles[]"
    bad = np.flatnonzero(~np.isfinite(user).all(axis=1))
    if bad.size:
        r.fail(path, user[bad[0]].tolist(), f"entry {bad[0]} is not finite")
    R = user[:, 0:3]
    if len(R) < 2 or not A > 0:
        return
    from .particles.cells import pairs_within
    i, j, d = pairs_within(R, box, A)          # i < j, sorted by (i, j)
    r2 = np.einsum("ij,ij->i", d, d)
    close = r2 < A * A
    if groups is not None:
        close &= groups[i] != groups[j]
    if close.any():
        k = int(np.flatnonzero(close)[0])      # the first pair, as a scan by i would find
        first = np.flatnonzero(close & (i == i[k]))
        k = int(first[np.argmin(r2[first])])   # its closest partner
        i, j = int(i[k]), int(j[k])
        what = f"particles {i} and {j}" if groups is None else \
            f"beads {i} and {j} of rigid bodies {int(groups[i])} and {int(groups[j])}"
        r.fail(path, [R[i].tolist(), R[j].tolist()],
               f"{what} are {math.sqrt(r2[k]):.3g} apart, less than half the contact "
               f"distance 2A = {2 * A:g} (they overlap)")


def _check_bodies_fit(r: _Reader, species, user, box: np.ndarray, A: float,
                      orientation: str) -> None:
    """Every rigid body must fit in the box: user_specify shapes by their actual extent
    (the span of their beads plus a diameter, along each axis), the program's straight
    rods of touching beads by their length 2A x beads (along x for space_align, in any
    direction otherwise)."""
    beads = [s.beads for s in species for _ in range(s.number)]
    if user is not None:
        at = 0
        for b, nb in enumerate(beads):
            R = user[at:at + nb, 0:3]
            at += nb
            extent = R.max(axis=0) - R.min(axis=0) + 2 * A
            if (extent >= box).any():
                r.fail("switch.INIT_distribution.user_specify.Particles[]", None,
                       f"rigid body {b} ({nb} beads of radius {A:g}) spans "
                       f"{_dims(extent)}, more than the box {_dims(box)} along "
                       f"{'xyz'[int(np.argmax(extent >= box))]}")
        return
    longest = max(beads)
    room = box[0] if orientation == "space_align" else box.min()
    if longest * 2 * A >= room:
        r.fail("object_type.rigid.Rigid_spec", None,
               f"a rigid body of {longest} beads of radius {A:g} is a rod of length "
               f"{longest * 2 * A:g}, which does not fit in the box {_dims(box)}"
               + (" along x (INIT_orientation space_align)" if orientation == "space_align"
                  else ""))


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
        dt = auto_dt(time.factor, fluid.RHO, fluid.ETA, mesh.DX, mesh.shape)
    except (ZeroDivisionError, OverflowError):
        dt = float("nan")
    if not (dt > 0 and math.isfinite(dt)):
        r.fail("time_increment.auto.factor", time.factor,
               f"the automatic time step factor RHO / (ETA KMAX2) (FORMAT.md) with "
               f"RHO = {fluid.RHO:g}, ETA = {fluid.ETA:g}, DX = {mesh.DX:g} is not a finite "
               f"positive time step")


def _electric(r: _Reader, obj: str, species, mesh: Mesh):
    """switch.quincke and switch.multipole (PHYSICS-EXTRA.md §4): (Quincke | None,
    Dipoles | None), checked as the original does (Quincke needs rigid bodies of one bead;
    multipole needs Dipole ON; QUINCKE dipoles need switch.quincke ON), plus what kapsel-py
    needs: QUINCKE dipoles with the field along Z (their Pz term and images are along z),
    mirror images with a FLAT Z wall (the electrode: images are reflected in its lower
    surface z = DH DX / 2)."""
    from .particles.dipoles import AXES, Dipoles, Quincke
    from .particles.ewald import tolerance_from_original
    bad = getattr(r, "report", None) or r.fail
    quincke = dipoles = None
    q = "switch.quincke"
    if r.has(f"{q}.type") and r.get(f"{q}.type") == "ON":
        if obj != "rigid" or any(s.beads != 1 for s in species):
            bad(f"{q}.type", "ON", "Quincke rollers are rigid bodies of one bead each: needs "
                                   "object_type rigid with Beads_number 1 (as the original)")
        quincke = Quincke(AXES[r.get(f"{q}.ON.e_dir")], AXES[r.get(f"{q}.ON.w_dir")],
                          float(r.finite(f"{q}.ON.torque_amp")))
    # the Lees-Edwards types too (the original's Force_OBL omits the Quincke torque and
    # refuses nothing: docs/physics-quincke.md), with the dipoles summed over the sheared lattice
    m = "switch.multipole"
    if not (r.has(f"{m}.type") and r.get(f"{m}.type") == "ON"):
        return quincke, None
    d = f"{m}.ON.Dipole"
    if not (r.has(f"{d}.type") and r.get(f"{d}.type") == "ON"):
        bad(f"{m}.type", "ON", f"multipole interactions need {d}.type ON (dipoles are the "
                               f"only multipoles the original reads)")
        return quincke, None
    e = f"{m}.ON.EwaldParams"
    alpha = r.positive(f"{e}.alpha")
    delta = r.get(f"{e}.delta")
    if not 0 < delta < 1:
        bad(f"{e}.delta", delta, "must lie between 0 and 1 (the reciprocal-space tolerance)")
        delta = 1e-8
    converge = r.positive(f"{e}.converge")
    eps = r.finite(f"{e}.epsilon")
    common = dict(magnitude=float(r.finite(f"{d}.ON.magnitude")),
                  tol=tolerance_from_original(alpha, delta, converge),
                  epsilon_surface=float(eps) if eps >= 0 else float("inf"))
    kind = r.get(f"{d}.ON.type")
    if kind == "FIXED":
        return quincke, Dipoles("FIXED", axis=AXES[r.get(f"{d}.ON.FIXED.dir")], **common)
    qd = f"{d}.ON.QUINCKE"
    if quincke is None:
        bad(f"{d}.ON.type", kind, "QUINCKE dipoles need switch.quincke.type ON (as the "
                                  "original)")
        return None, None
    if quincke.field_dir != AXES["Z"]:
        bad(f"{q}.ON.e_dir", r.get(f"{q}.ON.e_dir"), "QUINCKE dipoles need the field along "
            "Z: their static Pz part and mirror images are along z (as the original's)")
    mirror_z = None
    if r.get(f"{qd}.type") == "with_mirror_image":
        w = "switch.wall"
        if not (r.has(f"{w}.type") and r.get(f"{w}.type") == "FLAT"
                and r.get(f"{w}.FLAT.axis") == "Z"):
            bad(f"{qd}.type", "with_mirror_image", "mirror images need the electrode: "
                "switch.wall FLAT with axis Z (images are reflected in its lower surface)")
        else:
            mirror_z = 0.5 * r.get(f"{w}.FLAT.DH") * (mesh.DX if mesh is not None else 1.0)
    return quincke, Dipoles("QUINCKE", pz_factor=float(r.finite(f"{qd}.Pz_factor")),
                            mirror_z=mirror_z, **common)
