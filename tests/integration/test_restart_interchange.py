"""Spectral restarts interchange with the original (FORMAT.md "The spectral restart",
FORMAT-OUTPUT.md §6.3): Zeta / uk_dc packed as the original packs them, read back without
the state file; jikan.ts = steps done - 1 both ways.

The packer here is written from FORMAT.md alone, mode by mode, independently of
kapsel.io.restart."""
import argparse
import os
import shutil

import numpy as np
import pytest

from kapsel import config, models, typespec  # noqa: F401  (registers the types)
from kapsel.io.restart import read_restart, state_path, unpack_zeta
from kapsel.typespec import SOLVERS
from udf import UDFManager

from builders import cli, copy_schema, make_input, run_cli, scene as make_scene, TESTS


def original_k(n, dx):
    """2 pi m / L, m = 0..N/2 then negative (N/2 counted positive)."""
    return [2 * np.pi * (m if m <= n // 2 else m - n) / (n * dx) for m in range(n)]


def pack_like_the_original(u_hat, dx):
    """Zeta (NX, NY, NZ + 2, 2), uk_dc of an unnormalised rfftn u_hat, by FORMAT.md."""
    _, nx, ny, nh = u_hat.shape
    nz = 2 * (nh - 1)
    KX, KY = original_k(nx, dx), original_k(ny, dx)
    KZ = [2 * np.pi * m / (nz * dx) for m in range(nh)]
    zeta = np.zeros((nx, ny, nz + 2, 2))
    for i in range(nx):
        for j in range(ny):
            for m in range(nh):
                k = np.array([KX[i], KY[j], KZ[m]])
                w = 1j * np.cross(k, u_hat[:, i, j, m])
                if i != 0:
                    z = (w[1], w[2])
                elif j != 0:
                    z = (w[2], w[0])
                else:
                    z = (w[0], w[1])
                for c in (0, 1):
                    zeta[i, j, 2 * m, c] = z[c].real
                    zeta[i, j, 2 * m + 1, c] = z[c].imag
    return zeta, u_hat[:, 0, 0, 0].real.copy()


def project_original(u_hat, dx):
    _, nx, ny, nh = u_hat.shape
    k = np.meshgrid(original_k(nx, dx), original_k(ny, dx),
                    [2 * np.pi * m / (2 * (nh - 1) * dx) for m in range(nh)], indexing="ij")
    k2 = sum(c * c for c in k)
    s = sum(c * u for c, u in zip(k, u_hat)) / np.where(k2 > 0, k2, 1.0)
    return np.array([u - c * s for c, u in zip(k, u_hat)])


def test_unpack_inverts_the_documented_packing_on_every_mode():
    """A random solenoidal spectrum (Nyquist modes included) comes back to round-off."""
    rng = np.random.default_rng(3)
    dx = 0.8
    u_hat = rng.normal(size=(3, 8, 8, 5)) + 1j * rng.normal(size=(3, 8, 8, 5))
    u_hat = project_original(u_hat, dx)
    u_hat[:, 0, 0, 0] = [1.5, -0.25, 0.75]
    zeta, dc = pack_like_the_original(u_hat, dx)
    back = unpack_zeta(zeta, dc, dx)
    assert np.max(np.abs(back - u_hat)) < 1e-12 * np.max(np.abs(u_hat))


def known_velocity(n, dx):
    """A divergence-free field with a mean flow: u_x(y, z), u_y(x, z), u_z(x, y)."""
    L = n * dx
    x = np.arange(n) * dx
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    a = 2 * np.pi / L
    return np.array([0.02 + 0.05 * np.sin(2 * a * Y) + 0.03 * np.cos(a * Z),
                     -0.01 + 0.04 * np.cos(a * X + 0.3) * np.sin(3 * a * Z),
                     0.005 + 0.02 * np.sin(a * (X + 2 * Y))])


def load(path, quiet=True):
    """The model of an input (a restart.udf), continued from it, in-process."""
    doc = UDFManager(str(path))
    cfg = config.from_document(doc, str(path))
    args = argparse.Namespace(seed=5, quiet=quiet, threads=1)
    model = SOLVERS[cfg.type](cfg, args, doc)
    saved = read_restart(doc, str(path), cfg.resume.calculation)
    model.load_restart(saved)
    return model, saved


def test_a_restart_in_the_originals_packing_continues_with_its_velocity(tmp_path):
    d = tmp_path / "o"
    inp = make_input(d, "Navier_Stokes", particles=0, gts=2, nsnap=1, kBT=0.0)
    assert cli(d, inp) == 0
    rs = UDFManager(str(d / "restart.udf"))
    dx = rs.get("constitutive_eq.Navier_Stokes.DX")
    n = 2 ** rs.get("mesh.NPX")
    u = known_velocity(n, dx)
    zeta, dc = pack_like_the_original(np.fft.rfftn(u, axes=(1, 2, 3)), dx)
    base = "resume.CONTINUE.Saved_Data"
    rs.put(zeta, f"{base}.Zeta[]")
    rs.put([float(c) for c in dc], f"{base}.uk_dc")
    rs.put([6, 7 * 0.1], f"{base}.jikan")           # the original: ts = 6 after 7 steps
    rs.put(5, "output.Num_snap")
    rs.write(str(d / "orig.udf"))                      # no state file: the original's
    assert not os.path.exists(state_path(str(d / "orig.udf")))
    model, saved = load(d / "orig.udf")
    assert saved.exact is None
    assert model.step_index == 7 and model.time == pytest.approx(0.7)
    assert np.max(np.abs(model.spm.velocity() - u)) < 1e-14
    # and the run goes on from there: snapshots at steps 8 and 10 (7 is not one, GTS = 2)
    os.remove(d / "output.udf")
    assert cli(d, "orig.udf") == 0
    out = UDFManager(str(d / "output.udf"))
    assert out.totalRecord() == 2
    for rec, step in enumerate((8, 10)):
        out.jump(rec)
        t = out.get("t")
        assert t == step or t == pytest.approx(0.7 + (step - 7) * model.dt, rel=1e-6)


@pytest.mark.parametrize("eq", typespec.names(grid="spectral", ions=False))
def test_our_spectral_restart_reads_back_from_its_udf_data_alone(tmp_path, eq):
    d = tmp_path / "s"
    if eq == "Navier_Stokes":
        inp = make_input(d, eq, particles=3, gts=2, nsnap=2)
    else:
        from builders import shear_input
        inp = shear_input(d, eq=eq, particles=2, gts=3, nsnap=2, rate=0.6, kind="DC")
    assert cli(d, inp) == 0
    with_state, _ = load(d / "restart.udf")
    shutil.copy(d / "restart.udf", d / "alone.udf")
    alone, saved = load(d / "alone.udf")
    assert saved.exact is None
    a, b = with_state.fluid.u_hat, alone.fluid.u_hat
    assert np.max(np.abs(a - b)) < 1e-12 * np.max(np.abs(a))
    assert alone.step_index == with_state.step_index
    assert np.array_equal(alone.particles.R, with_state.particles.R)
    if "Lees" in eq:
        assert alone.fluid.frame_strain == pytest.approx(with_state.fluid.frame_strain,
                                                         abs=1e-12)


def test_step_convention_of_the_restart(tmp_path):
    """After GTS * Num_snap = 4 steps the run takes one more step, as the original does, and
    writes ts = 4, time = 5 dt (FORMAT-OUTPUT.md §6.3); continuing it starts at step 5."""
    d = tmp_path / "c"
    inp = make_input(d, "Navier_Stokes_FDM", ns="explicit_scheme", particles=2, gts=2,
                     nsnap=2, kBT=0.0)
    assert cli(d, inp) == 0
    rs = UDFManager(str(d / "restart.udf"))
    ts, time = rs.get("resume.CONTINUE_FDM.Saved_Data.jikan")
    model, saved = load(d / "restart.udf")
    assert ts == 4 and time == pytest.approx(5 * model.dt)
    assert model.step_index == 5 and saved.exact is not None


def test_our_zeta_is_the_documented_packing(tmp_path):
    """What we write is what the original reads: Zeta / uk_dc of our restart equal the
    FORMAT.md packing (the packer above) of the velocity in its state file."""
    d = tmp_path / "p"
    inp = make_input(d, "Navier_Stokes", particles=2, gts=2, nsnap=1)
    assert cli(d, inp) == 0
    rs = UDFManager(str(d / "restart.udf"))
    base = "resume.CONTINUE.Saved_Data"
    zeta = np.asarray(rs.getArray(f"{base}.Zeta[]"), dtype=float)
    dc = np.asarray(rs.get(f"{base}.uk_dc"), dtype=float)
    with np.load(state_path(str(d / "restart.udf"))) as z:
        u_hat = z["u_hat"]
    want, want_dc = pack_like_the_original(u_hat, rs.get("constitutive_eq.Navier_Stokes.DX"))
    assert zeta.shape == want.shape == (16, 16, 18, 2)
    assert np.max(np.abs(zeta - want)) <= 1e-13 * np.max(np.abs(want))
    assert np.array_equal(dc, want_dc)


# ---------------------------------------------------------------- rigid bodies
# The original writes one Particles[] row per rigid body (resume.cxx Get_Rigid_Particle_Data:
# centre, V, Omega, q and the summed forces after the step's reset) and the bodies' geometry
# in GR_body[], GR_masses[], GR_moments_body[].  Two 16^3 scenes (spectral, kBT 0, dt 0.05,
# A = 2): a free L of 4 beads settling and turning (Rigid_velocity, body-frame Rigid_omega,
# G 0.002 along -Z) and a fixed 3-bead body moving with Rigid_velocity and turning with
# Rigid_omega.  tests/data/rigid_restart/<scene>_original.udf is the original's restart after
# 11 steps (ts = 10); ORIGINAL holds the original's bodies after 21 steps (its restart of
# MSTEP 20, %.17g): uninterrupted ("straight"), continued from its own restart ("cont") and
# continued from kapsel-py's restart ("from_py": kapsel-py's restart.udf of the 11 steps,
# flattened for it); made with the kref tools (mkscene.py, flatten_udf.py, unflatten_udf.py)
# on the kref build of kapsel3 8ee457a.
RIGID_DATA = os.path.join(TESTS, "data", "rigid_restart")
SAMPLES = os.path.join(TESTS, "..", "samples")
_RS = "object_type.rigid.Rigid_spec[0]"
_COMMON = [("constitutive_eq.type", "Navier_Stokes"), ("constitutive_eq.Navier_Stokes.kBT", 0.0),
           ("mesh.NPX", 4), ("mesh.NPY", 4), ("mesh.NPZ", 4), ("A_XI", 2.0), ("A", 2.0),
           ("switch.INIT_distribution.type", "user_specify"), ("time_increment.type", "manual"),
           ("time_increment.manual.delta_t", 0.05), ("switch.LJ_truncate", "ON"),
           ("object_type.type", "rigid"), (f"{_RS}.Chain_number", 1)]
_US = "switch.INIT_distribution.user_specify.Particles[]"


def _beads(xs):
    return np.array([x + [0, 0, 0, 1, 0, 0, 0, 0, 0, 0] for x in xs], dtype=float)


RIGID_SCENES = {
    "free": _COMMON + [
        (f"{_RS}.MASS_RATIO", 2.0), (f"{_RS}.Beads_number", 4), (f"{_RS}.Rigid_motion", "free"),
        (f"{_RS}.Rigid_velocity.x", 0.004), (f"{_RS}.Rigid_velocity.y", -0.002),
        (f"{_RS}.Rigid_omega.x", 0.004), (f"{_RS}.Rigid_omega.z", 0.008),
        ("gravity.G", 0.002), ("gravity.G_direction", "-Z"),
        ("switch.INIT_orientation", "space_align"),
        (_US, _beads([[6.0, 7.0, 8.0], [9.5, 7.5, 8.3], [6.5, 10.4, 7.6], [3.2, 7.2, 8.4]]))],
    "fixed": _COMMON + [
        (f"{_RS}.MASS_RATIO", 1.5), (f"{_RS}.Beads_number", 3), (f"{_RS}.Rigid_motion", "fix"),
        (f"{_RS}.Rigid_velocity.x", 0.01), (f"{_RS}.Rigid_velocity.z", 0.005),
        (f"{_RS}.Rigid_omega.y", 0.004), (f"{_RS}.Rigid_omega.z", 0.02),
        ("gravity.G", 0.0), ("switch.INIT_orientation", "space_align"),
        (_US, _beads([[5.0, 6.0, 8.0], [9.0, 6.3, 8.4], [6.8, 10.0, 7.6]]))]}

ORIGINAL = {
    "free": {
        "straight": {"R": [6.351999843868203, 8.055402701709085, 8.073741614233896],
                     "v": [0.0014624108003249625, -0.0005590018691860412, -0.0005004270730390618],
                     "omega": [0.0019699752745168998, 0.0004518659970956743, 0.0011388566926653384],
                     "q": [0.021585179916355165, 0.7082920570691115, 0.11043029834833062,
                           0.6968942467171645],
                     "f_hydro": [-0.1704764072215311, 0.07826436730639905, 0.2110093070987497]},
        "cont": {"R": [6.3519998437319884, 8.05540270148493, 8.073741614381849],
                 "v": [0.0014624104126951653, -0.0005590025485049938, -0.000500426687793978],
                 "omega": [0.0019699750281581834, 0.0004518666449326733, 0.0011388564998238483],
                 "q": [0.021583396769289304, 0.708292259593599, 0.11042964014819898,
                       0.6968942004066563],
                 "f_hydro": [-0.17047645878129514, 0.0782642405484593, 0.21100932886219642]},
        "from_py": {"R": [6.3519998437319884, 8.05540270148493, 8.073741614381849],
                    "v": [0.0014624104126951675, -0.0005590025485049937, -0.0005004266877939804],
                    "omega": [0.001969975028158179, 0.00045186664493267355, 0.001138856499823841],
                    "q": [0.021583396769289616, 0.7082922595935988, 0.11042964014819931,
                          0.6968942004066561],
                    "f_hydro": [-0.17047645878129364, 0.07826424054845926, 0.21100932886219306]}},
    "fixed": {
        "straight": {"R": [6.936663727677978, 7.436880400448512, 8.003729735282782],
                     "v": [0.01, 0.0, 0.005],
                     "omega": [0.0035638053277067612, 0.019905326625019107, -0.0026603126766451754],
                     "q": [-0.4452853419257141, 0.5062762249801517, 0.5646754682763637,
                           0.4759694988261498],
                     "f_hydro": [-2.0088827657343518, -0.03340699599977237, -1.3845333971146663]},
        "from_py": {"R": [6.936663727677992, 7.436880400448512, 8.003729735282768],
                    "v": [0.01, 0.0, 0.005],
                    "omega": [0.003563805327706713, 0.019905326625019114, -0.002660312676645203],
                    "q": [-0.4452853419257145, 0.5062762249801515, 0.564675468276364,
                          0.4759694988261494],
                    "f_hydro": [-2.0088827657343464, -0.033406995999768235, -1.38453339711463]}}}
ORIGINAL["fixed"]["cont"] = ORIGINAL["fixed"]["straight"]    # bit for bit, in the original


def _rigid_dir(d, restart):
    """``d`` holding ``restart`` as input.udf, next to the sample's define.udf."""
    os.makedirs(d, exist_ok=True)
    copy_schema(d)
    shutil.copy(restart, d / "input.udf")
    return d / "input.udf"


def _advance(model, steps):
    from kapsel import simulation
    for _ in range(steps):
        simulation.advance(model)
    return model.particles.constraints.state


def _rel(s, ref):
    """|ours - the original's| / max|the original's| of the body's R, V, Omega, q, F_H."""
    out = {}
    for k in ("R", "v", "omega", "q", "f_hydro"):
        a, b = np.asarray(getattr(s, k)[0]), np.asarray(ref[k])
        out[k] = np.abs(a - b).max() / np.abs(b).max()
    return out


@pytest.mark.parametrize("scene", ["free", "fixed"])
def test_the_originals_rigid_restart_continues_as_its_uninterrupted_run(tmp_path, scene):
    """orig -> kapsel-py: the original's restart (one row per body, GR_*) continued 10 steps
    follows the original's uninterrupted run to round-off (measured: positions 1e-12 of the
    motion, V and Omega 3e-15 of their size).  The original's own continuation of a turning
    body does not: its restore sets the beads' omega_old to Omega (resume.cxx
    Set_Rigid_Particle_Data) and its first Adams-Bashforth quaternion step reads that
    instead of the body's Omega_old (rigid.h solver_Rigid_Position); kapsel-py made to do
    the same reproduces the original's continuation to round-off."""
    inp = _rigid_dir(tmp_path / "o", os.path.join(RIGID_DATA, f"{scene}_original.udf"))
    model, saved = load(inp)
    assert saved.exact is None and model.step_index == 11
    b = model.particles.constraints
    doc = UDFManager(str(inp))
    base = "resume.CONTINUE.Saved_Data"
    assert saved.particles.shape[0] == b.nb == 1
    assert np.array_equal(b.masses, doc.getArray(f"{base}.GR_masses[]"))
    assert np.array_equal(b.moments_body.reshape(-1, 9),
                          np.asarray(doc.getArray(f"{base}.GR_moments_body[]")))
    assert np.array_equal(b.body_positions, np.asarray(doc.getArray(f"{base}.GR_body[]")))
    row = np.asarray(doc.getArray(f"{base}.Particles[]"))[0]
    assert np.array_equal(b.state.omega_old[0], row[33:36])      # the body's Omega_old
    # the beads sit where the bodies put them: x_k = R_g + R(q) r_k^B, v_k = V + Omega x r_k
    from kapsel.particles import quaternion as quat
    r = quat.rotate(b.state.q[b.body], b.body_positions)
    assert np.abs(model.particles.R - (b.state.R[b.body] + r)).max() < 1e-14
    assert np.abs(model.particles.v - (b.state.v[b.body]
                                       + np.cross(b.state.omega[b.body], r))).max() < 1e-17
    s = _advance(model, 10)
    ref = ORIGINAL[scene]
    assert max(_rel(s, ref["straight"]).values()) < 1e-12
    # the original's restore, mimicked: its own continuation to round-off
    mimic, _ = load(inp)
    ms = mimic.particles.constraints.state
    ms.omega_old[:] = ms.omega
    ms = _advance(mimic, 10)
    assert max(_rel(ms, ref["cont"]).values()) < 1e-12
    gap = np.abs(np.asarray(ref["cont"]["q"]) - ref["straight"]["q"]).max()
    if scene == "free":          # Omega changes: the original leaves its own straight run
        assert gap > 1e-6 and np.abs(s.q[0] - ref["straight"]["q"]).max() < 1e-5 * gap
    else:                        # a fixed body keeps Omega: no difference
        assert gap == 0.0


@pytest.mark.parametrize("scene", ["free", "fixed"])
def test_our_rigid_restart_is_the_one_the_original_writes_and_reads(tmp_path, scene):
    """kapsel-py -> orig: kapsel-py's restart of the scene after 11 steps has the original's
    layout (one Particles[] row per body, current forces 0 and the step's in *_previous,
    GR_body / GR_masses / GR_moments_body) and the original's values to round-off; the
    original continued it (ORIGINAL 'from_py') as its own restart (measured 1.6e-15 of V
    and Omega), and kapsel-py reading it as the original reads it (the beads' omega_old =
    Omega) reproduces that run to round-off."""
    d = tmp_path / "p"
    inp = make_scene(d, os.path.join(SAMPLES, "input.udf"),
                     RIGID_SCENES[scene] + [("output.GTS", 5), ("output.Num_snap", 2)])
    assert run_cli(d, inp, seed=1) == 0
    ours, orig = UDFManager(str(d / "restart.udf")), UDFManager(
        os.path.join(RIGID_DATA, f"{scene}_original.udf"))
    base = "resume.CONTINUE.Saved_Data"
    assert ours.get(f"{base}.jikan") == [10, pytest.approx(0.55, rel=1e-15)]
    a = np.asarray(ours.getArray(f"{base}.Particles[]"), dtype=float)
    b = np.asarray(orig.getArray(f"{base}.Particles[]"), dtype=float)
    assert a.shape == b.shape == (1, 65)
    assert np.array_equal(a == 0.0, b == 0.0)      # the same members zero (current forces)
    cols = np.abs(b).max(axis=0)
    assert np.all(np.abs(a - b) <= 1e-12 * np.maximum(cols, np.abs(b).max() * 1e-3))
    for name in ("GR_body", "GR_masses", "GR_moments_body"):
        x = np.asarray(ours.getArray(f"{base}.{name}[]"), dtype=float)
        y = np.asarray(orig.getArray(f"{base}.{name}[]"), dtype=float)
        assert x.shape == y.shape and np.abs(x - y).max() <= 1e-12 * np.abs(y).max()
    # read as the original reads it (the text alone, its restore of omega_old)
    os.remove(state_path(str(d / "restart.udf")))
    rs = UDFManager(str(d / "restart.udf"))
    rs.put(4, "output.Num_snap")
    rs.write(str(d / "cont.udf"))
    model, saved = load(d / "cont.udf")
    assert saved.exact is None
    s = model.particles.constraints.state
    s.omega_old[:] = s.omega
    s = _advance(model, 10)
    assert max(_rel(s, ORIGINAL[scene]["from_py"]).values()) < 1e-12

