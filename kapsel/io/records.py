"""output.udf: the input's data as the common part, then one record per snapshot.

Each record holds ``E`` (total kinetic energy of fluid and particles), ``t`` (time, in units
of tau) and ``Particles[]`` with every ``outParticle`` member the define.udf lists (R, R_raw,
v, q, omega, f_hydro, torque_hydro, f_r, torque_r, f_slip, torque_slip); with rigid bodies
(object_type rigid) also ``RigidParticles[]``, one entry per body: centre of mass R, R_raw,
V, q, Omega, and the bead forces / torques summed about the centre (kapsel.particles.rigid).
The schema has no item for the bodies' rotational energy (it is part of ``E``; ``kapsel-py
analyze erotate`` computes it per body from the records).  ``float`` values
are written at single precision, as OCTA stores them.

The header and common part are written once (atomically); each record is then appended with
one write call and flushed, so an interrupted run keeps every complete record.
"""
from __future__ import annotations

import os

import numpy as np

from udf import UDFManager, atomic_write_text
from udf.files import open_regular

from .atomic import append_whole  # noqa: F401  (tests patch records.os.write)
from udf.schema import Struct, leaf_count, leaf_slice

# outParticle / sParticle member -> ParticleState attribute.  f_hydro1 and torque_hydro1
# (intermediate values of the original's integrator) hold the step's hydrodynamic force.
OUT_FIELDS = {"R": "R", "R_raw": "R_raw", "v": "v", "v_old": "v_old", "q": "q",
              "q_old": "q_old", "omega": "omega", "omega_old": "omega_old",
              "f_hydro": "f_hydro", "f_hydro_previous": "f_hydro_previous",
              "f_hydro1": "f_hydro", "torque_hydro": "torque_hydro",
              "torque_hydro_previous": "torque_hydro_previous", "torque_hydro1": "torque_hydro",
              "f_r": "f_r", "fr": "f_r", "fr_previous": "f_r_previous",
              "torque_r": "torque_r", "torque_r_previous": "torque_r_previous",
              "f_slip": "f_slip", "f_slip_previous": "f_slip_previous",
              "torque_slip": "torque_slip", "torque_slip_previous": "torque_slip_previous"}


def particle_table(state, struct: Struct) -> np.ndarray:
    """The (N, leaf_count) array of a particle record type, filled by member name."""
    table = np.zeros((state.n, leaf_count(struct)))
    for m in struct.members:
        if m.name not in OUT_FIELDS:
            raise ValueError(f"the define file's particle class has a member {m.name!r} "
                             f"that kapsel-py does not know")
    for m in struct.members:
        off, cnt, _ = leaf_slice(struct, [m.name])
        attr = OUT_FIELDS.get(m.name)
        if attr is not None and hasattr(state, attr):
            table[:, off:off + cnt] = getattr(state, attr)
    return table


class OutputUDF:
    """Writer of output.udf following the schema of ``define_path``."""

    def __init__(self, path: str, define_path: str, input_doc: UDFManager, append=False,
                 comment: str = ""):
        """``comment``: a first line (without //) for a new file: kapsel-py writes the run
        id and the seed there (``run_id`` reads it back)."""
        self.path = path
        self.torn_tail = 0
        self.doc = UDFManager(schema_from=define_path)
        self.doc.single_precision_records = True
        for name, value in input_doc.common.items():
            if name in self.doc.schema.global_items:
                self.doc.common[name] = value
        m, _ = self.doc.schema.item("Particles")
        self.particle_type = m.type if m is not None else None
        m, _ = self.doc.schema.item("RigidParticles")
        self.rigid_type = m.type if m is not None else None
        if not append or not os.path.exists(path):
            head = [f"// {comment}\n"] if comment else []
            atomic_write_text(path, head + self.doc.pieces())

    def truncate_after(self, step: int) -> tuple[int, int, float | None]:
        """Drop the records later than ``step`` (those of a run being continued from an
        earlier restart; a record's ``t`` is its step, as the original writes it); returns
        (records kept, records dropped, t of the last kept record or None).  The kept
        bytes are not rewritten except for the cut, which is
        atomic."""
        import warnings
        from udf.manager import TornTailWarning
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TornTailWarning)
            old = UDFManager(self.path)
        self.torn_tail = old.torn_tail           # the caller says so
        times = []
        for n in range(old.totalRecord()):
            old.jump(n)
            times.append(float(old.get("t")))
        keep = sum(1 for t in times if t <= step + 0.5)   # t: a step, at single precision
        if keep < len(times) or old.torn_tail:
            with open_regular(self.path) as fh:
                data = fh.read()
            starts, i = [], data.find(b"\\begin{record}")
            while i >= 0:
                starts.append(i)
                i = data.find(b"\\begin{record}", i + 1)
            if len(starts) != len(times) + (1 if old.torn_tail else 0):
                raise ValueError(f"{self.path}: cannot locate its records")
            atomic_write_text(self.path, data[:starts[keep]].decode("utf-8"))
        return keep, len(times) - keep, (times[keep - 1] if keep else None)

    def has_record_item(self, name: str) -> bool:
        """Whether the define file declares ``name`` as a record item."""
        m, is_global = self.doc.schema.item(name)
        return m is not None and not is_global

    def put(self, name: str, value) -> None:
        """Set a common (global) item, e.g. an updated resume section."""
        self.doc.put(value, name)

    def add_record(self, step: int, time: float, energy: float, particles=None,
                   extra: dict | None = None) -> None:
        """Append one record (``extra``: further record items by name, e.g. PSI)."""
        self.doc.records = []
        self.doc.newRecord(f"step {step}")
        self.doc.put(float(energy), "E")
        self.doc.put(float(step), "t")   # the original's t: the step number (FORMAT.md)
        if particles is not None and particles.n and self.particle_type is not None:
            self.doc.put(particle_table(particles, self.particle_type), "Particles[]")
        bodies = getattr(getattr(particles, "constraints", None), "state", None)
        if bodies is not None and bodies.n and self.rigid_type is not None:
            self.doc.put(particle_table(bodies, self.rigid_type), "RigidParticles[]")
        for name, value in (extra or {}).items():
            self.doc.put(value, name)
        text = "".join(map(str, self.doc.record_pieces(self.doc.records[0])))
        append_whole(self.path, text.encode("utf-8"))
        self.doc.records = []


RUN_MARK = "kapsel-py run "


def run_comment(run_id: str, seed: int) -> str:
    return f"{RUN_MARK}{run_id}, random seed {seed} (rerun with --seed {seed} to reproduce)"


def _run_mark(path: str) -> str | None:
    """What follows RUN_MARK on the first line of an output.udf written by kapsel-py, else
    None."""
    try:
        with open_regular(path) as fh:
            first = fh.readline(400).decode("utf-8", "replace")
    except OSError:
        return None
    return first[3 + len(RUN_MARK):] if first.startswith("// " + RUN_MARK) else None


def run_id(path: str) -> str | None:
    """The run id in the first line of an output.udf written by kapsel-py, else None."""
    mark = _run_mark(path)
    return (mark.split(",")[0].strip() or None) if mark is not None else None


def run_line(path: str) -> tuple[str, int] | None:
    """(run id, seed) named by the first line of an output.udf written by kapsel-py, else
    None."""
    mark = _run_mark(path)
    if mark is None:
        return None
    head, _, rest = mark.partition(", random seed ")
    try:
        return head.strip(), int(rest.split()[0])
    except (ValueError, IndexError):
        return None


class TableLog:
    """A text table next to output.udf, one line per snapshot (``step t`` then ``columns``);
    for quantities the define.udf records have no place for.  Each row is appended whole
    (kapsel.io.atomic.append_whole: one write, synced, cut back if it fails)."""

    def __init__(self, path: str, columns, append: bool = False, until_step=None):
        """``append`` (a continued run): keep the lines up to ``until_step``, drop later
        ones (of an earlier run that went further) and a torn last line (a run killed
        while writing it; said on stderr)."""
        self.path = path
        self.header = "# step t " + " ".join(columns) + "\n"
        self.torn_tail = 0
        if not append or not os.path.exists(path):
            atomic_write_text(path, self.header)
            return
        with open_regular(path) as fh:
            data = fh.read()
        body, torn = data, b""
        if data and not data.endswith(b"\n"):
            cut = data.rfind(b"\n") + 1
            body, torn = data[:cut], data[cut:]
        self.torn_tail = len(torn)
        lines = body.decode("utf-8", "replace").splitlines(keepends=True)
        keep = [ln for ln in lines if ln.startswith("#") or not ln.strip()
                or _row_step(ln) is not None
                and (until_step is None or _row_step(ln) <= until_step)]
        if torn or len(keep) != len(lines):
            atomic_write_text(path, "".join(keep) or self.header)
        if torn:
            import sys
            print(f"#{path}: its last line was incomplete ({len(torn)} bytes, written when a "
                  f"run stopped); it was dropped", file=sys.stderr)

    def write_row(self, step: int, time: float, values) -> None:
        row = (f"{step} {time:.10g} " + " ".join(f"{float(v):.10g}" for v in values) + "\n")
        append_whole(self.path, row.encode("utf-8"))


def _row_step(line: str):
    """The step of a complete table row, or None for a line that is not one."""
    parts = line.split()
    try:
        return int(parts[0]) if len(parts) >= 2 and line.endswith("\n") else None
    except ValueError:
        return None


class ShearLog(TableLog):
    """``shear_stress.dat``: step, t, applied strain, shear rate, shear stress sigma_xy."""

    COLUMNS = ("Shear_strain", "Shear_rate", "Shear_stress")

    def __init__(self, path: str, append: bool = False, until_step=None):
        super().__init__(path, self.COLUMNS, append, until_step)

    def write(self, step: int, time: float, items: dict) -> None:
        self.write_row(step, time, [items[c] for c in self.COLUMNS])


class RotationalEnergyLog(TableLog):
    """``rotational_energy.dat``: step, t, the total rotational energy of the rigid bodies
    E_rot (spec 002 eq 7) and E_rot,g of each body g (eqs 3-6)."""

    def __init__(self, path: str, bodies: int, append: bool = False, until_step=None):
        cols = ["E_rot"] + [f"E_rot[{g}]" for g in range(bodies)]
        super().__init__(path, cols, append, until_step)

    def write(self, step: int, time: float, energies) -> None:
        e = np.asarray(energies, dtype=float)
        self.write_row(step, time, [e.sum(), *e])
