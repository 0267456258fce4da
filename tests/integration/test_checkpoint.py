"""Cheap restart checkpoints (issue 14): between the full restart.udf writes (first
snapshot of a run, end, interruption, failure) a run writes only the state file, which then
holds the schema data too.  A run killed at any moment (SIGKILL: no handler runs) continues
from its last snapshot, bit-identical to an uninterrupted run."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from kapsel.io.restart import read_restart, state_path
from udf import UDFManager

from builders import cli, make_input, saved_data


KAPSEL = [sys.executable, "-m", "kapsel.cli"]


def _kind(path):
    return UDFManager(str(path)).get("resume.Calculation")


@pytest.mark.parametrize("eq", ["Navier_Stokes_FDM", "Navier_Stokes"])
def test_killed_run_continues_from_its_last_snapshot(tmp_path, eq):
    whole = tmp_path / "whole"
    # long enough that the kill lands before the end (the short run ends in a blink now
    # that it keeps the numpy passes: kapsel.mesh.compiled.want)
    make_input(whole, eq, ns="explicit_scheme", gts=2, nsnap=200, kBT=0.5)
    assert cli(whole, "input.udf") == 0

    d = tmp_path / "killed"
    make_input(d, eq, ns="explicit_scheme", gts=2, nsnap=200, kBT=0.5)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(KAPSEL + ["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
                                      "-Rrestart.udf", "--seed", "11", "--quiet"],
                            cwd=d, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.time() + 200
    step = 0
    while time.time() < deadline and proc.poll() is None:
        time.sleep(0.1)
        try:
            doc = UDFManager(str(d / "restart.udf"))
            step = read_restart(doc, str(d / "restart.udf"), _kind(d / "restart.udf")).step
        except Exception:             # noqa: BLE001 - not written yet
            continue
        if step >= 10:
            break
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert 10 <= step < 400, step
    doc = UDFManager(str(d / "restart.udf"))
    # the full restart.udf of the run's first snapshot: 0 steps done, ts = -1 (ts = steps - 1)
    assert doc.get(f"resume.{_kind(d / 'restart.udf')}.Saved_Data.jikan")[0] == -1
    saved = read_restart(doc, str(d / "restart.udf"), _kind(d / "restart.udf"))
    assert saved.checkpoint_of == 0 and saved.step >= step and saved.exact is not None
    # continue, as after any interruption
    r = subprocess.run(KAPSEL + ["-Irestart.udf", "-Ooutput.udf", "-Ddefine.udf",
                                 "-Rrestart.udf", "--seed", "11"],
                       cwd=d, capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "its state file the later snapshot" in r.stderr
    a = saved_data(str(whole / "restart.udf"))
    b = saved_data(str(d / "restart.udf"))
    assert a["jikan"][0] == b["jikan"][0] == 400
    for k in a:
        assert np.array_equal(a[k], b[k]), k
    out = UDFManager(str(d / "output.udf"))
    assert out.totalRecord() == 201


def test_failed_run_writes_restart_udf_from_the_last_checkpoint(tmp_path, capsys,
                                                                 monkeypatch):
    d = tmp_path / "fail"
    make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", gts=5, nsnap=10, kBT=0.0)
    from kapsel.models.fdm import FDMModel
    advance = FDMModel.advance

    def poisoned(self):
        advance(self)
        if self.step_index == 17:
            self.u[0, 1, 2, 3] = np.nan
    monkeypatch.setattr(FDMModel, "advance", poisoned)
    assert cli(d, "input.udf") == 1
    assert "(step 15)" in capsys.readouterr().err
    rs = UDFManager(str(d / "restart.udf"))
    assert rs.get("resume.CONTINUE_FDM.Saved_Data.jikan")[0] == 14   # 15 steps done
    saved = read_restart(rs, str(d / "restart.udf"), "CONTINUE_FDM")
    assert saved.exact is not None and saved.checkpoint_of is None   # a full pair again
    assert not [f for f in os.listdir(d) if ".tmp" in f]
    assert os.path.exists(state_path(str(d / "restart.udf")))
