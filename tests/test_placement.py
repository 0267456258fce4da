"""Initial placements (table 7 INIT_distribution / INIT_orientation)."""
import numpy as np
import pytest

from kapsel.particles import placement as P
from kapsel.particles import quaternion as Q

BOX = np.array([40.0, 32.0, 48.0])


def _check(R, radius, box, n):
    assert R.shape == (n, 3)
    assert np.all(R >= 0) and np.all(R < box)
    assert len(P.overlapping_pairs(R, radius, box)[0]) == 0


@pytest.mark.parametrize("seed", [0, 1])
def test_uniform_random(seed):
    rng = np.random.default_rng(100 + seed)
    radius = rng.uniform(1.5, 3.5, 250)
    R = P.uniform_random(250, radius, BOX, seed)
    assert 0.3 < P.volume_fraction(radius, BOX) < 0.35   # polydisperse, placed largest first
    _check(R, radius, BOX, 250)
    assert np.array_equal(R, P.uniform_random(250, radius, BOX, seed))
    assert not np.array_equal(R, P.uniform_random(250, radius, BOX, seed + 7))


def test_uniform_random_dense_but_possible():
    # volume fraction ~0.3 (below random sequential jamming ~0.38)
    n, a = 110, 2.5
    box = np.array([32.0, 32.0, 24.0])
    assert 0.28 < P.volume_fraction(a, box, n) < 0.33
    _check(P.uniform_random(n, a, box, 3), np.full(n, a), box, n)


def test_uniform_random_impossible():
    box = np.array([20.0, 20.0, 20.0])
    with pytest.raises(ValueError, match="volume fraction 0.49"):   # phi ~ 0.49, RSA jams
        P.uniform_random(60, 2.5, box, 1, max_rounds=30)
    with pytest.raises(ValueError, match="close packing"):
        P.uniform_random(200, 2.5, box, 1)
    with pytest.raises(ValueError, match="larger than the box"):
        P.uniform_random(1, 11.0, box, 1)


def test_random_walk():
    radius = np.full(100, 2.0)
    R = P.random_walk(100, radius, BOX, 30, rng=5)
    _check(R, radius, BOX, 100)
    assert np.array_equal(R, P.random_walk(100, radius, BOX, 30, rng=5))
    R0 = P.random_walk(100, radius, BOX, 0, rng=5)
    _check(R0, radius, BOX, 100)
    assert np.abs(R - R0).max() > 1.0            # particles actually moved
    # dense: moves mostly rejected but never overlapping
    box = np.array([16.0, 16.0, 16.0])
    Rd = P.random_walk(64, 1.9, box, 20, rng=1)
    _check(Rd, np.full(64, 1.9), box, 64)


@pytest.mark.parametrize("kind,per_cell", [("FCC", 4), ("BCC", 2)])
def test_lattices(kind, per_cell):
    box = np.array([32.0, 32.0, 32.0])
    n = 100
    R = P.lattice(kind, n, 2.0, box)
    _check(R, np.full(n, 2.0), box, n)
    m = int(np.ceil((n / per_cell) ** (1 / 3) - 1e-9))
    # sites lie on the scaled lattice: coordinates are multiples of a quarter cell
    frac = R / (box / m) * 4
    assert np.allclose(frac, np.round(frac))
    full = (P.fcc if kind == "FCC" else P.bcc)(per_cell * 27, 1.0, box)
    assert len(np.unique(np.round(full, 9), axis=0)) == per_cell * 27
    with pytest.raises(ValueError, match=kind):
        P.lattice(kind, n, 4.0, box)


def test_orientations():
    rng = np.random.default_rng(0)
    q = P.orientations("random", 20000, rng)
    assert np.allclose(np.linalg.norm(q, axis=1), 1)
    # uniform rotations: rotated z axis uniform on the sphere (mean ~0, <z^2> = 1/3)
    z = Q.rotate(q, np.array([0, 0, 1.0]))
    assert np.abs(z.mean(axis=0)).max() < 0.03
    assert abs((z[:, 2] ** 2).mean() - 1 / 3) < 0.01
    assert np.array_equal(P.orientations("space_align", 3), Q.identity(3))
    assert np.array_equal(P.orientations("user_specify", 3), Q.identity(3))
    u = P.orientations("user_specify", 2, user_q=[[0, 0, 0, 0], [2, 0, 0, 2]])
    assert np.allclose(u, [[1, 0, 0, 0], [np.sqrt(0.5), 0, 0, np.sqrt(0.5)]])
    with pytest.raises(ValueError):
        P.orientations("sideways", 2)
