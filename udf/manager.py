"""``UDFManager``: the API users' OCTA scripts call, on top of our reader and writer.

    u = UDFManager("output.udf")
    u.get("mesh.NPX")                       # common (global_def) data, from any record
    u.jump(u.totalRecord() - 1)             # select a record
    u.get("Particles[].R")                  # list over particles of [x, y, z]
    u.get("Particles[].R.x", [3])           # '[]' filled from the indices list -> one value
    u.getArray("Particles[].R")             # the same as a numpy array
    u.put(0.5, "t"); u.newRecord("step 10"); u.write("out.udf")

Paths: ``name[i].member[].leaf``; ``[]`` means "every element" unless an index list is given,
in which case the indices fill the ``[]`` in order.  ``jump(-1)`` selects the common part.
"""
from __future__ import annotations

import os
import re

import numpy as np

from .errors import UDFError, raise_all
from .files import read_bytes
from .parser import build_schema, load_sections
from .schema import Primitive, Schema, Struct, leaf_count, leaf_slice
from .values import bind, default, from_python, nest
from .writer import item_pieces, write_pieces

_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[\s*-?\d*\s*\])*)$")
_BRACKET = re.compile(r"\[\s*(-?\d*)\s*\]")
ALL = object()


class AbsentItem(UDFError):
    """An item the schema defines but the file holds no value for."""


class Record:
    __slots__ = ("comment", "values")

    def __init__(self, comment: str = "", values: dict | None = None):
        self.comment = comment
        self.values = values if values is not None else {}


from .files import create_temporary as _temporary, fsync_directory, put_in_place, user_mode  # noqa: E402,F401


class TornTailWarning(UserWarning):
    """A UDF file ended in an incomplete record, which was left out."""


def atomic_write_text(path: str, text, place: bool = True):
    """Write ``text`` (a str, or a list of writer pieces) to ``path`` through a temporary
    file in the same directory (synced) and a rename: readers never see a half-written
    file.  ``place=False``: return the complete temporary file instead of renaming it (the
    caller puts it in place, e.g. after a companion file)."""
    fd, tmp = _temporary(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            if isinstance(text, str):
                fh.write(text.encode("utf-8"))
            else:
                write_pieces(fh, text)
            fh.flush()
            os.fsync(fh.fileno())
        if not place:
            return tmp
        put_in_place(tmp, path)
    except OSError as e:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise OSError(e.errno, e.strerror, os.fspath(path)) from None
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _no_repeat(name, seen: dict, file, line, col) -> None:
    """An item given twice is an error (the second would silently win)."""
    if name in seen:
        f, l0, c0 = seen[name]
        first = f"line {l0}" if f == file else f"{f}:{l0}"
        raise UDFError(f"{name!r} is given twice (first at {first})", file, line, col,
                       path=name)


class UDFManager:
    """A UDF document: schema, common data and records."""

    def __init__(self, path: str | None = None, *, schema_from: str | None = None):
        """Open ``path``; or, with ``schema_from``, start an empty document whose schema is
        that define file's (the way KAPSEL creates output.udf and restart.udf)."""
        self.path = path
        self.schema = Schema()
        self.schema_texts: list[str] = []   # def/global_def/unit source, for writing
        self.header_text = ""
        self.common: dict = {}
        self.common_where: dict = {}
        self.common_raw: dict = {}         # name -> parsed value, for value positions
        self.invalid_choices: dict = {}    # path -> UDFError of a select value not allowed
        self.records: list[Record] = []
        self.current = -1
        # OCTA stores `float` as single precision; output files may do the same (restart
        # files must not: they continue runs bit for bit).
        self.single_precision_records = False
        source = schema_from or path
        self.torn_tail = 0          # bytes of an incomplete last record that were dropped
        if source is None:
            return
        try:
            sections = load_sections(source)
        except UDFError as e:
            sections = self._without_torn_tail(source, e) if schema_from is None else None
            if sections is None:
                raise
        self.schema = build_schema(sections)
        for sec in sections:
            if sec.kind == "header" and not self.header_text:
                self.header_text = sec.text
            elif sec.kind in ("def", "global_def", "unit"):
                self.schema_texts.append(sec.text)
        if schema_from is not None:
            return
        errors = []      # every problem of the file, reported together
        for sec in sections:
            if sec.kind == "data":
                for name, ndim, g, line, col in sec.items:
                    try:
                        m = self._member(name, sec.file, line, col, want_global=True)
                        _no_repeat(name, self.common_where, sec.file, line, col)
                        self.common[name] = bind(m.type, m.ndim, g, name, sec.file,
                                                 self.invalid_choices)
                    except UDFError as e:
                        errors.append(e)
                        continue
                    self.common_where[name] = (sec.file, line, col)
                    self.common_raw[name] = g
            elif sec.kind == "record":
                rec = Record(sec.comment or "")
                seen = {}
                for name, ndim, g, line, col in sec.items:
                    try:
                        m = self._member(name, sec.file, line, col, want_global=False)
                        _no_repeat(name, seen, sec.file, line, col)
                        seen[name] = (sec.file, line, col)
                        rec.values[name] = bind(m.type, m.ndim, g, name, sec.file)
                    except UDFError as e:
                        errors.append(e)
                self.records.append(rec)
        raise_all(errors)
        self.current = 0 if self.records else -1

    def blank(self) -> "UDFManager":
        """A new empty document with this one's schema (UDFManager(schema_from=...) without
        reading the define file again: a document made once at start-up serves every
        later restart write, whatever happens to the file meanwhile)."""
        doc = UDFManager()
        doc.schema, doc.header_text = self.schema, self.header_text
        doc.schema_texts = list(self.schema_texts)
        return doc

    def _without_torn_tail(self, path, error):
        """A file whose last record is incomplete (a run stopped while appending it: power
        loss, a full disk) is read without that record, and says so (``torn_tail``, a
        warning); None if the error lies elsewhere."""
        import warnings
        try:
            data = read_bytes(path)
        except OSError:
            return None
        cut = data.rfind(b"\\begin{record}")
        if cut < 0 or error.file is None or os.path.normpath(error.file) != \
                os.path.normpath(path) or error.line is None:
            return None
        if error.line < data.count(b"\n", 0, cut) + 1 or \
                data.rstrip().endswith(b"\\end{record}"):
            return None                     # an error elsewhere, or in a complete record
        try:
            sections = load_sections(path, data=data[:cut])
        except UDFError:
            return None
        self.torn_tail = len(data) - cut
        warnings.warn(f"{path}: its last record is incomplete ({self.torn_tail} bytes, a run "
                      f"stopped while writing it); it is left out", TornTailWarning,
                      stacklevel=3)
        return sections

    def _member(self, name, file, line, col, want_global):
        m, is_global = self.schema.item(name)
        if m is None:
            import difflib
            known = list(self.schema.global_items if want_global else self.schema.record_items)
            close = difflib.get_close_matches(name, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise UDFError(f"{name!r} is not defined in the schema{hint}", file, line, col,
                           path=name)
        if is_global != want_global:
            where = "common data" if want_global else "a record"
            raise UDFError(f"{name!r} does not belong in {where}", file, line, col, path=name)
        return m

    # ------------------------------------------------------------------ records
    def totalRecord(self) -> int:
        return len(self.records)

    def jump(self, n: int) -> int:
        if n < -1 or n >= len(self.records):
            raise UDFError(f"no record {n}: the file has {len(self.records)} records")
        self.current = n
        return n

    def currentRecord(self) -> int:
        return self.current

    def newRecord(self, comment: str = "") -> int:
        self.records.append(Record(comment))
        self.current = len(self.records) - 1
        return self.current

    def eraseRecord(self, pos: int, num: int = 1) -> None:
        del self.records[pos:pos + num]
        self.current = min(self.current, len(self.records) - 1)

    # ------------------------------------------------------------------ paths
    def _parse(self, path: str, indices):
        ops = []
        fill = list(indices) if indices is not None else None
        parts = path.strip().split(".")
        for part in parts:
            m = _PART.match(part.strip())
            if not m:
                raise UDFError(f"malformed path {path!r} (at {part!r})", path=path)
            ops.append(("member", m.group(1)))
            for b in _BRACKET.findall(m.group(2)):
                if b == "":
                    if fill:
                        ops.append(("idx", int(fill.pop(0))))
                    else:
                        ops.append(("all",))
                else:
                    ops.append(("idx", int(b)))
        return ops

    def _root(self, name, path, create=False):
        m, is_global = self.schema.item(name)
        if m is None:
            raise UDFError(f"no such item {name!r} in the schema (path {path!r})", path=path)
        if is_global:
            store = self.common
        else:
            if self.current < 0:
                raise UDFError(f"{path!r} is record data: jump to a record first "
                               f"({len(self.records)} records)", path=path)
            store = self.records[self.current].values
        if name not in store:
            if not create and (is_global or self.path is not None):
                where = "common data" if is_global else f"record {self.current}"
                raise AbsentItem(f"{name!r} is absent from {self.path or 'this document'} "
                               f"({where}): the schema defines it but the file holds no "
                               f"value; put() one first", path=path)
            store[name] = default(m.type, m.ndim)
        return store, m

    def _walk(self, path, indices):
        """Yield (value, type, ndim) at the end of the path, mapping over '[]'."""
        ops = self._parse(path, indices)
        if self.invalid_choices:
            self._check_choices(ops, path)
        store, m = self._root(ops[0][1], path)
        return self._apply(store[ops[0][1]], m.type, m.ndim, ops[1:], path)

    def _check_choices(self, ops, path):
        """A select value outside its choices is an error when it is read (the reader
        kept it so that unused branches of an input may hold stale values)."""
        m, is_global = self.schema.item(ops[0][1])
        if not is_global:
            return
        want = _canonical(ops)
        for bad, err in self.invalid_choices.items():
            have = _canonical(self._parse(bad, None))
            n = min(len(want), len(have))
            if all(a == b or "all" in (a[0], b[0]) for a, b in zip(want[:n], have[:n])):
                raise err

    def value_where(self, path: str):
        """(file, line, column) of the value at ``path`` in the common data as written in
        the file (the innermost value the path reaches; a numeric array lifted out as a
        whole gives its start); None if the item is not in the file."""
        ops = self._parse(path, None)
        name = ops[0][1]
        if name not in self.common_raw:
            return None
        file = self.common_where[name][0]
        g = self.common_raw[name]
        m, _ = self.schema.item(name)
        t, ndim = m.type, m.ndim
        for op in ops[1:]:
            items = getattr(g, "items", None)
            kind = getattr(g, "kind", None)
            if op[0] == "member":
                if ndim or not isinstance(t, Struct) or t.index(op[1]) is None:
                    break
                i = t.index(op[1])
                mem = t.members[i]
                if kind == "{" and i < len(items):
                    g = items[i]
                elif len(t.members) != 1:
                    break
                t, ndim = mem.type, mem.ndim
            elif op[0] == "idx" and kind == "[" and ndim and -len(items) <= op[1] < len(items):
                g, ndim = items[op[1]], ndim - 1
            else:
                break
        line, col = getattr(g, "line", None), getattr(g, "column", None)
        if line is None:
            return None
        return file, line, col

    def _apply(self, v, t, ndim, ops, path):
        if isinstance(v, np.ndarray):
            return self._apply_array(v, t, ndim, ops, path)
        for k, op in enumerate(ops):
            if op[0] == "idx":
                if not ndim:
                    raise UDFError(f"{path!r}: not an array here", path=path)
                i = op[1]
                if not -len(v) <= i < len(v):
                    raise UDFError(f"{path!r}: index {i} out of range (size {len(v)})", path=path)
                v, ndim = v[i], ndim - 1
            elif op[0] == "all":
                if not ndim:
                    raise UDFError(f"{path!r}: not an array here", path=path)
                return ("map", [self._apply(x, t, ndim - 1, ops[k + 1:], path) for x in v])
            else:
                if ndim:
                    raise UDFError(f"{path!r}: {op[1]!r} is reached through an array; "
                                   f"give an index or []", path=path)
                if not isinstance(t, Struct) or t.index(op[1]) is None:
                    raise UDFError(f"{path!r}: no member {op[1]!r} here", path=path)
                i = t.index(op[1])
                mem = t.members[i]
                if isinstance(v, np.ndarray):
                    return self._apply_array(v, t, 0, ops[k:], path)
                v, t, ndim = v[i], mem.type, mem.ndim
            if isinstance(v, np.ndarray):
                return self._apply_array(v, t, ndim, ops[k + 1:], path)
        return ("leaf", v, t, ndim)

    def _apply_array(self, arr, t, ndim, ops, path):
        index = []
        mapped = 0
        k = 0
        while k < len(ops) and ops[k][0] in ("idx", "all"):
            if len(index) >= ndim:
                raise UDFError(f"{path!r}: too many indices", path=path)
            if ops[k][0] == "idx":
                n = arr.shape[len(index)]
                if not -n <= ops[k][1] < n:
                    raise UDFError(f"{path!r}: index {ops[k][1]} out of range (size {n})",
                                   path=path)
                index.append(ops[k][1])
            else:
                index.append(slice(None))
                mapped += 1
            k += 1
        names = [op[1] for op in ops[k:]]
        if any(op[0] != "member" for op in ops[k:]):
            raise UDFError(f"{path!r}: arrays inside numeric elements are not supported",
                           path=path)
        remaining = ndim - len(index)
        if names and remaining:
            raise UDFError(f"{path!r}: {names[0]!r} is reached through an array; give an "
                           f"index or []", path=path)
        try:
            off, cnt, sub = leaf_slice(t, names)
        except KeyError as e:
            raise UDFError(f"{path!r}: no member {e.args[0]!r} here", path=path) from None
        index += [slice(None)] * remaining
        if not isinstance(t, Primitive):
            index.append(off if isinstance(sub, Primitive) else slice(off, off + cnt))
        return ("array", arr, tuple(index), sub, remaining, mapped)

    # ------------------------------------------------------------------ get / put
    def get(self, path: str, *args):
        """get(path[, indices][, unit]) -> Python value (lists for structs and arrays)."""
        indices, unit = _split_args(args)
        res = self._walk(path, indices)
        value, t = _to_python(res)
        if unit is not None:
            from .units import convert
            src = self._unit_of(path)
            value = convert(value, src, unit, self)
        return value

    def getArray(self, path: str, indices=None) -> np.ndarray:
        res = self._walk(path, indices)
        if res[0] == "array":
            _, arr, index, sub, remaining, mapped = res
            return np.array(arr[index])
        return np.array(_to_python(res)[0])

    def size(self, path: str, indices=None) -> int:
        """Length of the array at ``path`` (``name`` or ``name[]`` both work); an array
        item the file does not hold has none (0)."""
        try:
            res = self._walk(path, indices)
        except AbsentItem:
            m, _ = self.schema.item(self._parse(path, indices)[0][1])
            if m is not None and m.ndim:
                return 0
            raise
        if res[0] == "array":
            _, arr, index, sub, remaining, mapped = res
            part = arr[index]
            if not (remaining or mapped) or part.ndim == 0:
                raise UDFError(f"{path!r} is not an array", path=path)
            return int(part.shape[0])
        if res[0] == "map":
            return len(res[1])
        _, v, t, ndim = res
        if not ndim:
            raise UDFError(f"{path!r} is not an array", path=path)
        return len(v)

    def put(self, value, path: str, indices=None, *, copy: bool = True) -> None:
        """put(value, path[, indices]): set a value; putting at index == size appends.
        ``copy=False`` hands a numpy array of the item's dtype over without copying it (the
        caller must not change it afterwards: a restart's fields, hundreds of MB)."""
        ops = self._parse(path, indices)
        if any(op[0] == "all" for op in ops):
            # put of a whole array at the end of the path: "Particles[]" -> the array
            if ops[-1][0] == "all" and not any(op[0] == "all" for op in ops[:-1]):
                ops = ops[:-1]
            else:
                raise UDFError(f"put({path!r}): give indices for every []", path=path)
        name = ops[0][1]
        store, m = self._root(name, path, create=True)
        if len(ops) == 1:
            store[name] = from_python(m.type, m.ndim, value, path, copy)
            return
        store[name] = self._put(store[name], m.type, m.ndim, ops[1:], value, path, copy)

    def _put(self, v, t, ndim, ops, value, path, copy=True):
        op = ops[0]
        if op[0] == "idx":
            if not ndim:
                raise UDFError(f"{path!r}: not an array here", path=path)
            i = op[1]
            n = len(v)
            if i == n or (i > n):  # extend
                grow = i + 1 - n
                if isinstance(v, np.ndarray):
                    pad = np.zeros((grow,) + v.shape[1:], dtype=v.dtype)
                    if v.ndim > 1 and v.shape[1:] == (0,) * (v.ndim - 1):
                        pad = None
                    v = np.concatenate([v, pad]) if pad is not None else v
                    if pad is None:
                        leaves = leaf_count(t)
                        shape = (grow,) + ((leaves,) if not isinstance(t, Primitive) else ())
                        if ndim > 1:
                            raise UDFError(f"{path!r}: cannot grow a multi-dimensional array "
                                           f"element by element; put the whole array", path=path)
                        v = np.zeros(shape, dtype=v.dtype)
                else:
                    v = v + [default(t, ndim - 1) for _ in range(grow)]
            elif i < -n:
                raise UDFError(f"{path!r}: index {i} out of range", path=path)
            if isinstance(v, np.ndarray):
                sub = v[i]
                rest = ops[1:]
                if not rest:
                    v[i] = _leaves_of(value, t, ndim - 1, path, sub.shape)
                    return v
                res = self._apply_array(v, t, ndim, ops, path)
                _, arr, index, subt, remaining, mapped = res
                arr[index] = _leaves_of(value, subt, remaining, path, arr[index].shape)
                return v
            if len(ops) == 1:
                v[i] = from_python(t, ndim - 1, value, path, copy)
            else:
                v[i] = self._put(v[i], t, ndim - 1, ops[1:], value, path, copy)
            return v
        # member
        if ndim:
            raise UDFError(f"{path!r}: {op[1]!r} is reached through an array; give an index",
                           path=path)
        if not isinstance(t, Struct) or t.index(op[1]) is None:
            raise UDFError(f"{path!r}: no member {op[1]!r} here", path=path)
        i = t.index(op[1])
        mem = t.members[i]
        if len(ops) == 1:
            v[i] = from_python(mem.type, mem.ndim, value, path, copy)
        else:
            v[i] = self._put(v[i], mem.type, mem.ndim, ops[1:], value, path, copy)
        return v

    # ------------------------------------------------------------------ units
    def _unit_of(self, path: str) -> str | None:
        ops = self._parse(path, None)
        m, _ = self.schema.item(ops[0][1])
        unit = m.unit
        t = m.type
        for op in ops[1:]:
            if op[0] == "member" and isinstance(t, Struct):
                mem = t.members[t.index(op[1])]
                unit = mem.unit or (mem.type.unit if isinstance(mem.type, Struct) else None) \
                    or unit
                t = mem.type
        return unit

    def where(self, name: str) -> str:
        """'file:line:col' where the common item ``name`` was read, for messages."""
        if name in self.common_where:
            f, line, col = self.common_where[name]
            return f"{f}:{line}:{col}"
        return self.path or ""

    # ------------------------------------------------------------------ writing
    def pieces(self, record=None) -> list:
        parts = []
        if self.header_text:
            parts.append(self.header_text + "\n")
        parts.extend(t + "\n" for t in self.schema_texts)
        if self.common:
            order = [n for n in self.schema.global_items if n in self.common]
            parts.append("\\begin{data}\n")
            parts.extend(item_pieces([(n, self.common[n]) for n in order],
                                     self.schema.global_items))
            parts.append("\\end{data}\n")
        recs = self.records if record is None else [self.records[record]]
        for rec in recs:
            parts.extend(self.record_pieces(rec))
        return parts

    def text(self, record=None) -> str:
        return "".join(map(str, self.pieces(record)))

    def record_pieces(self, rec: Record) -> list:
        order = [n for n in self.schema.record_items if n in rec.values]
        comment = rec.comment.replace('"', "'")
        return (["\\begin{record}{\"%s\"}\n\\begin{data}\n" % comment]
                + item_pieces([(n, rec.values[n]) for n in order], self.schema.record_items,
                              self.single_precision_records)
                + ["\\end{data}\n\\end{record}\n"])

    def record_text(self, rec: Record) -> str:
        return "".join(map(str, self.record_pieces(rec)))

    def write(self, file: str | None = None, record=None, mode=None, place: bool = True):
        """Write the document (atomically: temporary file, synced, then rename;
        ``place=False``: return the temporary file, see :func:`atomic_write_text`)."""
        target = file or self.path
        if not target:
            raise UDFError("write(): no file name given")
        try:
            if record is None and self._large():
                tmp = _write_in_two_processes(self, target, place)
            else:
                tmp = atomic_write_text(target, self.pieces(record), place)
        except ValueError as e:
            raise UDFError(f"cannot write {target}: {e}") from None
        if file and place:
            self.path = file
        return tmp

    def _large(self) -> bool:
        if len(self.records) < 8 or (os.cpu_count() or 1) < 2 or not hasattr(os, "fork"):
            return False
        n = 0
        for rec in self.records:
            for v in rec.values.values():
                n += v.size if isinstance(v, np.ndarray) else 1
        return n > PARALLEL_WRITE_NUMBERS


PARALLEL_WRITE_NUMBERS = 4_000_000


def _write_in_two_processes(doc: "UDFManager", target: str, place: bool = True):
    """Format the records in two processes: a forked child writes the second half to its own
    temporary file, the parent the head and first half; the kernel then appends the child's
    file (copy_file_range) and the result is renamed into place."""
    half = len(doc.records) // 2
    fd_c, tmp_c = _temporary(target)
    try:
        pid = os.fork()
        if pid == 0:
            code = 0
            try:
                with os.fdopen(fd_c, "wb") as fh:
                    for rec in doc.records[half:]:
                        write_pieces(fh, doc.record_pieces(rec))
            except BaseException:
                code = 1
            os._exit(code)
        os.close(fd_c)
        recs = doc.records
        try:
            doc.records = recs[:half]
            head = doc.pieces()
        finally:
            doc.records = recs
        fd, tmp = _temporary(target)
        try:
            with os.fdopen(fd, "wb") as fh:
                write_pieces(fh, head)
                fh.flush()
                _, status = os.waitpid(pid, 0)
                if status != 0:
                    raise ValueError("formatting the second half of the records failed")
                with open(tmp_c, "rb") as src:
                    size = os.fstat(src.fileno()).st_size
                    copied = 0
                    while copied < size:
                        n = os.copy_file_range(src.fileno(), fh.fileno(), size - copied)
                        if n == 0:
                            break
                        copied += n
                fh.flush()
                os.fsync(fh.fileno())
            if not place:
                return tmp
            put_in_place(tmp, target)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
    finally:
        if os.path.exists(tmp_c):
            os.unlink(tmp_c)


def _canonical(ops):
    return [op if op[0] != "member" else ("member", op[1]) for op in ops]


def _split_args(args):
    indices = unit = None
    for a in args:
        if isinstance(a, str):
            unit = a
        elif a is not None:
            indices = list(a) if not isinstance(a, int) else [a]
    return indices, unit


def _to_python(res):
    kind = res[0]
    if kind == "map":
        vals = [_to_python(x)[0] for x in res[1]]
        return vals, None
    if kind == "leaf":
        _, v, t, ndim = res
        if isinstance(v, list):
            return _deep_copy(v), t
        return v, t
    _, arr, index, sub, remaining, mapped = res
    part = arr[index]
    if isinstance(sub, Primitive):
        out = part.tolist()
        if sub.name == "int":
            out = _ints(out)
        return out, sub
    lc = leaf_count(sub)
    flat = part.reshape(-1, lc)
    rows = [nest(r, sub) for r in flat.tolist()]
    shape = part.shape[:-1]
    return _reshape(rows, shape), sub


def _ints(x):
    if isinstance(x, list):
        return [_ints(y) for y in x]
    return int(x)


def _reshape(rows, shape):
    if not shape:
        return rows[0]
    if len(shape) == 1:
        return rows
    step = int(np.prod(shape[1:]))
    return [_reshape(rows[i * step:(i + 1) * step], shape[1:]) for i in range(shape[0])]


def _deep_copy(v):
    if isinstance(v, list):
        return [_deep_copy(x) for x in v]
    if isinstance(v, np.ndarray):
        return v.copy()
    return v


def _leaves_of(value, t, ndim, path, shape):
    """Flatten a user value for assignment into a numeric array slot of ``shape``."""
    if isinstance(value, np.ndarray):
        arr = value
    else:
        from .values import flatten_leaves
        if isinstance(value, (list, tuple)):
            arr = np.array(flatten_leaves(list(value)), dtype=float)
        else:
            if isinstance(value, str):
                raise UDFError(f"{path!r}: expected a number, got {value!r}", path=path)
            arr = np.array(value, dtype=float)
    try:
        return np.asarray(arr, dtype=float).reshape(shape)
    except ValueError:
        raise UDFError(f"{path!r}: value has {np.size(arr)} numbers, expected "
                       f"{int(np.prod(shape))}", path=path) from None
