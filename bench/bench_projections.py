"""The two forms of the compiled spectral projections, point by point and by blocks of rows
(kapsel.fluid.spectral_kernels), timed on scratch fields of several shapes.

    .venv/bin/python bench/bench_projections.py [NXxNYxNZ ...] [--repeat R]

For each real-space shape, ``project_add`` and ``project_etd1`` of both forms run alternately
``--repeat`` times (default 15) on the same arrays; the table gives the median ns per mode of
the half spectrum, the ratio rows / points and which form kapsel.fluid.spectral's timing
picks for that shape in this process.  Bit identity of the forms is a test
(tests/unit/test_spectral.py), not measured here.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

DEFAULT = ["32x32x32", "48x48x48", "64x64x32", "32x32x64", "64x64x64", "64x64x128",
           "128x64x64", "96x96x96", "128x128x128"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("shapes", nargs="*", default=DEFAULT)
    ap.add_argument("--repeat", type=int, default=15)
    a = ap.parse_args(argv)
    from kapsel.fluid import spectral
    from kapsel.mesh import compiled
    from kapsel.mesh.grid import Grid
    if not compiled.enable():
        print("numba is not installed: no compiled kernels to time", file=sys.stderr)
        return 2
    K = compiled.spectral
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.uname().nodename}, "
          f"load {os.getloadavg()[0]:.2f}, 1 thread\n")
    print("| shape | add points ns/mode | add rows ns/mode | rows/points | etd1 points | "
          "etd1 rows | rows/points | picked |")
    print("|---|---|---|---|---|---|---|---|")
    for s in a.shapes:
        g = Grid(tuple(int(n) for n in s.split("x")), 1.0)
        cs = g.local_cshape
        n = int(np.prod(cs))
        rng = np.random.default_rng(0)
        d = g.empty_complex()
        u = g.empty_complex()
        d[...] = rng.standard_normal(d.shape)
        u[...] = rng.standard_normal(u.shape)
        w = rng.random(cs)
        k = [rng.random(m) for m in cs]
        runs = {"add": ((K.project_add, K.project_add_rows), lambda f: f(d, u, w, *k, w)),
                "etd1": ((K.project_etd1, K.project_etd1_rows),
                         lambda f: f(d, u, w, w, *k, w, False))}
        cells = []
        for name, (forms, call) in runs.items():
            t = [[], []]
            for f in forms:
                call(f)
            for _ in range(a.repeat):
                for i, f in enumerate(forms):
                    t0 = time.perf_counter()
                    call(f)
                    t[i].append(time.perf_counter() - t0)
            p, r = (statistics.median(x) / n * 1e9 for x in t)
            cells += [f"{p:.1f}", f"{r:.1f}", f"{r / p:.2f}"]
        spectral._PROJECTIONS.pop(cs, None)
        picked = "rows" if spectral.projection_kernels(K, g)[2] is K.project_add_rows else "points"
        print(f"| {s} | " + " | ".join(cells) + f" | {picked} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
