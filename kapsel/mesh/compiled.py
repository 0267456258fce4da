"""The compiled (numba) kernels, loaded on demand.

``kapsel.fluid.spectral_kernels`` (fused spectral passes), ``kapsel.mesh.stencils`` (MAC
stencils) and ``kapsel.mesh.regrid_kernels`` (the Lees-Edwards row shifts) are bit-identical to the numpy passes they replace, so a run may switch to them at
any step without changing a single bit of its results.  What they cost is start-up: importing
numba and loading the cached machine code takes about 0.65 s of CPU per process (0.2 s import,
0.45 s to initialise numba's code generator on the first cached function; measured on the
shared 2-core machine), and the first run on a machine also compiles them (about 2 s, then
cached in __pycache__ by ``cache=True``).  That is more than the whole start-up budget of the
sample (1 s), and it pays back only after some 30-150 steps (32^3-64^3).  Hence:

* ``spectral`` / ``stencils`` are None (numpy passes) until ``enable()`` loads them;
* the time loop (kapsel.activities.CompiledSwitch) calls ``enable()`` once a run has done
  ``AFTER_STEPS`` steps, still has at least ``MIN_REMAINING`` to go, and the kernels pay for
  their loading in the steps left: ``remaining * points * SAVING_PER_POINT >= LOAD_CPU``
  (``points``: the whole mesh's).  So a short or small run never pays (the 32^3
  Navier_Stokes run of 200 steps: 3.1 ms a step and 101 MB peak with the numpy passes, 4.4 ms
  and 201 MB with the kernels loaded at step 10, bench_vs_original.py, 2026-12-04), and long
  ones run compiled from there on.  The rule uses no clock: when a run switches depends on
  its input alone (the kernels give the numpy passes' numbers, but not always the sign of a
  zero: a run must not depend on the machine's load);
* SAVING_PER_POINT is the CPU time the kernels save per mesh point and step, at 32^3
  (bench/profile_step.py --np 5, KAPSEL_PY_COMPILED=0 against 1, 2026-12-04, ns per point):
  Lees-Edwards 186, LE_FDM 150, NSCH_FDM 82, squirmers 82, NS_FDM 79, Navier_Stokes 73,
  zigzag 49, Electrolyte 37; 40 ns is taken;
* the kernels also cost memory: numba and its code generator take about 100 MB of resident
  memory once loaded;
* ``KAPSEL_PY_COMPILED``: ``auto`` (default, as above), ``1`` (from the start), ``0`` (never).
"""
from __future__ import annotations

import importlib
import os

spectral = None     # kapsel.fluid.spectral_kernels once enabled (kapsel.fluid.spectral provides it)
stencils = None     # kapsel.mesh.stencils once enabled

AFTER_STEPS = 10
MIN_REMAINING = 50
LOAD_CPU = 0.65             # s of CPU to import numba and load the cached kernels
SAVING_PER_POINT = 40e-9    # s of CPU saved per mesh point and step (docstring)

# slot -> the module of compiled kernels that fills it; a module with kernels of its own
# names them with ``provide`` (the switch knows no module above kapsel.mesh)
_PROVIDERS = {"stencils": __name__.rsplit(".", 1)[0] + ".stencils"}
_enabled = False


def mode() -> str:
    m = os.environ.get("KAPSEL_PY_COMPILED", "auto").strip().lower()
    return m if m in ("0", "1", "auto") else "auto"


def provide(slot: str, module: str) -> None:
    """``module`` (its dotted name) holds the compiled kernels of ``slot`` (this module's
    attribute the numpy passes look at); loaded at once if the kernels are enabled."""
    _PROVIDERS[slot] = module
    if _enabled:
        globals()[slot] = importlib.import_module(module)


def enable() -> bool:
    """Load the compiled kernels (True), or leave the numpy passes if numba is missing or
    KAPSEL_PY_COMPILED=0 (False)."""
    global _enabled
    if _enabled:
        return True
    if mode() == "0":
        return False
    try:
        loaded = {slot: importlib.import_module(m) for slot, m in _PROVIDERS.items()}
        from . import regrid, regrid_kernels
    except ImportError:     # pragma: no cover - numba missing
        return False
    except (OSError, MemoryError) as e:     # numba's code generator cannot be loaded (out
        import sys                          # of memory under ulimit -v): the numpy passes
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        print(f"#the compiled kernels could not be loaded ({why}); the run goes on with the "
              f"numpy passes (the same numbers, slower)", file=sys.stderr)
        return False
    globals().update(loaded)
    regrid.kernels = regrid_kernels
    _enabled = True
    return True


def disable() -> None:
    """Back to the numpy passes (tests compare the two)."""
    global _enabled
    from . import regrid
    for slot in _PROVIDERS:
        globals()[slot] = None
    regrid.kernels = None
    _enabled = False


def want(step_done: int, remaining: int, points: int | None = None) -> bool:
    """Whether the time loop should enable the kernels now (module docstring); ``points``:
    the whole mesh's (None: the step counts alone decide)."""
    m = mode()
    if m == "1":
        return True
    if m != "auto" or step_done < AFTER_STEPS or remaining < MIN_REMAINING:
        return False
    return points is None or remaining * points * SAVING_PER_POINT >= LOAD_CPU
