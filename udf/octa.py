"""OCTA's Python ``UDFManager`` API over :class:`udf.manager.UDFManager`, so that users'
scripts (``from UDFManager import *``, the top-level module that re-exports this one) run
unchanged (FORMAT.md "OCTA's Python UDFManager").

Differences from :class:`udf.UDFManager` (which kapsel-py uses internally, with numpy
arrays): values come back as plain Python lists, as OCTA returns them, also for arrays of
structs whose members differ in type (``object_type.spherical_particle.Particle_spec[]`` is
a list of lists); errors are ``RuntimeError`` (bad paths, files) or ``IndexError``
(record numbers, indices), as OCTA raises them; ``jump`` past the last record goes to the
last one and returns its number, so ``if u.jump(t) == t`` tests whether record t exists.
"""
from __future__ import annotations

import os
import re

import numpy as np

from .errors import UDFError
from .manager import UDFManager as _Base

__all__ = ["UDFManager", "Location", "rlocation"]


class Location:
    """A UDF path with the indices of its ``[]`` (OCTA's location object).

    ``Location("Particles[].R", [3]).str()`` is ``"Particles[3].R"``; ``sub(name)`` goes
    one member down, ``sub(name, i)`` into element i of an array member; ``next()`` moves
    the last index on by one.
    """

    def __init__(self, path: str = "", index=None):
        self.path = str(path)
        self.index = [int(i) for i in (index or [])]

    def str(self) -> str:
        idx = list(self.index)
        out = []
        for part in re.split(r"(\[\])", self.path):
            if part == "[]" and idx:
                out.append(f"[{idx.pop(0)}]")
            else:
                out.append(part)
        return "".join(out)

    def sub(self, name: str, *index) -> "Location":
        path = f"{self.path}.{name}" if self.path else name
        if index:
            path += "[]" * len(index)
        return Location(path, self.index + [int(i) for i in index])

    def next(self) -> "Location":
        if not self.index:
            raise IndexError(f"{self.path!r} has no index to advance")
        self.index[-1] += 1
        return self

    def __str__(self) -> str:
        return self.str()

    def __repr__(self) -> str:
        return f"Location({self.path!r}, {self.index!r})"


def rlocation(path: str, indices=None) -> Location:
    """The location of ``path`` with its ``[]`` filled from ``indices``."""
    return Location(path, indices)


def _plain(v):
    """numpy arrays and scalars inside a value -> Python lists and numbers."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, np.generic):
        return v.item()
    return v


def _path_args(path, args):
    """(path string, indices, unit) from OCTA's (path[, location][, unit]) arguments; a
    Location may stand for the path or for the indices."""
    if isinstance(path, Location):
        path = path.str()
    indices = unit = None
    for a in args:
        if a is None:
            continue
        if isinstance(a, Location):
            indices = a.index
        elif isinstance(a, str):
            if a.strip():
                unit = a
        elif isinstance(a, (int, np.integer)):
            indices = [int(a)]
        else:
            indices = [int(i) for i in a]
    return str(path), indices, unit


def _octa_errors(fn):
    def wrapped(*args, **kw):
        try:
            return fn(*args, **kw)
        except UDFError as e:
            msg = str(e)
            if "out of range" in msg or "no record" in msg:
                raise IndexError(msg) from None
            raise RuntimeError(msg) from None
    wrapped.__name__ = fn.__name__
    wrapped.__doc__ = fn.__doc__
    return wrapped


class UDFManager(_Base):
    """OCTA's UDFManager: ``UDFManager(path)`` opens a UDF file (its ``\\include``d
    definitions too); see the module docstring."""

    @_octa_errors
    def __init__(self, path: str, *args, **kw):
        if not os.path.exists(str(path)):
            raise RuntimeError(f"{path}: no such file")
        super().__init__(str(path))

    # ------------------------------------------------------------------ values
    @_octa_errors
    def get(self, path, *args):
        """get(path[, location][, unit]): the value at the current record (lists for
        structs and arrays); ``[]`` filled from the location's indices."""
        p, indices, unit = _path_args(path, args)
        if unit is None:
            return _plain(super().get(p, indices))
        return _plain(super().get(p, indices, unit))

    @_octa_errors
    def getArray(self, path, *args):
        """getArray(path[, location][, unit]): an array (or struct) as nested lists; an
        array of structs gives one list per element."""
        return self.get(path, *args)

    @_octa_errors
    def put(self, value, path, *args):
        """put(value, path[, location][, unit]): the value first, as OCTA has it."""
        p, indices, unit = _path_args(path, args)
        if unit is not None:
            from .units import convert
            src = self._unit_of(p)
            if not src:
                raise RuntimeError(f"{p!r} has no unit; cannot put a value in [{unit}]")
            value = convert(value, unit.strip().strip("[]"), src, self)
        super().put(value, p, indices)

    @_octa_errors
    def size(self, path, *args):
        p, indices, _ = _path_args(path, args)
        return super().size(p, indices)

    # ------------------------------------------------------------------ records
    def jump(self, n: int) -> int:
        """Make record n current (-1: the common part); past the last record, the last
        one; returns the record reached."""
        n = int(n)
        if n < -1:
            raise IndexError(f"no record {n}")
        if n >= self.totalRecord():
            n = self.totalRecord() - 1
        self.current = n
        return n

    def eraseRecord(self, record_pos: int = -1, record_num: int = 1) -> None:
        """Delete ``record_num`` records from ``record_pos`` (default: the current one)."""
        pos = self.current if record_pos is None or record_pos < 0 else int(record_pos)
        if not 0 <= pos < self.totalRecord():
            raise IndexError(f"no record {pos}: the file has {self.totalRecord()} records")
        super().eraseRecord(pos, int(record_num))

    def write(self, filename: str | None = None, record: int = 0, mode: int = 0,
              define=None) -> None:
        """Save.  ``record``: 0 all records, 1 the current record only, -1 none (the
        common part); ``mode``: 0 overwrite, 1 append the records to the file."""
        if define not in (None, ""):
            raise RuntimeError("write(define=...) is not supported by kapsel-py's UDFManager")
        target = filename or self.path
        if not target:
            raise RuntimeError("write(): no file name given")
        if record == 0:
            recs = self.records
        elif record == 1:
            recs = [self.records[self.current]] if self.current >= 0 else []
        elif record == -1:
            recs = []
        else:
            raise RuntimeError(f"write(record={record!r}): expected 0, 1 or -1")
        from .manager import atomic_write_text
        if mode == 1 and os.path.exists(target):
            from .files import open_regular
            with open_regular(target, "r", encoding="utf-8") as fh:
                text = fh.read()
            atomic_write_text(target, [text] + [p for r in recs for p in self.record_pieces(r)])
        elif mode in (0, 1):
            keep = self.records
            try:
                self.records = list(recs)
                atomic_write_text(target, self.pieces())
            except ValueError as e:
                raise RuntimeError(f"cannot write {target}: {e}") from None
            finally:
                self.records = keep
        else:
            raise RuntimeError(f"write(mode={mode!r}): expected 0 or 1")
        if filename:
            self.path = filename

    # ------------------------------------------------------------------ file facts
    def _header(self, name: str) -> str:
        m = re.search(r'\b%s\s*:\s*"([^"]*)"' % re.escape(name), self.header_text or "")
        return m.group(1) if m else ""

    def getEngineName(self) -> str:
        """The header's EngineType, e.g. ``"Kapsel"``."""
        return self._header("EngineType")

    def getEngineVersion(self) -> str:
        """The header's EngineVersion, e.g. ``"v3.4"``."""
        return self._header("EngineVersion")

    def udfFile(self) -> str:
        return os.path.abspath(self.path) if self.path else ""

    def udfDirectory(self) -> str:
        return os.path.dirname(self.udfFile())
