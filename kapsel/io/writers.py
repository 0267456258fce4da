"""Output writers: one small protocol, and the registry of a run's writers (WRITERS).

A writer is an object with

    open(snap, resumed)   at the start (snap: the initial kapsel.snapshot.Snapshot) or on
                          resuming from a restart (snap: the restored state); a writer that
                          already holds the snapshot of that step (written by the run being
                          continued) does not write it again
    write(snap)           at every snapshot (steps divisible by output.GTS)
    close(reason)         at the end of the run, on interruption and on failure
                          (reason "end", "interrupted", "failed"): flush and close

Each writer runs as an activity of the time loop (kapsel.activities.WriterActivity, on
the schedule of the snapshots) and reads what it needs from the snapshot by name
(kapsel.snapshot); a writer that needs
something the model does not offer is refused by ``make_writers`` before anything is written.
One module of kapsel/io per format: records.py (output.udf and the text logs), fields.py (the
FDM types' per-snapshot files), extended.py (output.AVS EXTENDED), avs.py (legacy AVS).
A new output quantity is a factory line in :data:`WRITERS` (a :class:`TableWriter` for a
table of numbers per snapshot; docs/extending.md).
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import numpy as np


class Writer:
    """Base of the writers (the protocol of the module docstring)."""

    def open(self, snap, resumed: bool) -> None:
        pass

    def write(self, snap) -> None:
        raise NotImplementedError

    def close(self, reason: str) -> None:
        pass

    def files(self, resumed: bool) -> list[tuple[str, str]]:
        """(directory, what) of the files this writer makes, for the banner and --check."""
        return []


class RecordWriter(Writer):
    """output.udf (kapsel.io.records.OutputUDF): a continued run appends its records (later
    records of the run being replaced are dropped) unless --overwrite."""

    def __init__(self, args, input_doc, comment=None):
        self.args, self.input_doc, self.comment = args, input_doc, comment
        self.output = None
        self._skip = None

    def open(self, snap, resumed):
        from .records import OutputUDF
        args = self.args
        append = resumed and os.path.exists(args.output) and not args.overwrite
        self.output = OutputUDF(args.output, args.define, self.input_doc, append=append,
                                comment=self.comment)
        if append:
            kept, dropped, last = self.output.truncate_after(snap.step)
            if self.output.torn_tail:
                print(f"#{args.output}: its last record was incomplete ({self.output.torn_tail} "
                      f"bytes, written when a run stopped); it was dropped", file=sys.stderr)
            if last is not None and abs(last - snap.step) <= 0.5:   # t is the record's step
                self._skip = snap.step
            if not args.quiet:
                print(f"#continuing at step {snap.step} (t = {snap.time:g}): appending "
                      f"to {args.output} ({kept} records kept"
                      + (f", {dropped} later ones dropped" if dropped else "") + ")",
                      file=sys.stderr)

    def files(self, resumed):
        args = self.args
        append = resumed and os.path.exists(args.output) and not args.overwrite
        return [(output_dir(args), os.path.basename(args.output)
                 + (" (records appended)" if append else " (records)"))]

    def write(self, snap):
        if snap.step == self._skip:
            self._skip = None
            return
        out = self.output
        items = dict(snap.get("record"))
        if snap.offers("shear"):
            items.update({k: v for k, v in snap.get("shear").items() if out.has_record_item(k)})
        if snap.offers("E_rot") and out.has_record_item("E_rot"):
            items["E_rot"] = float(np.sum(snap.get("E_rot")))
        out.add_record(snap.step, snap.time, snap.get("E"), snap.particles, items)


class _LogWriter(Writer):
    """A text table next to output.udf (kapsel.io.records.TableLog): a continued run keeps
    the rows up to the restart's step and appends."""

    def __init__(self, path):
        self.path = path
        self.log = None
        self._skip = None

    def _make(self, snap, append):
        raise NotImplementedError

    def open(self, snap, resumed):
        self.log = self._make(snap, resumed)
        if resumed and _last_row_step(self.path) == snap.step:
            self._skip = snap.step

    def write(self, snap):
        if snap.step == self._skip:
            self._skip = None
            return
        self._row(snap)

    def files(self, resumed):
        return [(os.path.dirname(self.path), os.path.basename(self.path))]


class ShearLogWriter(_LogWriter):
    """shear_stress.dat of the sheared types."""

    def _make(self, snap, append):
        from .records import ShearLog
        return ShearLog(self.path, append=append, until_step=snap.step)

    def _row(self, snap):
        self.log.write(snap.step, snap.time, snap.get("shear"))


class RotationalEnergyWriter(_LogWriter):
    """rotational_energy.dat of rigid bodies."""

    def _make(self, snap, append):
        from .records import RotationalEnergyLog
        return RotationalEnergyLog(self.path, len(snap.get("E_rot")), append=append,
                                   until_step=snap.step)

    def _row(self, snap):
        self.log.write(snap.step, snap.time, snap.get("E_rot"))


class ElectrolyteTable:
    """The Electrolyte free-energy table on stderr at every snapshot (FORMAT-OUTPUT.md §1.5):
    a header line, then ts and, as %.15g, total, ideal_gas, electrostatic free energy, the
    ions' total charge and the number of every species.  Silent with --quiet."""

    def __init__(self, stream=None):
        self.stream = stream

    def files(self, resumed: bool) -> list:
        return []

    def open(self, snap, resumed: bool) -> None:
        pass

    def write(self, snap) -> None:
        if self.stream is None:
            return
        fe = snap.get("free_energy")
        n = fe["numbers"]
        labels = ("6:total_counterion " if len(n) == 1 else
                  "6:total_positive_ion 7:total_negative_ion ")
        vals = [fe["total"], fe["ideal_gas"], fe["electrostatic"], fe["liquid_charge"], *n]
        print("#1:time 2:total 3:ideal_gas 4:electrostatic 5:liquid_charge " + labels,
              file=self.stream)
        print(f"{snap.step}" + "".join(f" {v:.15g}" for v in vals), file=self.stream)

    def close(self, reason: str) -> None:
        pass


def _last_row_step(path):
    try:
        from udf.files import open_regular
        with open_regular(path, "r", encoding="utf-8") as fh:
            rows = [ln for ln in fh if ln.strip() and not ln.startswith("#")]
        return int(rows[-1].split()[0]) if rows else None
    except (OSError, ValueError, IndexError):
        return None


def output_dir(args) -> str:
    """Where the writers put their files: the directory of output.udf."""
    return os.path.dirname(os.path.abspath(args.output))


class TableWriter(_LogWriter):
    """A table of one row per snapshot, ``step t`` then ``columns`` (kapsel.io.records.
    TableLog: rows appended whole, a continued run keeps its rows up to the restart);
    ``values(snap)`` gives a row's values.  What a new output quantity needs besides its
    factory line in :data:`WRITERS`."""

    def __init__(self, path, columns, values):
        super().__init__(path)
        self.columns, self.values = list(columns), values

    def _make(self, snap, append):
        from .records import TableLog
        return TableLog(self.path, self.columns, append=append, until_step=snap.step)

    def _row(self, snap):
        self.log.write_row(snap.step, snap.time, self.values(snap))


@dataclass(frozen=True)
class WriterContext:
    """What a writer factory may ask: the run's configuration, command line and input
    document, the model's first snapshot (what it offers), the directory of output.udf,
    whether to print the console block (not for --check) and output.udf's first line."""
    cfg: object
    args: object
    input_doc: object
    snap: object
    out_dir: str
    announce: bool = True
    comment: str | None = None


def _records(c):
    return RecordWriter(c.args, c.input_doc, c.comment) if c.cfg.output.UDF else None


def _snapshot_files(c):
    from .fields import SnapshotFiles
    files = SnapshotFiles(c.out_dir, c.cfg.type, c.cfg.mesh.shape, c.cfg.mesh.DX,
                          c.cfg.output.GTS, c.snap.n_particles)
    if not files.series:
        return None
    _require(c.snap, files.needs(), "the per-snapshot files")
    return files


def _fields(c):
    if c.cfg.output.fields is None:
        return None
    check_output(c.cfg, c.snap)
    return field_writer(c.cfg, c.args, c.snap, c.announce)


def _shear_table(c):
    return (ShearLogWriter(os.path.join(c.out_dir, "shear_stress.dat"))
            if c.snap.offers("shear") else None)


def _rotational_energy_table(c):
    return (RotationalEnergyWriter(os.path.join(c.out_dir, "rotational_energy.dat"))
            if c.snap.offers("E_rot") else None)


def _electrolyte_table(c):
    if not c.snap.offers("free_energy"):
        return None
    return ElectrolyteTable(None if getattr(c.args, "quiet", False) else sys.stderr)


#: the writer factories, in the order the writers write a snapshot:
#: ``factory(WriterContext) -> Writer or None`` (None: the run has nothing for it).
#: Adding an output quantity: its source in the model's snapshot (if it is new) and a
#: factory line here, e.g. a :class:`TableWriter` of it.
WRITERS = [_records, _snapshot_files, _fields, _shear_table, _rotational_energy_table,
           _electrolyte_table]


def make_writers(cfg, args, input_doc, snap, announce: bool = True, comment=None) -> list:
    """The writers a run needs (:data:`WRITERS`), from the configuration and what the model
    offers (``snap``: its first snapshot).  Raises kapsel.config.ConfigError for output the
    type cannot give.  ``announce``: print the original's console block of the field writer
    (not for --check); ``comment``: output.udf's first line (kapsel.io.records.run_comment)."""
    c = WriterContext(cfg, args, input_doc, snap, output_dir(args), announce, comment)
    return [w for w in (make(c) for make in WRITERS) if w is not None]


def field_directory(cfg, args) -> str:
    """output.ON.Out_dir; a relative one is taken from the directory of output.udf."""
    d = os.path.expanduser(cfg.output.fields.Out_dir)
    return d if os.path.isabs(d) else os.path.join(output_dir(args), d)


def _obstacles(snap):
    """Indices of the OBSTACLE janus particles (kapsel.particles.janus), written apart."""
    janus = getattr(snap.particles, "janus", None) if snap.n_particles else None
    return () if janus is None else tuple(int(i) for i in janus.obstacles)


def field_writer(cfg, args, snap, announce: bool = True):
    """The writer of output.AVS ON: EXTENDED (kapsel.io.extended) or legacy AVS
    (kapsel.io.avs)."""
    spec = cfg.output.fields
    directory = field_directory(cfg, args)
    species = snap.particles.species if snap.n_particles else []
    if spec.FileType == "EXTENDED":
        from .extended import ExtendedHDF5
        w = ExtendedHDF5(directory, spec, cfg.mesh.shape, cfg.mesh.DX, snap.dt,
                         cfg.output.GTS, snap.n_particles, species, snap.sheared,
                         obstacles=_obstacles(snap))
    else:
        from .avs import LegacyAVS
        w = LegacyAVS(directory, spec, cfg.mesh.shape, cfg.mesh.DX, cfg.output.Num_snap,
                      snap.n_particles, snap.particles, charge=cfg.spec.ions)
    if announce and not getattr(args, "quiet", False):
        print(w.console(), end="", file=sys.stderr)
    return w


# what each print switch needs, and its name in messages
_FIELD_NAMES = {"u": "velocity", "phi": "particle profile", "pressure": "pressure",
                "tau": "viscous stress"}


_FLAGS = {"u": "Vel", "pressure": "Pressure", "tau": "Tau"}


def check_output(cfg, model) -> None:
    """Refuse output the type cannot give (kapsel.config.ConfigError naming the switch), e.g.
    the pressure of the spectral Lees-Edwards type: never a zero-filled placeholder.
    ``model``: the model or its snapshot."""
    from ..config import ConfigError
    spec = cfg.output.fields
    if spec is None:
        return
    from ..snapshot import Snapshot
    snap = model if isinstance(model, Snapshot) else model.snapshot()
    if spec.FileType == "EXTENDED":
        for flag, name in (("Vel", "u"), ("Pressure", "pressure"), ("Tau", "tau")):
            if getattr(spec, flag) and not snap.offers(name):
                raise ConfigError(f"{cfg.type} does not compute the {_FIELD_NAMES[name]} "
                                  f"field in kapsel-py; set it to NO",
                                  path=f"output.ON.EXTENDED.Print_field.{flag}", value="YES")
        return
    missing = [n for n in ("u", "pressure", "tau") if not snap.offers(n)]
    if missing:
        raise ConfigError(f"the legacy AVS files hold the {', '.join(_FIELD_NAMES[n] for n in missing)}, "
                          f"which {cfg.type} does not compute in kapsel-py; use EXTENDED and "
                          f"switch {', '.join(_FLAGS[n] for n in missing)} off",
                          path="output.ON.FileType", value=spec.FileType)


def _require(snap, names, what):
    missing = sorted(n for n in names if not snap.offers(n))
    if missing:
        raise RuntimeError(f"{what} need {', '.join(missing)}, which this model does not offer")


def new_run_targets(cfg, args) -> list:
    """(what, path) of the files a new run would replace besides -O and -R (the CLI refuses
    to replace them without --overwrite)."""
    from .fields import series_for
    out_dir = output_dir(args)
    out = [(f"the field series {s.name}.xmf", os.path.join(out_dir, s.name + ".xmf"))
           for s in series_for(cfg.type, cfg.particles.count)]
    spec = cfg.output.fields
    if spec is not None:
        ext = ".h5" if spec.FileType == "EXTENDED" else ".fld"
        path = os.path.join(field_directory(cfg, args), spec.Out_name + ext)
        out.append((f"the output.AVS file {path}", path))
    if cfg.spec.sheared:                    # the tables of make_writers, from the input
        out.append(("the table shear_stress.dat", os.path.join(out_dir, "shear_stress.dat")))
    if cfg.particles.object_type == "rigid" and cfg.particles.count:
        out.append(("the table rotational_energy.dat",
                    os.path.join(out_dir, "rotational_energy.dat")))
    return out
