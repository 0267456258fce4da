"""SPM profile (eqs 1-4) and particle-fluid coupling (eqs 6, 11-12): fast unit tests."""
import numpy as np
import pytest

from kapsel.particles.coupling import (hydro_force_torque, particle_velocity_field,
                                       rigid_velocity, rigidity_increment)
from kapsel.particles.profile import Stencil, g, particle_profiles, total_phi

SHAPE = (24, 24, 24)
A, XI, DX = 4.0, 2.0, 1.0


@pytest.fixture
def two():
    rng = np.random.default_rng(1)
    R = np.array([[5.3, 6.1, 7.7], [15.2, 17.9, 12.4]]) + rng.uniform(0, 1, (2, 3))
    st = Stencil(A, XI, DX)
    idx, phi, r = particle_profiles(R, st, SHAPE, DX)
    return R, st, idx, phi, r


def test_profile_bounds_inside_outside(two):
    R, st, idx, phi, r = two
    d = np.linalg.norm(r, axis=2)
    assert phi.min() >= 0 and phi.max() <= 1
    assert np.all(phi[d <= A - XI / 2] == 1.0)
    assert np.all(phi[d >= A + XI / 2] == 0.0)
    mid = (d > A - XI / 2) & (d < A + XI / 2)
    assert np.all((phi[mid] >= 0) & (phi[mid] <= 1))  # exp(-1/x^2) underflows at the ends
    order = np.argsort(d[mid])
    assert np.all(np.diff(phi[mid][order]) <= 1e-15)  # decreasing with distance
    assert g(A, A, XI, DX) == pytest.approx(0.5)
    field = total_phi(idx, phi, np.prod(SHAPE)).reshape(SHAPE)
    assert field.max() <= 1.0 and field.sum() == pytest.approx(phi.sum())


def test_stencil_covers_support():
    """Brute force over the whole grid: no point with phi > 0 is missing from the stencil."""
    st = Stencil(A, XI, DX)
    rng = np.random.default_rng(2)
    x = np.stack(np.meshgrid(*[np.arange(n) * DX for n in SHAPE], indexing="ij"), -1)
    L = np.array(SHAPE) * DX
    for R in rng.uniform(0, L, (5, 3)):
        d = x - R
        d -= L * np.round(d / L)
        full = g(np.linalg.norm(d, axis=-1), A, XI, DX)
        idx, phi, r = particle_profiles(R[None], st, SHAPE, DX)
        sparse = total_phi(idx, phi, full.size).reshape(SHAPE)
        np.testing.assert_allclose(sparse, full, atol=1e-15)
        assert len(np.unique(idx)) == idx.size


def test_grid_volume(two):
    _, _, _, phi, _ = two
    vol = phi.sum(axis=1) * DX ** 3
    np.testing.assert_allclose(vol, 4 / 3 * np.pi * A ** 3, rtol=0.02)


def test_translation_field(two):
    R, st, idx, phi, r = two
    V = np.array([[0.1, -0.2, 0.3], [0.1, -0.2, 0.3]])
    f = particle_velocity_field(idx, phi, r, V, np.zeros((2, 3)), np.prod(SHAPE), SHAPE)
    ph = total_phi(idx, phi, np.prod(SHAPE)).reshape(SHAPE)
    np.testing.assert_allclose(f, V[0][:, None, None, None] * ph, atol=1e-15)


def test_no_force_when_comoving(two):
    R, st, idx, phi, r = two
    rng = np.random.default_rng(3)
    V, W = rng.normal(size=(2, 3)), rng.normal(size=(2, 3)) * 0.1
    u = rng.normal(size=(3,) + SHAPE)
    flat = u.reshape(3, -1)
    flat[:, idx] = rigid_velocity(r, V, W)  # fluid moves rigidly with each particle
    F, T = hydro_force_torque(u, idx, phi, r, V, W, 1.0, DX, 0.1)
    assert np.abs(F).max() < 1e-12 and np.abs(T).max() < 1e-12


def test_rigidity_increment_inside(two):
    R, st, idx, phi, r = two
    rng = np.random.default_rng(4)
    V, W = rng.normal(size=(2, 3)), rng.normal(size=(2, 3)) * 0.1
    u = rng.normal(size=(3,) + SHAPE)
    u2 = u + rigidity_increment(u, idx, phi, r, V, W, np.prod(SHAPE))
    inside = phi == 1.0
    got = u2.reshape(3, -1)[:, idx]
    want = rigid_velocity(r, V, W)
    np.testing.assert_allclose(got[:, inside], want[:, inside], atol=1e-14)
    outside = np.ones(np.prod(SHAPE), bool)
    outside[idx[phi > 0]] = False
    np.testing.assert_array_equal(u2.reshape(3, -1)[:, outside], u.reshape(3, -1)[:, outside])


def test_momentum_exchange_bookkeeping(two):
    """One exchange step (eqs 9-12 + rigidity increment) conserves RHO DX^3 sum(u) +
    sum_i (M_i - RHO DX^3 sum phi_i) V_i exactly when r is taken about the discrete centroid
    (sum phi_i r = 0): F_H dt is the momentum the fluid loses inside the particle, and the
    rigidity increment gives back RHO DX^3 V_p,i dV_i.  With the grid mass
    M_i = RHO DX^3 sum phi_i the fluid field momentum alone is invariant."""
    R, st, idx, phi, r = two
    rng = np.random.default_rng(5)
    rho, dt = 1.3, 0.07
    vol = phi.sum(axis=1)
    r = r - (np.einsum("ns,nsk->nk", phi, r) / vol[:, None])[:, None, :]
    Vp = rho * DX ** 3 * vol
    scale = rho * DX ** 3 * np.abs(3 * np.ones((3,) + SHAPE)).sum()
    for excess in (0.0, 1.7):
        M = Vp * (1 + excess)
        V, W = rng.normal(size=(2, 3)), rng.normal(size=(2, 3)) * 0.1
        u = rng.normal(size=(3,) + SHAPE)
        F, T = hydro_force_torque(u, idx, phi, r, V, W, rho, DX, dt)
        # F_H dt is exactly the momentum the fluid loses inside the particles
        lost = rho * DX ** 3 * (np.einsum("ns,cns->nc", phi, u.reshape(3, -1)[:, idx])
                                - vol[:, None] * V)
        np.testing.assert_allclose(F * dt, lost, atol=1e-13 * scale)
        V1 = V + dt * F / M[:, None]
        W1 = W + dt * T / 10.0
        du = rigidity_increment(u, idx, phi, r, V1, W1, np.prod(SHAPE))
        dP = rho * DX ** 3 * du.sum(axis=(1, 2, 3)) + ((M - Vp)[:, None] * (V1 - V)).sum(0)
        assert np.abs(dP).max() < 1e-13 * scale
