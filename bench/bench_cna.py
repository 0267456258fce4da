"""Common Neighbor Analysis speed (spec 000): seconds and particles/s for noisy FCC crystals.

    .venv/bin/python bench/bench_cna.py [--sizes 10000 100000 1000000] [--noise 0.02]

Periodic FCC (lattice constant 1, cutoff 0.5 (1/sqrt2 + 1)) with Gaussian noise of
``noise`` x the nearest-neighbour distance per coordinate (seeded), single thread
(BLAS/OpenMP pinned to one thread, cKDTree workers=1).  Each size is the best of
``--repeat`` runs of kapsel.analysis.cna.cna (neighbour search included).
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from kapsel.analysis.cna import FCC, cna, fcc_cutoff  # noqa: E402


def noisy_fcc(n_target, noise, seed=0):
    n = max(2, int(round((n_target / 4) ** (1 / 3))))
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 1, 3)
    basis = np.array([[0, 0, 0], [.5, .5, 0], [.5, 0, .5], [0, .5, .5]])
    p = (g + basis).reshape(-1, 3).astype(np.float64)
    p += np.random.default_rng(seed).normal(0.0, noise / np.sqrt(2), p.shape)
    return p, np.full(3, float(n))


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    print(f"{'N':>10} {'seconds':>9} {'particles/s':>12} {'FCC %':>7}")
    for size in a.sizes:
        p, box = noisy_fcc(size, a.noise)
        best = np.inf
        for _ in range(a.repeat):
            t = time.perf_counter()
            lab = cna(p, box, fcc_cutoff(1.0))
            best = min(best, time.perf_counter() - t)
        print(f"{len(p):>10d} {best:>9.3f} {len(p) / best:>12.4g} "
              f"{100 * np.mean(lab == FCC):>7.2f}", flush=True)


if __name__ == "__main__":
    main()
