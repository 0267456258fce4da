"""bench/work_precision.py cannot rot: its --quick mode on the Taylor-Green test (all four
fluid schemes, 16^3, ~2 s) prints the table, writes the CSV and the PNG, and the errors are
those of a converging solver (spectral exact for this flow, MAC second order in space)."""
import csv
import os
import subprocess
import sys

import pytest

from builders import TESTS


ROOT = os.path.dirname(TESTS)


def test_work_precision_quick_taylor_green(tmp_path):
    pytest.importorskip("matplotlib")
    r = subprocess.run([sys.executable, os.path.join(ROOT, "bench", "work_precision.py"),
                        "--quick", "--only", "taylor_green", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "cheapest setting reaching" in r.stdout
    with open(tmp_path / "work_precision.csv") as fh:
        rows = list(csv.DictReader(fh))
    schemes = {row["scheme"]: row for row in rows}
    assert set(schemes) == {"spectral etd1", "spectral etd2", "MAC explicit", "MAC implicit"}
    err = {k: abs(float(v["relative_error"])) for k, v in schemes.items()}
    assert err["spectral etd1"] < 1e-8 and err["spectral etd2"] < 1e-8
    assert 1e-4 < err["MAC explicit"] < 1e-2 and 1e-4 < err["MAC implicit"] < 1e-2
    assert all(float(v["cpu_s"]) > 0 for v in rows)
    png = tmp_path / "work_precision_taylor_green.png"
    assert png.stat().st_size < 100_000
    with open(png, "rb") as fh:
        assert fh.read(8) == b"\x89PNG\r\n\x1a\n"
