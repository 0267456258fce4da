"""Where a time step goes: cProfile of ``model.advance()`` for a scene of bench_vs_original.

    .venv/bin/python bench/profile_step.py SCENE [--steps N] [--top K] [--np NP] [--memory]

Builds the scene's input (samples/input.udf with the scene's edits), the model as the CLI does, runs 3
warm-up steps, then N steps (default 20) under cProfile and prints the functions by their own
(tottime) and cumulative time per step, plus the CPU ms/step without the profiler.
The compiled kernels (kapsel.mesh.compiled) are on, as in a long CLI run; KAPSEL_PY_COMPILED=0
times the numpy passes.  ``--np NP`` overrides the mesh (2^NP per axis).  ``--memory``: peak RSS (ru_maxrss) after the
steps, per grid point, minus the RSS before the model was built.
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):   # as kapsel.cli,
    os.environ.setdefault(_v, "1")                                        # before numpy

import argparse  # noqa: E402
import cProfile
import io
import pstats
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_vs_original import SAMPLE, SCENES  # noqa: E402


def make_input(d: Path, edits: dict) -> Path:
    """input.udf of a scene in ``d``: samples/input.udf with ``edits`` (UDF path -> value)."""
    import shutil
    from udf import UDFManager
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(SAMPLE.parent / f, d / f)
    u = UDFManager(str(SAMPLE))
    for k, v in edits.items():
        u.put(v, k)
    u.write(str(d / "input.udf"))
    return d / "input.udf"


# stage of a profiled function (own time), by file and name; first match wins
STAGES = (
    ("FFT", ("grid.py:forward", "grid.py:backward", "grid.py:rfft_scalar",
             "grid.py:irfft_scalar", "grid.py:_run_scalar", "grid.py:_aligned", "mac.py:solve",
             "pyfftw", "pocketfft", "scipy/fft", "pencil.py:forward", "pencil.py:backward")),
    ("linear solver", ("_isolve", "linalg.py", "_sparsetools", "mac.py:mv", "_interface.py",
                       "mac.py:_assemble", "stencils.py:implicit_matvec", "method 'dot'",
                       "cahn_hilliard.py:mv", "cahn_hilliard.py:solve")),
    ("MAC stencils", ("operators.py", "stencils.py", "_aot_kernels.stencils__")),
    ("spectral element-wise", ("spectral_kernels.py", "fluid/spectral.py", "grid.py:project",
                               "grid.py:k_dot", "oblique.py", "_aot_kernels.spectral__",
                               "ions_kernels.py", "_aot_kernels.ions__")),
    ("phase field", ("phase/",)),
    ("particles", ("particles/", "models/common.py")),
)


def stage_table(stats, steps):
    """ms per step by stage (own time of the functions), from a pstats.Stats."""
    acc = {}
    for (fname, _line, func), (_cc, _nc, tt, _ct, _callers) in stats.stats.items():
        key = f"{fname}:{func}"
        stage = next((name for name, pats in STAGES if any(p in key for p in pats)), "other")
        acc[stage] = acc.get(stage, 0.0) + tt
    total = sum(acc.values())
    rows = sorted(acc.items(), key=lambda kv: -kv[1])
    return total / steps * 1e3, [(k, v / steps * 1e3, v / total) for k, v in rows]


def build(name, np_override=None, threads=1):
    import udf
    from kapsel import config, models  # noqa: F401
    from kapsel.cli import build_parser
    from kapsel import typespec
    SOLVERS = getattr(typespec, "SOLVERS", None)
    if not SOLVERS:         # a tree before the registry moved (before/after comparisons)
        from kapsel.simulation import SOLVERS
    edits = dict(SCENES[name][1])
    if np_override:
        edits.update({f"mesh.NP{ax}": np_override for ax in "XYZ"})
    d = Path(tempfile.mkdtemp(prefix=f"prof-{name}-"))
    path = make_input(d, edits)
    doc = udf.UDFManager(str(path))
    cfg = config.from_document(doc, str(path))
    args = build_parser().parse_args([f"-I{path}", "--seed", "1", "--quiet",
                                      "--threads", str(threads)])
    return SOLVERS[cfg.type](cfg, args, doc)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", choices=list(SCENES))
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--np", type=int, default=None)
    ap.add_argument("--memory", action="store_true")
    ap.add_argument("--threads", type=int, default=1, help="as kapsel-py --threads")
    ap.add_argument("--wall", action="store_true",
                    help="with --time-only: print wall ms/step too")
    ap.add_argument("--time-only", action="store_true",
                    help="print only the CPU ms/step of N steps (no profile)")
    ap.add_argument("--stages", action="store_true",
                    help="print only the profiled time per stage (FFT, stencils, ...)")
    a = ap.parse_args(argv)
    try:
        from kapsel.mesh import compiled
        from kapsel.mesh import stencils as st
    except ImportError:     # a tree before kapsel.mesh (before/after comparisons)
        from kapsel.fluid import compiled, stencils as st
    import kapsel.fluid.spectral  # noqa: F401  (provides its kernels to the switch)
    if compiled.enable():   # as a long CLI run from step 10 on (KAPSEL_PY_COMPILED=0: never)
        import numpy as np
        from kapsel.fluid import spectral_kernels as sk
        z, f = np.zeros((3, 4, 4, 4)), np.zeros((4, 4, 4))
        st.div_b(z, 1.0, f)                 # numba's code generator loaded before the RSS base
        sk.cross(z, z, z.copy())
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    model = build(a.scene, a.np, a.threads)
    for _ in range(3):
        model.advance()
    t0, w0 = time.process_time(), time.perf_counter()
    for _ in range(a.steps):
        model.advance()
    ms = (time.process_time() - t0) / a.steps * 1e3
    wall = (time.perf_counter() - w0) / a.steps * 1e3
    if a.memory:
        import numpy as np
        npts = int(np.prod(model.cfg.mesh.shape))
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print(f"peak RSS {rss / 1024:.0f} MB (before the model {rss0 / 1024:.0f} MB): "
              f"{(rss - rss0) * 1024 / npts:.0f} bytes per grid point at {model.cfg.mesh.shape}")
    if a.time_only:
        print(f"{ms:.3f}" + (f" wall {wall:.3f}" if a.wall else ""))
        return
    print(f"{a.scene}: {ms:.1f} ms/step CPU (no profiler), dt = {model.dt:g}")
    pr = cProfile.Profile()
    pr.enable()
    for _ in range(a.steps):
        model.advance()
    pr.disable()
    if a.stages:
        total, rows = stage_table(pstats.Stats(pr), a.steps)
        print(f"profiled {total:.1f} ms/step: " + ", ".join(
            f"{k} {ms:.1f} ({100 * f:.0f}%)" for k, ms, f in rows))
        return
    for key in ("tottime", "cumulative"):
        s = io.StringIO()
        st = pstats.Stats(pr, stream=s)
        st.sort_stats(key).print_stats(a.top)
        lines = s.getvalue().splitlines()
        print(f"--- by {key} (seconds over {a.steps} steps)")
        start = next(i for i, ln in enumerate(lines) if ln.lstrip().startswith("ncalls"))
        print("\n".join(lines[start:start + a.top + 1]))


if __name__ == "__main__":
    main()
