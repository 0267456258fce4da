"""Values -> UDF text.  Floats are written round-trip exact, so restart files continue runs
bit for bit.  Numeric arrays are formatted in C (orjson) and restructured with numpy, so bulk
numbers never go one by one through Python code."""
from __future__ import annotations

import numpy as np
import orjson

from .schema import Primitive, Select, Struct, leaf_count, leaf_kinds


_STEP = np.zeros(256, dtype=np.int8)
_STEP[ord("[")] = 1
_STEP[ord("]")] = -1


def _struct_affixes(t):
    """Per-leaf (prefix, suffix) brace strings of a numeric-flat struct, outer braces excluded."""
    pre, suf = [], []

    def walk(tt, depth):
        if isinstance(tt, Primitive):
            pre.append("")
            suf.append("")
            return
        first = len(pre)
        for m in tt.members:
            walk(m.type, depth + 1)
        if depth > 0:
            pre[first] = "{" + pre[first]
            suf[-1] = suf[-1] + "}"
    walk(t, 0)
    return pre, suf


def format_array(arr: np.ndarray, t, ndim: int, single: bool = False) -> str:
    """Format a numeric array stored as (n1..nd[, leaf_count]) in one vectorised pass.

    Numbers come from orjson (shortest round-trip repr, about 10x faster than '%r');
    the JSON brackets of struct elements are then turned into UDF braces with numpy.
    ``single``: float-typed leaves are written at single precision, as OCTA stores them.
    """
    shape = arr.shape[:ndim]
    if arr.size == 0 or 0 in shape:
        return "[]"
    kinds = leaf_kinds(t)
    if all(k == "int" for k in kinds):
        data = np.ascontiguousarray(arr, dtype=np.int64)
    else:
        data = np.ascontiguousarray(arr, dtype=np.float64)
        if not np.isfinite(data).all():
            raise ValueError("cannot write NaN or infinite values to a UDF file")
        if single and all(k == "float" for k in kinds):
            if data.size and np.abs(data).max() > np.finfo(np.float32).max:
                raise ValueError("a value is beyond the range of the define file's float type "
                                 "(|x| <= 3.4028235e+38)")
            data = data.astype(np.float32)
    b = np.frombuffer(orjson.dumps(data, option=orjson.OPT_SERIALIZE_NUMPY), dtype=np.uint8)
    depth = np.cumsum(_STEP[b], dtype=np.int8)
    opens = b == 91
    closes = b == 93
    commas = b == 44
    ins_pos = []
    ins_val = []
    if isinstance(t, Primitive):
        row_depth = ndim
    else:
        leaf = ndim + 1
        row_depth = leaf
        out = b.copy()
        lo = np.flatnonzero(opens & (depth == leaf))
        lc_ = np.flatnonzero(closes & (depth == leaf - 1))
        out[lo] = ord("{")
        out[lc_] = ord("}")
        pre, suf = _struct_affixes(t)
        if any(pre) or any(suf):
            n_el = lo.size
            lcount = len(pre)
            cm = np.flatnonzero(commas & (depth == leaf)).reshape(n_el, lcount - 1)
            starts = np.concatenate([lo[:, None] + 1, cm + 1], axis=1)
            ends = np.concatenate([cm, lc_[:, None]], axis=1)
            for j in range(lcount):
                for ch in suf[j]:
                    ins_pos.append(ends[:, j])
                    ins_val.append(ord(ch))
                for ch in pre[j]:
                    ins_pos.append(starts[:, j])
                    ins_val.append(ord(ch))
        b = out
    # the comma between rows becomes a newline (a blank separates values as well as a comma)
    if b.flags.writeable is False:
        b = b.copy()
    b[commas & (depth < row_depth)] = 10
    if ins_pos:
        pos = np.concatenate(ins_pos)
        val = np.concatenate([np.full(p.size, v, dtype=np.uint8) for p, v in zip(ins_pos, ins_val)])
        order = np.argsort(pos, kind="stable")
        b = np.insert(b, pos[order], val[order])
    return _Raw(b)


class _Raw:
    """Already-formatted ASCII bytes (kept as a numpy buffer: no extra copies)."""
    __slots__ = ("buf",)

    def __init__(self, buf):
        self.buf = buf

    def __str__(self):
        return self.buf.tobytes().decode("ascii")


def format_value(v, t, ndim: int, single: bool = False) -> str:
    out: list = []
    _emit(out, v, t, ndim, single)
    return "".join(map(str, out))


# numbers formatted at a time: format_array holds about 7 bytes of work per byte of text
# (the text and its masks, some 25 bytes a number), so a restart's velocity field (10^8
# numbers, 1.3 GB of text at 256 x 256 x 512) is formatted in blocks of rows, each written
# before the next is formed (_Blocks), and a row larger than a block in blocks of its own
# rows: the whole text is never held (2^18 numbers: about 45 MB of work)
CHUNK_NUMBERS = 1 << 18


class _Blocks:
    """A large array's text as blocks of rows formed one at a time when iterated (the same
    bytes as one format_array call: the blocks are joined by the separator between rows);
    ``write_pieces`` writes each block before the next is formatted."""
    __slots__ = ("v", "t", "ndim", "single", "rows", "sep")

    def __init__(self, v, t, ndim, single, rows, sep):
        self.v, self.t, self.ndim, self.single, self.rows, self.sep = v, t, ndim, single, rows, sep

    def __iter__(self):
        yield "["
        for s in range(0, len(self.v), self.rows):
            if s:
                yield self.sep
            if self.rows == 1 and self.ndim > 1 and self.v[s].size > CHUNK_NUMBERS:
                # a row larger than a block (a short first axis: the species of a
                # Concentration[]) is itself written in blocks of its rows
                inner: list = []
                _emit_array(inner, self.v[s], self.t, self.ndim - 1, self.single)
                yield inner[0]
            else:
                yield _Raw(format_array(self.v[s:s + self.rows], self.t, self.ndim,
                                        self.single).buf[1:-1])
        yield "]"

    def __str__(self):
        return "".join(map(str, self))


def _emit_array(out, v, t, ndim, single):
    """An array's text: one format_array call, or _Blocks of rows along its first axis when
    it has more than CHUNK_NUMBERS numbers."""
    per_row = v[0].size if len(v) else 0
    if len(v) < 2 or v.size <= CHUNK_NUMBERS or per_row == 0:
        out.append(format_array(v, t, ndim, single))
        return
    rows = max(1, CHUNK_NUMBERS // per_row)
    sep = "\n" if (ndim if isinstance(t, Primitive) else ndim + 1) > 1 else ","
    out.append(_Blocks(v, t, ndim, single, rows, sep))


def _emit(out, v, t, ndim, single):
    """Append the pieces of ``v``'s text to ``out`` (joined once: big arrays are not copied
    at every nesting level)."""
    if ndim:
        if isinstance(v, np.ndarray):
            _emit_array(out, v, t, ndim, single)
            return
        out.append("[")
        for i, x in enumerate(v):
            if i:
                out.append(",")
            _emit(out, x, t, ndim - 1, single)
        out.append("]")
        return
    if isinstance(t, Primitive):
        if t.name == "int":
            out.append(str(int(v)))
        elif t.name in ("float", "double"):
            out.append(repr(float(np.float32(v))) if single and t.name == "float"
                       else repr(float(v)))
        elif t.name == "bool":
            out.append("1" if v else "0")
        else:
            out.append('"' + str(v) + '"')
        return
    if isinstance(t, Select):
        out.append('"' + str(v) + '"')
        return
    if isinstance(v, np.ndarray):  # a numeric-flat struct held as leaves
        from .values import nest
        v = nest(v.ravel().tolist(), t)
    out.append("{")
    for i, (x, m) in enumerate(zip(v, t.members)):
        if i:
            out.append(",")
        _emit(out, x, m.type, m.ndim, single)
    out.append("}")


def item_pieces(items, schema_items, single: bool = False) -> list:
    """``name: value`` lines for a data block, as pieces: str, or _Raw bulk buffers."""
    out: list = []
    for name, v in items:
        m = schema_items[name]
        out.append(f"{name}{'[]' * m.ndim}:")
        _emit(out, v, m.type, m.ndim, single)
        out.append("\n")
    return out


def format_items(items, schema_items, single: bool = False) -> str:
    return "".join(map(str, item_pieces(items, schema_items, single)))


def write_pieces(fh, pieces) -> None:
    """Write pieces to a binary file, coalescing small strings."""
    small: list[str] = []
    for p in pieces:
        if isinstance(p, _Blocks):
            if small:
                fh.write("".join(small).encode("utf-8"))
                small = []
            write_pieces(fh, p)
        elif isinstance(p, _Raw):
            if small:
                fh.write("".join(small).encode("utf-8"))
                small = []
            fh.write(memoryview(p.buf))
        else:
            small.append(p)
    if small:
        fh.write("".join(small).encode("utf-8"))
