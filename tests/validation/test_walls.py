"""Flat walls (switch.wall FLAT, kapsel.particles.walls; PHYSICS-EXTRA.md §2).

Measured (4 x 4 x 32 mesh, walls DH = 4 normal to the 32-point axis, DX = RHO = ETA = 1,
dt = 0.1, body force g = 1e-3 along the walls, from rest; the gap is h = L - DH DX = 28, the
distance between the two phi_wall = 1/2 planes, and the analytic mean velocity over the gap
is g h^2 / (12 nu) = 0.06533): after 5000 steps the flux / h is 0.06590 (spectral, +0.9 %)
and 0.06648 (MAC explicit, +1.8 %); the profile's peak g h_eff^2 / (8 nu) gives an effective
gap h_eff = 28.16, i.e. the no-slip planes sit 0.08 DX inside the solid's interface.
"""
import math
import os
import types

import numpy as np
import pytest

from kapsel import config
from kapsel.fluid.mac import MACSolver
from kapsel.fluid.spectral import SpectralNS
from kapsel.mesh.grid import Grid
from kapsel.models.fdm import _ModelH_SPM
from kapsel.particles import forces as pf
from kapsel.particles import quaternion as quat
from kapsel.particles.rigid import RigidBodies
from kapsel.particles.spm import SPM
from kapsel.particles.state import ParticleState
from kapsel.particles.walls import FlatWall

from builders import copy_schema, EX14, wall_run_input


def no_particles():
    return ParticleState.spheres([], [], [], 1.0)


def channel(axis, n=32, across=4):
    shape = [across] * 3
    shape[axis] = n
    return tuple(shape)


@pytest.mark.parametrize("solver,axis,steps", [("spectral", 0, 4000), ("mac", 2, 3400)])
def test_pressure_driven_flow_between_walls_is_parabolic(solver, axis, steps):
    """Poiseuille flow from rest: mean velocity over the gap h = L - DH DX within 3 % of
    g h^2 / (12 nu) (measured 0.14 % below (spectral), 2.3 % above (MAC)); the profile is
    the parabola.  The walls hold the fluid by the SPM rigidity of the original (the solid
    a body at rest; its projection leaves a little velocity in the solid: measured 0.59 %
    (spectral) and 0.53 % (MAC) of max|u| at the end, below 0.8 % after the first step)."""
    shape, dt, g = channel(axis), 0.1 if solver == "spectral" else 0.15, 1e-3
    fa = (axis + 1) % 3                       # flow direction, along the walls
    wall = FlatWall(axis, 4, shape, 1.0, 2.0)
    if solver == "spectral":
        fluid = SpectralNS(Grid(shape, 1.0), 1.0, 1.0, dt)
        F = np.zeros(3)
        F[fa] = g
        fluid.set_force(F)
        spm = SPM(fluid, no_particles(), 4.0, 2.0, 1.0, 1.0, dt, wall=wall)
        step_args = {}
    else:
        spm = _ModelH_SPM(MACSolver(Grid(shape, 1.0), 1.0, 1.0, dt), no_particles(), 4.0, 2.0, 1.0,
                          1.0, dt, wall=wall)
        f = np.zeros((3,) + shape)
        f[fa] = g
        step_args = {"force": f}
    solid = wall.solid()
    for k in range(steps):
        spm.step(**step_args)
        if k % 500 == 0 and k:
            u = spm.velocity()
            assert np.abs(u[:, solid]).max() < 0.01 * np.abs(u).max()
    u = spm.velocity()
    prof = u[fa].mean(axis=tuple(a for a in range(3) if a != axis))
    h = wall.gap
    assert h == 28.0
    mean = prof.sum() / h                     # flux per unit width / gap
    assert mean == pytest.approx(g * h * h / 12.0, rel=0.03)
    z = np.arange(32) + 0.0
    fluid_nodes = (z > wall.lo + 1.5) & (z < wall.hi - 1.5)
    parab = g / 2.0 * (z - wall.lo) * (wall.hi - z)
    err = np.abs(prof[fluid_nodes] - parab[fluid_nodes]).max()
    assert err < 0.03 * parab.max()
    assert np.abs(u[:, solid]).max() < 0.01 * np.abs(u).max()
    assert np.abs(u[axis]).max() < 1e-12      # no flow through the walls


def test_wall_profile_is_the_same_for_every_axis_and_dx():
    """phi_wall follows the coordinate along the wall's own axis (the original picks the
    side of its wall gradient from the z index, right only for Z walls at DX = 1)."""
    wz = FlatWall(2, 4, (8, 8, 32), 1.0, 2.0)
    for axis in (0, 1):
        w = FlatWall(axis, 4, channel(axis, 32, 8), 1.0, 2.0)
        assert np.array_equal(np.moveaxis(w.phi, axis, 2), wz.phi)
    w2 = FlatWall(2, 4, (4, 4, 16), 2.0, 4.0)            # DX = 2: every length doubled
    assert w2.lo == 4.0 and w2.hi == 28.0
    assert np.allclose(w2.profile, FlatWall(2, 4, (4, 4, 16), 1.0, 2.0).profile)
    for w in (wz, w2):
        # 1 in the solid, 1/2 on the faces, 0 in the fluid; symmetric about the box centre
        assert np.allclose(w.profile, np.roll(w.profile[::-1], 1))
        r = w.r
        assert np.all(w.profile[(r < w.lo - w.xi / 2) | (r > w.hi + w.xi / 2)] == 1.0)
        assert np.all(w.profile[(r > w.lo + w.xi / 2) & (r < w.hi - w.xi / 2)] == 0.0)
        # |grad phi_wall|^2 lies on the two faces only, the same on both
        g2 = np.moveaxis(w.grad_phi_sq(), 2, 0)[:, 0, 0]
        assert np.allclose(g2, np.roll(g2[::-1], 1)) and g2.max() > 0
        assert np.all(g2[(r > w.lo + w.xi) & (r < w.hi - w.xi)] == 0)
        # the gradient of phi_wall points into the solid on both sides, for every axis
        grad = np.gradient(w.profile, w.dx)
        assert np.all(grad[(r > w.lo - w.xi) & (r < w.lo + w.xi)] <= 0)
        assert np.all(grad[(r > w.hi - w.xi) & (r < w.hi + w.xi)] >= 0)


@pytest.mark.parametrize("powers,truncate", [("12:6", "ON"), ("36:18", "ON"), ("12:6", "OFF"),
                                             ("24:12", "OFF")])
def test_wall_force_is_minus_the_gradient_of_the_wall_energy(powers, truncate):
    wall = FlatWall(2, 4, (32, 32, 32), 1.0, 2.0, powers, 3.0, truncate)
    a = 4.0
    rng = np.random.default_rng(1)
    z = np.concatenate([wall.lo + a + rng.uniform(-0.3, 3.0, 6),
                        wall.hi - a - rng.uniform(-0.3, 3.0, 6)])
    R = np.stack([rng.uniform(0, 32, 12), rng.uniform(0, 32, 12), z], axis=1)
    F, U, ratio = wall.forces(R, a)
    assert np.all(F[:, :2] == 0)
    assert np.all(F[:6, 2] >= 0) or truncate == "OFF"     # pushed away from the lower wall
    assert np.all(F[6:, 2] <= 0) or truncate == "OFF"
    assert np.any(F[:6, 2] > 0) and np.any(F[6:, 2] < 0)
    h = 1e-6
    for k in range(len(R)):
        up, dn = R.copy(), R.copy()
        up[k, 2] += h
        dn[k, 2] -= h
        dU = (wall.energy(up, a) - wall.energy(dn, a)) / (2 * h)
        assert -dU == pytest.approx(F[k, 2], rel=1e-5, abs=1e-7)
    # a particle touching the face feels the pair force of two particles at contact
    touch = np.array([[5.0, 5.0, wall.lo + 0.9 * a]])
    Ft = wall.forces(touch, a)[0][0, 2]
    assert Ft == pytest.approx(pf.pair_force_magnitude(1.9 * a, 2 * a, powers, 3.0, truncate))


def test_wall_torque_adds_to_the_pair_torque_of_a_rigid_body():
    """The original assigns the wall torque GRvec[I] x F to a rigid body, overwriting the LJ
    torque accumulated before; here each bead's wall force acts at the bead."""
    from kapsel.models.common import make_forces
    A, L = 4.0, 32
    shape = np.array([[-4.0, 0, 0], [4.0, 0, 0]])          # dumbbell along x
    beads = ParticleState.spheres([0, 0, 0], [A] * 3, [1.0] * 3, 1.0)
    wall = FlatWall(2, 4, (L, L, L), 1.0, 2.0, "12:6", 1.0, "ON")
    # body centre low enough that both beads feel the lower wall; a free third sphere
    # presses on the +x bead from above
    zc = wall.lo + 0.95 * A
    b = RigidBodies.nominal(np.array([0, 0]), shape, beads.mass[:2], beads.inertia[:2], [0],
                    np.array([[16.0, 16.0, zc]]), quat.identity(1), [[True] * 3],
                    [[True] * 3], [[0, 0, 0]], [[0, 0, 0]], [L] * 3)
    p2 = ParticleState.spheres([0, 0], [A] * 2, [1.0] * 2, 1.0)
    b.place_beads(p2)
    R = np.vstack([p2.R, [[21.0, 16.0, zc + 1.9 * A]]])
    inter = types.SimpleNamespace(LJ_truncate="ON", EPSILON=1.0, LJ_powers="12:6", G=0.0,
                                  G_direction="-Z")
    cfg = types.SimpleNamespace(interactions=inter, mesh=types.SimpleNamespace(box=[L] * 3),
                                particles=types.SimpleNamespace(object_type="rigid"))
    beads.R[:] = R
    beads.constraints = types.SimpleNamespace(body=np.array([0, 0, -1]))
    forces = make_forces(cfg, beads, wall=wall)
    F, T = forces(beads)
    Fw = wall.forces(R, A)[0]
    Fp = pf.pair_forces(R, [L] * 3, [A] * 3, "12:6", 1.0, "ON", group=[0, 0, -1])[0]
    assert np.allclose(F, Fw + Fp)
    assert abs(Fp[1, 0]) > 0 and Fw[0, 2] > 0 and Fw[1, 2] > 0
    # the body's non-hydrodynamic torque: sum of r_k x F_k of both forces on both beads
    zeros = np.zeros((2, 3))
    b.update_velocities(p2, zeros, zeros, F[:2], T[:2], 0.1, True)
    r = p2.R - b.state.R[0]
    expect = np.cross(r, Fw[:2]).sum(axis=0) + np.cross(r, Fp[:2]).sum(axis=0)
    assert np.allclose(b.state.torque_r[0], expect)
    wall_only = np.cross(r, Fw[:2]).sum(axis=0)
    assert not np.allclose(b.state.torque_r[0], wall_only)     # the original's result


def _ex14(tmp_path, old=None, new=None, name="input.udf"):
    copy_schema(tmp_path, EX14)
    text = open(os.path.join(EX14, "input.udf")).read()
    text = text.replace('"Navier_Stokes_Cahn_Hilliard_FDM"', '"Navier_Stokes_FDM"', 1)
    if old is not None:
        assert old in text
        text = text.replace(old, new, 1)
    p = tmp_path / name
    p.write_text(text)
    return str(p)


FLAT = '{"FLAT",{"Z",4,"MANUAL",{"ON","36:18",100.000000000000}}}'


def test_wall_configuration(tmp_path):
    cfg = config.load(_ex14(tmp_path))
    w = cfg.switches.wall
    assert (w.axis, w.DH, w.powers, w.EPSILON, w.truncate, w.LJ_Params) == \
        (2, 4, "36:18", 100.0, "ON", "MANUAL")
    cfg = config.load(_ex14(tmp_path, FLAT, '{"FLAT",{"X",6,"AUTO",{"OFF","12:6",1.0}}}'))
    w = cfg.switches.wall
    assert (w.axis, w.DH, w.powers, w.EPSILON, w.truncate) == (0, 6, "36:18", 5.0, "ON")
    assert config.load(_ex14(tmp_path, FLAT, '{"NONE",{"X",6,"AUTO",{"OFF","12:6",1.0}}}')
                       ).switches.wall is None
    for bad, what in (('{"FLAT",{"Z",1,"AUTO",{"OFF","12:6",1.0}}}', "interface"),
                      ('{"FLAT",{"Z",30,"AUTO",{"OFF","12:6",1.0}}}', "gap")):
        with pytest.raises(config.ConfigError, match=what):
            config.load(_ex14(tmp_path, FLAT, bad))


def test_walls_are_refused_for_the_sheared_types(tmp_path):
    path = _ex14(tmp_path, '"Navier_Stokes_FDM"', '"Shear_Navier_Stokes_Lees_Edwards_FDM"')
    with pytest.raises(config.ConfigError, match="FLAT walls are available for"):
        config.load(path)


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Navier_Stokes_FDM"])
def test_particles_settle_between_walls_in_a_run(tmp_path, eq):
    """ex14's walls (Z, DH 4, MANUAL 36:18, EPSILON 100) with two settling particles (G = 1):
    placed between the walls; the fluid in the solid (phi_wall = 1) is held by the
    original's SPM rigidity, whose single projection of the combined increment lets the
    particles' pressure gradient into the solid: measured 5.1 % (spectral) and 5.2 % (FDM)
    of max|u| after 10 steps (the original: up to 7 %; kapsel-py held it at round-off with a
    second, constrained projection before it took the original's algorithm)."""
    from kapsel import cli
    copy_schema(tmp_path, EX14)
    (tmp_path / "in.udf").write_text(wall_run_input(tmp_path, eq))
    cfg = config.load(str(tmp_path / "in.udf"))
    args = types.SimpleNamespace(seed=3, quiet=True, threads=1)
    from kapsel import models  # noqa: F401
    from kapsel.typespec import SOLVERS
    model = SOLVERS[eq](cfg, args, None)
    p = model.particles
    assert p.n == 2 and np.all(p.R[:, 2] > 2 + 4) and np.all(p.R[:, 2] < 30 - 4)
    for _ in range(10):
        model.advance()
    solid = model.wall.solid()
    u = model.velocity_field()
    assert np.abs(u).max() > 1e-6
    assert np.abs(u[:, solid]).max() < 0.08 * np.abs(u).max()
    phi = model.snapshot().get("phi")
    assert phi.max() == 1.0 and np.all(phi[solid] == 1.0)


def brenner(h_over_a, terms=60):
    """Brenner (1961): drag on a sphere moving towards a plane wall over Stokes' drag,
    centre at h from the wall, alpha = arccosh(h/a)."""
    al = math.acosh(h_over_a)
    s = 0.0
    for n in range(1, terms):
        num = 2 * math.sinh((2 * n + 1) * al) + (2 * n + 1) * math.sinh(2 * al)
        den = 4 * math.sinh((n + 0.5) * al) ** 2 - (2 * n + 1) ** 2 * math.sinh(al) ** 2
        s += n * (n + 1) / ((2 * n - 1) * (2 * n + 3)) * (num / den - 1)
    return 4.0 / 3.0 * math.sinh(al) * s


def test_brenner_reference():
    assert brenner(math.cosh(1.0)) == pytest.approx(3.036, abs=1e-3)     # Brenner's table
    assert brenner(10.0) == pytest.approx(1 + 9 / 80, rel=0.02)           # Lorentz, far


def _modes(z, k, c, s):
    """Rows n = 0..3 (d^n/dz^n) of g = exp(s k (z - c)) and f = k (z - c) g at z, the
    solutions of (D^2 - k^2)^2 w = 0 scaled to stay <= 1 on their side."""
    t = z - c
    e = math.exp(s * k * t)
    g = [e * (s * k) ** n for n in range(4)]
    f = [k * t * e, k * (1 + s * k * t) * e, s * k * k * (2 + s * k * t) * e,
         k ** 3 * (3 + s * k * t) * e]
    return np.array([g, f]).T


def _w_hat(k, z0, H):
    """Normal velocity at the source of a unit point force normal to no-slip walls at z = 0
    and z = H (H = inf: the wall at 0 only), ETA = 1, in the lateral Fourier mode k:
    (D^2 - k^2)^2 w = k^2 delta(z - z0), w = w' = 0 on the walls."""
    one = math.isinf(H)
    nb = 4
    n = nb + (2 if one else 4)

    def below(z):
        return np.hstack([_modes(z, k, 0.0, -1), _modes(z, k, z0, +1)])

    def above(z):
        r = _modes(z, k, z0, -1)
        return r if one else np.hstack([r, _modes(z, k, H, +1)])
    M, b = np.zeros((n, n)), np.zeros(n)
    M[0, :nb], M[1, :nb] = below(0.0)[:2]
    r = 2
    if not one:
        M[2, nb:], M[3, nb:] = above(H)[:2]
        r = 4
    Bz, Az = below(z0), above(z0)
    M[r:r + 4, :nb], M[r:r + 4, nb:] = -Bz, Az       # w, w', w'' continuous, w''' jumps
    b[r + 3] = k * k
    return Bz[0] @ np.linalg.solve(M, b)[:nb]


def wall_reflection(z0, H=math.inf):
    """The walls' (reflected) velocity at a unit point force normal to them, ETA = 1: the
    lateral Fourier integral of w_hat minus the free Stokeslet's 1 / (4 k) (Liron & Mochon
    1976).  One wall: -3 / (16 pi z0) (Lorentz: lambda ~ 1 + 9 a / (8 h))."""
    from scipy.integrate import quad
    L = min(z0, H - z0)
    f = lambda k: k * (_w_hat(k, z0, H) - 0.25 / k)      # noqa: E731
    return quad(f, 0.0, 40.0 / L, limit=400)[0] / (2.0 * math.pi)


def test_the_point_force_reflection_between_two_walls():
    """Lorentz's one-wall value, and at mid-gap (l = H/2) the two-wall coefficient
    lambda^-1 = 1 - 1.4516 a / l of the literature (Ganatos, Pfeffer & Weinbaum 1980), far
    below the 2 x 9/8 of adding the two walls' effects."""
    for z0 in (5.0, 10.0):
        assert wall_reflection(z0) == pytest.approx(-3.0 / (16 * math.pi * z0), rel=1e-8)
    l = 30.0
    assert -6 * math.pi * l * wall_reflection(l, 2 * l) == pytest.approx(1.4516, abs=2e-4)


def hasimoto_drag(a_over_L):
    """Drag of a simple cubic array of spheres over Stokes' drag, K(a / L) (Hasimoto 1959,
    extended by Sangani & Acrivos 1982), c the volume fraction."""
    c = 4.0 * math.pi / 3.0 * a_over_L ** 3
    return 1.0 / (1.0 - 1.7601 * c ** (1 / 3) + c - 1.5593 * c ** 2 + 3.9799 * c ** (8 / 3)
                  - 3.0734 * c ** (10 / 3))


BRENNER_DT = 1.0 / math.pi ** 2


def wall_no_slip_offset(nsteps=8000):
    """delta: how far the walls' hydrodynamic no-slip planes lie beyond the solid faces
    (phi_wall = 1/2), from the steady Poiseuille flux Q = g h_eff^3 / (12 nu) between walls
    DH = 4, XI = 2 (spectral, 4 x 4 x 32, dt = 1/pi^2 as the sphere runs; the flux at
    t = 810, 10 viscous times h^2 / (pi^2 nu) of the gap): h_eff = h + 2 delta.  Measured
    delta = 0.0180, 0.0466, 0.0490 after 4000, 6000, 8000 steps (dt = 0.1)."""
    shape, g = (4, 4, 32), 1e-3
    wall = FlatWall(2, 4, shape, 1.0, 2.0)
    fluid = SpectralNS(Grid(shape, 1.0), 1.0, 1.0, BRENNER_DT, advection=False)
    fluid.set_force([g, 0.0, 0.0])
    spm = SPM(fluid, no_particles(), 4.0, 2.0, 1.0, 1.0, BRENNER_DT, wall=wall)
    spm.run(nsteps)
    Q = spm.velocity()[0].mean(axis=(0, 1)).sum()
    return 0.5 * ((12.0 * Q / g) ** (1 / 3) - wall.gap)


def sphere_velocity(N, A, Fz, nsteps, wall=None, z=None, before=0):
    """Steady velocity of a sphere (radius A, XI = 2) driven by Fz along z (unsteady Stokes,
    spectral, dt = 1/pi^2), held at its height (its position is reset after each step, so
    the drag is that of one height).  Without wall: periodic N^3 box with a uniform counter
    force on the fluid (Hasimoto's problem), velocity relative to the mean flow.  Returns
    the velocity after nsteps (with ``before``: also the one ``before`` steps earlier)."""
    p = ParticleState.spheres([0], [A], [1.0], 1.0)
    p.R[:] = [[N / 2, N / 2, N / 2 if z is None else z]]
    p.R_raw[:] = p.R
    R0 = p.R.copy()
    fluid = SpectralNS(Grid((N, N, N), 1.0), 1.0, 1.0, BRENNER_DT, advection=False)
    if wall is None:
        fluid.set_force([0.0, 0.0, -Fz / N ** 3])
    F = np.array([[0.0, 0.0, Fz]])
    spm = SPM(fluid, p, A, 2.0, 1.0, 1.0, BRENNER_DT, wall=wall,
              forces=lambda q: (F, np.zeros((1, 3))))
    hist = {}
    for k in range(1, nsteps + 1):
        spm.step()
        p.R[:] = p.R_raw[:] = R0
        spm.refresh()
        if k in (nsteps - before, nsteps):
            hist[k] = p.v[0, 2] - (fluid.mean_velocity()[2] if wall is None else 0.0)
    return (hist[nsteps - before], hist[nsteps]) if before else hist[nsteps]


@pytest.mark.slow
def test_a_sphere_driven_towards_a_wall_slows_as_brenner_predicts():
    """A sphere (A = 4, XI = 2) pushed towards a Z wall by a constant force (Stokes flow) in
    a 64^3 spectral box with walls DH = 4: its drag lambda(h) = F / (6 pi ETA a U) is within
    5 % of Brenner's single-wall value at h/a = 2, 3, 4, in absolute terms.  What the SPM
    and the box add is measured or computed, not fitted:

    * a: the SPM sphere's hydrodynamic radius, from its drag in a periodic 32^3 box (no
      walls) and Hasimoto's K(a / L): K = 1.4550 -> a = 3.867 (64^3, extrapolated to steady
      state: K = 1.1665 -> a = 3.870, the same; nominal A = 4 would give K = 1.530, 1.214);
    * h: sphere centre to the wall's no-slip plane, which lies delta beyond the solid face
      (phi_wall = 1/2), delta = 0.051 from the steady Poiseuille flux between the same walls
      (wall_no_slip_offset); the sphere is placed at z = lo - delta + h a;
    * the far wall (H - h = 13.5 .. 11.5 a away) and the box: the first-order (point-force)
      effect of the far wall, the two-wall reflection minus the one-wall one
      (wall_reflection), is removed from the mobility: 1/lambda_near = 1/lambda -
      6 pi a (w_2 - w_1) = 1/lambda + 0.0004, 0.0016, 0.0044.  It is that small because a
      force normal to a wall makes a far field decaying as 1/r^3; adding the far wall's
      single-wall excess drag instead (lambda_B(H - h) - 1 = 0.09 .. 0.11) would remove
      13 to 60 times too much (measured at mid-gap, l = 7.77 a: lambda = 1.292 after 1250 steps,
      1.257 after 2500, still settling: the slow far-field mode; point-force two-wall
      theory 1 / (1 - 1.4516 a / l) = 1.230, the two walls' excesses added 1.336).  The
      periodic images along the walls, 64 = 16.5 a apart, are screened by the walls (the
      flow of a force normal to two walls decays as exp(-4.2 r / H), H = 60; Liron &
      Mochon 1976) and neglected.
    The sphere is held at its height (quasi-static, Brenner's problem) for 2000 steps
    (t = 203; near the wall the drag settles within t ~ 100, the walls screening the slow
    far-field modes: the change over the last 500 steps is asserted below 1 %).
    Measured (this test: delta = 0.0510, K(32) = 1.4550, a = 3.8670):

        h/a   lambda (500 steps before)   far wall   lambda_near   Brenner
        2     2.0956 (2.0970)             0.00036    2.0940        2.1255  (-1.5 %)
        3     1.5755 (1.5792)             0.00157    1.5717        1.5692  (+0.2 %)
        4     1.4012 (1.4080)             0.00433    1.3928        1.3802  (+0.9 %)

    asserted within 5 % (the issue asks 10 %).  With the nominal A = 4 and h from the solid
    face, the same runs read lambda = 2.03, 1.52, 1.35 at h/a = 1.92, 2.89, 3.85 (the old
    ratio-only test: 1.946, 1.498, 1.346 after 1500 steps, the sphere free to move, the
    fluid in the walls not held).  Run time 545 s on the 2-core machine shared with other
    jobs, nearly all of it the three 64^3 runs of 2000 steps."""
    N, A, Fz = 64, 4.0, -0.075
    delta = wall_no_slip_offset()
    assert 0.0 < delta < 0.2
    K = Fz / (6 * math.pi * A * sphere_velocity(32, A, Fz, 2000))
    from scipy.optimize import brentq
    a = brentq(lambda r: r * hasimoto_drag(r / 32) - A * K, 0.5 * A, 1.5 * A)
    assert abs(a - A) < 0.1 * A
    wall = FlatWall(2, 4, (N, N, N), 1.0, 2.0)
    lo, hi = wall.lo - delta, wall.hi + delta          # the no-slip planes
    print(f"delta = {delta:.4f}, K(32) = {K:.4f}, a = {a:.4f}")
    for h in (2.0, 3.0, 4.0):
        U0, U = sphere_velocity(N, A, Fz, 2000, wall, lo + h * a, before=500)
        lam = Fz / (6 * math.pi * a * U)
        far = 6 * math.pi * a * (wall_reflection(h * a, hi - lo) - wall_reflection(h * a))
        near = 1.0 / (1.0 / lam - far)
        print(f"h/a = {h}: lambda = {lam:.4f} (500 steps before: "
              f"{Fz / (6 * math.pi * a * U0):.4f}), far wall {-far:.5f} in 1/lambda, "
              f"lambda_near = {near:.4f}, Brenner {brenner(h):.4f} "
              f"({near / brenner(h) - 1:+.2%})")
        assert abs(U / U0 - 1) < 0.01
        assert near == pytest.approx(brenner(h), rel=0.05)


def test_rigid_bodies_are_placed_between_the_walls():
    from kapsel.particles.rigid import place_bodies, rod_shape
    rng = np.random.default_rng(7)
    off = [rod_shape(3, 2.0) for _ in range(20)]
    R = place_bodies(off, 2.0, [32.0, 32.0, 16.0], rng, slab=(2, 4.5, 11.5))
    z = (R[:, None, :] + np.array(off))[..., 2]
    assert np.all((z >= 4.5) & (z <= 11.5))
