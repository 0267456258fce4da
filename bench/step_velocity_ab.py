"""The step with u* made by the update's own sweep, against the step then u* made apart:
alternated step by step in one process (CPU ms a step).

    .venv/bin/python bench/step_velocity_ab.py [SCENE ...] [--steps N]

For each scene of bench_vs_original (default ns32 ns64 le64) the model is built as the CLI
builds it, the compiled kernels on, 3 steps run; then N pairs of steps, each pair one step
of each form in alternating order: ``fluid.step(velocity=u)`` (kapsel.fluid.spectral:
``project_etd1_velocity``; kapsel.fluid.oblique: ``project_oblique_etd1_velocity``) and
``fluid.step(); fluid.velocity(out=u)``.  The two give the same bits
(tests/unit/test_spectral.py), so the run is one trajectory whatever the order, and the two
forms meet the same machine: the median of the pairs' ratios is what the fusion gains on a
busy host where separate runs vary by up to 2x.
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))


def measure(scene, steps):
    """(ms a step apart, ms fused: medians; median of the pairs' fused / apart)."""
    from profile_step import build
    from kapsel.mesh import compiled
    compiled.enable()
    model = build(scene)
    spm, fluid = model.spm, model.spm.fluid

    def apart():
        fluid.step()
        fluid.velocity(out=spm.u)

    def fused():
        fluid.step(velocity=spm.u)
    for _ in range(3):
        model.advance()
    t = {apart: [], fused: []}
    try:
        for k in range(steps):
            for form in ((apart, fused) if k % 2 == 0 else (fused, apart)):
                spm._fluid_step = form
                t0 = time.process_time()
                model.advance()
                t[form].append((time.process_time() - t0) * 1e3)
    finally:
        del spm._fluid_step
    ratios = [b / a for a, b in zip(t[apart], t[fused])]
    return statistics.median(t[apart]), statistics.median(t[fused]), statistics.median(ratios)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="*", default=["ns32", "ns64", "le64"])
    ap.add_argument("--steps", type=int, default=100, help="pairs of steps (default 100)")
    a = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    rows = [(s,) + measure(s, a.steps) for s in a.scene]
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    print(f"{stamp}, {a.steps} pairs of steps, 1 thread, load {load0:.1f} -> "
          f"{os.getloadavg()[0]:.1f}")
    print("| scene | u* apart ms | u* in the update ms | fused / apart (median of pairs) |")
    print("|---|---|---|---|")
    for s, x, y, r in rows:
        print(f"| {s} | {x:.2f} | {y:.2f} | {r:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
