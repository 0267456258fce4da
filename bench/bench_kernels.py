"""The compiled passes a change touched, timed in two trees side by side (CPU ms a call).

    .venv/bin/python bench/bench_kernels.py [TREE ...] [--np N] [--repeat R]

Each case is what a step does at that point, made with the kernels the tree has (so a
tree before a fusion times the passes the fusion replaced):

- ``u* after the update``: the ETD1 update of u_hat and the components of u_hat / N for the
  c2r of u* (``project_etd1_velocity``; before 4077578: ``project_etd1`` and three
  ``frame_component`` sweeps);
- ``LE u and omega for u x omega``: the components of the truncated Cartesian u / N and
  of its vorticity for their c2r (``velocity_vorticity``; before it: three
  ``frame_component`` and three ``frame_vorticity_component`` sweeps);
- ``LE u x omega, contravariant``: ``cross_contravariant`` in place (before 94d94ee: into a
  third array);
- ``ions charge density`` (2 species) and ``ions flux`` (advected, the surface points of 8
  spheres of radius 5): the Electrolyte's passes (8f3ebc0).

Every tree runs in its own process (PYTHONPATH = the tree, the kernels loaded as a run loads
them: built ahead of time when current), the trees alternately ``--repeat`` times (default
3); each run gives the best of 5 rounds of 10 calls.  The table has the median over the
repeats.  Default trees: this checkout.  The arrays are random (the same seed in each tree):
the times, not the values, are compared (bit identity is the tests' and bench/bitident.py's).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _best(fn, reps=10, rounds=5):
    best = float("inf")
    for _ in range(rounds):
        t0 = time.process_time()
        for _ in range(reps):
            fn()
        best = min(best, (time.process_time() - t0) / reps * 1e3)
    return best


def worker(n):
    """{case: ms} with the kernels of the package on sys.path."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import numpy as np
    import kapsel.fluid.ions  # noqa: F401   (the slots' modules)
    import kapsel.fluid.spectral  # noqa: F401
    from kapsel.fluid import spectral_kernels
    from kapsel.mesh import compiled
    from kapsel.mesh.grid import Grid
    compiled.enable()
    K, KI = compiled.spectral, compiled.ions
    g = Grid((n, n, n), 1.0)
    rng = np.random.default_rng(0)
    shape = (3,) + g.cshape
    nl = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    uh = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * g.dealias_f
    E = np.exp(-0.01 * g.k2)
    a1 = np.ascontiguousarray(0.05 * g.dealias_f * np.ones(g.cshape))
    k1 = [np.ascontiguousarray(k) for k in g.k_axes]
    inv_k2 = np.ascontiguousarray(g.inv_k2)
    box = g.dealias_box
    s = g.empty_complex(None)
    out = {}
    if hasattr(spectral_kernels, "project_etd1_velocity"):
        out["u* after the update"] = _best(lambda: K.project_etd1_velocity(
            nl, uh, E, a1, *k1, inv_k2, *box, 1.0))
    else:
        def apart():
            K.project_etd1(nl, uh, E, a1, *k1, inv_k2, False)
            for c in range(3):
                K.frame_component(uh, *box, 1.0, 0.0, c, False, s)
        out["u* after the update"] = _best(apart)
    t, c3 = g.empty_complex(None), g.empty_complex(None)
    if hasattr(spectral_kernels, "velocity_vorticity"):
        def le():
            K.velocity_vorticity(uh, *box, 1.0, 0.1, *k1, nl, s, t, c3)
    else:
        def le():
            for c in range(3):
                K.frame_component(uh, *box, 1.0, 0.1, c, True, s)
            for c in range(3):
                K.frame_vorticity_component(uh, *box, 1.0, 0.1, *k1, c, s)
    out["LE u and omega for u x omega"] = _best(le)
    u, w = rng.standard_normal((3,) + g.shape), rng.standard_normal((3,) + g.shape)
    if spectral_kernels.cross_contravariant.py_func.__code__.co_argcount == 3:
        out["LE u x omega, contravariant"] = _best(lambda: K.cross_contravariant(u, w, 0.1))
    else:
        third = np.empty_like(u)
        out["LE u x omega, contravariant"] = _best(
            lambda: K.cross_contravariant(u, w, third, 0.1))
    cs, z = rng.random((2,) + g.shape), np.array([1.0, -1.0])
    phi, rho_surf, rho = rng.random(g.shape), rng.standard_normal(g.shape), np.empty(g.shape)
    out["ions charge density"] = _best(lambda: KI.charge_density(cs, z, phi, rho_surf, rho))
    points = set()
    for _ in range(8):
        centre = rng.integers(0, n, 3)
        for d in np.ndindex(13, 13, 13):
            r = np.array(d) - 6
            if 4.5 < np.sqrt(r @ r) < 5.5:
                x, y, q = (centre + r) % n
                points.add((x * n + y) * n + q)
    at = np.array(sorted(points), dtype=np.int64)
    normal = rng.standard_normal((3, at.size))
    inv_n2 = 1.0 / (normal ** 2).sum(axis=0)
    J, grad, c = rng.standard_normal((3,) + g.shape), rng.standard_normal((3,) + g.shape), \
        rng.random(g.shape)
    field = np.array([0.1, 0.0, 0.0])
    out["ions flux"] = _best(lambda: KI.flux(J, grad, field, c, 0.9, 0.3, u, True, at,
                                             normal, inv_n2))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trees", nargs="*", default=[str(ROOT)])
    ap.add_argument("--np", type=int, default=64, help="mesh points per axis (default 64)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        print(json.dumps(worker(a.np)))
        return 0
    trees = [Path(t).resolve() for t in a.trees]
    runs = {t: [] for t in trees}
    load0 = os.getloadavg()[0]
    for _ in range(a.repeat):
        for t in trees:
            env = dict(os.environ, PYTHONPATH=str(t), OMP_NUM_THREADS="1")
            r = subprocess.run([sys.executable, __file__, "--worker", "--np", str(a.np)],
                               env=env, cwd=t, capture_output=True, text=True, check=True)
            runs[t].append(json.loads(r.stdout.strip().splitlines()[-1]))
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    print(f"{stamp}, {a.np}^3, 1 thread, {a.repeat} repeats alternating, load "
          f"{load0:.1f} -> {os.getloadavg()[0]:.1f}; CPU ms a call (median of the repeats)")
    cases = list(runs[trees[0]][0])
    print("| case | " + " | ".join(t.name for t in trees) + " |")
    print("|---|" + "---|" * len(trees))
    for case in cases:
        cells = [f"{statistics.median(r[case] for r in runs[t]):.3f}" for t in trees]
        print(f"| {case} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
