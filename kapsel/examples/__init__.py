"""Example inputs shipped with kapsel-py, copied out by ``kapsel-py example NAME DIR``.

``sample``: the manual's sample (samples/ of the repository: Navier_Stokes_Cahn_Hilliard_FDM,
32^3, 8 particles, 1000 steps, with its define.udf, kapsel_unit.udf and the ParaView state
pv_sample.pvsm).
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
EXAMPLES = {
    "sample": "the manual's sample: Navier_Stokes_Cahn_Hilliard_FDM, 32^3, 8 particles, "
              "1000 steps (about a minute), with its ParaView state pv_sample.pvsm",
}


def files(name: str) -> list[Path]:
    return sorted(p for p in (HERE / name).iterdir() if p.is_file())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="kapsel-py example",
        description="Copy an example input shipped with kapsel-py into a directory.")
    ap.add_argument("name", nargs="?", help="the example (see --list)")
    ap.add_argument("directory", nargs="?", help="where to copy it (created if needed)")
    ap.add_argument("--list", action="store_true", help="list the examples")
    ap.add_argument("--overwrite", action="store_true", help="replace files already there")
    a = ap.parse_args(argv)
    if a.list or a.name is None:
        for k, v in EXAMPLES.items():
            print(f"{k:10s} {v}")
        return 0
    if a.name not in EXAMPLES:
        print(f"kapsel-py example: error: no example {a.name!r} (there is: "
              f"{', '.join(EXAMPLES)})", file=sys.stderr)
        return 2
    if a.directory is None:
        print("kapsel-py example: error: give the directory to copy it to, e.g. "
              f"kapsel-py example {a.name} {a.name}", file=sys.stderr)
        return 2
    dst = Path(a.directory)
    if dst.exists() and not dst.is_dir():
        print(f"kapsel-py example: error: {dst} is not a directory", file=sys.stderr)
        return 2
    src = files(a.name)
    there = [f.name for f in src if (dst / f.name).exists()]
    if there and not a.overwrite:
        print(f"kapsel-py example: error: {dst} already has {', '.join(there)} "
              f"(--overwrite replaces them)", file=sys.stderr)
        return 2
    try:
        dst.mkdir(parents=True, exist_ok=True)
        for f in src:
            shutil.copyfile(f, dst / f.name)
    except OSError as e:
        print(f"kapsel-py example: error: cannot write {dst}: {e.strerror or e}",
              file=sys.stderr)
        return 2
    print(f"{a.name} copied to {dst}: {', '.join(f.name for f in src)}")
    print(f"run it:  cd {dst} && kapsel-py -Iinput.udf -Ooutput.udf -Ddefine.udf "
          f"-Rrestart.udf")
    return 0
