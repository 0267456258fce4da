"""``kapsel-py analyze ...``: the analyses shipped with kapsel-py.

    kapsel-py analyze sq OUTPUT_DIR [--dx 1.0] [--plot sq.png] [--table sq.txt] [--octant]
    kapsel-py analyze cna OUTPUT.udf|positions.xyz|dump.lammpstrj [--cutoff r] [--record n|all]
    kapsel-py analyze erotate OUTPUT.udf
    kapsel-py analyze show RUN_DIR [--record -1|I|all] [--z K] [--udf output.udf] [--out DIR]
"""
from __future__ import annotations

import argparse
import math
import os
import sys


def _fail(msg: str, code: int = 2) -> int:
    """One line on stderr; exit 2 (what was asked cannot be done) or 1 (a write failed)."""
    print(f"kapsel-py analyze: error: {msg}", file=sys.stderr)
    return code


def _write_failed(path, e: OSError) -> int:
    from udf.files import write_failure
    return _fail(f"cannot write {path}: {write_failure(e)}", 1)


def cmd_sq(a) -> int:
    from .structure_factor import (characteristic_wavenumber, read_psi, snapshot_files,
                                   snapshot_times, structure_factor)
    if not os.path.isdir(a.directory):
        return _fail(f"{a.directory}: not a directory")
    if not (a.dx > 0 and math.isfinite(a.dx)):
        return _fail(f"--dx {a.dx}: the grid spacing must be a positive number")
    table = a.table or os.path.join(a.directory, "sq.txt")
    plot = a.plot or os.path.join(a.directory, "sq.png")
    for flag, path in (("--table", table), ("--plot", plot)):
        problem = _output_problem(path)
        if problem:
            return _fail(f"{flag} {path}: {problem}")
    files = snapshot_files(a.directory)
    if not files:
        return _fail(f"no orderparam_<n>.h5 files in {a.directory}")
    try:
        times = snapshot_times(a.directory)
    except (OSError, UnicodeDecodeError) as e:
        print(f"kapsel-py analyze: warning: the snapshot times are not read ({e})",
              file=sys.stderr)
        times = {}
    rows = []
    curves = []
    for f in files:
        n = int(os.path.basename(f).split("_")[1].split(".")[0])
        try:
            psi = read_psi(f)
        except (OSError, KeyError, ValueError, StopIteration) as e:
            print(f"kapsel-py analyze: warning: {f} is skipped: it cannot be read "
                  f"({str(e).splitlines()[0] if str(e) else type(e).__name__}; a run "
                  f"stopped while writing it?)", file=sys.stderr)
            continue
        q, s, _ = structure_factor(psi, a.dx, octant=a.octant)
        q1 = characteristic_wavenumber(q, s)
        rows.append((n, times.get(n, float("nan")), q1))
        curves.append((n, q, s))
    lines = ["# snapshot  time  q1 (characteristic wavenumber)  domain size 2pi/q1"]
    lines += [f"{n:8d} {t:12.6g} {q1:16.10g} {2 * 3.141592653589793 / q1:14.6g}"
              for n, t, q1 in rows]
    lines.append("")
    lines.append("# S(q) per snapshot: snapshot q S(q)")
    for n, q, s in curves:
        lines += [f"{n:8d} {qq:14.6g} {ss:14.6g}" for qq, ss in zip(q, s)]
    if not rows:
        return _fail(f"no readable orderparam_<n>.h5 file in {a.directory}")
    text = "\n".join(lines) + "\n"
    from udf.files import remove_temporaries_of

    from ..io.atomic import atomic_write_text
    try:
        remove_temporaries_of(table)
        atomic_write_text(table, text)
    except OSError as e:
        return _write_failed(table, e)
    print("\n".join(lines[:len(rows) + 1]))
    print(f"S(q) table written to {table}")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot (pip install matplotlib)", file=sys.stderr)
        return 0
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for n, q, s in curves:
        ax.plot(q, s, label=f"snapshot {n}")
    ax.set_xlabel("q [1/DX]")
    ax.set_ylabel("S(q)")
    ax.set_yscale("log")
    if len(curves) <= 12:
        ax.legend(fontsize=7)
    fig.tight_layout()
    try:
        save_figure(fig, plot, dpi=120)
    except OSError as e:
        return _write_failed(plot, e)
    print(f"plot written to {plot}")
    return 0


def _output_problem(path) -> str | None:
    """Why an analysis output file cannot be written there, or None (checked before the
    work)."""
    if os.path.isdir(path):
        return "is a directory, not a file name"
    if os.path.lexists(path) and not os.path.isfile(path):
        return "exists and is not a regular file; it is never replaced"
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        return f"the directory {d} does not exist"
    if not os.access(d, os.W_OK | os.X_OK):
        return f"the directory {d} is not writable"
    return None


def save_figure(fig, path, **kw) -> None:
    """``fig.savefig`` through a temporary file and a rename (udf.files); what killed
    writes of ``path`` left is removed first."""
    from udf.files import remove_temporaries_of, write_stream
    remove_temporaries_of(path)
    fmt = os.path.splitext(path)[1].lstrip(".") or "png"
    write_stream(path, lambda fh: fig.savefig(fh, format=fmt, **kw))


def cmd_cna(a) -> int:
    from . import cna_command
    return cna_command.run(a)


def cmd_erotate(a) -> int:
    from . import erotate_command
    return erotate_command.run(a)


def cmd_show(a) -> int:
    from .show import ShowError, ShowWriteError, run
    try:
        return run(a)
    except ShowWriteError as e:
        return _write_failed(e.filename, e)
    except ShowError as e:
        return _fail(str(e))


def main(argv) -> int:
    p = argparse.ArgumentParser(prog="kapsel-py analyze", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("sq", help="structure factor S(q) of the order parameter snapshots")
    s.add_argument("directory")
    s.add_argument("--dx", type=float, default=1.0, help="grid spacing (default 1)")
    s.add_argument("--plot", help="PNG file (default OUTPUT_DIR/sq.png)")
    s.add_argument("--table", help="text table (default OUTPUT_DIR/sq.txt)")
    s.add_argument("--octant", action="store_true",
                   help="average over the one octant of wave vectors the sample's "
                        "sq_analysis.py uses (its numbers exactly); default: whole shells")
    s.set_defaults(fn=cmd_sq)
    c = sub.add_parser("cna", help="Common Neighbor Analysis (FCC/HCP/BCC/ICOS/OTHER)")
    c.add_argument("file", help="output.udf, an XYZ file or a LAMMPS dump")
    c.add_argument("--cutoff", type=float, help="neighbour cutoff (default: from the data)")
    c.add_argument("--record", default="all", help="record number or 'all' (default all)")
    c.add_argument("--labels", help="write per-particle labels to this .csv or .h5 file")
    c.set_defaults(fn=cmd_cna)
    e = sub.add_parser("erotate", help="rotational energy of rigid bodies per record")
    e.add_argument("file", help="output.udf")
    e.set_defaults(fn=cmd_erotate)
    w = sub.add_parser("show", help="picture of a run: a slice of psi (or |u|) with the "
                                    "particles, and E (shear stress) over time; one PNG per "
                                    "snapshot")
    w.add_argument("run_dir", metavar="RUN_DIR", help="the directory output.udf and the "
                                                      "field files are in")
    w.add_argument("--record", default="-1",
                   help="record of output.udf to draw: an index (negative from the end) or "
                        "'all' (default -1, the last)")
    w.add_argument("--z", type=int, default=None, metavar="K",
                   help="mesh index of the z slice (default: the middle)")
    w.add_argument("--udf", help="the run's output UDF (default RUN_DIR/output.udf)")
    w.add_argument("--out", help="directory of the PNGs (default RUN_DIR)")
    w.set_defaults(fn=cmd_show)
    a = p.parse_args(argv)
    return a.fn(a)
