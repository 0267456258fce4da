"""The package: ``python -m kapsel``, the shipped sample and ``kapsel-py example``."""
import filecmp
import subprocess
import sys
from pathlib import Path

from kapsel.cli import main
from kapsel.examples import HERE, files

from builders import TESTS


ROOT = Path(TESTS).resolve().parent


def test_python_m_kapsel_is_the_command():
    r = subprocess.run([sys.executable, "-m", "kapsel", "--version"], capture_output=True,
                       text=True, cwd=ROOT)
    assert r.returncode == 0
    assert r.stdout.startswith("kapsel-py ")


def test_shipped_sample_is_the_repository_sample():
    names = [f.name for f in files("sample")]
    assert names == ["define.udf", "input.udf", "kapsel_unit.udf", "pv_sample.pvsm"]
    for n in names:
        assert filecmp.cmp(HERE / "sample" / n, ROOT / "samples" / n, shallow=False), n


def test_example_copies_and_refuses_to_overwrite(tmp_path, capsys):
    d = tmp_path / "run"
    assert main(["example", "sample", str(d)]) == 0
    assert (d / "input.udf").read_bytes() == (ROOT / "samples" / "input.udf").read_bytes()
    (d / "input.udf").write_text("mine")
    assert main(["example", "sample", str(d)]) == 2
    assert "already has" in capsys.readouterr().err
    assert (d / "input.udf").read_text() == "mine"
    assert main(["example", "sample", str(d), "--overwrite"]) == 0
    assert (d / "input.udf").read_bytes() == (ROOT / "samples" / "input.udf").read_bytes()
    assert main(["example", "nosuch", str(d)]) == 2
    assert main(["example", "--list"]) == 0
    assert "sample" in capsys.readouterr().out
