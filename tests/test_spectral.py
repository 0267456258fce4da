"""Pseudo-spectral NS solver (kapsel.fluid.spectral) and grid (kapsel.grid): fast tests."""
import numpy as np
import pytest

from kapsel.fluid.spectral import SpectralNS, phi1, phi2
from kapsel.grid import Grid


def taylor_green(grid, U=0.1):
    x, y, z = grid.coordinates()
    k = 2 * np.pi / grid.box[0]
    u = np.zeros((3,) + grid.shape)
    u[0] = U * np.sin(k * x) * np.cos(k * y) + 0 * z
    u[1] = -U * np.cos(k * x) * np.sin(k * y) + 0 * z
    return u, k


def random_solenoidal(grid, kmax=3, amp=0.05, seed=0):
    rng = np.random.default_rng(seed)
    uh = grid.empty_complex()
    uh[...] = 0
    m = [np.fft.fftfreq(n, 1.0 / n) for n in grid.shape]
    sel = ((np.abs(m[0])[:, None, None] <= kmax) & (np.abs(m[1])[None, :, None] <= kmax)
           & (np.arange(grid.cshape[2])[None, None, :] <= kmax))
    noise = rng.normal(size=(3,) + grid.cshape) + 1j * rng.normal(size=(3,) + grid.cshape)
    uh[:, sel] = noise[:, sel]
    grid.project(uh)
    u = np.fft.irfftn(uh, s=grid.shape, axes=(1, 2, 3))
    return amp * u / np.abs(u).max()


def test_grid_transforms_roundtrip_and_normalisation():
    g = Grid((16, 8, 12), dx=0.5)
    u = np.random.default_rng(0).normal(size=(3,) + g.shape)
    uh = g.forward(u, out=g.empty_complex())
    np.testing.assert_allclose(uh, np.fft.rfftn(u, axes=(1, 2, 3)), atol=1e-12)
    np.testing.assert_allclose(g.backward(uh), u, atol=1e-13)
    np.testing.assert_allclose(g.backward(uh, out=np.zeros_like(u)), u, atol=1e-13)
    before = uh.copy()
    g.backward(uh)
    np.testing.assert_array_equal(uh, before)  # preserved
    assert uh[0, 0, 0, 0].real == pytest.approx(u[0].sum())


def test_grid_wavenumbers_dealias_kmax_autodt():
    g = Grid((32, 32, 32), dx=1.0)
    assert g.trunc == (10, 10, 10)
    assert g.k_max == pytest.approx(2 * np.pi * 10 / 32)
    assert g.auto_dt(1.0, 1.0, 1.0) == pytest.approx(1.0 / g.k_max ** 2)
    assert g.auto_dt(0.5, 2.0, 4.0) == pytest.approx(0.25 / g.k_max ** 2)
    assert g.dealias.sum() == 21 * 21 * 11
    g2 = Grid((64, 32, 16), dx=2.0)
    assert g2.k_max == pytest.approx(max(2 * np.pi * 21 / 128, 2 * np.pi * 10 / 64,
                                         2 * np.pi * 5 / 32))


def test_phi_functions_series_continuity():
    z = np.array([-1e-12, -1e-5, -0.0999999, -0.1, -0.1000001, -1.0, -50.0, 0.0])
    p1, p2 = phi1(z), phi2(z)
    exact2 = np.array([0.5 + zz / 6 + zz * zz / 24 if abs(zz) < 1e-3 else
                       (np.expm1(zz) - zz) / zz ** 2 for zz in z])
    np.testing.assert_allclose(p2, exact2, rtol=1e-13)
    np.testing.assert_allclose(p1[:-1], np.expm1(z[:-1]) / z[:-1], rtol=1e-15)
    assert p1[-1] == 1.0 and p2[-1] == 0.5


@pytest.mark.parametrize("scheme", ["etd1", "etd2"])
def test_taylor_green_decay(scheme):
    g = Grid((16, 16, 8), dx=1.0)
    nu, rho = 0.7, 1.3
    dt = g.auto_dt(1.0, rho, rho * nu)
    ns = SpectralNS(g, rho, rho * nu, dt, scheme=scheme)
    u0, k = taylor_green(g)
    ns.set_velocity(u0)
    nsteps = 60
    ns.run(nsteps)
    t = nsteps * dt
    expect = u0 * np.exp(-2 * nu * k * k * t)
    err = np.abs(ns.velocity() - expect).max() / np.abs(expect).max()
    assert err < 1e-6, err
    assert ns.kinetic_energy() == pytest.approx(
        0.5 * rho * np.sum(expect ** 2), rel=1e-10)


def test_projection_and_fix_cell():
    g = Grid((16, 16, 16))
    rng = np.random.default_rng(1)
    ns = SpectralNS(g, 1.0, 1.0, g.auto_dt(1, 1, 1), fix_cell=(True, False, True))
    du = rng.normal(size=(3,) + g.shape) + np.array([0.3, -0.2, 0.1])[:, None, None, None]
    ns.add_solenoidal(du)
    assert ns.divergence_max() < 1e-12 * np.abs(du).max()
    np.testing.assert_allclose(ns.mean_velocity(), du.reshape(3, -1).mean(1), atol=1e-14)
    np.testing.assert_allclose(ns.momentum(), du.reshape(3, -1).sum(1), atol=1e-12)
    ns.step()
    m = ns.mean_velocity()
    assert m[0] == 0.0 and m[2] == 0.0 and m[1] == pytest.approx(du[1].mean(), rel=1e-12)
    assert ns.divergence_max() < 1e-12


def test_momentum_conserved_and_force_integrated():
    g = Grid((16, 16, 16))
    ns = SpectralNS(g, 1.5, 1.0, 0.2)
    ns.set_velocity(random_solenoidal(g, kmax=7, amp=0.3) + 0.05)
    p0 = ns.momentum()
    ns.run(20)
    np.testing.assert_allclose(ns.momentum(), p0, rtol=0, atol=1e-14 * np.abs(p0).max())
    f = np.array([1e-3, 0, -2e-3])
    ns.set_force(f)
    ns.run(10)
    np.testing.assert_allclose(ns.momentum(), p0 + 1.5 * g.size * f * 10 * 0.2,
                               rtol=1e-12)


def _error(scheme, dt, nsteps, g, u0, ref):
    ns = SpectralNS(g, 1.0, 0.05, dt, scheme=scheme)
    ns.set_velocity(u0)
    ns.run(nsteps)
    return np.abs(ns.velocity() - ref).max()


def test_time_order_etd1_etd2():
    """Nonlinear 3D flow at Re ~ 10: ETD1 first order, ETD2 second order in dt."""
    g = Grid((16, 16, 16))
    u0 = random_solenoidal(g, kmax=2, amp=0.5)
    T = 4.0
    ns = SpectralNS(g, 1.0, 0.05, T / 512, scheme="etd2")
    ns.set_velocity(u0)
    ns.run(512)
    ref = ns.velocity()
    for scheme, order in (("etd1", 1), ("etd2", 2)):
        e = [_error(scheme, T / n, n, g, u0, ref) for n in (16, 32)]
        rate = np.log2(e[0] / e[1])
        assert abs(rate - order) < 0.3, (scheme, e, rate)
