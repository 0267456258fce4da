"""Field snapshots (kapsel.io.fields): HDF5 layout, XDMF time series, atomic writes, VTK reading."""
import os
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

from kapsel.io import fields as fieldsmod
from kapsel.io.fields import FieldWriter, read_snapshot

SHAPE = (8, 4, 2)  # (NX, NY, NZ), non-cubic on purpose
DX = 0.5
TIMES = (0.0, 0.125, 0.75)


def analytic(t, shape=SHAPE, dx=DX):
    """psi, phi, u on the grid at time t, as functions of the physical point (X, Y, Z)."""
    nx, ny, nz = shape
    X, Y, Z = np.meshgrid(np.arange(nx) * dx, np.arange(ny) * dx, np.arange(nz) * dx,
                          indexing="ij")
    return {
        "psi": psi_at(X, Y, Z, t),
        "phi": 0.5 + 0.1 * X - 0.2 * Y + 0.3 * Z * (1 + t),
        "u": np.stack(u_at(X, Y, Z, t)),
    }


def psi_at(X, Y, Z, t):
    return np.sin(X) + 10.0 * Y + 100.0 * Z + 1000.0 * t


def u_at(X, Y, Z, t):
    return (X + t, -2.0 * Y + 3.0 * t, 5.0 * Z - t + X * Y)


def write_series(directory, times=TIMES, **kw):
    w = FieldWriter(directory, SHAPE, DX, **kw)
    for n, t in enumerate(times):
        w.write(n, t, **analytic(t))
    return w


EXPECTED = {"orderparam.xmf", "particle.xmf", "velocity.xmf"} | {
    f"{p}_{n}.h5" for p in ("orderparam", "particle", "velocity") for n in range(3)}


def test_datasets_shapes_values(tmp_path):
    write_series(tmp_path)
    f = analytic(TIMES[1])
    nx, ny, nz = SHAPE
    expect = {"orderparam_1.h5": {"PSI": f["psi"]}, "particle_1.h5": {"PHI": f["phi"]},
              "velocity_1.h5": {"UX": f["u"][0], "UY": f["u"][1], "UZ": f["u"][2]}}
    for name, datasets in expect.items():
        with h5py.File(tmp_path / name, "r") as h:
            assert sorted(h.keys()) == sorted(datasets)
            for ds, field in datasets.items():
                d = h[ds]
                assert d.shape == (nz, ny, nx)
                assert d.dtype == np.float64
                a = d[()]
                for x, y, z in [(0, 0, 0), (7, 0, 0), (1, 3, 0), (5, 2, 1), (7, 3, 1)]:
                    assert a[z, y, x] == field[x, y, z]
                np.testing.assert_array_equal(a, field.transpose(2, 1, 0))
                np.testing.assert_array_equal(read_snapshot(tmp_path / name, ds), field)
    # first dataset by default, as the analysis scripts read them
    np.testing.assert_array_equal(read_snapshot(tmp_path / "orderparam_1.h5"), f["psi"])
    np.testing.assert_array_equal(read_snapshot(tmp_path / "particle_1.h5"), f["phi"])
    np.testing.assert_array_equal(read_snapshot(tmp_path / "velocity_1.h5"), f["u"][0])
    assert read_snapshot(tmp_path / "orderparam_1.h5").shape == SHAPE


def test_temporal_collection(tmp_path):
    write_series(tmp_path)
    assert set(os.listdir(tmp_path)) == EXPECTED  # no temporary file left
    for prefix, attr, datasets in [("orderparam", "PSI", ["PSI"]), ("particle", "PHI", ["PHI"]),
                                   ("velocity", "U", ["UX", "UY", "UZ"])]:
        root = ET.parse(tmp_path / f"{prefix}.xmf").getroot()
        assert root.tag == "Xdmf" and root.get("Version") == "2.0"
        coll = root.find("Domain/Grid")
        assert coll.get("GridType") == "Collection"
        assert coll.get("CollectionType") == "Temporal"
        grids = coll.findall("Grid")
        assert len(grids) == 3
        for n, (g, t) in enumerate(zip(grids, TIMES)):
            assert g.get("GridType") == "Uniform"
            assert float(g.find("Time").get("Value")) == t
            topo = g.find("Topology")
            assert topo.get("TopologyType") == "3DCORECTMesh"
            assert topo.get("Dimensions").split() == ["2", "4", "8"]  # NZ NY NX
            geo = g.find("Geometry")
            assert geo.get("GeometryType") == "ORIGIN_DXDYDZ"
            origin, spacing = geo.findall("DataItem")
            assert [float(v) for v in origin.text.split()] == [0, 0, 0]
            assert [float(v) for v in spacing.text.split()] == [DX] * 3
            a = g.find("Attribute")
            assert a.get("Name") == attr
            if len(datasets) == 1:
                assert a.get("AttributeType") == "Scalar"
                items = a.findall("DataItem")
            else:
                assert a.get("AttributeType") == "Vector"
                (join,) = a.findall("DataItem")
                assert join.get("ItemType") == "Function"
                assert join.get("Function").replace(" ", "") == "JOIN($0,$1,$2)"
                assert join.get("Dimensions").split() == ["2", "4", "8", "3"]
                items = join.findall("DataItem")
            assert [i.text for i in items] == [f"{prefix}_{n}.h5:/{d}" for d in datasets]
            for i in items:
                assert i.get("Format") == "HDF"
                assert i.get("NumberType") == "Float" and i.get("Precision") == "8"
                assert i.get("Dimensions").split() == ["2", "4", "8"]


def test_only_given_fields_written(tmp_path):
    w = FieldWriter(tmp_path, SHAPE, DX, fields=("psi",))
    w.write(0, 0.0, psi=analytic(0.0)["psi"])
    w.write(1, 0.5, psi=analytic(0.5)["psi"], phi=None, u=None)
    assert set(os.listdir(tmp_path)) == {"orderparam.xmf", "orderparam_0.h5", "orderparam_1.h5"}


def test_failed_write_leaves_nothing(tmp_path, monkeypatch):
    w = FieldWriter(tmp_path, SHAPE, DX)
    with pytest.raises(ValueError):
        w.write(0, 0.0, u=np.zeros(SHAPE))  # a vector needs (3, NX, NY, NZ)
    with pytest.raises(ValueError):
        w.write(0, 0.0, psi=np.zeros((2, 4, 8)))  # (NZ, NY, NX) is not the internal order
    assert os.listdir(tmp_path) == []

    def boom(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(fieldsmod.os, "replace", boom)
    with pytest.raises(OSError):
        w.write(0, 0.0, psi=analytic(0.0)["psi"])
    assert os.listdir(tmp_path) == []


def test_files_readable_like_any_other(tmp_path):
    old = os.umask(0o022)
    try:
        write_series(tmp_path, times=TIMES[:1])
    finally:
        os.umask(old)
    assert os.stat(tmp_path / "orderparam_0.h5").st_mode & 0o777 == 0o644
    assert os.stat(tmp_path / "velocity.xmf").st_mode & 0o777 == 0o644


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError):
        FieldWriter(tmp_path, SHAPE, DX, fields=("psi", "pressure"))
    with pytest.raises(ValueError):
        FieldWriter(tmp_path, (8, 4), DX)
    with pytest.raises(ValueError):
        FieldWriter(tmp_path, SHAPE, 0.0)


def grid_times(path):
    root = ET.parse(path).getroot()
    return [float(g.find("Time").get("Value")) for g in root.findall("Domain/Grid/Grid")]


def test_continued_run_appends(tmp_path):
    write_series(tmp_path)
    w = FieldWriter.existing(tmp_path)  # shape, dx and times taken from disk
    assert w.shape == SHAPE and w.dx == DX
    assert w.snapshots["psi"] == dict(enumerate(TIMES))
    w.write(3, 1.5, **analytic(1.5))
    for prefix in ("orderparam", "particle", "velocity"):
        assert grid_times(tmp_path / f"{prefix}.xmf") == [*TIMES, 1.5]

    # the constructor flag does the same; a continuation from an earlier restart point
    # (snapshot 2 again) drops the later snapshots of the run it replaces
    w = FieldWriter(tmp_path, SHAPE, DX, fields=("psi", "phi", "u"), resume=True)
    w.write(2, 0.8, **analytic(0.8))
    assert grid_times(tmp_path / "orderparam.xmf") == [0.0, 0.125, 0.8]
    np.testing.assert_array_equal(read_snapshot(tmp_path / "orderparam_2.h5"),
                                  analytic(0.8)["psi"])

    # a fresh writer starts a new series
    w = FieldWriter(tmp_path, SHAPE, DX)
    w.write(0, 0.0, **analytic(0.0))
    assert grid_times(tmp_path / "velocity.xmf") == [0.0]

    with pytest.raises(ValueError):  # a different grid cannot continue these files
        FieldWriter(tmp_path, (4, 4, 2), DX, resume=True)
    with pytest.raises(ValueError):
        FieldWriter.existing(tmp_path / "empty")


def test_vtk_xdmf2_reader(tmp_path):
    """What ParaView shows: vtkXdmfReader (XDMF2) on the written .xmf files."""
    xdmf2 = pytest.importorskip(
        "vtkmodules.vtkIOXdmf2",
        reason="VTK (pip install vtk) is needed to check the files with ParaView's XDMF reader")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as SDDP

    write_series(tmp_path)
    nx, ny, nz = SHAPE
    points = [(0, 0, 0), (1, 0, 0), (7, 0, 0), (0, 1, 0), (3, 2, 1), (7, 3, 1)]

    def open_reader(name):
        r = xdmf2.vtkXdmfReader()
        r.SetFileName(str(tmp_path / name))
        r.UpdateInformation()
        steps = r.GetOutputInformation(0).Get(SDDP.TIME_STEPS())
        assert steps is not None and tuple(steps) == pytest.approx(TIMES)
        return r

    def check_grid(img):
        assert img.GetDimensions() == SHAPE
        assert img.GetSpacing() == pytest.approx((DX, DX, DX))
        assert img.GetOrigin() == pytest.approx((0, 0, 0))
        assert img.GetNumberOfPoints() == nx * ny * nz

    psi_reader = open_reader("orderparam.xmf")
    u_reader = open_reader("velocity.xmf")
    for t in (TIMES[1], TIMES[2]):
        psi_reader.UpdateTimeStep(t)
        img = psi_reader.GetOutputDataObject(0)
        check_grid(img)
        psi = vtk_to_numpy(img.GetPointData().GetArray("PSI"))
        assert psi.shape == (nx * ny * nz,)
        for x, y, z in points:
            pid = x + nx * (y + ny * z)  # VTK point order: x fastest
            X, Y, Z = img.GetPoint(pid)
            assert (X, Y, Z) == pytest.approx((x * DX, y * DX, z * DX))
            assert psi[pid] == pytest.approx(psi_at(X, Y, Z, t), abs=1e-12)

        u_reader.UpdateTimeStep(t)
        img = u_reader.GetOutputDataObject(0)
        check_grid(img)
        u = vtk_to_numpy(img.GetPointData().GetArray("U"))
        assert u.shape == (nx * ny * nz, 3)
        for x, y, z in points:
            pid = x + nx * (y + ny * z)
            X, Y, Z = img.GetPoint(pid)
            assert tuple(u[pid]) == pytest.approx(u_at(X, Y, Z, t), abs=1e-12)
        # the whole arrays, too
        f = analytic(t)
        np.testing.assert_allclose(psi, f["psi"].ravel(order="F"), atol=0)
        np.testing.assert_allclose(u, f["u"].reshape(3, -1, order="F").T, atol=0)


def test_prefix_names_and_vector_read(tmp_path):
    w = FieldWriter(tmp_path, SHAPE, DX, fields=("orderparam", "velocity"))
    assert w.fields == ("psi", "u")
    f = analytic(0.5)
    w.write(0, 0.5, **f)
    np.testing.assert_array_equal(read_snapshot(tmp_path / "velocity_0.h5", "U"), f["u"])
    w2 = FieldWriter(tmp_path, SHAPE, DX, fields=("psi", "u"))
    assert w2.resume() == {"psi": {0: 0.5}, "phi": {}, "u": {0: 0.5}}
    assert w2.resume(upto=-1)["psi"] == {}
