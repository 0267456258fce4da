"""Quincke constraint and dipoles (kapsel/particles/dipoles.py, PHYSICS-EXTRA.md §4): moments,
mirror images in the electrode plane, every species, the input sections (ex12), and runs."""
import os
import subprocess
import sys
import types

import numpy as np
import pytest

from kapsel import config
from kapsel.particles import dipoles as dp
from kapsel.particles import ewald as ew
from kapsel.particles.quaternion import from_axis_angle, rotate
from udf import UDFManager
from udf.errors import UDFError

from builders import EX12_DATA, nowall_input


EX12 = "a2_N65_Rer025_dipole_mirror.udf"


def _random_q(n, seed):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1)[:, None]


# ---------------------------------------------------------------- Quincke constraint
def test_quincke_torque_is_minus_the_derivative_of_the_constraint_energy():
    qk = dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 50.0)
    q = _random_q(5, 1)
    T = dp.quincke_torque(q, qk)
    h = 1e-6
    for c in range(3):
        dq = from_axis_angle(np.eye(3)[c], h)
        from kapsel.particles.quaternion import multiply
        Up = dp.quincke_energy(multiply(np.tile(dq, (5, 1)), q), qk)
        Um = dp.quincke_energy(multiply(np.tile(from_axis_angle(np.eye(3)[c], -h), (5, 1)),
                                        q), qk)
        np.testing.assert_allclose(T[:, c], -(Up - Um) / (2 * h), atol=1e-6)
    # no torque when the axis is perpendicular to the field (identity: e = x, n = z)
    assert np.allclose(dp.quincke_torque(np.array([[1.0, 0, 0, 0]]), qk), 0.0)


# ---------------------------------------------------------------- moments
def test_fixed_dipoles_turn_with_the_body():
    q = _random_q(4, 2)
    d = dp.Dipoles("FIXED", 2.5, axis=(0.0, 1.0, 0.0))
    mu = dp.moments(q, d)
    np.testing.assert_allclose(mu, 2.5 * rotate(q, np.tile([0.0, 1.0, 0.0], (4, 1))))


def test_quincke_dipoles_lie_across_field_and_axis_plus_the_static_part():
    qk = dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 50.0)
    d = dp.Dipoles("QUINCKE", 6.0, pz_factor=3.0)
    q = _random_q(6, 3)
    mu = dp.moments(q, d, qk)
    rot = mu - [0.0, 0.0, -18.0]
    e = rotate(q, np.tile([1.0, 0, 0], (6, 1)))
    np.testing.assert_allclose(np.linalg.norm(rot, axis=1), 6.0)
    np.testing.assert_allclose(np.einsum("ij,ij->i", rot, e), 0.0, atol=1e-12)
    np.testing.assert_allclose(rot[:, 2], 0.0, atol=1e-12)       # across n = z
    np.testing.assert_allclose(np.cross(rot, np.cross([0, 0, 1.0], e)), 0.0, atol=1e-12)


@pytest.mark.parametrize("tilt", [0.0, 30.0, 60.0, 89.0, 90.0])
def test_quincke_static_part_does_not_follow_the_tilt(tilt):
    """The static part is p0 Pz_factor along -z at any tilt of the roller's axis out of the
    plane across the field, for the dipole and its image, and finite with the axis along the
    field (define.udf: "Pz strength += Pz_factor*magnitude").  The original divides it by
    |n x e| as its rotating part (md_force.cxx:22,26,34,38; docs/physics-quincke.md)."""
    qk = dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 20.0)
    d = dp.Dipoles("QUINCKE", 6.0, pz_factor=3.0, mirror_z=2.5)
    q = from_axis_angle(np.array([[0.0, 1.0, 0.0]]), np.array([-np.radians(tilt)]))
    e = rotate(q, np.array([[1.0, 0.0, 0.0]]))[0]
    assert abs(e[2] - np.sin(np.radians(tilt))) < 1e-12        # tilted towards the field
    mu = dp.moments(q, d, qk)[0]
    X, m = dp.sources(np.array([[8.0, 8.0, 6.0]]), q, d, qk)
    across = tilt < 90.0
    for v in (mu, m[0], m[1]):
        assert np.all(np.isfinite(v))
        np.testing.assert_allclose(v[2], -18.0, atol=1e-12)
        np.testing.assert_allclose(np.hypot(v[0], v[1]), 6.0 if across else 0.0, atol=1e-9)
    np.testing.assert_allclose(m[1][:2], -m[0][:2], atol=1e-12)     # image: -mu_x, -mu_y
    np.testing.assert_allclose(X[1], [8.0, 8.0, -1.0])


@pytest.mark.parametrize("h", [3.0, 6.0])
def test_mirror_image_is_the_reflection_in_the_electrode_plane(h):
    """A Quincke dipole at height h above the electrode (z_w = 2.5) feels its conducting-plane
    image (-mu_x, -mu_y, mu_z) at distance 2h, in a box large enough that periodic copies do
    not matter (1%).  The original puts the image 4.1 below the particle whatever h is: its
    force would be that of a dipole at distance 4.1 and this test would fail."""
    box = np.array([300.0, 300.0, 300.0])
    zw = 2.5
    qk = dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 50.0)
    d = dp.Dipoles("QUINCKE", 6.0, pz_factor=0.7, mirror_z=zw, tol=1e-10)
    q = from_axis_angle([0.0, 0.0, 1.0], 0.4)[None]            # e in the xy plane
    R = np.array([[150.0, 150.0, zw + h]])
    F, T = dp.dipole_forces(R, q, box, d, qk)
    mu = dp.moments(q, d, qk)[0]
    img = mu.copy()
    img[:2] *= -1
    U0, F0, E0 = ew.bare_dipole_pair(np.array([0.0, 0.0, 2 * h]), mu, img)
    assert np.linalg.norm(F[0] - F0) < 0.01 * np.linalg.norm(F0)
    assert np.linalg.norm(T[0] - np.cross(mu, E0)) < 0.01 * np.linalg.norm(mu) * np.linalg.norm(E0)
    assert F[0, 2] < 0                                            # drawn to the electrode
    _, Fbug, _ = ew.bare_dipole_pair(np.array([0.0, 0.0, 4.1]), mu, img)
    assert np.linalg.norm(F[0] - Fbug) > 0.2 * np.linalg.norm(F0)


def test_mirror_images_do_not_wrap_onto_the_particles_in_a_slab_box():
    """ex12's slab (64 x 64 x 32, electrode plane z_w = 2.5): the image of a dipole at
    z = 18.7 lies at 2 z_w - z = -13.7, which the box's own z period would put 0.4 below the
    particle (a force of 5e4 blew ex12 up at its first step).  The Ewald cell is doubled
    along z (kapsel.particles.dipoles.ewald_box): the force stays that of an image at the
    mirror distance 2 (z - z_w) = 32.4, not of a dipole 0.4 away."""
    box = np.array([64.0, 64.0, 32.0])
    zw = 2.5
    qk = dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 50.0)
    d = dp.Dipoles("QUINCKE", 6.0, pz_factor=3.0, mirror_z=zw, tol=1e-8)
    q = from_axis_angle([0.0, 0.0, 1.0], 0.4)[None]
    R = np.array([[32.0, 32.0, 18.7]])
    F, _ = dp.dipole_forces(R, q, box, d, qk)
    mu = dp.moments(q, d, qk)[0]
    img = mu.copy()
    img[:2] *= -1
    _, Fnear, _ = ew.bare_dipole_pair(np.array([0.0, 0.0, 0.4]), mu, img)
    _, Fmirror, _ = ew.bare_dipole_pair(np.array([0.0, 0.0, 2 * (18.7 - zw)]), mu, img)
    assert np.linalg.norm(F[0]) < 1e-3 * np.linalg.norm(Fnear)
    assert np.linalg.norm(F[0]) < 50 * np.linalg.norm(Fmirror)     # periodic copies add some


def test_images_receive_no_force_and_real_pairs_see_each_other_and_all_images():
    box = np.array([20.0, 20.0, 30.0])
    qk = dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 1.0)
    d = dp.Dipoles("QUINCKE", 2.0, pz_factor=1.0, mirror_z=2.0, tol=1e-10)
    R = np.array([[5.0, 5.0, 6.0], [9.0, 7.0, 8.0], [14.0, 12.0, 5.0]])
    q = _random_q(3, 7)
    F, T = dp.dipole_forces(R, q, box, d, qk)
    X, mu = dp.sources(R, q, d, qk)
    assert X.shape == (6, 3) and np.allclose(X[3:, 2], 4.0 - R[:, 2])
    cell = dp.ewald_box(box, d)                  # doubled along z with images
    assert cell[2] == 2 * box[2]
    _, F2, E2 = ew.dipolar_ewald(X, mu, cell, ew.choose_parameters(cell, 6, 1e-12))
    np.testing.assert_allclose(F, F2[:3], atol=1e-8 * np.abs(F2).max())
    np.testing.assert_allclose(T, np.cross(mu[:3], E2[:3]), atol=1e-8 * np.abs(T).max())


# ---------------------------------------------------------------- input


def test_ex12_sections_are_read(tmp_path):
    """The derived input (ex12 without walls): Quincke e_dir Z, w_dir X, K 50; QUINCKE
    dipoles of magnitude 6, Pz 3, no images; EwaldParams alpha 8, delta 1e-16, converge 0.51,
    epsilon -1 = tin-foil."""
    cfg = config.load(nowall_input(tmp_path))
    qk, d = cfg.switches.quincke, cfg.switches.dipoles
    assert qk == dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 50.0)
    assert d.kind == "QUINCKE" and d.magnitude == 6.0 and d.pz_factor == 3.0
    assert d.mirror_z is None and d.epsilon_surface == np.inf
    assert d.tol == pytest.approx(ew.tolerance_from_original(8.0, 1e-16, 0.51))


def test_ex12_verbatim_sections_with_the_wall_images(tmp_path):
    """The real ex12 input: mirror images in the lower surface of its FLAT Z wall
    (DH = 5, DX = 1: z_w = 2.5).  Its unused FIXED.dir holds "", which the UDF reader binds
    lazily only with issue 11's reader (branch i11); until that is merged this is skipped."""
    try:
        doc = UDFManager(os.path.join(EX12_DATA, EX12))
    except UDFError as e:
        pytest.skip(f"the UDF reader does not yet accept ex12's unused empty select ({e})")
    r = config._Reader(doc)
    species = [config.Species(65, 1, 1.5)]
    qk, d = config._electric(r, "rigid", species, config.Mesh(64, 64, 32, DX=1.0))
    assert qk == dp.Quincke((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 50.0)
    assert d.kind == "QUINCKE" and d.magnitude == 6.0 and d.pz_factor == 3.0
    assert d.mirror_z == 2.5 and d.epsilon_surface == np.inf


@pytest.mark.parametrize("puts, message", [
    (dict(switch__quincke__type="OFF"), "need switch.quincke.type ON"),
    (dict(switch__quincke__ON__e_dir="X"), "field along Z"),
    (dict(switch__multipole__ON__Dipole__ON__QUINCKE__type="with_mirror_image"),
     "mirror images need the electrode"),
    (dict(switch__multipole__ON__Dipole__type="OFF"), "need switch.multipole.ON.Dipole.type ON"),
    (dict(switch__multipole__ON__EwaldParams__delta=2.0), "between 0 and 1"),
])
def test_bad_dipole_settings_are_named(tmp_path, puts, message):
    with pytest.raises(config.ConfigError, match=message):
        config.load(nowall_input(tmp_path, **puts))


def test_quincke_needs_one_bead_bodies(tmp_path):
    path = nowall_input(tmp_path, switch__multipole__type="OFF")
    u = UDFManager(path)
    u.put([[2, 3, 1.5, 0.0, "free", [0.0, 0, 0], [0.0, 0, 0]]], "object_type.rigid.Rigid_spec[]")
    u.write(path)
    with pytest.raises(config.ConfigError, match="one bead each"):
        config.load(path)


def _model(path, eq=None):
    from kapsel.typespec import SOLVERS  # noqa: F401  (registers the models)
    cfg = config.load(path)
    if cfg.type == "Navier_Stokes":
        from kapsel.models.spectral import SpectralModel
        return SpectralModel(cfg, types.SimpleNamespace(seed=2, quiet=True, threads=1))
    from kapsel.models.fdm import FDMModel
    return FDMModel(cfg, types.SimpleNamespace(seed=2, quiet=True, threads=1))


def test_every_species_carries_its_dipole(tmp_path):
    """Two species of FIXED dipoles: the particles of species 1 carry dipoles and feel forces
    and torques, exactly the Ewald sum over all particles.  The original's dipole array
    restarts at offset 0 for every species, so species 1 would carry none (and this fails)."""
    path = nowall_input(tmp_path, switch__quincke__type="OFF",
                   switch__multipole__ON__Dipole__ON__type="FIXED",
                   switch__multipole__ON__Dipole__ON__FIXED__dir="Y",
                   switch__INIT_orientation="random", EPSILON=0.0, gravity__G=0.0)
    u = UDFManager(path)
    u.put([[1, 3, 1.5, 0.0, "free", [0.0, 0, 0], [0.0, 0, 0]],
           [1, 3, 1.0, 0.0, "free", [0.0, 0, 0], [0.0, 0, 0]]], "object_type.rigid.Rigid_spec[]")
    u.put([], "switch.free_rigid.YES.DOF[]")
    u.write(path)
    m = _model(path)
    p = m.particles
    assert list(p.species) == [0, 0, 0, 1, 1, 1]
    F, T = m.spm.forces(p)
    mu = 6.0 * rotate(p.q, np.tile([0.0, 1.0, 0.0], (6, 1)))
    box = m.cfg.mesh.box
    _, F0, E0 = ew.dipolar_ewald(p.R, mu, box, ew.choose_parameters(box, 6, 1e-12))
    np.testing.assert_allclose(F, F0, atol=1e-6 * np.abs(F0).max())
    np.testing.assert_allclose(T, np.cross(mu, E0), atol=1e-6 * np.abs(T).max())
    assert np.all(np.linalg.norm(T[3:], axis=1) > 0)


def _axis_field_cos(m):
    return rotate(m.particles.q, np.tile([1.0, 0, 0], (m.particles.n, 1)))[:, 2]


def test_constraint_keeps_the_axis_across_the_field_under_thermal_noise(tmp_path):
    """kBT = 1, K = 200: n.e, the cosine of axis and field, stays small, as equipartition
    in U = (K/2)(n.e)^2 says (<(n.e)^2> = kT/K = 0.005, less the part of the kicks the fluid
    takes), while without the constraint the same noise turns the axes well away from the
    plane across the field.  16^3, 4 rollers, 300 steps (5 s)."""
    puts = dict(switch__multipole__type="OFF", switch__INIT_orientation="space_align",
                gravity__G=0.0, mesh__NPX=4, mesh__NPY=4, mesh__NPZ=4,
                constitutive_eq__Navier_Stokes__kBT=1.0,
                constitutive_eq__Navier_Stokes__alpha_v=1.0,
                constitutive_eq__Navier_Stokes__alpha_o=1.0,
                switch__quincke__ON__torque_amp=200.0)
    spread = {}
    for on in ("ON", "OFF"):
        path = nowall_input(tmp_path, name=f"q{on}.udf", switch__quincke__type=on, **puts)
        u = UDFManager(path)
        u.put([[1, 4, 1.5, 0.0, "free", [0.0, 0, 0], [0.0, 0, 0]]],
              "object_type.rigid.Rigid_spec[]")
        u.put([], "switch.free_rigid.YES.DOF[]")
        u.write(path)
        m = _model(path)
        c2 = []
        for _ in range(300):
            m.advance()
            c2.append(_axis_field_cos(m) ** 2)
        spread[on] = np.array(c2)
    on, off = spread["ON"], spread["OFF"]
    kT_over_K = 1.0 / 200.0                      # measured: <(n.e)^2> = 0.0042, max 0.032
    assert 0.2 * kT_over_K < np.mean(on[50:]) < 2 * kT_over_K and np.max(on) < 0.08
    assert np.mean(off[50:]) > 5 * np.mean(on[50:])          # measured 0.069


@pytest.mark.parametrize("eq", ["Shear_Navier_Stokes_Lees_Edwards", "Shear_NS_LE_CH_FDM"])
def test_dipoles_under_lees_edwards_sum_the_sheared_lattice(tmp_path, eq):
    """FIXED dipoles on spheres in the Lees-Edwards types: after some steps (the frame
    strained) the particles' forces and torques are the Ewald sum over the sheared lattice at
    the model's strain (kapsel.particles.ewald, strain != 0), not the unsheared one."""
    from kapsel import models  # noqa: F401  (registers the types)
    from kapsel.typespec import SOLVERS
    path = nowall_input(tmp_path, switch__quincke__type="OFF", switch__free_rigid__type="NO",
                   object_type__type="spherical_particle", constitutive_eq__type=eq,
                   switch__multipole__ON__Dipole__ON__type="FIXED", gravity__G=0.0, EPSILON=0.0,
                   switch__INIT_orientation="random",
                   **{"object_type__spherical_particle__Particle_spec[]":
                      [[4, 1.5, 0.0, "NONE", "OFF", [0.0, 0, 0], [0.0, 0, 0], 0.0, 0.0, 0.0,
                        0.0]]})
    cfg = config.load(path)
    m = SOLVERS[eq](cfg, types.SimpleNamespace(seed=2, quiet=True, threads=1), None)
    for _ in range(3):
        m.advance()
    p = m.particles
    g = m.frame_strain()
    assert abs(g) > 1e-4
    F, T = m.spm.forces(p)
    mu = dp.moments(p.q, cfg.switches.dipoles)
    box = cfg.mesh.box
    prm = ew.choose_parameters(box, p.n, 1e-12)
    _, F0, E0 = ew.dipolar_ewald(p.R, mu, box, prm, strain=g)
    np.testing.assert_allclose(F, F0, atol=1e-6 * np.abs(F0).max())
    np.testing.assert_allclose(T, np.cross(mu, E0), atol=1e-6 * np.abs(T).max())
    _, Fu, _ = ew.dipolar_ewald(p.R, mu, box, prm)
    assert np.abs(Fu - F0).max() > 100 * 1e-6 * np.abs(F0).max()   # the check can tell


def _run_last_record(d, name):
    """Run the command on ``name`` in ``d`` (seed 3) and return out.udf at its last record."""
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", f"-I{name}", "-Oout.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--seed", "3", "--quiet"],
                       cwd=d, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    u = UDFManager(str(d / "out.udf"))
    u.jump(u.totalRecord() - 1)
    return u


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Navier_Stokes_FDM"])
def test_the_derived_ex12_input_runs(tmp_path, eq):
    """ex12 without walls (tests/data/ex12/nowall.udf: 6 Quincke rollers with QUINCKE dipoles,
    omega_x fixed, 16^3) runs with the command; the rollers feel the constraint and dipole
    torques (torque_r) and keep their fixed omega_x."""
    nowall_input(tmp_path, name="nowall.udf", constitutive_eq__type=eq)
    u = _run_last_record(tmp_path, "nowall.udf")
    q = np.array(u.getArray("Particles[].q"))
    T = np.array(u.getArray("Particles[].torque_r"))
    w = np.array(u.getArray("Particles[].omega"))
    assert q.shape == (6, 4) and np.all(np.isfinite(q)) and np.all(np.isfinite(T))
    assert np.all(np.linalg.norm(T, axis=1) > 0.1)     # measured 0.58 - 7.1 (2026-12-01)
    # omega_x is fixed in the body frame (Quincke w_dir, as the original's rollers turn with
    # their body); q is a float record, hence the tolerance
    from kapsel.particles import quaternion as quat
    wb = quat.to_body(q / np.linalg.norm(q, axis=1, keepdims=True), w)
    np.testing.assert_allclose(wb[:, 0], 0.0625, rtol=1e-5)


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Shear_Navier_Stokes"])
def test_fixed_dipoles_on_spheres_run(tmp_path, eq):
    """FIXED dipoles on spherical particles (no Quincke): the spheres turn under mu x E."""
    path = nowall_input(tmp_path, name="s.udf", switch__quincke__type="OFF",
                   switch__free_rigid__type="NO", object_type__type="spherical_particle",
                   constitutive_eq__type=eq, switch__multipole__ON__Dipole__ON__type="FIXED",
                   switch__INIT_orientation="random", output__GTS=2, output__Num_snap=1,
                   **{"object_type__spherical_particle__Particle_spec[]":
                      [[4, 1.5, 0.0, "NONE", "OFF", [0.0, 0, 0], [0.0, 0, 0], 0.0, 0.0, 0.0,
                        0.0]]})
    u = _run_last_record(tmp_path, "s.udf")
    T = np.array(u.getArray("Particles[].torque_r"))
    w = np.array(u.getArray("Particles[].omega"))
    assert T.shape == (4, 3) and np.all(np.linalg.norm(T, axis=1) > 0)
    assert np.all(np.linalg.norm(w, axis=1) > 0)


def test_check_names_the_constraint_and_the_dipoles(tmp_path):
    nowall_input(tmp_path, name="nowall.udf")
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", "-Inowall.udf", "-Oout.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--check"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "Quincke constraint: field along Z, body axis X, K = 50" in r.stdout
    assert "dipoles 6 (QUINCKE, Pz_factor 3, no mirror images); Ewald to 1.1e-07 (tin-foil" \
        in r.stdout


def test_quincke_rollers_under_lees_edwards_keep_their_constraint(tmp_path):
    """The original's Lees-Edwards force routine has no Quincke torque (PHYSICS-EXTRA.md §7);
    kapsel-py applies it in every type.  Under Lees-Edwards shear, 6 rollers started with
    random axes, free to move (ex12's K = 50, e_dir Z, w_dir X; dipoles off): the torque they
    feel is the constraint's, and it turns their axes across the field (max |n.e| from 0.64
    to 0.13 in 120 steps, t = 7.2), while without it the axes stay out of that plane (0.61).
    16^3, 2 x 120 steps."""
    from kapsel import models  # noqa: F401  (registers the types)
    from kapsel.typespec import SOLVERS
    eq = "Shear_Navier_Stokes_Lees_Edwards"
    end = {}
    for on in ("ON", "OFF"):
        path = nowall_input(tmp_path, name=f"q{on}.udf", constitutive_eq__type=eq,
                       switch__multipole__type="OFF", switch__quincke__type=on,
                       switch__INIT_orientation="random", switch__free_rigid__type="NO",
                       gravity__G=0.0)
        u = UDFManager(path)
        u.put([[1, 6, 1.5, 0.0, "free", [0.0, 0, 0], [0.0, 0, 0]]],
              "object_type.rigid.Rigid_spec[]")
        u.write(path)
        cfg = config.load(path)
        m = SOLVERS[eq](cfg, types.SimpleNamespace(seed=2, quiet=True, threads=1), None)
        start = np.max(np.abs(_axis_field_cos(m)))
        for _ in range(120):
            m.advance()
        end[on] = np.max(np.abs(_axis_field_cos(m)))
        if on == "ON":
            p = m.particles
            _, T = m.spm.forces(p)
            np.testing.assert_allclose(T, dp.quincke_torque(p.q, cfg.switches.quincke),
                                       atol=1e-12 * np.abs(T).max())
    assert start > 0.5
    assert end["ON"] < start / 3 and end["OFF"] > start / 2
