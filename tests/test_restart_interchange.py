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

from kapsel import config, models  # noqa: F401  (registers the types)
from kapsel.io.restart import read_restart, state_path, unpack_zeta
from kapsel.simulation import SOLVERS
from test_restart import cli, make_input
from udf import UDFManager


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


@pytest.mark.parametrize("eq", ["Navier_Stokes", "Shear_Navier_Stokes",
                                "Shear_Navier_Stokes_Lees_Edwards"])
def test_our_spectral_restart_reads_back_from_its_udf_data_alone(tmp_path, eq):
    d = tmp_path / "s"
    if eq == "Navier_Stokes":
        inp = make_input(d, eq, particles=3, gts=2, nsnap=2)
    else:
        from test_shear_le import make_input as shear_input
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
