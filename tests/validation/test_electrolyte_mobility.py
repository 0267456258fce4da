"""Electrophoretic mobility of a weakly charged sphere against Henry's function (issue 16).

What is compared (the slow test's docstring has the numbers):

* Henry's mobility in Ohshima's (1994) closed form, mu = 2 eps zeta f(kappa a) / (3 eta),
  f(x) = 1 + 1 / (2 (1 + 2.5 / (x (1 + 2 exp(-x))))^3), units of the model: e = 1,
  eps = Dielectric_cst, Bjerrum length e^2 / (4 pi eps kBT), kappa = 1 / Debye_length.
* zeta: the Debye-Hueckel potential of the surface charge, zeta = Z e / (4 pi eps a
  (1 + kappa a)) (Henry's own low-potential relation), not a measured surface potential:
  the smeared SPM charge |phi'| lies half outside r = A, so the equilibrium potential at
  r = A is 0.8-0.9 of zeta_DH, while the whole charge moves with the particle (its force
  acts on it) as if it sat on the surface.
* a: the SPM sphere's hydrodynamic radius a_h, calibrated in the same box at the same dt
  from the Hasimoto drag of a sphere under a constant force (the SPM's radius depends on
  nu dt / xi^2: a_h = 3.93 for A = 4, L = 32, dt = 0.0715); kappa a = a_h / lambda_D.
* The periodic correction C = U_periodic / U_isolated of Henry's linear problem with the
  undisturbed field: a translating sphere is a shell of uniform traction (its Stokeslet
  shell, form factor S(k) = sin(ka)/(ka)), pushed by Z E; the Debye-Hueckel cloud
  outside it, charge density -Z kappa^2 exp(-kappa (r - a)) / (4 pi r (1 + kappa a)), pushes
  the fluid by -Z E in all.  By Faxen's law the sphere moves at the shell average of the
  flow of both, U = int d^3k/(2 pi)^3 (2/3) S(k) F(k) / (eta k^2) with F(k) the Fourier
  transform of the force density (isolated: exactly Z E / (6 pi eta a (1 + kappa a)),
  Hueckel's 2 eps zeta E / (3 eta)); in the periodic box with zero mean velocity
  (FIX_CELL) the integral becomes (1 / L^3) sum over k != 0 (Hasimoto 1959).  The net
  force of sphere and cloud is zero, so F(k) ~ k^2 at small k and the correction is
  small: C ~ 1 - (2/3) 6 pi a (1 + kappa a) (lambda_D^2 + ...) / L^3 (0.88 for kappa a =
  0.5, A = 4, L = 32; 0.98 for kappa a = 3), and it tends to Hasimoto's
  1 - 1.7601 phi^(1/3) as kappa -> 0 (the cloud spreads into the uniform background).
  Two boxes: kappa a = 0.5 (A = 4, lambda_D = 8) gives v / v_Henry(A) = 0.892 on 32^3
  (C = 0.876) and 0.991 at t = 250 on 64^3 (C = 0.981; bench/electrophoresis.py, 12 min):
  1.018 and 1.010 after C.
  Resolution: the thin layer's ratio falls towards 1 as lambda_D grows in grid units:
  kappa a = 3 with A = 8, lambda_D = 8/3 on 64^3 (29 min, not a test) gives 1.004 with
  a = A (1.085 on 32^3 with a = A; kappa a = 4 with lambda_D = 1 on 32^3: 1.12).
  The field's distortion by the insulating sphere (f - 1 of Henry's function) is a dipole
  field decaying as r^-3: its periodic correction is O(phi) (0.8 % here), not applied.
"""
import time

import numpy as np
import pytest
from scipy import integrate


def henry_f(ka):
    """Ohshima's (1994) closed form of Henry's function."""
    return 1.0 + 1.0 / (2.0 * (1.0 + 2.5 / (ka * (1.0 + 2.0 * np.exp(-ka)))) ** 3)


def henry_velocity(Z, a, debye, E, eps=1.0, eta=1.0):
    """2 eps zeta f(kappa a) E / (3 eta) with zeta = Z / (4 pi eps a (1 + kappa a))."""
    ka = a / debye
    zeta = Z / (4.0 * np.pi * eps * a * (1.0 + ka))
    return 2.0 * eps * zeta * henry_f(ka) * E / (3.0 * eta)


def _shell(k, a):
    return np.sinc(k * a / np.pi)


def _force(k, a, kappa):
    """F(k) / (Z E): the sphere's shell minus its Debye-Hueckel cloud."""
    cloud = (kappa ** 2 / (k ** 2 + kappa ** 2)
             * (np.cos(k * a) + kappa / k * np.sin(k * a)) / (1.0 + kappa * a))
    return _shell(k, a) - cloud


def _kernel(k, a, kappa):
    return (2.0 / 3.0) * _shell(k, a) * _force(k, a, kappa) / k ** 2


def isolated_velocity(a, kappa, K=np.inf):
    """int_{|k| < K} d^3k / (2 pi)^3 (2/3) S F / k^2, eta = Z E = 1."""
    pts = None
    if np.isfinite(K):
        pts = np.arange(np.pi / a, K, np.pi / a)
    g = lambda k: _kernel(k, a, kappa) * k ** 2 / (2.0 * np.pi ** 2)
    return integrate.quad(g, 1e-12, K, limit=5000, points=pts)[0]


def periodic_velocity(a, kappa, L, K):
    """(1 / L^3) sum_{0 < |k| < K} (2/3) S F / k^2 over the box's wave vectors."""
    n = int(K * L / (2.0 * np.pi)) + 1
    m = np.arange(-n, n + 1)
    kx, ky, kz = np.meshgrid(m, m, m, indexing="ij", sparse=True)
    k = 2.0 * np.pi / L * np.sqrt(kx ** 2 + ky ** 2 + kz ** 2)
    k = k[(k > 0) & (k < K)]
    return float(np.sum(_kernel(k, a, kappa))) / L ** 3


def periodic_correction(a, debye, L, K=6.0):
    """C = U_periodic / U_isolated (module docstring); sum and integral cut at the same
    |k| < K (their difference converges long before either does)."""
    kappa = 1.0 / debye
    iso = 1.0 / (6.0 * np.pi * a * (1.0 + kappa * a))
    return 1.0 + (periodic_velocity(a, kappa, L, K) - isolated_velocity(a, kappa, K)) / iso


def hasimoto_K(a, L):
    c = 4.0 / 3.0 * np.pi * a ** 3 / L ** 3
    return 1.0 / (1 - 1.7601 * c ** (1 / 3) + c - 1.5593 * c ** 2 + 3.9799 * c ** (8 / 3)
                  - 3.0734 * c ** (10 / 3))


def hydrodynamic_radius(ratio, A, L):
    """a_h with F / (6 pi eta a_h K(a_h)) = ratio F / (6 pi eta A K(A))."""
    from scipy.optimize import brentq
    return brentq(lambda a: 1.0 / (a * hasimoto_K(a, L)) - ratio / (A * hasimoto_K(A, L)),
                  0.5 * A, 1.5 * A)


# ---------------------------------------------------------------------------- fast checks
def test_isolated_linear_problem_gives_hueckel():
    """The undisturbed-field linear problem of an isolated sphere gives exactly
    Z E / (6 pi eta a (1 + kappa a)) = 2 eps zeta E / (3 eta), for thick and thin layers."""
    K = 100.0          # the tail beyond K: (2/3) <S^2> / (2 pi^2) / K = 1 / (6 pi^2 a^2 K)
    for a, debye in ((4.0, 8.0), (4.0, 4 / 3), (8.0, 1.0)):
        u = isolated_velocity(a, 1.0 / debye, K) + 1.0 / (6 * np.pi ** 2 * a ** 2 * K)
        assert u * 6 * np.pi * a * (1 + a / debye) == pytest.approx(1.0, abs=1e-4)


def test_periodic_correction_limits():
    """kappa -> 0: the cloud is the uniform background and C is Hasimoto's leading terms
    1 - 1.7601 phi^(1/3) + phi; kappa L large: C -> 1; the same geometry scaled keeps C."""
    L, a = 32.0, 4.0
    phi = 4 / 3 * np.pi * a ** 3 / L ** 3
    assert periodic_correction(a, 1e6, L) == pytest.approx(
        1 - 1.7601 * phi ** (1 / 3), abs=0.01)
    assert periodic_correction(a, 0.5, L) == pytest.approx(1.0, abs=0.02)
    assert periodic_correction(4.0, 8.0, 32.0) == pytest.approx(
        periodic_correction(8.0, 16.0, 64.0), abs=1e-3)
    assert 0.86 < periodic_correction(4.0, 8.0, 32.0) < 0.89      # kappa a = 0.5


def test_henry_function_limits():
    assert henry_f(1e-6) == pytest.approx(1.0, abs=1e-6)
    assert henry_f(1e6) == pytest.approx(1.5, abs=1e-4)
    assert henry_f(1.0) == pytest.approx(1.027, rel=0.01)   # Henry: 1.027; Ohshima: < 1 %


# ---------------------------------------------------------------------------- slow test
def electrophoresis(N, A, debye, Z, E, T, tmp):
    """Velocity along E of one sphere (salt 1:1, Poisson-Boltzmann start, DC field,
    FIX_CELL on) at t = T and at t = T - 20."""
    from builders import electrolyte_input, model_of
    from udf import UDFManager
    npx = int(round(np.log2(N)))
    p = electrolyte_input(tmp, npx=npx, particles=[[N / 2, N / 2, N / 2]], salt=True, field="DC",
                   init="Poisson_Boltzmann", charge=Z, debye=debye, A=A)
    u = UDFManager(p)
    u.put(E, "constitutive_eq.Electrolyte.Electric_field.ON.DC.Ex")
    u.write(p)
    m = model_of(p)
    assert all(m.cfg.switches.fix_cell)
    steps = int(round(T / m.dt))
    back = int(round(20.0 / m.dt))
    v_before = None
    for i in range(steps):
        m.advance()
        if i == steps - back - 1:
            v_before = m.particles.v[0, 0]
    return m.particles.v[0, 0], v_before, m.dt


@pytest.mark.slow
def test_mobility_follows_henry(tmp_path):
    """One sphere, A = 4, XI = 2, in a 1:1 salt on 32^3, E = 0.01 along x (the input's
    auto dt = 0.0715, FIX_CELL on), kappa a = 0.5 (lambda_D = 8, Z = -10,
    zeta = -0.13 kBT/e) and kappa a = 3 (lambda_D = 4/3, Z = -30, zeta = -0.15 kBT/e):
    the steady velocity over Henry's (a = a_h from the Hasimoto drag in the same box and
    dt, zeta from Z, times the periodic correction C; module docstring) within 10 %.
    Measured (h16, 2-core machine at load 10, 390 s): a_h = 3.931 (V / V_Hasimoto(A) =
    1.0266); kappa a_h = 0.491: v / (C v_Henry) = 0.991 (C = 0.879; v / v_Henry(A), no C,
    0.892); kappa a_h = 2.948: 1.055 (C = 0.982; uncorrected 1.066).  Linear regime
    (kappa a = 3, t = 90): E = 0.02 gives 1.062, Z = -15 gives 1.055 against 1.066 of the
    uncorrected ratio.  Steady: v changes by < 1 % over the last 20 time units (the
    slowest viscous mode decays in L^2 / (4 pi^2 nu) = 26, the thick cloud in
    lambda_D^2 / D = 64).  About 7 min."""
    from builders import terminal_velocity
    t0 = time.perf_counter()
    N, A, E = 32, 4.0, 0.01
    out = []
    for debye, Z, T in ((8.0, -10.0, 150.0), (4.0 / 3.0, -30.0, 100.0)):
        v, v_before, dt = electrophoresis(N, A, debye, Z, E, T, tmp_path / f"l{debye:.2f}")
        assert abs(v - v_before) < 0.01 * abs(v), (v, v_before)
        out.append((debye, Z, v, dt))
    ratio, _ = terminal_velocity(N, dt=out[0][3])
    a_h = hydrodynamic_radius(ratio[0], A, N)
    ratios = []
    for debye, Z, v, dt in out:
        C = periodic_correction(a_h, debye, N)
        ref = henry_velocity(Z, a_h, debye, E) * C
        print(f"\nkappa a_h = {a_h / debye:.3f} (a_h = {a_h:.3f}, V/V_Hasimoto(A) = "
              f"{ratio[0]:.4f}): v = {v:.5e}, Henry {henry_velocity(Z, a_h, debye, E):.5e}, "
              f"C = {C:.4f}, v / (C v_Henry) = {v / ref:.4f} "
              f"({time.perf_counter() - t0:.0f} s)")
        ratios.append(v / ref)
    for r in ratios:
        assert abs(r - 1) < 0.10, ratios
