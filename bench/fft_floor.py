"""The FFT floor of a time step: how many 3-D transforms a step does, and what they alone cost.

    .venv/bin/python bench/fft_floor.py [SCENE ...] [--steps N] [--repeat R] [--np NP] [--threads T]

For each scene of bench_vs_original (default: the spectral ones) the model is built as the CLI
builds it and advanced 3 steps (the compiled kernels on, as in a long run).  Every FFTW
``execute`` is recorded (pyfftw.FFTW replaced by a subclass that records, before the model
is built): the plan, the arrays it ran on, and the part of the step it ran in.  Then R x N
steps, each timed (CPU ms) and followed at once by its own transforms replayed alone (the
same plans in the same order on the same arrays; the arrays they write restored after):
the floor of that step.  The step and its floor run a few ms apart, so a shared machine's
slow spells fall on both.  The table gives the transforms per step by kind (r2c forward, c2r
backward; a vector field is three; c2c the stages of the transforms that skip the lines of
zeros), the medians of step ms and floor ms, and the median of the steps' ratios (issue 25:
the spectral step within 1.5x of its floor); the same for the fluid's part of the step
(``FLUID_PART``: the solver's step, u* after it, the particles' increment transformed,
projected and added), timed within the same steps, against the replay of the transforms
made within it; the rest of a step is the particles' coupling.  The "hot floor" column runs
each plan's executions of a step back to back on its last arrays, which the cache then
holds: a bound below what any step can reach.  The load average is printed with the table.

    .venv/bin/python bench/fft_floor.py --pruned [--np NP ...]

times one scalar transform of a 2/3-truncated field whole and with the lines of zeros
skipped (kapsel.mesh.grid: ``backward_scalar_truncated``, ``rfft_scalar_truncated``), CPU ms,
the two alternating, the best of 7 rounds.  In the step table the skipped transforms' stages
show as c2c executions beside their r2c / c2r.
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import collections  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import numpy as np  # noqa: E402
import pyfftw  # noqa: E402

SPECTRAL = ("ns32", "ns64", "ns64x100", "le64", "squirmer64", "el64")


class _Counts:
    """Executions per (plan, part of the step) while ``on``; ``part``: "fluid" inside the
    fluid's part of the step (``_FluidPart``), else "particles"; ``seq``: every execution
    in order, (plan, its input array, its output array, part)."""

    def __init__(self):
        self.on = False
        self.part = "particles"
        self.calls = collections.Counter()
        self.plans = {}
        self.seq = []

    def count(self, plan):
        if self.on:
            self.calls[(id(plan), self.part)] += 1
            self.plans[id(plan)] = plan
            self.seq.append((plan, plan.input_array, plan.output_array, self.part))


COUNTS = _Counts()


class CountingFFTW(pyfftw.FFTW):
    """pyfftw.FFTW that counts its executions: ``__call__`` (arrays updated, then
    normalised) runs through ``execute``, so counting there counts each once."""

    def execute(self):
        COUNTS.count(self)
        return super().execute()


def _kind(plan) -> str:
    real_in = plan.input_array.dtype.kind == "f"
    return "r2c" if real_in else "c2r" if plan.output_array.dtype.kind == "f" else "c2c"


#: the particle model's methods that make the fluid's part of a step: the solver's step with
#: u* after it, and the increment's transforms, projection and addition (every transform of
#: a plain step); the rest is the particles' coupling (motion, profiles, sums, the rigidity
#: increment, Lees-Edwards re-gridding; squirmers' slip flow and the Electrolyte's force on
#: the particles make transforms of their own there)
FLUID_PART = ("_fluid_step", "_add_solenoidal")


class _FluidPart:
    """Within the ``with``: the fluid's part of each step of ``model`` timed (``spent``, CPU
    seconds) and its transforms counted as "fluid"."""

    def __init__(self, model):
        self.spm = getattr(model, "spm", None)
        self.spent = 0.0

    def _wrap(self, fn):
        def call(*args, **kwargs):
            t = time.process_time()
            COUNTS.part = "fluid"
            try:
                return fn(*args, **kwargs)
            finally:
                COUNTS.part = "particles"
                self.spent += time.process_time() - t
        return call

    def __enter__(self):
        if self.spm is not None:
            for name in FLUID_PART:
                setattr(self.spm, name, self._wrap(getattr(self.spm, name)))
        return self

    def __exit__(self, *exc):
        if self.spm is not None:
            for name in FLUID_PART:
                delattr(self.spm, name)


def _floor_hot(per_step, steps):
    """CPU ms per step of the plans of ``per_step`` ({plan id: executions per step}) run
    alone, each its executions of a step one after the other on the arrays it last had:
    the cache holds them (a c2r plan destroys its input: the values do not matter for the
    time, only the sizes).  A bound below any step: the step's transforms run on other
    arrays (three components, the scratch of each stage)."""
    schedule = [(COUNTS.plans[k], round(n)) for k, n in per_step.items()]
    for plan, n in schedule:                          # warm the caches of each plan once
        pyfftw.FFTW.execute(plan)
    t0 = time.process_time()
    for _ in range(steps):
        for plan, n in schedule:
            for _ in range(n):
                pyfftw.FFTW.execute(plan)
    return (time.process_time() - t0) / steps * 1e3


_SNAPSHOTS = {}      # (address, shape, strides) -> the buffer its values are kept in


def _replay(seq, part=None):
    """CPU ms of the executions recorded in ``seq`` (``_Counts.seq``; ``part``: only those
    of that part of the step) replayed alone: the same plans, in the same order, each
    pointed at the arrays it ran on.  What they cost without the rest of the step.  The
    arrays they write are restored after (through buffers made once: no page faults), so
    the model goes on from where it was."""
    runs = [(p, i, o) for p, i, o, pt in seq if part is None or pt == part]
    keep = {}
    for _, i, o in runs:
        for a in (i, o):
            key = (a.__array_interface__["data"][0], a.shape, a.strides)
            if key not in keep:
                buf = _SNAPSHOTS.get(key)
                if buf is None:
                    buf = _SNAPSHOTS[key] = np.empty_like(a)
                np.copyto(buf, a)
                keep[key] = (a, buf)
    t0 = time.process_time()
    for plan, i, o in runs:
        plan.update_arrays(i, o)
        pyfftw.FFTW.execute(plan)
    spent = (time.process_time() - t0) * 1e3
    for a, was in keep.values():
        np.copyto(a, was)
    return spent


def measure(scene, steps, np_override=None, threads=1, repeats=3):
    """dict of one scene: step, floor, the fluid's part and its floor (ms; the part None
    without particles) and the ratios, each the median over ``repeats`` x ``steps`` steps;
    transforms per step by kind (all, the fluid's part), mesh.  Each step is timed, then
    its own transforms are replayed alone (``_replay``: the floor) and those of its fluid
    part (the fluid's floor): the step and its floor a few ms apart, so that a shared
    machine's slow spells fall on both; the ratios are those of each step, their median
    reported."""
    from profile_step import build
    from kapsel.mesh import compiled
    compiled.enable()
    model = build(scene, np_override, threads)
    for _ in range(3):
        model.advance()
    kinds, fluid_kinds = collections.Counter(), collections.Counter()
    rows = []      # per step: step, fluid's part, floor, its floor, hot floor (ms)
    with _FluidPart(model) as part:          # (two clock reads a call: microseconds a step)
        for k in range(steps * repeats):
            COUNTS.calls.clear()
            COUNTS.plans.clear()
            COUNTS.seq.clear()
            spent = part.spent
            COUNTS.on = True
            t0 = time.process_time()
            model.advance()
            step_ms = (time.process_time() - t0) * 1e3
            COUNTS.on = False
            seq = list(COUNTS.seq)
            whole = collections.Counter()
            for (key, pt), n in COUNTS.calls.items():
                whole[key] += n
                kinds[_kind(COUNTS.plans[key])] += n
                if pt == "fluid":
                    fluid_kinds[_kind(COUNTS.plans[key])] += n
            hot = _floor_hot(whole, 1) if k % steps == 0 else None   # once a round
            rows.append((step_ms, (part.spent - spent) * 1e3, _replay(seq),
                         _replay(seq, "fluid"), hot))
    med = statistics.median
    step_ms, fluid_ms, floor_ms, fluid_floor = (med(r) for r in list(zip(*rows))[:4])
    n = steps * repeats
    has_part = part.spm is not None
    return dict(step=step_ms, floor=floor_ms, ratio=med(r[0] / r[2] for r in rows),
                hot_floor=med(r[4] for r in rows if r[4] is not None),
                kinds={k: v / n for k, v in kinds.items()},
                fluid=fluid_ms if has_part else None,
                fluid_floor=fluid_floor if has_part else None,
                fluid_ratio=med(r[1] / r[3] for r in rows) if has_part else None,
                fluid_kinds={k: v / n for k, v in fluid_kinds.items()},
                mesh=tuple(model.cfg.mesh.shape))


def pruned(nps, threads=1):
    """Whole against truncated transforms at 2^np per axis (module docstring)."""
    import numpy as np
    from kapsel.mesh.grid import Grid
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {threads} thread(s), "
          f"load {os.getloadavg()[0]:.1f}")
    print("| mesh | c2r whole ms | c2r truncated ms | r2c whole ms | r2c truncated ms |")
    print("|---|---|---|---|---|")
    for n in nps:
        g = Grid((2 ** n,) * 3, threads=threads)
        rng = np.random.default_rng(0)
        spec = (rng.normal(size=g.cshape) + 1j * rng.normal(size=g.cshape)) * g.dealias
        c, r = g.empty_complex(None), g.empty_real(None)
        r[...] = rng.normal(size=g.shape)
        reps = max(3, int(2e7 / g.size))

        def timed(fn, a, b):
            t0 = time.process_time()
            for _ in range(reps):
                if a is c:
                    c[...] = spec            # (a c2r destroys its input)
                fn(a, b)
            return (time.process_time() - t0) / reps * 1e3
        best = [[], [], [], []]
        copy = timed(lambda a, b: None, c, r)
        for _ in range(7):
            best[0].append(timed(g.backward_scalar_raw, c, r) - copy)
            best[1].append(timed(g.backward_scalar_truncated, c, r) - copy)
            best[2].append(timed(lambda a, b: g.rfft_scalar(a, out=b), r, c))
            best[3].append(timed(g.rfft_scalar_truncated, r, c))
        print(f"| {2 ** n}^3 | " + " | ".join(f"{min(b):.3f}" for b in best) + " |")


def main(argv=None):
    from bench_vs_original import SCENES
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="*", help=f"scenes of bench_vs_original (default: "
                    f"{' '.join(SPECTRAL)})")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3, help="rounds of --steps steps (medians)")
    ap.add_argument("--np", type=int, default=None, help="mesh 2^NP per axis")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--pruned", action="store_true",
                    help="time whole against truncated transforms (at --np, default 5 6 7)")
    a = ap.parse_args(argv)
    if a.pruned:
        pruned([a.np] if a.np else [5, 6, 7], a.threads)
        return
    unknown = [s for s in a.scene if s not in SCENES]
    if unknown:
        ap.error(f"unknown scene(s) {' '.join(unknown)}; choose from {' '.join(SCENES)}")
    a.scene = a.scene or list(SPECTRAL)
    pyfftw.FFTW = CountingFFTW          # before any plan is made
    load0 = os.getloadavg()[0]
    rows = []
    for scene in a.scene:
        r = measure(scene, a.steps, a.np, a.threads, a.repeat)
        rows.append((scene, r))
        print(f"# {scene}: {r}", file=sys.stderr, flush=True)
    load1 = os.getloadavg()[0]
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {a.repeat} x {a.steps} "
          f"steps, each followed by its transforms alone (medians; the ratios: of each "
          f"step), {a.threads} thread(s), load {load0:.1f} -> {load1:.1f}")
    print("| scene | mesh | transforms / step (r2c + c2r) | step ms | FFT floor ms | "
          "step / floor | fluid's part: transforms | ms | floor ms | ratio | "
          "hot floor ms |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")

    def transforms(kinds):
        t = " + ".join(f"{kinds.get(k, 0):g}" for k in ("r2c", "c2r"))
        return t + (f" (+{kinds['c2c']:g} c2c)" if kinds.get("c2c") else "")
    for scene, r in rows:
        fl = "- | - | - | -" if r["fluid"] is None else (
            f"{transforms(r['fluid_kinds'])} | {r['fluid']:.2f} | {r['fluid_floor']:.2f} | "
            f"{r['fluid_ratio']:.2f}")
        print(f"| {SCENES[scene][0]} | {'x'.join(map(str, r['mesh']))} | "
              f"{transforms(r['kinds'])} | {r['step']:.2f} | {r['floor']:.2f} | "
              f"{r['ratio']:.2f} | {fl} | {r['hot_floor']:.2f} |")

if __name__ == "__main__":
    main()
