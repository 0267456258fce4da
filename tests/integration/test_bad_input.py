"""Every broken input in tests/bad_inputs/ is refused by the real CLI with one clear line on
stderr (file:line:col for syntax and type errors; the UDF path and value for bad values),
a non-zero exit, no traceback, and nothing written: no output.udf, restart.udf, .h5 or .xmf.

The corpus files are the manual's sample shrunk to a 16^3 mesh, 2 particles and one step,
each with one thing broken; tests/bad_inputs/make_corpus.py regenerates them."""
import os
import subprocess
import sys

import pytest

from kapsel import cli, models  # noqa: F401  (models register their types at import)

from builders import (bad_input_command, bad_input_dir, copy_schema, CORPUS, CORPUS_DIR,
                      CORPUS_FLAGS, TESTS)


HERE = TESTS
SAMPLES = os.path.join(HERE, "..", "samples")
sys.path.insert(0, CORPUS_DIR)     # make_corpus
import make_corpus  # noqa: E402


# files with several independent problems: one line each (all others: one line)
LINES = {"several_problems.udf": 3, "unsupported_together.udf": 2}


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
    bad_input_dir(tmp_path, name)
    before = listing(tmp_path)
    monkeypatch.chdir(tmp_path)
    code = cli.main(bad_input_command(name))    # no --seed, no --quiet: as a user runs it
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
    bad_input_dir(tmp_path, name)
    before = listing(tmp_path)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.join(HERE, "..")] + sys.path))
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", *bad_input_command(name)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""
    for fragment in CORPUS[name][1]:
        assert fragment in r.stderr
    assert listing(tmp_path) == before


def run_ok(tmp_path, text, monkeypatch):
    copy_schema(tmp_path)
    (tmp_path / "input.udf").write_text(text)
    monkeypatch.chdir(tmp_path)
    return cli.main(["-Iinput.udf", *CORPUS_FLAGS, "--seed", "1", "--quiet"])


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
