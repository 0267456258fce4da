"""The console as the original writes it (FORMAT-OUTPUT.md §1.3, §1.4, §1.6): the snapshot
line and closing summary on stderr, the sheared types' stress table (header on stdout, a
row after every step), --quiet silencing stderr."""
import re
import subprocess
import sys

import numpy as np
import pytest

from kapsel.models.shear import LE_TABLE

from builders import shear_input


STEP_LINE = re.compile(r"^# Step: [ \d]{9}/[ \d]{9}\t  Block time \(m\): [ \d.]{8}\t "
                       r"Global time \(m\): [ \d.]{8}/[ \d.-]{8}$")


def kapsel(d, *extra):
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", "-Iinput.udf", "-Ooutput.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--seed", "2", *extra], cwd=d,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def le_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("le")
    shear_input(d, particles=2, gts=3, nsnap=2, rate=0.6, kind="DC")
    return d, kapsel(d)


def test_snapshot_lines_and_summary_on_stderr(le_run):
    _, r = le_run
    err = r.stderr.splitlines()
    steps = [line for line in err if line.startswith("# Step:")]
    assert len(steps) == 2 and all(STEP_LINE.match(s) for s in steps), steps
    assert [int(s.split()[2].split("/")[0]) for s in steps] == [3, 6]
    tail = err[err.index("#output.udf end."):]
    assert tail[:3] == ["#output.udf end.", "#restart.udf end.", "#Simulation has ended!"]
    assert re.match(r"^#Total Running Time \(s\): +\d+\.\d\d$", tail[3])
    assert re.match(r"^#Average Step Time  \(s\): +\d+\.\d\d$", tail[6])


def test_lees_edwards_stress_table_on_stdout(le_run):
    d, r = le_run
    out = r.stdout.splitlines()
    assert out[0] == "#" + "".join(f"{i + 1}:{n} " for i, n in enumerate(LE_TABLE))
    rows = np.array([[float(x) for x in line.split()] for line in out[1:]])
    # a row after every step: 6 steps and the step after the last snapshot
    assert rows.shape == (7, 12)
    assert all(len(line) == 12 * 16 + 11 for line in out[1:])       # %16.8g, one space
    from kapsel import config
    from kapsel.models.common import time_step
    from udf import UDFManager
    dt = time_step(config.from_document(UDFManager(str(d / "input.udf")),
                                        str(d / "input.udf")))
    assert np.allclose(rows[:, 0], dt * np.arange(1, 8), rtol=1e-7)   # time after the step
    assert np.allclose(rows[:, 1], 0.6)
    assert np.allclose(rows[:, 3], 0.6 * rows[:, 0], rtol=1e-7)        # strain
    assert np.allclose(rows[:, 8], 0.6)                                # ETA gamma_dot
    assert np.allclose(rows[:, 10], rows[:, 6] + rows[:, 7] + rows[:, 4] + rows[:, 8]
                       + rows[:, 9], rtol=1e-6, atol=1e-9)
    assert np.allclose(rows[:, 11], rows[:, 10] / rows[:, 1], rtol=1e-6)
    # the step-3 and step-6 rows' particle stresses average to shear_stress.dat's column
    log = np.loadtxt(d / "shear_stress.dat")
    assert np.isclose(log[1, 4], 0.6 + rows[:3, 6].mean(), rtol=1e-6)


def test_quiet_silences_stderr_but_not_the_table(tmp_path):
    shear_input(tmp_path, particles=1, gts=2, nsnap=1, rate=0.1, kind="DC",
               eq="Shear_Navier_Stokes")
    r = kapsel(tmp_path, "--quiet")
    assert r.stderr == ""
    assert r.stdout.splitlines() == ["#1:time 2:shear_rate_temporal 3:shear_strain_temporal "
                                     "4:shear_stress_temporal 5:viscosity "]
    r = kapsel(tmp_path, "--overwrite")         # Shear_Navier_Stokes: rows on stderr
    rows = [line for line in r.stderr.splitlines() if not line.startswith("#")]
    assert len(rows) == 3 and all(len(line.split()) == 5 for line in rows)


def test_heartbeat_comes_within_the_first_seconds_then_every_interval(monkeypatch):
    """A run whose snapshots are far apart says within ``first`` seconds (10) that it runs,
    then again only after ``every`` seconds without a line (issue 28)."""
    import io
    from kapsel import progress
    clock = [100.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: clock[0])
    out = io.StringIO()
    p = progress.Progress(1000, stream=out, every=60.0)
    clock[0] += 9.0
    p.step(1, 0.1)
    assert out.getvalue() == ""
    clock[0] += 1.5
    p.step(2, 0.2)
    assert out.getvalue().startswith("#step 2/1000")
    clock[0] += 30.0
    p.step(3, 0.3)
    assert out.getvalue().count("#step") == 1
    clock[0] += 31.0
    p.step(4, 0.4)
    assert out.getvalue().count("#step") == 2
