"""Continuation from restart.udf: N steps + restart + M steps is bit-identical to N + M steps
in one run, for every implemented type (with thermal noise where the type has particles);
the continued run appends to output.udf and the field series; a restart without its state
file continues from the schema data."""
import os
import shutil

import h5py
import numpy as np
import pytest

from kapsel.cli import main
from kapsel.io.restart import state_path
from udf import UDFManager

from builders import cli, continue_input, make_input, records, SAMPLES, saved_data


CASES = [("Navier_Stokes", {}),
         ("Navier_Stokes_FDM", {"ns": "explicit_scheme"}),
         ("Navier_Stokes_FDM", {"ns": "implicit_scheme"}),
         ("Navier_Stokes_Cahn_Hilliard_FDM", {"ns": "implicit_scheme", "ch": "implicit_scheme"}),
         ("Navier_Stokes_Cahn_Hilliard_FDM", {"ns": "explicit_scheme", "ch": "explicit_scheme"})]


@pytest.mark.parametrize("eq,kw", CASES, ids=[f"{e}-{'-'.join(k.values())}" for e, k in CASES])
def test_continuation_is_bit_identical(tmp_path, eq, kw):
    one = make_input(tmp_path / "one", eq, nsnap=4, **kw)
    assert cli(tmp_path / "one", one) == 0
    two = make_input(tmp_path / "two", eq, nsnap=2, **kw)
    assert cli(tmp_path / "two", two) == 0
    # continue: the restart file is the input, with Num_snap raised to the full run
    continue_input(tmp_path / "two")
    assert cli(tmp_path / "two", "cont.udf") == 0
    a = saved_data(str(tmp_path / "one" / "restart.udf"))
    b = saved_data(str(tmp_path / "two" / "restart.udf"))
    assert a["jikan"][0] == 8
    assert set(a) == set(b)
    for k in a:
        assert np.array_equal(a[k], b[k]), k
    # output.udf: the same time line, records appended (initial + 4), same particle data
    ra, rb = records(str(tmp_path / "one" / "output.udf")), records(str(tmp_path / "two" /
                                                                           "output.udf"))
    assert len(ra) == len(rb) == 5
    for (ta, pa), (tb, pb) in zip(ra, rb):
        assert ta == tb
        assert (pa is None and pb is None) or np.array_equal(pa, pb)
    if eq != "Navier_Stokes":   # field series continue: snapshots 0..4 in one .xmf
        with h5py.File(tmp_path / "one" / "velocity_4.h5") as fa, \
                h5py.File(tmp_path / "two" / "velocity_4.h5") as fb:
            for ds in ("UX", "UY", "UZ"):
                assert np.array_equal(fa[ds][...], fb[ds][...])
        xmf = (tmp_path / "two" / "velocity_field.xmf").read_text()
        assert all(f"xdmf_{n}.h5:/velocity_field" in xmf for n in range(5))


def test_continuation_drops_later_records_of_the_earlier_run(tmp_path):
    """Continuing from a restart older than the output (e.g. a failed run) keeps one time
    line: records after the restart's time are replaced."""
    d = tmp_path / "r"
    inp = make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", nsnap=2)
    assert cli(d, inp) == 0
    shutil.copy(d / "restart.udf", d / "mid.udf")
    shutil.copy(state_path(str(d / "restart.udf")), state_path(str(d / "mid.udf")))
    rs = UDFManager(str(d / "mid.udf"))
    rs.put(4, "output.Num_snap")
    rs.write(str(d / "mid.udf"))
    shutil.copy(state_path(str(d / "restart.udf")), state_path(str(d / "mid.udf")))
    assert cli(d, "mid.udf") == 0                     # appends steps 6, 8
    ts = [t for t, _ in records(str(d / "output.udf"))]
    assert len(ts) == 5 and ts == sorted(ts)
    # continue again from the step-4 restart: the records of steps 6 and 8 are dropped
    # and written anew
    assert cli(d, "mid.udf") == 0
    ts2 = [t for t, _ in records(str(d / "output.udf"))]
    assert ts2 == ts


def test_continuation_without_state_file(tmp_path):
    """A restart.udf alone (written by another program, say) continues an FDM run: same
    fields, R_raw restarting at R."""
    d = tmp_path / "s"
    inp = make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", kBT=0.0)
    assert cli(d, inp) == 0
    rs = UDFManager(str(d / "restart.udf"))
    rs.put(4, "output.Num_snap")
    rs.write(str(d / "cont.udf"))                      # no state file next to it
    assert cli(d, "cont.udf") == 0
    doc = UDFManager(str(d / "restart.udf"))
    assert doc.get("resume.CONTINUE_FDM.Saved_Data.jikan")[0] == 8


def test_spectral_restart_continues_without_its_state_file(tmp_path, capsys):
    """Zeta / uk_dc alone (the original's packing, tests/integration/test_restart_interchange.py) carry
    the velocity; the run says it continues without the state file."""
    d = tmp_path / "z"
    inp = make_input(d, "Navier_Stokes")
    assert cli(d, inp) == 0
    rs = UDFManager(str(d / "restart.udf"))
    assert rs.get("resume.Calculation") == "CONTINUE"
    assert rs.size("resume.CONTINUE.Saved_Data.Zeta[]") == 16
    rs.put(3, "output.Num_snap")
    rs.write(str(d / "cont.udf"))
    cwd = os.getcwd()
    os.chdir(d)
    try:
        assert main(["-Icont.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed",
                     "11"]) == 0
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err
    assert "no matching state file" in err
    assert "############################ Parameters are restored." in err.splitlines()


def test_restart_of_another_type_is_refused(tmp_path, capsys):
    d = tmp_path / "w"
    inp = make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme")
    assert cli(d, inp) == 0
    rs = UDFManager(str(d / "restart.udf"))
    rs.put("Navier_Stokes_Cahn_Hilliard_FDM", "constitutive_eq.type")
    rs.write(str(d / "cont.udf"))
    assert cli(d, "cont.udf") == 2
    err = capsys.readouterr().err
    assert "resume.Calculation" in err and "CONTINUE_FDM_PHASE_SEPARATION" in err


def test_spectral_restart_in_a_define_that_calls_it_continue_original(tmp_path):
    """ex11's define.udf names the spectral restart CONTINUE_ORIGINAL (the manual's name)."""
    d = tmp_path / "orig"
    inp = make_input(d, "Navier_Stokes", nsnap=1)
    ex11 = os.path.join(SAMPLES, "kapsel-udf", "ex11", "define.udf")   # fixture copy
    shutil.copy(ex11, d / "define11.udf")
    cwd = os.getcwd()
    os.chdir(d)
    try:
        assert main([f"-I{inp}", "-Ooutput.udf", "-Ddefine11.udf", "-Rrestart.udf", "--seed",
                     "1", "--quiet"]) == 0
        rs = UDFManager("restart.udf")
        assert rs.get("resume.Calculation") == "CONTINUE_ORIGINAL"
        rs.put(2, "output.Num_snap")
        rs.write("cont.udf")
        shutil.copy(state_path("restart.udf"), state_path("cont.udf"))
        assert main(["-Icont.udf", "-Ooutput.udf", "-Ddefine11.udf", "-Rrestart.udf",
                     "--quiet"]) == 0
        assert UDFManager("restart.udf").get("resume.CONTINUE_ORIGINAL.Saved_Data.jikan")[0] == 4
    finally:
        os.chdir(cwd)
