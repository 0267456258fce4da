"""Test-session settings: single-threaded BLAS, as the kapsel-py command runs; tests/ on
sys.path, so that every tier (tests/unit, tests/integration, tests/validation,
tests/distributed) imports the shared helpers (builders.py, kill_points.py) and no test module
imports another."""
import os
import sys

import pytest

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Subprocesses (``python -m kapsel.cli`` under mpiexec, strace, the CLI tests) import the code
# of this checkout, not whichever copy the environment installed (a git worktree beside an
# editable install of another one).
_TESTS = os.path.dirname(os.path.abspath(__file__))
_ROOT = os.path.dirname(_TESTS)
if _TESTS not in sys.path:
    sys.path.insert(0, _TESTS)
os.environ["PYTHONPATH"] = os.pathsep.join(
    [_ROOT] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])


# The distributed tier's repeats: each of these is a second or third variant of a distributed
# test whose first variant stays in the fast suite (the same code path under another type or
# scheme); they run with the slow tests (``pytest -m slow``).  Measured 2026-12-01 on the
# 2-core VM at load 2-3: 25-82 s each, about 370 s together.
SLOW_VARIANTS = {
    "test_mpi_fdm.py::test_distributed_fdm_runs_agree_with_the_serial_run"
    "[Navier_Stokes_Cahn_Hilliard_FDM-NS_implicit-CH_implicit-eta]",
    "test_mpi_fdm.py::test_distributed_fdm_runs_agree_with_the_serial_run"
    "[Navier_Stokes_FDM-NS_implicit-CH_explicit]",
    "test_mpi_fdm.py::test_fdm_restarts_interchange_between_distributed_and_serial_runs"
    "[Shear_NS_LE_CH_FDM-explicit_scheme-implicit_scheme]",
    "test_mpi_particles.py::test_rigid_bodies_agree_with_the_serial_run"
    "[Shear_Navier_Stokes_Lees_Edwards]",
    "test_mpi_particles.py::test_rigid_bodies_agree_with_the_serial_run[Shear_Navier_Stokes]",
    "test_mpi_particles.py::test_rigid_body_restarts_interchange_between_distributed_and_"
    "serial_runs[Shear_Navier_Stokes_Lees_Edwards]",
    "test_mpi_particles.py::test_self_propelled_particles_agree_with_the_serial_run"
    "[Shear_Navier_Stokes]",
    # 2026-12-02, clean clone at load 1.5-2: 76 s, 19 s, 25 s
    "test_mpi_fdm.py::test_lees_edwards_fdm_distributed"
    "[Shear_NS_LE_CH_FDM-implicit_scheme-implicit_scheme-True]",
    "test_mpi_fdm.py::test_fdm_restarts_interchange_between_distributed_and_serial_runs"
    "[Navier_Stokes_Cahn_Hilliard_FDM-implicit_scheme-implicit_scheme]",
    "test_mpi_particles.py::test_dipoles_agree_with_the_serial_run[fixed_lees_edwards]",
}


class CompiledKernels:
    """The compiled kernels (kapsel.mesh.compiled) switched on or off inside a test: the
    ahead-of-time build (``kind`` 'aot') or numba's JIT ('jit')."""

    def __init__(self, compiled, kind="jit"):
        self._compiled = compiled
        self.kind = kind

    def on(self):
        """Load them; the test is skipped where numba is missing.  Every call must have
        gone to the ahead-of-time code: none fell back to the JIT (``off`` checks)."""
        if not self._compiled.enable():
            pytest.skip("numba not installed")

    def off(self):
        """Back to the numpy passes."""
        self._compiled.disable()
        assert not self._compiled.fallbacks, (
            f"calls the ahead-of-time kernels could not take: {self._compiled.fallbacks}")

    def both(self, compute):
        """``compute()`` with the compiled kernels, then with the numpy passes: the two
        results, to compare bit for bit."""
        self.on()
        first = compute()
        self.off()
        return first, compute()


@pytest.fixture(params=["aot", "jit"])
def compiled_kernels(request, monkeypatch):
    """The compiled on / off switch of the tests that compare the compiled kernels with the
    numpy passes: off at the start and again after the test, whatever it did.  Each such test
    runs twice: with the ahead-of-time build (``python -m kapsel.build_kernels``; skipped
    where it is not built) and with numba's JIT."""
    from kapsel.mesh import compiled
    compiled.disable()
    monkeypatch.setattr(compiled, "fallbacks", [])
    if request.param == "aot":
        if not compiled.aot_slots():
            pytest.skip("the kernels are not compiled ahead of time (python -m "
                        "kapsel.build_kernels)")
    else:
        monkeypatch.setattr(compiled, "_aot_record", {})
    yield CompiledKernels(compiled, request.param)
    compiled.disable()


# The tiers, one directory each: a test is marked with its tier's name too (``-m unit``).
TIERS = ("unit", "integration", "validation", "distributed")


def pytest_collection_modifyitems(config, items):
    for item in items:
        path, _, name = item.nodeid.partition("::")          # tests/<tier>/test_x.py
        if f"{os.path.basename(path)}::{name}" in SLOW_VARIANTS:
            item.add_marker(pytest.mark.slow)
        tier = os.path.basename(os.path.dirname(path))
        if tier in TIERS:
            item.add_marker(getattr(pytest.mark, tier))
