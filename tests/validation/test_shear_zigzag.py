"""Shear_Navier_Stokes, the zigzag shear flow (kapsel.models.zigzag): the start-up from rest,
the two pinned planes and the profile they keep, the original's stress table, the start of
the particles, the density-weighted stress with particles, and the type end to end."""
import numpy as np
import pytest

from builders import build, shear_cli, shear_input


SNS = "constitutive_eq.Shear_Navier_Stokes"


def zigzag_input(d, kind="DC", rate=0.01, freq=0.5, particles=0, npx=5, dx=1.0, dt=0.05,
                 rows=None, mass_ratio=1.0, **kw):
    """The manual's sample as Shear_Navier_Stokes: kBT 0, manual dt, 2^npx cells a side."""
    from udf import UDFManager
    inp = shear_input(d, particles=particles, kind=kind, rate=rate, freq=freq, npx=npx,
                     eq="Shear_Navier_Stokes", **kw)
    u = UDFManager(inp)
    u.put("manual", "time_increment.type")
    u.put(dt, "time_increment.manual.delta_t")
    u.put(dx, f"{SNS}.DX")
    u.put(mass_ratio, "object_type.spherical_particle.Particle_spec[0].MASS_RATIO")
    if rows is not None:
        u.put("user_specify", "switch.INIT_distribution.type")
        u.put(np.asarray(rows, dtype=float), "switch.INIT_distribution.user_specify.Particles[]")
    u.write(inp)
    return inp


def profile(m):
    """The x-z mean of u_x along y, and max |u_y|, |u_z|."""
    u = m.spm.velocity()
    return u[0].mean(axis=(0, 2)), np.abs(u[1:]).max()


def reference_profile(ny, dx, rate, nu, dt, steps):
    """The same algorithm written for the mean profile alone (a parallel flow is an exact
    Navier-Stokes solution: only viscosity acts): exact viscous decay of each k_y mode, the
    planes NY/4, 3NY/4 set to -+ rate Ly/4, the modes |m| > (NY-1)//3 cut."""
    m = np.fft.fftfreq(ny, 1.0 / ny)
    k = 2 * np.pi * m / (ny * dx)
    keep = np.abs(m) <= (ny - 1) // 3
    c = np.zeros(ny, dtype=complex)
    a = rate * ny * dx / 4
    out = []
    for _ in range(steps):
        c *= np.exp(-nu * k * k * dt)
        f = np.fft.ifft(c).real
        f[ny // 4], f[3 * ny // 4] = -a, a
        c = np.fft.fft(f) * keep
        out.append(np.fft.ifft(c).real)
    return out


@pytest.mark.parametrize("dx", [1.0, 0.5])
def test_start_up_from_rest_and_the_pinned_planes(tmp_path, dx):
    """A particle-free run starts at rest and follows, step by step, the viscous start-up of
    the profile pinned at y = Ly/4, 3Ly/4 (the reference algorithm above, to round-off);
    v = w = 0.  In physical units for DX = 0.5 too: the pinned speed is gamma_dot Ly/4 (the
    original would pin gamma_dot Ly DX / 4: fluid_solver.cxx dmy2 = Shear_rate * qLY * DX)."""
    m = build(zigzag_input(tmp_path, npx=4, dx=dx))
    ny, rate = 16, 0.01
    assert np.abs(m.spm.velocity()).max() == 0.0
    ref = reference_profile(ny, dx, rate, 1.0, 0.05, 40)
    for k in range(40):
        m.advance()
        p, cross = profile(m)
        assert np.abs(p - ref[k]).max() < 1e-15, k
        assert cross < 1e-17
    # the 2/3 rule smooths the pinned planes (within 3 % of the pinned speed here), and the
    # flow half-way between them is still at rest after t = 2
    a = rate * ny * dx / 4
    assert p[ny // 4] == pytest.approx(-a, rel=0.03)
    assert p[3 * ny // 4] == pytest.approx(a, rel=0.03)
    assert abs(p[ny // 2]) < 1e-3 * a and abs(p[0]) < 1e-3 * a


def test_developed_profile_is_the_zigzag(tmp_path):
    """Run long (8 x 16 x 8, t = 60: 9 decay times of the slowest mode): the profile is the
    zigzag gamma_dot (y - Ly/2) on [Ly/4, 3Ly/4], -gamma_dot y below, gamma_dot (Ly - y)
    above, up to the 2/3 rule's rounding of its corners (measured: 5.5 % of gamma_dot Ly/4
    at most, the planes 1.3 % below the pinned speed); v = w = 0.  The table then reads
    the original's signs: rate -gamma_dot (-0.019007, the rounded corners lower the slope
    between the planes by 5 %), stress -ETA gamma_dot within 4 %, viscosity 1.09 ETA."""
    from udf import UDFManager
    inp = zigzag_input(tmp_path, npx=3, dt=0.1, rate=0.02)
    u = UDFManager(inp)
    u.put(4, "mesh.NPY")
    u.write(inp)
    m = build(inp)
    for _ in range(600):
        m.advance()
    p, cross = profile(m)
    y = np.arange(16.0)
    zz = np.where(y < 4, -0.02 * y, np.where(y >= 12, 0.02 * (16 - y), 0.02 * (y - 8)))
    a = 0.02 * 16 / 4
    assert np.abs(p - zz).max() < 0.06 * a
    assert p[4] == pytest.approx(-a, rel=0.015) and p[12] == pytest.approx(a, rel=0.015)
    assert cross < 1e-17
    row = m.shear_table_row()
    assert row[1] == pytest.approx(-0.019007, rel=1e-4)
    assert row[3] == pytest.approx(-0.02, rel=0.04)
    assert 1.0 < row[4] < 1.1


# the original's rows (kref build of kapsel3 8ee457a, OMP_NUM_THREADS=1) for this document:
# 32^3, dt 0.05, gamma_dot 0.01, AC Frequency 0.5, no particles; steps 1, 2, 50 and 201
ORIGINAL_ROWS = {
    "DC": [[0.05, -0.0055607197, -0.00027803599, -0.8, 143.86627],
           [0.1, -0.0075524607, -0.00065565902, -0.3300866, 43.705835],
           [2.5, -0.0094814151, -0.022777471, -0.028274123, 2.9820573],
           [10.05, -0.0097369959, -0.095655616, -0.014281232, 1.4666979]],
    "AC": [[0.05, -0.0095860441, -0.00047930221, -6.4, 6.4028463, 0.0028463034],
           [0.1, -0.0095830486, -0.00095845464, -0.0056795227, -0.0020007853, -0.007680308],
           [2.5, -0.0032491511, -0.018357153, 0.1470527, -0.14990204, -0.0028493339],
           [10.05, -0.0027191982, 0.018075992, -0.1559728, 0.15404768, -0.0019251197]]}


@pytest.mark.parametrize("kind", ["DC", "AC"])
def test_stress_table_is_the_originals_without_particles(tmp_path, kind):
    """Every column of the original's table for a particle-free run, to its 8 printed
    digits (201 steps at 32^3, about 6 s)."""
    m = build(zigzag_input(tmp_path, kind=kind))
    rows = {}
    for k in range(1, 202):
        m.advance()
        if k in (1, 2, 50, 201):
            rows[k] = m.shear_table_row()
    for got, want in zip(rows.values(), ORIGINAL_ROWS[kind]):
        np.testing.assert_allclose(got, want, rtol=6e-8, atol=0)


def test_particles_start_at_rest_in_x(tmp_path):
    """A user_specify velocity is imposed on the fluid at the start (as Navier_Stokes), then
    v_x and omega_z are set to 0 (the original's Show_parameter for the sheared types)."""
    rows = [[16.0, 12.0, 16.0, 0.01, 0.02, 0.03, 1, 0, 0, 0, 0.004, 0.005, 0.006]]
    m = build(zigzag_input(tmp_path, particles=1, rows=rows))
    p = m.particles
    assert p.v[0].tolist() == [0.0, 0.02, 0.03]
    assert p.omega[0].tolist() == [0.004, 0.005, 0.0]
    u = m.spm.velocity()
    assert u[0].max() > 0.005                 # the fluid got the input v_x


def brute_force_stress(m, delta, ux_new, ux_old_moment):
    """The table's stress and AC inertia from whole fields: rho = RHO + (MASS_RATIO - 1)
    RHO phi (one species), y = j DX, sums over every grid point."""
    cfg = m.cfg
    rho = cfg.fluid.RHO + (cfg.particles.species[0].MASS_RATIO - 1.0) * cfg.fluid.RHO * m.spm.phi()
    dx = cfg.mesh.DX
    y = (np.arange(m.grid.shape[1]) * dx)[None, :, None]
    V = m.grid.volume
    f = rho * delta
    stress = -dx ** 3 / (V * m.dt) * float(((f - f.mean()) * y).sum())
    M = float((y * rho * ux_new).sum())
    return stress, dx ** 3 / (V * m.dt) * (M - ux_old_moment), M


@pytest.mark.parametrize("kind", ["DC", "AC"])
def test_stress_with_heavy_particles_is_the_density_weighted_moment(tmp_path, kind):
    """With MASS_RATIO 2 spheres cut by a pinned plane: the stress (and AC inertia) of each
    step equal the sums over whole fields (rho from the total phi) to round-off."""
    rows = [[8.0, 10.0, 16.0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0],
            [24.0, 21.0, 16.0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0]]
    m = build(zigzag_input(tmp_path, kind=kind, particles=2, rows=rows, mass_ratio=2.0,
                           rate=0.05))
    M_old = 0.0
    for k in range(6):
        m.advance()
        stress, inertia, M = brute_force_stress(m, m.pin.delta, m.spm.velocity()[0], M_old)
        M_old = M
        assert m.zz.stress == pytest.approx(stress, rel=1e-12, abs=1e-15)
        if kind == "AC":
            assert m.zz.inertia == pytest.approx(inertia, rel=1e-10, abs=1e-14)
    assert abs(m.zz.stress) > 1e-3


def test_type_end_to_end_with_particles(tmp_path):
    """Records, shear_stress.dat (the table's measured rate and strain, the mean stress of
    the steps since the previous record) and the restart."""
    from udf import UDFManager
    inp = zigzag_input(tmp_path, particles=2, gts=5, nsnap=2, npx=4)
    assert shear_cli(tmp_path, inp) == 0
    assert UDFManager(str(tmp_path / "output.udf")).totalRecord() == 3
    log = np.loadtxt(tmp_path / "shear_stress.dat")
    assert log.shape == (3, 5) and np.all(np.isfinite(log))
    assert log[0, 2:].tolist() == [0.0, 0.0, 0.0]      # at rest before the first step
    assert np.all(log[1:, 3] < 0) and np.all(log[1:, 4] < 0)   # the original's signs
    assert (tmp_path / "restart.udf").exists()


def test_ac_header_lists_all_six_columns():
    from kapsel.models.zigzag import TABLE_AC
    from kapsel.progress import ShearTable
    assert ShearTable(TABLE_AC).header() == (
        "#1:time 2:shear_rate_temporal 3:shear_strain_temporal 4:shear_stress_temporal "
        "5:shear_inertia_stress_temporal 6:apparent_shear_stress ")


# the original (same build) for 2 spheres (A 4, LJ NONE) at (8, 12, 16) and (24, 20, 16),
# DC gamma_dot 0.01, the rest as above: table rows of steps 1, 2, 50, 101 and sphere 0 after
# step 100 (its output record of t = 100, printed at full precision)
ORIGINAL_SPHERES = {
    "rows": [[0.05, -0.0055269294, -0.00027634647, -0.8, 144.74583],
             [0.1, -0.0075068122, -0.00065168708, -0.33302609, 44.363184],
             [2.5, -0.0094699583, -0.022725751, -0.029347713, 3.0990329],
             [5.05, -0.009625177, -0.047109647, -0.020674984, 2.1480107]],
    "R": [7.883524117457021, 11.999959615945365, 16.0],
    "v": [-3.3990916714468973e-02, -1.7672059782463545e-05, 0.0],
    "omega_z": -7.8517008437287445e-03}


def test_two_spheres_follow_the_originals_run(tmp_path):
    """Two spheres released at rest at different y: the table and the motion of the
    original's run to round-off (the SPM step is the original's; 101 steps, about 8 s)."""
    from udf import UDFManager
    rows = [[8.0, 12.0, 16.0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0],
            [24.0, 20.0, 16.0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0]]
    inp = zigzag_input(tmp_path, particles=2, rows=rows)
    u = UDFManager(inp)
    u.put("NONE", "switch.LJ_truncate")
    u.write(inp)
    m = build(inp)
    got = {}
    for k in range(1, 102):
        if k == 101:
            p = m.particles
            R, v, w = p.R[0].copy(), p.v[0].copy(), p.omega[0, 2]
        m.advance()
        if k in (1, 2, 50, 101):
            got[k] = m.shear_table_row()
    want = ORIGINAL_SPHERES
    for g, w_ in zip(got.values(), want["rows"]):
        np.testing.assert_allclose(g, w_, rtol=6e-8, atol=0)
    np.testing.assert_allclose(R, want["R"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(v, want["v"], rtol=0, atol=1e-12 * 0.034)
    assert w == pytest.approx(want["omega_z"], rel=1e-10)
