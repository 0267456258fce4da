"""Speed of the pseudo-spectral fluid solver alone (kapsel.fluid.spectral.SpectralNS).

    .venv/bin/python bench/bench_spectral.py [--big] [--steps N] [--scheme etd1|etd2]
                                             [--planners] [--profile N]

Prints ms/step and ns per grid point per step for 32^3, 64^3 (128^3 with --big), 1 and 2
FFT threads, a random small-amplitude field, dt = auto_dt(1), FIX_CELL on, planner "auto".
Times: median and best of the timed steps after 2 warm-up steps.  --planners compares
FFTW_MEASURE and FFTW_ESTIMATE (plan time, one forward+backward vector pair), the
measurement behind kapsel.mesh.grid's default.  --profile N: cProfile of 20 steps at N^3.
(The benchmark with particles is bench/bench_spm.py.)

Measured 2026-11-22 with both shared cores busy with other jobs (load ~3.5), etd1, medians:
over two runs 32^3 0.9-1.3 ms/step (27-39 ns/pt), 64^3 20-28 ms (76-108 ns/pt), 128^3
196-285 ms (94-136 ns/pt) on 1 thread; 2 threads were never faster and up to 50x slower in
median (32^3 64 ms once: each of the 9 transforms waits for the busy second core), so use
threads=1 on a loaded machine.  A 64^3 step is
~half FFTs (9 component transforms, ~9 ms), half numpy element-wise work (curl, u x omega,
projection, ETD update).
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")      # single-threaded BLAS, as kapsel-py runs (kapsel.cli)

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from kapsel.fluid.spectral import SpectralNS  # noqa: E402
from kapsel.mesh.grid import Grid  # noqa: E402
from kapsel.timestep import auto_dt  # noqa: E402


def build(n, threads, scheme="etd1", planner="auto"):
    g = Grid((n, n, n), 1.0, threads=threads, planner=planner)
    ns = SpectralNS(g, 1.0, 1.0, auto_dt(1.0, 1.0, 1.0, 1.0, g.shape), fix_cell=True,
                    scheme=scheme)
    ns.set_velocity(np.random.default_rng(0).normal(size=(3,) + g.shape) * 1e-3)
    return ns


def time_steps(ns, nsteps, min_time):
    for _ in range(2):
        ns.step()
    times = []
    while len(times) < nsteps or sum(times) < min_time:
        t0 = time.perf_counter()
        ns.step()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), min(times), len(times)


def planners(sizes, threads=1, repeat=10):
    import pyfftw
    print(f"{'grid':>6} {'planner':>14} {'plan s':>8} {'ms/pair':>9}")
    for n in sizes:
        for planner in ("FFTW_MEASURE", "FFTW_ESTIMATE"):
            shape = (n, n, n)
            pyfftw.forget_wisdom()  # else MEASURE's wisdom serves ESTIMATE
            t0 = time.perf_counter()
            g = Grid(shape, 1.0, threads=threads, planner=planner)
            plan = time.perf_counter() - t0
            u = np.random.default_rng(0).normal(size=(3,) + g.shape)
            uh, v = g.empty_complex(), g.empty_real()
            best = np.inf
            for _ in range(repeat):
                t0 = time.perf_counter()
                g.rfft(u, out=uh)
                g.irfft(uh, out=v)
                best = min(best, time.perf_counter() - t0)
            print(f"{n:>5}^3 {planner:>14} {plan:>8.2f} {best * 1e3:>9.2f}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--big", action="store_true", help="add 128^3")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--scheme", default="etd1", choices=("etd1", "etd2"))
    ap.add_argument("--planners", action="store_true")
    ap.add_argument("--profile", type=int, default=0)
    args = ap.parse_args(argv)
    sizes = [32, 64] + ([128] if args.big else [])
    if args.planners:
        planners(sizes)
        return
    if args.profile:
        import cProfile
        import pstats
        ns = build(args.profile, 1, args.scheme)
        ns.step()
        pr = cProfile.Profile()
        pr.enable()
        for _ in range(20):
            ns.step()
        pr.disable()
        pstats.Stats(pr).sort_stats("tottime").print_stats(12)
        return
    print(f"SpectralNS.step, scheme {args.scheme}, 9 FFTs of 3-vectors' components per step")
    print(f"{'grid':>6} {'threads':>7} {'ms/step':>9} {'best ms':>9} {'ns/pt/step':>11} "
          f"{'steps':>6}")
    for n in sizes:
        for t in (1, 2):
            ns = build(n, t, args.scheme)
            med, best, k = time_steps(ns, args.steps if n < 128 else max(5, args.steps // 4),
                                      1.0 if n < 128 else 3.0)
            print(f"{n:>5}^3 {t:>7} {med * 1e3:>9.2f} {best * 1e3:>9.2f} "
                  f"{med / n ** 3 * 1e9:>11.1f} {k:>6}", flush=True)


if __name__ == "__main__":
    main()
