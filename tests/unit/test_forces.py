"""Pair forces (eqs 9, 33, 34), neighbour pairs, gravity and thermal noise."""
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from kapsel.particles import forces as F
from kapsel.particles.cells import minimum_image, pairs_within
from kapsel.particles.noise import ThermalNoise
from kapsel.particles.placement import uniform_random

CASES = [(p, t) for p in ("12:6", "24:12", "36:18") for t in ("ON", "OFF")] + \
        [("macro_vdw", "OFF"), ("macro_vdw", "ON")]


def _config(seed, n=40, box=(20.0, 17.0, 23.0)):
    rng = np.random.default_rng(seed)
    radius = rng.uniform(1.5, 2.5, n)
    # non-overlapping hard cores at 0.9 sigma so the (steep) LJ forces stay moderate,
    # then squeezed so many pairs sit inside the interaction range
    R = uniform_random(n, 0.45 * radius / 0.5, np.array(box), rng)
    return R, radius, np.array(box)


def _energy(R, box, radius, p, t):
    return F.pair_forces(R, box, radius, p, 1.3, t)[1]


@pytest.mark.parametrize("powers,truncate", CASES)
def test_force_is_minus_gradient(powers, truncate):
    R, radius, box = _config(1)
    Fa, U, mr = F.pair_forces(R, box, radius, powers, 1.3, truncate)
    assert np.isfinite(mr) and mr > 0.85
    h = 1e-6
    Fn = np.zeros_like(R)
    for k in range(len(R)):
        for c in range(3):
            Rp, Rm = R.copy(), R.copy()
            Rp[k, c] += h
            Rm[k, c] -= h
            Fn[k, c] = -(_energy(Rp, box, radius, powers, truncate)
                         - _energy(Rm, box, radius, powers, truncate)) / (2 * h)
    scale = np.abs(Fa).max()
    assert scale > 0
    assert np.abs(Fa - Fn).max() <= 1e-6 * scale
    assert np.abs(Fa.sum(axis=0)).max() <= 1e-12 * max(1.0, scale)


def test_force_sum_and_pair_symmetry_large():
    rng = np.random.default_rng(5)
    box = np.array([30.0, 30.0, 30.0])
    R = rng.random((400, 3)) * box
    radius = np.full(400, 1.0)
    Fa, U, mr = F.pair_forces(R, box, radius, "12:6", 1.0, "OFF")
    assert np.abs(Fa.sum(axis=0)).max() <= 1e-12 * np.abs(Fa).max()


@pytest.mark.parametrize("powers", ["12:6", "24:12", "36:18", "macro_vdw"])
@pytest.mark.parametrize("truncate", ["ON", "OFF"])
def test_two_particles_inside_contact_repel(powers, truncate):
    box = np.array([32.0, 32.0, 32.0])
    R = np.array([[10.0, 10.0, 10.0], [10.0 + 0.95 * 5.0, 10.0, 10.0]])
    Fa, U, mr = F.pair_forces(R, box, [2.0, 3.0], powers, 1.0, truncate)
    assert Fa[1, 0] > 0 and Fa[0, 0] < 0
    assert Fa[0, 0] == -Fa[1, 0]
    assert mr == pytest.approx(0.95)


def test_pair_across_periodic_boundary():
    box = np.array([16.0, 16.0, 16.0])
    R = np.array([[0.2, 5.0, 5.0], [15.0, 5.0, 5.0]])   # distance 1.2 through x = 0
    Fa, _, mr = F.pair_forces(R, box, [0.6, 0.6], "12:6", 1.0, "ON")
    assert mr == pytest.approx(1.0)
    R[1, 0] = 15.1                                       # r = 1.1 < sigma -> push apart
    Fa, _, _ = F.pair_forces(R, box, [0.6, 0.6], "12:6", 1.0, "ON")
    assert Fa[0, 0] > 0 and Fa[1, 0] < 0


@pytest.mark.parametrize("powers,n", [("12:6", 6), ("24:12", 12), ("36:18", 18)])
def test_wca_zero_beyond_rmin(powers, n):
    sigma = 3.0
    rmin = 2.0 ** (1.0 / n) * sigma
    r = np.array([rmin * (1 - 1e-9), rmin, rmin * 1.01, 2 * sigma])
    f = F.pair_force_magnitude(r, sigma, powers, 1.0, "ON")
    V = F.pair_potential(r, sigma, powers, 1.0, "ON")
    assert np.all(f[1:] == 0) and np.all(V[1:] == 0)
    assert abs(f[0]) < 1e-6 and abs(V[0]) < 1e-12
    # OFF: full LJ with minimum -EPSILON at r_min, cut at 2.5 sigma
    assert F.pair_potential(rmin, sigma, powers, 1.0, "OFF") == pytest.approx(-1.0)
    assert F.pair_force_magnitude(2.49 * sigma, sigma, powers, 1.0, "OFF") < 0
    assert F.pair_force_magnitude(2.5 * sigma, sigma, powers, 1.0, "OFF") == 0
    assert np.all(F.pair_force_magnitude(r, sigma, powers, 1.0, "NONE") == 0)


def test_truncate_none_returns_zeros():
    R = np.array([[1.0, 1.0, 1.0], [1.5, 1.0, 1.0]])
    Fa, U, mr = F.pair_forces(R, (8, 8, 8), 1.0, "12:6", 1.0, "NONE")
    assert np.all(Fa == 0) and U == 0 and mr == np.inf


def test_macro_vdw_continuity_and_form():
    H, sigma, n = 2.0, 4.0, F.MACRO_VDW_N
    rc = n * sigma
    e = 1e-7 * sigma
    V = lambda r: F.pair_potential(np.asarray(r), sigma, "macro_vdw", H, "OFF")
    f = lambda r: F.pair_force_magnitude(np.asarray(r), sigma, "macro_vdw", H, "OFF")
    # value continuous: the jump across n sigma is only the slope term, O(e^2) left
    assert abs(V(rc + e) - V(rc - e) - (-f(rc)) * 2 * e) < 1e-11
    # slope continuous: the jump in -dV/dr is O(e) (curvature), not O(1)
    assert abs(f(rc + e) - f(rc - e)) < 1e-5 * abs(f(rc))
    # both closed forms of eq 34 evaluated exactly at r = n sigma
    c = H / (48 * (n - 1) ** 3)
    assert c * (n * n - 2 * n - (3 * n * n - 6 * n + 2)) == pytest.approx(-H / (24 * (n - 1)), rel=1e-12)
    assert c * (2 * n - 2) == pytest.approx(H / (24 * (n - 1) ** 2), rel=1e-12)
    assert V(rc) == pytest.approx(-H / (24 * (n - 1)), rel=1e-12)
    # outer branch is eq 33
    r = np.array([1.3, 1.8, 2.2]) * sigma
    assert np.allclose(V(r), -H * sigma / (24 * (r - sigma)))
    # minimum at contact, soft repulsion inside
    assert f(sigma) == pytest.approx(0, abs=1e-14)
    assert V(sigma) == pytest.approx(-H / (16 * (n - 1)))
    assert f(0.9 * sigma) > 0 and f(1.05 * sigma) < 0
    # ON: repulsive part only, shifted to 0 at contact
    assert F.pair_potential(sigma * 0.999999, sigma, "macro_vdw", H, "ON") == pytest.approx(0, abs=1e-9)
    assert F.pair_force_magnitude(1.01 * sigma, sigma, "macro_vdw", H, "ON") == 0
    assert F.pair_force_magnitude(0.9 * sigma, sigma, "macro_vdw", H, "ON") > 0


def test_gravity():
    a = np.array([2.0, 3.0])
    g = F.gravity_force(a, [1.5, 0.5], 1.0, 0.01, "-Y")
    mag = 0.01 * 4 / 3 * np.pi * a ** 3 * np.array([0.5, -0.5])
    assert np.allclose(g[:, 1], -mag) and np.all(g[:, [0, 2]] == 0)
    with pytest.raises(ValueError):
        F.gravity_force(a, 1.5, 1.0, 0.01, "-W")


def test_pairs_equal_brute_force_noncubic():
    rng = np.random.default_rng(3)
    box = np.array([20.0, 13.0, 31.0])
    R = rng.random((300, 3)) * box
    R[:5] -= box                                  # some outside [0, L): must be wrapped
    for rcut in (2.5, 6.0, 7.0):                  # 7 > 13/2: all-pairs fallback
        i, j, dr = pairs_within(R, box, rcut)
        ii, jj = np.triu_indices(300, 1)
        d = minimum_image(R[jj] - R[ii], box)
        keep = np.linalg.norm(d, axis=1) <= rcut
        assert np.array_equal(i, ii[keep]) and np.array_equal(j, jj[keep])
        assert np.allclose(dr, d[keep], atol=1e-12)
        assert np.all(i < j)


def _brute(R, box, rcut):
    W = np.mod(R, box)
    ii, jj = np.triu_indices(len(R), 1)
    d = minimum_image(W[jj] - W[ii], box)
    keep = np.einsum("ij,ij->i", d, d) <= rcut * rcut
    return ii[keep], jj[keep], d[keep]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1),
       box=st.tuples(*[st.floats(8.0, 40.0)] * 3),
       frac=st.floats(0.05, 0.45))
def test_pairs_all_methods_match_brute_force(seed, box, frac):
    box = np.array(box)
    rng = np.random.default_rng(seed)
    R = rng.random((300, 3)) * box * 1.5 - 0.25 * box        # partly outside [0, L)
    R[0] = box                                                # exactly on the far faces
    rcut = frac * box.min()
    bi, bj, bd = _brute(R, box, rcut)
    for method in ("auto", "cells", "kdtree", "brute"):
        i, j, dr = pairs_within(R, box, rcut, method)
        assert np.array_equal(i, bi) and np.array_equal(j, bj), method
        assert np.allclose(dr, bd, atol=1e-10), method


def test_pairs_three_cells_and_tiny_inputs():
    rng = np.random.default_rng(11)
    box = np.array([15.0, 30.0, 45.0])                          # exactly 3, 6, 9 cells of 5
    R = rng.random((500, 3)) * box
    bi, bj, bd = _brute(R, box, 4.99)
    for method in ("cells", "kdtree"):
        i, j, dr = pairs_within(R, box, 4.99, method)
        assert np.array_equal(i, bi) and np.array_equal(j, bj)
        assert np.allclose(dr, bd, atol=1e-12)
    for n in (0, 1):
        i, j, dr = pairs_within(np.zeros((n, 3)), box, 3.0)
        assert len(i) == len(j) == 0 and dr.shape == (0, 3)
    with pytest.raises(ValueError):
        pairs_within(R, box, 3.0, "octree")


def test_dVdr_and_deep_overlap_ratio():
    r = np.linspace(2.0, 3.3, 7)
    assert np.array_equal(F.pair_dVdr(r, 3.0, "24:12", 1.0, "ON"),
                          -F.pair_force_magnitude(r, 3.0, "24:12", 1.0, "ON"))
    R = np.array([[5.0, 5.0, 5.0], [5.0, 5.0, 6.0]])
    _, _, mr = F.pair_forces(R, (16, 16, 16), 1.5, "12:6", 1.0, "ON")
    assert mr == pytest.approx(1.0 / 3.0) and mr < F.DEEP_OVERLAP_RATIO


def test_noise_accepts_pcg64_generator():
    g = np.random.Generator(np.random.PCG64(42))
    a = ThermalNoise(g).impulses(3, 0.1, 1.0, 1, 1, 2.0, 3.0)
    b = ThermalNoise(42).impulses(3, 0.1, 1.0, 1, 1, 2.0, 3.0)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    with pytest.raises(ValueError, match="PCG64"):
        ThermalNoise(np.random.Generator(np.random.MT19937(1)))


def test_noise_variance_and_state():
    noise = ThermalNoise(7)
    n, dt, kBT = 20000, 0.05, 0.3
    a = np.full(n, 2.0)
    gv, go = 6 * np.pi * a, 8 * np.pi * a ** 3
    dP, dL = noise.impulses(n, dt, kBT, 1.2, 0.8, gv, go)
    for x, var in ((dP, 2 * kBT * 1.2 * gv[0] * dt), (dL, 2 * kBT * 0.8 * go[0] * dt)):
        s = x.var() / var
        assert abs(s - 1) < 5 * np.sqrt(2 / x.size)
        assert abs(x.mean()) < 5 * np.sqrt(var / x.size)
        c = np.mean(x[:, 0] * x[:, 1]) / var
        assert abs(c) < 5 / np.sqrt(n)
    # per-particle friction given as (n, 1) columns, as the model layer does
    st0 = noise.get_state()
    x1 = noise.impulses(4, dt, kBT, 1, 1, gv[:4, None], go[:4, None])
    noise.set_state(st0)
    x2 = noise.impulses(4, dt, kBT, 1, 1, gv[:4], go[:4])
    assert x1[0].shape == (4, 3) and np.array_equal(x1[0], x2[0]) and np.array_equal(x1[1], x2[1])
    # kBT = 0 draws nothing
    before = json.dumps(noise.get_state())
    z = noise.impulses(10, dt, 0.0, 1, 1, 1, 1)
    assert all(np.all(zz == 0) for zz in z)
    assert json.dumps(noise.get_state()) == before
    # exact restart through JSON
    st = json.loads(before)
    a1 = noise.impulses(5, dt, kBT, 1, 1, 1, 1)
    other = ThermalNoise(123)
    other.set_state(st)
    a2 = other.impulses(5, dt, kBT, 1, 1, 1, 1)
    assert np.array_equal(a1[0], a2[0]) and np.array_equal(a1[1], a2[1])


@pytest.mark.parametrize("powers,truncate", CASES)
def test_force_magnitude_is_minus_dV_dr(powers, truncate):
    sigma, h = 3.0, 1e-6
    rc = F.interaction_range(powers, truncate) * sigma
    r = np.linspace(0.88 * sigma, rc, 400)[1:-1]
    num = -(F.pair_potential(r + h, sigma, powers, 0.7, truncate)
            - F.pair_potential(r - h, sigma, powers, 0.7, truncate)) / (2 * h)
    f = F.pair_force_magnitude(r, sigma, powers, 0.7, truncate)
    far = np.abs(r - rc) > 2 * h
    assert np.allclose(f[far], num[far], rtol=1e-6, atol=1e-8 * np.abs(f).max())


def test_temperature_alphas_of_the_memory_langevin_prediction():
    """alpha = 1 / ratio; a heavier particle keeps more of its kicks (ratio -> 1 as
    MASS_RATIO grows, the fluid's share vanishing)."""
    from kapsel.particles.noise import kinetic_temperature_ratios, temperature_alphas
    rv, ro = kinetic_temperature_ratios(4.0)
    assert rv == pytest.approx(0.2063, abs=1e-3) and ro == pytest.approx(0.4602, abs=1e-3)
    av, ao = temperature_alphas(4.0)
    assert av * rv == pytest.approx(1.0) and ao * ro == pytest.approx(1.0)
    heavy = kinetic_temperature_ratios(4.0, mass_ratio=100.0)
    assert rv < heavy[0] < 1.0 and ro < heavy[1] < 1.0


def test_off_cutoff_stays_within_half_the_box():
    """LJ_truncate OFF: r_c = min(N_min DX / 2, 2.5 sigma), the original's A_R_cutoff
    (PHYSICS-EXTRA.md §5); 2.5 sigma without a box; ON / NONE keep theirs."""
    assert F.interaction_range("12:6", "OFF", 32.0, 8.0) == 2.0
    assert F.interaction_range("12:6", "OFF", 64.0, 8.0) == 2.5
    assert F.interaction_range("12:6", "OFF") == 2.5
    assert F.interaction_range("12:6", "ON", 32.0, 8.0) == 2.0 ** (1 / 6)
    assert F.interaction_range("macro_vdw", "OFF", 30.0, 8.0) == 30.0 / 16.0
    assert F.interaction_range("12:6", "NONE", 32.0, 8.0) == 0.0


def _sample_forces(R, box=32.0):
    import types
    from kapsel.models.common import make_forces
    from kapsel.particles.state import ParticleState
    inter = types.SimpleNamespace(LJ_truncate="OFF", EPSILON=5.0, LJ_powers="12:6", G=0.0,
                                  G_direction="-Z")
    cfg = types.SimpleNamespace(type="Navier_Stokes_Cahn_Hilliard_FDM", interactions=inter,
                                mesh=types.SimpleNamespace(box=np.array([box] * 3)),
                                particles=types.SimpleNamespace(
                                    object_type="spherical_particle", A=4.0, A_XI=2.0),
                                switches=types.SimpleNamespace(wall=None))
    n = len(R)
    p = ParticleState.spheres([0] * n, [4.0] * n, [1.0] * n, 1.0)
    p.R[:] = R
    return make_forces(cfg, p)(p)[0]


# the manual's sample (32^3, A 4, LJ 12:6 OFF, EPSILON 5) at step 11 of the original's run
_SAMPLE_R = np.array([[5.749, 26.136, 5.870], [18.709, 13.509, 0.811], [10.118, 1.960, 2.677],
                      [31.260, 31.301, 27.968], [1.698, 8.604, 2.953], [22.0, 3.5, 20.5],
                      [9.0, 20.0, 12.0], [14.0, 27.0, 19.0]])


def test_run_pair_forces_cut_at_half_the_box():
    """A run's LJ OFF pair force (make_forces) ends at half the 32 box (r_c = 2 sigma =
    16, not 2.5 sigma = 20): a pair 12 sqrt 2 = 16.97 apart feels nothing, one 10 sqrt 2 =
    14.14 apart the LJ force."""
    far = _sample_forces(np.array([[5.0, 5, 5], [17.0, 17, 5]]))
    assert np.all(far == 0.0)
    near = _sample_forces(np.array([[5.0, 5, 5], [15.0, 15, 5]]))
    f = F.pair_force_magnitude(10.0 * np.sqrt(2.0), 8.0, "12:6", 5.0, "OFF") / np.sqrt(2.0)
    assert near[1, :2] == pytest.approx([f, f]) and f != 0.0


def test_pair_forces_count_each_pair_once_in_a_small_box():
    """Each pair once at its minimum image, whatever cells the particles fall in: the
    sample's forces equal the sum over pairs and do not change when the whole configuration
    is translated (the original's link cells of 16 DX count a pair 2^m times in boxes under
    48 DX, m the axes along which the pair's cells differ, so its forces change under a
    translation; docs/physics-spm.md "Pair forces")."""
    R = _SAMPLE_R
    F0 = _sample_forces(R)
    ref = np.zeros_like(R)
    for i in range(len(R)):
        for j in range(len(R)):
            d = minimum_image(R[j] - R[i], np.array([32.0] * 3))
            r = np.linalg.norm(d)
            if i != j and r < 16.0:
                ref[j] += F.pair_force_magnitude(r, 8.0, "12:6", 5.0, "OFF") * d / r
    assert np.abs(F0 - ref).max() <= 1e-12 * np.abs(ref).max()
    for shift in ([8.0, 0, 0], [8.0, 8.0, 8.0], [3.3, 11.7, 5.1]):
        Fs = _sample_forces(np.mod(R + np.array(shift), 32.0))
        assert np.abs(Fs - F0).max() <= 1e-12 * np.abs(F0).max()
