"""The analyze cna / erotate commands on kapsel output.udf files."""
import os

import numpy as np

from kapsel.analysis.cli import main as analyze
from udf import UDFManager

from builders import TESTS


SAMPLES = os.path.join(TESTS, "..", "samples")


def fcc_output(path, n=4, a=8.0):
    inp = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u = UDFManager(schema_from=os.path.join(SAMPLES, "define.udf"))
    u.common.update(inp.common)
    base = np.array([[0, 0, 0], [.5, .5, 0], [.5, 0, .5], [0, .5, .5]])
    pts = np.array([(np.array([i, j, k]) + b) * a for i in range(n) for j in range(n)
                    for k in range(n) for b in base])
    u.newRecord()
    P = np.zeros((len(pts), 34))
    P[:, :3] = pts
    P[:, 3:6] = pts
    u.put(P, "Particles[]")
    u.write(str(path))
    return len(pts)


def test_cna_on_output_udf(tmp_path, capsys):
    n = fcc_output(tmp_path / "o.udf")
    assert analyze(["cna", str(tmp_path / "o.udf"), "--labels", str(tmp_path / "l.csv")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].split()[2] == str(n)  # all FCC
    lines = (tmp_path / "l.csv").read_text().splitlines()
    assert len(lines) == n + 1 and lines[1].endswith("FCC")


def test_cna_bad_file(tmp_path, capsys):
    (tmp_path / "x.xyz").write_text("3\ncomment\nC 0 0 zero\n")
    assert analyze(["cna", str(tmp_path / "x.xyz"), "--cutoff", "1"]) == 2
    assert "error" in capsys.readouterr().err


def test_erotate_needs_rigid_bodies(tmp_path, capsys):
    fcc_output(tmp_path / "o.udf")
    assert analyze(["erotate", str(tmp_path / "o.udf")]) == 2
    assert "rigid" in capsys.readouterr().err


def test_erotate_two_bodies(tmp_path, capsys):
    inp = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u = UDFManager(schema_from=os.path.join(SAMPLES, "define.udf"))
    u.common.update(inp.common)
    u.put("rigid", "object_type.type")
    u.put([[2, 2, 1.0, 0.0, "free", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]],
          "object_type.rigid.Rigid_spec[]")
    u.newRecord()
    u.put(0.0, "t")                      # every output.udf record has its t
    P = np.zeros((4, 34))
    P[:, 3:6] = [[0, 0, 0], [2, 0, 0], [10, 10, 10], [10, 12, 10]]  # R_raw
    u.put(P, "Particles[]")
    Rb = np.zeros((2, 34))
    Rb[:, 13:16] = [[0, 0, 1.0], [0, 0, 2.0]]  # omega (after R, R_raw, v, q)
    u.put(Rb, "RigidParticles[]")
    u.write(str(tmp_path / "r.udf"))
    assert analyze(["erotate", str(tmp_path / "r.udf")]) == 0
    line = capsys.readouterr().out.splitlines()[1].split()
    m = 4 / 3 * np.pi * 4.0 ** 3
    # each dumbbell: two beads at distance 1 from the centre, about z: I = 2 m
    # E = 1/2 I w^2 = 1/2 (2 m) 1 + 1/2 (2 m) 4 = 5 m
    assert abs(float(line[2]) - 5 * m) / (5 * m) < 1e-5
