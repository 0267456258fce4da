"""kapsel.particles.interactions: the particles' forces as a list of force objects; adding
one is its class and a line in FORCES (issue 27), shown here by a force this test adds."""
import os

import numpy as np
import pytest

from kapsel.particles import interactions

from builders import sample_input


class Push:
    """A constant force on every bead along x (a test's own force object)."""

    local = True
    cutoff = 0.0

    def __init__(self, f):
        self.f = f

    def compute(self, p, gid=None, weight=None, reduce=None):
        F = np.zeros((p.n, 3))
        F[:, 0] = self.f
        return F, None, np.inf, 0.0


def _run(d, monkeypatch, push):
    from kapsel import Simulation
    u = sample_input(d, "Navier_Stokes", 4)
    u.put(1, "object_type.spherical_particle.Particle_spec[0].Particle_number")
    u.put(2.0, "A")
    u.put(1.0, "A_XI")
    u.put(0.0, "constitutive_eq.Navier_Stokes.kBT")
    u.put(0.0, "gravity.G")
    u.write(os.path.join(d, "input.udf"))
    if push:
        monkeypatch.setattr(interactions, "FORCES", interactions.FORCES +
                            [lambda cfg, particles, strain, wall, virial: Push(1e-3)])
    sim = Simulation.from_udf(*(os.path.join(d, f) for f in
                                ("input.udf", "output.udf", "define.udf", "restart.udf")),
                              seed=1, overrides={"output.GTS": 5, "output.Num_snap": 2})
    sim.run()
    return sim.particles.v


def test_a_new_force_is_one_class_and_one_line(tmp_path, monkeypatch):
    """With no interaction the particle stays at rest; the added force pushes it along x
    only (and nothing else of the run changes: same path for every type)."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    rest = _run(str(tmp_path / "a"), monkeypatch, push=False)
    pushed = _run(str(tmp_path / "b"), monkeypatch, push=True)
    assert np.abs(rest).max() == 0.0
    assert pushed[0, 0] > 0 and np.abs(pushed[0, 1:]).max() < 0.02 * pushed[0, 0]


def test_the_sum_keeps_the_order_of_the_list():
    """Interactions adds the forces in FORCES's order (the order fixes the round-off) and
    takes the torques of the force that gives them."""
    class P:
        n = 2
        R = np.zeros((2, 3))

    class T(Push):
        def compute(self, p, gid=None, weight=None, reduce=None):
            return None, np.ones((p.n, 3)), 0.5, 0.0
    acc = interactions.Interactions([Push(1.0), T(0.0), Push(2.0)], 2, np.zeros((3, 3)))
    F, torque = acc(P())
    _, _, ratio, _ = acc.local(P(), np.ones(2), None)
    assert np.array_equal(F[:, 0], [3.0, 3.0]) and np.array_equal(torque, np.ones((2, 3)))
    assert ratio == 0.5 and acc.local is not None


def test_the_overlap_check_is_the_interactions_own():
    """With an overlap limit the sum stops a run whose closest pair is nearer than it (the
    same check a distributed run makes on the minimum over the ranks); without, it does not;
    a plain function becomes a Callback with no reach and no virial."""
    class P:
        n = 2
        R = np.zeros((2, 3))

    class Close(Push):
        def compute(self, p, gid=None, weight=None, reduce=None):
            return None, None, 0.4, 0.0
    interactions.Interactions([Close(0.0)], 2, np.zeros((3, 3)))(P())
    with pytest.raises(FloatingPointError, match="overlap deeply"):
        interactions.Interactions([Close(0.0)], 2, np.zeros((3, 3)),
                                  interactions.OVERLAP_LIMIT)(P())
    cb = interactions.as_forces(lambda p: (np.ones((p.n, 3)), None, "extra"))
    assert isinstance(cb, interactions.Callback) and interactions.as_forces(cb) is cb
    assert cb.cutoff == 0.0 and cb.virial is None and cb.local is None
    F, T = cb(P())
    assert np.array_equal(F, np.ones((2, 3))) and T is None
