"""output.AVS ON, FileType BINARY / ASCII (kapsel.io.avs): the legacy AVS files exactly as
FORMAT-OUTPUT.md §2 describes, read back by following the .fld as AVS does."""
import os
import re

import numpy as np
import pytest

from kapsel import typespec
from kapsel.io.avs import LegacyAVS
from kapsel.config import FieldOutput

from builders import DT, DX, fake_snapshot, SHAPE, with_stress


NX, NY, NZ = SHAPE


def avs_writer(d, kind="BINARY", n_particles=3, num_snap=2):
    return LegacyAVS(d, FieldOutput(str(d), "run", kind), SHAPE, DX, num_snap, n_particles,
                     fake_snapshot(0, n_particles).particles)


def write(d, kind="BINARY", steps=(0, 2, 4), n_particles=3, resumed=False, num_snap=2):
    w = avs_writer(d, kind, n_particles, num_snap)
    snaps = [with_stress(fake_snapshot(s, n_particles)) for s in steps]
    w.open(snaps[0], resumed)
    for s in snaps:
        w.write(s)
    w.close("end")
    return w, snaps


def read_fld(path, base):
    """Follow an AVS .fld: {step: {variable n: values, coord n: values}} (float32 arrays)."""
    text = open(path).read()
    head = dict(re.findall(r"^(\w+)=(\S+)$", text.split("time value")[0], re.M))
    out = {}
    for block in re.findall(r'time value = "step(\d+)time[^"]*"\n(.*?)\nEOT', text, re.S):
        step, body = int(block[0]), block[1]
        vals = {}
        for kind, n, fname, ftype, rest in re.findall(
                r"(coord|variable) (\d+) file = (\S+) filetype = (\w+) (.*)", body):
            opts = dict(re.findall(r"(\w+) =\s*(\d+)", rest))
            path_ = os.path.join(base, fname)
            if ftype == "binary":
                count = int(head["dim1"]) * int(head.get("dim2", 1)) * int(head.get("dim3", 1))
                if kind == "coord" and head["field"] == "uniform":
                    continue
                a = np.fromfile(path_, dtype=np.float32, count=count,
                                offset=int(opts["skip"]))
            else:
                rows = open(path_).read().splitlines()[int(opts["skip"]):]
                if head["field"] == "uniform" and kind == "coord":
                    a = np.array([float(rows[0])])
                else:
                    table = np.array([[float(v) for v in r.split()] for r in rows])
                    a = table[:, int(opts["offset"])]
            vals[(kind, int(n))] = a
        out[step] = vals
    return head, out


@pytest.mark.parametrize("kind", ["BINARY", "ASCII"])
def test_field_and_particle_files(tmp_path, kind):
    w, snaps = write(tmp_path, kind)
    names = sorted(os.listdir(tmp_path))
    assert names == ["avs", "run.cod", "run.fld", "runp.fld"]
    assert sorted(os.listdir(tmp_path / "avs")) == sorted(
        [f"run_{s}.dat" for s in (0, 2, 4)] + [f"runp_{s}.cod" for s in (0, 2, 4)]
        + [f"runp_{s}.dat" for s in (0, 2, 4)])
    fld = (tmp_path / "run.fld").read_text()
    assert fld.startswith("# AVS field file\nndim=3\ndim1=8\ndim2=4\ndim3=2\nnspace=3\n"
                          "veclen=10\ndata=float\nfield=uniform\nnstep=3\nlabel = ux uy uz "
                          "phi pressure tau_xy tau_yz tau_zx tau_xx tau_yy\n"
                          'time value = "step0time0"\n'
                          "coord 1 file = run.cod filetype = ascii skip = 0\n"
                          "coord 2 file = run.cod filetype = ascii skip = 2\n"
                          "coord 3 file = run.cod filetype = ascii skip = 4\n")
    if kind == "BINARY":
        assert "variable 2 file = avs/run_2.dat filetype = binary skip = 256\n" in fld
    else:
        assert ("variable 2 file = avs/run_2.dat filetype = ascii skip = 2 offset = 1 "
                "stride = 10\n") in fld
    assert fld.endswith("EOT\n") and fld.count("EOT\n") == 3
    assert (tmp_path / "run.cod").read_text() == "0\n3.5\n0\n1.5\n0\n0.5\n"
    pfld = (tmp_path / "runp.fld").read_text()
    assert pfld.startswith("# AVS field file\nndim=1\ndim1=3\nnspace=3\nveclen=10\n"
                           "data=float\nfield=irregular\nnstep=3\nlabel = Radius x1 x2 x3 "
                           "y1 y2 y3 z1 z2 z3\n")
    if kind == "BINARY":
        assert "coord 1 file = avs/runp_4.cod filetype = binary skip = 24\n" in pfld
        assert (tmp_path / "avs" / "run_2.dat").stat().st_size == 10 * 4 * NX * NY * NZ
    else:
        assert "coord 3 file = avs/runp_4.cod filetype = ascii skip = 0 offset = 0 stride =3\n" \
            in pfld
        assert "variable 10 file = avs/runp_4.dat filetype = ascii skip = 2 offset = 9 " \
            "stride = 10\n" in pfld
        lines = (tmp_path / "avs" / "run_2.dat").read_text().splitlines()
        assert lines[0] == f"timesteps=2 time={2 * DT:f}"
        assert len(lines) == 2 + NX * NY * NZ
    # what AVS reads by following the .fld
    tol = dict(rtol=0, atol=0) if kind == "BINARY" else dict(rtol=6e-3, atol=1e-12)
    head, blocks = read_fld(tmp_path / "run.fld", tmp_path)
    assert sorted(blocks) == [0, 2, 4]
    for s, snap in zip((0, 2, 4), snaps):
        want = w.field_columns(snap)
        for n in range(10):
            got = blocks[s][("variable", n + 1)]
            np.testing.assert_allclose(got, want[n].ravel(order="F"), **tol)   # x fastest
        assert blocks[s][("variable", 4)][1] == pytest.approx(float(snap.get("phi")[1, 0, 0]),
                                                              rel=6e-3)
        tau = snap.get("tau")
        np.testing.assert_allclose(blocks[s][("variable", 6)], tau[1].ravel(order="F")
                                   .astype(np.float32), **tol)                  # tau_xy
        np.testing.assert_allclose(blocks[s][("variable", 8)], tau[2].ravel(order="F")
                                   .astype(np.float32), **tol)                  # tau_zx
    head, pblocks = read_fld(tmp_path / "runp.fld", tmp_path)
    if kind == "BINARY":
        p = snaps[2].particles
        np.testing.assert_array_equal(pblocks[4][("coord", 1)], p.R[:, 0].astype(np.float32))
        np.testing.assert_array_equal(pblocks[4][("coord", 3)], p.R[:, 2].astype(np.float32))
        np.testing.assert_array_equal(pblocks[4][("variable", 1)], [1.0] * 3)
        np.testing.assert_array_equal(pblocks[4][("variable", 2)], [1.0] * 3)   # x1: body x
        np.testing.assert_array_equal(pblocks[4][("variable", 6)], [1.0] * 3)   # y2
        np.testing.assert_array_equal(pblocks[4][("variable", 3)], [0.0] * 3)   # x2


def test_body_axes_of_a_rotated_particle(tmp_path):
    """Blocks x1 x2 x3 hold the body x axis in the lab frame: a quarter turn about z takes
    it to +y."""
    w = avs_writer(tmp_path, n_particles=1)
    snap = with_stress(fake_snapshot(0, 1))
    snap.particles.q[0] = [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]
    cols = w.particle_columns(snap)
    np.testing.assert_allclose(cols[1:4, 0], [0, 1, 0], atol=1e-7)     # x axis -> +y
    np.testing.assert_allclose(cols[4:7, 0], [-1, 0, 0], atol=1e-7)    # y axis -> -x
    np.testing.assert_allclose(cols[7:10, 0], [0, 0, 1], atol=1e-7)


def test_continued_run_keeps_the_earlier_blocks(tmp_path):
    write(tmp_path, steps=(0, 2, 4))
    write(tmp_path, steps=(4, 6), resumed=True, num_snap=3)
    fld = (tmp_path / "run.fld").read_text()
    assert re.findall(r'"step(\d+)time', fld) == ["0", "2", "4", "6"]
    assert "nstep=4\n" in fld
    write(tmp_path, steps=(2,), resumed=True)           # from an earlier restart
    assert re.findall(r'"step(\d+)time', (tmp_path / "runp.fld").read_text()) == ["0", "2"]


@pytest.mark.parametrize("eq", typespec.names(ions=False))     # every type but Electrolyte
def test_every_type_writes_avs(tmp_path, eq):
    """A run of each type: the files, their sizes, the .fld blocks at steps 0, 2, 4; the
    particles where output.udf has them; FDM velocity as in velocity_<n>.h5."""
    from builders import extended_input
    from builders import cli
    from udf import UDFManager
    inp = extended_input(tmp_path, eq, file_type="BINARY")
    assert cli(tmp_path, inp) == 0
    out = tmp_path / "out"
    assert sorted(os.listdir(out)) == ["avs", "traj.cod", "traj.fld", "trajp.fld"]
    head, blocks = read_fld(out / "traj.fld", out)
    assert sorted(blocks) == [0, 2, 4]
    _, pblocks = read_fld(out / "trajp.fld", out)
    rec = UDFManager(str(tmp_path / "output.udf"))
    rec.jump(2)
    R = rec.getArray("Particles[].R")
    for c in range(3):
        np.testing.assert_allclose(pblocks[4][("coord", c + 1)], R[:, c], rtol=1e-6)
    assert all(np.isfinite(blocks[4][("variable", n)]).all() for n in range(1, 11))
    if "FDM" in eq:
        from kapsel.io.fields import read_snapshot
        np.testing.assert_array_equal(
            blocks[4][("variable", 1)],
            read_snapshot(tmp_path / "velocity_2.h5", "UX").astype(np.float32).ravel(order="F"))
