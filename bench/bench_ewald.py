"""Cost of the periodic dipolar Ewald sum (kapsel/particles/ewald.py) against N at fixed
density (0.02 per unit volume, tol 1e-8): prints N, alpha, r_cut / L, k vectors, the real
and reciprocal times and their total; the total should grow about as N^1.5.

    PYTHONPATH=. python bench/bench_ewald.py [N ...]
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")      # single-threaded BLAS, as kapsel-py runs (kapsel.cli)

import sys
import time

import numpy as np

from kapsel.particles import ewald as ew


def main(sizes):
    print(f"{'N':>6} {'alpha':>8} {'rcut/L':>7} {'k vecs':>7} {'real s':>8} {'recip s':>8} "
          f"{'total s':>8}")
    for n in sizes:
        L = (n / 0.02) ** (1 / 3)
        box = np.full(3, L)
        rng = np.random.default_rng(1)
        R, mu = rng.uniform(0, L, (n, 3)), rng.normal(size=(n, 3))
        p = ew.choose_parameters(box, n, 1e-8)
        t0 = time.perf_counter()
        ew._real_space(R, mu, box, p.alpha, p.r_cut)
        t1 = time.perf_counter()
        ew._reciprocal(R, mu, box, p.alpha, p.k_cut)
        t2 = time.perf_counter()
        nk = len(ew.reciprocal_vectors(box, p.k_cut))
        print(f"{n:6d} {p.alpha:8.4f} {p.r_cut / L:7.3f} {nk:7d} {t1 - t0:8.3f} {t2 - t1:8.3f} "
              f"{t2 - t0:8.3f}", flush=True)


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [125, 500, 2000, 8000])
