"""Every real KAPSEL input (samples/kapsel-udf/*/: the original's examples and sample,
define.udf versions 3.02 to 4.1, copied from ../shared/kapsel-udf) is either accepted
unchanged, or refused up front -- exit 2, one line, nothing written -- only for features
kapsel-py does not have (docs/running.md, "Not supported"), all named in that line.

The accepted ones then run in a copy with only output.GTS / Num_snap edited, with the field
output (output.AVS) the input asks for: for 200 steps (LONG: or their own length, if
shorter), in the fast suite where that is cheap (FAST_200), as slow tests otherwise (their
times: TIMES_200); those also run 2 steps in the fast suite.  The two that are too large
for a test (ex02: 256 x 256 x 512 with 3204 particles; ex11: 128^3 with 4096 particles) are
checked unchanged and run on a reduced mesh with fewer particles (REDUCED).  The unchanged
inputs run by the original and by kapsel-py side by side, with their agreement:
bench/real_inputs.py (bench/results/real_inputs.md)."""
import glob
import os
import shutil

import numpy as np
import pytest

from kapsel import cli
from kapsel.config import from_document
from kapsel.io.restart import schema_kind
from udf import UDFManager

from builders import TESTS


HERE = TESTS
REAL = os.path.join(HERE, "..", "samples", "kapsel-udf")
INPUTS = sorted(p for p in glob.glob(os.path.join(REAL, "*", "*.udf"))
                if os.path.basename(p) not in ("define.udf", "kapsel_unit.udf"))

# input -> the unsupported features its refusal must name (empty: it runs)
UNSUPPORTED = {
    "ex01/colloid_1.udf": [],
    "ex02/gravity.udf": [],
    "ex06/s000_t010_free.udf": [],
    "ex06/s001_t010_free.udf": [],
    "ex09/squirm_single_a+2.udf": [],
    "ex10/input_rigid_free1.udf": [],
    "ex11/fdm_4096p_shear_1e-2.udf": [],
    "ex12/a2_N65_Rer025_dipole_mirror.udf": [],
    "ex13/pickering_emulsion.udf": [],
    "ex14/input.udf": [],
    "sample/input.udf": [],
}

# inputs too large for a test run: (mesh, particles of the one species) of the run copy
REDUCED = {"ex02/gravity.udf": ((5, 5, 5), 20),
           "ex11/fdm_4096p_shear_1e-2.udf": ((5, 5, 5), 16)}


def name_of(path):
    return os.path.relpath(path, REAL).replace(os.sep, "/")


def copy_example(path, d):
    """The example's directory (define.udf, kapsel_unit.udf, the input) copied to ``d``."""
    for f in os.listdir(os.path.dirname(path)):
        shutil.copy(os.path.join(os.path.dirname(path), f), d / f)
    return os.path.basename(path)


def listing(d):
    return sorted(os.listdir(d))


def test_the_walk_covers_every_real_input():
    assert sorted(map(name_of, INPUTS)) == sorted(UNSUPPORTED)


@pytest.mark.parametrize("path", INPUTS, ids=name_of)
def test_real_input_unchanged_is_accepted_or_refused_for_unsupported_features_only(
        path, tmp_path, monkeypatch, capsys):
    name = name_of(path)
    inp = copy_example(path, tmp_path)
    monkeypatch.chdir(tmp_path)
    # the inputs, not the test machine's memory: ex02 needs about 7 GB (a machine with less
    # refuses it, tests/integration/test_check_banner.py)
    monkeypatch.setenv("KAPSEL_PY_MEMORY_LIMIT_GB", "64")
    before = listing(tmp_path)
    try:
        cfg, doc, define = cli.validate(inp, "define.udf")
        problems = []
    except cli.BadInput as e:
        problems = str(e).splitlines()
    features = UNSUPPORTED[name]
    if not problems:
        assert not features, f"{name} was accepted; expected refused for {features}"
        assert cfg.type and cfg.output.total_steps > 0
        return
    assert len(problems) == 1, problems          # one line: nothing else is wrong
    line = problems[0]
    assert f"{inp}:" in line and "not supported by kapsel-py" in line, line
    named = [part for part in line.split(": ", 2)[-1].split("; ") if " = " in part]
    for f in features:
        assert f in line, (f, line)
    others = [p for p in named if not any(f in p for f in features)]
    assert not others, others                    # no feature refused that is not expected
    # through the command line: exit 2, that one line, no traceback, nothing written
    code = cli.main([f"-I{inp}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.strip().splitlines() == [f"kapsel-py: error: {line}"]
    assert listing(tmp_path) == before


def run_copy(path, d, steps=2, snapshots=1):
    """A copy of the input that runs ``steps`` steps (``snapshots`` snapshots, every
    steps / snapshots), reduced where REDUCED says (with AVS off there: its crop is the full
    mesh's); returns its file name."""
    name = name_of(path)
    inp = copy_example(path, d)
    u = UDFManager(str(d / inp))
    u.put(steps // snapshots, "output.GTS")
    u.put(snapshots, "output.Num_snap")
    if name in REDUCED:
        u.put("OFF", "output.AVS")
        mesh, n = REDUCED[name]
        u.put(list(mesh), "mesh")
        u.put(n, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.write(str(d / "run.udf"))
    return "run.udf"


RUNS = [p for p in INPUTS if not UNSUPPORTED[name_of(p)]]
LONG = 200
# test_real_input_runs_200_steps of each input: seconds of the test call (wall, 2-core VM at
# load 3-5) / CPU of the pytest process (user + system), 1 thread, 2026-12-01.  The two ex06
# run in the fast suite (FAST_200: about 15 s more than their 2-step runs); the others are
# slow tests and keep a 2-step run in the fast suite.  ex02 and ex11 run REDUCED.
TIMES_200 = {
    "ex06/s000_t010_free.udf": (7, 8),
    "ex06/s001_t010_free.udf": (9, 7),
    "ex14/input.udf": (29, 18),
    "sample/input.udf": (24, 19),
    "ex10/input_rigid_free1.udf": (93, 45),         # 2026-12-01 at load 3 (ran 7 steps before the rigid merge)
    "ex02/gravity.udf": (16, 8),
    "ex12/a2_N65_Rer025_dipole_mirror.udf": (74, 25),
    "ex09/squirm_single_a+2.udf": (55, 29),
    "ex01/colloid_1.udf": (87, 51),
    "ex11/fdm_4096p_shear_1e-2.udf": (32, 20),
    "ex13/pickering_emulsion.udf": (706, 138),      # at load 7-11
}
FAST_200 = {"ex06/s000_t010_free.udf", "ex06/s001_t010_free.udf"}


def _run(inp, d, monkeypatch, capsys):
    """kapsel-py -I<inp> ... --seed 1 --quiet in ``d``: exit 0; its output.udf."""
    monkeypatch.chdir(d)
    code = cli.main([f"-I{inp}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                     "--seed", "1", "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    return UDFManager("output.udf")


@pytest.mark.parametrize("path", [p for p in RUNS if name_of(p) not in FAST_200], ids=name_of)
def test_real_input_runs(path, tmp_path, monkeypatch, capsys):
    inp = run_copy(path, tmp_path)
    out = _run(inp, tmp_path, monkeypatch, capsys)
    assert out.totalRecord() == 2
    out.jump(1)
    assert out.get("t") == 2.0                       # the record's t is its step
    restart = UDFManager("restart.udf")
    assert restart.get("resume.Calculation") != "NEW"


def _long_params():
    for p in RUNS:
        marks = () if name_of(p) in FAST_200 else (pytest.mark.slow,)
        yield pytest.param(p, id=name_of(p), marks=marks)


@pytest.mark.parametrize("path", list(_long_params()))
def test_real_input_runs_200_steps(path, tmp_path, monkeypatch, capsys):
    """LONG steps (or the input's own length) with a record every LONG / 10 steps: exit 0,
    every record written at its step with finite particle positions and velocities, the
    positions in the box, and the restart that of the last step."""
    cfg = from_document(UDFManager(path), path)
    steps = min(LONG, cfg.output.total_steps)
    snaps = 10 if steps % 10 == 0 else 1
    inp = run_copy(path, tmp_path, steps, snapshots=snaps)
    out = _run(inp, tmp_path, monkeypatch, capsys)
    assert out.totalRecord() == snaps + 1
    box = np.asarray(from_document(UDFManager(inp), inp).mesh.box)
    for r in range(out.totalRecord()):
        out.jump(r)
        assert out.get("t") == r * (steps // snaps)
        if cfg.particles.count:
            R = np.asarray(out.getArray("Particles[].R"), float)
            v = np.asarray(out.getArray("Particles[].v"), float)
            assert np.isfinite(R).all() and np.isfinite(v).all()
            assert (R >= 0).all() and (R <= box).all()      # single precision: R <= L
    restart = UDFManager("restart.udf")
    kind = restart.get("resume.Calculation")
    assert kind != "NEW"
    ts = restart.get(f"resume.{schema_kind(restart, kind)}.Saved_Data.jikan.ts")
    assert ts == steps                  # after steps + 1 steps, as the original says


def test_a_define_without_gr_masses_restarts_and_continues(tmp_path, monkeypatch):
    """ex10's define.udf (v3.02) has no GR_masses[] / GR_moments_body[] in its restart
    schema (a rigid run used to fail at the first restart write): restart.udf gets what the
    schema holds, the state file the rest, and the run continues from them."""
    inp = run_copy(os.path.join(REAL, "ex10", "input_rigid_free1.udf"), tmp_path, steps=1)
    monkeypatch.chdir(tmp_path)
    flags = ["-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "1", "--quiet"]
    assert cli.main([f"-I{inp}", *flags]) == 0
    with np.load("restart.udf.state.npz") as z:
        assert z["Saved_Data.GR_masses"].shape == (1,)
        assert z["Saved_Data.GR_moments_body"].shape == (1, 9)
    rs = UDFManager("restart.udf")
    assert rs.size("resume.CONTINUE.Saved_Data.GR_body[]") == 65
    rs.put(2, "output.Num_snap")
    rs.write("restart.udf")
    assert cli.main(["-Irestart.udf", *flags]) == 0
    out = UDFManager("output.udf")
    assert out.totalRecord() == 3
    out.jump(2)
    assert out.get("t") == 2.0
