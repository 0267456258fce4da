"""A run that blows up writes no NaN or infinity (issue 17, stability map): the sheared
types print their stress table every step (stdout, or stderr for Shear_Navier_Stokes; users
redirect it to a file), while the blow-up checks run every 10 steps and at snapshots, so
a row is checked before it is printed."""
import re

import numpy as np
import pytest

from kapsel.cli import main

from builders import make_input


def table_rows(text):
    """The all-numeric lines of a console stream (the stress table's rows), as strings."""
    rows = []
    for line in text.splitlines():
        tokens = line.split()
        try:
            [float(t) for t in tokens]
        except ValueError:
            continue
        if tokens:
            rows.append(tokens)
    return rows


@pytest.mark.parametrize("eq,model", [("Shear_Navier_Stokes_Lees_Edwards", "ShearLEModel"),
                                      ("Shear_Navier_Stokes", "ZigzagModel")])
def test_the_stress_table_never_prints_a_non_finite_row(tmp_path, capsys, monkeypatch, eq,
                                                        model):
    d = tmp_path / "run"
    make_input(d, eq, particles=2, gts=20, nsnap=2, kBT=0.0)
    from kapsel.models import shear, zigzag
    cls = getattr(shear if "Lees" in eq else zigzag, model)
    advance = cls.advance

    def poisoned(self):
        advance(self)
        if self.step_index == 13:          # between the checks at steps 10 and 20
            self.fluid.u_hat[0, 1, 2, 3] = np.nan
    monkeypatch.setattr(cls, "advance", poisoned)
    assert main([f"-I{d}/input.udf", f"-O{d}/output.udf", f"-D{d}/define.udf",
                 f"-R{d}/restart.udf", "--seed", "11"]) == 1    # not --quiet: all rows
    out = capsys.readouterr()
    rows = table_rows(out.out) + table_rows(out.err)
    assert rows, "the table printed no rows"
    bad = [r for r in rows if not np.isfinite([float(t) for t in r]).all()]
    assert not bad, bad[:2]
    m = re.search(r"the run stopped at step (\d+)", out.err)
    assert m and 13 <= int(m.group(1)) < 20, out.err[-500:]   # before the check at step 20
    assert len(rows) == int(m.group(1)) - 1                    # every good step's row


def test_rate_zero_keeps_the_originals_nan_viscosity(tmp_path, capsys):
    """At shear rate 0 the viscosity column is stress / 0 = NaN, as the original prints
    it: not an instability."""
    d = tmp_path / "run"
    eq = "Shear_Navier_Stokes_Lees_Edwards"
    make_input(d, eq, particles=2, gts=5, nsnap=2, kBT=0.0)
    from udf import UDFManager
    u = UDFManager(str(d / "input.udf"))
    u.put("DC", f"constitutive_eq.{eq}.External_field.type")
    u.put(0.0, f"constitutive_eq.{eq}.External_field.DC.Shear_rate")
    u.write(str(d / "input.udf"))
    assert main([f"-I{d}/input.udf", f"-O{d}/output.udf", f"-D{d}/define.udf",
                 f"-R{d}/restart.udf", "--seed", "11", "--quiet"]) == 0
    rows = table_rows(capsys.readouterr().out)
    assert len(rows) == 11 and all(r[-1].lower() == "nan" for r in rows)


def _poison_step(monkeypatch, step, spoil):
    """Navier_Stokes runs ``spoil(model)`` right after its step number ``step``."""
    from kapsel.models import spectral
    advance = spectral.SpectralModel.advance

    def poisoned(self):
        advance(self)
        if self.step_index == step:
            spoil(self)
    monkeypatch.setattr(spectral.SpectralModel, "advance", poisoned)


def test_an_interrupt_just_after_a_blow_up_says_so_without_a_traceback(tmp_path, capsys,
                                                                      monkeypatch):
    """SIGINT arrives in the step where the fluid turned NaN, before the every-10-steps check:
    the run stops with exit 1 and a message (the state is not saved; the restart file keeps
    the last good one), never a traceback, and the advice names no scheme the spectral type
    lacks."""
    import os
    import signal

    d = tmp_path / "run"
    make_input(d, "Navier_Stokes", particles=2, gts=5, nsnap=4, kBT=0.0)

    def spoil(model):
        model.fluid.u_hat[0, 1, 2, 3] = np.nan
        os.kill(os.getpid(), signal.SIGINT)
    _poison_step(monkeypatch, 13, spoil)
    assert main([f"-I{d}/input.udf", f"-O{d}/output.udf", f"-D{d}/define.udf",
                 f"-R{d}/restart.udf", "--seed", "11", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "interrupted at step 13, where the field u is not finite" in err, err[-600:]
    assert "holds the last good state (step 10)" in err
    assert "implicit_scheme" not in err


def test_a_blow_up_is_named_without_numpys_warnings(tmp_path, capsys, monkeypatch):
    """A step that overflows (u_hat set to 1e300 at step 12) stops the run with kapsel-py's
    message only: numpy's RuntimeWarnings (overflow, invalid value), which used to fill the
    screen before it, are not printed (simulation.advance)."""
    d = tmp_path / "run"
    make_input(d, "Navier_Stokes", particles=2, gts=5, nsnap=4, kBT=0.0)

    def spoil(model):
        model.fluid.u_hat[:, 1, 2, 3] = 1e300
    _poison_step(monkeypatch, 12, spoil)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # a warning would now raise and fail the run
        assert main([f"-I{d}/input.udf", f"-O{d}/output.udf", f"-D{d}/define.udf",
                     f"-R{d}/restart.udf", "--seed", "11", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "RuntimeWarning" not in err and "Traceback" not in err
    assert "the run stopped at step" in err and "not finite" in err
