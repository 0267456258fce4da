"""SPM step speed with the spectral solver: steps/s and ns per grid point per step.

    .venv/bin/python bench/bench_spm.py [--big] [--steps 20] [--threads 1 2] [--profile]

Grids 32^3, 64^3 (and 128^3 with --big); 0, 1 and 100 particles (A = 4, xi = 2, random
non-overlapping positions, small random velocities so the coupling does real work);
dt = auto_dt(1).  Combinations that cannot hold the particles (volume fraction > 0.35)
are skipped.  Times: median over the timed steps after 3 warm-up steps.
--profile prints the split of one configuration (64^3, 100 particles, 1 thread).
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")      # single-threaded BLAS, as kapsel-py runs (kapsel.cli)

import argparse
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from kapsel.fluid.spectral import SpectralNS  # noqa: E402
from kapsel.mesh.grid import Grid  # noqa: E402
from kapsel.particles.placement import uniform_random  # noqa: E402
from kapsel.particles.spm import SPM  # noqa: E402
from kapsel.particles.state import ParticleState  # noqa: E402
from kapsel.timestep import auto_dt  # noqa: E402

A, XI = 4.0, 2.0


def build(n, npart, threads, seed=0):
    dt = auto_dt(1.0, 1.0, 1.0, 1.0, (n, n, n))
    grid = Grid((n, n, n), 1.0, threads=threads)
    fluid = SpectralNS(grid, 1.0, 1.0, dt, fix_cell=(True, True, True))
    rng = np.random.default_rng(seed)
    p = ParticleState.spheres([0] * npart, [A] * npart, [1.0] * npart, 1.0)
    if npart:
        p.R[:] = uniform_random(npart, np.full(npart, A + 0.5), np.full(3, float(n)), rng)
        p.R_raw[:] = p.R
        p.v[:] = rng.normal(scale=1e-2, size=(npart, 3))
        p.omega[:] = rng.normal(scale=1e-3, size=(npart, 3))
    F = rng.normal(scale=0.1, size=(npart, 3))
    return SPM(fluid, p, A, XI, 1.0, 1.0, dt, forces=lambda q: (F, np.zeros_like(F)))


def time_steps(spm, steps):
    """Median wall time of one ``spm.step()`` over ``steps`` steps, after 3 warm-up steps."""
    for _ in range(3):
        spm.step()
    ts = []
    for _ in range(steps):
        t0 = time.perf_counter()
        spm.step()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def profile(steps):
    """Split of the 64^3 / 100-particle step into its parts (ms, median)."""
    from kapsel.particles import coupling, motion, profile as prof
    spm = build(64, 100, 1)
    p = spm.p
    parts = {}

    def t(name, f, *a, **k):
        t0 = time.perf_counter()
        r = f(*a, **k)
        parts.setdefault(name, []).append(time.perf_counter() - t0)
        return r

    for _ in range(steps):
        t("fluid step", spm.fluid.step)
        u = t("velocity (irfft)", spm.fluid.velocity, out=spm.u)
        F, T = t("hydro force", coupling.hydro_force_torque, u, spm.idx, spm.phi_i, spm.r,
                 p.v, p.omega, 1.0, 1.0, spm.dt)
        t("update velocities", motion.update_velocities, p, F, T, None, None, spm.dt, True,
          mass=spm.mass, inertia=spm.inertia)
        du = t("rigidity increment", coupling.rigidity_increment, u, spm.idx, spm.phi_i, spm.r,
               p.v, p.omega, spm.size)
        t("add_solenoidal", spm.fluid.add_solenoidal, du)
        t("update positions", motion.update_positions, p, spm.dt, spm.box, True)
        t("profiles", spm._profiles)
    del prof
    total = sum(np.median(v) for v in parts.values())
    for k, v in parts.items():
        print(f"  {k:20s} {1e3 * np.median(v):8.2f} ms")
    print(f"  {'total':20s} {1e3 * total:8.2f} ms = {1e9 * total / 64 ** 3:.0f} ns/point")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--big", action="store_true", help="add 128^3")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--particles", type=int, nargs="+", default=[0, 1, 100])
    ap.add_argument("--profile", action="store_true")
    a = ap.parse_args()
    if a.profile:
        profile(a.steps)
        return
    sizes = [32, 64] + ([128] if a.big else [])
    print(f"{'grid':>6} {'N':>4} {'thr':>3} {'ms/step':>9} {'steps/s':>8} {'ns/pt/step':>10}")
    for n in sizes:
        for npart in a.particles:
            if npart * 4 / 3 * np.pi * (A + 0.5) ** 3 > 0.35 * n ** 3:
                print(f"{n:>4}^3 {npart:>4}   - skipped (volume fraction too high)")
                continue
            for th in a.threads:
                spm = build(n, npart, th)
                t = time_steps(spm, a.steps)
                print(f"{n:>4}^3 {npart:>4} {th:>3} {1e3 * t:9.2f} {1 / t:8.1f} "
                      f"{1e9 * t / n ** 3:10.0f}", flush=True)


if __name__ == "__main__":
    main()
