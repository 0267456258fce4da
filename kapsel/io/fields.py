"""Field snapshots: one HDF5 file per snapshot and field, plus an XDMF 2.0 time series.

Layout (shared/FORMAT.md, "Field snapshots"):

* ``orderparam_<n>.h5`` holds the single dataset ``PSI``, ``particle_<n>.h5`` the single
  dataset ``PHI``, ``velocity_<n>.h5`` the datasets ``UX``, ``UY``, ``UZ``.  Every dataset is
  float64 with shape (NZ, NY, NX): x varies fastest.  The file root carries the attributes
  ``n``, ``time`` and ``dx`` (attributes, not datasets: readers that take "the first dataset"
  still get the field), so a continued run can rebuild the series from the files alone.
* ``orderparam.xmf``, ``particle.xmf``, ``velocity.xmf``: XDMF 2.0, a temporal collection of
  uniform grids, each a ``3DCORECTMesh`` topology (point dimensions NZ NY NX) with
  ``ORIGIN_DXDYDZ`` geometry (origin 0, spacing DX; both given in z, y, x order) and attributes
  pointing at ``<file>.h5:/<DATASET>`` by relative name.  The velocity is one vector attribute
  ``U`` assembled by a ``JOIN($0, $1, $2)`` function data item over UX, UY, UZ.

Internally a scalar field is a float64 array indexed [x, y, z] with shape (NX, NY, NZ) and a
vector field has shape (3, NX, NY, NZ).

Every file is written under a temporary name in the output directory and then moved into
place with :func:`os.replace`, so a reader (or a run killed mid-write) never sees a partial
file.  The ``.xmf`` files are rewritten after the snapshot's ``.h5`` files are in place.
"""
from __future__ import annotations

import os
import re
import secrets
import xml.etree.ElementTree as ET
from xml.sax.saxutils import escape

import h5py
import numpy as np

__all__ = ["FieldWriter", "read_snapshot", "FIELDS"]

# field keyword -> (file prefix, dataset names, XDMF attribute name)
FIELDS = {
    "psi": ("orderparam", ("PSI",), "PSI"),
    "phi": ("particle", ("PHI",), "PHI"),
    "u": ("velocity", ("UX", "UY", "UZ"), "U"),
}
# the file prefixes are accepted as field names too
ALIASES = {prefix: key for key, (prefix, _, _) in FIELDS.items()}


def _field_key(name: str) -> str:
    key = ALIASES.get(name, name)
    if key not in FIELDS:
        raise ValueError(f"unknown field {name!r}; known: {sorted(FIELDS)} or {sorted(ALIASES)}")
    return key


def _fmt(x) -> str:
    """Shortest round-tripping text for a float (integers without a trailing '.0')."""
    x = float(x)
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _atomic_write(path: str, write) -> None:
    """Call ``write(tmp_path)`` on a temporary file next to ``path``, then rename it to ``path``."""
    directory, name = os.path.split(path)
    while True:
        tmp = os.path.join(directory, f".{name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
        try:  # created with the usual 0666 & ~umask mode (mkstemp would give 0600)
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _atomic_write_text(path: str, text: str) -> None:
    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
    _atomic_write(path, write)


def read_snapshot(path, dataset: str | None = None) -> np.ndarray:
    """Read one dataset of a snapshot file as a float64 array indexed [x, y, z].

    ``dataset`` defaults to the file's first dataset (``PSI``, ``PHI`` or ``UX``).  For a
    velocity file ``dataset="U"`` gives the vector (3, NX, NY, NZ) from UX, UY, UZ.
    """
    with h5py.File(path, "r") as f:
        if dataset == "U" and "U" not in f:
            return np.stack([np.asarray(f[c][()], dtype=np.float64).T
                             for c in ("UX", "UY", "UZ")])
        if dataset is None:
            names = [k for k in f.keys() if isinstance(f[k], h5py.Dataset)]
            if not names:
                raise ValueError(f"{path}: no dataset")
            dataset = names[0]
        data = f[dataset][()]
    return np.ascontiguousarray(np.asarray(data, dtype=np.float64).T)


class FieldWriter:
    """Write field snapshots and keep the per-field XDMF time series up to date.

    ``FieldWriter(directory, shape, dx, fields=("psi", "phi", "u"))`` starts a new series
    (``fields`` may also use the file prefixes ``orderparam``, ``particle``, ``velocity``);
    files of an earlier run are not listed (those with the same snapshot numbers are
    overwritten as the run goes).  With ``resume=True`` (or :meth:`existing`) the snapshots
    already on disk for ``fields`` are listed first, so a continued run appends to them; a
    snapshot written with number n then drops resumed entries with a number above n from the
    series (they belong to the run being replaced).

    ``write(n, time, psi=None, phi=None, u=None)`` writes snapshot n of each field given
    (None: not written).  ``snapshots[key]`` is {n: time} of each field ("psi", "phi", "u").
    """

    def __init__(self, directory, shape, dx, fields=("psi", "phi", "u"), resume: bool = False):
        self.directory = os.fspath(directory)
        shape = tuple(int(s) for s in shape)
        if len(shape) != 3 or min(shape) < 1:
            raise ValueError(f"shape must be (NX, NY, NZ) of positive sizes, got {shape}")
        self.shape = shape
        self.dx = float(dx)
        if not self.dx > 0:
            raise ValueError(f"dx must be positive, got {dx}")
        self.fields = tuple(dict.fromkeys(_field_key(f) for f in fields))
        self.snapshots: dict[str, dict[int, float]] = {f: {} for f in FIELDS}
        self._resumed: dict[str, set[int]] = {f: set() for f in FIELDS}
        os.makedirs(self.directory, exist_ok=True)
        if resume:
            self.resume()

    @classmethod
    def existing(cls, directory, shape=None, dx=None, fields=("psi", "phi", "u")):
        """A writer that appends to the snapshots already in ``directory``.

        ``shape`` and ``dx`` default to those stored in the existing files.
        """
        directory = os.fspath(directory)
        if shape is None or dx is None:
            for field in fields:
                field = _field_key(field)
                found = _scan(directory, field)
                if found:
                    n = max(found)
                    if shape is None:
                        shape = found[n][1]
                    if dx is None:
                        dx = _stored_dx(directory, field, n)
                    break
        if shape is None:
            raise ValueError(f"{directory}: no snapshot on disk, shape must be given")
        if dx is None:
            raise ValueError(f"{directory}: grid spacing not found on disk, dx must be given")
        return cls(directory, shape, dx, fields=fields, resume=True)

    def resume(self, upto: int | None = None) -> dict:
        """List the snapshots on disk of ``self.fields`` (n <= ``upto`` if given).

        Returns ``self.snapshots``.  The .xmf files are rewritten at the next ``write``.
        """
        for field in self.fields:
            found = _scan(self.directory, field)
            series = {}
            for n, (time, shp) in found.items():
                if upto is not None and n > upto:
                    continue
                if shp != self.shape:
                    raise ValueError(
                        f"{_h5_name(field, n)}: grid {shp} differs from {self.shape}")
                series[n] = time
            self.snapshots[field] = dict(sorted(series.items()))
            self._resumed[field] = set(series)
        return self.snapshots

    # -- writing -----------------------------------------------------------------------
    def write(self, n, time, psi=None, phi=None, u=None) -> None:
        """Write snapshot ``n`` (at ``time``) of every field given, then the XDMF files."""
        n = int(n)
        if n < 0:
            raise ValueError(f"snapshot number must be >= 0, got {n}")
        time = float(time)
        given = {k: v for k, v in (("psi", psi), ("phi", phi), ("u", u)) if v is not None}
        arrays = {}
        for field, value in given.items():
            a = np.asarray(value, dtype=np.float64)
            want = (3,) + self.shape if field == "u" else self.shape
            if a.shape != want:
                raise ValueError(f"{field}: shape {a.shape}, expected {want}")
            arrays[field] = a
        for field, a in arrays.items():
            _prefix, datasets, _attr = FIELDS[field]
            comps = [a] if len(datasets) == 1 else [a[i] for i in range(3)]

            def h5write(tmp, comps=comps, datasets=datasets):
                with h5py.File(tmp, "w") as f:
                    for name, c in zip(datasets, comps):
                        f.create_dataset(name, data=np.ascontiguousarray(c.T))
                    f.attrs["n"] = n
                    f.attrs["time"] = time
                    f.attrs["dx"] = self.dx

            _atomic_write(os.path.join(self.directory, _h5_name(field, n)), h5write)
        for field in arrays:
            series = self.snapshots[field]
            for m in [m for m in self._resumed[field] if m > n]:
                series.pop(m, None)
                self._resumed[field].discard(m)
            self._resumed[field].discard(n)
            series[n] = time
            _atomic_write_text(self.xmf_path(field), self.xdmf(field))

    # -- XDMF --------------------------------------------------------------------------
    def xmf_path(self, field: str) -> str:
        return os.path.join(self.directory, FIELDS[_field_key(field)][0] + ".xmf")

    def xdmf(self, field: str) -> str:
        """The XDMF 2.0 text of ``field``'s temporal collection."""
        field = _field_key(field)
        prefix, datasets, attr = FIELDS[field]
        nx, ny, nz = self.shape
        dims = f"{nz} {ny} {nx}"
        d = _fmt(self.dx)
        out = [
            '<?xml version="1.0" ?>',
            '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>',
            '<Xdmf Version="2.0">',
            ' <Domain>',
            f'  <Grid Name="{prefix}" GridType="Collection" CollectionType="Temporal">',
        ]
        for n, time in sorted(self.snapshots[field].items()):
            h5 = escape(_h5_name(field, n))
            out += [
                f'   <Grid Name="{prefix}_{n}" GridType="Uniform">',
                f'    <Time Value="{_fmt(time)}"/>',
                f'    <Topology TopologyType="3DCORECTMesh" Dimensions="{dims}"/>',
                '    <Geometry GeometryType="ORIGIN_DXDYDZ">',
                '     <DataItem Name="Origin" Format="XML" NumberType="Float" Precision="8"'
                ' Dimensions="3">0 0 0</DataItem>',
                '     <DataItem Name="Spacing" Format="XML" NumberType="Float" Precision="8"'
                f' Dimensions="3">{d} {d} {d}</DataItem>',
                '    </Geometry>',
            ]
            if len(datasets) == 1:
                out += [
                    f'    <Attribute Name="{attr}" AttributeType="Scalar" Center="Node">',
                    f'     <DataItem Format="HDF" NumberType="Float" Precision="8"'
                    f' Dimensions="{dims}">{h5}:/{datasets[0]}</DataItem>',
                    '    </Attribute>',
                ]
            else:
                out += [
                    f'    <Attribute Name="{attr}" AttributeType="Vector" Center="Node">',
                    f'     <DataItem ItemType="Function" Function="JOIN($0, $1, $2)"'
                    f' Dimensions="{dims} 3">',
                ]
                out += [
                    f'      <DataItem Format="HDF" NumberType="Float" Precision="8"'
                    f' Dimensions="{dims}">{h5}:/{ds}</DataItem>'
                    for ds in datasets
                ]
                out += ['     </DataItem>', '    </Attribute>']
            out.append('   </Grid>')
        out += ['  </Grid>', ' </Domain>', '</Xdmf>', '']
        return "\n".join(out)


# -- reading back what is on disk ---------------------------------------------------------
def _h5_name(field: str, n: int) -> str:
    return f"{FIELDS[field][0]}_{n}.h5"


def _xmf_times(directory: str, field: str) -> dict[int, float]:
    """Snapshot number -> time from an existing .xmf (fallback for files without attrs)."""
    prefix = FIELDS[field][0]
    path = os.path.join(directory, prefix + ".xmf")
    times: dict[int, float] = {}
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return times
    pat = re.compile(rf"^{re.escape(prefix)}_(\d+)\.h5:")
    for grid in root.iter("Grid"):
        t = grid.find("Time")
        item = grid.find(".//Attribute//DataItem[@Format='HDF']")
        if t is None or item is None or item.text is None:
            continue
        m = pat.match(item.text.strip())
        if m:
            try:
                times[int(m.group(1))] = float(t.get("Value"))
            except (TypeError, ValueError):
                pass
    return times


def _scan(directory: str, field: str) -> dict[int, tuple[float, tuple[int, int, int]]]:
    """Complete snapshot files of ``field`` in ``directory``: n -> (time, (NX, NY, NZ)).

    The time is the file's ``time`` attribute, else the one the .xmf lists, else n.
    """
    prefix, datasets, _attr = FIELDS[field]
    pat = re.compile(rf"^{re.escape(prefix)}_(\d+)\.h5$")
    try:
        names = os.listdir(directory)
    except OSError:
        return {}
    xmf_times = None
    found = {}
    for name in names:
        m = pat.match(name)
        if not m:
            continue
        n = int(m.group(1))
        try:
            with h5py.File(os.path.join(directory, name), "r") as f:
                if not all(ds in f for ds in datasets):
                    continue
                shapes = {f[ds].shape for ds in datasets}
                if len(shapes) != 1 or len(next(iter(shapes))) != 3:
                    continue
                nz, ny, nx = shapes.pop()
                time = f.attrs.get("time")
        except OSError:
            continue
        if time is None:
            if xmf_times is None:
                xmf_times = _xmf_times(directory, field)
            time = xmf_times.get(n, float(n))
        found[n] = (float(time), (nx, ny, nz))
    return found


def _stored_dx(directory: str, field: str, n: int):
    try:
        with h5py.File(os.path.join(directory, _h5_name(field, n)), "r") as f:
            dx = f.attrs.get("dx")
    except OSError:
        dx = None
    if dx is not None:
        return float(dx)
    try:
        root = ET.parse(os.path.join(directory, FIELDS[field][0] + ".xmf")).getroot()
        item = root.find(".//Geometry/DataItem[@Name='Spacing']")
        return float(item.text.split()[0])
    except (OSError, ET.ParseError, AttributeError, ValueError, IndexError):
        return None
