"""Electrophoresis of one weakly charged sphere against Henry's function: the runs behind
tests/validation/test_electrolyte_mobility.py and the numbers of docs/physics-electrolyte.md, at any size.

    PYTHONPATH=. .venv/bin/python bench/electrophoresis.py --npx 5 --A 4 --debye 8 --Z -10 \
        [--E 0.01] [--T 150] [--every 10] [--ratio 1.0266]

ex01/colloid_1.udf shrunk to 2^npx cells per side (1:1 salt, Poisson-Boltzmann start,
DC field E along x, FIX_CELL, auto dt), one sphere at the centre.  Prints every ``every``
time units t, V_x, V_x / v_Henry(A) and V_x / (C v_Henry(a_h)), where a_h is the
hydrodynamic radius for a measured Hasimoto drag ratio V / V_Hasimoto(A) = ``ratio``
(1.0266 for A = 4, 32^3, dt = 0.0715; tests/builders.py terminal_velocity) and C
the periodic correction (tests/validation/test_electrolyte_mobility.py's docstring).

Measured (h16, 2026-11-29, shared 2-core machine):
    --npx 5 --A 4 --debye 8 --Z -10 --T 190          0.892 of Henry(A); / C(a_h) 0.991
    --npx 5 --A 4 --debye 1.3333 --Z -30 --T 100     1.066;              1.055
    --npx 5 --A 4 --debye 1 --Z -40 --T 140          1.10;               1.087
    --npx 6 --A 8 --debye 2.6667 --Z -60 --T 190     0.978 (rising, tau = 50: 0.985); C(A) = 0.981
    --npx 6 --A 4 --debye 8 --Z -10 --T 260          0.991 at t = 250 (tau ~ 70); C(A) = 0.981
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))


def main(argv=None):
    import numpy as np
    from test_electrolyte import make_input, model_of
    from test_electrolyte_mobility import (henry_velocity, hydrodynamic_radius,
                                           periodic_correction)
    from udf import UDFManager
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--npx", type=int, default=5)
    ap.add_argument("--A", type=float, default=4.0)
    ap.add_argument("--debye", type=float, default=8.0)
    ap.add_argument("--Z", type=float, default=-10.0)
    ap.add_argument("--E", type=float, default=0.01)
    ap.add_argument("--T", type=float, default=150.0)
    ap.add_argument("--every", type=float, default=10.0)
    ap.add_argument("--ratio", type=float, default=1.0266,
                    help="measured V / V_Hasimoto(A) of the SPM sphere (a_h)")
    a = ap.parse_args(argv)
    n = 2 ** a.npx
    with tempfile.TemporaryDirectory(prefix="electrophoresis-") as d:
        p = make_input(d, npx=a.npx, particles=[[n / 2, n / 2, n / 2]], salt=True,
                       field="DC", init="Poisson_Boltzmann", charge=a.Z, debye=a.debye,
                       A=a.A)
        u = UDFManager(p)
        u.put(a.E, "constitutive_eq.Electrolyte.Electric_field.ON.DC.Ex")
        u.write(p)
        m = model_of(p)
        a_h = hydrodynamic_radius(a.ratio, a.A, n)
        v_A = henry_velocity(a.Z, a.A, a.debye, a.E)
        v_h = henry_velocity(a.Z, a_h, a.debye, a.E) * periodic_correction(a_h, a.debye, n)
        print(f"# {n}^3, A = {a.A}, a_h = {a_h:.4f}, lambda_D = {a.debye}, kappa A = "
              f"{a.A / a.debye:.3f}, Z = {a.Z}, E = {a.E}, dt = {m.dt:.6g}; v_Henry(A) = "
              f"{v_A:.5e}, C v_Henry(a_h) = {v_h:.5e}", flush=True)
        every = max(1, int(round(a.every / m.dt)))
        t0 = time.perf_counter()
        for i in range(1, int(round(a.T / m.dt)) + 1):
            m.advance()
            if i % every == 0:
                v = m.particles.v[0, 0]
                print(f"{m.time:9.3f} {v:.6e} {v / v_A:.4f} {v / v_h:.4f}", flush=True)
        print(f"# {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
