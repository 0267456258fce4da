"""SPM drag against Hasimoto (issue 17): how the sphere's hydrodynamic radius depends on the
time step and the interface width, and what ``--spm-drag calibrated`` makes of it.

    .venv/bin/python bench/spm_drag_calibration.py [--points XI:FACTOR ...] [--A 4] [--L 32]
                                                   [--solver spectral|explicit_scheme|
                                                    implicit_scheme] [--calibrated] [--fit]

One sphere (radius A, interface XI) in an L^3 periodic box is pulled by F = (1, 0, 0) (RHO =
ETA = DX = 1, FIX_CELL on: the mean fluid velocity is held at 0) until its velocity is
steady (relative change < 2e-4 over half the slowest decay time L^2 / (4 pi^2), Aitken
extrapolated).  Printed per point: V / V_Hasimoto (V_H = F / (6 pi ETA A K), K Hasimoto's
periodic-array factor), the effective radius a_eff (the radius whose V_H is the measured V),
d = a_eff - A, and ms/step.  dt = factor / (NU KMAX2), the auto time step (kapsel.timestep).

--calibrated gives the SPM the profile radius of kapsel.particles.drag_calibration (the
option --spm-drag calibrated); --fit prints the least-squares coefficients of the offset
d(ell, xi) from the points run (ell = sqrt(NU dt)).
"""
import argparse
import json
import math
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

from kapsel.particles.spm import SPM  # noqa: E402
from kapsel.particles.state import ParticleState  # noqa: E402
from kapsel.timestep import auto_dt  # noqa: E402


def hasimoto_K(a, L):
    c = 4 / 3 * np.pi * a ** 3 / L ** 3
    return 1.0 / (1 - 1.7601 * c ** (1 / 3) + c - 1.5593 * c ** 2 + 3.9799 * c ** (8 / 3)
                  - 3.0734 * c ** (10 / 3))


def effective_radius(V, L, F=1.0):
    """The radius a whose Hasimoto velocity F / (6 pi a K(a)) is V (ETA = 1)."""
    return brentq(lambda a: F / (6 * np.pi * a * hasimoto_K(a, L)) - V, 0.3, L / 3)


class _FixCell(SPM):
    """MAC fluid with the mean velocity removed after each fluid step (FIX_CELL)."""

    def _fluid_step(self):
        self.fluid.step(self.u)
        self.u -= self.u.reshape(3, -1).mean(axis=1)[:, None, None, None]


def terminal_velocity(L, A, xi, factor, solver="spectral", profile=None, tol=2e-4,
                      max_tau=15):
    """(V_x, steps, seconds per step) of the pulled sphere; ``profile``: the SPM's
    profile radius (default A)."""
    dt = auto_dt(factor, 1.0, 1.0, 1.0, (L, L, L))
    if solver == "spectral":
        from kapsel.fluid.spectral import SpectralNS
        from kapsel.mesh.grid import Grid
        fluid, cls = SpectralNS(Grid((L, L, L), 1.0), 1.0, 1.0, dt, fix_cell=(True,) * 3), SPM
    else:
        from kapsel.fluid.mac import MACSolver
        from kapsel.mesh.grid import Grid
        fluid, cls = MACSolver(Grid((L, L, L), 1.0), 1.0, 1.0, dt, scheme=solver), _FixCell
    p = ParticleState.spheres([0], [A], [1.0], 1.0)
    p.R[:] = p.R_raw[:] = [[L / 2 + 0.3, L / 2 + 0.2, L / 2 - 0.3]]
    F = np.array([[1.0, 0.0, 0.0]])
    spm = cls(fluid, p, profile or A, xi, 1.0, 1.0, dt, forces=lambda q: (F, np.zeros((1, 3))))
    tau = L ** 2 / (4 * np.pi ** 2)
    n = max(1, int(round(tau / dt / 2)))
    hist = []
    t0 = time.perf_counter()
    while spm.step_index * dt < max_tau * tau:
        spm.run(n)
        hist.append(p.v[0, 0])
        if len(hist) > 2 and abs(hist[-1] - hist[-2]) < tol * abs(hist[-1]):
            break
    sec = (time.perf_counter() - t0) / spm.step_index
    V = hist[-1]
    if len(hist) >= 3:      # Aitken: the last samples decay geometrically
        d1, d2 = hist[-1] - hist[-2], hist[-2] - hist[-3]
        if d1 != d2 and abs(d1) < abs(d2):
            V = hist[-1] - d1 * d1 / (d1 - d2)
    return V, spm.step_index, sec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", nargs="+", default=["2:1"],
                    help="XI:FACTOR pairs (default 2:1, the manual's sample settings)")
    ap.add_argument("--A", type=float, default=4.0)
    ap.add_argument("--L", type=int, default=32)
    ap.add_argument("--solver", default="spectral",
                    choices=["spectral", "explicit_scheme", "implicit_scheme"])
    ap.add_argument("--calibrated", action="store_true")
    ap.add_argument("--fit", action="store_true")
    ap.add_argument("--json", action="store_true", help="one JSON object per point")
    a = ap.parse_args()
    from kapsel.particles.drag_calibration import profile_radius
    rows = []
    if not a.json:
        print(f"{'solver':<16} {'A':>4} {'xi':>4} {'factor':>6} {'ell':>6} {'profile':>8} "
              f"{'V/V_H':>7} {'a_eff':>7} {'d':>7} {'steps':>6} {'ms/step':>8}")
    for pt in a.points:
        xi, factor = (float(x) for x in pt.split(":"))
        dt = auto_dt(factor, 1.0, 1.0, 1.0, (a.L,) * 3)
        prof = profile_radius(a.A, xi, 1.0, dt, solver=a.solver) if a.calibrated else a.A
        V, steps, sec = terminal_velocity(a.L, a.A, xi, factor, a.solver, prof)
        VH = 1.0 / (6 * np.pi * a.A * hasimoto_K(a.A, a.L))
        ae = effective_radius(V, a.L)
        r = dict(solver=a.solver, A=a.A, xi=xi, factor=factor, ell=math.sqrt(dt),
                 profile=prof, ratio=V / VH, a_eff=ae, d=ae - a.A, steps=steps,
                 ms=1e3 * sec)
        rows.append(r)
        if a.json:
            print(json.dumps(r), flush=True)
        else:
            print(f"{a.solver:<16} {a.A:4g} {xi:4g} {factor:6g} {r['ell']:6.3f} {prof:8.4f} "
                  f"{r['ratio']:7.4f} {ae:7.4f} {r['d']:7.3f} {steps:6d} {r['ms']:8.2f}",
                  flush=True)
    if a.fit and len(rows) >= 6:
        X = np.array([[r["xi"] ** i * r["ell"] ** j for i in range(3) for j in range(3)]
                      for r in rows])
        d = np.array([r["d"] for r in rows])
        c, *_ = np.linalg.lstsq(X, d, rcond=None)
        print("C =", np.array2string(c.reshape(3, 3), precision=5, separator=", "))
        print("residuals:", np.array2string(X @ c - d, precision=3))


if __name__ == "__main__":
    main()
