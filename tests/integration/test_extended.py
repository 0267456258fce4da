"""output.AVS ON, FileType EXTENDED (kapsel.io.extended): the original's HDF5 trajectory
(groups, attributes, datasets, dtypes, frame naming, crop), its .conf, and the XDMF files read
by VTK, for every type; derived fields (kapsel.fluid.diagnostics) against exact solutions."""
import os
import shutil

import h5py
import numpy as np
import pytest

from kapsel import typespec
from kapsel.mesh.grid import Grid
from kapsel.fluid import diagnostics as dg

from builders import CROP, extended_input, run_dt, vtk_at, vtk_reader


NS, SNS, LE = "Navier_Stokes", "Shear_Navier_Stokes", "Shear_Navier_Stokes_Lees_Edwards"
NS_FDM, NSCH = "Navier_Stokes_FDM", "Navier_Stokes_Cahn_Hilliard_FDM"
LE_FDM, LECH = "Shear_Navier_Stokes_Lees_Edwards_FDM", "Shear_NS_LE_CH_FDM"
TYPES = list(typespec.names(ions=False))     # every type but Electrolyte (no EXTENDED output)
SHEARED = typespec.names(sheared=True)


def run(d, eq, **kw):
    from builders import cli
    inp = extended_input(d, eq, **kw)
    assert cli(d, inp) == 0
    return h5py.File(os.path.join(d, "out", "traj.h5"), "r")


def fields_expected(eq):
    return ["phi", "pressure", "tau_xx", "tau_xy", "tau_xz", "tau_yy", "tau_yz", "u_x", "u_y",
            "u_z"]


@pytest.mark.parametrize("eq", TYPES)
def test_trajectory_of_every_type(tmp_path, eq):
    """Layout and dtypes of the original; particles in every frame as output.udf has them;
    phi ~ 1 at the grid point nearest each particle; frame times step * dt; gamma = frame
    strain for the sheared types; the .conf; VTK opens both XDMF files (times, points at the
    grid coordinates, array names)."""
    from udf import UDFManager
    f = run(tmp_path, eq)
    dt = run_dt(tmp_path)
    n = 16
    a = f.attrs
    assert a["dx"].dtype == np.float32 and a["dx"].shape == (1,) and a["dx"][0] == 1.0
    assert a["nxnynz"].dtype == np.int64 and list(a["nxnynz"]) == [n, n, n]
    assert a["origin"].dtype == np.float32 and list(a["origin"]) == [0, 0, 0]
    for k in ("nump", "nump_obs", "nump_total"):
        assert a[k].dtype == np.int32 and a[k].shape == (1,)
    assert (a["nump"][0], a["nump_obs"][0], a["nump_total"][0]) == (2, 0, 2)
    assert h5py.h5a.open(f.id, b"git_version").get_type().get_strpad() == h5py.h5t.STR_NULLTERM
    assert sorted(f["system_data"]) == ["field", "particle"]
    x = f["system_data/field/x"]
    assert x.dtype == np.float32 and x.shape == (n, n, n) and x[3, 0, 1] == 3.0
    assert f["system_data/field/z"][3, 0, 1] == 1.0
    assert f["system_data/particle/id"].dtype == np.int32
    np.testing.assert_array_equal(f["system_data/particle/id"], [0, 1])
    np.testing.assert_array_equal(f["system_data/particle/spec"], [0, 0])
    traj = f["trajectory_data"]
    assert sorted(traj) == ["frame_0", "frame_1", "frame_2"]
    out = UDFManager(str(tmp_path / "output.udf"))
    for k in range(3):
        fr = traj[f"frame_{k}"]
        assert fr.attrs["time"].dtype == np.float32 and fr.attrs["time"].shape == (1,)
        assert fr.attrs["time"][0] == np.float32(2 * k * dt)
        assert ("gamma" in fr.attrs) == (eq in SHEARED)
        if eq in (LE, LE_FDM, LECH):
            assert fr.attrs["gamma"][0] == pytest.approx(0.05 * 2 * k * dt, rel=1e-5)
        elif eq == SNS:
            assert fr.attrs["gamma"][0] == 0.0
        assert sorted(fr["field"]) == sorted(fields_expected(eq))
        for name in fr["field"]:
            assert fr["field"][name].dtype == np.float32 and fr["field"][name].shape == (n,) * 3
        p = fr["particle"]
        assert sorted(p) == sorted(["QR", "force_h", "force_r", "omega", "pos", "pos_raw",
                                    "torque_h", "torque_r", "vel"])
        assert p["QR"].shape == (2, 3, 3) and p["pos"].shape == (2, 3)
        assert all(p[d].dtype == np.float32 for d in p)
        out.jump(k)
        np.testing.assert_allclose(p["pos"], out.getArray("Particles[].R"), rtol=1e-6)
        np.testing.assert_allclose(p["vel"], out.getArray("Particles[].v"), rtol=1e-5,
                                   atol=1e-7)
        np.testing.assert_allclose(np.einsum("nac,nbc->nab", p["QR"], p["QR"]),
                                   np.broadcast_to(np.eye(3), (2, 3, 3)), atol=1e-6)
        phi = fr["field/phi"][()]
        for R in p["pos"][()]:
            i, j, l = (int(round(c)) % n for c in R)
            assert phi[i, j, l] > 0.5, (R, phi[i, j, l])
    # FDM types: the trajectory's velocity is the per-snapshot file's (rectangular frame)
    if eq in (NS_FDM, NSCH, LE_FDM, LECH):
        from kapsel.io.fields import read_snapshot
        np.testing.assert_allclose(traj["frame_2/field/u_x"],
                                   read_snapshot(tmp_path / "velocity_2.h5", "UX"),
                                   rtol=1e-6, atol=1e-9)
    f.close()
    conf = (tmp_path / "out" / "traj.conf").read_text()
    assert conf.startswith("#Configure file needed to generate xdmf trajectory\n#v1.1\n"
                           "[Filename]\n traj\n[Grid Dimensions]\n 16 16 16\n[Time Series]\n"
                           f" 0.0 {2 * dt:.6f} 3\n[Particle Number]\n 2\n[Obstacle Number]\n 0\n")
    assert "[Field Vector]\n u_x u_y u_z u\n" in conf and "[Particle Tensor]\n QR\n" in conf
    assert "[Field Scalar]\n pressure\n" in conf
    times = [np.float32(2 * k * dt) for k in range(3)]
    r, steps = vtk_reader(tmp_path / "out" / "traj_fluid.xdmf")
    assert steps == pytest.approx(times)
    grid, arrays = vtk_at(r, times[1])
    assert grid.GetNumberOfPoints() == n ** 3
    assert sorted(arrays) == sorted(["u"] + [k for k in fields_expected(eq)
                                             if not k.startswith("u_")])
    assert arrays["u"].shape == (n ** 3, 3)
    r, steps = vtk_reader(tmp_path / "out" / "traj_particle.xdmf")
    assert steps == pytest.approx(times)
    pts, arrays = vtk_at(r, times[2])
    from vtkmodules.util.numpy_support import vtk_to_numpy
    out.jump(2)
    np.testing.assert_allclose(vtk_to_numpy(pts.GetPoints().GetData()),
                               out.getArray("Particles[].R"), rtol=1e-6)
    assert sorted(arrays) == sorted(["id", "spec", "vel", "omega", "force_h", "force_r",
                                     "torque_h", "torque_r", "QR"])
    assert arrays["QR"].shape == (2, 9)


def test_crop_hyperslab(tmp_path):
    """Crop writes start + m stride of each axis; the XDMF points sit at those grid points
    and hold the values of the full field there."""
    from kapsel.io.fields import read_snapshot
    f = run(tmp_path, NS_FDM, crop=CROP)
    assert list(f.attrs["nxnynz"]) == [5, 16, 3]
    assert list(f.attrs["origin"]) == [1.0, 0.0, 2.0]
    idx = tuple(np.arange(s, s + c * st, st) for s, c, st in CROP)
    X, Y, Z = np.meshgrid(*idx, indexing="ij")
    np.testing.assert_array_equal(f["system_data/field/x"], X)
    np.testing.assert_array_equal(f["system_data/field/z"], Z)
    full = read_snapshot(tmp_path / "velocity_1.h5", "UY")
    np.testing.assert_array_equal(f["trajectory_data/frame_1/field/u_y"],
                                  full[np.ix_(*idx)].astype(np.float32))
    f.close()
    r, _ = vtk_reader(tmp_path / "out" / "traj_fluid.xdmf")
    t = run_dt(tmp_path) * 2
    grid, arrays = vtk_at(r, np.float32(t))
    from vtkmodules.util.numpy_support import vtk_to_numpy
    pts = vtk_to_numpy(grid.GetPoints().GetData())
    # VTK runs the fastest-varying (z) index first
    np.testing.assert_array_equal(pts, np.stack([X, Y, Z], -1).reshape(-1, 3))
    np.testing.assert_array_equal(arrays["u"][:, 1], full[np.ix_(*idx)].astype(np.float32).ravel())


def test_continued_run_appends_frames(tmp_path):
    """A continued run appends frames to the trajectory (the original overwrites it); the
    result equals an uninterrupted run's, frame by frame."""
    from builders import cli
    from udf import UDFManager
    from kapsel.io.restart import state_path
    one = run(tmp_path / "one", NS_FDM, nsnap=4)
    d = tmp_path / "two"
    run(d, NS_FDM, nsnap=2).close()
    rs = UDFManager(str(d / "restart.udf"))
    rs.put(4, "output.Num_snap")
    rs.write(str(d / "cont.udf"))
    shutil.copy(state_path(str(d / "restart.udf")), state_path(str(d / "cont.udf")))
    assert cli(d, "cont.udf") == 0
    with h5py.File(d / "out" / "traj.h5", "r") as two:
        assert sorted(two["trajectory_data"]) == [f"frame_{k}" for k in range(5)]
        for k in range(5):
            a, b = one[f"trajectory_data/frame_{k}"], two[f"trajectory_data/frame_{k}"]
            assert a.attrs["time"][0] == b.attrs["time"][0]
            for name in ("field/u_x", "field/tau_xy", "field/pressure", "particle/pos"):
                np.testing.assert_array_equal(a[name], b[name])
    one.close()
    assert " 5\n[Particle Number]" in (d / "out" / "traj.conf").read_text()
    # the XDMF files' views (kapsel.io.extended) cover every frame of the continued file
    with h5py.File(d / "out" / "traj_xdmf.h5", "r") as x, \
            h5py.File(d / "out" / "traj.h5", "r") as two:
        assert sorted(x) == ["field_xyz", *[f"frame_{k}" for k in range(5)], "particle_vertex"]
        for k in range(5):
            np.testing.assert_array_equal(x[f"frame_{k}/u"][..., 2],
                                          two[f"trajectory_data/frame_{k}/field/u_z"][()])


def test_what_a_type_does_not_compute_is_refused(tmp_path):
    """A print switch (or legacy AVS) needing a field the model does not offer is refused
    with the item named, before anything is written."""
    from kapsel import config
    from kapsel.io.writers import check_output
    from builders import fake_snapshot
    inp = extended_input(tmp_path, NS)
    cfg = config.load(inp)
    snap = fake_snapshot(0)                   # offers u, phi, psi, flux: no pressure, no tau
    with pytest.raises(config.ConfigError, match="Print_field.Pressure.*set it to NO"):
        check_output(cfg, snap)
    cfg = config.load(extended_input(tmp_path, NS, file_type="BINARY"))
    with pytest.raises(config.ConfigError, match="output.ON.FileType.*pressure, viscous stress"):
        check_output(cfg, snap)
    snap.sources.update(pressure=lambda: 0, tau=lambda: 0)
    check_output(cfg, snap)


def test_bad_crop_is_refused(tmp_path, capsys):
    from builders import cli
    inp = extended_input(tmp_path, NS, crop=[(0, 8, 4), (0, 16, 1), (0, 16, 1)])
    assert cli(tmp_path, inp) == 2
    err = capsys.readouterr().err
    assert "Slab_x" in err and "start + (count-1) stride < 16" in err


# ------------------------------------------------------------------------- derived fields
def _grid(n, dx):
    x = np.arange(n) * dx
    return np.meshgrid(x, x, x, indexing="ij")


def test_spectral_pressure_of_the_taylor_green_vortex():
    """u = (sin x cos y, -cos x sin y, 0): p = RHO/4 (cos 2x + cos 2y) (mean 0)."""
    n, rho = 16, 1.7
    X, Y, Z = _grid(n, 2 * np.pi / n)
    u = np.stack([np.sin(X) * np.cos(Y), -np.cos(X) * np.sin(Y), 0 * X])
    p = dg.spectral_pressure(u, None, rho, 0.1, 2 * np.pi / n)
    np.testing.assert_allclose(p, rho / 4 * (np.cos(2 * X) + np.cos(2 * Y)), atol=1e-12)
    # a gradient body force f = RHO du/dt = grad q is balanced by the pressure: p = q
    q = np.cos(X + 2 * Z)
    du = 0.1 / rho * np.stack([-np.sin(X + 2 * Z), 0 * X, -2 * np.sin(X + 2 * Z)])
    np.testing.assert_allclose(dg.spectral_pressure(0 * u, du, rho, 0.1, 2 * np.pi / n), q,
                               atol=1e-12)


def test_spectral_pressure_of_a_sheared_deviation():
    """Deviation u = (0, A sin kx, 0) from U = gamma_dot y e_x: (u.grad)u = 0, and
    lap p = -2 RHO gamma_dot d_x u_y gives p = 2 RHO gamma_dot A cos(kx) / k, also seen
    from an oblique grid."""
    n, rho, rate, A, k = 16, 1.3, 0.2, 0.5, 2.0
    dx = 2 * np.pi / n
    X, Y, Z = _grid(n, dx)
    u = np.stack([0 * X, A * np.sin(k * X), 0 * X])
    p = dg.spectral_pressure(u, None, rho, 0.1, dx, rate=rate)
    np.testing.assert_allclose(p, 2 * rho * rate * A * np.cos(k * X) / k, atol=1e-12)
    # oblique grid of strain g = 1/2: the grid mode (2, 1) is the Cartesian (2, 0) wave
    # (x^ = x - g y), divergence-free; a flat metric would see |k|^2 = 5 instead of 4
    u = np.stack([0 * X, A * np.sin(2 * X + Y), 0 * X])
    p = dg.spectral_pressure(u, None, rho, 0.1, dx, rate=rate, strain=0.5)
    np.testing.assert_allclose(p, 2 * rho * rate * A * np.cos(2 * X + Y) / 2, atol=1e-12)


def test_viscous_stress_spectral_central_and_oblique():
    n, eta = 16, 0.7
    dx = 2 * np.pi / n
    X, Y, Z = _grid(n, dx)
    u = np.stack([np.sin(Y), np.cos(Z), np.sin(X)])
    exact = eta * np.stack([0 * X, np.cos(Y), np.cos(X), 0 * X, -np.sin(Z)])
    tau = dg.stress_from_gradient(dg.velocity_gradient_spectral(u, dx), eta)
    np.testing.assert_allclose(tau, exact, atol=1e-12)
    np.testing.assert_allclose(dg.viscous_stress_spectral(u, dx, eta), exact, atol=1e-12)
    tau = dg.stress_from_gradient(dg.velocity_gradient_central(u, dx), eta)
    np.testing.assert_allclose(tau, exact, atol=0.03)          # O(dx^2)
    # on the oblique grid x^ = x - g y of a field periodic there: d_y = d_y^ - g d_x^
    g = 0.3
    f = np.sin(X + 2 * Y)                                        # a field of (x^, y)
    grad = dg.velocity_gradient_spectral(np.stack([f, 0 * f, 0 * f]), dx, strain=g)
    np.testing.assert_allclose(grad[0, 1], (2 - g) * np.cos(X + 2 * Y), atol=1e-12)
    tau = dg.viscous_stress_spectral(np.stack([f, 0 * f, 0 * f]), dx, eta, strain=g)
    np.testing.assert_allclose(tau[1], eta * (2 - g) * np.cos(X + 2 * Y), atol=1e-12)
    np.testing.assert_allclose(tau[0], 2 * eta * np.cos(X + 2 * Y), atol=1e-12)


def test_pressure_at_the_nodes():
    p = np.zeros((4, 4, 4))
    p[1, 1, 1] = 8.0                   # the cell (1.5, 1.5, 1.5)
    q = dg.pressure_at_nodes(p)
    assert q.sum() == 8.0
    assert all(q[i, j, k] == 1.0 for i in (1, 2) for j in (1, 2) for k in (1, 2))


def test_a_cut_frame_is_dropped_on_continuing(tmp_path):
    """A frame left incomplete by a killed run is not kept when the run is continued."""
    from kapsel.config import FieldOutput
    from kapsel.io.extended import ExtendedHDF5
    from builders import with_stress
    from builders import fake_snapshot, SHAPE, DX, DT

    def writer():
        return ExtendedHDF5(tmp_path, FieldOutput(str(tmp_path), "t", "EXTENDED"), SHAPE, DX,
                            DT, 2, 3, [0, 0, 0], False)
    snaps = [with_stress(fake_snapshot(s)) for s in (0, 2, 4)]
    w = writer()
    w.open(snaps[0], False)
    for s in snaps:
        w.write(s)
    w.close("interrupted")
    with h5py.File(tmp_path / "t.h5", "a") as f:
        del f["trajectory_data/frame_2/field/u_x"]
    w = writer()
    w.open(snaps[2], True)
    assert w.frames == 2 and w._skip is None
    w.write(snaps[2])
    w.close("end")
    with h5py.File(tmp_path / "t.h5", "r") as f:
        assert sorted(f["trajectory_data"]) == ["frame_0", "frame_1", "frame_2"]
        np.testing.assert_array_equal(f["trajectory_data/frame_2/field/u_x"],
                                      snaps[2].get("u")[0].astype(np.float32))
    assert " 0.0 0.125000 3\n" in (tmp_path / "t.conf").read_text()


def test_mac_projection_pressure_balances_a_gradient_force():
    """The FDM pressure adds RHO/dt phi for the particles' increment du: for du = dt/RHO G q
    (a pure B-grid gradient force) that part is q itself (zero mean), in both frames."""
    from kapsel.mesh import operators as op
    from kapsel.fluid.mac import MACSolver
    from kapsel.fluid.oblique import ObliqueMAC
    from kapsel.frame import ShearFlow
    n, dx, rho, dt = 8, 1.0, 1.3, 0.05
    rng = np.random.default_rng(1)
    q = rng.standard_normal((n, n, n))
    q -= q.mean()
    m = MACSolver(Grid((n, n, n), dx), rho, 1.0, dt)
    du = (dt / rho) * op.grad_b(q, dx)
    p = m.projection_pressure(du)
    # the B-grid D G has null modes beyond the mean: compare through G
    np.testing.assert_allclose(op.grad_b(p, dx), op.grad_b(q, dx), atol=1e-10)
    # the oblique solver at strain 0 is the same
    o = ObliqueMAC(Grid((n, n, n), dx), rho, 1.0, dt, ShearFlow("DC", 0.0))
    np.testing.assert_allclose(op.grad_b(o.projection_pressure(du), dx), op.grad_b(q, dx),
                               atol=1e-10)


def test_a_new_run_does_not_replace_a_trajectory(tmp_path, capsys):
    from builders import cli
    run(tmp_path, NS).close()
    os.remove(tmp_path / "output.udf")
    os.remove(tmp_path / "restart.udf")
    assert cli(tmp_path, "input.udf") == 2
    assert "traj.h5 exists; pass --overwrite" in capsys.readouterr().err
    assert cli(tmp_path, "input.udf", "--overwrite") == 0


def test_the_banner_lists_only_the_files_written(tmp_path, capsys):
    """Every Print_field NO: no _fluid.xdmf is written, and the banner does not name one;
    every view it names exists."""
    import re
    from kapsel.cli import main
    from udf import UDFManager
    inp = extended_input(tmp_path, NS, pressure=False)
    u = UDFManager(inp)
    for flag in ("Vel", "Phi", "Tau", "Charge"):
        u.put("NO", f"output.ON.EXTENDED.Print_field.{flag}")
    u.write(inp)
    os.chdir(tmp_path)
    assert main([f"-I{inp}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "1"]) == 0
    cap = capsys.readouterr()
    line = next(x for x in (cap.out + cap.err).splitlines() if "traj.h5 (EXTENDED" in x)
    assert "traj_fluid.xdmf" not in line
    assert not (tmp_path / "out" / "traj_fluid.xdmf").exists()
    named = re.findall(r"traj[\w.]*\.(?:xdmf|conf|h5)", line)
    assert "traj_particle.xdmf" in named
    for f in named:
        assert (tmp_path / "out" / f).exists(), f
