"""`kapsel-py analyze show RUN_DIR`: a PNG of a snapshot (a psi or |u| slice with the
particles, and the records over time), checked pixel by pixel against the snapshot's data."""
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from builders import copy_schema, TESTS


matplotlib = pytest.importorskip("matplotlib")
import matplotlib.image  # noqa: E402

from kapsel import cli, models  # noqa: E402,F401
from kapsel.analysis import show  # noqa: E402
from udf import UDFManager  # noqa: E402

HERE = TESTS
SAMPLES = os.path.join(HERE, "..", "samples")
sys.path.insert(0, os.path.join(HERE, "bad_inputs"))
import make_corpus  # noqa: E402

FLAGS = ["-Iinput.udf", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--seed", "3",
         "--quiet"]


def short_run(d, monkeypatch, eq=None, gts=2, nsnap=2):
    """The tiny sample (16^3, 2 particles) for gts * nsnap steps, in d."""
    copy_schema(d)
    (d / "tiny.udf").write_text(make_corpus.tiny_sample())
    u = UDFManager(str(d / "tiny.udf"))
    if eq:
        u.put(eq, "constitutive_eq.type")
    u.put(gts, "output.GTS")
    u.put(nsnap, "output.Num_snap")
    u.write(str(d / "input.udf"))
    monkeypatch.chdir(d)
    assert cli.main(FLAGS) == 0


def pixel(img, pic, i, j, nx, ny):
    """RGB of the centre of mesh cell (i, j) of the slice in the PNG array."""
    x0, y0, x1, y1 = pic.axes_px
    x = x0 + (i + 0.5) / nx * (x1 - x0)
    y = y0 + (j + 0.5) / ny * (y1 - y0)
    return img[int(img.shape[0] - y), int(x), :3]


def test_show_draws_the_last_snapshot_as_its_data(tmp_path, monkeypatch, capsys):
    short_run(tmp_path, monkeypatch)
    assert cli.main(["analyze", "show", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    png = tmp_path / "show_2.png"            # snapshot 2 = the last record, t = step 4
    assert png.exists() and str(png) in out
    img = matplotlib.image.imread(str(png))
    assert img.shape[:2] == (500, 1200)      # FIGSIZE x DPI

    # the same drawing through the function, which says where the slice's pixels are
    rec = show.read_records(str(tmp_path / "output.udf"))
    files = show.snapshot_files(str(tmp_path))
    assert set(files) == {0, 1, 2} and rec.t[-1] == 2 * rec.gts    # record t is the step
    assert show.match_snapshot(files, rec.t[-1], rec.gts) == 2
    pic = show.render(str(tmp_path / "again.png"), rec, 2, {"psi": files[2]["psi"]})
    assert (matplotlib.image.imread(str(tmp_path / "again.png")) == img).all()

    psi = show.read_field(files[2]["psi"], "psi")
    assert pic.kind == "psi" and np.array_equal(pic.slice, psi[:, :, pic.z_index])
    nx, ny = psi.shape[:2]
    box = np.array(rec.shape, float) * rec.dx
    circles = show.particle_circles(rec.R[2], rec.A, box, pic.z_index * rec.dx)
    cmap = matplotlib.colormaps[pic.cmap]
    norm = matplotlib.colors.Normalize(pic.vmin, pic.vmax)

    def clear(i, j):     # cell centre away from every particle outline
        c = (np.array([i, j]) + 0.5) * rec.dx
        return all(abs(np.hypot(*(c - (cx, cy))) - r) > 1.5 * rec.dx for cx, cy, r, _ in circles)

    cells = [(i, j) for i in range(nx) for j in range(ny) if clear(i, j)]
    sl = pic.slice
    picks = sorted(cells, key=lambda c: sl[c])
    picks = [picks[0], picks[-1], picks[len(picks) // 3], picks[2 * len(picks) // 3]]
    for i, j in picks:
        want = np.array(cmap(norm(sl[i, j]))[:3])
        assert np.abs(pixel(img, pic, i, j, nx, ny) - want).max() < 3 / 255, (i, j)
    # and the test can tell x from y: a cell whose transposed value has another colour
    i, j = max(((i, j) for i, j in cells if clear(j, i)), key=lambda c: abs(sl[c] - sl[c[::-1]]))
    assert np.abs(pixel(img, pic, i, j, nx, ny)
                  - np.array(cmap(norm(sl[j, i]))[:3])).max() > 10 / 255


def test_show_record_options_and_errors(tmp_path, monkeypatch, capsys):
    """On a one-component fluid (|u| is drawn)."""
    short_run(tmp_path, monkeypatch, eq="Navier_Stokes_FDM", gts=1, nsnap=1)
    rec = show.read_records(str(tmp_path / "output.udf"))
    files = show.snapshot_files(str(tmp_path))
    assert "psi" not in files[1]
    pic = show.render(str(tmp_path / "u.png"), rec, 1, {"u": files[1]["u"]}, z_index=5)
    with h5py.File(files[1]["u"]) as f:
        speed = np.sqrt(sum(np.asarray(f[c]) ** 2 for c in ("UX", "UY", "UZ"))).T
    assert pic.kind == "u" and pic.z_index == 5 and np.allclose(pic.slice, speed[:, :, 5])
    assert cli.main(["analyze", "show", str(tmp_path), "--record", "all",
                     "--out", str(tmp_path / "pics")]) == 0
    assert sorted(os.listdir(tmp_path / "pics")) == ["show_0.png", "show_1.png"]
    assert cli.main(["analyze", "show", str(tmp_path), "--record", "0", "--z", "3"]) == 0
    capsys.readouterr()
    assert cli.main(["analyze", "show", str(tmp_path), "--record", "5"]) == 2
    assert "output.udf has 2 records" in capsys.readouterr().err
    assert cli.main(["analyze", "show", str(tmp_path / "nothere")]) == 2
    assert "not a directory" in capsys.readouterr().err
    # the console command: the last snapshot by default
    r = subprocess.run([sys.executable, "-m", "kapsel.cli", "analyze", "show", str(tmp_path),
                        "--out", str(tmp_path / "cli")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert os.listdir(tmp_path / "cli") == ["show_1.png"] and "show_1.png" in r.stdout


def test_show_spectral_shear_run_says_it_has_no_fields(tmp_path, monkeypatch, capsys):
    """Spectral types write no field files (yet): particles and records, with the shear
    stress of shear_stress.dat, and a message saying so."""
    short_run(tmp_path, monkeypatch, eq="Shear_Navier_Stokes_Lees_Edwards", gts=1, nsnap=2)
    assert cli.main(["analyze", "show", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert "no field files" in err and "spectral types write fields only with output.AVS" in err
    png = tmp_path / "show_record2.png"
    assert png.exists() and matplotlib.image.imread(str(png)).shape[:2] == (500, 1200)


def test_show_without_matplotlib_names_the_extra(tmp_path, monkeypatch, capsys):
    (tmp_path / "output.udf").write_text("")
    monkeypatch.setitem(sys.modules, "matplotlib", None)     # import matplotlib fails
    assert cli.main(["analyze", "show", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "matplotlib is not installed" in err and "kapsel-py[plot]" in err


def test_periodic_and_lees_edwards_images():
    box = np.array([16.0, 16.0, 16.0])
    R = np.array([[1.0, 1.0, 8.0]])        # near the x = 0 and y = 0 edges, cut by z = 8
    plain = {(cx, cy) for cx, cy, r, cut in show.particle_circles(R, 2.0, box, 8.0)}
    assert plain == {(1, 1), (17, 1), (1, 17), (17, 17)}
    sheared = show.particle_circles(R, 2.0, box, 8.0, le_shift=4.0)
    assert {(cx, cy) for cx, cy, *_ in sheared} == {(1, 1), (17, 1), (5, 17)}
    assert all(cut for *_, cut in sheared)
    assert not any(cut for *_, cut in show.particle_circles(R, 2.0, box, 12.0))


def test_show_with_an_unreadable_field_file_draws_the_particles(tmp_path, monkeypatch, capsys):
    """A field file that cannot be read (a FIFO in its place, or torn) is said as a read
    problem and the record drawn with its particles only, not reported as a failed write of
    the picture (re-audit 2026-12-04)."""
    short_run(tmp_path, monkeypatch)
    last = sorted(tmp_path.glob("orderparam_2.h5")) or sorted(tmp_path.glob("*_2.h5"))
    assert last
    last[0].unlink()
    os.mkfifo(last[0])
    assert cli.main(["analyze", "show", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert f"{last[0]} cannot be read" in err and "particles only" in err
    assert "cannot write" not in err
    assert (tmp_path / "show_2.png").exists()
