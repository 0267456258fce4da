"""``output.AVS ON`` with ``FileType BINARY`` or ``ASCII``: the legacy AVS field files
(FORMAT-OUTPUT.md §2), every type.

In ``Out_dir``:

    <Out_name>.fld            header (nstep = Num_snap + 1), then one block per snapshot
    <Out_name>.cod            uniform grid extents: 0, (NX-1) DX, 0, (NY-1) DX, 0, (NZ-1) DX
    avs/<Out_name>_<ts>.dat   ux uy uz phi pressure tau_xy tau_yz tau_zx tau_xx tau_yy
    <Out_name>p.fld           (with particles) header, one block per snapshot
    avs/<Out_name>p_<ts>.cod  particle positions (wrapped): all z, all y, all x
    avs/<Out_name>p_<ts>.dat  Radius, then the body x, y, z axes in the lab frame (x1 x2 x3 ...)

``<ts>`` is the step.  BINARY data are float32 blocks (native order) with x fastest; ASCII
files have two header lines and one line per grid point / particle of ``%.3g`` values (the
original's 3 digits).  The fields are the snapshot's (kapsel.snapshot, rectangular frame for
the sheared types): velocity, phi (0 without particles), pressure and the viscous stress; a
type that did not compute one of them would be refused (kapsel.io.writers.check_output),
nothing is zero-filled (the original writes zeros as the spectral types' pressure).

Differences from the original, on purpose: a continued run keeps the earlier run's blocks of
the .fld files up to the restart's step and appends (the original truncates them to the header,
so AVS no longer finds the earlier snapshots whose data files are still there); each .fld is
rewritten atomically with every snapshot, after its data files are in place; the ASCII
particle .fld says ``skip = 2``, as its .dat files have two header lines (the original says
``skip = 1``, so AVS would read the label line as the first particle).
"""
from __future__ import annotations

import os
import re

import numpy as np

from udf.files import open_regular

from .atomic import atomic_write, atomic_write_text

LABELS = "ux uy uz phi pressure tau_xy tau_yz tau_zx tau_xx tau_yy"
# Electrolyte (FORMAT-OUTPUT.md §2.4): the charge fields replace pressure and stress
EL_LABELS = "ux uy uz phi surface_charge rho e_potential"
EL_FIELDS = ("surface_charge", "solute_charge", "e_potential")
PLABELS = "Radius x1 x2 x3 y1 y2 y3 z1 z2 z3"
VECLEN = 10
# snapshot stress (xx, xy, xz, yy, yz) -> AVS order tau_xy tau_yz tau_zx tau_xx tau_yy
TAU_ORDER = (1, 4, 2, 0, 3)


class LegacyAVS:
    """Writer (kapsel.io.writers protocol) of the legacy AVS files."""

    def __init__(self, directory, spec, shape, dx, num_snap, n_particles, particles=None,
                 charge=False):
        self.directory = os.fspath(directory)
        self.charge = bool(charge)         # Electrolyte: u, phi and the charge fields
        self.labels = EL_LABELS if self.charge else LABELS
        self.veclen = len(self.labels.split())
        self.name = spec.Out_name
        self.binary = spec.FileType == "BINARY"
        self.shape, self.dx = tuple(int(s) for s in shape), float(dx)
        self.nstep = int(num_snap) + 1
        self.nump = int(n_particles)
        self.radius = float(particles.radius[0]) if self.nump else 0.0
        self.blocks: list[tuple[int, str]] = []      # (step, .fld block) of the field file
        self.pblocks: list[tuple[int, str]] = []
        self._skip = None

    def needs(self) -> set:
        return {"u"} | (set(EL_FIELDS) if self.charge else {"pressure", "tau"})

    def console(self) -> str:
        kind = "binary" if self.binary else "ascii"
        out = [f"#for AVS (filetype is {kind})", f"#directory:{self.directory}",
               f"# (mesh data)->\t{{{self.name}.fld, {self.name}.cod, avs/{self.name}_*.dat}}"]
        if self.nump:
            out.append(f"# (particle data)->\t{{{self.name}p.fld, avs/{self.name}p_*.cod, "
                       f"avs/{self.name}p_*.dat}}")
        return "\n".join(out) + "\n"

    def files(self, resumed: bool) -> list[tuple[str, str]]:
        n = self.name
        out = [(self.directory, f"{n}.fld + {n}.cod + avs/{n}_<step>.dat (AVS "
                + ("binary)" if self.binary else "ascii)"))]
        if self.nump:
            out.append((self.directory, f"{n}p.fld + avs/{n}p_<step>.cod + avs/{n}p_<step>.dat"))
        return out

    # ------------------------------------------------------------------ protocol
    def open(self, snap, resumed: bool) -> None:
        os.makedirs(os.path.join(self.directory, "avs"), exist_ok=True)
        self.blocks, self.pblocks = [], []
        if resumed:
            self.blocks = _kept_blocks(self._fld(), snap.step)
            if self.nump:
                self.pblocks = _kept_blocks(self._fld("p"), snap.step)
            if self.blocks and self.blocks[-1][0] == snap.step:
                self._skip = snap.step
        nx, ny, nz = self.shape
        d = self.dx
        atomic_write_text(os.path.join(self.directory, self.name + ".cod"),
                          "".join(f"{v:g}\n" for v in (0, (nx - 1) * d, 0, (ny - 1) * d,
                                                       0, (nz - 1) * d)))
        self._write_fld()

    def write(self, snap) -> None:
        if snap.step == self._skip:
            self._skip = None
            return
        ts = snap.step
        atomic_write(self._path(f"avs/{self.name}_{ts}.dat"),
                     lambda tmp: self._field_dat(tmp, snap))
        self.blocks = [b for b in self.blocks if b[0] < ts] + [(ts, self._field_block(snap))]
        if self.nump:
            atomic_write(self._path(f"avs/{self.name}p_{ts}.cod"),
                         lambda tmp: self._particle_cod(tmp, snap))
            atomic_write(self._path(f"avs/{self.name}p_{ts}.dat"),
                         lambda tmp: self._particle_dat(tmp, snap))
            self.pblocks = [b for b in self.pblocks if b[0] < ts] + \
                [(ts, self._particle_block(snap))]
        self._write_fld()

    def close(self, reason: str) -> None:
        """Nothing is buffered: every file is complete once written."""

    # ------------------------------------------------------------------ .fld
    def _path(self, rel):
        return os.path.join(self.directory, rel)

    def _fld(self, suffix=""):
        return self._path(f"{self.name}{suffix}.fld")

    def _write_fld(self):
        nx, ny, nz = self.shape
        head = (f"# AVS field file\nndim=3\ndim1={nx}\ndim2={ny}\ndim3={nz}\nnspace=3\n"
                f"veclen={self.veclen}\ndata=float\nfield=uniform\nnstep={self.nstep}\n"
                f"label = {self.labels}\n")
        atomic_write_text(self._fld(), head + "".join(b for _, b in self.blocks))
        if self.nump:
            head = (f"# AVS field file\nndim=1\ndim1={self.nump}\nnspace=3\nveclen={VECLEN}\n"
                    f"data=float\nfield=irregular\nnstep={self.nstep}\nlabel = {PLABELS}\n")
            atomic_write_text(self._fld("p"), head + "".join(b for _, b in self.pblocks))

    def _field_block(self, snap) -> str:
        ts, name = snap.step, self.name
        out = [f'time value = "step{ts}time{snap.time:g}"']
        out += [f"coord {i + 1} file = {name}.cod filetype = ascii skip = {2 * i}"
                for i in range(3)]
        out += self._variables(f"avs/{name}_{ts}.dat", self.veclen,
                               4 * int(np.prod(self.shape)))
        return "\n".join(out + ["EOT"]) + "\n"

    def _particle_block(self, snap) -> str:
        ts, name = snap.step, self.name
        out = [f'time value = "step{ts}time{snap.time:g}"']
        size = 4 * self.nump
        for n in range(3):
            if self.binary:
                out.append(f"coord {3 - n} file = avs/{name}p_{ts}.cod filetype = binary "
                           f"skip = {n * size}")
            else:
                out.append(f"coord {3 - n} file = avs/{name}p_{ts}.cod filetype = ascii "
                           f"skip = 0 offset = {n} stride =3")
        out += self._variables(f"avs/{name}p_{ts}.dat", VECLEN, size)
        return "\n".join(out + ["EOT"]) + "\n"

    def _variables(self, path: str, veclen: int, size: int) -> list:
        """The .fld lines of the ``veclen`` variables of a .dat file (binary: one block of
        ``size`` bytes each; ascii: interleaved columns after two header lines)."""
        if self.binary:
            return [f"variable {n} file = {path} filetype = binary skip = {(n - 1) * size}"
                    for n in range(1, veclen + 1)]
        return [f"variable {n} file = {path} filetype = ascii skip = 2 offset = {n - 1} "
                f"stride = {veclen}" for n in range(1, veclen + 1)]

    # ------------------------------------------------------------------ data files
    def field_columns(self, snap) -> np.ndarray:
        """(10, NX, NY, NZ) float32 in the AVS order (Electrolyte: (7, ...))."""
        out = np.empty((self.veclen,) + self.shape, dtype=np.float32)
        out[0:3] = snap.get("u")
        out[3] = snap.get("phi") if snap.offers("phi") else 0.0     # no particles: phi = 0
        if self.charge:
            for k, n in enumerate(EL_FIELDS):
                out[4 + k] = snap.get(n)
            return out
        out[4] = snap.get("pressure")
        tau = snap.get("tau")
        for k, i in enumerate(TAU_ORDER):
            out[5 + k] = tau[i]
        return out

    def _field_dat(self, tmp, snap):
        cols = self.field_columns(snap)
        with open(tmp, "wb") as fh:
            if self.binary:
                for c in cols:                      # x fastest: [z][y][x] in C order
                    fh.write(np.ascontiguousarray(c.T).tobytes())
            else:
                fh.write(f"timesteps={snap.step} time={snap.time:f}\n{self.labels}\n".encode())
                fh.write(_g3(cols.reshape(self.veclen, -1, order="F").T))

    def _particle_cod(self, tmp, snap):
        R = np.asarray(snap.particles.R, dtype=np.float32)[:, ::-1]     # z, y, x
        with open(tmp, "wb") as fh:
            if self.binary:
                fh.write(np.ascontiguousarray(R.T).tobytes())
            else:
                fh.write(_g3(R))

    def particle_columns(self, snap) -> np.ndarray:
        """(10, N) float32: Radius, then M[c][a] for body axis a = x, y, z, c = 0, 1, 2 (M the
        body-to-lab rotation)."""
        from ..particles.quaternion import to_matrix
        m = to_matrix(snap.particles.q)                       # (N, 3, 3): m[n, c, a]
        out = np.empty((VECLEN, self.nump), dtype=np.float32)
        out[0] = self.radius
        out[1:] = np.swapaxes(m, 1, 2).reshape(self.nump, 9).T   # a slowest, c fastest
        return out

    def _particle_dat(self, tmp, snap):
        cols = self.particle_columns(snap)
        with open(tmp, "wb") as fh:
            if self.binary:
                fh.write(np.ascontiguousarray(cols).tobytes())
            else:
                fh.write(f"timesteps={snap.step} time={snap.time:f}\n{PLABELS}\n".encode())
                fh.write(_g3(cols.T))


def _g3(table) -> bytes:
    """Rows of ``%.3g`` values separated by single spaces (one formatting call for the whole
    table: 1.8x faster than numpy.savetxt's row loop)."""
    rows, cols = table.shape
    row = " ".join(["%.3g"] * cols) + "\n"
    return ((row * rows) % tuple(table.ravel().tolist())).encode("ascii")


def _kept_blocks(path, upto):
    """(step, block) of an existing .fld with step <= ``upto`` ([] if none)."""
    try:
        with open_regular(path, "r", encoding="utf-8") as fh:
            text = fh.read()
    except OSError:
        return []
    out = []
    for m in re.finditer(r'time value = "step(\d+)time[^"]*"\n.*?\nEOT\n', text, re.S):
        step = int(m.group(1))
        if step <= upto:
            out.append((step, m.group(0)))
    return out
