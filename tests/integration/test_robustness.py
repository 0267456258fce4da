"""A run never loses what it wrote: Ctrl-C / SIGTERM stop cleanly with a restart that
continues; an instability (CFL limit, NaN) stops the run naming the step and the quantity,
with the last good state on disk."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from kapsel import simulation
from kapsel.io.restart import state_path
from udf import UDFManager

from builders import cli, make_input


KAPSEL = [sys.executable, "-m", "kapsel.cli"]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_cleanly_and_the_run_continues(tmp_path, signum):
    d = tmp_path / "sig"
    make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", gts=5, nsnap=100000, kBT=0.0)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(KAPSEL + ["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf",
                                      "-Rrestart.udf", "--seed", "3", "--quiet"],
                            cwd=d, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.time() + 120
    from kapsel.io.restart import read_restart
    while time.time() < deadline:        # wait for a few snapshots (checkpoints count)
        if (d / "restart.udf").exists():
            try:
                doc = UDFManager(str(d / "restart.udf"))
                if read_restart(doc, str(d / "restart.udf"), "CONTINUE_FDM").step >= 10:
                    break
            except Exception:           # noqa: BLE001 - the state file is being replaced
                pass
        time.sleep(0.2)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    assert "interrupted at step" in err and "Continue with: kapsel-py -Irestart.udf" in err
    assert "Traceback" not in err
    rs = UDFManager(str(d / "restart.udf"))
    step = rs.get("resume.CONTINUE_FDM.Saved_Data.jikan")[0] + 1   # ts = steps done - 1
    assert step >= 10
    assert os.path.exists(state_path(str(d / "restart.udf")))
    out = UDFManager(str(d / "output.udf"))   # consistent: every record complete
    n = out.totalRecord()
    assert n == step // 5 + 1
    # continue two more snapshots from the restart, as the message says
    rs.put(step // 5 + 2, "output.Num_snap")
    rs.write(str(d / "restart.udf"))
    assert cli(d, "restart.udf") == 0
    out = UDFManager(str(d / "output.udf"))
    assert out.totalRecord() == step // 5 + 3
    out.jump(out.totalRecord() - 1)
    assert out.get("t") == (step // 5 + 2) * 5     # t of a record is its step (FORMAT.md)


def test_cfl_limit_stops_the_run_with_last_good_state(tmp_path, capsys):
    """Heavy particles under strong gravity speed up until max|V| dt/DX passes 1."""
    d = tmp_path / "cfl"
    inp = make_input(d, "Navier_Stokes_FDM", ns="implicit_scheme", gts=5, nsnap=40, kBT=0.0,
                     particles=1)
    doc = UDFManager(inp)
    doc.put(20.0, "object_type.spherical_particle.Particle_spec[0].MASS_RATIO")
    doc.put(2.0, "gravity.G")
    doc.write(inp)
    assert cli(d, "input.udf") == 1
    err = capsys.readouterr().err
    assert "the run stopped at step" in err and "CFL number" in err
    assert "Try a smaller time_increment" in err and "holds the last good state" in err
    rs = UDFManager(str(d / "restart.udf"))
    step = rs.get("resume.CONTINUE_FDM.Saved_Data.jikan")[0] + 1   # ts = steps done - 1
    assert 0 < step < 200 and step % 5 == 0
    assert np.isfinite(rs.getArray("resume.CONTINUE_FDM.Saved_Data.U[]")).all()


def test_nan_in_the_fluid_is_caught_between_snapshots(tmp_path, capsys, monkeypatch):
    d = tmp_path / "nan"
    inp = make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", gts=20, nsnap=2, kBT=0.0)
    from kapsel.models.fdm import FDMModel
    advance = FDMModel.advance

    def poisoned(self):
        advance(self)
        if self.step_index == 23:
            self.u[0, 1, 2, 3] = np.nan
    monkeypatch.setattr(FDMModel, "advance", poisoned)
    assert cli(d, inp) == 1
    err = capsys.readouterr().err
    assert "stopped at step 30" in err and "not finite" in err
    assert "(step 20)" in err                 # the last good state on disk
    rs = UDFManager(str(d / "restart.udf"))
    assert rs.get("resume.CONTINUE_FDM.Saved_Data.jikan")[0] == 19   # after 20 steps


def test_check_step_names_the_quantity():
    class Fake:
        def stability(self):
            return 2.5, "the CFL number max|u| dt/DX = 2.5 exceeds 1"
    with pytest.raises(simulation.InstabilityError, match="CFL number"):
        simulation.check_step(Fake())


def test_a_new_run_does_not_overwrite_outputs(tmp_path, capsys):
    """Existing output.udf, restart.udf or field series are kept unless --overwrite."""
    d = tmp_path / "ow"
    inp = make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", nsnap=1, kBT=0.0)
    assert cli(d, inp) == 0
    before = {p.name: p.stat().st_mtime_ns for p in d.iterdir()}
    assert cli(d, inp) == 2
    assert "-Ooutput.udf exists; pass --overwrite" in capsys.readouterr().err
    os.remove(d / "output.udf")
    os.remove(d / "restart.udf")
    assert cli(d, inp) == 2
    assert "particle_phase.xmf exists; pass --overwrite" in capsys.readouterr().err
    after = {p.name: p.stat().st_mtime_ns for p in d.iterdir()}
    assert all(after[k] == before[k] for k in after)
    assert cli(d, inp, "--overwrite") == 0
