"""Where a time step goes: cProfile of ``model.advance()`` for a scene of bench_vs_original.

    .venv/bin/python bench/profile_step.py SCENE [--steps N] [--top K] [--np NP] [--memory]

Builds the scene's input (bench_vs_original.make_input), the model as the CLI does, runs 3
warm-up steps, then N steps (default 20) under cProfile and prints the functions by their own
(tottime) and cumulative time per step, plus the CPU ms/step without the profiler.
The compiled kernels (kapsel.compiled) are on, as in a long CLI run; KAPSEL_PY_COMPILED=0
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

from bench_vs_original import SCENES, make_input  # noqa: E402


def build(name, np_override=None):
    import udf
    from kapsel import config, models  # noqa: F401
    from kapsel.cli import build_parser
    from kapsel.simulation import SOLVERS
    edits = dict(SCENES[name][2])
    if np_override:
        edits["np"] = np_override
    d = Path(tempfile.mkdtemp(prefix=f"prof-{name}-"))
    path = make_input(d, edits, 2)
    doc = udf.UDFManager(str(path))
    cfg = config.from_document(doc, str(path))
    args = build_parser().parse_args([f"-I{path}", "--seed", "1", "--quiet"])
    return SOLVERS[cfg.type](cfg, args, doc)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", choices=list(SCENES))
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--np", type=int, default=None)
    ap.add_argument("--memory", action="store_true")
    ap.add_argument("--time-only", action="store_true",
                    help="print only the CPU ms/step of N steps (no profile)")
    a = ap.parse_args(argv)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    model = build(a.scene, a.np)
    from kapsel import compiled
    compiled.enable()       # as a long CLI run from step 10 on (KAPSEL_PY_COMPILED=0: never)
    for _ in range(3):
        model.advance()
    t0 = time.process_time()
    for _ in range(a.steps):
        model.advance()
    ms = (time.process_time() - t0) / a.steps * 1e3
    if a.memory:
        import numpy as np
        npts = int(np.prod(model.cfg.mesh.shape))
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print(f"peak RSS {rss / 1024:.0f} MB (before the model {rss0 / 1024:.0f} MB): "
              f"{(rss - rss0) * 1024 / npts:.0f} bytes per grid point at {model.cfg.mesh.shape}")
    if a.time_only:
        print(f"{ms:.3f}")
        return
    print(f"{a.scene}: {ms:.1f} ms/step CPU (no profiler), dt = {model.dt:g}")
    pr = cProfile.Profile()
    pr.enable()
    for _ in range(a.steps):
        model.advance()
    pr.disable()
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
