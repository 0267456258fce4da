"""The run API (kapsel.api.Simulation): the same run as the command line, bit for bit."""
import os
import re
import shutil

import numpy as np
import pytest

from kapsel import BadInput, Simulation

from builders import api_input, api_simulation, continue_input, run_cli, SAMPLES, SEED, TESTS


BENCH = os.path.join(TESTS, "..", "bench")


def output_hashes(d) -> dict:
    """{file: hash} of every output in ``d`` as bench/bitident.py hashes them (output.udf
    without its run-id line, the state file without the run id, HDF5 files by their
    datasets and attributes)."""
    import sys
    from pathlib import Path
    if BENCH not in sys.path:
        sys.path.insert(0, BENCH)
    from bitident import hashes
    return hashes(Path(d))


@pytest.fixture(scope="module", params=["Navier_Stokes", "Navier_Stokes_FDM"])
def cli_run(request, tmp_path_factory):
    """A 20-step command-line run (16^3, 8 particles, snapshots every 5 steps)."""
    d = str(tmp_path_factory.mktemp(request.param))
    api_input(d, request.param)
    assert run_cli(d, "input.udf", seed=SEED) == 0
    return request.param, d


def test_run_10_then_10_is_the_command_line_run(cli_run, tmp_path):
    """run(10) + run(10) writes what the command line's 20-step run writes: records,
    restart and its state, the field files; the state read in between is the model's."""
    eq, ref = cli_run
    d = str(tmp_path)
    api_input(d, eq)
    sim = api_simulation(d)
    sim.run(10)
    assert (sim.step, sim.time) == (10, pytest.approx(10 * sim.dt))
    p = sim.particles
    assert p.R.shape == p.v.shape == p.omega.shape == p.f_hydro.shape == (8, 3)
    assert p.q.shape == (8, 4)
    assert sim.field("u").shape == (3, 16, 16, 16) and sim.field("phi").shape == (16, 16, 16)
    assert [r["t"] for r in sim.records()] == [0, 5, 10]
    sim.run(10)
    assert sim.ended and sim.step == 21       # one step after the last snapshot, as the CLI
    mine, theirs = output_hashes(d), output_hashes(ref)
    assert sorted(mine) == sorted(theirs)
    assert [f for f in mine if mine[f] != theirs[f]] == []
    if eq == "Navier_Stokes_FDM":
        assert any(f.endswith(".h5") for f in mine)


def test_run_to_the_end_in_one_call(cli_run, tmp_path):
    eq, ref = cli_run
    if eq != "Navier_Stokes":
        pytest.skip("one type is enough")
    d = str(tmp_path)
    api_input(d, eq)
    api_simulation(d).run()
    assert output_hashes(d) == output_hashes(ref)


def test_particles_and_fields_equal_the_restart(tmp_path):
    """What the API reads at the end is the state the restart holds: the particles of
    restart.udf, the velocity field of the FDM type's restart."""
    from udf import UDFManager
    d = str(tmp_path)
    api_input(d, "Navier_Stokes_FDM")
    sim = api_simulation(d, overrides={"output.Num_snap": 1})
    sim.run()
    rs = UDFManager(os.path.join(d, "restart.udf"))
    base = f"resume.{sim.model.restart_kind}.Saved_Data"
    p = sim.particles
    for k in ("R", "v", "omega"):
        assert np.array_equal(np.asarray(rs.getArray(f"{base}.Particles[].{k}")),
                              getattr(p, k)), k
    saved_u = np.moveaxis(np.asarray(rs.getArray(f"{base}.U[][][]"), dtype=float), -1, 0)
    u = sim.field("u")
    assert u.shape == saved_u.shape == (3, 16, 16, 16)
    assert np.array_equal(u, saved_u)


def test_overrides_take_effect_and_are_written(tmp_path):
    d = str(tmp_path)
    api_input(d, "Navier_Stokes")
    sim = api_simulation(d, overrides={"output.Num_snap": 2, "mesh.NPX": 3})
    assert sim.total_steps == 10 and sim.field("u").shape == (3, 8, 16, 16)
    sim.run(until=3.5 * sim.dt)         # the first step at or after t
    assert sim.step == 4
    sim.run()
    from udf import UDFManager
    assert UDFManager(os.path.join(d, "restart.udf")).get("mesh.NPX") == 3
    assert [r["t"] for r in sim.records()] == [0, 5, 10]


def test_bad_input_raises_every_message_and_writes_nothing(tmp_path):
    d = str(tmp_path)
    api_input(d, "Navier_Stokes")
    before = sorted(os.listdir(d))
    with pytest.raises(BadInput) as e:
        api_simulation(d, overrides={"mesh.NPX": -1, "constitutive_eq.Navier_Stokes.ETA": -2.0})
    lines = str(e.value).splitlines()
    assert any("NPX" in ln for ln in lines) and any("ETA" in ln for ln in lines), lines
    assert all("input.udf" in ln for ln in lines)
    with pytest.raises(BadInput, match=r"cannot set no\.such\.item"):
        api_simulation(d, overrides={"no.such.item": 1})
    assert sorted(os.listdir(d)) == before


def test_refuses_to_replace_a_run_and_to_run_past_the_end(tmp_path):
    d = str(tmp_path)
    api_input(d, "Navier_Stokes")
    sim = api_simulation(d, overrides={"output.Num_snap": 1})
    with pytest.raises(ValueError, match="ends at step 5"):
        sim.run(6)
    sim.run()
    with pytest.raises(BadInput, match="exists; pass --overwrite"):
        api_simulation(d)
    api_simulation(d, overwrite=True).close()


def test_a_user_activity_runs_on_its_schedule_and_can_be_removed(tmp_path):
    d = str(tmp_path)
    api_input(d, "Navier_Stokes")
    sim = api_simulation(d)
    seen = []
    act = sim.add(lambda s: seen.append((s.step, s.particles.R[0, 0])), every=3)
    sim.run(7)
    assert [s for s, _ in seen] == [0, 3, 6]
    sim.remove(act)
    sim.remove("output.udf")
    with pytest.raises(ValueError, match="part of the run"):
        sim.remove("restart")
    sim.run()
    assert [s for s, _ in seen] == [0, 3, 6]
    assert [r["t"] for r in sim.records()] == [0, 5]      # no records after the removal


@pytest.mark.parametrize("state", ["ours", "text only"])
def test_continues_from_its_restart_as_the_command_line(tmp_path, state):
    """A run continued through the API from the restart of a 10-step run writes what
    the command line's continuation writes; "text only": without the state file, as from
    the original's restart.udf."""
    from kapsel.io.restart import state_path
    a, b = str(tmp_path / "a"), str(tmp_path / "b")
    for d in (a, b):
        api_input(d, "Navier_Stokes")
        sim = api_simulation(d, overrides={"output.Num_snap": 2})
        sim.run()
    cont_a, cont_b = continue_input(a, num_snap=4), continue_input(b, num_snap=4)
    if state == "text only":
        for c in (cont_a, cont_b):
            os.remove(state_path(c))
    assert run_cli(a, cont_a, seed=SEED) == 0
    sim = Simulation.from_restart(cont_b, os.path.join(b, "output.udf"),
                                  os.path.join(b, "define.udf"),
                                  os.path.join(b, "restart.udf"), seed=SEED)
    assert sim.resumed and sim.step == 11
    sim.run()
    assert output_hashes(a) == output_hashes(b)


def test_the_readme_example_runs(tmp_path, monkeypatch, cli_run):
    """README "Driving a run from Python": its code, run in a copy of the sample, gives
    the command line's 20-step run."""
    eq, ref = cli_run
    if eq != "Navier_Stokes":
        pytest.skip("the README's example is spectral")
    readme = open(os.path.join(TESTS, "..", "README.md")).read()
    section = readme.split("## Driving a run from Python", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    for f in ("input.udf", "define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(SAMPLES, f), tmp_path / f)
    monkeypatch.chdir(tmp_path)
    code = code.replace("seed=1", f"seed={SEED}")
    exec(compile(code, "README.md", "exec"), {})
    assert output_hashes(tmp_path) == output_hashes(ref)


def test_interrupt_and_failure_raise_the_command_lines_messages(tmp_path):
    """SIGINT (here sent by a user activity at step 5) stops the run at that step with its
    state saved, raising Interrupted with the command line's message; a blow-up raises
    RunError naming the restart's last good step."""
    import signal

    from kapsel import Interrupted, RunError
    from udf import UDFManager
    a, b = str(tmp_path / "a"), str(tmp_path / "b")
    api_input(a, "Navier_Stokes")
    sim = api_simulation(a)
    sim.add(lambda s: s.step == 5 and os.kill(os.getpid(), signal.SIGINT), every=5)
    with pytest.raises(Interrupted) as e:
        sim.run()
    assert e.value.line.startswith("kapsel-py: interrupted at step 5 (t = ")
    assert "Continue with: kapsel-py -I" in str(e.value) and sim.ended
    assert UDFManager(os.path.join(a, "restart.udf")).get(    # the original's ts: the
        "resume.CONTINUE.Saved_Data.jikan.ts") == 4               # step before (§6.3)
    api_input(b, "Navier_Stokes")
    sim = api_simulation(b)

    def spoil(s):
        if s.step == 5:
            s.model.fluid.u_hat[0, 1, 2, 3] = np.nan
    sim.add(spoil, every=5)
    with pytest.raises(RunError) as e:
        sim.run()
    assert e.value.line.startswith("kapsel-py: error: the run stopped at step 10: ")
    assert "holds the last good state (step 5)" in str(e.value)
