"""``output.AVS ON`` with ``FileType EXTENDED``: one HDF5 trajectory, its ``.conf`` and XDMF
files (FORMAT-OUTPUT.md §3).

``<Out_dir>/<Out_name>.h5``:

    root attributes  dx float32 (1,), nxnynz int64 (3,) (written field dims), origin float32
                     (3,) = start * DX, nump / nump_obs / nump_total int32 (1,), git_version,
                     git_ref (fixed-length NUL-terminated strings)
    /system_data/field/x, y, z          float32 (cx, cy, cz): grid coordinates (index * DX)
    /system_data/particle/id, spec      int32 (nump,)
    /trajectory_data/frame_<f>/         attributes time float32 (1,), gamma float32 (1,) (frame
                                        strain, sheared types only)
        field/    u_x u_y u_z (Vel), phi (Phi), pressure (Pressure),
                  tau_xx tau_xy tau_xz tau_yy tau_yz (Tau): float32 (cx, cy, cz), [x][y][z]
        particle/ pos pos_raw vel omega force_h force_r torque_h torque_r float32 (nump, 3),
                  QR float32 (nump, 3, 3): QR[n][a][c] = lab component c of body axis a

``Crop YES`` writes the hyperslab start + m stride (m < count) of every axis.  Fields are
the snapshot's (kapsel.snapshot) in the rectangular frame; force_h / torque_h are the
hydrodynamic plus slip force / torque of the step just taken, force_r / torque_r the others.
Obstacles (janus_propulsion OBSTACLE) are apart, as the original: nump counts the others,
nump_obs the obstacles; /system_data/obstacle/{id, spec, pos} (positions once: they do not
move), frame_<f>/obstacle/{force_h, force_r}, the .conf obstacle block and
``<Out_name>_obstacle.xdmf``.

``<Out_name>.conf``: the original's text, from which its Tools/h5kapsel2xdmf.py builds the
XDMF files; and those XDMF files written directly, as that script names them:
``<Out_name>_fluid.xdmf`` (3DSMesh on system_data/field/x, y, z: every point where it is,
crop included; scalar attributes and the vector ``u``) and ``<Out_name>_particle.xdmf``
(Polyvertex of the positions; id, spec, the vectors and the tensor QR).  Each grid carries its
frame's time (the script writes a HyperSlab start / step / count time instead).

Both of ParaView's XDMF readers (legacy ``XDMFReader`` and ``Xdmf3ReaderS`` / ``T``) read
them (see kapsel.io.fields for what Xdmf3 needs): where the script joins x, y, z or u_x, u_y,
u_z with ``Function="JOIN(...)"`` or ``X_Y_Z`` items, the files read
``<Out_name>_xdmf.h5``, which holds no data of its own: ``field_xyz`` (cx, cy, cz, 3) and
``frame_<f>/u`` (cx, cy, cz, 3) are HDF5 virtual datasets of ``<Out_name>.h5``'s
system_data/field/{x,y,z} and frame_<f>/field/u_{x,y,z}; ``particle_vertex`` and
``obstacle_vertex`` (int32 0 .. n-1) are the Polyvertex connectivities (n one-point cells;
the script writes one cell of n points, which the Xdmf3 reader cannot build).  Item
Dimensions have the datasets' rank (id ``n``, QR ``n 3 3``): Xdmf3 aborts on ``n 1`` / ``n 9``.

Differences from the original, on purpose: a continued run appends its frames to the file
(frames later than the restart are dropped; the original truncates the file and counts
frames and time from 0 again, losing the earlier trajectory); the ``time`` attribute is the
snapshot's time (the original's f * DT * GTS restarts at 0 on resume); the .conf and .xdmf
files are rewritten (atomically) after every frame, so they always describe the file; the
XDMF text reads the sidecar described above (the script's opens only in the legacy reader).
The .h5 file is flushed after every frame and closed at the end, on interruption and on
failure.
"""
from __future__ import annotations

import os
import sys

import h5py
import numpy as np

from . import journal
from .atomic import atomic_write_text, fmt
from .fields import SIDECAR_LIBVER, interlaced
from .h5file import append_h5, write_h5

F32 = np.float32
TAU = ("tau_xx", "tau_xy", "tau_xz", "tau_yy", "tau_yz")
# Charge (Electrolyte only): the particles' surface charge density, the ions' charge density
# sum_s z_s c_s (1 - phi), the potential of the internal charges (kapsel.models.electrolyte)
CHARGE = ("surface_charge", "solute_charge", "e_potential")
PARTICLE_VECTORS = ("vel", "omega", "force_h", "force_r", "torque_h", "torque_r")


def _string_attr(obj, name, text):
    """A scalar fixed-length NUL-terminated ASCII attribute, as the original's."""
    b = text.encode("ascii")
    tid = h5py.h5t.C_S1.copy()
    tid.set_size(len(b) + 1)
    tid.set_strpad(h5py.h5t.STR_NULLTERM)
    obj.attrs.create(name, np.array(b, dtype=f"S{len(b) + 1}"), dtype=h5py.Datatype(tid))


class ExtendedHDF5:
    """Writer (kapsel.io.writers protocol) of the EXTENDED trajectory."""

    def __init__(self, directory, spec, shape, dx, dt, gts, n_particles, species, sheared,
                 obstacles=()):
        self.directory = os.fspath(directory)
        self.name = spec.Out_name
        self.path = os.path.join(self.directory, self.name + ".h5")
        self.sidecar = os.path.join(self.directory, self.name + "_xdmf.h5")
        self.shape, self.dx, self.dt, self.gts = tuple(shape), float(dx), float(dt), int(gts)
        self.sheared = bool(sheared)
        slabs = spec.slabs or tuple((0, n, 1) for n in self.shape)
        self.slabs = slabs
        self.index = tuple(slice(s, s + (c - 1) * st + 1, st) for s, c, st in slabs)
        self.dims = tuple(c for _, c, _ in slabs)
        self.fields = [n for n, on in (("u", spec.Vel), ("phi", spec.Phi),
                                       ("pressure", spec.Pressure), ("tau", spec.Tau),
                                       ("charge", spec.Charge)) if on]
        obs = np.zeros(int(n_particles), dtype=bool)
        obs[np.asarray(obstacles, dtype=np.int64)] = True
        self.ids = np.flatnonzero(~obs).astype(np.int32)        # "particle" list
        self.obs_ids = np.flatnonzero(obs).astype(np.int32)     # "obstacle" list
        self.nump, self.nobs = len(self.ids), len(self.obs_ids)
        self.species = np.asarray(species, dtype=np.int32).reshape(-1)
        self.file = None
        self.io = None                  # the journaled file object under self.file
        self.frames = 0
        self._skip = None
        self._times: list[float] = []

    def needs(self) -> set:
        return {n for n in self.fields if n != "charge"} | (
            set(CHARGE) if "charge" in self.fields else set())

    def console(self) -> str:
        """The original's HDF5 block at initialisation (FORMAT-OUTPUT.md §3.8)."""
        nx, ny, nz = self.shape
        out = ["# *** HDF5 Parameters ***", f"# Output Name          : {self.path}",
               f"# Mem Layout           : ({nx}, {ny}, {nz}, {nz + 2})",
               f"# Grid spacing         : {self.dx:.3g}",
               f"# Time between frames  : {self.dt * self.gts:.3g}"]
        if self.fields:
            for ax, (s, c, st) in zip("xyz", self.slabs):
                out.append(f"# {ax}-axis slicing       : start = {s:4d}, stride = {st:4d}, "
                           f"count = {c:4d}")
            o = [s * self.dx for s, _, _ in self.slabs]
            out.append(f"# Output Origin        : ({o[0]:.3g}, {o[1]:.3g}, {o[2]:.3g})")
            for label, name in (("velocity", "u"), ("phi", "phi"), ("charge", "charge"),
                                ("Pressure", "pressure"), ("Stress", "tau")):
                out.append(f"# Print {label + ' field':<15}: "
                           f"{'YES' if name in self.fields else 'NO'}")
        else:
            out.append("# Field Data is being suppressed")
        out.append("# ***********************")
        return "\n".join(out) + "\n"

    def files(self, resumed: bool) -> list[tuple[str, str]]:
        n = self.name
        views = ([f"{n}_fluid.xdmf"] if self.fields else []) + (
            [f"{n}_particle.xdmf"] if self.nump else []) + (
            [f"{n}_obstacle.xdmf"] if self.nobs else []) + (
            [f"{n}_xdmf.h5"] if self._described() else [])
        return [(self.directory, f"{n}.h5 (EXTENDED, frames"
                 + (" appended)" if resumed else ")") + f" + {n}.conf"
                 + "".join(" + " + v for v in views))]

    # ------------------------------------------------------------------ protocol
    def open(self, snap, resumed: bool) -> None:
        os.makedirs(self.directory, exist_ok=True)
        if resumed and os.path.exists(self.path):
            if self._continue(snap):
                return
            print(f"#{self.path} cannot be continued (another grid, crop or particle "
                  f"number, or not readable): a new trajectory replaces it", file=sys.stderr)
        journal.discard(self.path)
        self.io = journal.JournaledFile(self.path, create=True)
        self.file = h5py.File(self.io, "w")
        self._guarded(lambda: self._header(snap))
        self.frames, self._times = 0, []
        self._write_sidecar()
        self._describe()

    def _continue(self, snap) -> bool:
        """Open the existing trajectory (first put back to its last complete frame if a run
        was killed or failed while writing it: kapsel.io.journal), drop frames later than
        the restart; False if it was written for another grid, crop or particle count or
        cannot be read (then it is replaced)."""
        try:
            journal.recover(self.path)
            self.io = journal.JournaledFile(self.path)
        except OSError as e:
            raise OSError(e.errno, e.strerror, self.path) from None
        try:
            f = h5py.File(self.io, "a")
        except (OSError, ValueError, KeyError, RuntimeError):
            self.io.close()
            return False
        try:
            ok = (list(f.attrs.get("nxnynz", [])) == list(self.dims)
                  and int(f.attrs.get("nump", [-1])[0]) == self.nump
                  and int(f.attrs.get("nump_obs", [0])[0]) == self.nobs
                  and "trajectory_data" in f)
        except (OSError, ValueError, KeyError, RuntimeError, IndexError, TypeError):
            ok = False
        if not ok:
            f.close()
            self.io.close()
            return False
        self.file = f
        traj = f["trajectory_data"]
        n = 0
        times = []
        tol = 1e-6 * max(1.0, abs(snap.time))
        while f"frame_{n}" in traj and self._complete(traj[f"frame_{n}"]) \
                and float(traj[f"frame_{n}"].attrs["time"][0]) <= snap.time + tol:
            times.append(float(traj[f"frame_{n}"].attrs["time"][0]))
            n += 1
        drop = []
        while f"frame_{n + len(drop)}" in traj:
            drop.append(f"frame_{n + len(drop)}")

        def cut():
            for name in drop:
                del traj[name]
        if drop:
            self._guarded(cut)
        self.frames, self._times = n, times
        if times and abs(times[-1] - snap.time) <= tol:
            self._skip = snap.step
        self._write_sidecar()
        self._describe()
        return True

    def _guarded(self, change) -> None:
        """Make ``change`` to the file, flush it and commit (kapsel.io.journal); a failed
        write (a full disk) puts the file back to the last commit and raises OSError
        naming the file."""
        try:
            change()
            self.file.flush()
            self.io.commit()
        except Exception as e:              # h5py wraps the failed write in its own error
            failed = self.io.error or (e if isinstance(e, OSError) and e.errno else None)
            self._abandon()
            if failed is None:
                raise
            raise OSError(failed.errno, failed.strerror, self.path) from None

    def _abandon(self) -> None:
        """After a failure: no further write reaches the file, which is rolled back."""
        self.io.rollback()
        try:
            self.file.close()
        except Exception:                   # noqa: BLE001 - its writes fail on purpose
            pass
        self.file = None

    def _complete(self, frame) -> bool:
        """A frame with every dataset this run writes (not one cut by a killed run)."""
        names = [f"field/{n}" for n in self._dataset_names()]
        if self.nump:
            names += [f"particle/{n}" for n in ("pos", "pos_raw", "QR") + PARTICLE_VECTORS]
        if self.nobs:
            names += ["obstacle/force_h", "obstacle/force_r"]
        try:
            return "time" in frame.attrs and all(n in frame for n in names)
        except (OSError, KeyError):
            return False

    def _dataset_names(self):
        out = []
        for name in self.fields:
            out += {"u": ["u_x", "u_y", "u_z"], "tau": list(TAU),
                    "charge": list(CHARGE)}.get(name, [name])
        return out

    def write(self, snap) -> None:
        if snap.step == self._skip:
            self._skip = None
            return
        if self.file is None:
            raise OSError(0, "the trajectory was closed after a failed write", self.path)
        self._guarded(lambda: self._frame(snap))
        self._sidecar_frame(self.frames)
        self.frames += 1
        self._times.append(float(np.float32(snap.time)))
        self._describe()

    def _frame(self, snap) -> None:
        g = self.file.create_group(f"trajectory_data/frame_{self.frames}")
        g.attrs.create("time", np.array([snap.time], dtype=F32))
        if self.sheared:
            g.attrs.create("gamma", np.array([snap.strain], dtype=F32))
        if self.fields:
            fg = g.create_group("field")
            for name, data in self._field_data(snap):
                fg.create_dataset(name, data=data)
        if self.nump or self.nobs:
            data = particle_data(snap.particles)
        if self.nump:
            pg = g.create_group("particle")
            for name, d in data.items():
                pg.create_dataset(name, data=d[self.ids] if self.nobs else d)
        if self.nobs:
            og = g.create_group("obstacle")
            for name in ("force_h", "force_r"):
                og.create_dataset(name, data=data[name][self.obs_ids])

    def close(self, reason: str) -> None:
        if self.file is None:
            return
        try:
            self.file.close()
            self.io.commit()
            self.io.close()
        except Exception as e:              # noqa: BLE001 - a full disk at the close
            failed = self.io.error or (e if isinstance(e, OSError) and e.errno else None)
            self._abandon()
            if reason == "end":
                if failed is None:
                    raise
                raise OSError(failed.errno, failed.strerror, self.path) from None
        finally:
            self.file = None

    # ------------------------------------------------------------------ content
    def _crop(self, a):
        return np.ascontiguousarray(a[self.index], dtype=F32)

    def _field_data(self, snap):
        for name in self.fields:
            if name == "u":
                u = snap.get("u")
                yield from (("u_x", self._crop(u[0])), ("u_y", self._crop(u[1])),
                            ("u_z", self._crop(u[2])))
            elif name == "tau":
                tau = snap.get("tau")
                yield from ((n, self._crop(tau[i])) for i, n in enumerate(TAU))
            elif name == "charge":
                yield from ((n, self._crop(snap.get(n))) for n in CHARGE)
            elif name == "phi" and not snap.offers("phi"):      # no particles: phi = 0
                yield "phi", np.zeros(self.dims, dtype=F32)
            else:
                yield name, self._crop(snap.get(name))

    def _header(self, snap=None):
        f = self.file
        f.attrs.create("dx", np.array([self.dx], dtype=F32))
        f.attrs.create("nxnynz", np.array(self.dims, dtype=np.int64))
        f.attrs.create("origin", np.array([s * self.dx for s, _, _ in self.slabs], dtype=F32))
        f.attrs.create("nump", np.array([self.nump], dtype=np.int32))
        f.attrs.create("nump_obs", np.array([self.nobs], dtype=np.int32))
        f.attrs.create("nump_total", np.array([self.nump + self.nobs], dtype=np.int32))
        from .. import __version__
        _string_attr(f, "git_version", f"kapsel-py {__version__}")
        _string_attr(f, "git_ref", "kapsel-py")
        sysd = f.create_group("system_data")
        if self.fields:
            fg = sysd.create_group("field")
            axes = np.meshgrid(*[(s + st * np.arange(c)) * self.dx for s, c, st in self.slabs],
                               indexing="ij")
            for name, a in zip("xyz", axes):
                fg.create_dataset(name, data=a.astype(F32))
        if self.nump:
            pg = sysd.create_group("particle")
            pg.create_dataset("id", data=self.ids)
            pg.create_dataset("spec", data=self.species[self.ids])
        if self.nobs:
            og = sysd.create_group("obstacle")
            og.create_dataset("id", data=self.obs_ids)
            og.create_dataset("spec", data=self.species[self.obs_ids])
            og.create_dataset("pos", data=np.ascontiguousarray(
                snap.particles.R[self.obs_ids], dtype=F32))
        f.create_group("trajectory_data")

    # ------------------------------------------------------------------ <Out_name>_xdmf.h5
    def _described(self) -> bool:
        """Whether XDMF files (and so the sidecar) are written."""
        return bool(self.fields or self.nump or self.nobs)

    def _write_sidecar(self):
        """The whole sidecar (module docstring) for the frames in the file, written anew."""
        if not self._described():
            return
        src = os.path.basename(self.path)

        def write(f):
            if self.fields:
                interlaced(f, "field_xyz", src, [f"/system_data/field/{a}" for a in "xyz"],
                           self.dims, F32)
            if self.nump:
                f.create_dataset("particle_vertex", data=np.arange(self.nump, dtype=np.int32))
            if self.nobs:
                f.create_dataset("obstacle_vertex", data=np.arange(self.nobs, dtype=np.int32))
            for i in range(self.frames):
                self._frame_views(f, i)
        write_h5(self.sidecar, write, libver=SIDECAR_LIBVER)

    def _sidecar_frame(self, i):
        """Frame i's views, added to the sidecar (one small metadata write per frame; a
        continued run writes the sidecar anew)."""
        if "u" in self.fields:
            def add(f):
                if f"frame_{i}" in f:
                    del f[f"frame_{i}"]
                self._frame_views(f, i)
            append_h5(self.sidecar, add, libver=SIDECAR_LIBVER)

    def _frame_views(self, f, i):
        if "u" in self.fields:
            base = f"/trajectory_data/frame_{i}/field"
            interlaced(f, f"frame_{i}/u", os.path.basename(self.path),
                       [f"{base}/u_{c}" for c in "xyz"], self.dims, F32)

    # ------------------------------------------------------------------ .conf and XDMF
    def conf(self) -> str:
        cx, cy, cz = self.dims
        out = ["#Configure file needed to generate xdmf trajectory", "#v1.1",
               "[Filename]", f" {self.name}", "[Grid Dimensions]", f" {cx} {cy} {cz}",
               "[Time Series]", f" 0.0 {self.dt * self.gts:.6f} {self.frames}",
               "[Particle Number]", f" {self.nump}", "[Obstacle Number]", f" {self.nobs}", ""]
        if self.nump:
            out += ["[Particle Grid]", " pos", "#[Particle Grid]", "#pos_raw",
                    "[Particle Scalar Const]", " id", "[Particle Scalar Const]", " spec"]
            for v in PARTICLE_VECTORS:
                out += ["[Particle Vector]", f" {v}"]
            out += ["[Particle Tensor]", " QR", ""]
        if self.nobs:
            out += ["[Obstacle Grid Const]", " pos", "[Obstacle Scalar Const]", " id",
                    "[Obstacle Scalar Const]", " spec", "[Obstacle Vector]", " force_h",
                    "[Obstacle Vector]", " force_r", ""]
        if self.fields:
            out += ["[Field GridX Const]", " x", "[Field GridY Const]", " y",
                    "[Field GridZ Const]", " z"]
            if "u" in self.fields:
                out += ["[Field Vector]", " u_x u_y u_z u"]
            for name in self._scalars():
                out += ["[Field Scalar]", f" {name}"]
            out.append("")
        return "\n".join(out) + "\n"

    def _scalars(self):
        names = [n for n in ("phi", "pressure") if n in self.fields]
        return (names + (list(TAU) if "tau" in self.fields else [])
                + (list(CHARGE) if "charge" in self.fields else []))

    def _describe(self):
        atomic_write_text(os.path.join(self.directory, self.name + ".conf"), self.conf())
        if self.fields:
            atomic_write_text(os.path.join(self.directory, self.name + "_fluid.xdmf"),
                              self.fluid_xdmf())
        if self.nump:
            atomic_write_text(os.path.join(self.directory, self.name + "_particle.xdmf"),
                              self.particle_xdmf())
        if self.nobs:
            atomic_write_text(os.path.join(self.directory, self.name + "_obstacle.xdmf"),
                              self.obstacle_xdmf())

    def _xdmf(self, collection, frame_lines):
        out = ['<?xml version="1.0" ?>', '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>',
               '<Xdmf Version="2.0"><Domain>',
               f' <Grid CollectionType="Temporal" GridType="Collection" Name="{collection}">']
        for i, t in enumerate(self._times):
            out += frame_lines(i, t)
        out += [' </Grid>', '</Domain></Xdmf>', '']
        return "\n".join(out)

    def _item(self, dims, path, number="Float", precision=4, file=None):
        file = file or f"{self.name}.h5"
        return (f'    <DataItem NumberType="{number}" Precision="{precision}" '
                f'Dimensions="{dims}" Format="HDF">{file}:{path}</DataItem>')

    def _side(self, dims, path, number="Float"):
        """An item of <Out_name>_xdmf.h5."""
        return self._item(dims, path, number, file=f"{self.name}_xdmf.h5")

    def _attribute(self, kind, name, dims, path, number="Float") -> list:
        """An XDMF Attribute holding one HDF dataset."""
        return [f'   <Attribute AttributeType="{kind}" Name="{name}" Center="Node">',
                self._item(dims, path, number), '   </Attribute>']

    def _vertices(self, n, name) -> list:
        """A Polyvertex topology of n one-point cells (connectivity in the sidecar)."""
        return [f'   <Topology TopologyType="Polyvertex" NumberOfElements="{n}">',
                self._side(n, f"/{name}", "Int"), '   </Topology>']

    def fluid_xdmf(self) -> str:
        dims = " ".join(str(c) for c in self.dims)

        def frame(i, t):
            base = f"/trajectory_data/frame_{i}/field"
            out = ['  <Grid Name="Fluid Frame" GridType="Uniform">', f'   <Time Value="{fmt(t)}"/>',
                   f'   <Topology TopologyType="3DSMesh" Dimensions="{dims}"/>',
                   '   <Geometry GeometryType="XYZ">', self._side(f"{dims} 3", "/field_xyz"),
                   '   </Geometry>']
            for name in self._scalars():
                out += self._attribute("Scalar", name, dims, f"{base}/{name}")
            if "u" in self.fields:
                out += ['   <Attribute AttributeType="Vector" Name="u" Center="Node">',
                        self._side(f"{dims} 3", f"/frame_{i}/u"), '   </Attribute>']
            out.append('  </Grid>')
            return out
        return self._xdmf("KAPSEL Fluid Trajectory", frame)

    def particle_xdmf(self) -> str:
        n = self.nump

        def frame(i, t):
            base = f"/trajectory_data/frame_{i}/particle"
            out = ['  <Grid Name="Particle Frame" GridType="Uniform">',
                   f'   <Time Value="{fmt(t)}"/>'] + self._vertices(n, "particle_vertex")
            out += ['   <Geometry GeometryType="XYZ">', self._item(f"{n} 3", f"{base}/pos"),
                    '   </Geometry>']
            for name in ("id", "spec"):
                out += self._attribute("Scalar", name, n, f"/system_data/particle/{name}", "Int")
            for name in PARTICLE_VECTORS:
                out += self._attribute("Vector", name, f"{n} 3", f"{base}/{name}")
            out += self._attribute("Tensor", "QR", f"{n} 3 3", f"{base}/QR") + ['  </Grid>']
            return out
        return self._xdmf("KAPSEL Particle Trajectory", frame)

    def obstacle_xdmf(self) -> str:
        """The obstacle file of h5kapsel2xdmf.py: static positions, id, spec, force_h / _r."""
        n = self.nobs

        def frame(i, t):
            base = f"/trajectory_data/frame_{i}/obstacle"
            out = ['  <Grid Name="Obstacle Frame" GridType="Uniform">',
                   f'   <Time Value="{fmt(t)}"/>'] + self._vertices(n, "obstacle_vertex")
            out += ['   <Geometry GeometryType="XYZ">',
                    self._item(f"{n} 3", "/system_data/obstacle/pos"), '   </Geometry>']
            for name in ("id", "spec"):
                out += self._attribute("Scalar", name, n, f"/system_data/obstacle/{name}", "Int")
            for name in ("force_h", "force_r"):
                out += self._attribute("Vector", name, f"{n} 3", f"{base}/{name}")
            out.append('  </Grid>')
            return out
        return self._xdmf("KAPSEL Obstacle Trajectory", frame)


def particle_data(p) -> dict:
    """The per-frame particle datasets of ParticleState ``p`` (float32)."""
    from ..particles.quaternion import to_matrix
    d = {"pos": p.R, "pos_raw": p.R_raw, "vel": p.v, "omega": p.omega,
         "force_h": p.f_hydro + p.f_slip, "force_r": p.f_r,
         "torque_h": p.torque_hydro + p.torque_slip, "torque_r": p.torque_r,
         "QR": np.swapaxes(to_matrix(p.q), -1, -2)}
    return {k: np.ascontiguousarray(v, dtype=F32) for k, v in d.items()}
