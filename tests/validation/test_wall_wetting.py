"""Cahn-Hilliard with walls and the particle-surface terms (z, w_wall, psi_0_p, psi_0_wall;
kapsel.phase.cahn_hilliard, PHYSICS-EXTRA.md §1.3, §2.5), and the real inputs ex13 / ex14."""
import math
import os
import shutil
import subprocess
import sys
import types

import numpy as np
import pytest

from kapsel import config
from kapsel.mesh.grid import Grid
from kapsel.config import PhaseField
from kapsel.particles.profile import Stencil, particle_profiles, total_phi
from kapsel.particles.walls import FlatWall
from kapsel.phase.cahn_hilliard import CahnHilliard, neutral_value, wetting_angle

from builders import TESTS


HERE = TESTS
UDF = os.path.join(HERE, "..", "samples", "kapsel-udf")

BASE = dict(tolerance=1e-12, maximum_iteration=500, potential="Landau", composition_ratio=0.0,
            initial_fluctuation=0.0, alpha=1.0, kappa=1.0, a=1.0, b=1.0)


def particle_phi(shape, centres, A=3.0, xi=2.0):
    st = Stencil(A, xi, 1.0)
    idx, phi, _ = particle_profiles(np.array(centres, dtype=float), st, shape, 1.0)
    return total_phi(idx, phi, int(np.prod(shape))).reshape(shape)


def params(scheme="explicit_scheme", **kw):
    d = dict(d=1.5, w=0.3, z=-0.1, w_wall=0.4, psi_0_p=0.3, psi_0_wall=-0.5)
    d.update(kw)
    return PhaseField(scheme, **BASE, **d)


def test_chemical_potential_is_the_gradient_of_the_free_energy():
    """mu = dF/dpsi / DX^3 with walls, z, w, w_wall, psi_0_p and a psi_0_wall map."""
    shape = (8, 8, 16)
    wall = FlatWall(2, 4, shape, 1.0, 2.0)
    rng = np.random.default_rng(2)
    psi0_map = rng.uniform(-1, 1, (8, 8))
    ch = CahnHilliard(Grid(shape, 1.0), params(psi_0_wall=psi0_map), 0.01, xi=2.0, wall=wall)
    phi = particle_phi(shape, [[4.0, 4.0, 8.0]])
    psi = rng.uniform(-1, 1, shape)
    mu = ch.chemical_potential(psi, phi)
    h = 1e-6
    for _ in range(12):
        i = tuple(rng.integers(0, n) for n in shape)
        up, dn = psi.copy(), psi.copy()
        up[i] += h
        dn[i] -= h
        dF = (ch.free_energy(up, phi) - ch.free_energy(dn, phi)) / (2 * h)
        assert dF == pytest.approx(mu[i], rel=1e-6, abs=1e-8)


def test_psi_relaxes_to_psi_0_inside_the_solids():
    """The neutral values make psi_0_p and psi_0_wall the equilibrium inside the solids."""
    p = params()
    for psi0 in (0.3, -0.5, 0.9):
        n = neutral_value(p, psi0, 0.0)
        assert p.a * psi0 ** 3 - p.b * psi0 + 2 * p.d * (psi0 - n) == pytest.approx(0.0,
                                                                                   abs=1e-14)
    shape = (4, 4, 32)
    wall = FlatWall(2, 8, shape, 1.0, 2.0)
    ch = CahnHilliard(Grid(shape, 1.0), params("implicit_scheme", z=0.0, w_wall=0.0, d=3.0), 0.05,
                      xi=2.0, wall=wall, preconditioner="fft")
    psi = np.zeros(shape)
    psi[:, :, 10:22] = 0.2
    for _ in range(3000):
        ch.step(psi)
    assert psi[0, 0, 0] == pytest.approx(-0.5, abs=0.02)      # deep in the solid


@pytest.mark.parametrize("scheme", ["explicit_scheme", "implicit_scheme"])
def test_psi_is_conserved_with_walls_and_particles(tmp_path, scheme):
    """The full model (ex14's walls and CH items, two particles, z, w_wall, psi_0_p): the sum
    of psi is conserved to 1e-10 (per node) by both schemes."""
    model = _ex14_model(tmp_path, scheme, particles=2, surface=True)
    total0 = model.psi.sum()
    for _ in range(4):
        model.advance()
    assert np.isfinite(model.psi).all()
    assert abs(model.psi.sum() - total0) / model.psi.size < 1e-10
    assert np.abs(model.psi - model.psi.mean()).max() > 1e-3       # it does evolve


def test_an_x_wall_evolves_as_the_z_wall_rotated():
    """The wall terms follow the wall's own axis (the original's wall gradient is right for
    Z walls only): psi of an X wall is psi of the Z wall with the axes exchanged."""
    rng = np.random.default_rng(5)
    psi_z = rng.uniform(-0.3, 0.3, (8, 8, 16))
    out = []
    for axis in (2, 0):
        shape = (8, 8, 16) if axis == 2 else (16, 8, 8)
        wall = FlatWall(axis, 4, shape, 1.0, 2.0)
        ch = CahnHilliard(Grid(shape, 1.0), params("implicit_scheme"), 0.05, xi=2.0, wall=wall,
                          preconditioner="fft")
        psi = psi_z.copy() if axis == 2 else np.ascontiguousarray(np.swapaxes(psi_z, 0, 2))
        for _ in range(5):
            ch.step(psi)
        out.append(psi if axis == 2 else np.swapaxes(psi, 0, 2))
    assert np.abs(out[0] - psi_z).max() > 1e-3
    assert np.allclose(out[0], out[1], atol=1e-9)


def _contact_angle(psi, wall):
    """Angle (degrees, in the psi > 0 phase on the right) between the lower wall face and a
    circle fitted to the psi = 0 line of the left interface, at the face plane."""
    pts = []
    for k in range(int(wall.lo) + 3, int(wall.hi) - 2):
        row = psi[:, 0, k]
        i = np.flatnonzero((row[:-1] < 0) & (row[1:] >= 0))
        i = i[(i > 2) & (i < psi.shape[0] // 2)]
        if len(i) == 1:
            i = i[0]
            pts.append((i + row[i] / (row[i] - row[i + 1]), k))
    P = np.array(pts)
    X, Z = P[:, 0], P[:, 1]
    A = np.c_[2 * X, 2 * Z, np.ones_like(X)]
    cx, cz, c = np.linalg.lstsq(A, X ** 2 + Z ** 2, rcond=None)[0]
    R = math.sqrt(c + cx ** 2 + cz ** 2)
    zf = wall.lo
    dxf = math.sqrt(max(R * R - (zf - cz) ** 2, 0.0))
    xf = min((cx + dxf, cx - dxf), key=lambda x: abs(x - X.mean()))
    t = np.array([-(zf - cz), xf - cx]) / R           # tangent of the circle at the face
    if t[1] < 0:
        t = -t                                        # pointing into the fluid
    return math.degrees(math.acos(max(-1.0, min(1.0, t[0]))))


@pytest.mark.slow
@pytest.mark.parametrize("w_wall", [0.7, -0.4])
def test_an_interface_meets_the_wall_at_the_predicted_contact_angle(w_wall):
    """Quasi-2D (32 x 2 x 16, Z walls DH = 4, Landau a = b = alpha = kappa = 1, d = 1,
    psi_0_wall = 0), a vertical strip of the A phase between the walls: the interfaces bend
    until they meet the faces at Young's angle of the wetting free energy
    (``wetting_angle``: 122.2 and 71.9 degrees; measured 120.4 and 70.9 from a circle fitted to
    the psi = 0 line, at the face plane).  BDF2, dt = 0.1, 3000 steps: 6-25 s each on a
    2-core machine, idle to loaded.  (The same at 64 x 2 x 32, w_wall = 0.314: 104.2 predicted,
    102.8 measured after 5000 steps.)"""
    shape = (32, 2, 16)
    wall = FlatWall(2, 4, shape, 1.0, 2.0)
    p = PhaseField("implicit_scheme", **BASE, d=1.0, w=0.0, w_wall=w_wall)
    theta = wetting_angle(p, wall, 2.0)
    assert abs(theta - 90.0) > 15.0
    ch = CahnHilliard(Grid(shape, 1.0), p, 0.1, xi=2.0, wall=wall, preconditioner="fft")
    x = np.arange(shape[0])
    psi = np.where((x >= 8) & (x < 24), 1.0, -1.0)[:, None, None] * (1.0 - wall.phi)
    total = psi.sum()
    assert np.all(psi[7, 0, 4:12] < 0) and np.all(psi[8, 0, 4:12] > 0)   # vertical: 90 deg
    for _ in range(3000):
        ch.step(psi)
    assert abs(psi.sum() - total) / psi.size < 1e-10
    assert _contact_angle(psi, wall) == pytest.approx(theta, abs=5.0)


# --------------------------------------------------------------------------- real inputs
def _copy(tmp_path, ex, name, edits=()):
    for f in os.listdir(os.path.join(UDF, ex)):
        shutil.copy(os.path.join(UDF, ex, f), tmp_path / f)
    text = open(os.path.join(UDF, ex, name)).read()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    (tmp_path / name).write_text(text)
    return str(tmp_path / name)


def _ex14_model(tmp_path, scheme, particles=0, surface=False):
    edits = [('[{0,2.00000000000000,0.0,"NONE"', f'[{{{particles},2.00000000000000,0.0,"NONE"'),
             ("gravity:{1.00000000000000", "gravity:{0.0")]
    if scheme == "explicit_scheme":
        edits.append(('{"implicit_scheme",{-9.00000000000000,1500}}\n  1.00000000000000,',
                      '{"explicit_scheme",{-9.00000000000000,1500}}\n  1.00000000000000,'))
    if surface:      # w, w_wall, z of ex14's Landau block: 0, 0, 0 -> 0.2, 0.3, -0.1
        edits.append(("    15.0000000000000,\n    0.0,\n    0.0,\n    0.0,\n",
                      "    15.0000000000000,\n    0.2,\n    0.3,\n    -0.1,\n"))
    path = _copy(tmp_path, "ex14", "input.udf", edits)
    cfg = config.load(path)
    assert cfg.phase.ch_solver == scheme and cfg.switches.wall is not None
    from kapsel import models  # noqa: F401
    from kapsel.typespec import SOLVERS
    return SOLVERS[cfg.type](cfg, types.SimpleNamespace(seed=2, quiet=True, threads=1), None)


def test_ex14_items_are_read(tmp_path):
    path = _copy(tmp_path, "ex14", "input.udf")
    ph = config.load(path).phase
    assert (ph.d, ph.w, ph.w_wall, ph.z, ph.psi_0_p, ph.psi_0_wall) == \
        (15.0, 0.0, 0.0, 0.0, 0.1, 1.0)


def _run(tmp_path, name):
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", f"-I{name}", "-Oout.udf",
                        "-Ddefine.udf", "-Rres.udf", "--seed", "1", "--quiet"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    return r


def test_ex14_walls_and_wetting_run(tmp_path):
    """ex14 (Z walls DH 4, psi_0_wall 1, psi_0_p 0.1, d 15) for 4 steps: psi goes to
    psi_0_wall inside the solid, and the fluid stays at rest in it."""
    _copy(tmp_path, "ex14", "input.udf", [("output:{100,200,", "output:{2,2,")])
    _run(tmp_path, "input.udf")
    import h5py
    with h5py.File(tmp_path / "orderparam_2.h5") as f:
        psi = f["PSI_ALL"][...]                        # (NZ, NY, NX)
    assert psi.shape == (32, 32, 32)
    assert psi[0].mean() > 0 > psi[16].mean()           # solid pulled up, fluid at -0.7
    from udf import UDFManager
    u = UDFManager(str(tmp_path / "out.udf"))
    assert u.totalRecord() == 3


def test_ex13_pickering_emulsion_runs(tmp_path):
    """ex13 (64^3, 195 particles, Landau z = -0.1, CH implicit) for 2 steps."""
    _copy(tmp_path, "ex13", "pickering_emulsion.udf", [("output:{100,500,", "output:{1,2,")])
    _run(tmp_path, "pickering_emulsion.udf")
    from udf import UDFManager
    u = UDFManager(str(tmp_path / "out.udf"))
    assert u.totalRecord() == 3
    u.jump(2)
    assert len(u.get("Particles[]")) == 195


def test_psi_0_wall_map_patterns_the_wall(tmp_path):
    """user_specify psi_0_wall[i][j] over the wall plane (Z wall: i = x, j = y); a larger
    table's first entries are used, as the original reads only those; a smaller one is
    refused."""
    shape = (4, 6, 16)
    wall = FlatWall(2, 6, shape, 1.0, 2.0)
    table = np.where(np.add.outer(np.arange(8), np.arange(8)) % 2 == 0, 0.8, -0.8)
    ch = CahnHilliard(Grid(shape, 1.0), params("implicit_scheme", z=0.0, w_wall=0.0, d=3.0,
                                         psi_0_wall=table), 0.05, xi=2.0, wall=wall,
                      preconditioner="fft")
    psi = np.zeros(shape)
    for _ in range(400):
        ch.step(psi)
    assert np.all(np.sign(psi[:, :, 0]) == np.sign(table[:4, :6]))
    with pytest.raises(ValueError, match="wall plane has 4 x 6"):
        CahnHilliard(Grid(shape, 1.0), params(psi_0_wall=table[:3]), 0.05, xi=2.0, wall=wall)
    # the input's table reaches the configuration
    path = _copy(tmp_path, "ex14", "input.udf", [('     "uniform",\n', '     "user_specify",\n')])
    grid = config.load(path).phase.psi_0_wall
    assert grid.shape == (64, 64) and grid[0, 12] == -1.0 and grid[0, 13] == 1.0


@pytest.mark.parametrize("scheme", ["explicit_scheme", "implicit_scheme"])
def test_psi_0_wall_does_nothing_without_a_wall(scheme):
    """No wall: psi_0_wall has no effect and a centred sphere keeps psi mirror-symmetric in x.
    The original computes its wall profile even when switch.wall is NONE (wall.cxx:93-105,
    Init_bottom_Wall, called from sp_3d_ns.cxx:845 whatever SW_WALL), from the zeroed wall
    parameters (axis x, lo = hi = 0): the profile is 1 for x >= L/2 and 0.5 on the plane x = 0,
    and Make_psi_all (fdm.cxx:26) adds psi_0_wall there.  Run by bench/parity.py's nsch_ex14
    (psi_0_wall 1, no wall), its psi after one step has mean -0.236 on x < L/2 and -0.091 ... 0.33
    on x >= L/2 along x, where kapsel-py keeps -0.7 (docs/physics-walls-shear.md)."""
    shape = (16, 16, 16)
    phi = particle_phi(shape, [(7.5, 7.5, 7.5)])
    runs = []
    for psi0w in (0.0, 1.0):
        ch = CahnHilliard(Grid(shape, 1.0), params(scheme, z=0.0, w_wall=0.0, d=3.0, psi_0_p=0.1,
                                             psi_0_wall=psi0w),
                          0.01, xi=2.0, preconditioner="fft")
        psi = -0.7 * (1.0 - phi) + 0.1 * phi      # the original's start, composition -0.7
        for _ in range(10):
            ch.step(psi, phi=phi)
        runs.append(psi)
    assert np.array_equal(runs[0], runs[1])
    mirrored = runs[1][::-1, :, :]            # x -> 15 - x about the sphere's centre 7.5
    assert np.allclose(runs[1], mirrored, atol=1e-10)
    assert abs(runs[1].mean() - (-0.7 * (1 - phi.mean()) + 0.1 * phi.mean())) < 1e-10
