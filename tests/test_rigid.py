"""Rigid bodies of beads (kapsel.particles.rigid), switch.free_rigid and switch.pin.

Measured (spectral, L = 32, A = 4, xi = 2; dumbbell = 2 touching beads along x):
* fixed Omega_x = 0.01 about the dumbbell axis, 300 steps of measured_dt(0.5): fluid angular
  velocity u_theta / (r Omega) around a bead, r = 3: 1.000, r = A: 0.897, r = 2A: 0.104
  (an isolated sphere: 1, 1, 0.125); hydrodynamic torque -31.9 (two isolated spheres
  8 pi ETA A^3 Omega each: -32.2);
* free dumbbell, MASS_RATIO 1.5, G = 0.002 along -Z, measured_dt(1): velocity along -Z only
  (other components < 3e-5 of it, |Omega| < 1e-9).  V / V_Stokes (unbounded, two touching
  spheres broadside, drag 2 x 0.716 x 6 pi ETA A): L = 32, 400 steps 0.478 (a one-bead body:
  0.634, Hasimoto for L = 32 gives 0.653); L = 64, 3000 steps (slow test, 66 s) 0.754, where
  the first-order periodic correction F (1/drag - 1.7601 / (6 pi ETA L)) gives 0.842.
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
from kapsel.particles.rigid import RigidBodies, build_bodies, rod_shape
from kapsel.particles.spm import SPM
from kapsel.particles.state import ParticleState
from udf import UDFManager

SAMPLES = os.path.join(os.path.dirname(__file__), "..", "samples")
A, XI = 4.0, 2.0


def measured_dt(factor, rho, eta, dx):
    """The time step these measurements were made at: factor RHO / (ETA (pi / DX)^2).  (Not
    the automatic time step of a run, kapsel.timestep.auto_dt; a fixed dt keeps the tables
    in the comments valid.)"""
    return factor * rho / (eta * (np.pi / dx) ** 2)


def beads(nb, mass_ratio=1.0):
    return ParticleState.spheres([0] * nb, [A] * nb, [mass_ratio] * nb, 1.0)


def one_body(shape, mass_ratio=1.0, free=(True, True), v_fixed=(0, 0, 0), o_fixed=(0, 0, 0),
             centre=(16.0, 16.0, 16.0), q=None, L=32):
    nb = len(shape)
    p = beads(nb, mass_ratio)
    b = RigidBodies(np.zeros(nb, int), shape, p.mass, p.inertia, [0], np.array([centre]),
                    quat.identity(1) if q is None else q, [[free[0]] * 3], [[free[1]] * 3],
                    [v_fixed], [o_fixed], [L] * 3)
    b.place_beads(p)
    p.constraints = b
    return p, b


# ---------------------------------------------------------------- body geometry (no fluid)
def test_com_masses_and_inertia_from_beads():
    X = np.array([[1.0, 2.0, 3.0], [9.0, 2.0, 3.0], [1.0, 10.0, 3.0], [1.0, 2.0, 11.0]])
    m = np.array([1.0, 2.0, 3.0, 4.0])
    Ik = 0.4 * m * A ** 2
    b = RigidBodies.from_beads(X, [0, 0, 0, 0], m, Ik, [0], [[True] * 3], [[True] * 3],
                               [[0.0] * 3], [[0.0] * 3], [32.0] * 3)
    I2, com = inertia_tensor(m, X)                             # spec 002 eq 2
    assert np.allclose(b.state.R[0], com)
    assert b.masses[0] == pytest.approx(10.0)
    assert np.allclose(b.moments_body[0], I2 + Ik.sum() * np.eye(3))
    assert np.allclose((m[:, None] * b.body_positions).sum(axis=0), 0.0, atol=1e-12)
    # the same body across the periodic boundary: unwrapped about its first bead
    Y = np.mod(X + [28.0, 0.0, 0.0], 32.0)
    c = RigidBodies.from_beads(Y, [0, 0, 0, 0], m, Ik, [0], [[True] * 3], [[True] * 3],
                               [[0.0] * 3], [[0.0] * 3], [32.0] * 3)
    assert np.allclose(c.body_positions, b.body_positions)
    assert np.allclose(c.moments_body, b.moments_body)


def test_rod_inertia_and_rotational_energy():
    p, b = one_body(rod_shape(3, A))
    m = p.mass[0]
    spin = 3 * 0.4 * m * A ** 2
    assert np.allclose(np.diag(b.moments_body[0]), [spin, spin + 2 * m * 64, spin + 2 * m * 64])
    # rotated body: I_g = R I^B R^T and E = 1/2 w.I w (eqs 3-5)
    q = quat.from_axis_angle([[1.0, 2.0, -0.5]], np.array([0.7]))
    p, b = one_body(rod_shape(3, A), q=q)
    b.state.omega[:] = [[0.01, -0.02, 0.03]]
    I, _ = inertia_tensor(p.mass, p.R_raw)
    I = I + spin * np.eye(3)
    assert np.allclose(b.inertia_space()[0], I)
    w = b.state.omega[0]
    assert b.rotational_energies()[0] == pytest.approx(0.5 * w @ I @ w, rel=1e-12)
    # a one-bead body: the scalar form 1/2 I |w|^2 (eq 6)
    p, b = one_body(np.zeros((1, 3)))
    b.state.omega[:] = [[0.1, 0.2, 0.3]]
    assert b.rotational_energies()[0] == pytest.approx(0.5 * p.inertia[0] * 0.14, rel=1e-12)


def test_record_energy_holds_body_translation_and_rotation():
    """E (common.kinetic_energy) sums the beads: 1/2 M V^2 + E_rot of every body."""
    from kapsel.models.common import kinetic_energy
    q = quat.from_axis_angle([[0.3, -1.0, 0.5]], np.array([1.1]))
    p, b = one_body(rod_shape(3, A), free=(False, False), v_fixed=(0.01, -0.02, 0.005),
                    o_fixed=(0.003, 0.001, -0.002), q=q)
    e = kinetic_energy(1.0, 1.0, np.zeros((3, 4, 4, 4)), None, p)
    V = b.state.v[0]
    assert e == pytest.approx(0.5 * b.masses[0] * V @ V + b.rotational_energies()[0],
                              rel=1e-12)


def test_force_and_torque_summed_about_the_centre():
    p, b = one_body(rod_shape(3, A))
    F = np.zeros((3, 3))
    F[2] = [0.0, 0.0, 2.0]                      # lifts the +x end: torque -y about the COM
    T = np.zeros((3, 3))
    T[1] = [0.5, 0.0, 0.0]
    dt = 0.1
    b.update_velocities(p, F, T, None, None, dt, True)
    M = p.mass.sum()
    I = b.moments_body[0]
    assert np.allclose(b.state.v[0], [0.0, 0.0, 2.0 * dt / M])
    torque = np.cross([8.0, 0.0, 0.0], F[2]) + T[1]
    assert np.allclose(b.state.omega[0], np.linalg.solve(I, torque * dt))
    assert np.allclose(b.state.f_hydro[0], F.sum(axis=0))
    assert np.allclose(b.state.torque_hydro[0], torque)
    r = p.R - b.state.R[0]
    assert np.allclose(p.v, b.state.v[0] + np.cross(b.state.omega[0], r))   # rigid beads
    assert np.allclose(p.omega, b.state.omega[0])


def test_fixed_rotation_keeps_the_shape_and_turns_by_omega_t():
    shape = np.array([[-4.0, -2.0, 0.0], [4.0, -2.0, 0.0], [0.0, 4.0, 1.0]])
    shape -= shape.mean(axis=0)
    w = np.array([0.0, 0.0, 0.05])
    p, b = one_body(shape, free=(False, False), v_fixed=(0.01, 0, 0), o_fixed=w)
    d0 = np.linalg.norm(p.R_raw[:, None] - p.R_raw[None], axis=2)
    dt, n = 0.1, 200
    zero = np.zeros((3, 3))
    for _ in range(n):
        b.update_velocities(p, zero + 1.0, zero, None, None, dt, True)   # forces ignored
        b.update_positions(p, dt, [32.0] * 3, True)
    d = np.linalg.norm(p.R_raw[:, None] - p.R_raw[None], axis=2)
    assert np.abs(d - d0).max() < 1e-10
    assert np.allclose(b.state.R_raw[0], [16.0 + 0.01 * dt * n, 16.0, 16.0])
    angle = 2 * np.arctan2(np.linalg.norm(b.state.q[0, 1:]), b.state.q[0, 0])
    assert angle == pytest.approx(0.05 * dt * n, rel=1e-12)
    assert np.allclose(p.R_raw - b.state.R_raw[0], quat.rotate(b.state.q[[0, 0, 0]], shape))


def test_free_rigid_components_are_honoured():
    nb = 2
    p = beads(nb)
    b = RigidBodies(np.array([0, 1]), np.zeros((2, 3)), p.mass, p.inertia, [0, 0],
                    np.array([[8.0, 8, 8], [20.0, 20, 20]]), quat.identity(2),
                    [[True, False, True], [False] * 3], [[False, True, False], [True] * 3],
                    [[0.0, 0.3, 0.0], [0.1, 0.2, 0.3]], [[0.05, 0.0, -0.05], [0.0] * 3],
                    [32.0] * 3)
    b.place_beads(p)
    F = np.ones((2, 3))
    for _ in range(3):
        b.update_velocities(p, F, F, None, None, 0.5, True)
    v, w = b.state.v, b.state.omega
    assert v[0, 1] == 0.3 and v[0, 0] > 0 and v[0, 2] > 0
    assert w[0, 0] == 0.05 and w[0, 2] == -0.05 and w[0, 1] > 0
    assert np.array_equal(v[1], [0.1, 0.2, 0.3])               # a 'fix' body's velocity
    assert np.all(w[1] > 0)                                    # ... with free rotation


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
    from kapsel.grid import Grid
    return SpectralNS(Grid((L,) * 3, 1.0), 1.0, 1.0, dt, fix_cell=(True,) * 3)


def mac(L, dt):
    from kapsel.fluid.mac import MACSolver
    return MACSolver((L,) * 3, 1.0, 1.0, 1.0, dt)


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
    p, b = one_body(rod_shape(2, A), free=(False, False), o_fixed=(w, 0.0, 0.0))
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
    p, b = one_body(rod_shape(nb, A), mass_ratio, centre=(L / 2,) * 3, L=L)
    g = gravity_force(p.radius, [mass_ratio] * nb, 1.0, G, "-Z")
    spm = SPM(spectral(L, dt), p, A, XI, 1.0, 1.0, dt, forces=lambda q: (g, 0 * g))
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
def rigid_input(tmp_path, specs, eq="Navier_Stokes", name="rigid.udf", raw=None, **puts):
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(SAMPLES, f), tmp_path / f)
    u = UDFManager(os.path.join(SAMPLES, "input.udf"))
    u.put(eq, "constitutive_eq.type")
    u.put("rigid", "object_type.type")
    u.put([[nb, n, mr, 0.0, motion, list(v), list(w)] for nb, n, mr, motion, v, w in specs],
          "object_type.rigid.Rigid_spec[]")
    u.put("ON", "switch.LJ_truncate")
    for path, value in puts.items():
        u.put(value, path.replace("__", "."))
    for path, value in (raw or {}).items():
        u.put(value, path)
    u.write(str(tmp_path / name))
    return str(tmp_path / name)


FREE3 = (3, 3, 1.5, "free", (0, 0, 0), (0, 0, 0))


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
    assert np.allclose(b.state.v[3:], [0.1, 0, 0]) and np.allclose(b.state.omega[3:], [0, 0, 0.02])
    assert np.allclose(b.state.v[:3], 0.0)
    # the fixed bodies' beads start with their rigid velocity
    r = p.R_raw[b.body == 3] - b.state.R_raw[3]
    assert np.allclose(p.v[b.body == 3], [0.1, 0, 0] + np.cross([0, 0, 0.02], r))


def test_user_specified_body_shape(tmp_path):
    X = [[10.0, 10, 10], [17.0, 10, 10], [10.0, 17, 10]]
    parts = np.array([x + [0.0, 0, 0, 1, 0, 0, 0, 0, 0, 0] for x in X])
    cfg = config.load(rigid_input(tmp_path, [(3, 1, 1.0, "free", (0, 0, 0), (0, 0, 0))],
                                  switch__INIT_distribution__type="user_specify",
                                  raw={"switch.INIT_distribution.user_specify.Particles[]":
                                       parts}))
    from kapsel.models.common import make_particles
    p = make_particles(cfg, np.random.default_rng(1))
    assert np.allclose(p.R, X)
    assert np.allclose(p.constraints.state.R[0], np.mean(X, axis=0))


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
    for f in ("define.udf", "kapsel_unit.udf"):
        shutil.copy(os.path.join(SAMPLES, f), tmp_path / f)
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
    assert np.allclose(W[3], [0, 0, 0.02]) and np.allclose(V[3], 0.0)
    e = subprocess.run([sys.executable, "-m", "kapsel.cli", "analyze", "erotate", "out.udf"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert e.returncode == 0, e.stderr
    last = e.stdout.strip().splitlines()[-1].split()
    assert len(last) == 3 + 4 and float(last[-1]) > 0           # the spinning body
    # each record's rotational energies (spec 002 eqs 3-7) in rotational_energy.dat
    rows = np.loadtxt(tmp_path / "rotational_energy.dat", ndmin=2)
    assert rows.shape == (3, 2 + 1 + 4)
    assert np.allclose(rows[:, 2], rows[:, 3:].sum(axis=1))
    assert rows[-1, -1] > 0 and rows[-1, -1] == pytest.approx(float(last[-1]), rel=0.5)


def test_continuation_of_rigid_bodies_is_bit_identical(tmp_path):
    """N steps + restart + M steps = N + M steps (body state in the state file); the
    restart holds GR_body, GR_masses, GR_moments_body; without the state file the bodies
    are rebuilt from the beads."""
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
    # from the schema data alone the bodies continue where the beads are
    os.makedirs(tmp_path / "bare")
    for f in ("define.udf", "kapsel_unit.udf", "bare.udf"):
        shutil.copy(tmp_path / "two" / f, tmp_path / "bare" / f)
    assert cli(tmp_path / "bare", "bare.udf") == 0
    c = last(tmp_path / "bare" / "output.udf")
    assert c[0] == a[0]
    assert np.abs(c[2] - a[2]).max() < 1e-5 and np.abs(c[3] - a[3]).max() < 1e-7
