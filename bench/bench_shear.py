"""Time per step of every sheared type against its unsheared twin, on the manual's sample
scene (its particles, kBT, LJ) at 32^3 and 64^3, shear rate 0.01 (DC), 1 thread:

    Shear_Navier_Stokes, Shear_Navier_Stokes_Lees_Edwards   vs  Navier_Stokes
    Shear_Navier_Stokes_Lees_Edwards_FDM (explicit, implicit) vs Navier_Stokes_FDM
    Shear_NS_LE_CH_FDM (NS / CH schemes)                      vs  Navier_Stokes_Cahn_Hilliard_FDM

    .venv/bin/python bench/bench_shear.py [--sizes 5 6] [--steps 10] [--warmup 3]

Prints ms per step (best of the timed steps' mean over two rounds) and the ratio.

Measured (2026-11, shared 2-core machine, default arguments):

    grid                           sheared type        NS        CH   ms/step   twin ms  ratio
      32^3                    Shear_Navier_Stokes         -         -       1.9       1.9   1.01
      32^3       Shear_Navier_Stokes_Lees_Edwards         -         -       2.6       1.9   1.38
      32^3   Shear_Navier_Stokes_Lees_Edwards_FDM  explicit         -       4.3       2.1   2.08
      32^3   Shear_Navier_Stokes_Lees_Edwards_FDM  implicit         -      25.0       8.7   2.87
      32^3                     Shear_NS_LE_CH_FDM  explicit  implicit      14.6       9.2   1.58
      32^3                     Shear_NS_LE_CH_FDM  implicit  implicit      36.3      15.9   2.28
      64^3                    Shear_Navier_Stokes         -         -      16.7      17.2   0.97
      64^3       Shear_Navier_Stokes_Lees_Edwards         -         -      20.4      17.2   1.19
      64^3   Shear_Navier_Stokes_Lees_Edwards_FDM  explicit         -      28.2      16.6   1.70
      64^3   Shear_Navier_Stokes_Lees_Edwards_FDM  implicit         -     167.5     104.5   1.60
      64^3                     Shear_NS_LE_CH_FDM  explicit  implicit     124.0      84.6   1.47
      64^3                     Shear_NS_LE_CH_FDM  implicit  implicit     272.9     150.5   1.81

The Lees-Edwards spectral step pays the per-step metric (exact viscous factor, projection)
and a second profile evaluation (the grid moves with the frame); the oblique MAC pays the
mixed-derivative viscous term and, in the implicit scheme, the matrix-free operator instead
of the assembled CSR of the rectangular solver (the mixed derivative widens the stencil).
"""
import argparse
import os
import sys
import tempfile
import time
from types import SimpleNamespace

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from kapsel import config, models  # noqa: E402,F401
from kapsel.typespec import SOLVERS  # noqa: E402
from udf import UDFManager  # noqa: E402

SAMPLES = os.path.join(os.path.dirname(__file__), "..", "samples")

PAIRS = [  # (sheared type, twin, NS scheme, CH scheme)
    ("Shear_Navier_Stokes", "Navier_Stokes", None, None),
    ("Shear_Navier_Stokes_Lees_Edwards", "Navier_Stokes", None, None),
    ("Shear_Navier_Stokes_Lees_Edwards_FDM", "Navier_Stokes_FDM", "explicit_scheme", None),
    ("Shear_Navier_Stokes_Lees_Edwards_FDM", "Navier_Stokes_FDM", "implicit_scheme", None),
    ("Shear_NS_LE_CH_FDM", "Navier_Stokes_Cahn_Hilliard_FDM", "explicit_scheme",
     "implicit_scheme"),
    ("Shear_NS_LE_CH_FDM", "Navier_Stokes_Cahn_Hilliard_FDM", "implicit_scheme",
     "implicit_scheme"),
]


def model(tmp, eq, npx, ns, ch):
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    base = f"constitutive_eq.{eq}"
    for ax in ("NPX", "NPY", "NPZ"):
        u.put(npx, f"mesh.{ax}")
    if eq.startswith("Shear"):
        u.put("DC", f"{base}.External_field.type")
        u.put(0.01, f"{base}.External_field.DC.Shear_rate")
    if ns is not None:
        u.put(ns, f"{base}.NS_solver.type")
    if ch is not None:
        u.put(ch, f"{base}.CH_solver.type")
    path = os.path.join(tmp, f"{eq}_{npx}_{ns}_{ch}.udf")
    u.write(path)
    cfg = config.load(path)
    return SOLVERS[eq](cfg, SimpleNamespace(seed=1, quiet=True, threads=1), u)


def time_step(m, warmup, steps):
    for _ in range(warmup):
        m.advance()
    best = float("inf")
    for _ in range(2):
        t0 = time.perf_counter()
        for _ in range(steps):
            m.advance()
        best = min(best, (time.perf_counter() - t0) / steps)
    return best * 1e3


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 6])
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=3)
    a = ap.parse_args()
    print(f"{'grid':>5} {'sheared type':>38} {'NS':>9} {'CH':>9} {'ms/step':>9} "
          f"{'twin ms':>9} {'ratio':>6}")
    twins = {}
    with tempfile.TemporaryDirectory() as tmp:
        for npx in a.sizes:
            steps = a.steps if npx <= 5 else max(3, a.steps // 2)
            for eq, twin, ns, ch in PAIRS:
                key = (npx, twin, ns, ch)
                if key not in twins:
                    twins[key] = time_step(model(tmp, twin, npx, ns, ch), a.warmup, steps)
                t = time_step(model(tmp, eq, npx, ns, ch), a.warmup, steps)
                short = lambda s: (s or "-").replace("_scheme", "")  # noqa: E731
                print(f"{2 ** npx:>4}^3 {eq:>38} {short(ns):>9} {short(ch):>9} {t:9.1f} "
                      f"{twins[key]:9.1f} {t / twins[key]:6.2f}", flush=True)


if __name__ == "__main__":
    main()
