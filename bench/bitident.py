"""Hash every output of one small run per type and object kind, serial and on 2 ranks.

    .venv/bin/python bench/bitident.py --save before.json [--scene NAME ...] [--ranks 1 2]
    .venv/bin/python bench/bitident.py --compare before.json      # exit 1 on any difference

A refactoring that must not change behaviour (issue 27's redesign, a reordering of work for
speed) runs this on the commit before and after it: every file a run writes (output.udf,
restart.udf and its state, the per-snapshot HDF5 and XDMF files, the EXTENDED trajectory, the
legacy AVS files, the .dat tables) is hashed by content: text files byte for byte (but the
run-id comment that opens output.udf), HDF5 files by their datasets (name, dtype, shape,
bytes) and attributes, .npz files by their arrays (the zip entries carry dates; the run id
is left out).  Scenes are 16^3, 20 steps with snapshots every 5 steps; kBT > 0 in some
of them (the noise stream and the seed are part of what must not change), and the CH types
keep their random initial composition (seed 1).  The 2-rank runs use the mpiexec of the `mpi`
extra; the types and options that do not run distributed are skipped there.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from parity import (CH, EL, FD, LE, LECH, LEF, NS, NSCH, SNS, chain, common, dipoles,  # noqa: E402
                    gravity, merge, rigid, row, shear, solvers, spheres, wall)
from udf import UDFManager  # noqa: E402

BASE = ROOT / "samples" / "kapsel-udf" / "ex14" / "input.udf"
N = 4          # 16^3
P3 = [row((4.0, 4.0, 4.0), v=(0.01, 0, 0)), row((11.0, 5.0, 8.0), v=(0, 0.01, 0)),
      row((6.0, 11.0, 12.0), w=(0, 0, 0.01))]
ROD = [row((4.0 + 2.0 * b, 8.0, 8.0)) for b in range(3)]
CHAIN = [row((3.0 + 2.1 * b, 8.0, 8.0)) for b in range(4)]
SMALL = {"A": 1.5, "A_XI": 1.0}


def sc(typ, *parts, noise=0.0, objects="spherical_particle", extra=None):
    e = merge(common(typ, n=N, dt=0.02, gts=5, objects=objects), SMALL, *parts)
    e[f"constitutive_eq.{typ}.kBT"] = noise
    if typ in CH:            # keep the random initial composition: the seed must count
        for pot in ("Landau", "Flory_Huggins"):
            e[f"constitutive_eq.{typ}.Potential.{pot}.initial_fluctuation"] = 0.05
        e[f"constitutive_eq.{typ}.Potential.Landau.d"] = 1.0
        e[f"constitutive_eq.{typ}.Potential.Landau.alpha"] = 1.0
        e[f"constitutive_eq.{typ}.Potential.Landau.composition_ratio"] = 0.0
    if extra:
        e.update(extra)
    return e


EXT = {"output.AVS": "ON", "output.ON.Out_dir": "avs", "output.ON.Out_name": "data",
       "output.ON.FileType": "EXTENDED", "output.ON.EXTENDED.Print_field.Crop": "NO",
       "output.ON.EXTENDED.Print_field.Vel": "YES", "output.ON.EXTENDED.Print_field.Phi": "YES",
       "output.ON.EXTENDED.Print_field.Pressure": "YES", "output.ON.EXTENDED.Print_field.Tau": "YES"}
LEGACY = {"output.AVS": "ON", "output.ON.Out_dir": "avs", "output.ON.Out_name": "data",
          "output.ON.FileType": "BINARY"}
PIN = {"switch.pin.type": "YES", "switch.pin.YES.pin[]": [0], "switch.pin.YES.pin_rot[]": [0]}

# name: (edits, runs distributed)
SCENES = {
    "ns_spheres": (sc(NS, spheres(P3), gravity(), noise=0.1, extra=EXT), True),
    "ns_chain": (sc(NS, chain(CHAIN), noise=0.1, objects="chain"), True),
    "ns_rigid": (sc(NS, rigid(ROD, 3), gravity(), objects="rigid", extra=LEGACY), True),
    "ns_rigid_fix": (sc(NS, rigid(ROD, 3, motion="fix", V=(0.01, 0, 0), W=(0, 0, 0.01)),
                        objects="rigid"), True),
    "ns_squirmer": (sc(NS, spheres(P3[:1], mass=1.0, janus=("Z", "SQUIRMER", (0, 0, 0),
                                                            (0, 0, 0), 0.01, -1.0))), True),
    "ns_tumbler": (sc(NS, spheres(P3[:1], mass=1.0, janus=("Z", "TUMBLER", (0, 0, 0.05),
                                                           (0.01, 0, 0), 0.0, 0.0))), True),
    "ns_pin": (sc(NS, spheres(P3), gravity(), PIN), True),
    "ns_wall": (sc(NS, spheres([row((8.0, 7.0, 8.0))]), gravity(), wall(dh=4)), False),
    "ns_dipoles": (sc(NS, spheres([row((8.0, 8.0, 4.0)), row((8.5, 8.0, 11.0))]), dipoles()),
                   True),
    "fdm_e": (sc(FD, solvers(FD, ns="explicit_scheme"), spheres(P3), gravity(), noise=0.1), True),
    "fdm_i": (sc(FD, solvers(FD, ns="implicit_scheme"), spheres(P3), gravity(), extra=EXT), True),
    "fdm_wall": (sc(FD, solvers(FD, ns="explicit_scheme"), spheres([row((8.0, 7.0, 8.0))]),
                    gravity(), wall(dh=4)), False),
    "nsch_ei": (sc(NSCH, solvers(NSCH, ns="explicit_scheme", ch="implicit_scheme"),
                   spheres(P3)), True),
    "nsch_ii": (sc(NSCH, solvers(NSCH, ns="implicit_scheme", ch="implicit_scheme"), spheres(P3),
                   {f"constitutive_eq.{NSCH}.NS_solver.implicit_scheme.viscosity_change": "ON"}),
                True),
    "nsch_fh": (sc(NSCH, solvers(NSCH, ns="explicit_scheme", ch="implicit_scheme"), spheres(P3),
                   {f"constitutive_eq.{NSCH}.Potential.type": "Flory_Huggins",
                    f"constitutive_eq.{NSCH}.Potential.Flory_Huggins.composition_ratio": 0.5}),
                True),
    "zz_dc": (sc(SNS, spheres(P3, mass=1.0), shear(SNS), noise=0.1), True),
    "zz_ac": (sc(SNS, spheres(P3, mass=1.0), shear(SNS, ac=True, freq=0.01)), True),
    "le_dc": (sc(LE, spheres(P3, mass=1.0), shear(LE), noise=0.1, extra=EXT), True),
    "le_rigid": (sc(LE, rigid(ROD, 3, mass=1.0), shear(LE, ac=True, freq=0.01),
                    objects="rigid"), True),
    "lef_e": (sc(LEF, solvers(LEF, ns="explicit_scheme"), spheres(P3, mass=1.0), shear(LEF)),
              True),
    "lef_i": (sc(LEF, solvers(LEF, ns="implicit_scheme"), spheres(P3, mass=1.0), shear(LEF)),
              True),
    "lech_ii": (sc(LECH, solvers(LECH, ns="implicit_scheme", ch="implicit_scheme"),
                   spheres(P3, mass=1.0), shear(LECH)), True),
    "el_salt": (sc(EL, spheres(P3[:2], mass=1.0), noise=0.1, extra={
        "object_type.spherical_particle.Particle_spec[0].Surface_charge": -2.0,
        f"constitutive_eq.{EL}.INIT_profile": "Poisson_Boltzmann",
        f"constitutive_eq.{EL}.Add_salt.type": "salt",
        f"constitutive_eq.{EL}.Add_salt.salt.Debye_length": 3.0,
        f"constitutive_eq.{EL}.Electric_field.type": "ON",
        f"constitutive_eq.{EL}.Electric_field.ON.type": "DC",
        f"constitutive_eq.{EL}.Electric_field.ON.DC.Ex": 0.01}), False),
}


def make_input(d: Path, edits: dict):
    d.mkdir(parents=True, exist_ok=True)
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(BASE.parent / f, d / f)
    u = UDFManager(str(BASE))
    edits = dict(edits, **{"output.Num_snap": 4})
    for k, v in edits.items():
        if isinstance(v, list) and v and isinstance(v[0], list):
            v = np.array(v, dtype=float)
        u.put(v, k)
    u.write(str(d / "input.udf"))


def mpiexec():
    here = Path(sys.executable).parent
    return shutil.which("mpiexec", path=str(here)) or shutil.which("mpiexec")


def run(d: Path, ranks: int):
    cmd = [sys.executable, "-m", "kapsel.cli", "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
           "-Rrestart.udf", "--seed", "1", "--quiet", "--threads", "1"]
    if ranks > 1:
        cmd = [mpiexec(), "-n", str(ranks)] + cmd
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    p = subprocess.run(cmd, cwd=d, env=env, capture_output=True, text=True)
    return p.returncode, (p.stderr.strip().splitlines() or [""])[-1][:200]


def digest_h5(path: Path) -> str:
    import h5py
    h = hashlib.sha256()
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            h.update(name.encode())
            for k in sorted(obj.attrs):
                h.update(k.encode())
                h.update(np.asarray(obj.attrs[k]).tobytes())
            if isinstance(obj, h5py.Dataset):
                a = obj[()]
                h.update(str((a.dtype.str, a.shape)).encode())
                h.update(np.ascontiguousarray(a).tobytes())
        visit("/", f)
        f.visititems(visit)
    return h.hexdigest()


def digest_npz(path: Path) -> str:
    h = hashlib.sha256()
    with zipfile.ZipFile(path) as z:
        for name in sorted(z.namelist()):
            if name == "run_id.npy":      # a fresh id per run (records.run_comment)
                continue
            h.update(name.encode())
            h.update(z.read(name))
    return h.hexdigest()


def digest(path: Path) -> str:
    if path.suffix == ".h5":
        return digest_h5(path)
    if path.suffix == ".npz":
        return digest_npz(path)
    data = path.read_bytes()
    if path.suffix == ".udf" and data.startswith(RUN_MARK):   # the run id line
        data = data[data.find(b"\n") + 1:]
    return hashlib.sha256(data).hexdigest()


RUN_MARK = b"// kapsel-py run "
SKIP = {"input.udf", "define.udf", "kapsel_unit.udf"}


def hashes(d: Path):
    out = {}
    for f in sorted(d.rglob("*")):
        if f.is_file() and f.name not in SKIP and not f.name.startswith("."):
            out[str(f.relative_to(d))] = digest(f)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--save", help="write the hashes here")
    ap.add_argument("--compare", help="compare with the hashes in this file")
    ap.add_argument("--scene", nargs="*")
    ap.add_argument("--ranks", nargs="*", type=int, default=[1, 2])
    ap.add_argument("--keep", help="keep the runs under this directory")
    a = ap.parse_args(argv)
    names = a.scene or list(SCENES)
    top = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="kapsel-bitident-"))
    result = {}
    if 2 in a.ranks and mpiexec() is None:
        print("no mpiexec (the mpi extra): 2-rank runs skipped", file=sys.stderr)
        a.ranks = [r for r in a.ranks if r == 1]
    for name in names:
        edits, dist = SCENES[name]
        for ranks in a.ranks:
            if ranks > 1 and not dist:
                continue
            d = top / f"{name}-{ranks}"
            if d.exists():
                shutil.rmtree(d)
            make_input(d, edits)
            rc, tail = run(d, ranks)
            h = hashes(d)
            h["exit"] = str(rc)
            result[f"{name}/{ranks}"] = h
            print(f"{name:12s} ranks {ranks}: exit {rc}, {len(h) - 1} files"
                  + (f"  [{tail}]" if rc else ""), flush=True)
    status = 0
    if a.compare:
        ref = json.loads(Path(a.compare).read_text())
        same = diff = 0
        for key, h in result.items():
            r = ref.get(key)
            if r is None:
                print(f"{key}: not in {a.compare}")
                continue
            for f in sorted(set(h) | set(r)):
                if h.get(f) != r.get(f):
                    diff += 1
                    print(f"DIFFERENT {key} {f}: {'missing' if f not in h else ''}"
                          f"{'new' if f not in r else ''}")
                else:
                    same += 1
        print(f"{same} files identical, {diff} different")
        status = 1 if diff else 0
    if a.save:
        Path(a.save).write_text(json.dumps(result, indent=1, sort_keys=True))
    if not a.keep:
        shutil.rmtree(top, ignore_errors=True)
    return status


if __name__ == "__main__":
    sys.exit(main())
