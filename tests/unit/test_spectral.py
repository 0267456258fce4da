"""Pseudo-spectral NS solver (kapsel.fluid.spectral) and grid (kapsel.mesh.grid): fast tests."""
import numpy as np
import pytest

from kapsel.fluid.spectral import SpectralNS, phi1, phi2
from kapsel.mesh.grid import Grid
from kapsel.timestep import auto_dt

from builders import TESTS


def measured_dt(factor, rho, eta, dx):
    """The time step these measurements were made at: factor RHO / (ETA (pi / DX)^2).  (Not
    the automatic time step of a run, kapsel.timestep.auto_dt; a fixed dt keeps the tables
    in the comments valid.)"""
    return factor * rho / (eta * (np.pi / dx) ** 2)


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


@pytest.mark.parametrize("threads", [1, 2])
def test_grid_transforms_roundtrip_and_normalisation(threads):
    g = Grid((16, 8, 12), dx=0.5, threads=threads)
    u = np.random.default_rng(0).normal(size=(3,) + g.shape)
    u0 = u.copy()
    uh = g.rfft(u)
    np.testing.assert_array_equal(u, u0)  # input preserved
    np.testing.assert_allclose(uh, np.fft.rfftn(u, axes=(1, 2, 3)), atol=1e-12)
    np.testing.assert_allclose(g.irfft(uh), u, atol=1e-13)
    np.testing.assert_allclose(g.irfft(uh, out=np.zeros_like(u)), u, atol=1e-13)
    before = uh.copy()
    g.irfft(uh)
    np.testing.assert_array_equal(uh, before)  # preserved
    assert uh[0, 0, 0, 0].real == pytest.approx(u[0].sum())
    # non-contiguous input / out
    o = np.zeros((3,) + g.cshape, complex)
    g.rfft(np.ascontiguousarray(u[:, ::-1])[:, ::-1], out=o)
    np.testing.assert_allclose(o, uh, atol=1e-12)
    # scalars
    f = u[1]
    fh = g.rfft_scalar(f)
    np.testing.assert_allclose(fh, np.fft.rfftn(f), atol=1e-12)
    np.testing.assert_allclose(g.irfft_scalar(fh), f, atol=1e-13)
    np.testing.assert_array_equal(fh, g.rfft_scalar(f, out=np.empty(g.cshape, complex)))
    np.testing.assert_allclose(g.irfft_scalar(fh, out=np.empty(g.shape)), f, atol=1e-13)


def test_grid_wavenumbers_dealias_volume():
    g = Grid((32, 32, 32), dx=1.0)
    assert g.cshape == (32, 32, 17)
    assert g.trunc == (10, 10, 10)
    assert g.k_trunc == pytest.approx(2 * np.pi * 10 / 32)
    assert g.dealias.dtype == bool and g.dealias.sum() == 21 * 21 * 11
    g2 = Grid((64, 32, 16), dx=2.0)
    assert g2.volume == pytest.approx(128 * 64 * 32)
    assert g2.kx.shape == (64, 1, 1) and g2.ky.shape == (1, 32, 1) and g2.kz.shape == (1, 1, 9)
    assert g2.kx[1, 0, 0] == pytest.approx(2 * np.pi / 128)
    assert g2.kz[0, 0, -1] == pytest.approx(np.pi / 2.0)  # Nyquist
    np.testing.assert_allclose(g2.k2, g2.kx ** 2 + g2.ky ** 2 + g2.kz ** 2)


def test_auto_dt_is_the_originals():
    """FORMAT.md: dt = factor / (NU KMAX2), KMAX2 = sum_d (2 pi TRN_d / (N_d DX))^2,
    TRN_d = floor((N_d + 2) / 3): 0.0714552 for a 32^3 mesh at factor 1 (the original's
    figure); 64 x 32 x 16: TRN = 22, 11, 6, KMAX2 = 2 (2 pi 11/32)^2 + (2 pi 6/16)^2."""
    assert auto_dt(1.0, 1.0, 1.0, 1.0, (32, 32, 32)) == pytest.approx(0.0714552, abs=5e-8)
    k2 = 2 * (2 * np.pi * 11 / 32) ** 2 + (2 * np.pi * 6 / 16) ** 2
    assert auto_dt(1.0, 1.0, 1.0, 1.0, (64, 32, 16)) == pytest.approx(1 / k2, rel=1e-12)
    assert auto_dt(1.0, 1.0, 1.0, 1.0, (64, 32, 16)) == pytest.approx(0.0671975, abs=5e-8)
    # factor, NU = ETA / RHO and DX enter as factor RHO DX^2 / ETA
    assert auto_dt(0.5, 2.0, 4.0, 0.5, (32, 32, 32)) == pytest.approx(
        0.0714551598 * 0.5 * 2.0 * 0.25 / 4.0, rel=1e-9)
    g = Grid((16, 16, 16), dx=0.5)
    assert g.auto_dt(0.3, 1.2, 0.7) == auto_dt(0.3, 1.2, 0.7, 0.5, (16, 16, 16))


def test_projection_solenoidal():
    g = Grid((16, 12, 10), dx=0.7)
    rng = np.random.default_rng(3)
    u = rng.normal(size=(3,) + g.shape) + np.array([1.0, 2.0, 3.0])[:, None, None, None]
    uh = g.rfft(u)
    k0 = uh[:, 0, 0, 0].copy()
    g.project(uh)
    div = g.kx * uh[0] + g.ky * uh[1] + g.kz * uh[2]
    scale = np.sqrt(g.k2).max() * np.abs(uh).max()
    assert np.abs(div).max() < 1e-13 * scale
    np.testing.assert_array_equal(uh[:, 0, 0, 0], k0)  # k = 0 untouched
    p2 = uh.copy()
    g.project(p2)
    np.testing.assert_allclose(p2, uh, atol=1e-12 * np.abs(uh).max())  # idempotent


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
    """2D Taylor-Green in 3D: u x omega is a gradient, so u decays as exp(-2 nu k^2 t)."""
    g = Grid((16, 16, 8), dx=1.0)
    nu, rho = 0.7, 1.3
    dt = measured_dt(1.0, rho, rho * nu, g.dx)
    ns = SpectralNS(g, rho, rho * nu, dt, scheme=scheme)
    u0, k = taylor_green(g)
    ns.set_velocity(u0)
    nsteps = 100
    ns.run(nsteps)
    t = nsteps * dt
    expect = u0 * np.exp(-2 * nu * k * k * t)
    assert np.exp(-2 * nu * k * k * t) < 0.5  # a real decay
    err = np.abs(ns.velocity() - expect).max() / np.abs(expect).max()
    assert err < 1e-6, err
    assert ns.kinetic_energy() == pytest.approx(
        0.5 * rho * np.sum(expect ** 2), rel=1e-10)


def test_taylor_green_3d_momentum_energy():
    """3D Taylor-Green at small Re: zero momentum kept, energy decays monotonically."""
    g = Grid((16, 16, 16), dx=1.0)
    x, y, z = g.coordinates()
    k = 2 * np.pi / 16
    U = 0.05
    u = np.zeros((3,) + g.shape)
    u[0] = U * np.sin(k * x) * np.cos(k * y) * np.cos(k * z)
    u[1] = -U * np.cos(k * x) * np.sin(k * y) * np.cos(k * z)
    rho, eta = 1.0, 0.5
    ns = SpectralNS(g, rho, eta, measured_dt(1.0, rho, eta, 1.0))
    ns.set_velocity(u)
    np.testing.assert_allclose(ns.velocity(), u, atol=1e-15)  # already solenoidal
    assert ns.kinetic_energy() == pytest.approx(0.5 * rho * np.sum(u ** 2), rel=1e-12)
    e = [ns.kinetic_energy()]
    for _ in range(60):
        ns.step()
        e.append(ns.kinetic_energy())
        assert np.abs(ns.momentum()).max() < 1e-15
    e = np.array(e)
    assert np.all(np.diff(e) < 0)
    # nonlinear term active but weak: close to the Stokes decay exp(-2 nu 3 k^2 t)
    t = 60 * ns.dt
    assert e[-1] / e[0] == pytest.approx(np.exp(-2 * 0.5 * 3 * k * k * t), rel=1e-3)
    assert ns.divergence_max() < 1e-14


def test_step_force_kolmogorov_steady_state():
    """f = F sin(k y) x: ETD1 has the exact steady state u = F/(nu k^2) sin(k y) x."""
    g = Grid((8, 16, 8), dx=1.0)
    _, y, _ = g.coordinates()
    k = 2 * np.pi / 16
    F = 1e-3
    f = np.zeros((3,) + g.shape)
    f[0] = F * np.sin(k * y)
    nu = 2.0
    ns = SpectralNS(g, 1.0, nu, 1.0)  # large dt: exact integration stays stable
    for _ in range(200):
        ns.step(f)
    expect = np.zeros_like(f)
    expect[0] = F / (nu * k * k) * np.sin(k * y)
    np.testing.assert_allclose(ns.velocity(), expect, atol=1e-12 * F / (nu * k * k))
    # a uniform force: momentum rises by RHO V f dt per step
    p0 = ns.momentum()
    fu = np.zeros_like(f)
    fu[2] = 0.01
    ns.step(fu)
    np.testing.assert_allclose(ns.momentum() - p0, [0, 0, 0.01 * g.volume * 1.0], atol=1e-12)


def test_add_solenoidal_gradient_only_changes_mean():
    g = Grid((16, 16, 12), dx=0.5)
    ns = SpectralNS(g, 2.0, 1.0, 0.01)
    ns.set_velocity(random_solenoidal(g, kmax=3, amp=0.1))
    before = ns.u_hat.copy()
    x, y, z = g.coordinates()
    L = g.box
    a, b, c = 2 * np.pi / L[0], 4 * np.pi / L[1], 2 * np.pi / L[2]
    # grad of sin(a x) cos(b y) + cos(c z) + mean
    du = np.zeros((3,) + g.shape)
    du[0] = a * np.cos(a * x) * np.cos(b * y) + 0 * z
    du[1] = -b * np.sin(a * x) * np.sin(b * y) + 0 * z
    du[2] = -c * np.sin(c * z) + 0 * x
    mean = np.array([0.1, -0.2, 0.3])
    du += mean[:, None, None, None]
    p0 = ns.momentum()
    ns.add_solenoidal(du)
    d = ns.u_hat - before
    d0 = d[:, 0, 0, 0].copy()
    d[:, 0, 0, 0] = 0
    assert np.abs(d).max() < 1e-12 * np.abs(before).max()
    np.testing.assert_allclose(d0.real, mean * g.size, rtol=1e-12)
    np.testing.assert_allclose(ns.momentum() - p0, 2.0 * g.volume * mean, rtol=1e-12)


def test_projection_and_fix_cell():
    g = Grid((16, 16, 16))
    rng = np.random.default_rng(1)
    ns = SpectralNS(g, 1.0, 1.0, measured_dt(1, 1, 1, g.dx), fix_cell=(True, False, True))
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


def test_deterministic_across_processes():
    """Default planner ('auto' = ESTIMATE at this size): bitwise equal in two processes."""
    import subprocess
    import sys
    code = (
        "import sys, hashlib, numpy as np\n"
        "from kapsel.mesh.grid import Grid\n"
        "from kapsel.fluid.spectral import SpectralNS\n"
        "g = Grid((32, 32, 32), 1.0)\n"
        "ns = SpectralNS(g, 1.0, 1.0, 0.1)\n"
        "ns.set_velocity(np.random.default_rng(0).normal(size=(3,) + g.shape) * 0.1)\n"
        "ns.step(); ns.step()\n"
        "print(g.planner, hashlib.md5(ns.u_hat.tobytes()).hexdigest())\n")
    root = str(__import__("pathlib").Path(TESTS).resolve().parent)
    out = [subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                          text=True, check=True).stdout for _ in range(2)]
    assert out[0].startswith("FFTW_ESTIMATE") and out[0] == out[1]


@pytest.mark.parametrize("scheme", ["etd1", "etd2"])
def test_compiled_step_bit_identical_to_numpy_passes(scheme, compiled_kernels):
    """The fused compiled passes (kapsel.fluid.spectral_kernels) give the same u_hat, bit for
    bit, as the numpy passes they replace: steps with a constant and a per-step force and
    solenoidal increments (the SPM path)."""
    g = Grid((16, 12, 10), 1.0)
    rng = np.random.default_rng(3)
    u0 = rng.normal(size=(3,) + g.shape) * 0.3
    f = rng.normal(size=(3,) + g.shape) * 0.01
    du = rng.normal(size=(3,) + g.shape) * 0.01

    def steps():
        ns = SpectralNS(g, 1.0, 0.7, 0.05, scheme=scheme, force=[0.01, 0.0, -0.02])
        ns.set_velocity(u0)
        for _ in range(4):
            ns.step(force=f)
            ns.add_solenoidal(du)
        return ns.u_hat.copy()
    out = compiled_kernels.both(steps)
    assert np.array_equal(out[0], out[1])


@pytest.mark.parametrize("form", ["points", "rows"])
@pytest.mark.parametrize("scheme", ["etd1", "etd2", "euler"])
def test_both_projection_forms_give_the_numpy_passes_bits(form, scheme, compiled_kernels,
                                                          monkeypatch):
    """The two forms of the compiled projections (point by point, and by blocks of rows:
    kapsel.fluid.spectral.projection_kernels times them and takes the faster) give the
    numpy passes' u_hat bit for bit (the Electrolyte's Euler update: up to the sign of zero
    modes), on a shape whose 12 rows are a block of 8 and a part block of 4."""
    from kapsel.fluid import spectral
    g = Grid((6, 12, 10), 1.0)
    rng = np.random.default_rng(5)
    u0 = rng.normal(size=(3,) + g.shape) * 0.3
    du = rng.normal(size=(3,) + g.shape) * 0.01

    def steps():
        K = spectral._compiled.spectral
        if K is not None:
            names = ("project_etd1", "project_etd2", "project_add", "project_euler",
                     "project_set_scaled", "project_etd1_velocity")
            suffix = "_rows" if form == "rows" else ""
            monkeypatch.setitem(spectral._PROJECTIONS, g.local_cshape,
                                tuple(getattr(K, n + suffix) for n in names))
        ns = SpectralNS(g, 1.0, 0.7, 0.05, scheme="etd1" if scheme == "euler" else scheme)
        ns.set_velocity(u0)
        for _ in range(3):
            ns.euler_step() if scheme == "euler" else ns.step()
            ns.add_solenoidal(du)
        return ns.u_hat.copy()
    out = compiled_kernels.both(steps)
    a, b = out[0].view(np.float64), out[1].view(np.float64)
    assert np.array_equal(a, b)
    # bit for bit but for the sign of zeros (the Euler update's numpy complex products)
    assert np.all((a.view(np.uint64) == b.view(np.uint64)) | (a == 0.0))


def test_projection_kernels_are_timed_once_per_shape(compiled_kernels):
    """projection_kernels picks one of the two forms for a shape and keeps it."""
    from kapsel.fluid import spectral
    compiled_kernels.on()
    K = spectral._compiled.spectral
    g = Grid((8, 8, 14), 1.0)
    spectral._PROJECTIONS.pop(g.local_cshape, None)
    first = spectral.projection_kernels(K, g)
    assert first in ((K.project_etd1, K.project_etd2, K.project_add, K.project_euler,
                      K.project_set_scaled, K.project_etd1_velocity),
                     (K.project_etd1_rows, K.project_etd2_rows, K.project_add_rows,
                      K.project_euler_rows, K.project_set_scaled_rows,
                      K.project_etd1_velocity_rows))
    assert spectral.projection_kernels(K, g) is first


def _step_then_velocity(fluid, u, fused):
    """A step of ``fluid`` and its new u in ``u``: made by the step (``fused``) or after it."""
    if fused:
        fluid.step(velocity=u)
    else:
        fluid.step()
        fluid.velocity(out=u)


@pytest.mark.parametrize("form", ["points", "rows"])
@pytest.mark.parametrize("start", ["whole", "truncated"])
@pytest.mark.parametrize("fix", [False, True])
def test_step_with_velocity_gives_the_step_then_velocitys_bits(form, start, fix,
                                                              compiled_kernels, monkeypatch):
    """step(velocity=u) (compiled: the update's sweep leaves u_hat / N for the c2r,
    ``project_etd1_velocity``) gives step() then velocity(out=u) bit for bit, u_hat and u,
    in both forms of the sweep, from a state with modes off the 2/3 mask (transformed
    whole) and from a truncated one (the lines of zeros skipped), with FIX_CELL's mean set
    after the sweep; and the numpy passes' bits."""
    from kapsel.fluid import spectral
    g = Grid((6, 12, 10), 1.0)
    rng = np.random.default_rng(7)
    u0 = rng.normal(size=(3,) + g.shape) * 0.3
    du = rng.normal(size=(3,) + g.shape) * 0.01
    calls = []

    def run(fused):
        K = spectral._compiled.spectral
        if K is not None:
            names = ("project_etd1", "project_etd2", "project_add", "project_euler",
                     "project_set_scaled", "project_etd1_velocity")
            suffix = "_rows" if form == "rows" else ""
            kernels = [getattr(K, n + suffix) for n in names]
            sweep = kernels[5]
            kernels[5] = lambda *a: calls.append(sweep(*a)) or calls[-1]
            monkeypatch.setitem(spectral._PROJECTIONS, g.local_cshape, tuple(kernels))
        ns = SpectralNS(g, 1.0, 0.7, 0.05, fix_cell=(fix, False, fix))
        ns.set_velocity(u0)
        if start == "truncated":
            ns.u_hat *= g.dealias_f
        u = g.empty_real()
        us = []
        for _ in range(3):
            _step_then_velocity(ns, u, fused)
            us.append(u.copy())
            ns.add_solenoidal(du)
        return ns.u_hat.copy(), np.array(us)

    compiled_kernels.on()
    ref = run(False)
    assert not calls
    got = run(True)
    assert calls == [start == "truncated"] * 3     # the sweep ran, and said so
    for a, b in zip(ref, got):
        assert np.array_equal(a.view(np.uint8), b.view(np.uint8))
    compiled_kernels.off()
    plain = run(True)
    for a, b in zip(ref, plain):
        assert np.array_equal(a, b)


def test_auto_planner_measures_threaded_plans():
    """FFTW_ESTIMATE's threaded plans were 2x slower than one thread at 64^3 (so --threads 2
    was slower than 1): with threads the 'auto' planner measures, with one thread it keeps
    the deterministic ESTIMATE up to 64^3 (kapsel.mesh.grid.auto_planner)."""
    from kapsel.mesh.grid import Grid, auto_planner
    assert auto_planner(64 ** 3, 1) == "FFTW_ESTIMATE"
    assert auto_planner(64 ** 3, 2) == "FFTW_MEASURE"
    assert auto_planner(128 ** 3, 1) == "FFTW_MEASURE"
    assert Grid((16, 16, 16), threads=2).planner == "FFTW_MEASURE"
    assert Grid((16, 16, 16), threads=1).planner == "FFTW_ESTIMATE"


@pytest.mark.parametrize("shape", [(32, 32, 32), (64, 64, 64), (16, 8, 12), (24, 32, 48),
                                   (27, 15, 9), (8, 8, 2)])
def test_truncated_transforms_skip_lines_of_zeros_with_the_same_bits(shape):
    """backward_scalar_truncated of a 2/3-truncated field gives backward_scalar_raw's bits;
    rfft_scalar_truncated gives rfft_scalar's on the mask (FFTW_ESTIMATE: the 3-D plan
    makes the same 1-D transforms in the same order); an array of another alignment takes
    the whole transform; a scratch given again and again, or in turn with another, too."""
    g = Grid(shape, dx=0.5)
    rng = np.random.default_rng(1)
    mask = g.dealias
    c = g.empty_complex(None)
    c[...] = (rng.normal(size=g.cshape) + 1j * rng.normal(size=g.cshape)) * mask
    full, pruned = g.empty_real(None), g.empty_real(None)
    g.backward_scalar_raw(c.copy(), full)
    g.backward_scalar_truncated(c.copy(), pruned)
    np.testing.assert_array_equal(pruned, full)
    f = rng.normal(size=shape)
    a, b = g.empty_complex(None), g.empty_complex(None)
    g.rfft_scalar(f, out=a)
    g.rfft_scalar_truncated(f, b)
    np.testing.assert_array_equal(b[mask], a[mask])
    # vector forms, and an unaligned output (the whole transform)
    u = rng.normal(size=(3,) + shape)
    vh = g.forward_truncated(u, g.empty_complex())
    np.testing.assert_array_equal(vh[:, mask], g.forward(u, out=g.empty_complex())[:, mask])
    raw = np.empty(g.size + 1)[1:].reshape(shape)
    g.backward_scalar_truncated(c.copy(), raw)
    np.testing.assert_array_equal(raw, full)
    out = g.backward_truncated(np.stack([c, c, c]), g.empty_real())
    np.testing.assert_array_equal(out[2], full)
    # a caller's scratch used again and again (the stages along x and y stay pointed at
    # it), alternating with another array: each time the whole transform's bits
    s1, s2 = g.empty_complex(None), g.empty_complex(None)
    for k in range(4):
        s = s1 if k != 2 else s2
        v = (rng.normal(size=g.cshape) + 1j * rng.normal(size=g.cshape)) * mask
        s[...] = v
        g.backward_scalar_truncated(s, pruned)
        g.backward_scalar_raw(v.copy(), full)
        np.testing.assert_array_equal(pruned, full)


def test_truncated_transforms_with_measured_plans():
    """Measured plans (above 64^3, or threads) may pick other 1-D algorithms than the 3-D
    plan: the same numbers to round-off."""
    g = Grid((16, 16, 16), dx=1.0, planner="FFTW_MEASURE")
    rng = np.random.default_rng(2)
    c = g.empty_complex(None)
    c[...] = (rng.normal(size=g.cshape) + 1j * rng.normal(size=g.cshape)) * g.dealias
    full, pruned = g.empty_real(None), g.empty_real(None)
    g.backward_scalar_raw(c.copy(), full)
    g.backward_scalar_truncated(c.copy(), pruned)
    np.testing.assert_allclose(pruned, full, atol=1e-12 * np.abs(full).max())


def test_velocity_transforms_a_truncated_state_as_one(compiled_kernels):
    """SpectralNS.velocity: the compiled pass that scales u_hat tells whether a component is
    0 off the 2/3 mask; only then are the lines of zeros skipped.  A state with modes off
    the mask (set_velocity does not truncate) is transformed whole: both give irfftn's
    numbers, and the compiled and numpy passes the same values."""
    g = Grid((16, 12, 10), 1.0)
    rng = np.random.default_rng(7)
    u0 = rng.normal(size=(3,) + g.shape)

    def velocities():
        ns = SpectralNS(g, 1.0, 0.7, 0.05)
        ns.set_velocity(u0)
        whole = ns.velocity().copy()
        assert np.abs(ns.u_hat[:, ~g.dealias]).max() > 0.1      # modes off the mask
        np.testing.assert_allclose(whole, np.fft.irfftn(ns.u_hat, s=g.shape, axes=(1, 2, 3)),
                                   atol=1e-12)
        ns.u_hat *= g.dealias_f
        parts = []
        for c, mode in ((2, (6, 0, 0)), (0, (1, 4, 2)), (1, (2, 1, 4))):   # off along x,
            ns.u_hat[(c,) + mode] = 0.5      # y, z: one component off the mask (the box
            parts.append(ns.velocity().copy())       # |m| <= 5, 3, 3)
            np.testing.assert_allclose(parts[-1], np.fft.irfftn(ns.u_hat, s=g.shape,
                                                                axes=(1, 2, 3)), atol=1e-12)
            ns.u_hat[(c,) + mode] = 0.0
        truncated = ns.velocity().copy()
        np.testing.assert_allclose(truncated, np.fft.irfftn(ns.u_hat, s=g.shape,
                                                            axes=(1, 2, 3)), atol=1e-12)
        return [whole, truncated] + parts
    out = compiled_kernels.both(velocities)
    for a, b in zip(*out):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("kind", ["DC", "AC"])
def test_oblique_step_with_velocity_gives_the_step_then_velocitys_bits(kind,
                                                                      compiled_kernels,
                                                                      monkeypatch):
    """ObliqueSpectralNS.step(velocity=u) (compiled: the fused update also leaves the new
    Cartesian u / N in the frame after the step, ``project_oblique_etd1_velocity``) gives
    step() then velocity(out=u) bit for bit, u_hat and u, with FIX_CELL's mean set after the
    sweep, across re-mappings of the frame (where u is made apart), DC and AC; and the numpy
    passes' bits."""
    from kapsel.fluid import oblique
    from kapsel.fluid.oblique import ObliqueSpectralNS
    from kapsel.frame import ShearFlow
    g = Grid((16, 12, 10), 1.0)
    rng = np.random.default_rng(13)
    u0 = rng.normal(size=(3,) + g.shape) * 0.2
    du = rng.normal(size=(3,) + g.shape) * 0.01
    shear = ShearFlow("DC", 4.0) if kind == "DC" else ShearFlow("AC", 4.0, frequency=0.1)
    calls = []

    def run(fused):
        K = oblique._compiled.spectral
        if K is not None and fused:
            sweep = K.project_oblique_etd1_velocity
            monkeypatch.setattr(K, "project_oblique_etd1_velocity",
                                lambda *a: calls.append(1) or sweep(*a))
        f = ObliqueSpectralNS(g, 1.0, 0.7, 0.05, shear, fix_cell=(True, False, True))
        f.set_velocity(u0)
        u = g.empty_real()
        out, remaps = [], []
        for _ in range(8):
            _step_then_velocity(f, u, fused)
            out += [u.copy(), f.u_hat.copy()]
            remaps.append(f.remaps)
            f.add_solenoidal(du)
        monkeypatch.undo()
        return out, remaps

    compiled_kernels.on()
    ref, remaps = run(False)
    assert len(set(remaps)) > 1              # the frame was re-mapped
    got, _ = run(True)
    assert len(calls) == 8
    for a, b in zip(ref, got):
        assert np.array_equal(a.view(np.uint8), b.view(np.uint8))
    compiled_kernels.off()
    plain, _ = run(True)
    for a, b in zip(ref, plain):
        assert np.array_equal(a, b)


def test_oblique_velocity_and_step_compiled_as_numpy(compiled_kernels):
    """ObliqueSpectralNS (Lees-Edwards): the compiled passes (Cartesian components, their
    vorticity, u x omega in contravariant components, the masked metric projection with the
    shear term, the ETD update, the truncation; fused, and apart with a body force or
    without advection; the Reynolds stress's sum) give the numpy passes' values; velocity()
    transforms a component with modes off the 2/3 mask whole, a truncated one with the
    lines of zeros skipped, both irfftn's numbers."""
    from kapsel.fluid.oblique import ObliqueSpectralNS
    from kapsel.frame import ShearFlow
    g = Grid((16, 12, 10), 1.0)
    rng = np.random.default_rng(11)
    u0 = rng.normal(size=(3,) + g.shape) * 0.2
    du = rng.normal(size=(3,) + g.shape) * 0.01

    def run():
        f = ObliqueSpectralNS(g, 1.0, 0.7, 0.05, ShearFlow("DC", 0.3))
        f.set_velocity(u0)
        out = []
        for _ in range(3):
            f.step()
            out.append(f.velocity().copy())              # truncated after the step
            f.add_solenoidal(du)                         # modes off the mask
            u = f.velocity().copy()
            cart = f.u_hat.copy()
            cart[0] += f.frame_strain * cart[1]
            np.testing.assert_allclose(u, np.fft.irfftn(cart, s=g.shape, axes=(1, 2, 3)),
                                       atol=1e-12)
            out += [u, f.u_hat.copy(), np.array(f.uxuy_sum())]
        f.step(force=du)                 # a body force: the unfused step, factors everywhere
        out.append(f.u_hat.copy())
        f.advection = False
        f.step()                         # no advection: unfused
        out.append(f.u_hat.copy())
        f.advection = True
        v = np.random.default_rng(5).normal(size=f.u_hat.shape + (2,)) @ [1.0, 1j]
        f.project_metric(v, f.frame_strain, rate=0.3, masked=True)   # u_hat not truncated:
        assert np.abs(v[:, ~g.dealias]).max() == 0.0                   # 0 off the mask all
        return out + [v]                                               # the same
    out = compiled_kernels.both(run)
    for a, b in zip(*out):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("g", [0.0, 0.3])
def test_velocity_vorticity_is_the_component_kernels(g, compiled_kernels):
    """velocity_vorticity (the truncated Cartesian u / N and its curl in one sweep, the
    Lees-Edwards advection's) writes what frame_component (truncated) and
    frame_vorticity_component write, bit for bit, off the mask too."""
    from kapsel.fluid import spectral
    compiled_kernels.on()
    K = spectral._compiled.spectral
    grid = Grid((6, 12, 10), 1.0)
    rng = np.random.default_rng(3)
    shape = (3,) + grid.cshape
    uh = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)   # off the mask too
    box, k1, inv = grid.dealias_box, [np.ascontiguousarray(k) for k in grid.k_axes], 0.01
    u_ref, w_ref = np.empty(shape, complex), np.empty(shape, complex)
    for c in range(3):
        K.frame_component(uh, *box, inv, g, c, True, u_ref[c])
        K.frame_vorticity_component(uh, *box, inv, g, *k1, c, w_ref[c])
    v = np.full(shape, np.nan, complex)
    w = [np.full(grid.cshape, np.nan, complex) for _ in range(3)]
    K.velocity_vorticity(uh, *box, inv, g, *k1, v, *w)
    assert np.array_equal(v.view(np.uint64), u_ref.view(np.uint64))
    for c in range(3):
        assert np.array_equal(w[c].view(np.uint64), w_ref[c].view(np.uint64))
