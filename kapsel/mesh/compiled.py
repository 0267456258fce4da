"""The compiled (numba) kernels, loaded on demand.

``kapsel.fluid.spectral_kernels`` (fused spectral passes), ``kapsel.fluid.ions_kernels``
(the Electrolyte's ions), ``kapsel.mesh.stencils`` (MAC stencils) and
``kapsel.mesh.regrid_kernels`` (the Lees-Edwards row shifts) give the numbers of the numpy
passes they replace (up to the sign of zero results), so a run may switch to them at any
step.  What they cost is start-up: importing
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

Compiled ahead of time.  ``python -m kapsel.build_kernels`` (``make`` runs it) compiles the
kernels with numba's ahead-of-time compiler into one extension module, ``_aot_kernels``, in
this directory, with a record (``_aot_kernels.json``) of the sources' SHA-256, the processor
and each kernel's argument types.  ``enable()`` loads it instead of numba for every slot whose
source is unchanged since, on the processor it was built on: plain machine code, no numba or
LLVM in the process (the 128^3 Navier_Stokes run's peak 592 -> ~490 MB), loaded in a few
milliseconds: with it, the time loop switches the kernels on before the first step of every
run (``from_start``), so a run and its continuation use the same passes at every step.  The
compiled code has no argument checks of its own: each function is wrapped in a check of its
arguments' dtype, dimensions and contiguity against the recorded types, and a call that does
not fit goes to the JIT kernel instead (``fallbacks`` lists them; the tests require none).
``KAPSEL_PY_AOT=0`` ignores the build.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import json
import os
import platform
from pathlib import Path

spectral = None     # kapsel.fluid.spectral_kernels once enabled (kapsel.fluid.spectral provides it)
stencils = None     # kapsel.mesh.stencils once enabled

AFTER_STEPS = 10
MIN_REMAINING = 50
LOAD_CPU = 0.65             # s of CPU to import numba and load the cached kernels
SAVING_PER_POINT = 40e-9    # s of CPU saved per mesh point and step (docstring)

AOT_MODULE = "_aot_kernels"
AOT_DIR = Path(__file__).resolve().parent       # where the build and its record are
REGRID_SLOT = "regrid"      # kapsel.mesh.regrid.kernels (set by enable, not a module slot)
REGRID_MODULE = __name__.rsplit(".", 1)[0] + ".regrid_kernels"
fallbacks: list = []        # (slot, kernel) of calls the ahead-of-time build could not take
_aot_record = None          # the build's record when it is usable (``aot_slots``), else {}

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
    globals()[slot] = _load(slot, module) if _enabled else globals().get(slot)


# ------------------------------------------------------------------ ahead-of-time build
def aot_name(slot: str, name: str) -> str:
    """The name of kernel ``name`` of ``slot`` in the ahead-of-time module."""
    return f"{slot}__{name}"


def source_sha256(module: str) -> str:
    """SHA-256 of a module's source file, found without importing it, and of the package
    modules it imports relatively (``from ..mesh.point_sums import add_at``: numba code it
    inlines), so that an edit of either makes the ahead-of-time build stale."""
    import re
    text = Path(importlib.util.find_spec(module).origin).read_bytes()
    digest = hashlib.sha256(text)
    package = module.rsplit(".", 1)[0]
    for rel in re.findall(rb"^from (\.+[\w.]*) import", text, flags=re.M):
        dep = importlib.util.resolve_name(rel.decode(), package)
        digest.update(Path(importlib.util.find_spec(dep).origin).read_bytes())
    return digest.hexdigest()


def cpu_fingerprint() -> str:
    """The processor the machine code is for: its model and instruction-set flags."""
    text = platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith(("model name", "flags", "Features", "CPU part")):
                    text += line
                if line.strip() == "":
                    break                       # the first processor is enough
    except OSError:
        text += platform.processor()
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def aot_slots() -> dict:
    """slot -> its record in the ahead-of-time build, for the slots the build can serve:
    the build exists, was made on this processor for this Python, and the slot's source
    is unchanged since (checked once per process)."""
    global _aot_record
    if _aot_record is None:
        _aot_record = {}
        here = AOT_DIR
        try:
            rec = json.loads((here / (AOT_MODULE + ".json")).read_text())
            import sys
            ok = (os.environ.get("KAPSEL_PY_AOT", "1") != "0"
                  and rec["cpu"] == cpu_fingerprint()
                  and rec["python"] == list(sys.version_info[:2])
                  and (here / rec["file"]).is_file())
            if ok:
                _aot_record = {slot: r for slot, r in rec["slots"].items()
                               if source_sha256(r["module"]) == r["sha256"]}
        except (OSError, ValueError, KeyError, TypeError, AttributeError, ImportError):
            _aot_record = {}
    return _aot_record


def _parse_signature(sig: str) -> tuple:
    """The argument types of a numba signature 'void(float64[:,::1], int64, ...)' as
    (kind, dtype, ndim): kind 'a' array (C-contiguous), 'i' int64, 'f' float64, 'b' bool."""
    import numpy as np
    inner = sig[sig.index("(") + 1:sig.rindex(")")]
    parts, depth, cur = [], 0, ""
    for ch in inner:
        depth += (ch == "[") - (ch == "]")
        if ch == "," and depth == 0:
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
    if cur.strip():
        parts.append(cur.strip())
    out = []
    for t in parts:
        if "[" in t:
            out.append(("a", np.dtype(t[:t.index("[")]), t[t.index("["):].count(",") + 1))
        else:
            out.append(({"int64": "i", "float64": "f", "boolean": "b"}[t], None, 0))
    return tuple(out)


def _checked(fast, slot: str, name: str, module: str, specs: tuple):
    """``fast`` (a function of the ahead-of-time module, which trusts its arguments) behind a
    check of the arguments against ``specs``; a call that does not fit runs the JIT kernel."""
    import numpy as np
    ndarray, integer64, floating, bool_ = np.ndarray, np.int64, np.floating, np.bool_

    def kernel(*args):
        if len(args) == len(specs):
            for a, (kind, dt, nd) in zip(args, specs):
                if kind == "a":
                    if not (type(a) is ndarray or isinstance(a, ndarray)) or a.ndim != nd \
                            or a.dtype != dt or not a.flags.c_contiguous \
                            or not a.flags.aligned:
                        break
                elif kind == "f":
                    if not isinstance(a, (float, floating)):
                        break
                elif kind == "i":
                    if not (type(a) is int or isinstance(a, integer64)):
                        break
                elif not isinstance(a, (bool, bool_)):
                    break
            else:
                return fast(*args)
        if len(fallbacks) < 1000:           # what a test checks; bounded in a long run
            fallbacks.append((slot, name))
        return getattr(importlib.import_module(module), name)(*args)
    kernel.__name__ = kernel.__qualname__ = name
    return kernel


class _AotSlot:
    """The kernels of one slot from the ahead-of-time module; a name it lacks comes from the
    slot's module (numba's JIT)."""

    def __init__(self, slot: str, module: str, ext, signatures: dict):
        self._module = module
        for name, sig in signatures.items():
            fast = getattr(ext, aot_name(slot, name))
            setattr(self, name, _checked(fast, slot, name, module, _parse_signature(sig)))

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(importlib.import_module(self._module), name)


def _load(slot: str, module: str):
    """The kernels of ``slot``: from the ahead-of-time build when it serves the slot, else
    ``module`` itself (numba's JIT)."""
    rec = aot_slots().get(slot)
    if rec is not None and rec["module"] == module:
        try:
            ext = importlib.import_module(__name__.rsplit(".", 1)[0] + "." + AOT_MODULE)
            return _AotSlot(slot, module, ext, rec["signatures"])
        except (ImportError, OSError, AttributeError):
            pass
    return importlib.import_module(module)


def enable() -> bool:
    """Load the compiled kernels (True), or leave the numpy passes if numba is missing or
    KAPSEL_PY_COMPILED=0 (False)."""
    global _enabled
    if _enabled:
        return True
    if mode() == "0":
        return False
    try:
        loaded = {slot: _load(slot, m) for slot, m in _PROVIDERS.items()}
        from . import regrid
        regrid_kernels = _load(REGRID_SLOT, REGRID_MODULE)
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


def from_start() -> bool:
    """Whether a run loads the kernels before its first step: ``KAPSEL_PY_COMPILED=1``, or
    ``auto`` with an ahead-of-time build that serves every slot (loading it costs a few
    milliseconds and no numba)."""
    m = mode()
    if m == "1":
        return True
    slots = aot_slots()
    return m == "auto" and all(s in slots for s in list(_PROVIDERS) + [REGRID_SLOT])


def want(step_done: int, remaining: int, points: int | None = None) -> bool:
    """Whether the time loop should enable the kernels now (module docstring); ``points``:
    the whole mesh's (None: the step counts alone decide)."""
    m = mode()
    if m == "1":
        return True
    if m != "auto" or step_done < AFTER_STEPS or remaining < MIN_REMAINING:
        return False
    return points is None or remaining * points * SAVING_PER_POINT >= LOAD_CPU
