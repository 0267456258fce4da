"""Shear_Navier_Stokes_Lees_Edwards_FDM and Shear_NS_LE_CH_FDM: the MAC schemes and the
Cahn-Hilliard equation in the oblique frame (kapsel.fluid.oblique.ObliqueMAC, eq 32)."""
import os

import numpy as np
import pytest

from kapsel.fluid.oblique import ObliqueMAC
from kapsel.frame import ShearFlow
from kapsel.mesh.grid import Grid

from builders import build, fdm_input, LE_CH, LE_FDM, shear_cli, shearing_wave


SCHEMES = ("explicit_scheme", "implicit_scheme")


@pytest.mark.parametrize("scheme", SCHEMES)
def test_mac_shearing_waves_converge(scheme):
    """Out-of-plane and in-plane shearing waves (exact linear solutions) through two
    re-mappings: second-order convergence in space (16^3 -> 32^3 error ratio > 4), error
    below 0.5 % at 32^3; the contravariant divergence stays at the round-off of the
    projection except right after a re-mapping (O(DX^2), corrected by the next step).
    Each step ends with the original's metric spectral projection (oblique.MetricProjector,
    as the SPM step applies it).  Measured (2026-12, the original's schemes, out-of-plane /
    in-plane): explicit 16: 3.8 / 3.8 %, 32: 0.27 / 0.89 %; implicit 16: 3.8 / 2.9 %, 32:
    0.24 / 0.70 % (before, with kapsel-py's own B-grid projection: 16: 3.8 / 4.4 %, 32:
    0.27 / 0.25 %, alike for implicit)."""
    from kapsel.fluid.oblique import MetricProjector
    shear, nu, dt = ShearFlow("DC", 0.1), 0.1, 0.05
    for inplane in (False, True):
        errs = []
        for n in (16, 32):
            g = Grid((n, n, 4))
            m = ObliqueMAC(Grid(g.shape, 1.0), 1.0, nu, dt, shear, scheme=scheme)
            sole = MetricProjector(g, m)
            u = shearing_wave(g, shear, nu, 0.0, m=(1, -1), inplane=inplane)
            for _ in range(300):
                m.step(u)
                sole(u)
            assert m.remap_count == 2
            ex = shearing_wave(g, shear, nu, m.time, m=(1, -1), inplane=inplane,
                               frame=m.frame_strain)
            errs.append(np.abs(u - ex).max() / np.abs(ex).max())
        assert errs[1] < 1e-2 and errs[0] / errs[1] > 4, errs


@pytest.mark.parametrize("eq", [LE_FDM, LE_CH])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_pure_fluid_zero_deviation_and_stress(tmp_path, eq, scheme):
    """Without particles and with a uniform composition the deviation stays exactly zero
    through re-mappings and sigma_xy = ETA gamma_dot (rel 1e-12), DC and AC."""
    for kind in ("DC", "AC"):
        inp = fdm_input(tmp_path / kind, eq=eq, ns=scheme, kind=kind, rate=0.5, freq=0.05)
        m = build(inp)
        if m.psi is not None:
            m.psi[...] = 0.3                 # one phase: no capillary force
            m.ch.psi_old = None
        rates = []
        for _ in range(40):
            rates.append(m.mac.shear.rate(m.time))
            m.advance()
        assert m.mac.remap_count >= 1
        assert np.abs(m.u).max() == 0.0
        rec = m.shear_record()
        # the field stress uses the frame's rate after each step: that of the step's
        # strain increment, gamma_dot at the step's start (the original's Shear_rate_eff)
        ends = [m.mac.shear.rate(k * m.dt) for k in range(40)]
        assert rec["Shear_stress"] == pytest.approx(m.cfg.fluid.ETA * np.mean(ends),
                                                    rel=1e-12, abs=1e-15)


def layers(shape, width=1.5):
    """psi of two flat interfaces parallel to the flow (normal along y) at Ly/4, 3Ly/4."""
    ny = shape[1]
    y = np.arange(ny, dtype=float)[None, :, None]
    psi = np.tanh((y - ny / 4) / width) * np.tanh((3 * ny / 4 - y) / width)
    return np.broadcast_to(psi, shape).copy()


# the time step the two interface tests were set up with (1 / pi^2; the automatic dt of a
# 16^3 mesh is 0.060): their step counts reach the re-mappings at that dt
MEASURED_DT = 1 / np.pi ** 2


@pytest.mark.parametrize("ch", SCHEMES)
def test_flat_interface_under_shear(tmp_path, ch):
    """Two-component fluid under shear with flat interfaces parallel to the flow: psi is
    conserved to 1e-8 (relative to sum |psi|), the interfaces stay flat (no x dependence)
    through re-mappings, and evolve exactly as without shear (the shear does not act on
    them)."""
    runs = []
    for rate in (0.2, 0.0):
        inp = fdm_input(tmp_path / str(rate), eq=LE_CH, ns="implicit_scheme", ch=ch,
                        rate=rate, dt=MEASURED_DT)
        m = build(inp)
        m.psi[...] = layers(m.shape)
        m.ch.psi_old = None
        total0 = float(m.psi.sum())
        scale = float(np.abs(m.psi).sum())
        for _ in range(80):
            m.advance()
        assert abs(float(m.psi.sum()) - total0) < 1e-8 * scale
        assert np.abs(m.psi - m.psi.mean(axis=(0, 2), keepdims=True)).max() < 1e-10
        runs.append((m.psi.copy(), m.mac.remap_count))
    assert runs[0][1] >= 1
    assert np.abs(runs[0][0] - runs[1][0]).max() < 1e-9


def test_tilted_interface_mass_conservation(tmp_path):
    """A random initial composition under shear with explicit NS and explicit CH: the mean of
    psi holds to 1e-8 relative through re-mappings (the row shifts are permutations)."""
    inp = fdm_input(tmp_path, eq=LE_CH, ns="explicit_scheme", ch="explicit_scheme",
                    rate=0.1, dt=MEASURED_DT)
    m = build(inp)
    total0 = float(m.psi.sum())
    scale = float(np.abs(m.psi).sum())
    for _ in range(60):
        m.advance()
    assert m.mac.remap_count >= 1
    assert abs(float(m.psi.sum()) - total0) < 1e-8 * scale


def test_viscosity_contrast_layers_harmonic_mean(tmp_path):
    """Flat layers of ETA_A = 2 and ETA_B = 0.5 of equal thickness sheared by the
    Lees-Edwards boundaries: at steady state the stress is gamma_dot / <1/eta>, the harmonic
    mean (0.93 for these diffuse layers; sharp ones 0.8; arithmetic mean 1.25), within 3 %.
    """
    inp = fdm_input(tmp_path, eq=LE_CH, ns="implicit_scheme", ch="implicit_scheme",
                    rate=0.01, viscosity=(2.0, 0.5))
    m = build(inp)
    m.psi[...] = layers(m.shape)
    m.ch.psi_old = None
    m._update_viscosity()
    for _ in range(400):
        m.advance()
    m.shear_record()
    for _ in range(100):
        m.advance()
    rec = m.shear_record()
    inv = float(np.mean(1.0 / m.eta_field))
    assert rec["Shear_stress"] / 0.01 == pytest.approx(1.0 / inv, rel=0.03)
    assert abs(1.0 / inv - 0.8) < 0.15


@pytest.mark.parametrize("scheme", SCHEMES)
def test_sphere_rotates_in_fdm_shear(tmp_path, scheme):
    """A free sphere at the shear origin in the FDM Lees-Edwards type spins at
    -gamma_dot / 2 within 5 % and hardly translates."""
    inp = fdm_input(tmp_path, ns=scheme, particles=1, rate=0.02)
    m = build(inp)
    p = m.particles
    p.R[0] = [8.3, 8.0, 8.0]
    p.R_raw[:] = p.R
    p.v[:] = 0.0
    m.u[...] = 0.0
    m.spm.refresh()
    m.spm.impose_particle_velocity()
    for _ in range(300):
        m.advance()
    assert p.omega[0, 2] / -0.01 == pytest.approx(1.0, abs=0.05)
    assert np.abs(p.v[0]).max() < 0.03 * 0.02 * 3


def test_ch_type_end_to_end_rectangular_fields(tmp_path):
    """The command writes records (PSI), HDF5 fields in the rectangular frame and the
    shear log; the restart carries oblique.degree_oblique."""
    import h5py
    from udf import UDFManager
    inp = fdm_input(tmp_path, eq=LE_CH, ns="explicit_scheme", ch="implicit_scheme",
                    particles=2, gts=4, nsnap=2, rate=0.05)
    assert shear_cli(tmp_path, inp) == 0
    u = UDFManager(str(tmp_path / "output.udf"))
    assert u.totalRecord() == 3
    with h5py.File(tmp_path / "velocity_2.h5") as f:
        ux = f["UX"][...]
    # the imposed flow is in the rectangular field: mean u_x over x, z grows with y
    prof = ux.mean(axis=(0, 2))      # (NZ, NY, NX) -> along y
    assert prof[-1] - prof[0] == pytest.approx(0.05 * 15, rel=0.05)
    assert os.path.exists(tmp_path / "orderparam_2.h5")
    log = np.loadtxt(tmp_path / "shear_stress.dat")
    assert log.shape == (3, 5) and np.all(np.isfinite(log))
    r = UDFManager(str(tmp_path / "restart.udf"))
    g = r.get("resume.CONTINUE_FDM_PHASE_SEPARATION.Saved_Data.oblique.degree_oblique")
    # the restart holds the step after the last snapshot, as the original's (§6.3)
    assert g == pytest.approx(0.05 * 9 * m_dt(tmp_path), abs=1e-6)


def m_dt(d):
    return build(os.path.join(d, "input.udf")).dt


@pytest.mark.parametrize("method", ["linear", "spline"])
def test_non_square_box_remap_interpolates(method):
    """NX < NY: a re-mapping shifts rows by s (j - y0) = (j - 16) / 2 points, half-integers
    for odd j: interpolated along x per OBL_INT.  An out-of-plane shearing wave through two
    re-mappings stays within 2 % (spline) / 6 % (linear) of the exact solution at 16 x 32,
    spline closer than linear.  Measured: spline 0.096 %, linear 2.4 % (at 32 x 32, where the
    shifts are integers: 7.4e-6 for both, the discretisation error)."""
    shear, nu, dt = ShearFlow("DC", 0.1), 0.05, 0.05
    g = Grid((16, 32, 4))
    m = ObliqueMAC(Grid(g.shape, 1.0), 1.0, nu, dt, shear, interpolation=method)
    u = shearing_wave(g, shear, nu, 0.0, m=(1, 1))
    for _ in range(220):                 # strain 1.1: re-mapped at 0.25, 0.75
        m.step(u)
    assert m.remap_count == 2
    ex = shearing_wave(g, shear, nu, m.time, m=(1, 1), frame=m.frame_strain)
    err = np.abs(u - ex).max() / np.abs(ex).max()
    assert err < (0.02 if method == "spline" else 0.06), err
    test_non_square_box_remap_interpolates.errors[method] = err
    if len(test_non_square_box_remap_interpolates.errors) == 2:
        e = test_non_square_box_remap_interpolates.errors
        assert e["spline"] < e["linear"]


test_non_square_box_remap_interpolates.errors = {}


# ---- the z term of the Cahn-Hilliard potential in the oblique frame -----------------------
def _spectral_div_coef_grad(c, f, g, dx):
    """div(c grad f) by exact (spectral) derivatives of periodic fields on the oblique grid:
    d_x = d_1, d_y = d_2 - g d_1, d_z = d_3."""
    k = [2 * np.pi * np.fft.fftfreq(n, d=dx) for n in c.shape]

    def d(a, ax):
        shape = [1, 1, 1]
        shape[ax] = -1
        return np.real(np.fft.ifft(1j * k[ax].reshape(shape) * np.fft.fft(a, axis=ax), axis=ax))

    def cart(a):
        return [d(a, 0), d(a, 1) - g * d(a, 0), d(a, 2)]
    gf = cart(f)
    return sum(cart(c * gf[a])[a] for a in range(3))


def test_oblique_z_term_converges_to_the_continuum_operator():
    """The z term's div(phi_s grad psi) in the oblique frame (the original's form phi lap psi +
    grad phi . grad psi, metric Laplacian and physical gradient) at frame strain 0.3 against
    exact derivatives of smooth periodic fields: second order (error ratio about 4 from 16^3
    to 32^3 in the same box)."""
    from kapsel.phase.oblique import ObliqueCahnHilliard
    L, g, errs = 8.0, 0.3, []
    for n in (16, 32):
        dx = L / n
        x = np.arange(n) * dx
        X, Y, Z = np.meshgrid(x, x, x, indexing="ij")       # oblique grid coordinates
        w = 2 * np.pi / L
        c = 0.5 + 0.3 * np.sin(w * X) * np.cos(w * Y) + 0.1 * np.cos(w * Z)
        f = np.cos(w * (X + 2 * Y)) + 0.5 * np.sin(w * Z) * np.cos(w * X)
        och = ObliqueCahnHilliard()
        och.dx, och.frame = dx, (lambda: g)
        got = och._div_coef_grad(c, f)
        ref = _spectral_div_coef_grad(c, f, g, dx)
        errs.append(np.abs(got - ref).max() / np.abs(ref).max())
    assert errs[1] < 0.02 and 3.3 < errs[0] / errs[1] < 4.7, errs


def test_z_term_runs_in_the_sheared_ch_type(tmp_path):
    """Shear_NS_LE_CH_FDM takes z (the original reads z for both potentials there; the
    sample's define.udf lacks the item, so z is set in the configuration): with z = 0.05 and
    two particles the chemical potential holds the z term (it differs from z = 0 where phi
    varies, and only there) and psi is conserved to 1e-10 through 20 sheared steps."""
    import dataclasses
    from types import SimpleNamespace

    from kapsel import config, models  # noqa: F401
    from kapsel.typespec import SOLVERS
    inp = fdm_input(tmp_path, eq=LE_CH, ch="implicit_scheme", particles=2, rate=0.05)
    cfg = config.load(inp)
    cfg = dataclasses.replace(cfg, phase=dataclasses.replace(cfg.phase, z=0.05))
    m = SOLVERS[LE_CH](cfg, SimpleNamespace(seed=3, quiet=True, threads=1), None)
    assert m.ch.z == 0.05
    total0, scale = float(m.psi.sum()), float(np.abs(m.psi).sum())
    for _ in range(20):
        m.advance()
    assert abs(float(m.psi.sum()) - total0) < 1e-10 * scale
    mu = m.ch.chemical_potential(m.psi, m.phi)
    m.ch.z = 0.0
    mu0 = m.ch.chemical_potential(m.psi, m.phi)
    diff = np.abs(mu - mu0)
    assert diff.max() > 1e-3 * np.abs(mu0).max()
    from scipy.ndimage import maximum_filter
    far = maximum_filter(m.phi, size=3, mode="wrap") < 1e-12     # phi = 0 on the stencil
    assert far.any() and diff[far].max() < 1e-12      # only where the solids' profile varies


def _phi_star_reference(m, xp):
    """The original's Make_phi_s_OBL by brute force: positions xp wrapped by PBC_OBL_half
    with the mid-step strain gt, on every rectangular grid point the profile of each
    particle and of its images across y displaced by the frame's own degree_oblique g0
    (Relative_coord_check_stepover_Y), min(sum, 1), then to the oblique grid (A2a_oblique,
    linear)."""
    from kapsel.mesh.regrid import to_oblique
    from kapsel.particles.profile import g as profile
    mac, spm = m.mac, m.spm
    L = spm.box
    g0, gt = mac.frame_strain, mac.mid_step_strain(mac.time)
    xp = np.array(xp, dtype=float)
    n = np.floor(xp[:, 1] / L[1])
    xp[:, 1] -= n * L[1]
    xp[:, 0] = np.mod(xp[:, 0] - n * gt * L[1], L[0])
    xp[:, 2] = np.mod(xp[:, 2], L[2])
    X = np.stack(np.meshgrid(*[np.arange(s) * m.dx for s in m.shape], indexing="ij"))
    phi = np.zeros(m.shape)
    for c in xp:
        for ny in (-1, 0, 1):
            im = c + ny * np.array([g0 * L[1], L[1], 0.0])
            d = X - im[:, None, None, None]
            for a in (0, 2):
                d[a] -= np.round(d[a] / L[a]) * L[a]
            r = np.sqrt((d * d).sum(axis=0))
            phi += profile(r, spm.stencil.A, spm.stencil.xi, m.dx)
    return to_oblique(np.minimum(phi, 1.0), g0, "linear", mac.y0 / m.dx)


def test_implicit_step_phi_star_and_frame(tmp_path):
    """The implicit oblique step's capillary force (fdm.cxx NS_solver_slavedEuler_Shear_OBL
    _implicit): phi* is the profile at the extrapolated positions R^n + (R^n - R^(n-1)) / 2
    on the rectangular grid (Make_phi_s_OBL: wrapped with gt, images with degree_oblique,
    A2a_oblique), also for a position extrapolated across the y boundary; mu and the force
    take the frame of the step's middle gt (Calc_cp_OBL / Cp2stress_OBL with gt): the
    contravariant force in the MAC's frame g0 is that of the frame gt."""
    inp = fdm_input(tmp_path, eq=LE_CH, ns="implicit_scheme", ch="implicit_scheme",
                    particles=2, rate=0.5)
    m = build(inp)
    assert m.spm.rect
    p = m.particles
    p.R[:] = [[4.3, 13.6, 8.2], [11.7, 5.1, 7.6]]
    p.R_raw[:] = p.R
    p.v[:] = [[0.4, 0.3, -0.2], [-0.3, 0.1, 0.2]]
    p.v_old[:] = p.v
    m.spm.refresh()
    m.phi = m.spm.phi()
    for _ in range(2):
        R0 = p.R_raw.copy()
        m.advance()
    dR = p.R_raw - R0
    assert np.abs(dR).max() > 1e-3
    got = m._extrapolated_phi()
    ref = _phi_star_reference(m, p.R + 0.5 * dR)
    assert np.abs(ref - m.phi).max() > 1e-3          # phi^n is not phi*
    assert np.abs(got - ref).max() < 1e-12
    np.testing.assert_allclose(m._dR, dR, rtol=0, atol=1e-15)
    # extrapolated across the top y boundary (by 0.7): wrapped with gt
    m._dR = np.array([[0.2, 2 * (16.0 - p.R[0, 1]) + 1.4, 0.0], [0.0, 0.0, 0.0]])
    xp = p.R + 0.5 * m._dR
    assert xp[0, 1] > 16.0
    got = m._extrapolated_phi()
    assert np.abs(got - _phi_star_reference(m, xp)).max() < 1e-12
    # a particle that crossed the bottom y boundary in the last step: phi* is drawn half a
    # step on from where it is (the unwrapped displacement), not half a box away as the
    # original's (3 x - x_previous) / 2 of the wrapped positions would put it
    p.R[0] = p.R_raw[0] = [4.3, 0.3, 8.2]
    m.spm.refresh()
    m._dR = np.array([[0.0, 0.6, 0.0], [0.0, 0.0, 0.0]])
    got = m._extrapolated_phi()
    assert np.abs(got - _phi_star_reference(m, p.R + 0.5 * m._dR)).max() < 1e-12
    wrapped_prev = p.R - m._dR
    wrapped_prev[0, 1] += 16.0                           # x_previous, wrapped: y = 15.7
    far = _phi_star_reference(m, (3 * p.R - wrapped_prev) / 2)
    assert np.abs(got - far).max() > 0.5
    # the frame of mu and of the force
    mac, ch = m.mac, m.ch
    g0, gt = mac.frame_strain, mac.mid_step_strain(mac.time)
    assert gt == pytest.approx(g0 + 0.5 * 0.5 * m.dt, abs=1e-14)
    psi_s = 1.5 * m.psi - 0.5 * ch.psi_old
    phi_s = m._extrapolated_phi()
    raw = m._capillary_force()
    frame = ch.frame
    ch.frame = lambda: gt
    try:
        F = ch.capillary_force(psi_s, ch.chemical_potential(psi_s, phi_s), m.rho)
    finally:
        ch.frame = frame
    assert np.abs(F).max() > 0
    np.testing.assert_allclose(raw[0] - g0 * raw[1], F[0] - gt * F[1], rtol=0,
                               atol=1e-14 * np.abs(F).max())
    np.testing.assert_allclose(raw[1:], F[1:], rtol=0, atol=0)
