"""The run configuration and the command line: typed values, refused values with the path
and the value in the message, unsupported options named, the CLI's flags and exit codes."""
import os
import subprocess
import sys

import pytest

from kapsel import cli, config

from builders import sample_copy, TESTS


HERE = TESTS
SAMPLES = os.path.join(HERE, "..", "samples")
SHARED = os.path.join(HERE, "..", "..", "shared", "kapsel-udf")


def test_sample_config():
    cfg = config.load(os.path.join(SAMPLES, "input.udf"))
    assert cfg.type == "Navier_Stokes_Cahn_Hilliard_FDM"
    assert cfg.mesh.shape == (32, 32, 32) and cfg.mesh.DX == 1.0
    assert cfg.fluid.ns_solver == "explicit_scheme"
    assert cfg.fluid.RHO == 1.0 and cfg.fluid.ETA == 1.0 and cfg.fluid.kBT == 0.0
    assert cfg.phase.ch_solver == "implicit_scheme"
    assert cfg.phase.tolerance == pytest.approx(1e-9) and cfg.phase.maximum_iteration == 1500
    assert cfg.phase.potential == "Landau" and cfg.phase.a == 1.0 and cfg.phase.b == 1.0
    assert cfg.phase.composition_ratio == 0.0 and cfg.phase.initial_fluctuation == 0.05
    assert cfg.particles.object_type == "spherical_particle"
    assert cfg.particles.count == 8 and cfg.particles.A == 4.0 and cfg.particles.A_XI == 2.0
    assert cfg.interactions.LJ_powers == "12:6" and cfg.interactions.EPSILON == 5.0
    assert cfg.interactions.LJ_truncate == "OFF"
    assert cfg.switches.ROTATION and cfg.switches.fix_cell == (True, True, True)
    assert cfg.switches.init_distribution == "uniform_random"
    assert cfg.time.kind == "auto" and cfg.time.factor == 1.0
    assert cfg.output.GTS == 100 and cfg.output.Num_snap == 10 and cfg.output.UDF
    assert cfg.resume.calculation == "NEW"
    with pytest.raises(Exception):
        cfg.mesh.NPX = 3  # frozen


def test_shear_fixture_config():
    path = os.path.join(HERE, "..", "samples", "kapsel-udf", "ex11", "fdm_4096p_shear_1e-2.udf")
    cfg = config.load(path)
    assert cfg.type == "Shear_NS_LE_CH_FDM" and cfg.shear.kind == "DC"
    assert cfg.shear.shear_rate == 0.01 and cfg.mesh.shape == (128, 128, 128)
    assert cfg.fluid.ns_solver == "explicit_scheme" and cfg.phase.ch_solver == "implicit_scheme"
    assert cfg.particles.count == 4096 and cfg.switches.OBL_INT == "linear"


@pytest.mark.parametrize("old,new,words", [
    ("{{\"explicit_scheme\",{-9.00000000000000,1000,\"OFF\",{1.00000000000000,10.0000000000000}}}"
     "{\"implicit_scheme\",{-9.00000000000000,1500}}1.00000000000000,1.00000000000000,"
     "1.00000000000000",
     "{{\"explicit_scheme\",{-9.00000000000000,1000,\"OFF\",{1.00000000000000,10.0000000000000}}}"
     "{\"implicit_scheme\",{-9.00000000000000,1500}}1.00000000000000,1.00000000000000,"
     "-1.00000000000000",
     ["Navier_Stokes_Cahn_Hilliard_FDM.ETA", "-1.0", "positive"]),
    ("mesh:{5,5,5}", "mesh:{0,5,5}", ["mesh.NPX", "= 0", "at least 1"]),
    ("A:4.00000000000000", "A:20.0", ["A = 20.0", "does not fit"]),
    ("[{8,1.00000000000000,0.0,\"NONE\"", "[{4000,1.00000000000000,0.0,\"NONE\"",
     ["4000 particles", "cannot fit"]),
    ("time_increment:{\"auto\",{1.00000000000000}", "time_increment:{\"auto\",{0.0}",
     ["time_increment.auto.factor", "positive"]),
    ("output:{100,10,", "output:{0,10,", ["output.GTS", "at least 1"]),
    ("{\"implicit_scheme\",{-9.00000000000000,1500}}",
     "{\"implicit_scheme\",{9.00000000000000,1500}}",
     ["CH_solver.implicit_scheme.tolerance", "negative"]),
    ("\"OFF\",{0.0,0.0,0.0}{0.0,0.0,0.0}0.0,0.0}]", "\"TUMBLER\",{0.0,0.0,0.0}{0.0,0.0,0.0}0.0,0.0}]",
     ["janus_propulsion", "TUMBLER", "Navier_Stokes or Shear_Navier_Stokes"]),
    ("output:{100,10,\"OFF\",{\"output\",\"data\",\"EXTENDED\",{{\"HDF5\"}{\"YES\",{{0,8,4}",
     "output:{100,10,\"ON\",{\"output\",\"data\",\"EXTENDED\",{{\"HDF5\"}{\"YES\",{{0,8,5}",
     ["output.ON.EXTENDED.Print_field.YES.Slab_x", "start + (count-1) stride < 32"]),
])
def test_invalid_values_are_refused(tmp_path, old, new, words):
    path = sample_copy(tmp_path, (old, new))
    with pytest.raises(config.ConfigError) as e:
        config.load(path)
    msg = str(e.value)
    assert "input.udf:" in msg, msg
    for w in words:
        assert w in msg, (w, msg)


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "kapsel.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def test_cli_unknown_select_choice(tmp_path):
    path = sample_copy(tmp_path, ('"Navier_Stokes_Cahn_Hilliard_FDM"', '"Navier_Stokes_XYZ"'))
    r = run_cli(f"-I{path}", f"-D{tmp_path / 'define.udf'}", cwd=tmp_path)
    assert r.returncode == 2
    assert "Navier_Stokes_XYZ" in r.stderr and "constitutive_eq.type" in r.stderr
    assert "Traceback" not in r.stderr


def test_cli_unimplemented_type_is_named(tmp_path, monkeypatch):
    from kapsel import models, typespec  # noqa: F401  (register the types first)
    monkeypatch.setattr(typespec, "SOLVERS", {})
    path = sample_copy(tmp_path)
    code = cli.main([f"-I{path}", "-D", str(tmp_path / "define.udf")])
    assert code == 2


def test_cli_flags_with_and_without_space(tmp_path, capsys, monkeypatch):
    from kapsel import models, typespec  # noqa: F401  (registered before the stub)
    seen = {}
    monkeypatch.setitem(typespec.SOLVERS, "Navier_Stokes_Cahn_Hilliard_FDM",
                        lambda cfg, args, doc: seen.setdefault("args", args))
    monkeypatch.setattr(cli, "run_to_end", lambda args, prepared: 0)
    monkeypatch.setattr("kapsel.io.writers.check_output", lambda cfg, model: None)
    path = sample_copy(tmp_path)
    d = str(tmp_path / "define.udf")
    assert cli.main([f"-I{path}", f"-O{tmp_path / 'o.udf'}", f"-D{d}", "-R", "r.udf",
                     "--threads", "2", "--seed", "5", "--quiet"]) == 0
    a = seen["args"]
    assert a.input == path and a.output.endswith("o.udf") and a.restart == "r.udf"
    assert a.threads == 2 and a.seed == 5


def test_cli_help_version_and_missing_file(tmp_path):
    r = run_cli("--help")
    assert r.returncode == 0 and "-I" in r.stdout and "--threads" in r.stdout
    r = run_cli("--version")
    assert r.returncode == 0 and "kapsel-py" in r.stdout
    r = run_cli(f"-I{tmp_path / 'missing.udf'}")
    assert r.returncode == 2 and "missing.udf" in r.stderr and "Traceback" not in r.stderr


def test_cli_syntax_error_has_position(tmp_path):
    path = sample_copy(tmp_path, ("A_XI:2.00000000000000", "A_XI:2.0 ]"))
    r = run_cli(f"-I{path}", f"-D{tmp_path / 'define.udf'}")
    assert r.returncode == 2 and "input.udf:" in r.stderr and "Traceback" not in r.stderr


def test_memory_limit_takes_the_control_groups_limit(tmp_path):
    """On a cluster node or in a container the job's cgroup limit, not the machine's memory,
    decides (issue 28): v2 memory.max and v1 memory.limit_in_bytes, the smallest of the group
    and its ancestors; 'max' and v1's ~2^63 mean none."""
    from kapsel.config import cgroup_memory_limit
    v2 = tmp_path / "v2"
    (v2 / "job" / "step").mkdir(parents=True)
    (v2 / "memory.max").write_text("max\n")
    (v2 / "job" / "memory.max").write_text(str(8 * 2 ** 30) + "\n")
    (v2 / "job" / "step" / "memory.max").write_text("max\n")
    pc = tmp_path / "cgroup2"
    pc.write_text("0::/job/step\n")
    assert cgroup_memory_limit(str(pc), str(v2)) == 8 * 2 ** 30
    v1 = tmp_path / "v1"
    (v1 / "memory" / "slurm" / "uid").mkdir(parents=True)
    (v1 / "memory" / "slurm" / "memory.limit_in_bytes").write_text("9223372036854771712\n")
    (v1 / "memory" / "slurm" / "uid" / "memory.limit_in_bytes").write_text(str(3 * 2 ** 30))
    pc1 = tmp_path / "cgroup1"
    pc1.write_text("5:cpu,cpuacct:/slurm/uid\n4:memory:/slurm/uid\n")
    assert cgroup_memory_limit(str(pc1), str(v1)) == 3 * 2 ** 30
    pc1.write_text("4:memory:/slurm\n")
    assert cgroup_memory_limit(str(pc1), str(v1)) == float("inf")
    assert cgroup_memory_limit(str(tmp_path / "absent"), str(v1)) == float("inf")
