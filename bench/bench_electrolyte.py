"""Speed of the Electrolyte type against Navier_Stokes (kapsel.models.electrolyte).

    .venv/bin/python bench/bench_electrolyte.py [--npx 6] [--particles 32] [--steps 20]

The real input ex01/colloid_1.udf (1:1 salt, Debye length 10, DC field) with 2^npx cells
per side and ``particles`` spheres of A = 5, Z = -100 at random places (seed 1); the same
scene as Navier_Stokes (kBT = 0: no noise, the same work but the ions).  Uniform start.
Prints the median and best ms/step of ``steps`` steps after 2 warm-up steps, one thread.

Measured 2026-11-29 09:40 UTC on the shared 2-core VM (load average 6.5, six jobs):
    Navier_Stokes  64^3, 32 particles:   142.7 ms/step median,    97.9 best (20 steps)
    Electrolyte    64^3, 32 particles:   340.1 ms/step median,   285.6 best (20 steps)
Electrolyte costs ~2.4-2.9 x Navier_Stokes: per species 8 scalar FFTs (grad c, div J) and
the flux arithmetic, plus Poisson (4) and the Coulomb force (3 + projection).
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")      # single-threaded BLAS, as kapsel-py runs (kapsel.cli)

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def build(kind, npx, n, d):
    import shutil
    from udf import UDFManager
    from kapsel import config
    ex = ROOT / "samples" / "kapsel-udf" / "ex01"
    shutil.copy(ex / "define.udf", Path(d) / "define.udf")
    u = UDFManager(str(ex / "colloid_1.udf"))
    u.put(kind, "constitutive_eq.type")
    u.put(0.0, "constitutive_eq.Navier_Stokes.kBT")
    for k in ("NPX", "NPY", "NPZ"):
        u.put(npx, f"mesh.{k}")
    u.put(n, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put("uniform_random", "switch.INIT_distribution.type")
    u.put("Uniform", "constitutive_eq.Electrolyte.INIT_profile")
    path = os.path.join(d, f"{kind}.udf")
    u.write(path)
    cfg = config.load(path)

    class Args:
        quiet, threads, seed = True, 1, 1
    from kapsel.typespec import SOLVERS
    import kapsel.models  # noqa: F401
    return SOLVERS[kind](cfg, Args(), None)


def measure(model, steps):
    for _ in range(2):
        model.advance()
    times = []
    for _ in range(steps):
        t = time.perf_counter()
        model.advance()
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times), 1e3 * min(times)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--npx", type=int, default=6)
    ap.add_argument("--particles", type=int, default=32)
    ap.add_argument("--steps", type=int, default=20)
    a = ap.parse_args()
    n = 2 ** a.npx
    with tempfile.TemporaryDirectory() as d:
        for kind in ("Navier_Stokes", "Electrolyte"):
            med, best = measure(build(kind, a.npx, a.particles, d), a.steps)
            print(f"{kind:14s} {n}^3, {a.particles} particles: {med:7.1f} ms/step median, "
                  f"{best:7.1f} best ({a.steps} steps)", flush=True)
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
