"""``kapsel-py analyze show RUN_DIR``: a picture of a run, one PNG per chosen snapshot.

Left: a z-slice of psi (two-component types) or of |u| (one-component fluids), with the
particles drawn at their positions and sizes (periodic images across the box edges, shifted
by strain x Ly across y for the Lees-Edwards types; solid outline: the particle is cut by the
slice, dashed: it lies off the slice).  Right: the record scalars over time, E and, for the
sheared types, the shear stress of shear_stress.dat, with the snapshot marked.

What is read, and where, is kept in two small functions (``snapshot_files`` for the field
files, ``read_records`` for output.udf) so a change of file names touches only them.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

from udf.files import check_regular, open_regular

# field files of a run directory: kind -> (file pattern, dataset(s))
FIELD_FILES = {
    "psi": (r"orderparam_(\d+)\.h5", ("PSI_ALL", "PSI")),   # the first one the file has
    "u": (r"velocity_(\d+)\.h5", ("UX", "UY", "UZ")),
}
FIGSIZE = (12.0, 5.0)        # inches; at DPI this is the PNG's size in pixels
DPI = 100
CMAPS = {"psi": "RdBu_r", "u": "viridis"}


class ShowError(Exception):
    """A run directory the picture cannot be made from: one line for the user."""


class ShowWriteError(OSError):
    """A picture that cannot be written (``filename``: its path)."""


# ---------------------------------------------------------------------------- reading
def snapshot_files(run_dir: str) -> dict[int, dict]:
    """Field snapshots on disk: n -> {"time": t or None, "psi": path, "u": path} (the kinds
    present).  The FDM files (kapsel.io.fields): orderparam_<n>.h5 (PSI_ALL or PSI),
    velocity_<n>.h5 (UX, UY, UZ),
    the time in the file's ``time`` attribute."""
    import h5py
    found: dict[int, dict] = {}
    try:
        names = sorted(os.listdir(run_dir))
    except OSError as e:
        raise ShowError(f"{run_dir}: {e.strerror}") from None
    for kind, (pattern, _) in FIELD_FILES.items():
        for name in names:
            m = re.fullmatch(pattern, name)
            if not m:
                continue
            path = os.path.join(run_dir, name)
            entry = found.setdefault(int(m.group(1)), {"time": None})
            entry[kind] = path
            if entry["time"] is None:
                try:
                    check_regular(path)
                    with h5py.File(path, "r") as f:
                        t = f.attrs.get("time")
                    entry["time"] = None if t is None else float(t)
                except OSError:
                    pass
    return found


def _unreadable(fields: dict) -> str | None:
    """Why one of the field files {kind: path} cannot be read (None when all can): not a
    regular file (a FIFO, a device), or not an HDF5 file (a torn write)."""
    import h5py
    for path in fields.values():
        try:
            check_regular(path)
            with h5py.File(path, "r"):
                pass
        except OSError as e:
            return f"{path} cannot be read ({e.strerror or str(e).splitlines()[0]})"
    return None


def read_field(path: str, kind: str) -> np.ndarray:
    """psi, or |u|, as a float64 array indexed [x, y, z] (the files are stored z, y, x)."""
    import h5py
    datasets = FIELD_FILES[kind][1]
    check_regular(path)
    with h5py.File(path, "r") as f:
        if kind == "psi":
            datasets = [next((d for d in datasets if d in f), datasets[0])]
        comps = [np.asarray(f[d][()], dtype=np.float64).T for d in datasets]
    if kind == "u":
        return np.sqrt(sum(c * c for c in comps))
    return comps[0]


@dataclass
class Records:
    """What output.udf holds for the picture: the run's type, mesh, radius and the records."""
    type: str
    shape: tuple
    dx: float
    A: float
    t: np.ndarray
    E: np.ndarray
    R: list = field(default_factory=list)      # (n, 3) positions per record
    gts: int = 1                               # output.GTS: snapshot n is step n GTS


def read_records(udf_path: str) -> Records:
    """Type, mesh, DX, A and every record's t, E and Particles[].R from output.udf."""
    import udf
    try:
        u = udf.UDFManager(udf_path)
        kind = u.get("constitutive_eq.type")
        shape = tuple(2 ** int(u.get(f"mesh.{ax}")) for ax in ("NPX", "NPY", "NPZ"))
        dx = float(u.get(f"constitutive_eq.{kind}.DX"))
        A = float(u.get("A")) * dx                # the radius is A DX (as the original)
        gts = int(u.get("output.GTS"))
        t, E, R = [], [], []
        for rec in range(u.totalRecord()):
            u.jump(rec)
            t.append(float(u.get("t")))
            E.append(float(u.get("E")))
            try:
                R.append(np.asarray(u.getArray("Particles[].R"), dtype=float).reshape(-1, 3))
            except udf.UDFError:
                R.append(np.zeros((0, 3)))
    except udf.UDFError as e:
        raise ShowError(str(e)) from None
    return Records(kind, shape, dx, A, np.array(t), np.array(E), R, gts)


def read_table(path: str):
    """A step-t-columns table (shear_stress.dat): (names, array) or None if absent."""
    if not os.path.exists(path):
        return None
    with open_regular(path, "r", encoding="utf-8") as fh:
        header = fh.readline().lstrip("#").split()
        fh.seek(0)
        data = np.loadtxt(fh, comments="#", ndmin=2)
    return header, data


# ---------------------------------------------------------------------------- drawing
def particle_circles(R: np.ndarray, A: float, box: np.ndarray, z: float,
                     le_shift: float = 0.0):
    """Circles (x, y, radius, cut) of the particles and of their periodic images that
    reach into the box: ``cut`` when the sphere crosses the plane z (periodic).
    ``le_shift``: the Lees-Edwards offset (strain x Ly) of the images across y = Ly (+)
    and y = 0 (-)."""
    out = []
    Lx, Ly, Lz = box
    for x, y, zz in np.mod(R, box):
        dz = (zz - z + Lz / 2) % Lz - Lz / 2
        cut = abs(dz) < A
        for sy in (-Ly, 0.0, Ly):
            x0 = (x + np.sign(sy) * le_shift) % Lx
            for sx in (-Lx, 0.0, Lx):
                cx, cy = x0 + sx, y + sy
                if -A < cx < Lx + A and -A < cy < Ly + A:
                    out.append((cx, cy, A, cut))
    return out


def lees_edwards_shift(rec: "Records", index: int, table, box) -> float:
    """strain x Ly of the Lees-Edwards types at the record (shear_stress.dat), else 0."""
    if "Lees_Edwards" not in rec.type and "_LE_" not in rec.type:
        return 0.0
    if table is None or "Shear_strain" not in table[0] or not len(table[1]):
        return 0.0
    names, data = table
    j = int(np.argmin(np.abs(data[:, names.index("step")] - rec.t[index])))
    return float(data[j, names.index("Shear_strain")]) * box[1]


def busiest_slice(R: np.ndarray, A: float, box: np.ndarray, nz: int) -> int:
    """The z mesh index whose plane cuts the most particles (ties: nearest the middle)."""
    if len(R) == 0:
        return nz // 2
    dz_mesh = box[2] / nz
    z = np.arange(nz) * dz_mesh
    d = (np.mod(R[:, 2], box[2])[None, :] - z[:, None] + box[2] / 2) % box[2] - box[2] / 2
    cuts = (np.abs(d) < A).sum(axis=1)
    best = np.flatnonzero(cuts == cuts.max())
    return int(best[np.argmin(np.abs(best - nz // 2))])


@dataclass
class Picture:
    """What ``render`` drew: the file, the slice, and where its pixels are."""
    path: str
    kind: str | None          # "psi", "u" or None (no field file)
    z_index: int
    slice: np.ndarray | None  # [x, y] values drawn
    vmin: float
    vmax: float
    cmap: str
    axes_px: tuple            # (x0, y0, x1, y1) of the slice axes, pixels from bottom-left
    size_px: tuple            # (width, height)


def render(path: str, rec: Records, index: int, fields: dict | None, z_index=None,
           table=None) -> Picture:
    """Draw record ``index`` (its field snapshot ``fields``: {"psi"/"u": path}, or None)
    and the record scalars into the PNG ``path``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    box = np.array(rec.shape, dtype=float) * rec.dx
    nz = rec.shape[2]
    k = busiest_slice(rec.R[index], rec.A, box, nz) if z_index is None else int(z_index) % nz
    z = k * rec.dx
    kind = None
    if fields:
        kind = "psi" if "psi" in fields else "u"
    fig = plt.figure(figsize=FIGSIZE, dpi=DPI)
    # the slice keeps the box's aspect ratio inside a 0.36 x 0.8 panel
    w_in, h_in = 0.36 * FIGSIZE[0], 0.8 * FIGSIZE[1]
    scale = min(w_in / box[0], h_in / box[1])
    w, h = box[0] * scale / FIGSIZE[0], box[1] * scale / FIGSIZE[1]
    ax = fig.add_axes([0.05 + (0.36 - w) / 2, 0.1 + (0.8 - h) / 2, w, h])
    cax = fig.add_axes([0.42, 0.1 + (0.8 - h) / 2, 0.012, h])
    sl, vmin, vmax, cmap = None, 0.0, 1.0, CMAPS.get(kind, "viridis")
    if kind is not None:
        data = read_field(fields[kind], kind)
        if data.shape != tuple(rec.shape):
            raise ShowError(f"{fields[kind]}: a {data.shape} field, but output.udf describes "
                            f"a {tuple(rec.shape)} mesh")
        sl = data[:, :, k]
        vmin, vmax = float(sl.min()), float(sl.max())
        if vmax <= vmin:
            vmax = vmin + 1.0
        im = ax.imshow(sl.T, origin="lower", cmap=cmap, vmin=vmin, vmax=vmax,
                       interpolation="nearest", extent=(0, box[0], 0, box[1]), aspect="auto")
        fig.colorbar(im, cax=cax, label="psi" if kind == "psi" else "|u|")
    else:
        cax.set_axis_off()
        ax.text(0.5, 0.5, "no field file for this snapshot\n(this type writes none)",
                ha="center", va="center", transform=ax.transAxes, color="0.4")
    shift = lees_edwards_shift(rec, index, table, box)
    for cx, cy, r, cut in particle_circles(rec.R[index], rec.A, box, z, shift):
        ax.add_patch(Circle((cx, cy), r, fill=False, lw=1.2, color="k",
                            ls="-" if cut else "--"))
    ax.set_xlim(0, box[0])
    ax.set_ylim(0, box[1])
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    what = {"psi": "psi", "u": "|u|"}.get(kind, "particles")
    ax.set_title(f"{rec.type}: {what} at z = {z:g} (slice {k}), step {rec.t[index]:g}",
                 fontsize=9)

    have_shear = table is not None and "Shear_stress" in table[0]
    ax_e = fig.add_axes([0.55, 0.57 if have_shear else 0.1, 0.42, 0.33 if have_shear else 0.8])
    ax_e.plot(rec.t, rec.E, "-", color="C0")
    ax_e.plot([rec.t[index]], [rec.E[index]], "o", color="C3")
    ax_e.set_ylabel("E")
    ax_e.set_title(f"record {index} of {len(rec.t)}", fontsize=9)
    if have_shear:
        names, data = table
        ts = data[:, names.index("step")]
        s = data[:, names.index("Shear_stress")]
        ax_s = fig.add_axes([0.55, 0.1, 0.42, 0.33], sharex=ax_e)
        ax_s.plot(ts, s, "-", color="C1")
        j = int(np.argmin(np.abs(ts - rec.t[index]))) if len(ts) else None
        if j is not None:
            ax_s.plot([ts[j]], [s[j]], "o", color="C3")
        ax_s.set_ylabel("shear stress")
        ax_s.set_xlabel("step")
        ax_e.tick_params(labelbottom=False)
    else:
        ax_e.set_xlabel("step")
    fig.canvas.draw()
    bb = ax.get_window_extent()
    from .cli import save_figure
    try:
        save_figure(fig, path, dpi=DPI)
    finally:
        plt.close(fig)
    size = (int(round(FIGSIZE[0] * DPI)), int(round(FIGSIZE[1] * DPI)))
    return Picture(path, kind, k, sl, vmin, vmax, cmap, (bb.x0, bb.y0, bb.x1, bb.y1), size)


# ---------------------------------------------------------------------------- command
def match_snapshot(files: dict[int, dict], step: float, gts: int):
    """The field snapshot of a record (its ``t`` is the step, as the original writes it:
    snapshot n = step / GTS), or None."""
    s = int(round(step))
    if gts < 1 or s % gts:
        return None
    n = s // gts
    return n if n in files else None


def choose(spec: str, count: int) -> list[int]:
    if spec == "all":
        return list(range(count))
    try:
        i = int(spec)
    except ValueError:
        raise ShowError(f"--record {spec!r}: give a record index (negative counts from the "
                        f"end) or 'all'") from None
    if not -count <= i < count:
        raise ShowError(f"--record {i}: output.udf has {count} records (0..{count - 1})")
    return [i % count]


def run(a) -> int:
    import sys
    run_dir = a.run_dir
    if not os.path.isdir(run_dir):
        raise ShowError(f"{run_dir}: not a directory")
    udf_path = a.udf or os.path.join(run_dir, "output.udf")
    if not os.path.isfile(udf_path):
        raise ShowError(f"{udf_path}: no such file (give the run's output.udf with --udf)")
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise ShowError("matplotlib is not installed: pip install 'kapsel-py[plot]' "
                        "(make run installs it)") from None
    rec = read_records(udf_path)
    if len(rec.t) == 0:
        raise ShowError(f"{udf_path}: no records yet")
    files = snapshot_files(run_dir)
    table = read_table(os.path.join(run_dir, "shear_stress.dat"))
    out_dir = a.out or run_dir
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as e:
        raise ShowError(f"--out {out_dir}: {e.strerror}") from None
    if not files:
        print(f"kapsel-py analyze show: no field files (orderparam_<n>.h5, velocity_<n>.h5) "
              f"in {run_dir}: the spectral types write fields only with output.AVS; drawing the particles and "
              f"the records only", file=sys.stderr)
    for i in choose(a.record, len(rec.t)):
        n = match_snapshot(files, rec.t[i], rec.gts)
        fields = {k: v for k, v in files[n].items() if k in FIELD_FILES} if n is not None else None
        if files and fields is None:
            print(f"kapsel-py analyze show: record {i} (t = {rec.t[i]:g}) has no field "
                  f"snapshot file; drawing its particles only", file=sys.stderr)
        unreadable = _unreadable(fields or {})
        if unreadable:              # a read problem is not a write failure of the picture
            print(f"kapsel-py analyze show: {unreadable}; drawing record {i}'s particles "
                  f"only", file=sys.stderr)
            fields = None
        name = f"show_{n}.png" if n is not None else f"show_record{i}.png"
        try:
            pic = render(os.path.join(out_dir, name), rec, i, fields, a.z, table)
        except OSError as e:
            raise ShowWriteError(e.errno, e.strerror, os.path.join(out_dir, name)) from None
        print(f"picture of record {i} (t = {rec.t[i]:g}) written to {pic.path}")
    return 0
