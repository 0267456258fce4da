"""Cahn-Hilliard solver (manual eqs 16-19, 30-31): linear spinodal growth of both schemes
against the discrete dispersion relation, the Landau tanh interface, conservation with
advection and particles, mu = dF/dpsi by finite differences, BiCGSTAB failure, helpers."""
import math

import numpy as np
import pytest

from kapsel.config import PhaseField
from kapsel.mesh.grid import Grid
from kapsel.phase import CahnHilliard, FloryHuggins, Landau, capillary_force, chemical_potential, free_energy
from kapsel.errors import SolverDidNotConverge, UnstableTimeStep


def params(scheme="explicit_scheme", potential="Landau", tol=1e-12, maxit=1000, **kw):
    d = dict(ch_solver=scheme, tolerance=tol, maximum_iteration=maxit, potential=potential,
             composition_ratio=0.0, initial_fluctuation=0.0, d=0.0, w=0.0, alpha=1.0,
             kappa=1.0, a=1.0, b=1.0)
    if potential == "Flory_Huggins":
        d.update(composition_ratio=0.5, na=5.0, nb=5.0, chi=0.5)
    d.update(kw)
    return PhaseField(**d)


def sphere(shape, centre, A, xi, dx=1.0):
    """KAPSEL smooth profile (manual eqs 1-3) of one periodic sphere."""
    x = np.indices(shape) * dx
    L = np.array(shape) * dx
    r2 = 0.0
    for i in range(3):
        s = x[i] - centre[i]
        s -= L[i] * np.round(s / L[i])
        r2 = r2 + s * s
    r = np.sqrt(r2)

    def h(s):
        out = np.zeros_like(s)
        m = s > 0
        out[m] = np.exp(-dx ** 2 / s[m] ** 2)
        return out
    a, b = h(A + xi / 2 - r), h(r - (A - xi / 2))
    return a / (a + b)


def shear_wave(shape, dx=1.0):
    """Divergence-free (in any discretisation) velocity: u_a depends only on another axis."""
    x = np.indices(shape) * dx
    L = np.array(shape) * dx
    u = np.zeros((3,) + shape)
    u[0] = 0.3 * np.sin(2 * np.pi * x[1] / L[1])
    u[1] = 0.2 * np.cos(2 * np.pi * x[2] / L[2])
    u[2] = 0.25 * np.sin(2 * np.pi * x[0] / L[0])
    return u


# ---------------------------------------------------------------------- linear growth
SHAPE = (32, 16, 8)
DX = 0.8


def mode(m):
    x = np.indices(SHAPE) * DX
    k = [2 * np.pi * m[i] / (SHAPE[i] * DX) for i in range(3)]
    c = np.cos(sum(k[i] * x[i] for i in range(3)))
    K2 = sum((2 / DX) ** 2 * math.sin(k[i] * DX / 2) ** 2 for i in range(3))
    return c, K2


def amplitude(psi, c):
    return 2.0 * float(np.mean((psi - psi.mean()) * c))


CASES = [("Landau", 0.0, {}), ("Landau", 0.3, dict(composition_ratio=0.3)),
         ("Flory_Huggins", 0.5, dict(chi=0.6)), ("Flory_Huggins", 0.42, dict(na=4.0, nb=7.0, chi=0.6))]


@pytest.mark.parametrize("pot,psi0,kw", CASES)
@pytest.mark.parametrize("m", [(2, 1, 0), (3, 2, 2)])
def test_explicit_linear_growth(pot, psi0, kw, m):
    """One Euler step multiplies the mode by 1 + dt omega, omega = -kappa K^2 (f'' + alpha K^2)
    with the discrete K^2 = sum (2/DX)^2 sin^2(k DX/2)."""
    p = params("explicit_scheme", pot, alpha=0.7, kappa=1.3, **kw)
    c, K2 = mode(m)
    eps, dt = 1e-8, 0.004
    ch = CahnHilliard(Grid(SHAPE, DX), p, dt)
    fpp = float(ch.potential.d2f(psi0))
    psi = psi0 + eps * c
    ch.step(psi)
    G = 1.0 + dt * ch.growth_rate(K2, fpp)
    assert G == pytest.approx(float(ch.amplification(K2, fpp)), rel=1e-15)
    assert amplitude(psi, c) / eps == pytest.approx(G, rel=1e-6)
    np.testing.assert_array_equal(ch.psi_old, psi0 + eps * c)


@pytest.mark.parametrize("pot,psi0,kw", CASES)
def test_bdf2_linear_growth(pot, psi0, kw):
    """Implicit scheme on a growing mode.  Linearised eq 31 with li = -kappa alpha K^4
    (implicit) and le = -kappa K^2 f''(psi0) (Adams-Bashforth 2 f'^n - f'^{n-1}):
        (3/2 - dt li) A^{n+1} = (2 + 2 dt le) A^n - (1/2 + dt le) A^{n-1},
    first step implicit Euler: A^1 = (1 + dt le) / (1 - dt li) A^0.  The amplitudes follow
    this recurrence; its ratio tends to the dominant root G of
        (3/2 - dt li) G^2 - (2 + 2 dt le) G + (1/2 + dt le) = 0."""
    p = params("implicit_scheme", pot, alpha=0.7, kappa=1.3, **kw)
    m = (1, 1, 0) if pot == "Flory_Huggins" else (2, 1, 0)
    c, K2 = mode(m)
    eps, dt = 1e-8, 0.8
    ch = CahnHilliard(Grid(SHAPE, DX), p, dt)
    fpp = float(ch.potential.d2f(psi0))
    assert ch.growth_rate(K2, fpp) > 0                       # spinodal mode
    le, li = -p.kappa * K2 * fpp, -p.kappa * p.alpha * K2 * K2
    ref = [eps, (1 + dt * le) / (1 - dt * li) * eps]
    steps = 12
    for _ in range(steps - 1):
        ref.append(((2 + 2 * dt * le) * ref[-1] - (0.5 + dt * le) * ref[-2]) / (1.5 - dt * li))
    psi = psi0 + eps * c
    got = [eps]
    for _ in range(steps):
        ch.step(psi)
        got.append(amplitude(psi, c))
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=0)
    roots = ch.amplification(K2, fpp)
    G = roots[np.argmax(np.abs(roots))]
    assert abs(G.imag) == 0 and G.real > 1
    A, B, C = 1.5 - dt * li, -(2 + 2 * dt * le), 0.5 + dt * le
    assert A * G.real ** 2 + B * G.real + C == pytest.approx(0, abs=1e-13)
    sub = float(np.min(np.abs(roots)))
    # the ratio converges to G like (sub/G)^n
    assert got[-1] / got[-2] == pytest.approx(G.real, rel=5 * (sub / G.real) ** (steps - 1))


# ---------------------------------------------------------------------- flat interface
def test_landau_flat_interface():
    """Two flat interfaces relax to sqrt(b/a) tanh(x / (sqrt 2 w)), w = sqrt(alpha/b)."""
    W, a, b = 3.0, 1.3, 0.8
    p = params("implicit_scheme", tol=1e-10, alpha=W * W * b, a=a, b=b)
    shape = (64, 4, 4)
    x = np.arange(shape[0], dtype=float)
    dist = 16.0 - np.abs(x - 32.0)          # signed distance to the interfaces at 16 and 48
    s = math.sqrt(2.0) * W
    ps = math.sqrt(b / a)
    psi = np.empty(shape)
    psi[...] = (ps * np.tanh(dist / (2 * s)))[:, None, None]     # twice too wide
    ch = CahnHilliard(Grid(shape, 1.0), p, dt=4.0)
    assert ch.dt < ch.stable_dt()                # BDF2/AB2 linear limit with f''(+-sqrt(b/a))
    assert ch.potential.equilibrium() == pytest.approx((-ps, ps), rel=1e-15)
    err0 = np.abs(psi[:, 0, 0] - ps * np.tanh(dist / s)).max() / ps
    for _ in range(150):
        ch.step(psi)
    err = np.abs(psi[:, 0, 0] - ps * np.tanh(dist / s)).max() / ps
    assert err0 > 0.2
    assert err < 0.01
    assert np.abs(psi - psi[:, :1, :1]).max() == 0.0
    mu = ch.chemical_potential(psi)
    assert np.abs(mu).max() < 1e-3 * b * ps


# ---------------------------------------------------------------------- conservation
@pytest.mark.parametrize("scheme,dt", [("explicit_scheme", 0.005), ("implicit_scheme", 0.1)])
@pytest.mark.parametrize("pot", ["Landau", "Flory_Huggins"])
def test_conservation_advection(scheme, dt, pot):
    shape = (16, 12, 10)
    kw = dict(composition_ratio=0.1) if pot == "Landau" else {}
    p = params(scheme, pot, tol=1e-9, initial_fluctuation=0.05, **kw)
    ch = CahnHilliard(Grid(shape, 1.0), p, dt)
    psi = ch.initial_field()
    u = shear_wave(shape)
    m0 = psi.sum()
    start = psi.copy()
    for _ in range(15):
        ch.step(psi, u)
    assert np.abs(psi - start).max() > 1e-3            # the field did evolve
    assert abs(psi.sum() - m0) <= 1e-13 * abs(m0)      # round-off


@pytest.mark.parametrize("scheme,dt", [("explicit_scheme", 0.005), ("implicit_scheme", 0.1)])
@pytest.mark.parametrize("pot", ["Landau", "Flory_Huggins"])
def test_conservation_with_particle(scheme, dt, pot):
    shape = (16, 16, 12)
    kw = dict(composition_ratio=0.1, w=-1.0) if pot == "Landau" else dict(
        composition_ratio=0.45, w=-0.1)
    p = params(scheme, pot, tol=1e-9, initial_fluctuation=0.05, d=1.0, **kw)
    ch = CahnHilliard(Grid(shape, 1.0), p, dt, xi=2.0)
    phi = sphere(shape, (7.3, 8.1, 5.6), 4.0, 2.0)
    psi = ch.initial_field()
    u = shear_wave(shape)
    m0 = psi.sum()
    for _ in range(15):
        ch.step(psi, u, phi)
    inside = phi > 0.99
    assert abs(psi[inside].mean() - ch.psi_bar) < abs(p.composition_ratio - ch.psi_bar)
    assert abs(psi.sum() - m0) <= 1e-8 * abs(m0)
    assert abs(psi.sum() - m0) <= 1e-13 * abs(m0)      # in fact round-off


# ---------------------------------------------------------------------- mu = dF/dpsi
@pytest.mark.parametrize("pot", ["Landau", "Flory_Huggins"])
def test_chemical_potential_is_free_energy_derivative(pot):
    shape, dx, xi = (7, 6, 5), 0.7, 1.5
    rng = np.random.default_rng(7)
    if pot == "Landau":
        p = params(potential=pot, a=1.2, b=0.7, alpha=0.9, d=0.6, w=-0.8)
        psi = rng.uniform(-1, 1, shape)
    else:
        p = params(potential=pot, na=3.0, nb=6.0, chi=0.9, alpha=0.9, d=0.6, w=-0.4)
        psi = rng.uniform(0.15, 0.85, shape)
    phi = sphere(shape, (2.1, 2.2, 1.7), 1.2, xi, dx)
    mu = chemical_potential(psi, phi, p, dx=dx, xi=xi)
    h = 1e-5
    for idx in [(0, 0, 0), (3, 2, 1), (6, 5, 4), (1, 4, 2), (2, 3, 1)]:
        e = np.zeros(shape)
        e[idx] = h
        num = (free_energy(psi + e, phi, p, dx=dx, xi=xi)
               - free_energy(psi - e, phi, p, dx=dx, xi=xi)) / (2 * h * dx ** 3)
        assert mu[idx] == pytest.approx(num, rel=1e-7, abs=1e-8)
    # the particle terms do act: w xi |grad phi|^2 and 2 d (psi - psi_bar) phi
    bare = chemical_potential(psi, None, p, dx=dx, xi=xi)
    assert np.abs(mu - bare).max() > 0.1


def test_potentials():
    L = Landau(1.5, 0.6)
    FH = FloryHuggins(4.0, 7.0, 0.6)
    for pot, pts in ((L, np.linspace(-1.4, 1.4, 9)), (FH, np.linspace(0.05, 0.95, 9))):
        h = 1e-6
        np.testing.assert_allclose(pot.df(pts), (pot.f(pts + h) - pot.f(pts - h)) / (2 * h),
                                   rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(pot.d2f(pts), (pot.df(pts + h) - pot.df(pts - h)) / (2 * h),
                                   rtol=1e-7, atol=1e-8)
    assert L.equilibrium() == pytest.approx((-math.sqrt(0.4), math.sqrt(0.4)))
    assert FH.critical == pytest.approx(math.sqrt(7) / (math.sqrt(4) + math.sqrt(7)))
    assert FH.psi_bar == 0.5          # the original's neutral value, whatever NA, NB
    lo, hi = FH.equilibrium()                     # common tangent
    assert FH.df(lo) == pytest.approx(FH.df(hi), abs=1e-12)
    assert FH.f(hi) - FH.f(lo) == pytest.approx(FH.df(lo) * (hi - lo), abs=1e-12)
    s1, s2 = FH.spinodal()
    assert lo < s1 < s2 < hi and abs(FH.d2f(s1)) < 1e-12
    sym = FloryHuggins(5.0, 5.0, 0.5)
    lo, hi = sym.equilibrium()
    assert lo + hi == pytest.approx(1.0, abs=1e-12) and sym.df(lo) == pytest.approx(0, abs=1e-12)
    # logarithm guard: finite outside (0, 1)
    out = FH.df(np.array([-0.1, 0.0, 1.0, 1.1]))
    assert np.all(np.isfinite(out)) and out[0] < 0 < out[-1]
    assert np.all(np.isfinite(FH.f(np.array([0.0, 1.0]))))


# ---------------------------------------------------------------------- solver failure
def test_bicgstab_non_convergence_raises():
    shape = (8, 8, 8)
    p = params("implicit_scheme", tol=1e-14, maxit=2, initial_fluctuation=0.3)
    ch = CahnHilliard(Grid(shape, 1.0), p, dt=5.0)
    psi = ch.initial_field()
    with pytest.raises(SolverDidNotConverge) as exc:
        ch.step(psi, shear_wave(shape))
    assert exc.value.iterations == 2 and exc.value.residual > 1e-14
    assert "Cahn-Hilliard" in str(exc.value)


# ---------------------------------------------------------------------- helpers
def test_explicit_stability_limit():
    """Largest |1 + dt omega| over the mesh modes, f'' frozen at psi0: just below the limit the
    highest mode decays, just above it grows; check_stability refuses dt above it."""
    shape, psi0 = (8, 8, 8), 0.8
    p = params("explicit_scheme", alpha=0.5, kappa=0.7)
    probe = CahnHilliard(Grid(shape, 1.0), p, 1.0)
    fpp = 3 * psi0 ** 2 - 1
    lim = probe.stable_dt(np.full(shape, psi0))
    assert lim == pytest.approx(2 / (0.7 * 12 * (fpp + 0.5 * 12)), rel=1e-14)
    c = np.cos(np.pi * np.indices(shape).sum(axis=0))           # K^2 = 12
    for f, grows in ((0.98, False), (1.02, True)):
        ch = CahnHilliard(Grid(shape, 1.0), p, f * lim)
        psi = psi0 + 1e-6 * c
        for _ in range(20):
            ch.step(psi)
        assert (amplitude(psi, c) > 1e-6) == grows
    with pytest.raises(UnstableTimeStep):
        CahnHilliard(Grid(shape, 1.0), p, 1.02 * lim).check_stability(np.full(shape, psi0))
    assert CahnHilliard(Grid(shape, 1.0), p, 0.98 * lim).check_stability(
        np.full(shape, psi0)) == pytest.approx(lim)


def test_capillary_force_and_initial_field():
    shape, dx = (16, 8, 4), 0.5
    x = np.indices(shape) * dx
    k = 2 * np.pi / (8 * dx)
    mu = np.sin(k * x[1])
    psi = 0.3 + 0.1 * np.cos(2 * np.pi * x[0] / (16 * dx))
    F = capillary_force(psi, mu, 2.0, dx)
    assert F.shape == (3,) + shape
    np.testing.assert_allclose(F[1], -(psi / 2.0) * np.sin(k * dx) / dx * np.cos(k * x[1]),
                               atol=1e-14)
    assert np.abs(F[0]).max() == 0 and np.abs(F[2]).max() == 0
    p = params(potential="Flory_Huggins", composition_ratio=0.4, initial_fluctuation=0.05)
    ch = CahnHilliard(Grid(shape, dx), p, 0.01)
    a = ch.initial_field()
    np.testing.assert_array_equal(a, ch.initial_field())
    assert a.min() >= 0.35 and a.max() <= 0.45 and abs(a.mean() - 0.4) < 0.01
    np.testing.assert_allclose(ch.capillary_force(psi, mu, 2.0), F)


def test_initial_field_is_the_originals():
    """The original's draw (kapsel.phase.fluctuation): the first nodes of its psi for
    composition_ratio 0, initial_fluctuation 0.05 (read from the PSI_OLD of a one-step run
    of the original, 32^3, the nodes away from its particle), bit for bit; inside a
    particle psi is value (1 - phi) (Landau), value (1 - phi) + 0.5 phi (Flory-Huggins)."""
    from kapsel.phase.fluctuation import original_uniform
    first = original_uniform(3, -0.05, 0.05)
    assert first.tolist() == [0.039015471328273793, -0.036929270594465186,
                              -0.046024050349744064]
    shape = (4, 3, 2)
    phi = np.linspace(0.0, 1.0, 24).reshape(shape)
    u = original_uniform(24, 0.4 - 0.05, 0.4 + 0.05).reshape(shape)
    for pot, want in (("Landau", u * (1 - phi)), ("Flory_Huggins", u * (1 - phi) + 0.5 * phi)):
        p = params(potential=pot, composition_ratio=0.4, initial_fluctuation=0.05)
        np.testing.assert_array_equal(CahnHilliard(Grid(shape, 1.0), p, 0.01).initial_field(phi),
                                      want)


def test_restart_from_psi_old():
    """psi_old (PSI_OLD) is all the BDF2 state: a new solver fed psi and psi_old continues
    the run exactly."""
    shape = (12, 10, 8)
    p = params("implicit_scheme", tol=1e-12, initial_fluctuation=0.1)
    a = CahnHilliard(Grid(shape, 1.0), p, 0.3)
    psi = a.initial_field()
    u = shear_wave(shape)
    for _ in range(3):
        a.step(psi, u)
    b = CahnHilliard(Grid(shape, 1.0), p, 0.3)
    b.psi_old = a.psi_old.copy()
    other = psi.copy()
    a.step(psi, u)
    b.step(other, u)
    np.testing.assert_array_equal(psi, other)


@pytest.mark.parametrize("pc", ["jacobi", "fft"])
def test_preconditioners_agree(pc):
    shape = (12, 10, 8)
    p = params("implicit_scheme", tol=1e-12, initial_fluctuation=0.1, d=1.0, w=-1.0)
    phi = sphere(shape, (5.0, 5.0, 4.0), 3.0, 2.0)
    u = shear_wave(shape)
    ref = CahnHilliard(Grid(shape, 1.0), p, 0.5, xi=2.0)
    psi = ref.initial_field()
    other = psi.copy()
    alt = CahnHilliard(Grid(shape, 1.0), p, 0.5, xi=2.0, preconditioner=pc)
    for _ in range(3):
        ref.step(psi, u, phi)
        alt.step(other, u, phi)
    np.testing.assert_allclose(other, psi, rtol=0, atol=1e-9)


def test_implicit_z_term_takes_the_interface_width():
    """The original's implicit scheme scales z by xi = sqrt(alpha / 2b) (its ps.xi), its
    chemical potential does not: mu is the same for both schemes, the implicit step's z
    term is xi times as strong (an implicit solver with z behaves as one with z xi whose mu
    keeps z)."""
    shape = (10, 10, 10)
    phi = sphere(shape, (5.0, 5.0, 5.0), 3.0, 2.0)
    kw = dict(tol=1e-13, initial_fluctuation=0.1, d=1.0, alpha=1.0, b=2.0)
    imp = CahnHilliard(Grid(shape, 1.0), params("implicit_scheme", z=-0.2, **kw), 0.05, xi=2.0)
    exp_ = CahnHilliard(Grid(shape, 1.0), params("explicit_scheme", z=-0.2, **kw), 0.05, xi=2.0)
    assert imp.z_width == pytest.approx(0.5) and exp_.z_width == 1.0
    psi = imp.initial_field()
    np.testing.assert_array_equal(imp.chemical_potential(psi, phi),
                                  exp_.chemical_potential(psi, phi))
    half = CahnHilliard(Grid(shape, 1.0), params("implicit_scheme", z=-0.1, **kw), 0.05, xi=2.0)
    half.z_width = 1.0
    a, b = psi.copy(), psi.copy()
    imp.step(a, None, phi)
    half.step(b, None, phi)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    c = psi.copy()
    zero = CahnHilliard(Grid(shape, 1.0), params("implicit_scheme", z=0.0, **kw), 0.05, xi=2.0)
    zero.step(c, None, phi)
    assert np.abs(c - a).max() > 1e-6           # z does act
