"""The compiled (numba) kernels, loaded on demand.

``kapsel.fluid.spectral_kernels`` (fused spectral passes), ``kapsel.fluid.stencils`` (MAC
stencils) and ``kapsel.regrid_kernels`` (the Lees-Edwards row shifts) are bit-identical to the numpy passes they replace, so a run may switch to them at
any step without changing a single bit of its results.  What they cost is start-up: importing
numba and loading the cached machine code takes about 0.65 s of CPU per process (0.2 s import,
0.45 s to initialise numba's code generator on the first cached function; measured on the
shared 2-core machine), and the first run on a machine also compiles them (about 2 s, then
cached in __pycache__ by ``cache=True``).  That is more than the whole start-up budget of the
sample (1 s), and it pays back only after some 30-150 steps (32^3-64^3).  Hence:

* ``spectral`` / ``stencils`` are None (numpy passes) until ``enable()`` loads them;
* the time loop (kapsel.simulation.run) calls ``enable()`` once a run has done
  ``AFTER_STEPS`` steps and still has at least ``MIN_REMAINING`` to go, so short runs never pay
  and long ones run compiled from there on;
* ``KAPSEL_PY_COMPILED``: ``auto`` (default, as above), ``1`` (from the start), ``0`` (never).
"""
from __future__ import annotations

import os

spectral = None     # kapsel.fluid.spectral_kernels once enabled
stencils = None     # kapsel.fluid.stencils once enabled

AFTER_STEPS = 10
MIN_REMAINING = 50


def mode() -> str:
    m = os.environ.get("KAPSEL_PY_COMPILED", "auto").strip().lower()
    return m if m in ("0", "1", "auto") else "auto"


def enable() -> bool:
    """Load the compiled kernels (True), or leave the numpy passes if numba is missing or
    KAPSEL_PY_COMPILED=0 (False)."""
    global spectral, stencils
    if spectral is not None:
        return True
    if mode() == "0":
        return False
    try:
        from . import spectral_kernels, stencils as st
        from .. import regrid, regrid_kernels
    except ImportError:     # pragma: no cover - numba missing
        return False
    spectral, stencils = spectral_kernels, st
    regrid.kernels = regrid_kernels
    return True


def disable() -> None:
    """Back to the numpy passes (tests compare the two)."""
    global spectral, stencils
    from .. import regrid
    spectral = stencils = None
    regrid.kernels = None


def want(step_done: int, remaining: int) -> bool:
    """Whether the time loop should enable the kernels now (module docstring)."""
    m = mode()
    if m == "1":
        return True
    return m == "auto" and step_done >= AFTER_STEPS and remaining >= MIN_REMAINING
