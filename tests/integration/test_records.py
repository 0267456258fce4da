"""output.udf records: common part from the input, one appended record per snapshot."""
import os

import numpy as np

from kapsel.io.records import OutputUDF
from kapsel.particles.state import ParticleState
from kapsel.progress import Progress
from udf import UDFManager

from builders import TESTS


SAMPLES = os.path.join(TESTS, "..", "samples")


def test_records_round_trip(tmp_path):
    inp = UDFManager(os.path.join(SAMPLES, "input.udf"))
    path = str(tmp_path / "output.udf")
    out = OutputUDF(path, os.path.join(SAMPLES, "define.udf"), inp)
    p = ParticleState.spheres([0, 0, 0], [4.0] * 3, [1.0] * 3, 1.0)
    rng = np.random.default_rng(0)
    for k in range(3):
        p.R[:] = rng.uniform(0, 32, (3, 3))
        p.R_raw[:] = p.R + 32 * k
        p.v[:] = rng.standard_normal((3, 3))
        p.torque_slip[:] = k
        out.add_record(step=100 * k, time=0.5 * k, energy=1.5 * k, particles=p)
    u = UDFManager(path)
    assert u.totalRecord() == 3
    assert u.get("mesh.NPX") == 5 and u.get("constitutive_eq.type") == inp.get(
        "constitutive_eq.type")
    u.jump(2)
    assert u.get("t") == 200.0 and u.get("E") == 3.0   # t is the step, as the original writes it
    assert np.allclose(u.getArray("Particles[].R"), p.R, rtol=1e-6)
    assert np.allclose(u.getArray("Particles[].R_raw"), p.R_raw, rtol=1e-6)
    assert np.allclose(u.getArray("Particles[].v"), p.v, rtol=1e-6)
    assert u.get("Particles[1].q") == [1.0, 0.0, 0.0, 0.0]
    assert u.get("Particles[0].torque_slip") == [2.0, 2.0, 2.0]


def test_summary_format():
    """The original's closing lines (FORMAT-OUTPUT.md §1.6)."""
    pr = Progress(10, quiet=True)
    for s in range(10):
        pr.step(s, 0.1 * s)
    lines = pr.summary("output.udf", "restart.udf").splitlines()
    assert lines[:3] == ["#output.udf end.", "#restart.udf end.", "#Simulation has ended!"]
    assert lines[3].startswith("#Total Running Time (s): ")
    assert lines[4].startswith("#                   (m): ")
    assert lines[6].startswith("#Average Step Time  (s): ")
    assert lines[7].startswith("#                   (m): ")
    assert len(lines) == 9
