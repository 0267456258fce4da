"""Test-session settings: single-threaded BLAS, as the kapsel-py command runs."""
import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Subprocesses (``python -m kapsel.cli`` under mpiexec, strace, the CLI tests) import the code
# of this checkout, not whichever copy the environment installed (a git worktree beside an
# editable install of another one).
_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
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


def pytest_collection_modifyitems(config, items):
    import pytest
    for item in items:
        if item.nodeid.split("tests/", 1)[-1] in SLOW_VARIANTS:
            item.add_marker(pytest.mark.slow)
