"""`make run` installs what a run needs (+ matplotlib for the picture) and nothing else;
`make test` installs the test tools; pip's output goes to a log (dry runs of make)."""
import os
import re
import shutil
import subprocess
import sys

import pytest

from builders import TESTS


ROOT = os.path.dirname(TESTS)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    tomllib = pytest.importorskip("tomli")


def dry_run(target, tmp_path):
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    venv = tmp_path / "venv"      # a venv that does not exist: every install step is listed
    r = subprocess.run(["make", "-n", "--no-print-directory", "-C", ROOT, target, f"VENV={venv}"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout


def pyproject():
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as fh:
        return tomllib.load(fh)["project"]


def names(reqs):
    return {re.split(r"[<>=!~\[ ]", r, maxsplit=1)[0].lower() for r in reqs}


def test_run_installs_the_run_and_the_picture_only(tmp_path):
    out = dry_run("run", tmp_path)
    installs = re.findall(r"pip install -e '\.\[(\w+)\]'", out)
    assert installs == ["plot"]
    extras = pyproject()["optional-dependencies"]
    assert names(extras["plot"]) == {"matplotlib"}
    assert not names(pyproject()["dependencies"]) & {"matplotlib", "vtk", "ovito", "pytest",
                                                      "hypothesis"}
    # one line saying what is installed; pip's output into a log, shown on failure only
    assert re.search(r"echo \"Installing into .*matplotlib", out)
    assert re.search(r"pip install -e '\.\[plot\]' >> \S+pip-plot\.log 2>&1", out)
    assert "tail -n 40" in out
    # the run is timed and ends with the picture of the last snapshot
    assert "Sample run took" in out
    assert out.rstrip().splitlines()[-1].endswith("kapsel-py analyze show samples")


def test_test_target_installs_the_test_extra(tmp_path):
    out = dry_run("test", tmp_path)
    assert re.findall(r"pip install -e '\.\[(\w+)\]'", out) == ["test"]
    test = names(pyproject()["optional-dependencies"]["test"])
    assert {"pytest", "hypothesis", "vtk", "ovito", "matplotlib"} <= test
