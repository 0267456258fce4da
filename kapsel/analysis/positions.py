"""Particle-position readers for the analyses: (extended) XYZ and LAMMPS text dumps.

Both read every frame and return a list of :class:`Frame`, a 3-tuple
``(positions (N, 3) float64, box (3,) or None, lo (3,))`` that also carries ``types``,
``ids``, ``timestep``, ``periodic`` (3 bools) and ``comment`` as attributes.  Only
orthorhombic boxes are accepted.  Malformed input raises ValueError naming file and line.
Files ending in .gz are read through gzip.
"""
from __future__ import annotations

import gzip
import re

import numpy as np

__all__ = ["Frame", "read_xyz", "read_lammps_dump", "read_positions"]


class Frame(tuple):
    """(positions, box, lo) with extra attributes types, ids, timestep, periodic, comment."""

    def __new__(cls, positions, box, lo, *, types=None, ids=None, timestep=None,
                periodic=None, comment=""):
        self = super().__new__(cls, (positions, box, lo))
        self.types = types
        self.ids = ids
        self.timestep = timestep
        self.periodic = (np.zeros(3, bool) if box is None else np.ones(3, bool)) \
            if periodic is None else np.asarray(periodic, dtype=bool)
        self.comment = comment
        return self

    positions = property(lambda self: self[0])
    box = property(lambda self: self[1])
    lo = property(lambda self: self[2])

    def __repr__(self):
        box = None if self.box is None else self.box.tolist()
        return f"Frame(N={len(self.positions)}, box={box}, lo={self.lo.tolist()}, " \
               f"timestep={self.timestep})"


def _open(path):
    """A regular file only (udf.files.open_regular: a FIFO or device is refused)."""
    from udf.files import open_regular
    path = str(path)
    if path.endswith(".gz"):
        return gzip.open(open_regular(path), "rt", encoding="utf-8")
    return open_regular(path, "r", encoding="utf-8")


def _read_lines(path):
    with _open(path) as fh:
        return fh.read().splitlines()


def _floats(tokens, path, lineno, what):
    try:
        return [float(t) for t in tokens]
    except ValueError:
        raise ValueError(f"{path}:{lineno}: {what}: cannot read numbers from "
                         f"{' '.join(tokens)!r}") from None


def _is_number(tok):
    try:
        float(tok)
        return True
    except ValueError:
        return False


# ---------------------------------------------------------------- XYZ
_KV = re.compile(r'(\w+)\s*=\s*("[^"]*"|\'[^\']*\'|\{[^}]*\}|\S+)')


def _xyz_comment(comment, path, lineno):
    """(box, lo, periodic, pos_column, species_column) from an extended-XYZ comment."""
    kv = {m.group(1).lower(): m.group(2).strip("\"'{}") for m in _KV.finditer(comment)}
    box, lo, periodic = None, np.zeros(3), None
    if "lattice" in kv:
        vals = _floats(kv["lattice"].split(), path, lineno, "Lattice")
        if len(vals) != 9:
            raise ValueError(f"{path}:{lineno}: Lattice needs 9 numbers, got {len(vals)}")
        cell = np.array(vals).reshape(3, 3)
        off = cell - np.diag(np.diag(cell))
        if np.any(np.abs(off) > 1e-12 * np.abs(cell).max()):
            raise ValueError(f"{path}:{lineno}: only orthorhombic cells are supported, "
                             f"Lattice={kv['lattice']!r} is triclinic")
        box = np.diag(cell).copy()
        if np.any(box <= 0):
            raise ValueError(f"{path}:{lineno}: Lattice lengths must be positive, got {box}")
        periodic = np.ones(3, bool)
        if "origin" in kv:
            lo = np.array(_floats(kv["origin"].split(), path, lineno, "Origin"))
            if lo.shape != (3,):
                raise ValueError(f"{path}:{lineno}: Origin needs 3 numbers")
        if "pbc" in kv:
            flags = kv["pbc"].split()
            if len(flags) != 3 or any(f.upper() not in ("T", "F", "TRUE", "FALSE", "1", "0")
                                      for f in flags):
                raise ValueError(f"{path}:{lineno}: pbc needs 3 of T/F, got {kv['pbc']!r}")
            periodic = np.array([f.upper() in ("T", "TRUE", "1") for f in flags])
    pos_col, spec_col = None, None
    if "properties" in kv:
        parts = kv["properties"].split(":")
        if len(parts) % 3:
            raise ValueError(f"{path}:{lineno}: Properties must be name:type:count triples, "
                             f"got {kv['properties']!r}")
        col = 0
        for name, _typ, cnt in zip(parts[0::3], parts[1::3], parts[2::3]):
            try:
                cnt = int(cnt)
            except ValueError:
                raise ValueError(f"{path}:{lineno}: bad count {cnt!r} in Properties") from None
            if name.lower() in ("pos", "position", "positions"):
                if cnt != 3:
                    raise ValueError(f"{path}:{lineno}: pos must have 3 components")
                pos_col = col
            elif name.lower() in ("species", "element", "type") and spec_col is None:
                spec_col = col
            col += cnt
        if pos_col is None:
            raise ValueError(f"{path}:{lineno}: Properties has no pos column")
    return box, lo, periodic, pos_col, spec_col


def read_xyz(path) -> list:
    """Frames of a (multi-frame) XYZ file: plain XYZ (``species x y z`` lines, box None) or
    extended XYZ with Lattice="Lx 0 0 0 Ly 0 0 0 Lz" (and optional Origin, pbc,
    Properties) in the comment line."""
    lines = _read_lines(path)
    frames = []
    i = 0
    while i < len(lines):
        if not lines[i].strip():
            i += 1
            continue
        head = lines[i].split()
        try:
            n = int(head[0])
            if n < 0 or len(head) != 1:
                raise ValueError
        except ValueError:
            raise ValueError(f"{path}:{i + 1}: expected the number of atoms of a frame, got "
                             f"{lines[i]!r}") from None
        if i + 1 >= len(lines):
            raise ValueError(f"{path}:{i + 2}: missing comment line of the frame")
        comment = lines[i + 1]
        box, lo, periodic, pos_col, spec_col = _xyz_comment(comment, path, i + 2)
        if i + 2 + n > len(lines):
            raise ValueError(f"{path}:{len(lines)}: frame at line {i + 1} announces {n} atoms "
                             f"but the file ends after {len(lines) - i - 2}")
        block = [ln.split() for ln in lines[i + 2:i + 2 + n]]
        if pos_col is None and n:
            first = block[0]
            if len(first) == 3 and all(_is_number(t) for t in first):
                pos_col, spec_col = 0, None
            else:
                pos_col, spec_col = 1, 0
        pos = np.empty((n, 3))
        species = []
        for k, tok in enumerate(block):
            if len(tok) < pos_col + 3:
                raise ValueError(f"{path}:{i + 3 + k}: expected at least {pos_col + 3} columns, "
                                 f"got {len(tok)}: {lines[i + 2 + k]!r}")
            pos[k] = _floats(tok[pos_col:pos_col + 3], path, i + 3 + k, "atom position")
            if spec_col is not None:
                species.append(tok[spec_col])
        if not np.isfinite(pos).all():
            raise ValueError(f"{path}:{i + 3}: non-finite coordinates in the frame")
        frames.append(Frame(pos, box, lo, types=np.array(species) if species else None,
                            periodic=periodic, comment=comment))
        i += 2 + n
    if not frames:
        raise ValueError(f"{path}:1: no XYZ frame found")
    return frames


# ---------------------------------------------------------------- LAMMPS dump
_COORDS = (("x", "y", "z", False), ("xu", "yu", "zu", False),
           ("xs", "ys", "zs", True), ("xsu", "ysu", "zsu", True))


def read_lammps_dump(path) -> list:
    """Frames of a LAMMPS text dump (ITEM: TIMESTEP / NUMBER OF ATOMS / BOX BOUNDS /
    ATOMS id type x y z, or xu.., xs ys zs, xsu..), atoms sorted by id."""
    lines = _read_lines(path)
    frames = []
    i = 0
    timestep, natoms, bounds, flags = None, None, None, None

    def need(k, what):
        if k >= len(lines):
            raise ValueError(f"{path}:{len(lines)}: file ends inside {what}")
        return lines[k]

    while i < len(lines):
        line = lines[i].strip()
        if not line:
            i += 1
            continue
        if not line.startswith("ITEM:"):
            raise ValueError(f"{path}:{i + 1}: expected an 'ITEM:' line, got {lines[i]!r}")
        item = line[5:].strip()
        if item.startswith("TIMESTEP"):
            tok = need(i + 1, "ITEM: TIMESTEP").split()
            try:
                timestep = int(tok[0])
            except (ValueError, IndexError):
                raise ValueError(f"{path}:{i + 2}: bad timestep {lines[i + 1]!r}") from None
            i += 2
        elif item.startswith("NUMBER OF ATOMS"):
            tok = need(i + 1, "ITEM: NUMBER OF ATOMS").split()
            try:
                natoms = int(tok[0])
                if natoms < 0:
                    raise ValueError
            except (ValueError, IndexError):
                raise ValueError(f"{path}:{i + 2}: bad number of atoms {lines[i + 1]!r}") from None
            i += 2
        elif item.startswith("BOX BOUNDS"):
            words = item.split()[2:]
            if any(w in ("xy", "xz", "yz") for w in words):
                raise ValueError(f"{path}:{i + 1}: triclinic boxes are not supported")
            flags = words if len(words) == 3 else ["pp", "pp", "pp"]
            bounds = []
            for d in range(3):
                tok = need(i + 1 + d, "ITEM: BOX BOUNDS").split()
                if len(tok) != 2:
                    raise ValueError(f"{path}:{i + 2 + d}: expected 'lo hi', got "
                                     f"{lines[i + 1 + d]!r}")
                bounds.append(_floats(tok, path, i + 2 + d, "box bounds"))
            bounds = np.array(bounds)
            if np.any(bounds[:, 1] <= bounds[:, 0]):
                raise ValueError(f"{path}:{i + 2}: box bounds must have hi > lo, got "
                                 f"{bounds.tolist()}")
            i += 4
        elif item.startswith("ATOMS"):
            cols = item.split()[1:]
            if natoms is None:
                raise ValueError(f"{path}:{i + 1}: ITEM: ATOMS before ITEM: NUMBER OF ATOMS")
            if bounds is None:
                raise ValueError(f"{path}:{i + 1}: ITEM: ATOMS before ITEM: BOX BOUNDS")
            names = None
            for cx, cy, cz, scaled in _COORDS:
                if all(c in cols for c in (cx, cy, cz)):
                    names = (cx, cy, cz, scaled)
                    break
            if names is None:
                raise ValueError(f"{path}:{i + 1}: ITEM: ATOMS has no x y z / xu yu zu / "
                                 f"xs ys zs / xsu ysu zsu columns: {' '.join(cols)!r}")
            if i + 1 + natoms > len(lines):
                raise ValueError(f"{path}:{len(lines)}: {natoms} atoms announced at line "
                                 f"{i + 1} but the file ends after {len(lines) - i - 1}")
            block = lines[i + 1:i + 1 + natoms]
            toks = [ln.split() for ln in block]
            for k, t in enumerate(toks):
                if len(t) != len(cols):
                    raise ValueError(f"{path}:{i + 2 + k}: expected {len(cols)} columns "
                                     f"({' '.join(cols)}), got {len(t)}: {block[k]!r}")
            arr = np.array(toks, dtype=object).reshape(natoms, len(cols)) if natoms else \
                np.empty((0, len(cols)), dtype=object)

            def column(name, typ):
                c = cols.index(name)
                try:
                    return arr[:, c].astype(typ)
                except (ValueError, TypeError):
                    for k in range(natoms):
                        try:
                            typ(arr[k, c])
                        except ValueError:
                            raise ValueError(f"{path}:{i + 2 + k}: column {name}: cannot read "
                                             f"{arr[k, c]!r}") from None
                    raise
            pos = np.stack([column(c, float) for c in names[:3]], axis=1) if natoms else \
                np.empty((0, 3))
            lo = bounds[:, 0].copy()
            box = bounds[:, 1] - bounds[:, 0]
            if names[3]:
                pos = lo + pos * box
            ids = column("id", np.int64) if "id" in cols else None
            types = column("type", np.int64) if "type" in cols else None
            if ids is not None:
                order = np.argsort(ids, kind="stable")
                pos, ids = pos[order], ids[order]
                types = types[order] if types is not None else None
            if not np.isfinite(pos).all():
                raise ValueError(f"{path}:{i + 2}: non-finite coordinates in the frame")
            periodic = np.array([f == "pp" for f in flags])
            frames.append(Frame(pos, box, lo, types=types, ids=ids, timestep=timestep,
                                periodic=periodic))
            i += 1 + natoms
            timestep, natoms, bounds = None, None, None
        else:                                   # ITEM: UNITS, ITEM: TIME, ...: skip
            i += 1
            while i < len(lines) and not lines[i].lstrip().startswith("ITEM:"):
                i += 1
    if not frames:
        raise ValueError(f"{path}:1: no LAMMPS dump frame (ITEM: ATOMS) found")
    return frames


def read_positions(path) -> list:
    """read_lammps_dump for files starting with 'ITEM:', read_xyz otherwise."""
    with _open(path) as fh:
        first = ""
        for line in fh:
            if line.strip():
                first = line.strip()
                break
    return read_lammps_dump(path) if first.startswith("ITEM:") else read_xyz(path)
