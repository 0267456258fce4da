"""Time per step of the two-component FDM type (Navier_Stokes_Cahn_Hilliard_FDM): the manual's
sample (32^3, 8 particles) and the same scene at 64^3, every NS / CH solver pair, 1 and 2
threads, with the BiCGSTAB iteration counts of the last step.  Prints a table.

    .venv/bin/python bench/bench_fdm.py [--steps 20] [--warmup 20] [--sizes 5 6]
"""
import argparse
import os
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

import numpy as np  # noqa: E402

from kapsel import config  # noqa: E402
from kapsel.models.fdm import FDMModel  # noqa: E402
from udf import UDFManager  # noqa: E402

SAMPLES = os.path.join(os.path.dirname(__file__), "..", "samples")
NS_CH = "constitutive_eq.Navier_Stokes_Cahn_Hilliard_FDM"


class Args:
    seed = 1
    quiet = True

    def __init__(self, threads):
        self.threads = threads


def scene(tmp, np_, ns, ch):
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    for ax in ("NPX", "NPY", "NPZ"):
        u.put(np_, f"mesh.{ax}")
    u.put(ns, f"{NS_CH}.NS_solver.type")
    u.put(ch, f"{NS_CH}.CH_solver.type")
    path = os.path.join(tmp, f"in_{np_}_{ns}_{ch}.udf")
    u.write(path)
    return config.load(path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 6])
    a = ap.parse_args()
    print(f"{'grid':>6} {'NS solver':>16} {'CH solver':>16} {'thr':>3} {'ms/step':>9} "
          f"{'ns/pt/step':>10} {'NS it':>6} {'CH it':>6} {'CH sub':>6}")
    with tempfile.TemporaryDirectory() as tmp:
        for np_ in a.sizes:
            for ns in ("explicit_scheme", "implicit_scheme"):
                for ch in ("explicit_scheme", "implicit_scheme"):
                    cfg = scene(tmp, np_, ns, ch)
                    for threads in (1, 2):
                        m = FDMModel(cfg, Args(threads))
                        for _ in range(a.warmup):
                            m.advance()
                        t0 = time.perf_counter()
                        for _ in range(a.steps):
                            m.advance()
                        dt = (time.perf_counter() - t0) / a.steps
                        n = int(np.prod(cfg.mesh.shape))
                        nsit = m.mac.iterations if ns == "implicit_scheme" else "-"
                        chit = m.ch.iterations if ch == "implicit_scheme" else "-"
                        print(f"{2 ** np_:>4}^3 {ns:>16} {ch:>16} {threads:>3} {dt * 1e3:9.1f} "
                              f"{dt / n * 1e9:10.0f} {nsit!s:>6} {chit!s:>6} {m.substeps:>6}",
                              flush=True)


if __name__ == "__main__":
    main()
