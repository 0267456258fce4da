"""Restart cost per snapshot (issue 14): the full restart.udf (+ state file) against the
checkpoint (state file only) that runs write between full writes, next to one time step.

    .venv/bin/python bench/bench_restart.py [--npx 6] [--types Navier_Stokes ...]

The manual's sample with one particle (A 4), kBT 0, explicit MAC, 2^npx cells per side;
CPU ms (process time, mean of 3) and wall ms.  kapsel.simulation writes the full restart.udf
at a run's first snapshot, at its end, on interruption and on failure, a checkpoint at every
other snapshot (kapsel.io.restart.write_checkpoint).
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

ROOT = os.path.join(os.path.dirname(__file__), "..")
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))
from kapsel import config, models  # noqa: E402,F401
from kapsel.io.restart import write_checkpoint, write_restart  # noqa: E402
from kapsel.typespec import SOLVERS  # noqa: E402
from builders import sample_input  # noqa: E402  (tests/builders.py)
from udf import UDFManager  # noqa: E402

NS_CH = "constitutive_eq.Navier_Stokes_Cahn_Hilliard_FDM"


def scene(d, eq, npx):
    u = sample_input(d, eq, npx)
    u.put("explicit_scheme", f"{NS_CH}.NS_solver.type")
    u.put("explicit_scheme", "constitutive_eq.Navier_Stokes_FDM.NS_solver.type")
    u.put(1, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    path = os.path.join(d, "input.udf")
    u.write(path)
    return path


def timed(f, n=3):
    c, w = time.process_time(), time.perf_counter()
    for _ in range(n):
        f()
    return (time.process_time() - c) / n * 1e3, (time.perf_counter() - w) / n * 1e3


class Args:
    seed, quiet, threads = 1, True, 1


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--npx", type=int, default=6)
    ap.add_argument("--types", nargs="+", default=["Navier_Stokes", "Navier_Stokes_FDM",
                                                   "Navier_Stokes_Cahn_Hilliard_FDM"])
    a = ap.parse_args()
    n = 2 ** a.npx
    print(f"{n}^3, 1 particle: ms per call, CPU (wall)")
    print(f"{'type':34s} {'time step':>15s} {'full restart.udf':>18s} {'checkpoint':>15s}")
    for eq in a.types:
        d = tempfile.mkdtemp(prefix="bench_restart_")
        try:
            path = scene(d, eq, a.npx)
            cfg = config.load(path)
            m = SOLVERS[cfg.type](cfg, Args(), None)
            doc = UDFManager(path)
            ddoc = UDFManager(schema_from=os.path.join(d, "define.udf"))
            rpath = os.path.join(d, "restart.udf")
            m.advance()
            step = timed(m.advance)

            def full():
                kind, data, exact = m.restart_state()
                write_restart(rpath, os.path.join(d, "define.udf"), doc, kind, m.step_index,
                              m.time, m.particles, data, exact)

            def checkpoint():
                kind, data, exact = m.restart_state(checkpoint=True)
                write_checkpoint(rpath, ddoc, kind, m.step_index, m.time, m.particles, data,
                                 exact, "bench", complete=m.checkpoint_complete)
            f, c = timed(full), timed(checkpoint)
            print(f"{eq:34s} {step[0]:7.0f} ({step[1]:5.0f}) {f[0]:9.0f} ({f[1]:5.0f}) "
                  f"{c[0]:7.0f} ({c[1]:5.0f})")
        finally:
            shutil.rmtree(d)


if __name__ == "__main__":
    main()
