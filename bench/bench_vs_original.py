"""kapsel-py against the original program (kapsel_u2m), run side by side on the same document.

    .venv/bin/python bench/bench_vs_original.py [--original PATH] [--kref DIR] [--scene NAME ...]
                                                [--repeat R] [--threads T] [--keep DIR] [--json F]

For every scene both programs run the same document (the original the flattened form its kref
stand-in for OCTA's UDFManager reads), alternately, A B A B ..., ``--repeat`` times (default 3),
each in a fresh process with T threads (the original: OMP_NUM_THREADS=T; kapsel-py:
``--threads T``).  Per program and scene the table gives:

    ms/step   CPU milliseconds (user + system, all threads) per step of the time loop with its
              snapshots (records, field files, restart), the median of the repeats: the
              original's from the two ``#KREF`` lines its kref build prints (start of the loop,
              end of the loop: before it writes its restart and output UDF files, which it
              does after the loop), kapsel-py's from the same two points of its run (the first
              step to the end of the loop, before the end's restart file is written; its
              output.udf records are written in the loop and counted), measured in-process by
              a hook on kapsel.progress and kapsel.simulation;
    RSS MB    the peak resident memory of the whole process (``wait4``'s ru_maxrss), largest of
              the repeats;

and the ratios kapsel-py / original.  Runs are long enough for kapsel-py's compiled kernels
(they switch on in the first steps of a run; kapsel.mesh.compiled).  The load average before and after
is printed with the table: the machine is shared, so CPU time, not wall time, is compared
(a second table gives the wall milliseconds per step as well: compare a ``--threads 2`` run's with a
``--threads 1`` run's to see what the second thread gives).

The original is not part of the project (no licence): build it from its public source with
``../shared/kref/`` (``KREF=<dir> KAPSEL3_GIT=<git dir> ../shared/kref/build.sh``) and give its
binary by ``--original`` or ``$KREF_CPP``; the kref tools (``flatten_udf.py``) by ``--kref`` or
``$KREF_TOOLS`` (default ``../shared/kref`` next to the repository).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from udf import UDFManager  # noqa: E402

SAMPLE = ROOT / "samples" / "input.udf"
SP = "object_type.spherical_particle.Particle_spec[0]"


def _ns(n, particles, A, typ="Navier_Stokes"):
    return {"constitutive_eq.type": typ, "mesh.NPX": n, "mesh.NPY": n, "mesh.NPZ": n,
            f"{SP}.Particle_number": particles, "A": A}


def _electrolyte(n, particles):
    return dict(_ns(n, particles, 2.0, "Electrolyte"),
                **{f"{SP}.Surface_charge": -1.0, "constitutive_eq.Electrolyte.kBT": 1.0})


# name: (label, edits of samples/input.udf, steps, GTS)
SCENES = {
    "sample": ("sample as is (NSCH_FDM 32^3, 8 particles)", {}, 1000, 100),
    "ns32": ("Navier_Stokes 32^3, 1 particle (A 4)", _ns(5, 1, 4.0), 200, 20),
    "ns64": ("Navier_Stokes 64^3, 1 particle (A 4)", _ns(6, 1, 4.0), 200, 20),
    "ns64x100": ("Navier_Stokes 64^3, 100 particles (A 2)", _ns(6, 100, 2.0), 200, 20),
    "ns128x1000": ("Navier_Stokes 128^3, 1000 particles (A 2)", _ns(7, 1000, 2.0), 200, 20),
    "ns256x8000": ("Navier_Stokes 256^3, 8000 particles (A 2)", _ns(8, 8000, 2.0), 20, 10),
    "fdm64e": ("Navier_Stokes_FDM explicit 64^3, 8 particles", dict(
        _ns(6, 8, 4.0, "Navier_Stokes_FDM"),
        **{"constitutive_eq.Navier_Stokes_FDM.NS_solver.type": "explicit_scheme"}), 200, 20),
    "nsch64": ("Navier_Stokes_Cahn_Hilliard_FDM 64^3, 8 particles", {
        "mesh.NPX": 6, "mesh.NPY": 6, "mesh.NPZ": 6}, 200, 20),
    "le64": ("Shear_Navier_Stokes_Lees_Edwards 64^3, 8 particles (DC 0.01)",
             _ns(6, 8, 4.0, "Shear_Navier_Stokes_Lees_Edwards"), 200, 20),
    "el64": ("Electrolyte 64^3, 8 particles (salt, Z -10)", dict(
        _ns(6, 8, 4.0, "Electrolyte"),
        **{f"{SP}.Surface_charge": -10.0, "constitutive_eq.Electrolyte.kBT": 1.0}), 200, 20),
    "sns64": ("Shear_Navier_Stokes (zigzag) 64^3, 8 particles",
              _ns(6, 8, 4.0, "Shear_Navier_Stokes"), 200, 20),
    "lef64": ("Shear_Navier_Stokes_Lees_Edwards_FDM 64^3, 8 particles (DC 0.01)",
              _ns(6, 8, 4.0, "Shear_Navier_Stokes_Lees_Edwards_FDM"), 200, 20),
    "lech64": ("Shear_NS_LE_CH_FDM 64^3, 8 particles (DC 0.01)",
               _ns(6, 8, 4.0, "Shear_NS_LE_CH_FDM"), 200, 20),
    "squirmer64": ("Navier_Stokes 64^3, 8 squirmers (B1 0.01, alpha -1)", dict(
        _ns(6, 8, 4.0),
        **{f"{SP}.janus_axis": "Z", f"{SP}.janus_propulsion": "SQUIRMER",
           f"{SP}.janus_slip_vel": 0.01, f"{SP}.janus_slip_mode": -1.0,
           "switch.ROTATION": "ON"}), 200, 20),
}
# the spectral types with particles at 128^3 and 256^3 (issue 25's memory)
for _n, _np in ((7, 1000), (8, 8000)):
    _size = f"{2 ** _n}^3, {_np} particles (A 2)"
    SCENES.update({
        f"sns{2 ** _n}x{_np}": (f"Shear_Navier_Stokes (zigzag) {_size}",
                                _ns(_n, _np, 2.0, "Shear_Navier_Stokes"), 20, 10),
        f"le{2 ** _n}x{_np}": (f"Shear_Navier_Stokes_Lees_Edwards {_size}",
                               _ns(_n, _np, 2.0, "Shear_Navier_Stokes_Lees_Edwards"), 20, 10),
        f"el{2 ** _n}x{_np}": (f"Electrolyte {2 ** _n}^3, {_np} particles (A 2, salt, Z -1)",
                               _electrolyte(_n, _np), 20, 10)})

# kapsel-py with the two timing points of the original's kref build (#KREF lines): from the
# first step to the end of the time loop, before the restart file of the end is written (the
# original's loop line is printed before its ufres->write() and ufout->write(), which come
# after the loop in sp_3d_ns.cxx main); with no such write, to the closing summary
_HOOK = r"""
import sys, time
import kapsel.progress as P
import kapsel.activities as A
import kapsel.simulation as S
_init, _summary = P.Progress.__init__, P.Progress.summary
_save, _end = A.Restart.save, S.TimeLoop._end
st = {}
def init(self, *a, **k):
    st["t"], st["c"] = time.perf_counter(), time.process_time()
    _init(self, *a, **k)
def end(self, *a, **k):
    st["ending"] = True
    return _end(self, *a, **k)
def save(self, *a, **k):
    if st.get("ending") and k.get("full") and "stop" not in st:
        st["stop"] = (time.perf_counter(), time.process_time())
    return _save(self, *a, **k)
def summary(self, *a, **k):
    t, c = st.get("stop") or (time.perf_counter(), time.process_time())
    sys.stderr.write("#KREF loop_s %.6f loop_cpu_s %.6f steps %d\n" % (
        t - st["t"], c - st["c"], self.steps))
    return _summary(self, *a, **k)
P.Progress.__init__, P.Progress.summary = init, summary
A.Restart.save, S.TimeLoop._end = save, end
from kapsel.cli import main
sys.argv[0] = "kapsel-py"
sys.exit(main())
"""


def make_scene(d: Path, edits: dict, steps: int, gts: int, kref: Path):
    d.mkdir(parents=True, exist_ok=True)
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(SAMPLE.parent / f, d / f)
    u = UDFManager(str(SAMPLE))
    for k, v in dict(edits, **{"output.GTS": gts, "output.Num_snap": steps // gts}).items():
        u.put(v, k)
    u.write(str(d / "input.udf"))
    subprocess.run([sys.executable, str(kref / "flatten_udf.py"), "input.udf", "input.flat"],
                   cwd=d, check=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))


def _kref(text):
    out = {}
    for m in re.finditer(r"#KREF (.*)", text):
        toks = m.group(1).split()
        out.update({k: float(v) for k, v in zip(toks[::2], toks[1::2])})
    return out


def run_once(prog: str, scene: Path, original: str, threads: int):
    """One run of ``prog`` ('original' / 'kapsel-py') in a fresh copy of the scene."""
    w = scene / prog
    if w.exists():
        shutil.rmtree(w)
    w.mkdir()
    for f in ("input.udf", "input.flat", "define.udf", "kapsel_unit.udf"):
        shutil.copy(scene / f, w / f)
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    if prog == "original":
        cmd = [original, "-Iinput.flat", "-Ooutput.flat", "-Ddefine.udf", "-Rrestart.flat"]
    else:
        cmd = [sys.executable, "-c", _HOOK, "-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
               "-Rrestart.udf", "--threads", str(threads), "--seed", "1"]
    with open(w / "stderr.txt", "w") as err, open(w / "stdout.txt", "w") as out:
        p = subprocess.Popen(cmd, cwd=w, env=env, stdout=out, stderr=err)
        _, status, ru = os.wait4(p.pid, 0)
    rc = os.waitstatus_to_exitcode(status)
    k = _kref((w / "stderr.txt").read_text(errors="replace"))
    res = {"rc": rc, "rss_mb": ru.ru_maxrss / 1024.0,
           "cpu_s": ru.ru_utime + ru.ru_stime}
    if "loop_cpu_s" in k and k.get("steps"):
        res["ms_step"] = 1e3 * k["loop_cpu_s"] / k["steps"]
        res["wall_ms_step"] = 1e3 * k["loop_s"] / k["steps"]
        res["steps"] = int(k["steps"])
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--original", default=os.environ.get("KREF_CPP"))
    ap.add_argument("--kref", default=os.environ.get("KREF_TOOLS",
                                                     str(ROOT.parent / "shared" / "kref")))
    ap.add_argument("--scene", nargs="*", choices=list(SCENES))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--steps", type=int, help="steps of every scene (default its own)")
    ap.add_argument("--keep", help="keep the runs under this directory")
    ap.add_argument("--json", help="append the results (one JSON line per scene) here")
    a = ap.parse_args(argv)
    kref = Path(a.kref).resolve()        # the scenes run in their own directories
    if not a.original or not Path(a.original).is_file() or not (kref / "flatten_udf.py").exists():
        print("bench_vs_original.py runs the original program itself; build it from its public "
              "source with ../shared/kref/:\n  KREF=<scratch dir> KAPSEL3_GIT=<git dir of "
              "kapsel-dns/kapsel3> ../shared/kref/build.sh\nthen: bench/bench_vs_original.py "
              "--original <scratch dir>/src/kapsel [--kref ../shared/kref]", file=sys.stderr)
        return 2
    top = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="kapsel-vs-original-"))
    load0 = os.getloadavg()
    rows = []
    for name in a.scene or list(SCENES):
        label, edits, steps, gts = SCENES[name]
        if a.steps:
            steps = a.steps
            gts = max(1, min(gts, steps // 2))
        d = top / name
        make_scene(d, edits, steps, gts, kref)
        runs = {"original": [], "kapsel-py": []}
        for _ in range(a.repeat):
            for prog in ("original", "kapsel-py"):
                runs[prog].append(run_once(prog, d, str(Path(a.original).resolve()), a.threads))
        r = {"scene": name, "label": label, "steps": steps, "threads": a.threads,
             "load": os.getloadavg()[0]}
        for prog, rs in runs.items():
            ok = [x for x in rs if x["rc"] == 0 and "ms_step" in x]
            r[prog] = {"rc": [x["rc"] for x in rs],
                       "ms_step": [round(x["ms_step"], 3) for x in ok],
                       "median_ms": statistics.median([x["ms_step"] for x in ok]) if ok else None,
                       "wall_ms": [round(x["wall_ms_step"], 3) for x in ok],
                       "median_wall_ms": (statistics.median([x["wall_ms_step"] for x in ok])
                                          if ok else None),
                       "rss_mb": max(x["rss_mb"] for x in rs)}
        o, p = r["original"], r["kapsel-py"]
        r["ratio"] = (p["median_ms"] / o["median_ms"]
                      if o["median_ms"] and p["median_ms"] else None)
        r["rss_ratio"] = p["rss_mb"] / o["rss_mb"] if o["rss_mb"] else None
        rows.append(r)
        print(f"{name:12s} original {o['ms_step']} ms  kapsel-py {p['ms_step']} ms  "
              f"ratio {r['ratio'] if r['ratio'] is None else round(r['ratio'], 2)}  "
              f"RSS {o['rss_mb']:.0f} / {p['rss_mb']:.0f} MB  (load {r['load']:.1f})",
              flush=True)
        if a.json:
            with open(a.json, "a") as fh:
                fh.write(json.dumps(r) + "\n")
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                          capture_output=True, text=True).stdout.strip()
    print(f"\n{stamp}, {os.uname().nodename} ({os.cpu_count()} cores), {a.threads} thread(s), "
          f"{a.repeat} repeats A B A B, load {load0[0]:.1f} -> {os.getloadavg()[0]:.1f}, "
          f"kapsel-py {head}\n")
    print("| scene | steps | original ms/step | kapsel-py ms/step | ratio | original RSS MB "
          "| kapsel-py RSS MB | RSS ratio |")
    print("|---|---|---|---|---|---|---|---|")
    f = (lambda x, s=".1f": "-" if x is None else format(x, s))
    for r in rows:
        o, p = r["original"], r["kapsel-py"]
        print(f"| {r['label']} | {r['steps']} | {f(o['median_ms'])} | {f(p['median_ms'])} | "
              f"{f(r['ratio'], '.2f')} | {o['rss_mb']:.0f} | {p['rss_mb']:.0f} | "
              f"{f(r['rss_ratio'], '.2f')} |")
    # wall time too (what --threads 2 is for: compare it with a --threads 1 run's)
    print(f"\nWall ms per step of the same runs ({a.threads} thread(s); median):\n")
    print("| scene | original wall ms/step | kapsel-py wall ms/step | ratio |")
    print("|---|---|---|---|")
    for r in rows:
        o, p = r["original"], r["kapsel-py"]
        w = (p["median_wall_ms"] / o["median_wall_ms"]
             if o["median_wall_ms"] and p["median_wall_ms"] else None)
        print(f"| {r['label']} | {f(o['median_wall_ms'])} | {f(p['median_wall_ms'])} | "
              f"{f(w, '.2f')} |")
    if not a.keep:
        shutil.rmtree(top, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
