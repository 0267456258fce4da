"""S(q): a single mode peaks at its wavenumber; Parseval holds over the shells; the
analyze sq command reads orderparam_<n>.h5 snapshots and writes a table."""
import os

import h5py
import numpy as np
import pytest

from kapsel.analysis.cli import main as analyze
from kapsel.analysis.structure_factor import characteristic_wavenumber, structure_factor


def test_single_mode_and_parseval():
    n = 32
    x = np.arange(n)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    psi = 0.3 + np.cos(2 * np.pi * 4 * X / n) + 0.5 * np.sin(2 * np.pi * 3 * Z / n)
    q, s, counts = structure_factor(psi)
    dq = 2 * np.pi / n
    top = q[np.argsort(s)[-2:]]
    assert sorted(np.rint(top / dq).astype(int)) == [3, 4]
    # Parseval: sum over all modes of |psi_k|^2 / N equals sum of (psi - mean)^2
    assert (s * counts).sum() == pytest.approx(((psi - psi.mean()) ** 2).sum(), rel=1e-12)
    q1 = characteristic_wavenumber(q, s)
    assert 3 * dq < q1 < 4 * dq


def test_analyze_sq_command(tmp_path, capsys):
    n = 16
    x = np.arange(n)
    X = np.meshgrid(x, x, x, indexing="ij")[0]
    for k, mode in enumerate((2, 4)):
        psi = np.cos(2 * np.pi * mode * X / n)
        with h5py.File(tmp_path / f"orderparam_{k}.h5", "w") as f:
            f["PSI"] = np.ascontiguousarray(psi.T)
    assert analyze(["sq", str(tmp_path), "--plot", str(tmp_path / "sq.png")]) == 0
    table = (tmp_path / "sq.txt").read_text().splitlines()
    q1 = [float(l.split()[2]) for l in table[1:3]]
    assert q1 == pytest.approx([2 * 2 * np.pi / n, 4 * 2 * np.pi / n], rel=1e-5)


def test_analyze_sq_without_files(tmp_path):
    assert analyze(["sq", str(tmp_path)]) == 2
