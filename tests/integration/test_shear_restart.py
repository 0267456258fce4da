"""Continuation of the sheared types: N steps + restart + M steps is bit-identical to N + M
steps in one run (fields, particles, frame strain oblique.degree_oblique, shear log)."""

import numpy as np
import pytest

from udf import UDFManager

from builders import continue_input, fdm_input, records, saved_data, shear_cli, shear_input


CASES = [("Shear_Navier_Stokes", {}),
         ("Shear_Navier_Stokes_Lees_Edwards", {}),
         ("Shear_Navier_Stokes_Lees_Edwards_FDM", {"ns": "explicit_scheme"}),
         ("Shear_Navier_Stokes_Lees_Edwards_FDM", {"ns": "implicit_scheme"}),
         ("Shear_NS_LE_CH_FDM", {"ns": "implicit_scheme", "ch": "implicit_scheme"}),
         ("Shear_NS_LE_CH_FDM", {"ns": "explicit_scheme", "ch": "explicit_scheme"}),
         ("Shear_Navier_Stokes_Lees_Edwards", {"obj": "rigid"}),
         ("Shear_Navier_Stokes_Lees_Edwards", {"obj": "chain"}),
         ("Shear_Navier_Stokes_Lees_Edwards_FDM", {"ns": "implicit_scheme", "obj": "rigid"})]


def inp(d, eq, nsnap, obj=None, **kw):
    common = dict(gts=5, nsnap=nsnap, rate=0.6, kind="AC", freq=0.02)
    if obj is not None:                 # chains or rigid bodies (Lees-Edwards images)
        from builders import bodies_input
        return bodies_input(d, eq, obj, **common, **kw)
    common["particles"] = 2
    if eq.endswith("FDM"):
        return fdm_input(d, eq=eq, **common, **kw)
    return shear_input(d, eq=eq, **common)


@pytest.mark.parametrize("eq,kw", CASES, ids=[f"{e}-{'-'.join(k.values())}" for e, k in CASES])
def test_shear_continuation_is_bit_identical(tmp_path, eq, kw):
    one = inp(tmp_path / "one", eq, 4, **kw)
    assert shear_cli(tmp_path / "one", one) == 0
    two = inp(tmp_path / "two", eq, 2, **kw)
    assert shear_cli(tmp_path / "two", two) == 0
    continue_input(tmp_path / "two")
    assert shear_cli(tmp_path / "two", str(tmp_path / "two" / "cont.udf")) == 0
    a = saved_data(str(tmp_path / "one" / "restart.udf"))
    b = saved_data(str(tmp_path / "two" / "restart.udf"))
    assert set(a) == set(b)
    for k in a:
        assert np.array_equal(a[k], b[k]), k
    ra = records(str(tmp_path / "one" / "output.udf"))
    rb = records(str(tmp_path / "two" / "output.udf"))
    assert len(ra) == len(rb) == 5
    for (ta, pa), (tb, pb) in zip(ra, rb):
        assert ta == tb and np.array_equal(pa, pb)
    la = np.loadtxt(tmp_path / "one" / "shear_stress.dat")
    lb = np.loadtxt(tmp_path / "two" / "shear_stress.dat")
    assert len(la) == len(lb) == 5 and np.array_equal(la, lb)
    if "Lees" in eq or "LE" in eq:
        kind = UDFManager(str(tmp_path / "one" / "restart.udf")).get("resume.Calculation")
        g = UDFManager(str(tmp_path / "one" / "restart.udf")).get(
            f"resume.{kind}.Saved_Data.oblique.degree_oblique")
        assert g != 0.0 and abs(g) <= 0.5 + 1e-6


@pytest.mark.parametrize("eq,kw", [CASES[1], CASES[2]], ids=["LE", "LE_FDM"])
def test_continuation_keeps_the_frames_own_clock(tmp_path, eq, kw):
    """The sheared fluid's clock is accumulated (t += dt) and the frame strain is a function
    of it: with dt 0.05, 0.05 added 6 times is not 6 x 0.05, so a continuation that took the
    time from the step count would differ in the last bit (found by the kill sweep of
    tests/integration/test_kill_points.py; the state file keeps the clock, ``fluid_time``)."""
    runs = {}
    for name, nsnap in (("one", 4), ("two", 2)):
        d = tmp_path / name
        path = inp(d, eq, nsnap, **kw)
        u = UDFManager(path)
        u.put("manual", "time_increment.type")
        u.put(0.05, "time_increment.manual.delta_t")
        u.put(3, "output.GTS")
        u.write(path)
        assert shear_cli(d, path) == 0
        runs[name] = d
    continue_input(runs["two"])
    assert shear_cli(runs["two"], str(runs["two"] / "cont.udf")) == 0
    a = saved_data(str(runs["one"] / "restart.udf"))
    b = saved_data(str(runs["two"] / "restart.udf"))
    assert set(a) == set(b)
    for k in a:
        assert np.array_equal(a[k], b[k]), k
