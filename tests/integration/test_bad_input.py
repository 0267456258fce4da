"""Every broken input in tests/bad_inputs/ is refused by the real CLI with one clear line on
stderr (file:line:col for syntax and type errors; the UDF path and value for bad values),
a non-zero exit, no traceback, and nothing written: no output.udf, restart.udf, .h5 or .xmf.

The corpus files are the manual's sample shrunk to a 16^3 mesh, 2 particles and one step,
each with one thing broken; tests/bad_inputs/make_corpus.py regenerates them."""
import os
import shutil
import subprocess
import sys

import pytest

from kapsel import cli, models  # noqa: F401  (models register their types at import)

from builders import TESTS


HERE = TESTS
CORPUS_DIR = os.path.join(HERE, "bad_inputs")
SAMPLES = os.path.join(HERE, "..", "samples")
sys.path.insert(0, CORPUS_DIR)
import make_corpus  # noqa: E402

# file -> (what is wrong, fragments the one-line message must contain, command-line changes)
CORPUS = {
    # --- syntax: truncated, unbalanced, garbage (file:line[:col])
    "truncated_mid_value.udf": ("file ends inside the string \"12:6\" of LJ_powers",
                                ["truncated_mid_value.udf:24:11:", "end of file inside a string"]),
    "truncated_mid_number.udf": ("file ends in the middle of the number A_XI:2.00000",
                                 ["truncated_mid_number.udf:20:", "unexpected end of file"]),
    "truncated_mid_block.udf": ("file ends inside the switch:{...} block",
                                ["truncated_mid_block.udf:36:", "unexpected end of file",
                                 "not closed"]),
    "missing_end_data.udf": ("\\end{data} removed",
                             ["missing_end_data.udf:109:", "unexpected end of file"]),
    "missing_data_block.udf": ("only the header and the include: no \\begin{data} block",
                               ["missing_data_block.udf:", "no \\begin{data}"]),
    "unbalanced_brace.udf": ("an extra closing brace: mesh:{4,4,4}}",
                             ["unbalanced_brace.udf:25:13:", "unexpected '}'"]),
    "empty_file.udf": ("an empty file", ["empty_file.udf:", "is not a KAPSEL input",
                                         'include{"define.udf"}']),
    "binary_garbage.udf": ("binary bytes instead of text",
                           ["binary_garbage.udf:1:1:", "binary data"]),
    "nan_value.udf": ("A:NaN (not a UDF number)", ["nan_value.udf:21:3:", "unexpected 'NaN'"]),
    # --- wrong types
    "string_for_float.udf": ('A:"four", a string where a double goes',
                             ["string_for_float.udf:21:3:", "expected a number", '"four"',
                              "(at A)"]),
    "float_for_int_mesh.udf": ("mesh:{4,4.5,4}, a float where an int goes",
                               ["float_for_int_mesh.udf:25:9:", "expected an integer", "4.5",
                                "mesh.NPY"]),
    "float_for_int_gts.udf": ("output.GTS = 1.5",
                              ["float_for_int_gts.udf:56:9:", "expected an integer",
                               "output.GTS"]),
    "number_for_select.udf": ("LJ_powers:12, a number where a select string goes",
                              ["number_for_select.udf:24:11:", "expected one of 12:6",
                               "(at LJ_powers)"]),
    "string_for_int_particles.udf": ('Particle_number "two"',
                                     ["string_for_int_particles.udf:11:5:", '"two"',
                                      "Particle_spec[0].Particle_number"]),
    "too_few_values.udf": ("gravity:{0.0}, one of its two values missing",
                           ["too_few_values.udf:22:9:", "expected 2 values", "found 1",
                            "(at gravity)"]),
    "int_infinite.udf": ("output.GTS = 1e400 (an int that overflows to infinity)",
                         ["int_infinite.udf:56:9:", "expected an integer, found 1e400",
                          "output.GTS"]),
    "int_out_of_range.udf": ("Particle_number 99999999999, beyond a UDF (32-bit) int",
                             ["int_out_of_range.udf:11:5:", "99999999999 is out of range",
                              "Particle_number"]),
    "unknown_item.udf": ("EPSILLON:5.0, a misspelt item",
                         ["unknown_item.udf:23:1:", "'EPSILLON' is not defined",
                          "did you mean 'EPSILON'"]),
    "missing_item.udf": ("the line A:4.0 deleted (it used to read as A = 0)",
                         ["missing_item.udf:", "A:", "is missing"]),
    "duplicate_item.udf": ("A given twice (the second used to win silently)",
                           ["duplicate_item.udf:22:1:", "'A' is given twice",
                            "first at line 21"]),
    # --- unknown or unsupported select values
    "unknown_constitutive_eq.udf": ("constitutive_eq type \"Navier_Stokes_Cahn_Hilliard\"",
                                    ["unknown_constitutive_eq.udf:7:18:",
                                     "unknown choice 'Navier_Stokes_Cahn_Hilliard'",
                                     "Navier_Stokes_Cahn_Hilliard_FDM",
                                     "(at constitutive_eq.type)"]),
    "electrolyte_zero_charge.udf": ("constitutive_eq type Electrolyte with uncharged "
                                    "particles (Surface_charge 0, the original exits)",
                                    ["electrolyte_zero_charge.udf:11:24:",
                                     "Surface_charge = 0.0", "must be non-zero"]),
    "bad_lj_powers.udf": ('LJ_powers:"12:7"',
                          ["bad_lj_powers.udf:24:11:", "unknown choice '12:7'", "36:18",
                           "(at LJ_powers)"]),
    "unknown_time_increment.udf": ('time_increment type "fixed"',
                                   ["unknown_time_increment.udf:26:17:",
                                    "unknown choice 'fixed'", "auto, manual"]),
    "unknown_g_direction.udf": ('gravity G_direction "+Y"',
                                ["unknown_g_direction.udf:22:14:", "unknown choice '+Y'",
                                 "gravity.G_direction"]),
    # --- includes
    "missing_include.udf": ('\\include{"defines.udf"}, a file that does not exist',
                            ["missing_include.udf:3:10:", '"defines.udf" not found']),
    "include_not_udf.udf": ("\\include of a plain text file (notes.txt)",
                            ["notes.txt:1:1:", "is this a UDF file?",
                             "included from include_not_udf.udf:3"]),
    "include_cycle.udf": ("the file includes itself",
                          ["include_cycle.udf", "include cycle"]),
    # --- impossible meshes
    "mesh_npx_zero.udf": ("NPX = 0", ["mesh_npx_zero.udf:25:7:", "mesh.NPX = 0",
                                      "at least 1"]),
    "mesh_npy_negative.udf": ("NPY = -2", ["mesh_npy_negative.udf:25:9:", "mesh.NPY = -2",
                                           "at least 1"]),
    "mesh_npz_too_large.udf": ("NPZ = 40 (2^40 points on one side)",
                               ["mesh_npz_too_large.udf:25:11:", "mesh.NPZ = 40",
                                "too large"]),
    "mesh_memory_absurd.udf": ("mesh {12,12,11}: 2^35 points, terabytes of memory",
                               ["mesh_memory_absurd.udf:25:6:", "mesh = [12, 12, 11]",
                                "4096 x 4096 x 2048", "TB of memory", "more than"]),
    "mesh_dx_zero.udf": ("DX = 0", ["mesh_dx_zero.udf:7:1037:",
                                    "Navier_Stokes_Cahn_Hilliard_FDM.DX = 0.0", "positive"]),
    # --- fluid and solvers
    "eta_negative.udf": ("ETA = -1", ["eta_negative.udf:7:1071:",
                                      "Navier_Stokes_Cahn_Hilliard_FDM.ETA = -1.0",
                                      "positive"]),
    "rho_zero.udf": ("RHO = 0", ["rho_zero.udf:7:1054:",
                                 "Navier_Stokes_Cahn_Hilliard_FDM.RHO = 0.0", "positive"]),
    "kbt_negative.udf": ("kBT = -0.5", ["kbt_negative.udf:7:1088:",
                                        "Navier_Stokes_Cahn_Hilliard_FDM.kBT = -0.5",
                                        "zero or positive"]),
    "eta_infinite.udf": ("ETA = 1e400 (overflows to infinity)",
                         ["eta_infinite.udf:7:", "1e400 is beyond the range of a double",
                          "Navier_Stokes_Cahn_Hilliard_FDM.ETA"]),
    "tolerance_positive.udf": ("CH_solver tolerance 9 (it is a base-10 exponent)",
                               ["tolerance_positive.udf:7:1013:",
                                "CH_solver.implicit_scheme.tolerance = 9.0",
                                "base-10 exponent", "negative"]),
    "tolerance_unreachable.udf": ("CH_solver tolerance exponent -300 (10^-300: never reached)",
                                  ["tolerance_unreachable.udf:7:1013:", "tolerance = -300.0",
                                   "below -15"]),
    "dx_huge_auto_dt_zero.udf": ("DX = 1e300: the automatic dt underflows to 0",
                                 ["dx_huge_auto_dt_zero.udf:26:25:", "DX = 1e+300",
                                  "not a finite positive time step"]),
    "maximum_iteration_zero.udf": ("CH_solver maximum_iteration 0",
                                   ["maximum_iteration_zero.udf:7:1031:",
                                    "implicit_scheme.maximum_iteration = 0", "at least 1"]),
    # --- time and output
    "factor_negative.udf": ("time_increment auto factor -1",
                            ["factor_negative.udf:26:25:", "time_increment.auto.factor = -1.0",
                             "positive"]),
    "delta_t_zero.udf": ("time_increment manual delta_t 0",
                         ["delta_t_zero.udf:26:45:", "time_increment.manual.delta_t = 0.0",
                          "positive"]),
    "delta_t_unstable.udf": ("manual delta_t 100, far past the explicit scheme's limit",
                             ["delta_t_unstable.udf:26:1:", "time_increment = 100.0",
                              "stability limit"]),
    "gts_zero.udf": ("GTS = 0", ["gts_zero.udf:56:9:", "output.GTS = 0", "at least 1"]),
    "num_snap_negative.udf": ("Num_snap = -3", ["num_snap_negative.udf:56:11:",
                                                "output.Num_snap = -3", "at least 1"]),
    "num_snap_zero.udf": ("Num_snap = 0 (a run of no steps)",
                          ["num_snap_zero.udf:56:11:", "output.Num_snap = 0", "at least 1"]),
    # --- particles
    "a_zero.udf": ("A = 0", ["a_zero.udf:21:3:", "A = 0.0", "positive"]),
    "a_xi_negative.udf": ("A_XI = -2", ["a_xi_negative.udf:20:6:", "A_XI = -2.0",
                                        "positive"]),
    "mass_ratio_zero.udf": ("MASS_RATIO = 0", ["mass_ratio_zero.udf:11:7:",
                                               "Particle_spec[0].MASS_RATIO = 0.0",
                                               "positive"]),
    "particle_number_negative.udf": ("Particle_number = -1",
                                     ["particle_number_negative.udf:11:5:",
                                      "Particle_spec[0].Particle_number = -1"]),
    "particle_larger_than_box.udf": ("A = 9 in a 16^3 box",
                                     ["particle_larger_than_box.udf:21:3:", "A = 9.0",
                                      "does not fit in the box 16 x 16 x 16"]),
    "too_many_particles.udf": ("200 particles of radius 4 in a 16^3 box",
                               ["too_many_particles.udf:8:13:", "200 particles",
                                "cannot fit"]),
    "user_specify_missing_data.udf": ("INIT_distribution user_specify with no entries for 2 "
                                      "particles",
                                      ["user_specify_missing_data.udf:34:4:",
                                       "user_specify.Particles[] = 0",
                                       "one entry per particle"]),
    "user_specify_too_few.udf": ("user_specify with 1 entry for 2 particles",
                                 ["user_specify_too_few.udf:34:4:",
                                  "user_specify.Particles[] = 1", "one entry per particle"]),
    "user_specify_overlap.udf": ("user_specify particles 1 apart with A = 4 (it used to "
                                 "write the first snapshot, then stop)",
                                 ["user_specify_overlap.udf:34:4:", "particles 0 and 1",
                                  "they overlap"]),
    "pin_without_particles.udf": ("Particle_number 0 but switch.pin YES pins particle 2",
                                  ["pin_without_particles.udf:44:4:",
                                   "switch.pin.YES.pin[] = [2]", "has none"]),
    "pin_id_out_of_range.udf": ("pin of particle 5 with 2 particles",
                                ["pin_id_out_of_range.udf:44:4:", "switch.pin.YES.pin[] = [5]",
                                 "0..1"]),
    "random_walk_negative.udf": ("INIT_distribution random_walk with iteration -100",
                                 ["random_walk_negative.udf:32:4:",
                                  "random_walk.iteration = -100"]),
    # --- several problems at once: one line each, at the value itself
    "several_problems.udf": ("mesh NPX 0, A 0 and GTS 0 in one file: all three reported",
                             ["several_problems.udf:25:7: mesh.NPX = 0",
                              "several_problems.udf:21:3: A = 0.0",
                              "several_problems.udf:56:9: output.GTS = 0"]),
    "unsupported_together.udf": ("TUMBLER janus particles in an Electrolyte run with "
                                 "uncharged particles: every problem at once, one line each "
                                 "(self-propelled particles need Navier_Stokes or "
                                 "Shear_Navier_Stokes, as in the original)",
                                 ["unsupported_together.udf:11:24:", "Surface_charge = 0.0",
                                  "unsupported_together.udf:11:35:",
                                  "janus_propulsion = 'TUMBLER'",
                                  "need constitutive_eq Navier_Stokes or Shear_Navier_Stokes"]),
    # --- resume
    "continue_without_saved_data.udf": ("resume CONTINUE_FDM_PHASE_SEPARATION in a fresh "
                                        "input (no saved data)",
                                        ["continue_without_saved_data.udf:57:1:",
                                         "resume.CONTINUE_FDM_PHASE_SEPARATION",
                                         "holds no saved state", "NEW"]),
    # --- command line: a valid input, bad flags
    "cli_define_missing.udf": ("-D names a file that does not exist",
                               ["-Dnosuch_define.udf", "no such file"],
                               ["-Dnosuch_define.udf"]),
    "cli_define_not_a_schema.udf": ("-D names a UDF without the KAPSEL schema "
                                    "(it used to write output.udf, then crash)",
                                    ["-Dkapsel_unit.udf", "not a KAPSEL define file",
                                     "lack E, t"], ["-Dkapsel_unit.udf"]),
    "cli_output_dir_missing.udf": ("-O in a directory that does not exist",
                                   ["-Onodir/output.udf", "nodir does not exist"],
                                   ["-Onodir/output.udf"]),
    "cli_output_dir_is_a_file.udf": ("-O below a plain file (not a directory)",
                                     ["-Onotes.txt/output.udf", "is not a directory"],
                                     ["-Onotes.txt/output.udf"]),
    "cli_restart_dir_missing.udf": ("-R in a directory that does not exist (it used to "
                                    "write output.udf and the fields, then crash)",
                                    ["-Rnodir/restart.udf", "nodir does not exist"],
                                    ["-Rnodir/restart.udf"]),
}

# files with several independent problems: one line each (all others: one line)
LINES = {"several_problems.udf": 3, "unsupported_together.udf": 2}

FLAGS = ["-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf"]


def setup_dir(d, name):
    """A run directory: the corpus file, the sample's schema files and notes.txt."""
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(SAMPLES, f), d / f)
    for f in make_corpus.SUPPORT:
        shutil.copy(os.path.join(CORPUS_DIR, f), d / f)
    shutil.copy(os.path.join(CORPUS_DIR, name), d / name)


def command_line(name):
    entry = CORPUS[name]
    flags = list(FLAGS)
    for arg in (entry[2] if len(entry) > 2 else []):
        flags = [f for f in flags if f[:2] != arg[:2]] + [arg]
    return [f"-I{name}"] + flags


def listing(d):
    return sorted(os.path.relpath(os.path.join(root, f), d)
                  for root, dirs, files in os.walk(d) for f in files + dirs)


def test_the_corpus_is_complete_and_current(tmp_path):
    files = sorted(f for f in os.listdir(CORPUS_DIR) if f.endswith(".udf"))
    assert files == sorted(CORPUS), set(files) ^ set(CORPUS)
    assert len(files) >= 30
    make_corpus.write_all(str(tmp_path))   # the committed files are what the script makes
    for f in files + list(make_corpus.SUPPORT):
        with open(os.path.join(CORPUS_DIR, f), "rb") as a, open(tmp_path / f, "rb") as b:
            assert a.read() == b.read(), f


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_bad_input_is_refused_cleanly(name, tmp_path, monkeypatch, capsys):
    setup_dir(tmp_path, name)
    before = listing(tmp_path)
    monkeypatch.chdir(tmp_path)
    code = cli.main(command_line(name))    # no --seed, no --quiet: as a user runs it
    out, err = capsys.readouterr()
    assert code == cli.EXIT_BAD_INPUT, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == LINES.get(name, 1), err
    assert all(line.startswith("kapsel-py: error: ") for line in lines), err
    for fragment in CORPUS[name][1]:
        assert any(fragment in line for line in lines), (fragment, lines)
    assert "Traceback" not in err and out == ""
    assert listing(tmp_path) == before      # nothing written


@pytest.mark.parametrize("name", ["mesh_memory_absurd.udf", "cli_restart_dir_missing.udf"])
def test_bad_input_through_the_console_command(name, tmp_path):
    setup_dir(tmp_path, name)
    before = listing(tmp_path)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.join(HERE, "..")] + sys.path))
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", *command_line(name)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""
    for fragment in CORPUS[name][1]:
        assert fragment in r.stderr
    assert listing(tmp_path) == before


def run_ok(tmp_path, text, monkeypatch):
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(SAMPLES, f), tmp_path / f)
    (tmp_path / "input.udf").write_text(text)
    monkeypatch.chdir(tmp_path)
    return cli.main(["-Iinput.udf", *FLAGS, "--seed", "1", "--quiet"])


def test_the_corpus_base_runs(tmp_path, monkeypatch):
    """The input every corpus file is derived from is good: each refusal is its defect's."""
    assert run_ok(tmp_path, make_corpus.tiny_sample(), monkeypatch) == 0
    assert (tmp_path / "output.udf").exists() and (tmp_path / "restart.udf").exists()


def test_zero_particles_need_no_particle_data(tmp_path, monkeypatch):
    """What a KAPSEL user expects: Particle_number 0 is a particle-free run, so options that
    only concern particles (user_specify positions, janus settings) need no data; only
    options that name particles (switch.pin) are refused (pin_without_particles.udf)."""
    text = make_corpus.user_specify([])(make_corpus.tiny_sample())
    text = text.replace(make_corpus.SPEC, make_corpus.SPEC.replace("{2,", "{0,"), 1)
    assert run_ok(tmp_path, text, monkeypatch) == 0


def test_memory_budget_can_be_lowered(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("KAPSEL_PY_MEMORY_LIMIT_GB", "0.001")
    assert run_ok(tmp_path, make_corpus.tiny_sample(), monkeypatch) == 2
    err = capsys.readouterr().err
    assert "16 x 16 x 16 mesh needs about" in err and "KAPSEL_PY_MEMORY_LIMIT_GB" in err
    assert not (tmp_path / "output.udf").exists()
    monkeypatch.setenv("KAPSEL_PY_MEMORY_LIMIT_GB", "lots")
    assert run_ok(tmp_path, make_corpus.tiny_sample(), monkeypatch) == 2
    assert "KAPSEL_PY_MEMORY_LIMIT_GB = 'lots'" in capsys.readouterr().err
