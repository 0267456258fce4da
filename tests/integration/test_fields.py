"""The FDM types' per-snapshot files (kapsel.io.fields): the original's names, datasets and
.xmf text (FORMAT-OUTPUT.md §4), read back with h5py and with VTK's XDMF reader (what
ParaView uses), atomic writes, continued runs, and the sample's ParaView state."""
import os
import re
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

from kapsel import typespec
from kapsel.io import atomic
from kapsel.io.fields import XMF_NAMES, SnapshotFiles, read_snapshot

from builders import (DT, DX, fake_snapshot, GTS, NSCH, run_dt, SHAPE, TESTS, vtk_at, vtk_reader,
                      write_series)


LECH = "Shear_NS_LE_CH_FDM"
SAMPLES = os.path.join(TESTS, "..", "samples")


def test_names_datasets_and_layout(tmp_path):
    write_series(tmp_path)
    names = set(os.listdir(tmp_path))
    assert names == {"fluid_phase.xmf", "particle_phase.xmf", "particle_coordinate.xmf",
                     "velocity_field.xmf", "flux_field.xmf"} | {
        f"{p}_{n}.h5" for p in ("orderparam", "flux", "particle", "particle_data", "velocity",
                                "xdmf") for n in range(3)}     # and no temporary file left
    snap = fake_snapshot(2)
    nx, ny, nz = SHAPE
    expect = {"orderparam_1.h5": {"PSI_ALL": snap.get("psi_all")},
              "particle_1.h5": {"PHI": snap.get("phi")},
              "velocity_1.h5": {f"U{c}": snap.get("u")[i] for i, c in enumerate("XYZ")},
              "flux_1.h5": {f"FLUX_{c}": snap.get("flux")[i] for i, c in enumerate("XYZ")}}
    for name, datasets in expect.items():
        with h5py.File(tmp_path / name, "r") as h:
            assert sorted(h.keys()) == sorted(datasets)
            for ds, field in datasets.items():
                d = h[ds]
                assert d.shape == (nz, ny, nx) and d.dtype == np.dtype("<f8")
                a = d[()]
                for x, y, z in [(0, 0, 0), (7, 0, 0), (1, 3, 0), (5, 2, 1), (7, 3, 1)]:
                    assert a[z, y, x] == field[x, y, z]
                np.testing.assert_array_equal(read_snapshot(tmp_path / name, ds), field)
    with h5py.File(tmp_path / "particle_data_1.h5", "r") as h:
        assert sorted(h.keys()) == ["DEGREE_OBLIQUE", "RX", "RY", "RZ", "VX", "VY", "VZ"]
        for i, c in enumerate("XYZ"):
            assert h[f"R{c}"].dtype == np.dtype("<f8") and h[f"R{c}"].shape == (3,)
            np.testing.assert_array_equal(h[f"R{c}"][()], snap.particles.R[:, i])
            np.testing.assert_array_equal(h[f"V{c}"][()], snap.particles.v[:, i])
        assert h["DEGREE_OBLIQUE"].shape == (1,)
    # xdmf_<n>.h5: views of the components (no data of their own) and the vertex list
    with h5py.File(tmp_path / "xdmf_1.h5", "r") as h:
        assert sorted(h.keys()) == ["flux_field", "particle_position", "particle_velocity",
                                    "particle_vertex", "velocity_field"]
        for name, src, comps in [("velocity_field", "velocity_1.h5", ["UX", "UY", "UZ"]),
                                 ("flux_field", "flux_1.h5", ["FLUX_X", "FLUX_Y", "FLUX_Z"]),
                                 ("particle_position", "particle_data_1.h5", ["RX", "RY", "RZ"]),
                                 ("particle_velocity", "particle_data_1.h5", ["VX", "VY", "VZ"])]:
            d = h[name]
            assert d.is_virtual and d.dtype == np.dtype("<f8")
            assert {(m.file_name, m.dset_name) for m in d.virtual_sources()} == \
                {(src, c) for c in comps}
            with h5py.File(tmp_path / src, "r") as g:
                np.testing.assert_array_equal(d[()], np.stack([g[c][()] for c in comps], -1))
        assert h["velocity_field"].shape == (nz, ny, nx, 3)
        assert h["particle_vertex"].dtype == np.int32
        np.testing.assert_array_equal(h["particle_vertex"][()], [0, 1, 2])


def test_which_files_each_type_writes(tmp_path):
    for eq, particles, want in [
            (LECH, 2, {"orderparam", "particle", "particle_data", "velocity", "xdmf"}),
            ("Navier_Stokes_FDM", 0, {"velocity", "xdmf"}),
            ("Shear_Navier_Stokes_Lees_Edwards_FDM", 1, {"particle", "particle_data",
                                                          "velocity", "xdmf"})]:
        d = tmp_path / eq
        write_series(d, eq=eq, steps=(0,), n_particles=particles)
        assert {n.rsplit("_", 1)[0] for n in os.listdir(d) if n.endswith(".h5")} == want
    with h5py.File(tmp_path / LECH / "orderparam_0.h5", "r") as h:
        assert list(h) == ["PSI"]


def test_xmf_text(tmp_path):
    """The original's text (grid and attribute names, layout, spacing) with what the Xdmf3
    readers need: Dimensions on the topology, a Center on every attribute, the vectors and
    particle positions as one plain HDF item of xdmf_<n>.h5 each (kapsel.io.fields)."""
    write_series(tmp_path, steps=(0, 2))
    text = (tmp_path / "fluid_phase.xmf").read_text()
    first = text.split('<Grid Name="Structured grid"')[0]
    assert first == ('<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
                     '<Xdmf Version="2.0">\n<Domain>\n<Grid Name="CellTime" '
                     'GridType="Collection" CollectionType="Temporal">\n\n')
    grid = ('<Grid Name="Structured grid" GridType="Uniform">\n<Time Value="0.125" />\n'
            '<Topology Name="tp" TopologyType="3DCORECTMesh" Dimensions="2 4 8"/>\n'
            '<Geometry Name="geo" GeometryType="ORIGIN_DXDYDZ">\n'
            '<DataItem Name="Origin" Dimensions="3" NumberType="Float" Precision="4" '
            'Format="XML">\n0 0 0\n</DataItem>\n'
            '<DataItem Name="Spacing" Dimensions="3" NumberType="Float" Precision="4" '
            'Format="XML">\n0.5 0.5 0.5\n</DataItem>\n</Geometry>\n'
            '<Attribute Name = "fluid_phase" AttributeType = "Scalar" Center = "Node">\n'
            '<DataItem Dimensions="2 4 8" NumberType="Float" Precision="8" Format="HDF">\n'
            'orderparam_1.h5:/PSI_ALL\n</DataItem>\n</Attribute>\n</Grid>\n\n')
    assert grid in text
    assert text.endswith("</Grid>\n\n</Grid>\n</Domain>\n</Xdmf>\n")
    vec = (tmp_path / "velocity_field.xmf").read_text()
    assert ('<Attribute Name = "velocity_field" AttributeType = "Vector" Center = "Node">\n'
            '<DataItem Dimensions="2 4 8 3" NumberType="Float" Precision="8" Format="HDF">\n'
            'xdmf_1.h5:/velocity_field\n</DataItem>\n</Attribute>\n') in vec
    part = (tmp_path / "particle_coordinate.xmf").read_text()
    assert ('<Topology Name="tp" TopologyType="Polyvertex" NumberOfElements="3">\n'
            '<DataItem Dimensions="3" NumberType="Int" Precision="4" Format="HDF">\n'
            'xdmf_0.h5:/particle_vertex\n</DataItem>\n</Topology>\n'
            '<Geometry GeometryType="XYZ">\n'
            '<DataItem Dimensions="3 3" NumberType="Float" Precision="8" Format="HDF">\n'
            'xdmf_0.h5:/particle_position\n</DataItem>\n</Geometry>\n'
            '<Attribute Name = "particle_velocity" AttributeType = "Vector" Center = "Node">\n'
            '<DataItem Dimensions="3 3" NumberType="Float" Precision="8" Format="HDF">\n'
            'xdmf_0.h5:/particle_velocity\n</DataItem>\n</Attribute>\n') in part
    for name in XMF_NAMES:
        text = (tmp_path / name).read_text()
        assert "Function" not in text and "NumberOfElements=\"2 4 8\"" not in text
        root = ET.fromstring(text)
        assert all(a.get("Center") == "Node" for a in root.iter("Attribute"))
    for name in ("fluid_phase", "particle_phase", "particle_coordinate", "velocity_field",
                 "flux_field"):
        root = ET.parse(tmp_path / f"{name}.xmf").getroot()
        assert [g.get("Name") for g in root.findall("Domain/Grid/Grid")] == \
            ["Structured grid"] * 2


def test_single_particle_layout(tmp_path):
    """The original writes each particle array with shape (2,) for one particle (dummy -1)."""
    write_series(tmp_path, eq="Navier_Stokes_FDM", steps=(0,), n_particles=1)
    with h5py.File(tmp_path / "particle_data_0.h5", "r") as h:
        for c in ("RX", "RY", "RZ", "VX", "VY", "VZ"):
            assert h[c].shape == (2,) and h[c][1] == -1.0
        assert h["RX"][0] == 0.25
    text = (tmp_path / "particle_coordinate.xmf").read_text()
    assert 'NumberOfElements="1"' in text and 'Dimensions="2 3"' in text
    r, steps = vtk_reader(tmp_path / "particle_coordinate.xmf")     # ParaView reads it
    assert steps == (0.0,)
    pts, arrays = vtk_at(r, 0.0)
    from vtkmodules.util.numpy_support import vtk_to_numpy
    p = fake_snapshot(0, 1).particles
    np.testing.assert_array_equal(vtk_to_numpy(pts.GetPoints().GetData())[0], p.R[0])
    np.testing.assert_array_equal(arrays["particle_velocity"][0], p.v[0])


def check_xmf_with_vtk(directory, shape, dx, times, fields, particles=None):
    """Open every .xmf of a directory with VTK: time values, grid dimensions and spacing,
    array names, field values at the right points (``fields``: xmf name -> function t ->
    array [x, y, z] or (3, ...)), particle positions and velocities (``particles``: t ->
    (R, v))."""
    nx, ny, nz = shape
    for name, field in fields.items():
        r, steps = vtk_reader(os.path.join(directory, name + ".xmf"))
        assert steps == pytest.approx(times), name
        for t in times:
            img, arrays = vtk_at(r, t)
            assert img.GetDimensions() == tuple(shape)
            assert img.GetSpacing() == pytest.approx((dx,) * 3)
            assert img.GetOrigin() == pytest.approx((0, 0, 0))
            assert list(arrays) == [name]
            want = field(t)
            got = arrays[name]
            if want.ndim == 4:   # VTK point order: x fastest
                np.testing.assert_array_equal(got, want.reshape(3, -1, order="F").T)
            else:
                np.testing.assert_array_equal(got, want.ravel(order="F"))
            for x, y, z in [(1, 0, 0), (0, 1, 0), (0, 0, 1), (nx - 1, ny - 1, nz - 1)]:
                assert img.GetPoint(x + nx * (y + ny * z)) == pytest.approx(
                    (x * dx, y * dx, z * dx))
    if particles is not None:
        r, steps = vtk_reader(os.path.join(directory, "particle_coordinate.xmf"))
        assert steps == pytest.approx(times)
        for t in times:
            pts, arrays = vtk_at(r, t)
            R, v = particles(t)
            assert list(arrays) == ["particle_velocity"]
            from vtkmodules.util.numpy_support import vtk_to_numpy
            got = vtk_to_numpy(pts.GetPoints().GetData())
            np.testing.assert_array_equal(got[:len(R)], R)
            np.testing.assert_array_equal(arrays["particle_velocity"][:len(R)], v)


def test_vtk_reads_the_series(tmp_path):
    write_series(tmp_path)
    times = [0.0, 2 * DT, 4 * DT]

    def f(name, comp=None):
        return lambda t: fake_snapshot(int(round(t / DT))).get(name)

    def parts(t):
        p = fake_snapshot(int(round(t / DT))).particles
        return p.R, p.v

    check_xmf_with_vtk(tmp_path, SHAPE, DX, times,
                       {"fluid_phase": f("psi_all"), "particle_phase": f("phi"),
                        "velocity_field": f("u"), "flux_field": f("flux")}, parts)


def test_continued_run_appends_and_replaces(tmp_path):
    write_series(tmp_path, steps=(0, 2, 4))
    before = os.stat(tmp_path / "velocity_2.h5").st_mtime_ns
    # continue from step 4: the earlier snapshots stay listed, step 4 is not rewritten
    w = write_series(tmp_path, steps=(4, 6), resumed=True)
    assert os.stat(tmp_path / "velocity_2.h5").st_mtime_ns == before
    assert w.times == {n: 2 * n * DT for n in range(4)}
    _r, steps = vtk_reader(tmp_path / "fluid_phase.xmf")
    assert steps == pytest.approx([0, 2 * DT, 4 * DT, 6 * DT])
    # continue from an earlier restart (step 2): the later snapshots of the replaced run go
    w = write_series(tmp_path, steps=(2, 4), resumed=True)
    assert sorted(w.times) == [0, 1, 2]
    # a new run starts a new series
    w = write_series(tmp_path, steps=(0,))
    assert w.times == {0: 0.0}


def test_continuing_files_without_xdmf_views(tmp_path):
    """Snapshots written without xdmf_<n>.h5 (the original's, or an older kapsel-py's) get
    it when a run continues them, so the rewritten .xmf files open."""
    write_series(tmp_path, steps=(0, 2))
    for n in (0, 1):
        os.remove(tmp_path / f"xdmf_{n}.h5")
    write_series(tmp_path, steps=(2, 4), resumed=True)
    for n in (0, 1, 2):
        with h5py.File(tmp_path / f"xdmf_{n}.h5", "r") as h, \
                h5py.File(tmp_path / f"velocity_{n}.h5", "r") as v:
            np.testing.assert_array_equal(h["velocity_field"][..., 1], v["UY"][()])
    check_xmf_with_vtk(tmp_path, SHAPE, DX, [0.0, 2 * DT, 4 * DT],
                       {"velocity_field": lambda t: fake_snapshot(int(round(t / DT))).get("u")})


def test_failed_write_leaves_nothing(tmp_path, monkeypatch):
    w = SnapshotFiles(tmp_path, NSCH, SHAPE, DX, GTS, 3)
    bad = fake_snapshot(0, shape=(2, 4, 8))     # (NZ, NY, NX) is not the internal order
    w.open(bad, False)
    with pytest.raises(ValueError):
        w.write(bad)
    assert os.listdir(tmp_path) == []

    def boom(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(atomic.os, "replace", boom)
    with pytest.raises(OSError):
        w.write(fake_snapshot(0))
    assert os.listdir(tmp_path) == []


def test_files_readable_like_any_other(tmp_path):
    old = os.umask(0o022)
    try:
        write_series(tmp_path, steps=(0,))
    finally:
        os.umask(old)
    assert os.stat(tmp_path / "orderparam_0.h5").st_mode & 0o777 == 0o644
    assert os.stat(tmp_path / "velocity_field.xmf").st_mode & 0o777 == 0o644


# ------------------------------------------------------------------------- real runs
def run_type(d, eq, particles=2, gts=2, nsnap=2):
    """A 16^3 run of ``eq`` (any type) through the command line, in ``d``."""
    from builders import cli, make_input
    from udf import UDFManager
    inp = make_input(d, eq if "Shear" not in eq else NSCH, particles=particles, gts=gts,
                     nsnap=nsnap, kBT=0.0)
    if "Shear" in eq:
        u = UDFManager(inp)
        u.put(eq, "constitutive_eq.type")
        base = f"constitutive_eq.{eq}"
        u.put("DC", f"{base}.External_field.type")
        u.put(0.05, f"{base}.External_field.DC.Shear_rate")
        u.write(inp)
    assert cli(d, inp) == 0
    return UDFManager(os.path.join(d, "output.udf"))


FDM = list(typespec.names(grid="fdm"))


@pytest.mark.parametrize("eq", FDM)
def test_every_fdm_type_with_vtk(tmp_path, eq):
    """Every .xmf of a real run opens in VTK with the snapshots' times (step * dt), the
    mesh, the arrays of the original, the particles where output.udf has them and psi as
    its PSI records."""
    out = run_type(tmp_path, eq)
    dt = run_dt(tmp_path)
    times = [0.0, 2 * dt, 4 * dt]
    n = 16

    def h5field(prefix, names):
        def get(t):
            k = int(round(t / (2 * dt)))
            arrs = [read_snapshot(tmp_path / f"{prefix}_{k}.h5", ds) for ds in names]
            return arrs[0] if len(arrs) == 1 else np.stack(arrs)
        return get

    psi_name = "PSI_ALL" if eq == NSCH else "PSI"
    fields = {"particle_phase": h5field("particle", ["PHI"]),
              "velocity_field": h5field("velocity", ["UX", "UY", "UZ"])}
    if eq in (NSCH, LECH):
        fields["fluid_phase"] = h5field("orderparam", [psi_name])
    if eq == NSCH:
        fields["flux_field"] = h5field("flux", ["FLUX_X", "FLUX_Y", "FLUX_Z"])
    xmfs = {f for f in os.listdir(tmp_path) if f.endswith(".xmf")}
    assert xmfs == {f + ".xmf" for f in fields} | {"particle_coordinate.xmf"}

    def parts(t):
        out.jump(int(round(t / (2 * dt))))
        return out.getArray("Particles[].R"), out.getArray("Particles[].v")

    # output.udf holds single precision: compare the particles through float32
    def parts32(t):
        R, v = parts(t)
        k = int(round(t / (2 * dt)))
        with h5py.File(tmp_path / f"particle_data_{k}.h5") as h:
            np.testing.assert_allclose(np.stack([h["RX"], h["RY"], h["RZ"]], 1), R,
                                       rtol=1e-6)
            assert h["DEGREE_OBLIQUE"][0] == pytest.approx(
                0.05 * t if "Shear" in eq else 0.0, abs=1e-12)
            return np.stack([h["RX"], h["RY"], h["RZ"]], 1), np.stack([h["VX"], h["VY"],
                                                                       h["VZ"]], 1)
    check_xmf_with_vtk(tmp_path, (n, n, n), 1.0, times, fields, parts32)
    if eq == NSCH:              # what `kapsel-py analyze sq` reads
        from kapsel.analysis import structure_factor as sq
        assert len(sq.snapshot_files(str(tmp_path))) == 3
        assert sq.snapshot_times(str(tmp_path)) == pytest.approx(dict(enumerate(times)))
        assert sq.read_psi(str(tmp_path / "orderparam_1.h5")).shape == (n, n, n)
    if eq in (NSCH, LECH):
        out.jump(2)
        psi = out.getArray("PSI[]")[..., 0]
        np.testing.assert_allclose(read_snapshot(tmp_path / "orderparam_2.h5"), psi,
                                   atol=1e-6)


def pvsm_references(path):
    """(files, arrays, grids) the ParaView state refers to: the XdmfReader file names, their
    point arrays and grid names."""
    root = ET.parse(path).getroot()
    files, arrays, grids = set(), set(), set()
    for proxy in root.iter("Proxy"):
        if proxy.get("group") != "sources" or proxy.get("type") != "XdmfReader":
            continue
        for prop in proxy.findall("Property"):
            values = [e.get("value") for e in prop.findall("Element")]
            if prop.get("name") == "FileNames":
                files |= {os.path.basename(v) for v in values}
            elif prop.get("name") == "PointArrayStatus":
                arrays |= set(values[0::2])
            elif prop.get("name") == "GridInfo":
                grids |= set(values)
    return files, arrays, grids


def test_pv_sample_state_finds_its_files(tmp_path):
    """samples/pv_sample.pvsm (the original's sample state): every file, point array and
    grid name it refers to is there after a short run of the sample's type."""
    files, arrays, grids = pvsm_references(os.path.join(SAMPLES, "pv_sample.pvsm"))
    assert files == {"fluid_phase.xmf", "particle_coordinate.xmf"}
    assert arrays == {"fluid_phase", "particle_velocity"}
    assert "Structured grid" in grids and "Structured grid[10]" in grids
    run_type(tmp_path, NSCH, particles=2, gts=1, nsnap=10)
    found_arrays, found_grids = set(), set()
    for f in files:
        assert (tmp_path / f).exists(), f
        r, steps = vtk_reader(tmp_path / f)
        assert len(steps) == 11                       # as the state's TimestepValues
        found_arrays |= {r.GetPointArrayName(i) for i in range(r.GetNumberOfPointArrays())}
        # the reader names the k-th repeated grid name "<name>[k]", as the state lists them
        found_grids |= {r.GetGridName(i) for i in range(r.GetNumberOfGrids())}
        for ref in re.findall(r"\n([\w.]+\.h5):/", (tmp_path / f).read_text()):
            assert (tmp_path / ref).exists(), ref
    assert arrays <= found_arrays
    assert grids <= found_grids
