"""Adding an output quantity is one factory line in kapsel.io.writers.WRITERS (issue 27): a
table of the particles' mean speed per snapshot, registered by one line, is written next to
output.udf with one row per record, equal to what the records say."""
import os

import numpy as np

from kapsel.io import writers
from udf import UDFManager

from builders import sample_input


def _mean_speed_table(c):
    """The example's factory: mean |v| of the particles, in mean_speed.dat."""
    if not c.snap.n_particles:
        return None
    return writers.TableWriter(os.path.join(c.out_dir, "mean_speed.dat"), ["mean_speed"],
                               lambda snap: [np.linalg.norm(snap.particles.v, axis=1).mean()])


def test_a_new_output_quantity_is_one_factory_line(tmp_path, monkeypatch):
    from kapsel import Simulation
    d = str(tmp_path)
    u = sample_input(d, "Navier_Stokes", 4)
    u.put(2, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.write(os.path.join(d, "input.udf"))
    monkeypatch.setattr(writers, "WRITERS", writers.WRITERS + [_mean_speed_table])
    Simulation.from_udf(*(os.path.join(d, f) for f in
                          ("input.udf", "output.udf", "define.udf", "restart.udf")),
                        seed=1, overrides={"output.GTS": 2, "output.Num_snap": 3}).run()
    rows = np.loadtxt(os.path.join(d, "mean_speed.dat"), ndmin=2)
    doc = UDFManager(os.path.join(d, "output.udf"))
    speeds = []
    for n in range(doc.totalRecord()):
        doc.jump(n)
        speeds.append(np.linalg.norm(np.array(doc.getArray("Particles[].v")), axis=1).mean())
    assert rows.shape == (len(speeds), 3) and len(speeds) == 4
    assert np.array_equal(rows[:, 0], [0, 2, 4, 6])
    assert max(speeds) > 0
    np.testing.assert_allclose(rows[:, 2], speeds, rtol=1e-6, atol=1e-12)
