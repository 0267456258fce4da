"""The Electrolyte type (PHYSICS-EXTRA §6): input, time step, conservation of ions and
charge, the Debye-Hueckel double layer, restart, the surface charge and normals."""
import os
import time

import numpy as np
import pytest

from kapsel import config
from kapsel.cli import main
from kapsel.fluid.ions import Ions, bulk_densities
from kapsel.mesh.grid import Grid
from kapsel.io.restart import state_path
from kapsel.particles.profile import Stencil, g as profile, particle_profiles
from kapsel.timestep import auto_dt, electrolyte_dt
from udf import UDFManager

from builders import (continue_input, electrolyte_cli, electrolyte_input, EX01, model_of,
                      sample_el_input, TESTS)


# ---------------------------------------------------------------------------- input
def test_ex01_is_read():
    cfg = config.load(os.path.join(EX01, "colloid_1.udf"))
    el = cfg.electrolyte
    assert el.salt and el.valency == (1.0, -1.0) and el.onsager == (1.0, 1.0)
    assert el.debye_length == 10.0 and el.dielectric == 1.0
    assert el.init_profile == "Poisson_Boltzmann"
    assert el.field_kind == "DC" and el.E == (0.1, 0.0, 0.0)
    assert cfg.particles.species[0].surface_charge == -100.0


def test_zero_charge_and_wrong_sign_counterions_are_refused(tmp_path):
    p = electrolyte_input(tmp_path / "a", charge=0.0)
    with pytest.raises(config.ConfigError, match="Surface_charge"):
        config.load(p)
    p = electrolyte_input(tmp_path / "b", charge=5.0, salt=False)   # counterion valency +1
    with pytest.raises(config.ConfigError, match="sign of the counterions"):
        config.load(p)


def test_time_step_limit():
    """§6.5: min(1/(nu K2), 1/(kBT L K2)), AC <= 0.01/f, times the factor."""
    shape = (32, 32, 32)
    ns = auto_dt(1.0, 1.0, 1.0, 1.0, shape)
    assert electrolyte_dt(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, shape) == ns
    assert electrolyte_dt(0.5, 1.0, 1.0, 1.0, 4.0, 1.0, shape) == pytest.approx(ns / 8)
    assert electrolyte_dt(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, shape, frequency=1.0) == 0.01
    assert electrolyte_dt(1.0, 1.0, 1.0, 0.0, 1.0, 1.0, shape) == ns


def test_bulk_densities_give_the_debye_length():
    n = bulk_densities((2.0, -1.0), 4.0, 2.0, 0.5)
    assert 2 * n[0] - n[1] == pytest.approx(0.0, abs=1e-15)       # neutral
    assert (4 * n[0] + n[1]) / (2.0 * 0.5) == pytest.approx(1 / 16)


# ---------------------------------------------------------------------------- conservation
@pytest.mark.parametrize("salt,field", [(True, "DC"), (False, "AC")])
def test_ion_numbers_and_neutrality_are_conserved(tmp_path, salt, field):
    """150 steps of two charged particles moving in a field: each species' number in the
    fluid and the total charge stay at their initial values to 1e-10."""
    m = model_of(electrolyte_input(tmp_path, salt=salt, field=field, charge=-30.0))
    if field == "AC":
        m.el = m.el.__class__(**{**m.el.__dict__, "frequency": 0.05})
    n0 = m.ion_numbers()
    Z = -30.0 * 2
    assert abs(m.total_charge()) < 1e-10 * abs(Z)
    for _ in range(150):
        m.advance()
    assert np.abs(m.particles.v).max() > 1e-5             # the field moves the particles
    assert np.allclose(m.ion_numbers(), n0, rtol=1e-10, atol=0)
    assert abs(m.total_charge()) < 1e-10 * abs(Z)
    assert np.all(m.ions.c > 0)


# ---------------------------------------------------------------------------- double layer
def debye_hueckel(r, Z, a, kappa, eps):
    return Z / (4 * np.pi * eps * (1 + kappa * a)) * np.exp(-kappa * (r - a)) / r


# one sphere (Z -1, A 4, XI 2) in a 1:1 salt of Debye length 3, off the grid by 0.3 in x
_N, _A, _XI, _LAM, _Z, _EPS = 32, 4.0, 2.0, 3.0, -1.0, 1.0


def _sphere_in_salt():
    """(grid, R, ions) of that sphere, its ions not yet started."""
    grid = Grid((_N, _N, _N))
    R = np.array([[_N / 2 + 0.3, _N / 2, _N / 2]])
    idx, phi, r = particle_profiles(R, Stencil(_A, _XI, 1.0), grid.shape, 1.0)
    ions = Ions(grid, (1.0, -1.0), (1.0, 1.0), _EPS, 1.0, 0.05)
    ions.set_particles(idx, phi, r, [_Z], _A, _XI)
    return grid, R, ions


def _debye_hueckel_error(grid, R, ions):
    """(psi, relative error of psi - psi(corner) against Debye-Hueckel on the shell
    a + xi/2 <= d <= a + xi/2 + 2 lambda)."""
    ions.potential()
    psi = ions.potential_real()
    x, y, z = grid.coordinates()
    d = np.sqrt((x - R[0, 0]) ** 2 + (y - R[0, 1]) ** 2 + (z - R[0, 2]) ** 2)
    sel = (d >= _A + _XI / 2) & (d <= _A + _XI / 2 + 2 * _LAM)
    far = np.unravel_index(np.argmax(d), d.shape)
    ref = (debye_hueckel(d[sel], _Z, _A, 1 / _LAM, _EPS)
           - debye_hueckel(d[far], _Z, _A, 1 / _LAM, _EPS))
    return psi, np.abs(psi[sel] - psi[far] - ref) / np.abs(ref)


def test_double_layer_matches_debye_hueckel():
    """Poisson-Boltzmann equilibrium of a weakly charged sphere (e Psi / kBT < 0.05) in a
    1:1 salt, lambda_D = 3, A = 4, xi = 2 on 32^3: Psi(r) within 5 % of the linearised
    (Debye-Hueckel) potential for a + xi/2 <= r <= a + xi/2 + 2 lambda_D.  The periodic
    potential has zero mean (Psi_k=0 = 0), so both are measured from their value at the
    point farthest from the particle (the corner of the box)."""
    grid, R, ions = _sphere_in_salt()
    vfree = float(np.sum(1 - ions.phi))
    n = bulk_densities((1.0, -1.0), _LAM, _EPS, 1.0)
    ions.init_poisson_boltzmann([n[0] * vfree - _Z, n[1] * vfree])
    psi, err = _debye_hueckel_error(grid, R, ions)
    assert np.abs(psi).max() < 0.05
    assert err.max() < 0.05, err.max()


def test_one_particle_in_salt_starts_from_the_originals_double_layer():
    """One particle in salt (the original's Set_Poisson_Boltzmann_ion_charge_density_salt):
    bulk densities held, a neutralising factor nu; the start is neutral to round-off and
    its potential within 5 % of Debye-Hueckel as the canonical start's (same sphere)."""
    grid, R, ions = _sphere_in_salt()
    n = bulk_densities((1.0, -1.0), _LAM, _EPS, 1.0)
    it = ions.init_poisson_boltzmann_bulk(n, _Z)
    assert 10 < it < 5000
    assert abs(ions.total_charge()) < 1e-10
    assert np.allclose(ions.counts, ions.fluid_counts(), rtol=1e-14)
    _psi, err = _debye_hueckel_error(grid, R, ions)
    assert err.max() < 0.05, err.max()


# ---------------------------------------------------------------------------- restart
def test_continuation_is_bit_identical(tmp_path):
    one = electrolyte_input(tmp_path / "one", nsnap=4, init="Poisson_Boltzmann")
    assert electrolyte_cli(tmp_path / "one", one) == 0
    two = electrolyte_input(tmp_path / "two", nsnap=2, init="Poisson_Boltzmann")
    assert electrolyte_cli(tmp_path / "two", two) == 0
    continue_input(tmp_path / "two")
    assert electrolyte_cli(tmp_path / "two", "cont.udf") == 0
    za = np.load(state_path(str(tmp_path / "one" / "restart.udf")))
    zb = np.load(state_path(str(tmp_path / "two" / "restart.udf")))
    for k in ("ion_c", "ion_c_hat", "ion_banded", "u_hat", "R_raw"):
        assert np.array_equal(za[k], zb[k]), k
    a = UDFManager(str(tmp_path / "one" / "restart.udf"))
    b = UDFManager(str(tmp_path / "two" / "restart.udf"))
    base = "resume.CONTINUE.Saved_Data"
    ca = np.asarray(a.getArray(f"{base}.Concentration[]"), dtype=float)
    assert ca.shape[:4] == (2, 16, 16, 18)
    assert np.array_equal(ca, np.asarray(b.getArray(f"{base}.Concentration[]"), dtype=float))


def test_continuation_from_concentration_alone(tmp_path):
    """Without the state file the ion densities come back from Concentration (Fourier)."""
    p = electrolyte_input(tmp_path, nsnap=1)
    assert electrolyte_cli(tmp_path, p) == 0
    m0 = np.load(state_path(str(tmp_path / "restart.udf")))["ion_c"]
    os.remove(state_path(str(tmp_path / "restart.udf")))
    from kapsel.io.restart import read_restart
    m = model_of(str(tmp_path / "restart.udf"))
    doc = UDFManager(str(tmp_path / "restart.udf"))
    m.load_restart(read_restart(doc, str(tmp_path / "restart.udf"), "CONTINUE"))
    assert np.allclose(m.ions.c, m0, rtol=1e-12, atol=1e-14)


# ---------------------------------------------------------------------------- output
SAMPLES = os.path.join(TESTS, "..", "samples")


def test_extended_output_holds_the_charge_fields(tmp_path):
    """Charge YES: surface_charge, solute_charge, e_potential in every frame; Pressure and
    Tau forced off (FORMAT-OUTPUT.md §3.1).  surface_charge is the original's: the charge
    density times 4 pi a^2 (DX^3 sum = 4 pi a^2 sum Z), and the frame is neutral."""
    import h5py
    p = sample_el_input(tmp_path)
    area = 4 * np.pi * config.load(p).particles.A ** 2
    assert electrolyte_cli(tmp_path, p) == 0
    with h5py.File(tmp_path / "output" / "data.h5") as f:
        fr = f["trajectory_data/frame_2/field"]
        assert sorted(fr) == sorted(["u_x", "u_y", "u_z", "phi", "surface_charge",
                                     "solute_charge", "e_potential"])
        surf = fr["surface_charge"][...].astype(float)
        ionic = fr["solute_charge"][...].astype(float)
        assert surf.sum() == pytest.approx(-20.0 * area, rel=1e-5)
        assert abs((surf / area + ionic).sum()) < 1e-4
        assert abs(fr["e_potential"][...].astype(float).mean()) < 1e-5
    conf = (tmp_path / "output" / "data.conf").read_text()
    assert " surface_charge" in conf and " e_potential" in conf and "tau_xx" not in conf


def test_legacy_avs_of_electrolyte_holds_the_charge_fields(tmp_path):
    """FORMAT-OUTPUT.md §2.4: EL writes u_x u_y u_z phi surface_charge rho e_potential."""
    p = sample_el_input(tmp_path)
    u = UDFManager(p)
    u.put("BINARY", "output.ON.FileType")
    u.write(p)
    area = 4 * np.pi * config.load(p).particles.A ** 2
    assert electrolyte_cli(tmp_path, p) == 0
    fld = (tmp_path / "output" / "data.fld").read_text()
    assert "veclen=7" in fld and "label = ux uy uz phi surface_charge rho e_potential" in fld
    raw = np.fromfile(tmp_path / "output" / "avs" / "data_4.dat", dtype=np.float32)
    assert raw.size == 7 * 16 ** 3
    surf = raw[4 * 16 ** 3:5 * 16 ** 3].astype(float)
    assert surf.sum() == pytest.approx(-20.0 * area, rel=1e-5)


def test_free_energy_table_on_stderr(tmp_path, capsys, monkeypatch):
    """FORMAT-OUTPUT.md §1.5: a header and a row per snapshot; with salt two ion columns;
    the ions' charge (col 5) neutralises the particles and their numbers do not change."""
    p = electrolyte_input(tmp_path, nsnap=2)
    monkeypatch.chdir(tmp_path)
    assert main([f"-I{p}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "1"]) == 0
    err = capsys.readouterr().err.splitlines()
    heads = [i for i, ln in enumerate(err) if ln.startswith("#1:time 2:total")]
    assert len(heads) == 3
    assert err[heads[0]].endswith("6:total_positive_ion 7:total_negative_ion ")
    rows = [err[i + 1].split() for i in heads]
    assert [r[0] for r in rows] == ["0", "2", "4"]
    for r in rows:
        assert len(r) == 7
        assert float(r[4]) == pytest.approx(40.0, rel=1e-10)      # two particles of Z = -20
        assert float(r[5]) == pytest.approx(float(rows[0][5]), rel=1e-12)
        assert float(r[6]) == pytest.approx(float(rows[0][6]), rel=1e-12)


@pytest.mark.slow
def test_nernst_planck_relaxes_to_the_poisson_boltzmann_double_layer():
    """From the uniform start, ion diffusion and migration alone (fluid at rest, as the
    original's Set_steadystate_ion_density) reach the Poisson-Boltzmann equilibrium at the
    same ion numbers: Psi within 2 % (of its maximum) everywhere after t = 71 (1000 steps),
    Z = -5, A = 4, lambda_D = 3, 32^3.  About 30 s on the shared machine (load 6)."""
    N, A, xi, lam, Z, eps = 32, 4.0, 2.0, 3.0, -5.0, 1.0
    grid = Grid((N, N, N))
    R = np.array([[N / 2 + 0.3, N / 2, N / 2]])
    idx, phi, r = particle_profiles(R, Stencil(A, xi, 1.0), grid.shape, 1.0)
    dt = electrolyte_dt(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, grid.shape)

    def make():
        ions = Ions(grid, (1.0, -1.0), (1.0, 1.0), eps, 1.0, dt)
        ions.set_particles(idx, phi, r, [Z], A, xi)
        return ions
    ref = make()
    vfree = float(np.sum(1 - ref.phi))
    n = bulk_densities((1.0, -1.0), lam, eps, 1.0)
    counts = [n[0] * vfree - Z, n[1] * vfree]
    ref.init_poisson_boltzmann(counts)
    ref.potential()
    pb = ref.potential_real().copy()
    ions = make()
    ions.init_uniform(counts)
    ions.potential()
    start = np.abs(ions.potential_real() - pb).max() / np.abs(pb).max()
    for _ in range(1000):
        ions.potential()
        ions.step(None)
        ions.rescale()
    ions.potential()
    err = np.abs(ions.potential_real() - pb).max() / np.abs(pb).max()
    assert start > 0.2 and err < 0.02, (start, err)
    assert np.allclose(ions.fluid_counts(), counts, rtol=1e-10)


def test_surface_charge_and_normals_are_the_originals(tmp_path):
    """The surface charge is the compact sine slope (pi / 2 xi) cos(pi (A - r) / xi) of
    every particle's shell |r - A| < xi / 2 times Z_i, scaled by one factor for all
    particles so that DX^3 sum |rho_surf| = sum |Z_i| (operate_electrolyte.cxx
    Make_phi_qq_particle); the surface normal is the sum of the unit radial vectors over
    the same shells (make_phi.cxx Make_surface_normal)."""
    p = electrolyte_input(tmp_path, particles=[[4.3, 4.1, 3.8], [11.6, 12.0, 11.2]], charge=-10.0)
    m = model_of(p)
    ions, spm = m.ions, m.spm
    A, xi = m.cfg.particles.A, m.cfg.particles.A_XI
    assert float(np.abs(ions.rho_surf).sum()) == pytest.approx(20.0, rel=1e-13)
    dist = np.sqrt(np.einsum("nsc,nsc->ns", spm.r, spm.r))
    shell = np.abs(dist - A) < xi / 2
    flat = ions.rho_surf.reshape(-1)
    assert np.all(flat[np.setdiff1d(np.arange(flat.size), spm.idx[shell])] == 0.0)
    g = 0.5 * np.pi / xi * np.cos(np.pi * (A - dist[shell]) / xi)
    factor = flat[spm.idx[shell]] / (-10.0 * g)        # the shells do not overlap here
    # one factor, ~ 1 / (4 pi A^2): the slope integrates to ~ 1 across the shell
    assert np.allclose(factor, factor[0], rtol=1e-12)
    assert abs(factor[0] * 4 * np.pi * A ** 2 - 1) < 0.05, factor[0] * 4 * np.pi * A ** 2
    n = ions.normal.reshape(3, -1)[:, spm.idx[shell]]
    assert np.allclose(np.einsum("cs,cs->s", n, n), 1.0, rtol=1e-12)
    rhat = spm.r[shell] / dist[shell][:, None]
    assert np.allclose(n.T, rhat, rtol=0, atol=1e-12)


def test_the_particle_feels_the_whole_force_on_its_charge(tmp_path):
    """The Coulomb force on a particle's own surface charge acts on the particle, not on the
    fluid of its interface shell: one step from rest in a field (Z = -10, A = 3, salt-free,
    16^3) gives the particle the momentum Z E dt (within 3 %: the counterions in the shell
    add theirs).  Through the fluid (the original's route) only the phi-weighted part of
    the shell force reaches it in a step, and the steady electrophoretic velocity falls to
    0.875 (kappa a = 0.49) and 0.754 (kappa a = 2.96) of Henry's
    (tests/validation/test_electrolyte_mobility.py; docs/physics-electrolyte.md)."""
    p = electrolyte_input(tmp_path, particles=[[8.2, 8.0, 7.9]], salt=False, field="DC",
                   charge=-10.0, A=3.0)
    m = model_of(p)
    E = m.field_now()
    M = m.spm.mass[0]
    m.advance()
    got = M * m.particles.v[0] / (-10.0 * E[0] * m.dt)
    assert abs(got[0] - 1) < 0.03 and np.abs(got[1:]).max() < 1e-3, got
    F, T = m.ions.particle_force(E)
    assert np.allclose(F[0], -10.0 * E, rtol=0, atol=1e-3 * abs(10.0 * E[0]))


def test_an_unstable_manual_time_step_is_named(tmp_path, capsys):
    """A manual dt far past the ion limit: the run stops (exit 1) naming the ion densities
    and the limit, not a traceback."""
    p = electrolyte_input(tmp_path, nsnap=10, gts=10)
    u = UDFManager(p)
    u.put("manual", "time_increment.type")
    u.put(2.0, "time_increment.manual.delta_t")
    u.write(p)
    assert electrolyte_cli(tmp_path, p) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "ion densities are not finite or negative" in err and "1 / (kBT L_max" in err, err


def test_check_banner_names_ions_lengths_and_the_dt_limit(tmp_path, capsys, monkeypatch):
    p = electrolyte_input(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["--check", f"-I{p}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf"]) == 0
    out = capsys.readouterr()
    text = out.out + out.err
    assert "ions: salt z = 1, -1, Debye length 3, Bjerrum length 0.0795775" in text
    assert "kBT = 1, Onsager 1" in text
