"""ParaView itself opens every XDMF file kapsel-py writes with its three XDMF readers (the
legacy ``XDMFReader`` and ``Xdmf3ReaderS`` / ``Xdmf3ReaderT``): the grid (points where the
HDF5 files put them, cells), every time step, the arrays under their names with the values
of the HDF5 files; pictures rendered through the Xdmf3 reader show the grid and the
particles; the sample's ParaView state (samples/pv_sample.pvsm, legacy reader) loads with
its files searched under the run directory and shows its picture.

Files: small runs of the three families that write XDMF (Navier_Stokes_Cahn_Hilliard_FDM
with particles: the five per-snapshot .xmf; spectral Navier_Stokes with output.AVS
EXTENDED: _fluid.xdmf and _particle.xdmf; Shear_NS_LE_CH_FDM with particles and a cropped
EXTENDED trajectory), the one-particle layout, every Print_field choice and an obstacle
file (the writers driven directly).  Runs only where ``pvbatch`` is found (under
``xvfb-run`` when there is no display); one pvbatch process does all of it.  About 30 s of
CPU (the runs, ParaView's start), 2 min on a loaded 2-core machine, hence ``slow``.
"""
import json
import os
import shutil
import subprocess

import h5py
import numpy as np
import pytest

from builders import TESTS


HERE = TESTS
SAMPLES = os.path.join(HERE, "..", "samples")
PVBATCH = shutil.which("pvbatch")
READERS = ("XDMFReader", "Xdmf3ReaderS", "Xdmf3ReaderT")
NSCH, LECH = "Navier_Stokes_Cahn_Hilliard_FDM", "Shear_NS_LE_CH_FDM"
BACKGROUND = (0, 255, 0)         # the pictures' background: pure green (grey field, red spheres)


def _launcher():
    if PVBATCH is None:
        return None, "pvbatch (ParaView) not found"
    if os.environ.get("DISPLAY"):
        return [PVBATCH], None
    if shutil.which("xvfb-run"):
        return ["xvfb-run", "-a", PVBATCH], None
    return None, "no display and no xvfb-run: pvbatch cannot render"


LAUNCH, WHY = _launcher()
pytestmark = [pytest.mark.slow, pytest.mark.skipif(LAUNCH is None, reason=WHY or "")]

# --------------------------------------------------------------------------- pvbatch side
PV_SCRIPT = r'''
import json
import sys

import numpy as np
from paraview import servermanager as sm
from paraview import simple as ps
from vtkmodules.util.numpy_support import vtk_to_numpy

READERS = ("XDMFReader", "Xdmf3ReaderS", "Xdmf3ReaderT")


def open_reader(kind, path):
    if kind == "XDMFReader":
        return ps.XDMFReader(FileNames=[path])
    return getattr(ps, kind)(FileName=[path])


def fetch(proxy, t=None):
    if t is not None:
        proxy.UpdatePipeline(t)
    d = sm.Fetch(proxy)
    if d.IsA("vtkMultiBlockDataSet"):
        d = d.GetBlock(0)
    return d


def points(d):
    if d.IsA("vtkImageData"):
        dims, org, spc = d.GetDimensions(), d.GetOrigin(), d.GetSpacing()
        ax = [org[a] + spc[a] * np.arange(dims[a]) for a in range(3)]
        z, y, x = np.meshgrid(ax[2], ax[1], ax[0], indexing="ij")
        return np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    return vtk_to_numpy(d.GetPoints().GetData()).astype(np.float64)    # a copy


def probe(key, path, arrays):
    rows = []
    for kind in READERS:
        r = open_reader(kind, path)
        times = [float(t) for t in r.TimestepValues]
        steps = []
        for i, t in enumerate(times):
            d = fetch(r, t)
            pd = d.GetPointData()
            names = {}
            for k in range(pd.GetNumberOfArrays()):
                a = pd.GetArray(k)
                names[a.GetName()] = a.GetNumberOfComponents()
                # a copy: the Xdmf3 reader frees its buffers at the next time step
                arrays[f"{key}|{kind}|{i}|{a.GetName()}"] = vtk_to_numpy(a).copy()
            if d.GetNumberOfPoints():
                arrays[f"{key}|{kind}|{i}|:points"] = points(d)
            steps.append({"points": d.GetNumberOfPoints(), "cells": d.GetNumberOfCells(),
                          "arrays": names})
        rows.append({"key": key, "reader": kind, "times": times, "steps": steps})
        ps.Delete(r)
    return rows


def to_pixels(view, xyz):
    """(row, column) in the saved picture of world points."""
    ren = view.GetRenderer()
    h = view.ViewSize[1]
    out = []
    for p in xyz:
        ren.SetWorldPoint(float(p[0]), float(p[1]), float(p[2]), 1.0)
        ren.WorldToDisplay()
        x, y, _ = ren.GetDisplayPoint()
        out.append([h - 1 - y, x])
    return out


def unlit(display, rgb=None):
    if rgb is not None:
        display.AmbientColor = list(rgb)
        display.DiffuseColor = list(rgb)
    display.Ambient, display.Diffuse, display.Specular = 1.0, 0.0, 0.0


def picture(job):
    """The plane z = job["z"] of job["fluid"] coloured in grey by job["color"], seen from +z
    in parallel projection, with job["particles"] as unlit red spheres: Xdmf3 reader, last
    time step."""
    v = ps.CreateRenderView()
    v.ViewSize = list(job["size"])
    v.OrientationAxesVisibility = 0
    if hasattr(v, "UseColorPaletteForBackground"):
        v.UseColorPaletteForBackground = 0
    v.Background = [c / 255.0 for c in job["background"]]
    f = ps.Xdmf3ReaderS(FileName=[job["fluid"]])
    t = float(list(f.TimestepValues)[-1])
    v.ViewTime = t
    sl = ps.Slice(Input=f)
    sl.SliceType = "Plane"
    sl.SliceType.Origin = [0.0, 0.0, job["z"]]
    sl.SliceType.Normal = [0.0, 0.0, 1.0]
    sd = ps.Show(sl, v)
    if job.get("component") is None:
        ps.ColorBy(sd, ("POINTS", job["color"]))
    else:
        ps.ColorBy(sd, ("POINTS", job["color"], job["component"]))
    ps.GetColorTransferFunction(job["color"]).ApplyPreset("Grayscale", True)
    sd.RescaleTransferFunctionToDataRange(True, False)
    unlit(sd)
    p = ps.Xdmf3ReaderS(FileName=[job["particles"]])
    g = ps.Glyph(Input=p, GlyphType="Sphere")
    g.ScaleArray = ["POINTS", "No scale array"]
    g.OrientationArray = ["POINTS", "No orientation array"]
    g.ScaleFactor = job["diameter"]
    g.GlyphMode = "All Points"
    g.GlyphType.ThetaResolution = g.GlyphType.PhiResolution = 24
    gd = ps.Show(g, v)
    gd.ColorArrayName = ["POINTS", ""]
    unlit(gd, (1.0, 0.0, 0.0))
    v.CameraParallelProjection = 1
    cx, cy, cz = job["center"]
    v.CameraFocalPoint = [cx, cy, cz]
    v.CameraPosition = [cx, cy, cz + 500.0]
    v.CameraViewUp = [0.0, 1.0, 0.0]
    v.ResetCamera()
    ps.Render(v)
    ps.SaveScreenshot(job["png"], v, ImageResolution=list(job["size"]))
    xyz = points(fetch(p, t))
    s = fetch(sl)
    b = s.GetBounds()
    return {"png": job["png"], "time": t, "particles": xyz.tolist(),
            "particle_pixels": to_pixels(v, xyz), "slice_bounds": list(b),
            "slice_corners": to_pixels(v, [[b[0], b[2], b[4]], [b[1], b[3], b[4]]]),
            "slice_points": s.GetNumberOfPoints()}


def state(job):
    """The ParaView state job["pvsm"], its files searched under job["dir"]."""
    ps.LoadState(job["pvsm"], data_directory=job["dir"], restrict_to_data_directory=True)
    v = ps.GetActiveViewOrCreate("RenderView")
    files = sorted(f for src in ps.GetSources().values() if src.GetXMLName() == "XdmfReader"
                   for f in src.FileNames)
    ps.Render(v)
    ps.SaveScreenshot(job["png"], v, ImageResolution=list(job["size"]))
    return {"png": job["png"], "files": files, "background": [float(c) for c in v.Background],
            "time": float(v.ViewTime)}


job = json.load(open(sys.argv[1]))
arrays = {}
out = {"probe": [], "pictures": [], "state": None}
for key, path in job["probe"]:
    out["probe"] += probe(key, path, arrays)
for p in job["pictures"]:
    out["pictures"].append(picture(p))
if job.get("state"):
    out["state"] = state(job["state"])
np.savez(job["out"] + ".npz", **arrays)
with open(job["out"] + ".json", "w") as fh:
    json.dump(out, fh)
'''


def run_pvbatch(d, job):
    """Run PV_SCRIPT on ``job`` in directory d; (results, arrays).  An X server that fails to
    start (xvfb-run races another one) is tried once more."""
    script, jpath = os.path.join(d, "pv_check.py"), os.path.join(d, "pv_job.json")
    with open(script, "w") as fh:
        fh.write(PV_SCRIPT)
    job = dict(job, out=os.path.join(d, "pv_result"))
    with open(jpath, "w") as fh:
        json.dump(job, fh)
    for attempt in range(2):
        p = subprocess.run(LAUNCH + [script, jpath], capture_output=True, text=True,
                           timeout=900)
        if p.returncode == 0 and os.path.exists(job["out"] + ".json"):
            break
        if attempt or not any(s in p.stderr for s in ("CreateAWindow", "cannot open display",
                                                      "xvfb-run: error")):
            raise AssertionError(f"pvbatch failed ({p.returncode}):\n{p.stderr[-4000:]}")
    with open(job["out"] + ".json") as fh:
        res = json.load(fh)
    with np.load(job["out"] + ".npz") as z:
        arrays = {k: z[k] for k in z.files}
    return res, arrays


# --------------------------------------------------------------------------- the files
def _runs(root):
    """The real runs: {name: directory}."""
    from builders import extended_input
    from builders import cli, make_input
    d = {k: os.path.join(root, k) for k in ("nsch", "spec", "lech", "sample")}
    inp = make_input(d["nsch"], NSCH, particles=4, gts=2, nsnap=2, kBT=0.0)
    assert cli(d["nsch"], inp) == 0
    inp = extended_input(d["spec"], "Navier_Stokes", particles=3, gts=2, nsnap=2)
    assert cli(d["spec"], inp) == 0
    inp = extended_input(d["lech"], LECH, particles=3, gts=2, nsnap=2,
                         crop=[(0, 16, 1), (2, 6, 2), (1, 8, 2)])
    assert cli(d["lech"], inp) == 0
    from builders import run_cli, sample_input
    u = sample_input(d["sample"], NSCH, npx=5)            # the manual's sample, 3 snapshots
    u.put(1, "output.GTS")
    u.put(2, "output.Num_snap")
    u.write(os.path.join(d["sample"], "input.udf"))
    assert run_cli(d["sample"], "input.udf", seed=3) == 0
    return d


def _fake_extended(root):
    """EXTENDED trajectories of every Print_field choice, a crop and an obstacle, written by
    kapsel.io.extended from analytic snapshots: {name: out directory}."""
    from builders import DX, fake_snapshot
    from kapsel.config import FieldOutput
    from kapsel.io.extended import ExtendedHDF5
    shape = (8, 4, 2)
    choices = {"vel": dict(Vel=True), "phi": dict(Phi=True), "pressure": dict(Pressure=True),
               "tau": dict(Tau=True), "charge": dict(Charge=True), "none": {},
               "crop_all": dict(Vel=True, Phi=True, Pressure=True, Tau=True, Charge=True),
               "obstacle": dict(Vel=True)}
    out = {}
    for name, on in choices.items():
        flags = {k: on.get(k, False) for k in ("Vel", "Phi", "Pressure", "Tau", "Charge")}
        slabs = ((1, 3, 2), (0, 4, 1), (0, 2, 1)) if name == "crop_all" else None
        spec = FieldOutput(Out_dir="out", Out_name="traj", FileType="EXTENDED", slabs=slabs,
                           **flags)
        d = os.path.join(root, "fake_" + name)
        w = ExtendedHDF5(os.path.join(d, "out"), spec, shape, DX, 0.0625, 2, 3, [0, 0, 1],
                         sheared=False,
                         obstacles=[2] if name == "obstacle" else ())
        snaps = []
        for step in (0, 2, 4):
            s = fake_snapshot(step, 3, shape)
            X = np.arange(shape[0])[:, None, None] * DX + np.zeros(shape)
            s.sources.update({
                "pressure": lambda X=X, t=s.time: X - t,
                "tau": lambda X=X, t=s.time: np.stack([X * (k + 1) + t for k in range(5)]),
                "surface_charge": lambda X=X: 2 * X, "solute_charge": lambda X=X: 3 * X,
                "e_potential": lambda X=X: 4 * X})
            snaps.append(s)
        w.open(snaps[0], False)
        for s in snaps:
            w.write(s)
        w.close("end")
        out[name] = d
    return out


def _fake_single(root):
    """The per-snapshot files of a one-particle run (the original's (2,) layout)."""
    from builders import write_series
    d = os.path.join(root, "single")
    write_series(d, eq="Navier_Stokes_FDM", steps=(0, 2), n_particles=1)
    return d


# --------------------------------------------------------------------------- expectations
def _grid_points(nx, ny, nz, dx):
    z, y, x = np.meshgrid(np.arange(nz) * dx, np.arange(ny) * dx, np.arange(nx) * dx,
                          indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], 1)


def _snapshots(d, prefix):
    ns = sorted(int(f[len(prefix) + 1:-3]) for f in os.listdir(d)
                if f.startswith(prefix + "_") and f[len(prefix) + 1:-3].isdigit())
    return ns


def expect_series(d, name, n_particles):
    """What a reader must give for .xmf ``name`` of directory d: [(time, points, cells,
    {array: values})] from the HDF5 files alone."""
    prefix, comps = {"fluid_phase": ("orderparam", None), "particle_phase": ("particle", ["PHI"]),
                     "velocity_field": ("velocity", ["UX", "UY", "UZ"]),
                     "flux_field": ("flux", ["FLUX_X", "FLUX_Y", "FLUX_Z"]),
                     "particle_coordinate": ("particle_data", None)}[name]
    out = []
    for n in _snapshots(d, prefix):
        with h5py.File(os.path.join(d, f"{prefix}_{n}.h5"), "r") as h:
            t = float(h.attrs["time"])
            if name == "particle_coordinate":
                pts = np.stack([h[c][()] for c in ("RX", "RY", "RZ")], 1)
                vel = np.stack([h[c][()] for c in ("VX", "VY", "VZ")], 1)
                out.append((t, pts, n_particles, {"particle_velocity": vel}))
                continue
            if comps is None:
                comps = [k for k in h if k in ("PSI_ALL", "PSI")]
            a = [h[c][()] for c in comps]
            nz, ny, nx = a[0].shape
            dx = float(h.attrs["dx"])
            vals = a[0].ravel() if len(a) == 1 else np.stack(a, -1).reshape(-1, 3)
            out.append((t, _grid_points(nx, ny, nz, dx), (nx - 1) * (ny - 1) * (nz - 1),
                        {name: vals}))
    return out


def expect_extended(d, kind):
    """The same for <Out_name>_{fluid,particle,obstacle}.xdmf of trajectory d/out/traj.h5."""
    out = []
    with h5py.File(os.path.join(d, "out", "traj.h5"), "r") as h:
        frames = sorted(h["trajectory_data"], key=lambda k: int(k.split("_")[1]))
        for fr in frames:
            g = h["trajectory_data"][fr]
            t = float(g.attrs["time"][0])
            if kind == "fluid":
                x, y, z = (h[f"system_data/field/{a}"][()] for a in "xyz")
                pts = np.stack([x, y, z], -1).reshape(-1, 3)
                cx, cy, cz = x.shape
                arrays = {k: g["field"][k][()].ravel() for k in g["field"]
                          if k not in ("u_x", "u_y", "u_z")}
                if "u_x" in g["field"]:
                    arrays["u"] = np.stack([g["field"][f"u_{c}"][()] for c in "xyz"],
                                           -1).reshape(-1, 3)
                out.append((t, pts, (cx - 1) * (cy - 1) * (cz - 1), arrays))
            elif kind == "particle":
                p = g["particle"]
                arrays = {k: p[k][()] for k in p if k not in ("pos", "pos_raw", "QR")}
                arrays["QR"] = p["QR"][()].reshape(-1, 9)
                for k in ("id", "spec"):
                    arrays[k] = h[f"system_data/particle/{k}"][()]
                out.append((t, p["pos"][()], len(p["pos"]), arrays))
            else:
                o = g["obstacle"]
                arrays = {k: o[k][()] for k in o}
                for k in ("id", "spec"):
                    arrays[k] = h[f"system_data/obstacle/{k}"][()]
                pos = h["system_data/obstacle/pos"][()]
                out.append((t, pos, len(pos), arrays))
    return out


# --------------------------------------------------------------------------- the test
@pytest.fixture(scope="module")
def paraview(tmp_path_factory):
    root = str(tmp_path_factory.mktemp("paraview"))
    runs = _runs(root)
    fakes = _fake_extended(root)
    single = _fake_single(root)
    probe, want = [], {}
    for fam in ("nsch", "lech"):
        d = runs[fam]
        for f in sorted(os.listdir(d)):
            if f.endswith(".xmf"):
                key = f"{fam}/{f}"
                probe.append([key, os.path.join(d, f)])
                want[key] = expect_series(d, f[:-4], 4 if fam == "nsch" else 3)
    for f in ("velocity_field", "particle_coordinate"):
        probe.append([f"single/{f}.xmf", os.path.join(single, f + ".xmf")])
        want[f"single/{f}.xmf"] = expect_series(single, f, 1)
    trajs = {"spec": runs["spec"], "lech": runs["lech"], **fakes}
    for name, d in trajs.items():
        for kind in ("fluid", "particle", "obstacle"):
            path = os.path.join(d, "out", f"traj_{kind}.xdmf")
            if os.path.exists(path):
                probe.append([f"{name}/traj_{kind}.xdmf", path])
                want[f"{name}/traj_{kind}.xdmf"] = expect_extended(d, kind)
    pictures = [
        dict(png=os.path.join(root, "nsch_psi_particles.png"),
             fluid=os.path.join(runs["sample"], "fluid_phase.xmf"),
             particles=os.path.join(runs["sample"], "particle_coordinate.xmf"),
             color="fluid_phase", z=0.5, diameter=8.0, center=[16, 16, 16]),
        dict(png=os.path.join(root, "extended_fluid.png"),
             fluid=os.path.join(runs["spec"], "out", "traj_fluid.xdmf"),
             particles=os.path.join(runs["spec"], "out", "traj_particle.xdmf"),
             color="pressure", z=0.5, diameter=3.0, center=[8, 8, 8]),
        dict(png=os.path.join(root, "lech_psi_particles.png"),
             fluid=os.path.join(runs["lech"], "fluid_phase.xmf"),
             particles=os.path.join(runs["lech"], "particle_coordinate.xmf"),
             color="fluid_phase", z=0.5, diameter=3.0, center=[8, 8, 8])]
    for p in pictures:
        p.update(size=[400, 400], background=list(BACKGROUND))
    job = {"probe": probe, "pictures": pictures,
           "state": {"pvsm": os.path.abspath(os.path.join(SAMPLES, "pv_sample.pvsm")),
                     "dir": runs["sample"], "png": os.path.join(root, "pv_sample.png"),
                     "size": [600, 500]}}
    res, arrays = run_pvbatch(root, job)
    return res, arrays, want, runs


def test_every_file_with_every_reader(paraview):
    """Each file x reader: the time steps, and at each the points (where the HDF5 files put
    them), the cells, the arrays by name, components and values."""
    res, arrays, want, _ = paraview
    rows = res["probe"]
    assert {(r["key"], r["reader"]) for r in rows} == {(k, rd) for k in want for rd in READERS}
    for r in rows:
        key, rd = r["key"], r["reader"]
        expected = want[key]
        where = f"{key} with {rd}"
        assert r["times"] == pytest.approx([e[0] for e in expected], rel=1e-6, abs=1e-12), where
        print(f"{key:40s} {rd:13s} times {len(r['times'])} points {r['steps'][-1]['points']} "
              f"cells {r['steps'][-1]['cells']} arrays "
              f"{' '.join(f'{a}:{c}' for a, c in sorted(r['steps'][-1]['arrays'].items()))}")
        for i, (step, (t, pts, cells, vals)) in enumerate(zip(r["steps"], expected)):
            assert step["points"] == len(pts) and step["cells"] == cells, (where, i, step)
            assert step["arrays"] == {k: (1 if v.ndim == 1 else v.shape[1])
                                      for k, v in vals.items()}, (where, i)
            np.testing.assert_allclose(arrays[f"{key}|{rd}|{i}|:points"], pts, rtol=1e-12,
                                       atol=1e-12, err_msg=where)
            for k, v in vals.items():
                got = arrays[f"{key}|{rd}|{i}|{k}"]
                np.testing.assert_array_equal(got.reshape(v.shape), v, err_msg=f"{where} {k}")


def _image(path):
    from vtkmodules.vtkIOImage import vtkPNGReader
    from vtkmodules.util.numpy_support import vtk_to_numpy
    r = vtkPNGReader()
    r.SetFileName(path)
    r.Update()
    img = r.GetOutput()
    w, h, _ = img.GetDimensions()
    a = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, -1)[::-1, :, :3]
    return a.astype(int)                                    # rows from the top


def test_pictures_through_the_xdmf3_reader(paraview):
    """A plane of the field in grey and the particles as red spheres, seen from +z: inside
    the plane's outline every pixel is field or particle (none of the green background) and
    the field is not uniform; at the centre of every particle above the plane the picture is
    red; the image corners are background."""
    pytest.importorskip("vtkmodules.vtkIOImage", reason="VTK reads the PNG pictures")
    res, *_ = paraview
    assert len(res["pictures"]) == 3
    for pic in res["pictures"]:
        img = _image(pic["png"])
        h, w, _ = img.shape
        name = os.path.basename(pic["png"])
        green = np.all(img == BACKGROUND, axis=-1)
        red = (img[..., 0] > 200) & (img[..., 1] < 60) & (img[..., 2] < 60)
        grey = (np.abs(img[..., 0] - img[..., 1]) < 12) & (np.abs(img[..., 1] - img[..., 2]) < 12)
        assert pic["slice_points"] > 0, name
        (r0, c0), (r1, c1) = pic["slice_corners"]
        top, bottom = int(np.ceil(min(r0, r1))) + 2, int(np.floor(max(r0, r1))) - 2
        left, right = int(np.ceil(min(c0, c1))) + 2, int(np.floor(max(c0, c1))) - 2
        assert bottom - top > 50 and right - left > 50, (name, pic["slice_corners"])
        inside = (slice(top, bottom), slice(left, right))
        assert not green[inside].any(), name
        assert (red | grey)[inside].mean() > 0.99, name
        assert grey[inside].sum() > 200, name
        levels = img[inside][..., 0][grey[inside]]
        assert levels.std() > 10, (name, levels.std())            # a field, not a flat plane
        seen = 0
        for (row, col), p in zip(pic["particle_pixels"], pic["particles"]):
            if p[2] > 1.0 and 0 <= row < h and 0 <= col < w:
                assert red[int(round(row)), int(round(col))], (name, p, row, col)
                seen += 1
        assert seen >= 1, name
        assert all(green[r, c] for r, c in [(0, 0), (0, w - 1), (h - 1, 0), (h - 1, w - 1)])


def test_sample_state_loads_and_shows_its_picture(paraview):
    """samples/pv_sample.pvsm with "search files under the directory": both files found in
    the run directory, and the picture is the volume-rendered box with its glyphs: many
    pixels off the background in the middle, few at the border."""
    pytest.importorskip("vtkmodules.vtkIOImage", reason="VTK reads the PNG pictures")
    res, _a, _w, runs = paraview
    st = res["state"]
    assert st["files"] == sorted(os.path.join(runs["sample"], f)
                                 for f in ("fluid_phase.xmf", "particle_coordinate.xmf"))
    img = _image(st["png"])
    h, w, _ = img.shape
    bg = np.round(np.asarray(st["background"]) * 255).astype(int)
    off = np.abs(img - bg).sum(-1) > 30
    middle = off[h // 4: 3 * h // 4, w // 4: 3 * w // 4]
    assert middle.mean() > 0.8, middle.mean()
    border = np.concatenate([off[:10].ravel(), off[:, -10:].ravel()])
    assert border.mean() < 0.2, border.mean()
    # the particles' glyphs are white-grey spheres: such pixels are there
    whiteish = (img.min(-1) > 170) & (np.ptp(img, axis=-1) < 25)
    assert whiteish[h // 8: 7 * h // 8, w // 8: 7 * w // 8].sum() > 200
