"""Rigid-body rotational energy (spec 002): eqs 2-3 and 5-7 against the bead sum of eq 1,
rotation invariance, spherical bodies (eq 6), quaternion <-> matrix round trips."""
import numpy as np
import pytest

from kapsel.analysis.rotational_energy import (body_inertia_tensors, inertia_tensor,
                                               matrix_to_quaternion, principal_frame,
                                               quaternion_to_matrix, rotational_energies,
                                               rotational_energy, rotational_energy_body,
                                               rotational_energy_sphere,
                                               total_rotational_energy)


def bead_energy(omega, masses, positions):
    """Eq 1 directly: 1/2 sum_k m_k |omega x r_k|^2, r_k about the centre of mass."""
    com = (masses[:, None] * positions).sum(0) / masses.sum()
    v = np.cross(omega, positions - com)
    return 0.5 * (masses * (v * v).sum(1)).sum()


def random_rotation(rng):
    q = rng.normal(size=4)
    return quaternion_to_matrix(q / np.linalg.norm(q))


def random_body(rng, n=None):
    n = n or int(rng.integers(2, 12))
    return rng.uniform(0.5, 3.0, n), rng.normal(size=(n, 3)) * rng.uniform(0.3, 2.0, 3) + 5.0


def test_energy_equals_bead_sum():
    rng = np.random.default_rng(0)
    for _ in range(50):
        m, x = random_body(rng)
        w = rng.normal(size=3)
        ref = bead_energy(w, m, x)
        assert rotational_energy(w, m, x) == pytest.approx(ref, rel=1e-12)     # eq 3
        I, com = inertia_tensor(m, x)
        assert np.allclose(com, (m[:, None] * x).sum(0) / m.sum(), rtol=1e-14)
        moments, R = principal_frame(I)                                         # eq 4
        assert np.allclose(R @ np.diag(moments) @ R.T, I, rtol=0, atol=1e-12 * abs(I).max())
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
        assert rotational_energy_body(w, moments, R) == pytest.approx(ref, rel=1e-12)  # eq 5
        q = matrix_to_quaternion(R)
        assert rotational_energy_body(w, moments, q) == pytest.approx(ref, rel=1e-12)


def test_rotating_body_and_omega_together_leaves_energy():
    rng = np.random.default_rng(1)
    for _ in range(20):
        m, x = random_body(rng)
        w = rng.normal(size=3)
        Q = random_rotation(rng)
        e0 = rotational_energy(w, m, x)
        assert rotational_energy(Q @ w, m, x @ Q.T + rng.normal(size=3)) == \
            pytest.approx(e0, rel=1e-12)
        # body frame: R -> Q R with omega -> Q omega
        moments, R = principal_frame(inertia_tensor(m, x)[0])
        assert rotational_energy_body(Q @ w, moments, Q @ R) == pytest.approx(e0, rel=1e-12)


def test_spherical_bodies_use_eq6():
    rng = np.random.default_rng(2)
    cube = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    octa = np.vstack([np.eye(3), -np.eye(3)]) * 1.7
    for pts in (cube, octa, np.vstack([cube, octa])):
        m = np.ones(len(pts)) * 1.3
        I, _ = inertia_tensor(m, pts)
        moments, R = principal_frame(I)
        assert np.ptp(moments) < 1e-12 * moments.max()
        for _ in range(5):
            w = rng.normal(size=3)
            Q = random_rotation(rng)
            ref = bead_energy(w, m, pts @ Q.T)
            e6 = rotational_energy_sphere(w, moments.mean())
            assert e6 == pytest.approx(ref, rel=1e-12)
            assert rotational_energy_body(w, moments, Q @ R) == pytest.approx(ref, rel=1e-12)
    # a single bead has no rotational energy
    assert rotational_energy([1.0, 2.0, 3.0], [2.0], [[1.0, 1.0, 1.0]]) == 0.0


def test_total_energy_many_bodies_vectorised():
    rng = np.random.default_rng(3)
    G = 40
    bodies = [random_body(rng) for _ in range(G)]
    ids = rng.permutation(np.arange(G) * 7 - 50)            # arbitrary, unsorted ids
    m = np.concatenate([b[0] for b in bodies])
    x = np.concatenate([b[1] + rng.uniform(-20, 20, 3) for b in bodies])
    body = np.concatenate([np.full(len(b[0]), i) for b, i in zip(bodies, ids)])
    shuffle = rng.permutation(len(m))
    m, x, body = m[shuffle], x[shuffle], body[shuffle]
    order = np.sort(ids)
    w = rng.normal(size=(G, 3))
    per = np.array([bead_energy(w[g], m[body == order[g]], x[body == order[g]])
                    for g in range(G)])
    assert np.allclose(rotational_energies(w, m, x, body), per, rtol=1e-12, atol=0)
    ref = per.sum()
    assert total_rotational_energy(w, m, x, body) == pytest.approx(ref, rel=1e-12)   # eq 7
    got_ids, I, com = body_inertia_tensors(m, x, body)
    assert np.array_equal(got_ids, order)
    moments, R = principal_frame(I)
    assert total_rotational_energy(w, moments=moments, rotation=R) == \
        pytest.approx(ref, rel=1e-12)
    assert total_rotational_energy(w, moments=moments, rotation=matrix_to_quaternion(R)) == \
        pytest.approx(ref, rel=1e-12)
    # periodic box: wrapping beads into the box changes nothing with box= given
    box = np.array([60.0, 70.0, 80.0])
    xw = np.mod(x, box)
    assert total_rotational_energy(w, m, xw, body, box=box) == pytest.approx(ref, rel=1e-12)
    with pytest.raises(ValueError, match="rows for"):
        rotational_energies(w[:-1], m, x, body)


def test_quaternion_round_trip_and_convention():
    rng = np.random.default_rng(4)
    q = rng.normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[:10] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0.6, 0.8, 0],
              [0.5, 0.5, 0.5, 0.5], [-1, 0, 0, 0], [0, 0, -0.6, 0.8], [1e-9, 1, 0, 0],
              [0.7071067811865476, 0, 0, -0.7071067811865476]]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R = quaternion_to_matrix(q)
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-14)
    assert np.allclose(np.linalg.det(R), 1.0, atol=1e-14)
    back = matrix_to_quaternion(R)
    assert (back[:, 0] >= 0).all()
    assert np.allclose(np.abs((back * q).sum(1)), 1.0, atol=1e-12)   # q ~ -q
    assert np.allclose(quaternion_to_matrix(back), R, atol=1e-14)
    # 90 degrees about z maps x to y; same convention as kapsel.particles.quaternion
    c = np.cos(np.pi / 4)
    assert np.allclose(quaternion_to_matrix([c, 0, 0, c]) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    from kapsel.particles.quaternion import to_matrix
    assert np.allclose(to_matrix(q), R, atol=1e-14)
    with pytest.raises(ValueError):
        quaternion_to_matrix([0, 0, 0, 0])
