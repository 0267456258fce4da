"""Rigid bodies of beads (kapsel.particles.rigid), switch.free_rigid and switch.pin.

Against the original (the kref build of kapsel3 8ee457a, run on the same documents; the
numbers in the tests are its records, %.17g): the body set-up (grid mass, centre, inertia,
principal frame and quaternion, Rigid_velocity / body-frame Rigid_omega) and the motion of a
free 4-bead body, of two Quincke rollers with a body-frame fixed omega component and of
ex10's 13-bead arch of overlapping beads agree to round-off (1e-12 relative asserted).

Measured (L = 32, A = 4, xi = 2; dumbbell = 2 touching beads along x; the step of the
original, 2026-12-01):
* fixed Omega_x = 0.01 about the dumbbell axis, 300 steps of measured_dt(0.5): fluid angular
  velocity u_theta / (r Omega) around a bead, r = 3: 1.008, r = A: 0.888, r = 2A: 0.110
  (spectral; MAC 1.008, 0.889, 0.109; an isolated sphere: 1, 1, 0.125); hydrodynamic torque
  -32.6 (MAC -32.2; two isolated spheres 8 pi ETA A^3 Omega each: -32.2);
* free dumbbell, MASS_RATIO 1.5, G = 0.002 along -Z, measured_dt(1): velocity along -Z only
  (other components ~1e-21, |Omega| ~1e-21).  V / V_Stokes (unbounded, two touching spheres
  broadside, drag 2 x 0.716 x 6 pi ETA A): L = 32, 400 steps 0.475 (a one-bead body: 0.631,
  Hasimoto for L = 32 gives 0.653); L = 64, 3000 steps (slow test, 66 s, measured with the
  former step) 0.754, where the first-order periodic correction
  F (1/drag - 1.7601 / (6 pi ETA L)) gives 0.842.
"""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from kapsel import config
from kapsel.analysis.rotational_energy import inertia_tensor
from kapsel.particles import quaternion as quat
from kapsel.particles.forces import gravity_force, pair_forces
from kapsel.particles.motion import Pinned
from kapsel.particles.profile import Stencil, particle_profiles
from kapsel.particles.rigid import RigidBodies, grid_integrals, rod_shape
from kapsel.particles.spm import SPM
from kapsel.particles.state import ParticleState
from udf import UDFManager

from builders import copy_schema, FREE3, measured_dt, rigid_input, run_model, scene, TESTS


SAMPLES = os.path.join(TESTS, "..", "samples")
A, XI = 4.0, 2.0


def beads(nb, mass_ratio=1.0):
    return ParticleState.spheres([0] * nb, [A] * nb, [mass_ratio] * nb, 1.0)


def one_body(shape, mass_ratio=1.0, free=(True, True), v_fixed=(0, 0, 0), o_fixed=(0, 0, 0),
             centre=(16.0, 16.0, 16.0), q=None, L=32, gravity=None):
    """One body of nominal beads at centre + R(q) shape (principal body frame; o_fixed is
    body-frame, as Rigid_omega)."""
    nb = len(shape)
    p = beads(nb, mass_ratio)
    b = RigidBodies.nominal(np.zeros(nb, int), shape, p.mass, p.inertia, [0],
                            np.array([centre]), quat.identity(1) if q is None else q,
                            [[free[0]] * 3], [[free[1]] * 3], [v_fixed], [o_fixed], [L] * 3,
                            gravity=gravity)
    b.place_beads(p)
    p.constraints = b
    return p, b


def close(a, b, rel=1e-12):
    """|a - b| <= rel max|b| (b: the original's numbers)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return np.abs(a - b).max() <= rel * np.abs(b).max()


# ---------------------------------------------------------------- body geometry (no fluid)
def test_nominal_masses_centre_and_inertia_in_the_principal_frame():
    X = np.array([[1.0, 2.0, 3.0], [9.0, 2.0, 3.0], [1.0, 10.0, 3.0], [1.0, 2.0, 11.0]])
    m = np.array([1.0, 2.0, 3.0, 4.0])
    Ik = 0.4 * m * A ** 2
    com = (m[:, None] * X).sum(axis=0) / m.sum()
    b = RigidBodies.nominal([0, 0, 0, 0], X - com, m, Ik, [0], [com], quat.identity(1),
                            [[True] * 3], [[True] * 3], [[0.0] * 3], [[0.0] * 3], [32.0] * 3)
    I2, c2 = inertia_tensor(m, X)                              # spec 002 eq 2
    assert np.allclose(b.state.R[0], c2) and b.masses[0] == pytest.approx(10.0)
    assert np.allclose(b.inertia_space()[0], I2 + Ik.sum() * np.eye(3))
    Ib = b.moments_body[0]
    assert np.allclose(Ib, np.diag(np.diag(Ib)), atol=1e-12 * np.abs(Ib).max())
    assert Ib[0, 0] >= Ib[1, 1] >= Ib[2, 2]         # body x: the largest moment, z: smallest
    assert np.allclose((m[:, None] * b.body_positions).sum(axis=0), 0.0, atol=1e-12)
    assert np.allclose(quat.rotate(b.state.q[[0] * 4], b.body_positions), X - com)
    # a rod's long axis is its body z axis
    p, r = one_body(rod_shape(3, A))
    assert np.allclose(np.abs(r.body_positions[:, 2]), [8.0, 0.0, 8.0])


def test_grid_mass_of_overlapping_beads_counts_every_node_once():
    """M = RHO_p DX^3 sum_k sum_x phi_k / max(phi_sum, 1) = RHO_p DX^3 sum_x min(phi_sum, 1)
    (make_phi.cxx Make_phi_rigid_mass): beads 3 apart of radius 4 overlap by far."""
    shape, dx, L = (32, 32, 32), 1.0, 32
    X = np.array([[14.3, 16.2, 15.9], [17.3, 16.2, 15.9], [17.3, 19.2, 15.9]])
    body = np.zeros(3, dtype=np.int64)
    M, R, I = grid_integrals(X, body, 1, [1.5], A, XI, dx, shape)
    idx, phi, r = particle_profiles(X, Stencil(A, XI, dx), shape, dx)
    psum = np.bincount(idx.ravel(), weights=phi.ravel(), minlength=L ** 3)
    assert M[0] == pytest.approx(1.5 * np.minimum(psum, 1.0).sum(), rel=1e-12)
    one, _, _ = grid_integrals(X[:1], body[:1], 1, [1.5], A, XI, dx, shape)
    assert 1.5 * one[0] < M[0] < 2.5 * one[0]                # not 3 beads' worth
    assert one[0] == pytest.approx(1.5 * 4 / 3 * np.pi * A ** 3, rel=0.03)
    # the same body across the periodic boundary (unwrapped positions)
    M2, R2, I2 = grid_integrals(X + [-14.0, 0.0, 0.0], body, 1, [1.5], A, XI, dx, shape)
    assert M2[0] == pytest.approx(M[0], rel=1e-12)
    assert np.allclose(R2, R + [-14.0, 0.0, 0.0]) and np.allclose(I2, I, rtol=1e-10)


FREE4 = [("constitutive_eq.type", "Navier_Stokes"), ("constitutive_eq.Navier_Stokes.kBT", 0.0),
         ("mesh.NPX", 5), ("mesh.NPY", 5), ("mesh.NPZ", 5), ("A_XI", 2.0),
         ("switch.INIT_distribution.type", "user_specify"), ("time_increment.type", "manual"),
         ("time_increment.manual.delta_t", 0.05), ("switch.LJ_truncate", "ON"), ("A", 3.0),
         ("object_type.type", "rigid"), ("object_type.rigid.Rigid_spec[0].Chain_number", 1),
         ("object_type.rigid.Rigid_spec[0].MASS_RATIO", 2.0),
         ("object_type.rigid.Rigid_spec[0].Beads_number", 4),
         ("object_type.rigid.Rigid_spec[0].Rigid_motion", "free"),
         ("object_type.rigid.Rigid_spec[0].Rigid_velocity.x", 0.004),
         ("object_type.rigid.Rigid_spec[0].Rigid_velocity.y", -0.002),
         ("object_type.rigid.Rigid_spec[0].Rigid_omega.x", 0.001),
         ("object_type.rigid.Rigid_spec[0].Rigid_omega.z", 0.002),
         ("gravity.G", 0.002), ("gravity.G_direction", "-Z"),
         ("switch.INIT_orientation", "user_specify"),
         ("switch.INIT_distribution.user_specify.Particles[]",
          np.array([x + [0, 0, 0, 0.9238795325112867, 0.0, 0.3826834323650898, 0.0, 0, 0, 0]
                    for x in ([14.2, 13.1, 15.0], [18.9, 16.2, 16.4], [13.5, 18.8, 17.1],
                              [9.1, 15.7, 15.9])]))]


def test_free_body_is_set_up_and_moves_as_in_the_original(tmp_path):
    """A free L of 4 beads (A = 3) with Rigid_velocity, Rigid_omega and a user q (not read:
    without Quincke the body frame is the principal one), 32^3, dt 0.05, settling along -Z:
    the original's set-up (mass, principal moments, GR_body, q; Omega = R(q) Rigid_omega,
    V = Rigid_velocity) and its state after 20 steps."""
    model = run_model(scene(tmp_path, os.path.join(SAMPLES, "input.udf"), FREE4), 0)
    b = model.particles.constraints
    s = b.state
    assert close(b.masses, [927.27189103482101])
    assert close(np.diag(b.moments_body[0]), [19101.627695093175, 14783.083782652529,
                                              7891.0829405973])
    assert close(b.body_positions[0], [-0.040352867243873325, 3.0607121066264917,
                                       0.15551936597176763], rel=1e-11)
    assert close(s.R[0], [13.930025903665083, 15.947872898320959, 16.100230507236631])
    assert close(s.q[0], [-0.13670532843697686, 0.68280724204630894, -0.11470867102963418,
                          0.70846866139347808])
    assert close(s.omega[0], [0.0019675434304678827, -0.00030204714602129624,
                              0.0010185972564282057])
    assert close(s.omega[0], quat.rotate(s.q[0], [0.001, 0.0, 0.002]))
    assert np.array_equal(s.v[0], [0.004, -0.002, 0.0])
    assert np.allclose(model.particles.R_raw[:, 0], [14.2, 18.9, 13.5, 9.1])   # as given
    for _ in range(20):
        from kapsel import simulation
        simulation.advance(model)
    assert close(s.R_raw[0], [13.932417493922891, 15.946776221354508, 16.099907573416075])
    assert close(s.v[0], [0.0019226595104599757, -0.00088375800643216503,
                          -0.00052788308127702996], rel=1e-10)
    assert close(s.omega[0], [0.00075885741905007712, -0.00013793745319780749,
                              0.00045502014551254569], rel=1e-10)
    assert close(s.q[0], [-0.1372879699460377, 0.68270562698012627, -0.11486632132631298,
                          0.70842837917656087])


def test_quincke_rollers_keep_their_body_frame_omega_as_in_the_original(tmp_path):
    """Two one-bead Quincke rollers (ex12's document without walls and dipoles, 32^3, A = 2,
    dt 0.05): the user q is the body frame; Rigid_omega (0.0625, 0, 0) is about body x and
    switch.free_rigid keeps that component fixed (omega flags are body-frame) while the
    Quincke torque turns the axes; the original's state after 20 steps."""
    base = os.path.join(SAMPLES, "kapsel-udf", "ex12", "a2_N65_Rer025_dipole_mirror.udf")
    qa = [0.9238795325112867, 0.0, 0.3826834323650898, 0.0]
    qb = [0.8660254037844387, 0.0, 0.0, 0.5]
    puts = [p for p in FREE4[:10]] + [
        ("A", 2.0), ("A_XI", 2.0), ("switch.wall.type", "NONE"),
        ("switch.multipole.type", "OFF"), ("gravity.G", 0.0),
        ("object_type.rigid.Rigid_spec[0].Chain_number", 2),
        ("object_type.rigid.Rigid_spec[0].MASS_RATIO", 1.5),
        ("switch.INIT_orientation", "user_specify"),
        ("switch.INIT_distribution.user_specify.Particles[]",
         np.array([[10.0, 12.0, 14.0, 0, 0, 0] + qa + [0, 0, 0],
                   [21.0, 19.0, 17.5, 0, 0, 0] + qb + [0, 0, 0]]))]
    model = run_model(scene(tmp_path, base, puts), 0)
    s = model.particles.constraints.state
    assert np.allclose(s.q, [qa, qb]) and close(s.omega, quat.rotate(s.q, [[0.0625, 0, 0]] * 2))
    from kapsel import simulation
    for _ in range(20):
        simulation.advance(model)
    assert close(s.R_raw, [[10.000003147613075, 12.000002878754129, 13.999998569103647],
                           [21.000000617427645, 19.000000220323379, 17.499999687079299]])
    assert close(s.omega, [[0.045192642422919815, -0.070977567648278991, -0.043123707345148955],
                           [0.031250375990211694, 0.054126370658380968, 3.0939981346117164e-09]],
                 rel=1e-11)
    assert close(s.q, [[0.93245666324991061, 0.029012829842370778, 0.35992868140392703,
                        -0.011583227883938648],
                       [0.86560261732767851, 0.027059017756376005, 0.015622292241710278,
                        0.49975580278636839]])
    # held about body x within each update; the stored space-frame Omega is read in the
    # next step's frame, so it drifts slowly (the original's numbers above do the same)
    assert close(quat.to_body(s.q, s.omega)[:, 0], [0.0625, 0.0625], rel=1e-4)


def test_arch_of_overlapping_beads_follows_the_original(tmp_path):
    """ex10's rigid arch as its generator (Examples/10/init_config_arch.py) makes it: 13
    beads 3 apart on an arc of radius 18 (A = 4: they overlap), MASS_RATIO 1.5 under G = 50
    along -Y, ex10's document on 64 x 64 x 32, auto dt (factor 0.02).  Before the bodies
    followed the original (nominal 13-bead masses and gravity, overlaps counted twice) this
    run stopped at step 20 with CFL 4.4; now its grid mass (2908.42, nominal 5228) and
    velocities are the original's to round-off.  40 steps: 2.5 s CPU here."""
    import math
    base = os.path.join(SAMPLES, "kapsel-udf", "ex10", "input_rigid_free1.udf")
    arch = [[16.0 + 18.0 - 18.0 * math.cos(3.0 * i / 18.0), 32.0 - 18.0 * math.sin(3.0 * i / 18.0),
             16.0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0] for i in range(13)]
    puts = [("mesh.NPX", 6), ("mesh.NPY", 6), ("mesh.NPZ", 5),
            ("object_type.rigid.Rigid_spec[0].Beads_number", 13),
            ("switch.INIT_distribution.user_specify.Particles[]", np.array(arch))]
    model = run_model(scene(tmp_path, base, puts), 0)
    b = model.particles.constraints
    assert close(b.masses, [2908.4200466762504])
    assert close(np.diag(b.moments_body[0]), [369907.74732998246, 340363.35040120146,
                                              49729.016718842162])
    from kapsel import simulation
    s = b.state
    for step in range(1, 41):
        simulation.advance(model)
        if step == 20:
            assert close(s.R_raw[0], [26.264732122283348, 19.865019374279171, 16.0])
            assert close(s.v[0, :2], [0.031752491949987922, -0.31453191868045932])
            assert close(s.omega[0, 2], 0.0022939121069778033)
    assert close(s.R_raw[0], [26.266106086917986, 19.851951994907282, 16.0])
    assert close(s.v[0, :2], [0.064209898857513506, -0.59768310789382662])
    assert close(s.omega[0, 2], 0.0046731000734855357)
    assert np.abs(s.v[0, 2]) < 1e-15 and np.abs(s.omega[0, :2]).max() < 1e-15


def test_force_and_torque_summed_about_the_centre():
    """Euler at the first step, then the hydrodynamic force in full and the other forces by
    the trapezoid rule (rigid.h calc_Rigid_VOGs), Euler's equations in the body frame."""
    p, b = one_body(rod_shape(3, A))
    F = np.zeros((3, 3))
    F[2] = [0.0, 0.0, 2.0]                      # lifts the +x end: torque -y about the COM
    T = np.zeros((3, 3))
    T[1] = [0.5, 0.0, 0.0]
    Fo = np.tile([0.1, 0.0, 0.0], (3, 1))
    dt = 0.1
    M = p.mass.sum()
    I = b.inertia_space()[0]
    b.update_velocities(p, F, T, Fo, None, dt, True, first=True)
    torque = np.cross([8.0, 0.0, 0.0], F[2]) + T[1]
    assert np.allclose(b.state.v[0], [0.3 * dt / M, 0.0, 2.0 * dt / M])
    assert np.allclose(b.state.omega[0], np.linalg.solve(I, torque * dt))
    assert np.allclose(b.state.f_hydro[0], F.sum(axis=0))
    assert np.allclose(b.state.torque_hydro[0], torque)
    assert np.allclose(b.state.f_r[0], [0.3, 0.0, 0.0])
    r = p.R - b.state.R[0]
    assert np.allclose(p.v, b.state.v[0] + np.cross(b.state.omega[0], r))   # rigid beads
    assert np.allclose(p.omega, b.state.omega[0])
    v1 = b.state.v[0].copy()
    b.update_velocities(p, F, None, 2.0 * Fo, None, dt, True, first=False)
    assert np.allclose(b.state.v[0] - v1, [dt / M * (0.3 + 0.6) / 2, 0.0, 2.0 * dt / M])


def test_euler_equations_in_the_body_frame():
    """No torque: a spin about a principal axis stays; a torque along it adds dt T / I_axis
    per step; a general spin keeps |L| to O(dt^2) over 200 steps (explicit AB2)."""
    X = np.array([[-4.0, -2.0, 0.0], [4.0, -2.0, 0.0], [0.0, 4.0, 1.0], [1.0, 0.0, -3.0]])
    p, b = one_body(X - X.mean(axis=0))
    Rm = quat.to_matrix(b.state.q[0])
    Ib = np.diag(b.moments_body[0])
    zero = np.zeros((4, 3))
    b.state.omega[0] = 0.01 * Rm[:, 1]              # about body y
    for k in range(5):
        b.update_velocities(p, zero, zero, None, None, 0.1, True, first=k == 0)
    assert np.allclose(b.state.omega[0], 0.01 * Rm[:, 1], rtol=1e-12, atol=1e-15)
    T = np.zeros((4, 3))
    T[0] = 2.0 * Rm[:, 1]
    w0 = b.state.omega[0].copy()
    b.update_velocities(p, zero, T, None, None, 0.1, True, first=False)
    assert np.allclose(b.state.omega[0] - w0, 0.1 * 2.0 / Ib[1] * Rm[:, 1])
    b.state.omega[0] = [0.01, -0.02, 0.015]
    L0 = np.linalg.norm(b.inertia_space()[0] @ b.state.omega[0])
    for k in range(200):
        b.update_positions(p, 0.1, [32.0] * 3, True, first=k == 0)
        b.update_velocities(p, zero, zero, None, None, 0.1, True, first=k == 0)
    L = np.linalg.norm(b.inertia_space()[0] @ b.state.omega[0])
    assert L == pytest.approx(L0, rel=1e-3)


def test_fixed_rotation_keeps_the_shape_and_turns_by_omega_t():
    shape = np.array([[-4.0, -2.0, 0.0], [4.0, -2.0, 0.0], [0.0, 4.0, 1.0]])
    shape -= shape.mean(axis=0)
    w = np.array([0.0, 0.0, 0.05])
    p, b = one_body(shape, free=(False, False), v_fixed=(0.01, 0, 0))
    b.state.omega[0] = w                                    # a fixed body keeps it
    b.set_bead_velocities(p)
    d0 = np.linalg.norm(p.R_raw[:, None] - p.R_raw[None], axis=2)
    q0 = b.state.q[0].copy()
    dt, n = 0.1, 200
    zero = np.zeros((3, 3))
    for k in range(n):
        b.update_positions(p, dt, [32.0] * 3, True, first=k == 0)
        b.update_velocities(p, zero + 1.0, zero, None, None, dt, True, first=k == 0)
    d = np.linalg.norm(p.R_raw[:, None] - p.R_raw[None], axis=2)
    assert np.abs(d - d0).max() < 1e-10
    assert np.allclose(b.state.R_raw[0], [16.0 + 0.01 * dt * n, 16.0, 16.0])
    assert np.allclose(b.state.omega[0], w, rtol=1e-12)
    dq = quat.multiply(b.state.q[0], quat.conjugate(q0))
    angle = 2 * np.arctan2(np.linalg.norm(dq[1:]), dq[0])
    assert angle == pytest.approx(0.05 * dt * n, rel=1e-5)        # additive steps: O(dt^2)
    assert np.allclose(dq[1:] / np.linalg.norm(dq[1:]), [0, 0, 1])
    assert np.allclose(p.R_raw - b.state.R_raw[0],
                       quat.rotate(b.state.q[[0, 0, 0]], b.body_positions))


def test_free_rigid_components_are_honoured():
    """Velocity flags act on space-frame components, angular-velocity flags on body-frame
    ones (particle_rotation_solver.h: 'fixes angular velocity about rigid body frame')."""
    p = beads(2)
    b = RigidBodies.assemble(np.array([[8.0, 8, 8], [20.0, 20, 20]]), [0, 1], [0, 0],
                             p.mass, [[8.0, 8, 8], [20.0, 20, 20]],
                             p.inertia[:, None, None] * np.eye(3),
                             quat.from_axis_angle([[1.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                                                  np.array([0.6, 0.0])),
                             [[0.0, 0.3, 0.0], [0.1, 0.2, 0.3]], [[0.05, 0.0, -0.05], [0.0] * 3],
                             [[True, False, True], [False] * 3],
                             [[False, True, False], [True] * 3], [32.0] * 3)
    b.place_beads(p)
    F = np.ones((2, 3))
    for k in range(3):
        b.update_positions(p, 0.5, [32.0] * 3, True, first=k == 0)
        before = quat.to_body(b.state.q, b.state.omega)      # in the frame of the update
        b.update_velocities(p, F, F, None, None, 0.5, True, first=k == 0)
        wb = quat.to_body(b.state.q, b.state.omega)
        assert wb[0, [0, 2]] == pytest.approx(before[0, [0, 2]], rel=1e-12)
        assert wb[0, 1] != before[0, 1]
    v = b.state.v
    assert v[0, 1] == 0.3 and v[0, 0] > 0 and v[0, 2] > 0
    assert abs(wb[0, 0] - 0.05) < 1e-3 and abs(wb[0, 2] + 0.05) < 1e-3
    assert np.array_equal(v[1], [0.1, 0.2, 0.3])               # a 'fix' body's velocity
    assert np.all(b.state.omega[1] > 0)                        # ... with free rotation


def test_pair_forces_skip_the_beads_of_one_body():
    R = np.array([[10.0, 10, 10], [15.0, 10, 10], [10.0, 17.5, 10]])
    F_all, _, ratio = pair_forces(R, [32.0] * 3, [A] * 3, "12:6", 1.0, "ON")
    F, _, ratio_g = pair_forces(R, [32.0] * 3, [A] * 3, "12:6", 1.0, "ON", group=[0, 0, 1])
    assert np.abs(F_all[0, 0]).max() > 0 and ratio == pytest.approx(5 / 8)
    assert np.allclose(F[:, 0], 0.0)                            # the 0-1 pair is internal
    assert np.allclose(F[2], F_all[2]) and ratio_g == pytest.approx(7.5 / 8)


# ---------------------------------------------------------------- with the fluid
def spectral(L, dt):
    from kapsel.fluid.spectral import SpectralNS
    from kapsel.mesh.grid import Grid
    return SpectralNS(Grid((L,) * 3, 1.0), 1.0, 1.0, dt, fix_cell=(True,) * 3)


def mac(L, dt):
    from kapsel.fluid.mac import MACSolver
    from kapsel.mesh.grid import Grid
    return MACSolver(Grid((L,) * 3, 1.0), 1.0, 1.0, dt)


def angular_velocity(u, centre, r, axis_index):
    """Mean u_theta / r of the fluid on a circle of radius r about centre in the plane of
    the grid index ``axis_index`` along x."""
    from scipy.ndimage import map_coordinates
    th = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    y, z = centre[1] + r * np.cos(th), centre[2] + r * np.sin(th)
    uy = map_coordinates(u[1, axis_index], [y, z], order=1, mode="wrap")
    uz = map_coordinates(u[2, axis_index], [y, z], order=1, mode="wrap")
    return float(np.mean((-np.sin(th) * uy + np.cos(th) * uz) / r))


@pytest.mark.parametrize("solver", [spectral, mac])
def test_fixed_omega_body_drives_the_fluid_round(solver):
    dt, w = measured_dt(0.5, 1.0, 1.0, 1.0), 0.01
    p, b = one_body(rod_shape(2, A), free=(False, False))
    b.state.omega[0] = [w, 0.0, 0.0]          # about the dumbbell axis (body z), kept fixed
    b.set_bead_velocities(p)
    spm = SPM(solver(32, dt), p, A, XI, 1.0, 1.0, dt)
    spm.run(300)
    u = spm.velocity()
    centre = p.R[1]                                            # a bead at (20, 16, 16)
    inner = angular_velocity(u, centre, 3.0, 20) / w
    surface = angular_velocity(u, centre, A, 20) / w
    outer = angular_velocity(u, centre, 2 * A, 20) / w
    assert inner == pytest.approx(1.0, abs=0.02)               # rigid inside
    assert 0.8 < surface < 1.0                                 # ~ Omega at the surface
    assert 0.05 < outer < 0.2                                  # sphere (A/r)^3: 0.125
    assert b.state.torque_hydro[0, 0] < 0                      # the fluid resists
    assert b.state.torque_hydro[0, 0] == pytest.approx(-2 * 8 * np.pi * A ** 3 * w, rel=0.1)
    assert np.allclose(b.state.v, 0.0) and np.allclose(p.R_raw, [[12, 16, 16], [20, 16, 16]])


def sediment(nb, steps, L=32, factor=1.0, mass_ratio=1.5, G=0.002):
    dt = measured_dt(factor, 1.0, 1.0, 1.0)
    p0 = beads(nb, mass_ratio)
    g = gravity_force(p0.radius, [mass_ratio] * nb, 1.0, G, "-Z")
    p, b = one_body(rod_shape(nb, A), mass_ratio, centre=(L / 2,) * 3, L=L,
                    gravity=g.sum(axis=0, keepdims=True))     # the body's net gravity
    spm = SPM(spectral(L, dt), p, A, XI, 1.0, 1.0, dt)
    spm.run(steps)
    return b, -g[:, 2].sum()


def stokes(nb, F):
    """Unbounded Stokes velocity of one sphere, or of two touching spheres moving broadside
    (drag 2 x 0.716 x 6 pi ETA A, Stimson & Jeffery)."""
    return F / (6 * np.pi * A * (1.0 if nb == 1 else 2 * 0.716))


def test_free_dumbbell_sediments_along_gravity():
    b2, F2 = sediment(2, 400)
    b1, F1 = sediment(1, 400)
    v2, v1 = b2.state.v[0], b1.state.v[0]
    assert v2[2] < 0 and np.abs(v2[:2]).max() < 1e-3 * abs(v2[2])
    assert np.abs(b2.state.omega).max() < 1e-6
    # periodic images slow both down (Hasimoto, L = 32: a single bead ~0.65 of Stokes)
    r1, r2 = -v1[2] / stokes(1, F1), -v2[2] / stokes(2, F2)
    assert 0.5 < r1 < 0.7 and 0.4 < r2 < 0.7
    assert -v2[2] > -v1[2]                       # twice the weight, less than twice the drag


@pytest.mark.slow
def test_sedimenting_dumbbell_large_box():
    """L = 64, 3000 steps of measured_dt(1): prints the terminal velocity against Stokes."""
    b2, F2 = sediment(2, 3000, L=64)
    r2 = -b2.state.v[0, 2] / stokes(2, F2)
    print(f"dumbbell L=64: V = {b2.state.v[0]}, V / V_Stokes = {r2:.3f}")
    assert 0.6 < r2 < 0.95


def test_pinned_particles_neither_move_nor_turn():
    dt = measured_dt(1.0, 1.0, 1.0, 1.0)
    p = ParticleState.spheres([0, 0, 0], [A] * 3, [2.0] * 3, 1.0)
    p.R[:] = p.R_raw[:] = [[8.0, 8, 8], [24.0, 8, 8], [8.0, 24, 24]]
    p.constraints = Pinned(pin=[0], pin_rot=[1])
    F = np.tile([0.0, 0.0, -5.0], (3, 1))
    T = np.tile([0.0, 0.0, 2.0], (3, 1))
    R0 = p.R.copy()
    SPM(spectral(32, dt), p, A, XI, 1.0, 1.0, dt, forces=lambda q: (F, T)).run(100)
    assert np.array_equal(p.R[0], R0[0]) and np.all(p.v[0] == 0)   # pinned
    assert p.omega[0, 2] > 0                                       # but free to turn
    assert p.R[1, 2] < R0[1, 2] - 0.1 and p.omega[1, 2] == 0       # moves, does not turn
    assert p.R[2, 2] < R0[2, 2] - 0.1 and p.omega[2, 2] > 0        # free


# ---------------------------------------------------------------- input and runs


def test_bodies_built_from_the_input(tmp_path):
    cfg = config.load(rigid_input(tmp_path, [FREE3, (2, 2, 1.0, "fix", (0.1, 0, 0),
                                                     (0, 0, 0.02))],
                                  switch__INIT_orientation="random"))
    from kapsel.models.common import make_particles
    p = make_particles(cfg, np.random.default_rng(4))
    b = p.constraints
    assert p.n == 13 and b.nb == 5 and list(b.state.species) == [0, 0, 0, 1, 1]
    assert np.array_equal(b.body, [0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 4, 4])
    d = np.linalg.norm(p.R_raw[b.body == 0][1:] - p.R_raw[b.body == 0][:-1], axis=1)
    assert np.allclose(d, 2 * A)                               # touching beads
    from kapsel.particles.placement import overlapping_pairs
    i, j, _ = overlapping_pairs(p.R, p.radius * 0.999, cfg.mesh.box)
    assert len(i) == 0
    # Rigid_velocity in the space frame, Rigid_omega in the body frame (rigid.h init_set_vGs)
    w = quat.rotate(b.state.q[3:], [[0, 0, 0.02]] * 2)
    assert np.allclose(b.state.v[3:], [0.1, 0, 0]) and np.allclose(b.state.omega[3:], w)
    assert np.allclose(b.state.v[:3], 0.0)
    # generated rods: nominal masses, the rod along its body z axis
    assert np.allclose(b.masses, [3 * p.mass[0]] * 3 + [2 * p.mass[-1]] * 2)
    assert np.allclose(np.abs(b.body_positions[:3, 2]), [2 * A, 0.0, 2 * A])
    # the fixed bodies' beads start with their rigid velocity
    r = p.R_raw[b.body == 3] - b.state.R_raw[3]
    assert np.allclose(p.v[b.body == 3], [0.1, 0, 0] + np.cross(w[0], r))


def test_user_specified_body_shape(tmp_path):
    X = [[10.0, 10, 10], [17.0, 10, 10], [10.0, 17, 10]]
    parts = np.array([x + [0.0, 0, 0, 1, 0, 0, 0, 0, 0, 0] for x in X])
    cfg = config.load(rigid_input(tmp_path, [(3, 1, 1.0, "free", (0, 0, 0), (0, 0, 0))],
                                  switch__INIT_distribution__type="user_specify",
                                  raw={"switch.INIT_distribution.user_specify.Particles[]":
                                       parts}))
    from kapsel.models.common import make_particles
    p = make_particles(cfg, np.random.default_rng(1))
    assert np.allclose(p.R, X)                       # the beads stay where they are given
    b = p.constraints
    # the centre and mass of the union of the (overlapping) beads' profiles
    assert np.allclose(b.state.R[0], np.mean(X, axis=0), atol=0.05)
    assert p.mass[0] < b.masses[0] < 3 * p.mass[0]
    assert np.allclose(quat.rotate(b.state.q[b.body], b.body_positions) + b.state.R[0], X)


@pytest.mark.parametrize("puts, path", [
    (dict(switch__pin__type="YES"), "switch.pin.type"),
    (dict(switch__free_rigid__type="YES",
          switch__free_rigid__YES__DOF=[[3, ["NO", "NO", "NO"], ["NO", "NO", "YES"]]]),
     "switch.free_rigid.YES.DOF[0].spec_id"),
    (dict(switch__INIT_distribution__type="FCC"), "switch.INIT_distribution.type"),
])
def test_unsupported_rigid_options_are_named(tmp_path, puts, path):
    with pytest.raises(config.ConfigError, match=path.replace("[", r"\[").replace("]", r"\]")):
        config.load(rigid_input(tmp_path, [FREE3], **puts))


def test_free_rigid_acts_on_rigid_bodies_only(tmp_path):
    """As the original (PHYSICS-EXTRA §1.2): switch.free_rigid is read for spheres too, and
    ignored: it only acts when object_type is rigid."""
    copy_schema(tmp_path)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put("YES", "switch.free_rigid.type")
    u.write(str(tmp_path / "s.udf"))
    assert config.load(str(tmp_path / "s.udf")).switches.free_rigid == ()


def test_a_body_longer_than_the_box_is_refused_before_anything_is_built(tmp_path):
    with pytest.raises(config.ConfigError) as e:
        config.load(rigid_input(tmp_path, [(5, 1, 1.0, "free", (0, 0, 0), (0, 0, 0))]))
    msg = str(e.value)
    assert "a rigid body of 5 beads of radius 4 is a rod of length 40, which does not fit " \
           "in the box 32 x 32 x 32" in msg and "np." not in msg


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Navier_Stokes_FDM"])
def test_kapsel_py_runs_rigid_bodies_and_writes_rigid_particles(tmp_path, eq):
    rigid_input(tmp_path, [FREE3, (2, 1, 1.0, "fix", (0, 0, 0), (0, 0, 0.02))], eq=eq,
                gravity__G=0.002, gravity__G_direction="-Z", output__GTS=10,
                output__Num_snap=2)
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", "-Irigid.udf", "-Oout.udf",
                        "-Ddefine.udf", "-Rrestart.udf", "--seed", "3", "--quiet"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    u = UDFManager(str(tmp_path / "out.udf"))
    assert u.totalRecord() == 3
    u.jump(2)
    assert u.size("Particles[]") == 11 and u.size("RigidParticles[]") == 4
    R = np.array(u.getArray("Particles[].R_raw"))
    G = np.array(u.getArray("RigidParticles[].R_raw"))
    V = np.array(u.getArray("RigidParticles[].v"))
    W = np.array(u.getArray("RigidParticles[].omega"))
    assert np.allclose(G[:3], R[:9].reshape(3, 3, 3).mean(axis=1), atol=1e-4)
    assert np.all(V[:3, 2] < 0)                                 # sediment along -Z
    # the fixed body turns at |Rigid_omega| about its body z, a constant space axis
    u.jump(0)
    W0 = np.array(u.getArray("RigidParticles[].omega"))
    assert np.linalg.norm(W[3]) == pytest.approx(0.02, rel=1e-6)
    assert np.allclose(W[3], W0[3], atol=1e-7) and np.allclose(V[3], 0.0)
    e = subprocess.run([sys.executable, "-m", "kapsel.cli", "analyze", "erotate", "out.udf"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert e.returncode == 0, e.stderr
    last = e.stdout.strip().splitlines()[-1].split()
    assert len(last) == 3 + 4
    # analyze erotate takes the beads as point masses (spec 002 eq 2): the fixed body spins
    # about its own axis, on which its two beads lie, so its energy is 0 there
    assert abs(float(last[-1])) < 1e-20 and max(map(float, last[3:6])) > 0
    # rotational_energy.dat: 1/2 Omega . I_g Omega with the body's own moments (the
    # original's I_g^B of its profile, GR_moments_body[], the ones its motion uses)
    rows = np.loadtxt(tmp_path / "rotational_energy.dat", ndmin=2)
    assert rows.shape == (3, 2 + 1 + 4)
    assert np.allclose(rows[:, 2], rows[:, 3:].sum(axis=1))
    rs = UDFManager(str(tmp_path / "restart.udf"))
    kind = rs.get("resume.Calculation")
    Ib = np.asarray(rs.getArray(f"resume.{kind}.Saved_Data.GR_moments_body[]"),
                    dtype=float).reshape(-1, 3, 3)[3]
    axial = float(np.linalg.eigvalsh(0.5 * (Ib + Ib.T))[0])      # a rod's smallest moment
    assert rows[-1, -1] == pytest.approx(0.5 * axial * float(W[3] @ W[3]), rel=1e-5)


def test_continuation_of_rigid_bodies_is_bit_identical(tmp_path):
    """N steps + restart + M steps = N + M steps, bit for bit in double precision (the
    final restart's body rows and the state file); the restart holds one Particles[] row
    per body (the original's layout) and GR_body, GR_masses, GR_moments_body; without the
    state file the bodies continue from their rows."""
    from kapsel.cli import main
    from kapsel.io.restart import state_path

    def cli(d, inp):
        cwd = os.getcwd()
        os.chdir(d)
        try:
            return main([f"-I{inp}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf",
                         "--seed", "5", "--quiet"])
        finally:
            os.chdir(cwd)
    specs = [FREE3, (2, 1, 1.0, "fix", (0.01, 0, 0), (0, 0, 0.02))]
    kw = dict(eq="Navier_Stokes_FDM", gravity__G=0.002, gravity__G_direction="-Z",
              switch__INIT_orientation="random", output__GTS=3,
              constitutive_eq__Navier_Stokes_FDM__kBT=0.0)
    for d, n in (("one", 4), ("two", 2)):
        os.makedirs(tmp_path / d)
        rigid_input(tmp_path / d, specs, output__Num_snap=n, **kw)
        assert cli(tmp_path / d, "rigid.udf") == 0
    rs = UDFManager(str(tmp_path / "two" / "restart.udf"))
    base = "resume.CONTINUE_FDM.Saved_Data"
    assert np.array(rs.getArray(f"{base}.GR_body[]")).shape == (11, 3)
    assert np.array(rs.getArray(f"{base}.GR_masses[]")).shape == (4,)
    assert np.array(rs.getArray(f"{base}.GR_moments_body[]")).shape == (4, 9)
    assert np.array(rs.getArray(f"{base}.Particles[]"), dtype=object).shape[0] == 4
    rs.put(4, "output.Num_snap")
    rs.write(str(tmp_path / "two" / "cont.udf"))
    rs.write(str(tmp_path / "two" / "bare.udf"))                 # without a state file
    shutil.copy(state_path(str(tmp_path / "two" / "restart.udf")),
                state_path(str(tmp_path / "two" / "cont.udf")))
    assert cli(tmp_path / "two", "cont.udf") == 0

    def last(path):
        u = UDFManager(str(path))
        u.jump(u.totalRecord() - 1)
        return (u.get("t"), np.array(u.getArray("Particles[].R")),
                np.array(u.getArray("RigidParticles[].R")),
                np.array(u.getArray("RigidParticles[].omega")))
    a, b = last(tmp_path / "one" / "output.udf"), last(tmp_path / "two" / "output.udf")
    assert a[0] == b[0] and all(np.array_equal(x, y) for x, y in zip(a[1:], b[1:]))
    ra, rb = (UDFManager(str(tmp_path / d / "restart.udf")) for d in ("one", "two"))
    for m in ("R", "v", "v_old", "omega", "omega_old", "q", "q_old",
              "f_hydro_previous", "torque_hydro_previous", "fr_previous"):
        x = np.array(ra.getArray(f"{base}.Particles[].{m}"), dtype=float)
        assert x.shape[0] == 4 and np.array_equal(
            x, np.array(rb.getArray(f"{base}.Particles[].{m}"), dtype=float)), m
    sa, sb = (np.load(state_path(str(tmp_path / d / "restart.udf"))) for d in ("one", "two"))
    for k in sa.files:
        if k.startswith("rigid_") or k == "R_raw":
            assert np.array_equal(sa[k], sb[k]), k
    # from the schema data alone the bodies continue where the beads are
    os.makedirs(tmp_path / "bare")
    for f in ("define.udf", "kapsel_unit.udf", "bare.udf"):
        shutil.copy(tmp_path / "two" / f, tmp_path / "bare" / f)
    assert cli(tmp_path / "bare", "bare.udf") == 0
    c = last(tmp_path / "bare" / "output.udf")
    assert c[0] == a[0]
    assert np.abs(c[2] - a[2]).max() < 1e-5 and np.abs(c[3] - a[3]).max() < 1e-7
