"""The finite-difference types' per-snapshot HDF5 files and their XDMF series, under the
original's names (FORMAT-OUTPUT.md §4), written every snapshot whatever output.AVS says.

Snapshot n = step / GTS (absolute: it keeps counting across a continued run):

    file                   written for                              datasets
    orderparam_<n>.h5      Navier_Stokes_Cahn_Hilliard_FDM          PSI_ALL
                           Shear_NS_LE_CH_FDM                       PSI (rectangular frame)
    flux_<n>.h5            Navier_Stokes_Cahn_Hilliard_FDM          FLUX_X FLUX_Y FLUX_Z
    particle_<n>.h5        the four FDM types, with particles       PHI
    particle_data_<n>.h5   the four FDM types, with particles       RX RY RZ VX VY VZ DEGREE_OBLIQUE
    velocity_<n>.h5        the four FDM types                       UX UY UZ

Field datasets are float64-LE of shape (NZ, NY, NX) (x fastest); ``particle_data`` holds
rank-1 float64-LE arrays of the N wrapped positions and velocities and DEGREE_OBLIQUE of
shape (1,) (with one particle the original writes each array with shape (2,), the particle
then a dummy -1.0: so do we).  Besides the datasets each file carries the root attributes
``n``, ``time`` and ``dx`` (readers that list the datasets do not see them), from which a
continued run rebuilds the series.

The .xmf files (XDMF 2.0, the original's layout: a temporal collection ``CellTime`` of
uniform grids all named ``Structured grid``, ``3DCORECTMesh`` + ``ORIGIN_DXDYDZ``, attributes
named after the file):

    fluid_phase.xmf          orderparam_<n>.h5:/PSI_ALL (or /PSI)   scalar  fluid_phase
    particle_phase.xmf       particle_<n>.h5:/PHI                   scalar  particle_phase
    particle_coordinate.xmf  Polyvertex at xdmf_<n>.h5:/particle_position, vector
                             particle_velocity (xdmf_<n>.h5:/particle_velocity)
    velocity_field.xmf       xdmf_<n>.h5:/velocity_field            vector  velocity_field
    flux_field.xmf           xdmf_<n>.h5:/flux_field                vector  flux_field

``xdmf_<n>.h5`` holds no field data: its vectors are HDF5 virtual datasets, (NZ, NY, NX, 3)
or (M, 3), whose components are the snapshot files' UX UY UZ, FLUX_X FLUX_Y FLUX_Z, RX RY RZ
and VX VY VZ (same directory, named without a path), and ``particle_vertex`` (int32 0 .. N-1)
is the Polyvertex connectivity.  Both of ParaView's readers read that text: the legacy
``XDMFReader`` (Xdmf2) and ``Xdmf3ReaderS`` / ``Xdmf3ReaderT``, which need ``Dimensions``
(not ``NumberOfElements``) on a structured topology (XdmfItemFactory.cpp, createItem), a
``Center`` on every attribute (XdmfAttributeCenter.cpp: it aborts without one), a
connectivity for Polyvertex cells, and plain HDF items wherever VTK takes the data: a
``Function`` (``JOIN``) or ``X_Y_Z`` item has no number type until read, and VTK's
vtkXdmf3DataSet.cxx (XdmfToVTKArray) asks for it first and drops the array ("Skipping
unrecognized array type [None]"); Xdmf3's JOIN also concatenates where Xdmf2's interlaces.

Differences from the original, on purpose (docs/output.md):
* the original writes every .xmf once, in advance, listing snapshots up to the end of the run
  whether their files exist yet or not, and a continued run's .xmf lists only the new
  snapshots; here each .xmf is rewritten (atomically) after each snapshot's files are in
  place and lists every snapshot on disk of this time line, the earlier run's included;
* ``flux_field.xmf`` is written only when flux files are (the original writes it for all four
  types, pointing at files that never exist);
* times are printed in full (shortest round-trip) precision, not 6 digits;
* the vectors and the particle positions are read from ``xdmf_<n>.h5`` instead of
  ``Function="JOIN($0, $1, $2)"`` items, structured topologies say ``Dimensions`` and every
  attribute a ``Center``: the original's text gives empty grids in the Xdmf3 readers and
  aborts them on particle_coordinate.xmf.

Every file goes to the directory of output.udf (the original: the working directory).
"""
from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET

import h5py
import numpy as np

from .atomic import atomic_write, atomic_write_text, fmt
from .h5file import write_h5

__all__ = ["SnapshotFiles", "series_for", "read_snapshot", "XMF_NAMES"]

XMF_NAMES = ("fluid_phase.xmf", "particle_phase.xmf", "particle_coordinate.xmf",
             "velocity_field.xmf", "flux_field.xmf")
F64 = "<f8"
SIDECAR = "xdmf"            # xdmf_<n>.h5: what the .xmf files read besides the snapshot files
# HDF5 1.10 is the oldest library that reads virtual datasets (ParaView >= 5.5 has it)
SIDECAR_LIBVER = ("earliest", "v110")


class _Series:
    """One .xmf: its name, the .h5 prefix and how its attribute is built."""

    def __init__(self, name, prefix, kind, datasets):
        self.name, self.prefix, self.kind, self.datasets = name, prefix, kind, datasets


def series_for(cfg_type: str, n_particles: int) -> list:
    """The files the original writes for a type (empty for the spectral types)."""
    from ..typespec import spec
    ts = spec(cfg_type)
    if not ts.fdm:
        return []
    out = []
    if ts.psi_file is not None:          # PSI_ALL (psi with the particles' psi_0_p) or PSI
        out.append(_Series("fluid_phase", "orderparam", "scalar",
                           ((ts.psi_file, ts.psi_file.lower(), None),)))
    if n_particles:
        out.append(_Series("particle_phase", "particle", "scalar", (("PHI", "phi", None),)))
        out.append(_Series("particle_coordinate", "particle_data", "particles", ()))
    out.append(_Series("velocity_field", "velocity", "vector",
                       tuple((f"U{c}", "u", i) for i, c in enumerate("XYZ"))))
    if ts.flux_file:
        out.append(_Series("flux_field", "flux", "vector",
                           tuple((f"FLUX_{c}", "flux", i) for i, c in enumerate("XYZ"))))
    return out


class SnapshotFiles:
    """Writer (kapsel.io.writers protocol) of the per-snapshot files and .xmf series."""

    def __init__(self, directory, cfg_type, shape, dx, gts, n_particles):
        self.directory = os.fspath(directory)
        self.shape = tuple(int(s) for s in shape)
        self.dx = float(dx)
        self.gts = int(gts)
        self.n_particles = int(n_particles)
        self.series = series_for(cfg_type, n_particles)
        self.times: dict[int, float] = {}       # snapshot number -> time, in the .xmf files
        self._skip = None

    def needs(self) -> set:
        """Snapshot names this writer reads (kapsel.snapshot)."""
        return {ds[1] for s in self.series for ds in s.datasets}

    def files(self, resumed: bool) -> list[tuple[str, str]]:
        out = [(self.directory, f"{s.prefix}_<n>.h5 + {s.name}.xmf") for s in self.series]
        if self.series:
            out.append((self.directory, f"{SIDECAR}_<n>.h5 (the .xmf files' vectors)"))
        return out

    # ------------------------------------------------------------------ protocol
    def open(self, snap, resumed: bool) -> None:
        os.makedirs(self.directory, exist_ok=True)
        self.times = {}
        if not resumed:
            return
        n0 = snap.step // self.gts
        old = _xmf_times(os.path.join(self.directory, "velocity_field.xmf"))
        for n in range(n0 + 1):
            if all(os.path.exists(self.path(s, n)) for s in self.series):
                self.times[n] = _stored_time(self.path(self.series[-1], n),
                                             old.get(n, n * self.gts * snap.dt))
                if not os.path.exists(self.sidecar_path(n)):   # e.g. the original's files
                    self._write_sidecar(n)
        if snap.step % self.gts == 0 and n0 in self.times:
            self._skip = snap.step                  # written by the run being continued

    def write(self, snap) -> None:
        if snap.step == self._skip:
            self._skip = None
            return
        n = snap.step // self.gts
        for s in self.series:
            self._h5(self.path(s, n), s, snap, n)
        self._write_sidecar(n)
        self.times = {m: t for m, t in self.times.items() if m < n}   # a replaced time line
        self.times[n] = float(snap.time)
        for s in self.series:
            atomic_write_text(os.path.join(self.directory, s.name + ".xmf"), self.xdmf(s))

    def close(self, reason: str) -> None:
        """Nothing is buffered: every file is complete once written."""

    # ------------------------------------------------------------------ files
    def path(self, s, n) -> str:
        return os.path.join(self.directory, f"{s.prefix}_{n}.h5")

    def sidecar_path(self, n) -> str:
        return os.path.join(self.directory, f"{SIDECAR}_{n}.h5")

    def _write_sidecar(self, n):
        """xdmf_<n>.h5: virtual (interlaced) views of snapshot n's vector components, which
        both XDMF readers read as one plain HDF item, and the Polyvertex connectivity."""
        def write(f):
            for s in self.series:
                if s.kind == "vector":
                    interlaced(f, s.name, f"{s.prefix}_{n}.h5",
                               [name for name, _src, _c in s.datasets], self.shape[::-1])
                elif s.kind == "particles":
                    m = 2 if self.n_particles == 1 else self.n_particles
                    f.create_dataset("particle_vertex",
                                     data=np.arange(self.n_particles, dtype=np.int32))
                    src = f"{s.prefix}_{n}.h5"
                    interlaced(f, "particle_position", src, ["RX", "RY", "RZ"], (m,))
                    interlaced(f, "particle_velocity", src, ["VX", "VY", "VZ"], (m,))
        write_h5(self.sidecar_path(n), write, libver=SIDECAR_LIBVER)

    def _h5(self, path, s, snap, n):
        """One snapshot file, atomically (kapsel.io.h5file.write_h5: a full disk is an
        OSError naming it)."""
        attrs = {"n": n, "time": float(snap.time), "dx": self.dx}
        if s.kind != "particles" and snap.h5_fields is not None:
            # parallel HDF5: every rank writes its block
            atomic_write(path, lambda tmp: snap.h5_fields(tmp, list(s.datasets), attrs))
            return

        def fill(f):
            if s.kind == "particles":
                p = snap.particles
                cols = {"RX": p.R[:, 0], "RY": p.R[:, 1], "RZ": p.R[:, 2],
                        "VX": p.v[:, 0], "VY": p.v[:, 1], "VZ": p.v[:, 2]}
                for name, c in cols.items():
                    if p.n == 1:      # the original's single-particle layout
                        c = np.array([c[0], -1.0])
                    f.create_dataset(name, data=np.asarray(c, dtype=F64))
                f.create_dataset("DEGREE_OBLIQUE", data=np.array([snap.strain], dtype=F64))
            else:
                for name, source, comp in s.datasets:
                    a = snap.get(source)
                    a = a if comp is None else a[comp]
                    if a.shape != self.shape:
                        raise ValueError(f"{source}: shape {a.shape}, expected {self.shape}")
                    f.create_dataset(name, data=np.ascontiguousarray(a.T, dtype=F64))
            for key, value in attrs.items():
                f.attrs[key] = value
        write_h5(path, fill)

    # ------------------------------------------------------------------ XDMF
    def xdmf(self, s) -> str:
        """The text of one .xmf (FORMAT-OUTPUT.md §4.2, with the changes of the module
        docstring)."""
        nx, ny, nz = self.shape
        dims = f"{nz} {ny} {nx}"
        d = fmt(self.dx)
        out = ['<?xml version="1.0" ?>', '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>',
               '<Xdmf Version="2.0">', '<Domain>',
               '<Grid Name="CellTime" GridType="Collection" CollectionType="Temporal">', '']
        npart = self.n_particles
        m = 2 if npart == 1 else npart

        def item(dimensions, ref, number="Float", precision=8):
            return [f'<DataItem Dimensions="{dimensions}" NumberType="{number}" '
                    f'Precision="{precision}" Format="HDF">', ref, '</DataItem>']

        for n, t in sorted(self.times.items()):
            h5 = f"{s.prefix}_{n}.h5"
            side = f"{SIDECAR}_{n}.h5"
            out += ['<Grid Name="Structured grid" GridType="Uniform">', f'<Time Value="{fmt(t)}" />']
            if s.kind == "particles":
                out.append(f'<Topology Name="tp" TopologyType="Polyvertex" '
                           f'NumberOfElements="{npart}">')
                out += item(npart, f"{side}:/particle_vertex", "Int", 4)
                out += ['</Topology>', '<Geometry GeometryType="XYZ">']
                out += item(f"{m} 3", f"{side}:/particle_position")
                out += ['</Geometry>', '<Attribute Name = "particle_velocity" '
                        'AttributeType = "Vector" Center = "Node">']
                out += item(f"{m} 3", f"{side}:/particle_velocity")
                out += ['</Attribute>', '</Grid>', '']
                continue
            out += [f'<Topology Name="tp" TopologyType="3DCORECTMesh" Dimensions="{dims}"/>',
                    '<Geometry Name="geo" GeometryType="ORIGIN_DXDYDZ">',
                    '<DataItem Name="Origin" Dimensions="3" NumberType="Float" Precision="4" '
                    'Format="XML">', '0 0 0', '</DataItem>',
                    '<DataItem Name="Spacing" Dimensions="3" NumberType="Float" Precision="4" '
                    'Format="XML">', f'{d} {d} {d}', '</DataItem>', '</Geometry>']
            if s.kind == "scalar":
                out.append(f'<Attribute Name = "{s.name}" AttributeType = "Scalar" Center = "Node">')
                out += item(dims, f"{h5}:/{s.datasets[0][0]}")
            else:
                out.append(f'<Attribute Name = "{s.name}" AttributeType = "Vector" Center = "Node">')
                out += item(f"{dims} 3", f"{side}:/{s.name}")
            out += ['</Attribute>', '</Grid>', '']
        out += ['</Grid>', '</Domain>', '</Xdmf>', '']
        return "\n".join(out)


def interlaced(f, name, source, components, shape, dtype=F64):
    """Virtual dataset ``name`` of shape ``shape + (3,)`` in h5py file ``f`` whose [..., c] is
    dataset ``components[c]`` (of ``shape`` and ``dtype``) of file ``source``.  The source is
    named without a directory: HDF5 looks for it next to the file holding the view.  Made
    with the low-level API to leave out the object's times (h5py's create_virtual_dataset
    records them), so the same views give the same bytes (a continued run's files equal an
    uninterrupted run's)."""
    shape = tuple(int(n) for n in shape)
    full = shape + (len(components),)
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_obj_track_times(False)
    space = h5py.h5s.create_simple(full)
    src = h5py.h5s.create_simple(shape)
    for c, comp in enumerate(components):
        view = space.copy()
        view.select_hyperslab((0,) * len(shape) + (c,), shape + (1,))
        dcpl.set_virtual(view, source.encode(), comp.encode(), src)
    lcpl = h5py.h5p.create(h5py.h5p.LINK_CREATE)
    lcpl.set_create_intermediate_group(True)
    h5py.h5d.create(f.id, name.encode(), h5py.h5t.py_create(np.dtype(dtype)), space,
                    dcpl=dcpl, lcpl=lcpl).close()


# -- reading back ---------------------------------------------------------------------------
def _xmf_times(path: str) -> dict[int, float]:
    """Snapshot number -> time listed in an existing .xmf ({} if none)."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return {}
    times = {}
    for grid in root.iter("Grid"):
        t = grid.find("Time")
        item = grid.find(".//DataItem[@Format='HDF']")
        if t is None or item is None or not item.text:
            continue
        m = re.search(r"_(\d+)\.h5:", item.text)
        if m:
            try:
                times[int(m.group(1))] = float(t.get("Value"))
            except (TypeError, ValueError):
                pass
    return times


def _stored_time(path: str, default: float) -> float:
    """The time attribute of a snapshot file on disk; ``default`` when there is none (or the
    path is no regular file: a FIFO there would block the open; the run then replaces it)."""
    from udf.files import check_regular
    try:
        check_regular(path)
        with h5py.File(path, "r") as f:
            t = f.attrs.get("time")
    except OSError:
        return float(default)
    return float(default if t is None else t)


def read_snapshot(path, dataset: str | None = None) -> np.ndarray:
    """One field dataset of a snapshot file as a float64 array indexed [x, y, z]
    (``dataset`` defaults to the file's first one); ``dataset="U"`` of a velocity file gives
    the vector (3, NX, NY, NZ)."""
    from udf.files import check_regular
    check_regular(path)
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
