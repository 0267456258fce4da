"""MAC solver speed (manual §5.1): time per step for explicit and implicit schemes, FFT threads
1 and 2, with BiCGSTAB iteration counts.  Prints a table.

    .venv/bin/python bench/bench_mac.py [--sizes 32 64] [--steps 10] [--threads 1 2]
                                        [--variable] [--linear sparse matfree]

The field is a random divergence-free velocity (Re ~ 1 on the grid scale) and
dt = RHO DX^2 / (ETA pi^2) (auto time increment with k_max = pi/DX, factor 1).  With
--variable the implicit rows are repeated with a viscosity field varying 1..10 (tanh
interfaces), as with viscosity_change ON.  Times are the median over the timed steps.
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")      # single-threaded BLAS, as kapsel-py runs (kapsel.cli)

import argparse
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from kapsel.fluid.mac import MACSolver  # noqa: E402
from kapsel.mesh.grid import Grid


def initial_field(n, rng):
    u = rng.standard_normal((3, n, n, n))
    uh = np.fft.rfftn(u, axes=(1, 2, 3))
    kx, ky, kz = (2 * np.pi * np.fft.fftfreq(n)[:, None, None],
                  2 * np.pi * np.fft.fftfreq(n)[None, :, None],
                  2 * np.pi * np.fft.rfftfreq(n)[None, None, :])
    k2 = kx ** 2 + ky ** 2 + kz ** 2
    uh *= np.exp(-k2 / (2 * 0.5 ** 2))      # smooth: energy at |k| < ~1/DX
    u = np.fft.irfftn(uh, s=(n, n, n), axes=(1, 2, 3))
    return 0.3 * u / np.abs(u).max()


def viscosity_field(n):
    x = np.arange(n)
    psi = np.tanh(3 * np.sin(2 * np.pi * x / n))[:, None, None] * np.ones((n, n, n))
    return 0.5 * (1 + psi) * 1.0 + 0.5 * (1 - psi) * 10.0


def bench(n, scheme, threads, steps, linear, variable):
    rng = np.random.default_rng(0)
    dt = 1.0 / np.pi ** 2
    s = MACSolver(Grid((n, n, n), 1.0), 1.0, 1.0, dt, scheme=scheme, threads=threads,
                  linear=linear)
    u = initial_field(n, rng)
    s.project(u)
    eta = viscosity_field(n) if variable else None
    s.step(u, eta_field=eta)                 # warm-up (plans, sparsity pattern)
    ts, its = [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        s.step(u, eta_field=eta)
        ts.append(time.perf_counter() - t0)
        its.append(s.iterations)
    return float(np.median(ts)), its


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 64])
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--linear", nargs="+", default=["sparse"], choices=["sparse", "matfree"])
    ap.add_argument("--variable", action="store_true",
                    help="also time implicit with a variable viscosity field (ratio 10)")
    a = ap.parse_args()
    print("%-6s %-16s %-8s %-7s %7s %12s  %s" % ("N^3", "scheme", "linear", "threads", "eta",
                                                "ms/step", "BiCGSTAB iterations"))
    for n in a.sizes:
        rows = [("explicit_scheme", "-", False)]
        for lin in a.linear:
            rows.append(("implicit_scheme", lin, False))
            if a.variable:
                rows.append(("implicit_scheme", lin, True))
        for scheme, lin, var in rows:
            for th in a.threads:
                t, its = bench(n, scheme, th, a.steps, lin if lin != "-" else "sparse", var)
                it = "-" if scheme == "explicit_scheme" else "%d-%d (mean %.1f)" % (
                    min(its), max(its), np.mean(its))
                print("%-6d %-16s %-8s %-7d %7s %12.1f  %s" % (
                    n, scheme, lin, th, "var" if var else "const", t * 1e3, it), flush=True)


if __name__ == "__main__":
    main()
