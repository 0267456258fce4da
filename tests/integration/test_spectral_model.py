"""The Navier_Stokes type end to end: records, reproducibility with a seed, the summary."""
import os
import subprocess
import sys

import numpy as np
import pytest

from udf import UDFManager

from builders import copy_schema, TESTS


SAMPLES = os.path.join(TESTS, "..", "samples")


def ns_input(tmp_path, **puts):
    copy_schema(tmp_path)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put("Navier_Stokes", "constitutive_eq.type")
    u.put(4, "output.GTS")
    u.put(3, "output.Num_snap")
    for path, value in puts.items():
        u.put(value, path.replace("__", "."))
    u.write(str(tmp_path / "ns.udf"))


def run(tmp_path, out, seed=5, extra=()):
    return subprocess.run([sys.executable, "-m", "kapsel.cli", "-Ins.udf", f"-O{out}",
                           "-Ddefine.udf", f"-R{out}.restart", "--seed", str(seed), *extra],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)


def test_navier_stokes_runs_and_writes_records(tmp_path):
    ns_input(tmp_path)
    r = run(tmp_path, "a.udf")
    assert r.returncode == 0, r.stderr
    assert "#Simulation has ended!" in r.stderr and "#Average Step Time  (s):" in r.stderr
    u = UDFManager(str(tmp_path / "a.udf"))
    assert u.totalRecord() == 4
    u.jump(3)
    assert u.size("Particles[]") == 8
    R = u.getArray("Particles[].R")
    assert np.all((R >= 0) & (R < 32))
    assert u.get("t") == 12.0           # t of a record is its step, as the original writes it
    # existing outputs are not silently replaced
    r = run(tmp_path, "a.udf")
    assert r.returncode == 2 and "--overwrite" in r.stderr


def test_same_seed_same_particles(tmp_path):
    ns_input(tmp_path, switch__LJ_truncate="ON")
    assert run(tmp_path, "a.udf", seed=11).returncode == 0
    assert run(tmp_path, "b.udf", seed=11).returncode == 0
    assert run(tmp_path, "c.udf", seed=12).returncode == 0
    a, b, c = (UDFManager(str(tmp_path / f)) for f in ("a.udf", "b.udf", "c.udf"))
    for u in (a, b, c):
        u.jump(3)
    assert np.array_equal(a.getArray("Particles[].R"), b.getArray("Particles[].R"))
    assert not np.array_equal(a.getArray("Particles[].R"), c.getArray("Particles[].R"))
