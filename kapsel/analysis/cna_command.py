"""``kapsel-py analyze cna``: CNA labels of the particles of output.udf records, or of the
frames of an XYZ / LAMMPS dump file; counts per record on stdout, labels to CSV or HDF5."""
from __future__ import annotations

import sys
import warnings

import numpy as np

from . import cna as C
from .positions import Frame, read_positions


def udf_frames(path: str, record: str):
    """Frames (positions, periodic box) of the records of a kapsel output.udf."""
    import udf
    u = udf.UDFManager(path)
    eq = u.get("constitutive_eq.type")
    dx = u.get(f"constitutive_eq.{eq}.DX")
    box = np.array([2 ** u.get(f"mesh.{a}") for a in ("NPX", "NPY", "NPZ")], float) * dx
    recs = range(u.totalRecord()) if record == "all" else [int(record)]
    frames = []
    for r in recs:
        u.jump(r)
        R = u.getArray("Particles[].R") if u.size("Particles[]") else np.zeros((0, 3))
        frames.append((r, Frame(np.mod(R, box), box, np.zeros(3))))
    return frames


def default_cutoff(positions, box) -> float:
    """0.5 (1 + sqrt 2) times the median nearest-neighbour distance: between the first and
    second shells of FCC/HCP.  BCC needs --cutoff between its second and third shells."""
    from scipy.spatial import cKDTree
    tree = cKDTree(positions, boxsize=box) if box is not None else cKDTree(positions)
    d, _ = tree.query(positions, k=2)
    return 0.5 * (1 + np.sqrt(2)) * float(np.median(d[:, 1]))


def _frame_problem(fr) -> str | None:
    """Why a frame cannot be analysed (None when it can): coordinates and box lengths must
    be finite, the box lengths positive."""
    if not np.isfinite(fr.positions).all():
        return "a coordinate is not a finite number"
    if fr.box is not None:
        L = np.asarray(fr.box, dtype=float)
        if not (np.isfinite(L).all() and (L > 0).all()):
            return f"the box {L.tolist()} has a length that is not a positive number"
    return None


def _wrapped(fr):
    """The frame's positions wrapped into its periodic box (as kapsel.analysis.cna does)."""
    if fr.box is None:
        return fr.positions
    L = np.broadcast_to(np.asarray(fr.box, dtype=float), (3,))
    per = np.broadcast_to(np.asarray(fr.periodic, dtype=bool), (3,))
    p = np.array(fr.positions, dtype=float, copy=True)
    p[:, per] = np.mod(p[:, per], L[per])
    p[:, per] = np.where(p[:, per] >= L[per], 0.0, p[:, per])
    return p


def run(a) -> int:
    from .cli import _output_problem
    if a.labels:
        problem = _output_problem(a.labels)
        if problem:
            print(f"kapsel-py analyze cna: error: --labels {a.labels}: {problem}",
                  file=sys.stderr)
            return 2
    try:
        if a.file.endswith(".udf"):
            frames = udf_frames(a.file, a.record)
        else:
            all_frames = read_positions(a.file)
            sel = range(len(all_frames)) if a.record == "all" else [int(a.record)]
            frames = [(i, all_frames[i]) for i in sel]
    except (ValueError, IndexError, OSError) as e:
        print(f"kapsel-py analyze cna: error: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # UDFError and friends: one line, no traceback
        print(f"kapsel-py analyze cna: error: {e}", file=sys.stderr)
        return 2
    rows = []
    print("record " + " ".join(f"{name:>8}" for name in C.NAMES.values()) + "   cutoff")
    for rec, fr in frames:
        if len(fr.positions) < 2:
            print(f"{rec:6d}  (fewer than 2 particles)")
            continue
        problem = _frame_problem(fr)
        if problem:
            print(f"kapsel-py analyze cna: error: record {rec}: {problem}", file=sys.stderr)
            return 2
        try:
            rc = a.cutoff or default_cutoff(_wrapped(fr), fr.box)
        except ValueError as e:
            print(f"kapsel-py analyze cna: error: record {rec}: {e}", file=sys.stderr)
            return 2
        if not (np.isfinite(rc) and rc > 0):
            why = "a given --cutoff" if a.cutoff else "particles on top of each other? give --cutoff"
            print(f"kapsel-py analyze cna: error: record {rec}: the cutoff {rc:g} is not a "
                  f"positive number ({why})",
                  file=sys.stderr)
            return 2
        if fr.box is not None and np.any(fr.periodic) and \
                2 * rc >= float(np.min(np.asarray(fr.box)[np.asarray(fr.periodic)])):
            L = float(np.min(np.asarray(fr.box)[np.asarray(fr.periodic)]))
            how = "the given --cutoff" if a.cutoff else "the default cutoff (from the " \
                "nearest-neighbour distance)"
            print(f"kapsel-py analyze cna: error: record {rec}: {how} {rc:.4g} is not below "
                  f"half the periodic box ({L:.4g} / 2): the box is too small for CNA; give "
                  f"--cutoff below {L / 2:.4g} or a larger box", file=sys.stderr)
            return 2
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            try:
                labels = C.cna(fr.positions, fr.box, rc, periodic=fr.periodic)
            except ValueError as e:
                print(f"kapsel-py analyze cna: error: record {rec}: {e}", file=sys.stderr)
                return 2
        for item in w:
            print(f"warning (record {rec}): {item.message}", file=sys.stderr)
        cnt = C.counts(labels)
        print(f"{rec:6d} " + " ".join(f"{cnt.get(n, 0):8d}" for n in C.NAMES.values())
              + f"   {rc:.4g}")
        rows.append((rec, labels))
    if a.labels:
        try:
            _write_labels(a.labels, rows)
        except OSError as e:
            from udf.files import write_failure
            print(f"kapsel-py analyze cna: error: cannot write {a.labels}: "
                  f"{write_failure(e)}", file=sys.stderr)
            return 1
        print(f"labels written to {a.labels}")
    return 0


def _write_labels(path, rows) -> None:
    """The labels as HDF5 (.h5, .hdf5) or CSV, atomically (kapsel.io: a killed or failed
    write leaves the old file or none; what killed writes left is removed first)."""
    from udf.files import remove_temporaries_of
    remove_temporaries_of(path)
    if path.endswith((".h5", ".hdf5")):
        from ..io.h5file import write_h5

        def fill(f):
            for rec, labels in rows:
                f[f"record_{rec}"] = labels
            f.attrs["names"] = [f"{k}={v}" for k, v in C.NAMES.items()]
        write_h5(path, fill)
        return
    lines = ["record,particle,label,structure\n"]
    for rec, labels in rows:
        lines += [f"{rec},{i},{lab},{C.NAMES[lab]}\n" for i, lab in enumerate(labels.tolist())]
    from ..io.atomic import atomic_write_text
    atomic_write_text(path, "".join(lines))
