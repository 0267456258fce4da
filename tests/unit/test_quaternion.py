"""Scalar-first quaternion algebra and the exact rotation integrator."""
import numpy as np

from kapsel.particles import quaternion as Q


def _rand_q(n, seed=0):
    return Q.normalise(np.random.default_rng(seed).standard_normal((n, 4)))


def test_multiply_conjugate_matrix():
    p, q = _rand_q(50, 1), _rand_q(50, 2)
    assert np.allclose(Q.multiply(q, Q.conjugate(q)), [1, 0, 0, 0])
    # composition: matrix of p ⊗ q is M(p) M(q)
    assert np.allclose(Q.to_matrix(Q.multiply(p, q)), Q.to_matrix(p) @ Q.to_matrix(q))
    M = Q.to_matrix(q)
    assert np.allclose(M @ np.swapaxes(M, 1, 2), np.eye(3))
    assert np.allclose(np.linalg.det(M), 1)
    v = np.random.default_rng(3).standard_normal((50, 3))
    qv = Q.multiply(Q.multiply(q, np.concatenate([np.zeros((50, 1)), v], 1)), Q.conjugate(q))
    assert np.allclose(qv[:, 1:], Q.rotate(q, v))
    # rotation by 90 deg about z maps x -> y
    qz = Q.from_axis_angle([0, 0, 1], np.pi / 2)
    assert np.allclose(Q.rotate(qz, [1, 0, 0]), [0, 1, 0])


def test_normalise_zero_is_identity():
    q = Q.normalise([[0, 0, 0, 0], [0, 3, 0, 4]])
    assert np.allclose(q, [[1, 0, 0, 0], [0, 0.6, 0, 0.8]])


def test_integrate_matches_analytic_rotation():
    rng = np.random.default_rng(4)
    n = 30
    q0 = _rand_q(n, 5)
    omega = rng.standard_normal((n, 3)) * 0.7
    dt, steps = 0.013, 250
    q = q0.copy()
    for _ in range(steps):
        q = Q.integrate(q, omega, dt)
    T = dt * steps
    w = np.linalg.norm(omega, axis=1)
    axis = omega / w[:, None]
    # Rodrigues rotation by |omega| T about omega, applied in the space frame
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    K -= np.swapaxes(K, 1, 2)
    th = (w * T)[:, None, None]
    Rot = np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K
    assert np.allclose(Q.to_matrix(q), Rot @ Q.to_matrix(q0), atol=1e-11)
    assert np.allclose(np.linalg.norm(q, axis=1), 1, atol=1e-14)
    # dq/dt = 1/2 (0, omega) ⊗ q for small dt
    h = 1e-6
    dq = (Q.integrate(q0, omega, h) - Q.integrate(q0, omega, -h)) / (2 * h)
    w4 = np.concatenate([np.zeros((n, 1)), omega], 1)
    assert np.allclose(dq, 0.5 * Q.multiply(w4, q0), atol=1e-8)
    # zero omega is the identity map
    assert np.allclose(Q.integrate(q0, np.zeros((n, 3)), dt), q0)
