"""Per-stage step profile of two trees side by side (a change that must not be slower).

    .venv/bin/python bench/profile_ab.py BEFORE_TREE [AFTER_TREE] [--scene S ...] [--np N]
                                         [--steps K] [--repeat R]

For every scene, this checkout's bench/profile_step.py runs on each tree (PYTHONPATH set to
the tree; the script copied into a temporary bench/ beside it when the tree lacks the
scenes), alternately A B A B ``--repeat`` times: CPU ms per step without the profiler (the
median and the minimum of the repeats), then once with cProfile for the time per stage (FFT,
linear solver, MAC stencils, spectral element-wise, phase field, particles, other).  The
compiled kernels are on in both, as in a long run.  Prints a markdown table and the load.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCENES = ["ns32", "sns64", "le64", "el64", "fdm64e", "nsch64", "lef64", "lech64"]


def _runner(tree: Path) -> tuple[Path, Path]:
    """(root on PYTHONPATH, profile_step.py to run): this checkout's script and scenes, run
    against ``tree``'s package."""
    d = Path(tempfile.mkdtemp(prefix="profab-"))
    (d / "bench").mkdir()
    for f in ("profile_step.py", "bench_vs_original.py"):
        shutil.copy(HERE / f, d / "bench" / f)
    for sub in ("kapsel", "udf", "samples"):
        os.symlink(tree / sub, d / sub)
    return d, d / "bench" / "profile_step.py"


def _run(root, script, scene, args, extra):
    env = dict(os.environ, PYTHONPATH=str(root), OMP_NUM_THREADS="1")
    cmd = [sys.executable, str(script), scene] + args + extra
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=root)
    if r.returncode:
        raise RuntimeError(f"{scene} on {root}: {r.stderr[-500:]}")
    return r.stdout.strip().splitlines()[-1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after", nargs="?", default=str(HERE.parent))
    ap.add_argument("--scene", nargs="*", default=SCENES)
    ap.add_argument("--np", type=int, default=5, help="2^NP mesh points per axis (default 32^3)")
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    trees = {"before": _runner(Path(a.before).resolve()),
             "after": _runner(Path(a.after).resolve())}
    args = ["--np", str(a.np), "--steps", str(a.steps)]
    print(f"load before: {os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    for scene in a.scene:
        ms = {k: [] for k in trees}
        for _ in range(a.repeat):
            for k, (root, script) in trees.items():
                ms[k].append(float(_run(root, script, scene, args, ["--time-only"])))
        stages = {k: _run(root, script, scene, args, ["--stages"])
                  for k, (root, script) in trees.items()}
        rows.append((scene, ms, stages))
        med = {k: statistics.median(v) for k, v in ms.items()}
        print(f"{scene}: before {med['before']:.2f} ms, after {med['after']:.2f} ms "
              f"({med['after'] / med['before']:.3f})", flush=True)
    print(f"load after: {os.getloadavg()[0]:.2f}\n")
    print(f"| scene (2^{a.np} per axis) | before ms/step median (min) | after ms/step median (min) "
          f"| after/before | stages before (profiled ms/step) | stages after |")
    print("|---|---|---|---|---|---|")

    def short(s):
        return re.sub(r"^profiled ", "", s)
    for scene, ms, stages in rows:
        b, f = ms["before"], ms["after"]
        print(f"| {scene} | {statistics.median(b):.2f} ({min(b):.2f}) | "
              f"{statistics.median(f):.2f} ({min(f):.2f}) | "
              f"{statistics.median(f) / statistics.median(b):.3f} | {short(stages['before'])} | "
              f"{short(stages['after'])} |")


if __name__ == "__main__":
    main()
