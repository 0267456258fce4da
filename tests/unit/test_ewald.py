"""Periodic dipolar Ewald sum (kapsel/particles/ewald.py): the bare law in a large box, the
simple cubic lattice in tin-foil, forces and fields as derivatives of the energy."""
import numpy as np
import pytest

from kapsel.particles import ewald as ew


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _random(n, box, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 1, (n, 3)) * box, rng.normal(size=(n, 3))


def test_pair_in_a_large_box_follows_the_bare_law():
    box = np.array([120.0, 110.0, 130.0])
    R = np.array([[40.0, 50.0, 60.0], [43.1, 49.2, 61.3]])
    mu = np.array([[0.2, -0.4, 1.0], [0.7, 0.1, -0.5]])
    U, F, E = ew.dipolar_ewald(R, mu, box, ew.choose_parameters(box, 2, 1e-10))
    U0, F0, E0 = ew.bare_dipole_pair(R[0] - R[1], mu[0], mu[1])
    assert abs(U - U0) < 0.01 * abs(U0)
    assert np.linalg.norm(F[0] - F0) < 0.01 * np.linalg.norm(F0)
    assert np.linalg.norm(F[1] + F0) < 0.01 * np.linalg.norm(F0)
    assert np.linalg.norm(E[0] - E0) < 0.01 * np.linalg.norm(E0)


@pytest.mark.parametrize("n", [1, 2, 3])
@pytest.mark.parametrize("direction", [(0, 0, 1.3), (0.6, -0.8, 0.4)])
def test_simple_cubic_lattice_in_tin_foil(n, direction):
    """Parallel dipoles on a simple cubic lattice of spacing a: in a spherical sample in
    vacuum the local field vanishes (the Lorentz cavity field 4 pi P / 3 cancels the
    depolarising field; the near-field lattice sum is 0 by cubic symmetry: Lorentz; de Leeuw,
    Perram & Smith 1980), so U/N = 0 with eps' = 1 and, removing the surface term
    2 pi |M|^2 / 3V, U/N = -(2 pi / 3) mu^2 / a^3 in tin-foil, where the field at every
    dipole is the Lorentz field E = (4 pi / 3) mu / a^3 (U = -1/2 sum mu.E)."""
    a = 1.7
    mu0 = np.array(direction)
    g = np.arange(n) * a
    R = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) + [0.1, 0.3, 0.2]
    mu = np.tile(mu0, (len(R), 1))
    box = np.full(3, n * a)
    p = ew.choose_parameters(box, len(R), 1e-8)
    U, F, E = ew.dipolar_ewald(R, mu, box, p)
    m2 = mu0 @ mu0
    exact = -(2 * np.pi / 3) * m2 / a ** 3
    assert abs(U / len(R) - exact) < 1e-6 * abs(exact)
    assert np.max(np.abs(F)) < 1e-6 * m2 / a ** 4
    np.testing.assert_allclose(E, np.tile(4 * np.pi / 3 * mu0 / a ** 3, (len(R), 1)),
                               rtol=0, atol=1e-6 * np.linalg.norm(mu0) / a ** 3)
    # vacuum boundary (eps' = 1): the lattice energy vanishes
    Uv, _, Ev = ew.dipolar_ewald(R, mu, box, p, epsilon_surface=1.0)
    assert abs(Uv / len(R)) < 1e-6 * abs(exact)
    assert np.max(np.abs(Ev)) < 1e-6 * np.linalg.norm(mu0) / a ** 3


def _minus_gradients(energy, R, mu, rows, h=1e-5):
    """(-dU/dR, -dU/dmu) of ``energy(R, mu)`` by central differences, for the given rows
    (zero elsewhere)."""
    Fn, En = np.zeros_like(R), np.zeros_like(R)
    for i in rows:
        for c in range(3):
            for arr, out in ((R, Fn), (mu, En)):
                plus, minus = arr.copy(), arr.copy()
                plus[i, c] += h
                minus[i, c] -= h
                args_p = (plus, mu) if arr is R else (R, plus)
                args_m = (minus, mu) if arr is R else (R, minus)
                out[i, c] = -(energy(*args_p) - energy(*args_m)) / (2 * h)
    return Fn, En


@pytest.mark.parametrize("eps", [np.inf, 1.0])
def test_force_is_minus_gradient_and_field_is_minus_mu_derivative(eps):
    box = np.array([9.0, 10.0, 11.0])
    R, mu = _random(12, box, 3)
    p = ew.choose_parameters(box, len(R), 1e-12)
    U, F, E = ew.dipolar_ewald(R, mu, box, p, eps)
    Fn, En = _minus_gradients(lambda r, m: ew.dipolar_ewald(r, m, box, p, eps)[0], R, mu,
                              range(len(R)))
    np.testing.assert_allclose(F, Fn, atol=1e-6 * _rms(F))
    np.testing.assert_allclose(E, En, atol=1e-6 * _rms(E))
    assert np.allclose(F.sum(axis=0), 0, atol=1e-10 * _rms(F))


def test_torque_is_mu_cross_field():
    """T = mu x E is minus the derivative of U under a rotation of one dipole."""
    from kapsel.particles.quaternion import from_axis_angle, rotate
    box = np.array([8.0, 8.0, 8.0])
    R, mu = _random(6, box, 5)
    p = ew.choose_parameters(box, len(R), 1e-12)
    _, _, E = ew.dipolar_ewald(R, mu, box, p)
    T = np.cross(mu, E)
    h = 1e-5
    for i in range(len(R)):
        for c in range(3):
            axis = np.eye(3)[c]
            Us = []
            for sgn in (1, -1):
                m = mu.copy()
                m[i] = rotate(from_axis_angle(axis, sgn * h)[None], m[i][None])[0]
                Us.append(ew.dipolar_ewald(R, m, box, p)[0])
            assert abs(T[i, c] + (Us[0] - Us[1]) / (2 * h)) < 1e-6 * _rms(T)


@pytest.mark.parametrize("tol", [1e-6, 1e-8, 1e-10])
def test_stated_accuracy(tol):
    """Energy, field and force errors against a sum converged to 1e-15 stay below tol
    (relative to |U|, the RMS field and the RMS force)."""
    box = np.array([30.0, 20.0, 25.0])
    for n in (20, 200):
        R, mu = _random(n, box, n)
        U0, F0, E0 = ew.dipolar_ewald(R, mu, box, ew.choose_parameters(box, n, 1e-15))
        U, F, E = ew.dipolar_ewald(R, mu, box, ew.choose_parameters(box, n, tol))
        assert abs(U - U0) < tol * abs(U0)
        assert _rms(E - E0) < tol * _rms(E0)
        assert _rms(F - F0) < tol * _rms(F0)


def test_split_balances_real_and_reciprocal_work():
    """alpha = sqrt(pi) (c N/V^2)^(1/6): real-space pairs per particle (from both ends) are
    1/c of the k vectors per particle (one of each +-k), and both grow as N^(1/2) at fixed
    density, so the whole sum costs N^1.5."""
    counts = []
    for n in (1000, 8000):
        L = (n / 0.05) ** (1 / 3)
        box = np.full(3, L)
        p = ew.choose_parameters(box, n, 1e-8)
        pairs_per = 0.05 * 4 / 3 * np.pi * p.r_cut ** 3
        k_per = len(ew.reciprocal_vectors(box, p.k_cut))
        assert pairs_per * ew.COST_RATIO / k_per == pytest.approx(2.0, rel=0.15)
        counts.append(k_per)
    assert counts[1] / counts[0] == pytest.approx(np.sqrt(8), rel=0.1)


def test_original_parameters_give_a_tolerance():
    # ex12: alpha 8, delta 1e-16, converge 0.51
    tol = ew.tolerance_from_original(8.0, 1e-16, 0.51)
    assert tol == pytest.approx(max(np.exp(-16), 1e-16 ** 0.51))


def test_spherical_direct_sum_converges_to_the_vacuum_ewald_energy():
    """Brute force: the bare pair law summed over periodic images inside a growing sphere
    (radius 80 for a 3 x 4 x 5 cell of 3 random dipoles) approaches the Ewald energy with the
    vacuum surface term, U_tinfoil + 2 pi |M|^2 / 3V (de Leeuw, Perram & Smith 1980);
    measured relative differences 1.1e-3, 3.9e-4, 6.0e-5 at radius 20, 40, 80."""
    box = np.array([3.0, 4.0, 5.0])
    rng = np.random.default_rng(2)
    R, mu = rng.uniform(0, 1, (3, 3)) * box, rng.normal(size=(3, 3))
    M = mu.sum(axis=0)
    U_tf = ew.dipolar_ewald(R, mu, box, ew.choose_parameters(box, 3, 1e-14))[0]
    U_vac = U_tf + 2 * np.pi / (3 * np.prod(box)) * (M @ M)
    assert ew.dipolar_ewald(R, mu, box, ew.choose_parameters(box, 3, 1e-14), 1.0)[0] == \
        pytest.approx(U_vac, rel=1e-12)
    rmax = 80.0
    nm = np.ceil(rmax / box).astype(int)
    n = np.stack(np.meshgrid(*[np.arange(-m, m + 1) for m in nm], indexing="ij"), -1)
    S = n.reshape(-1, 3) * box
    S = S[np.linalg.norm(S, axis=1) <= rmax]
    U = 0.0
    for i in range(3):
        for j in range(3):
            d = R[i] - R[j] + S
            if i == j:
                d = d[np.any(S != 0, axis=1)]
            r = np.linalg.norm(d, axis=1)
            U += 0.5 * np.sum(mu[i] @ mu[j] / r ** 3 - 3 * (d @ mu[i]) * (d @ mu[j]) / r ** 5)
    assert abs(U - U_vac) < 2e-4 * abs(U_vac)


# ---- the Lees-Edwards (sheared) lattice ---------------------------------------------------
def _sheared_config():
    box = np.array([9.0, 10.0, 11.0])
    R, mu = _random(10, box, 7)
    return box, R, mu


def test_sheared_lattice_independent_of_the_split():
    """On the sheared lattice (strain 0.37: images across y = Ly shifted by 3.7 along x) the
    converged sum does not depend on alpha: a wrong image set or reciprocal lattice would make
    the real and reciprocal parts disagree.  Two splits (alpha x1 and x1.6) agree to 1e-9."""
    box, R, mu = _sheared_config()
    p = ew.choose_parameters(box, len(R), 1e-13)
    q = ew.EwaldParameters(alpha=1.6 * p.alpha, r_cut=p.r_cut / 1.6, k_cut=1.6 * p.k_cut)
    U1, F1, E1 = ew.dipolar_ewald(R, mu, box, p, strain=0.37)
    U2, F2, E2 = ew.dipolar_ewald(R, mu, box, q, strain=0.37)
    assert abs(U1 - U2) < 1e-9 * abs(U1)
    assert _rms(F1 - F2) < 1e-9 * _rms(F1) and _rms(E1 - E2) < 1e-9 * _rms(E1)
    U0 = ew.dipolar_ewald(R, mu, box, p)[0]
    assert abs(U1 - U0) > 1e-3 * abs(U0)            # the shear does change the sum


def test_sheared_lattice_periodic_in_the_strain_and_unsheared_at_zero():
    """Strain g and g + Lx/Ly give the same lattice (the x shift g Ly taken modulo Lx); a
    strain of a whole period equals the unsheared sum; -x mirror symmetry: strain -g on the
    mirrored configuration gives the same energy."""
    box, R, mu = _sheared_config()
    p = ew.choose_parameters(box, len(R), 1e-12)
    U0 = ew.dipolar_ewald(R, mu, box, p)[0]
    Up = ew.dipolar_ewald(R, mu, box, p, strain=box[0] / box[1])[0]
    assert abs(Up - U0) < 1e-10 * abs(U0)
    Ug = ew.dipolar_ewald(R, mu, box, p, strain=0.21)[0]
    Ug2 = ew.dipolar_ewald(R, mu, box, p, strain=0.21 + box[0] / box[1])[0]
    assert abs(Ug - Ug2) < 1e-10 * abs(Ug)
    Rm, mum = R * [-1, 1, 1], mu * [-1, 1, 1]          # x -> -x maps strain g to -g
    Um = ew.dipolar_ewald(Rm, mum, box, p, strain=-0.21)[0]
    assert abs(Um - Ug) < 1e-10 * abs(Ug)


def test_sheared_lattice_forces_fields_and_the_bare_law():
    """On the sheared lattice the force is -dU/dR and the field -dU/dmu (finite differences),
    and a close pair in a large sheared box follows the bare law within 1 %."""
    box, R, mu = _sheared_config()
    p = ew.choose_parameters(box, len(R), 1e-12)
    g = 0.37
    U, F, E = ew.dipolar_ewald(R, mu, box, p, strain=g)
    rows = [0, 4]
    Fn, En = _minus_gradients(lambda r, m: ew.dipolar_ewald(r, m, box, p, strain=g)[0], R, mu,
                              rows)
    assert np.abs(F[rows] - Fn[rows]).max() < 1e-6 * _rms(F)
    assert np.abs(E[rows] - En[rows]).max() < 1e-6 * _rms(E)
    big = np.array([120.0, 110.0, 130.0])
    R2 = np.array([[40.0, 108.0, 60.0], [10.1, 1.2, 61.3]])    # close across y = Ly: 10.1 + 33
    mu2 = np.array([[0.2, -0.4, 1.0], [0.7, 0.1, -0.5]])
    shift = 0.3 * big[1]
    U, F, E = ew.dipolar_ewald(R2, mu2, big, ew.choose_parameters(big, 2, 1e-10), strain=0.3)
    r = R2[0] - (R2[1] + [shift, big[1], 0.0])             # the nearest image of particle 1
    r[0] -= big[0] * np.round(r[0] / big[0])
    U0, F0, E0 = ew.bare_dipole_pair(r, mu2[0], mu2[1])
    assert abs(U - U0) < 0.01 * abs(U0)
    assert np.linalg.norm(F[0] - F0) < 0.01 * np.linalg.norm(F0)
    assert np.linalg.norm(E[0] - E0) < 0.01 * np.linalg.norm(E0)


@pytest.mark.parametrize("strain, mirror", [(0.0, None), (0.0, 2.5), (0.3, None)])
def test_owned_sum_of_two_ranks_is_the_serial_sum(strain, mirror):
    """The distributed Ewald sum (kapsel.particles.dipoles ``dipole_forces_owned``) of two
    "ranks" splitting a 64 x 32 x 32 box at x = 32 (in the oblique coordinate x - g y of a
    sheared lattice, as kapsel.particles.ownership), each with its owned particles and the
    ghosts within r_cut (1 + |g|) of its half (a proper subset), the structure sums and total
    moment of the owned particles added over the ranks: forces and torques of every particle
    as the serial sum, to round-off (mirror images, Lees-Edwards lattice included)."""
    from kapsel.particles import dipoles as dp
    box = np.array([64.0, 32.0, 32.0])
    L = box[0]
    n = 16
    R = _random(n, box, 3)[0]
    R[:, 2] = 4.0 + 0.75 * R[:, 2]                 # above the electrode plane z = 2.5
    q = np.random.default_rng(4).normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    quincke = dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 50.0)
    dip = dp.Dipoles("QUINCKE", 6.0, pz_factor=3.0, mirror_z=mirror, epsilon_surface=2.0)
    s = ew.splitting_s(1e-10)
    params = ew.EwaldParameters(alpha=s / 8.0, r_cut=8.0, k_cut=2 * s * s / 8.0)
    F0, T0 = dp.dipole_forces(R, q, box, dip, quincke, params, strain=strain)
    xo = np.mod(R[:, 0] - strain * R[:, 1], L)
    halves = [xo < L / 2, xo >= L / 2]

    def table(h):
        x0 = 0.0 if h == 0 else L / 2
        d = np.mod(xo - x0, L)                # distance from the half [x0, x0 + L/2)
        dist = np.minimum(np.where(d < L / 2, 0.0, d - L / 2), L - d)
        ghost = ~halves[h] & (dist < params.r_cut * (1 + abs(strain)))
        rows = np.concatenate([np.flatnonzero(halves[h]), np.flatnonzero(ghost)])
        return rows, int(np.count_nonzero(halves[h]))
    parts = [[], []]                          # what each rank hands to the reduction
    for h in (0, 1):
        rows, k = table(h)
        assert len(rows) < n
        dp.dipole_forces_owned(R[rows], q[rows], k, box, dip, quincke, params,
                               lambda a, h=h: parts[h].append(np.array(a)) or a,
                               strain=strain)
    totals = [a + b for a, b in zip(*parts)]
    F, T = np.zeros_like(F0), np.zeros_like(T0)
    for h in (0, 1):
        rows, k = table(h)
        it = iter(totals)
        Fh, Th = dp.dipole_forces_owned(R[rows], q[rows], k, box, dip, quincke, params,
                                        lambda a: next(it), strain=strain)
        F[rows[:k]], T[rows[:k]] = Fh, Th
    np.testing.assert_allclose(F, F0, rtol=0, atol=1e-12 * np.abs(F0).max())
    np.testing.assert_allclose(T, T0, rtol=0, atol=1e-12 * np.abs(T0).max())
