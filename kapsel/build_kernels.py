"""Compile the numba kernels ahead of time, into one extension module beside kapsel.mesh.compiled.

    python -m kapsel.build_kernels          (``make`` runs it after installing)

The kernels (kapsel.fluid.spectral_kernels, kapsel.mesh.stencils, kapsel.mesh.regrid_kernels:
every module a ``kapsel.mesh.compiled.provide`` names, plus the regrid kernels) are compiled by
numba's ahead-of-time compiler (numba.pycc) for this machine's processor, with the types of
each module's ``SIGNATURES``, into ``kapsel/mesh/_aot_kernels<ext>``; ``_aot_kernels.json``
beside it records what it was built from (the sources' SHA-256, the processor, numba's
version) and the signatures.  A run then loads plain machine code: no numba and no LLVM in the
process (about 100 MB less resident memory and 0.65 s less CPU than the JIT's cached code;
issue 25), so the kernels can switch on from the first steps.  The same LLVM compiles both
ways, without fast-math: the results are the JIT kernels' bits (tests/unit/test_compiled.py).

Where the build is missing, stale (a kernel's source changed since) or made on another
processor, kapsel.mesh.compiled uses numba's JIT as before.
"""
from __future__ import annotations

import importlib
import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path


def kernel_modules() -> dict:
    """slot -> module name of every kernel module a run may load: the package's modules
    that name one (``compiled.provide(...)``) are imported, so that every slot is known."""
    from .mesh import compiled
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        if path.name not in ("compiled.py", "build_kernels.py") and ".provide(" in path.read_text(errors="replace"):
            rel = path.relative_to(root.parent).with_suffix("")
            importlib.import_module(".".join(rel.parts))
    return dict(compiled._PROVIDERS, **{compiled.REGRID_SLOT: compiled.REGRID_MODULE})


def build(directory: str | None = None, quiet: bool = False) -> Path:
    """Compile every kernel module's SIGNATURES into ``_aot_kernels`` in ``directory``
    (default: kapsel/mesh); returns the path of the record (``_aot_kernels.json``)."""
    from .mesh import compiled
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from numba.pycc import CC
        import numba
    out = Path(directory) if directory else Path(compiled.__file__).resolve().parent
    modules = kernel_modules()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=out, prefix=".aot-build-") as tmp:
        cc = CC(compiled.AOT_MODULE)
        cc.output_dir = tmp
        cc.target_cpu = "host"
        cc.verbose = False
        record = {"numba": numba.__version__, "cpu": compiled.cpu_fingerprint(),
                  "python": list(sys.version_info[:2]), "slots": {}}
        for slot, name in modules.items():
            mod = importlib.import_module(name)
            sigs = getattr(mod, "SIGNATURES", {})
            for fname, sig in sigs.items():
                cc.export(compiled.aot_name(slot, fname), sig)(getattr(mod, fname).py_func)
            record["slots"][slot] = {"module": name, "sha256": compiled.source_sha256(name),
                                     "signatures": sigs}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cc.compile()
        built = next(Path(tmp).glob(compiled.AOT_MODULE + ".*"))
        target = out / built.name
        os.replace(built, target)           # the module first, then the record naming it
        record["file"] = target.name
        rec = out / (compiled.AOT_MODULE + ".json")
        part = rec.with_suffix(".json.part")
        part.write_text(json.dumps(record, indent=1) + "\n")
        os.replace(part, rec)
    if not quiet:
        n = sum(len(s["signatures"]) for s in record["slots"].values())
        print(f"compiled {n} kernels of {len(modules)} modules ahead of time in "
              f"{time.perf_counter() - t0:.1f} s: {target}")
    return rec


def main(argv=None) -> int:
    try:
        build()
    except Exception as e:      # the JIT path stays: say why, do not fail the install
        print(f"the kernels were not compiled ahead of time ({type(e).__name__}: {e}); runs "
              f"use numba's JIT for them (the same numbers)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
