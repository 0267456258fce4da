"""Squirmers against plain Navier_Stokes: ms per SPM step at 64^3.

    .venv/bin/python bench/bench_janus.py [--n 64] [--particles 50] [--steps 10] [--iter 4]

Three runs on the same grid (spectral, FIX_CELL on, dt = 0.07, one thread):
no particles; ``--particles`` passive spheres; the same number of squirmers (B1 = 0.01,
alpha = -1, SLIP_tol 0: every step does ``--iter`` slip passes, the worst case; the
original's ex09 uses SLIP_tol 0.005, SLIP_iter 4).  A = 4, xi = 2, random non-overlapping
positions and orientations.  Times: median over the timed steps after 3 warm-up steps.
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from kapsel.fluid.spectral import SpectralNS  # noqa: E402
from kapsel.mesh.grid import Grid  # noqa: E402
from kapsel.particles.janus import Janus, JanusSpec  # noqa: E402
from kapsel.particles.placement import orientations, uniform_random  # noqa: E402
from kapsel.particles.spm import SPM  # noqa: E402
from kapsel.particles.state import ParticleState  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_spm import time_steps  # noqa: E402  (median ms of a step after 3 warm-up steps)

A, XI = 4.0, 2.0


def build(n, npart, squirm, slip_iter, seed=0):
    dt = 0.07
    fluid = SpectralNS(Grid((n, n, n), 1.0), 1.0, 1.0, dt, fix_cell=(True, True, True))
    rng = np.random.default_rng(seed)
    p = ParticleState.spheres([0] * npart, [A] * npart, [1.0] * npart, 1.0)
    if npart:
        p.R[:] = uniform_random(npart, np.full(npart, A + 0.5), np.full(3, float(n)), rng)
        p.R_raw[:] = p.R
        p.q[:] = orientations("random", npart, rng)
        p.q_old[:] = p.q
    if squirm:
        p.janus = Janus(p.species, [JanusSpec("Z", "SQUIRMER", slip_vel=0.01,
                                              slip_mode=-1.0)], 0.0, slip_iter)
    return SPM(fluid, p, A, XI, 1.0, 1.0, dt)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--particles", type=int, default=50)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--iter", type=int, default=4)
    a = ap.parse_args()
    base = None
    for label, npart, squirm in (("Navier_Stokes, no particles", 0, False),
                                 (f"Navier_Stokes, {a.particles} spheres", a.particles, False),
                                 (f"{a.particles} squirmers, {a.iter} slip passes",
                                  a.particles, True)):
        t = time_steps(build(a.n, npart, squirm, a.iter), a.steps)
        base = base or t
        print(f"{a.n}^3 {label:38s} {1e3 * t:9.1f} ms/step  ({t / base:.2f} x)", flush=True)


if __name__ == "__main__":
    main()
