"""Typed values: generic parsed data -> Python/numpy values positional against the schema.

Storage rules:
* int / float / double -> int / float; string and select -> str.
* struct -> list of member values, in member order.
* array -> list of element values, except arrays of numeric-flat elements, which are one
  numpy array of shape (n1, ..., nd) for bare numbers or (n1, ..., nd, leaf_count) for
  structs (float64; int64 when every leaf is an int).
"""
from __future__ import annotations

import math
import re

import numpy as np

from .errors import UDFError
from .parser import Bulk, Group
from .schema import Primitive, Select, Struct, leaf_count, leaf_kinds


INT_MIN, INT_MAX = -2 ** 31, 2 ** 31 - 1   # OCTA stores int as a C int
FLOAT_MAX = float(np.finfo(np.float32).max)  # OCTA stores float as a C float


_CONTINUATION = re.compile(r"\\\r?\n")


def string_value(tok) -> str:
    """The text of a STRING token: quotes removed, backslash-newline continuations joined
    (OCTA's old define.udf files continue long descriptions that way)."""
    s = str(tok)[1:-1]
    return _CONTINUATION.sub("", s) if "\\" in s else s


def _where(g):
    return getattr(g, "line", None), getattr(g, "column", None)


def _describe(g) -> str:
    if isinstance(g, Group):
        return "a {...} group" if g.kind == "{" else "an array [...]"
    if isinstance(g, Bulk):
        return "a numeric array"
    return repr(str(g)) if getattr(g, "type", "") != "STRING" else str(g)


def _err(msg, g, file, path):
    line, col = _where(g)
    return UDFError(f"{msg} (at {path})", file, line, col, path=path)


def bind(t, ndim: int, g, path: str, file: str, lazy: dict | None = None):
    """Bind generic value ``g`` to type ``t`` with ``ndim`` array dimensions.

    ``lazy``: a dict that collects, by path, the errors of select values that are not among
    the choices, instead of raising them (the value is kept as written): a select in a
    branch the input does not choose may hold a stale or empty value, and only the reader
    of that path should be told (UDFManager.get raises them)."""
    if ndim:
        return _bind_array(t, ndim, g, path, file, lazy)
    if isinstance(t, Primitive):
        if t.name in ("int", "float", "double"):
            if getattr(g, "type", None) != "NUMBER":
                raise _err(f"expected a number ({t.name}), found {_describe(g)}", g, file, path)
            s = str(g)
            if t.name == "int":
                try:
                    v = int(s)
                except ValueError:
                    f = float(s)
                    if not math.isfinite(f) or f != int(f):
                        raise _err(f"expected an integer, found {s}", g, file, path) from None
                    v = int(f)
                if not INT_MIN <= v <= INT_MAX:
                    raise _err(f"the integer {s} is out of range (a UDF int is 32-bit: "
                               f"{INT_MIN}..{INT_MAX})", g, file, path)
                return v
            v = float(s)
            if not math.isfinite(v):
                raise _err(f"the number {s} is beyond the range of a double", g, file, path)
            if t.name == "float" and abs(v) > FLOAT_MAX:
                raise _err(f"the number {s} is beyond the range of a float (|x| <= "
                           f"{FLOAT_MAX:.8g}), the type the define file gives it", g, file,
                           path)
            return v
        if t.name == "bool":
            if getattr(g, "type", None) == "NUMBER":
                return bool(int(float(str(g))))
            if getattr(g, "type", None) == "STRING":
                return string_value(g).lower() in ("true", "on", "yes", "1")
        if getattr(g, "type", None) != "STRING":
            raise _err(f"expected a string, found {_describe(g)}", g, file, path)
        return string_value(g)
    if isinstance(t, Select):
        if getattr(g, "type", None) != "STRING":
            raise _err(f"expected one of {', '.join(t.choices)}, found {_describe(g)}",
                       g, file, path)
        s = string_value(g)
        if s not in t.choices:
            e = _err(f"unknown choice {s!r}; allowed: {', '.join(t.choices)}", g, file, path)
            if lazy is None:
                raise e
            lazy[path] = e
        return s
    if isinstance(t, Struct):
        if isinstance(g, Group) and g.kind == "{":
            if len(g.items) != len(t.members):
                raise _err(f"expected {len(t.members)} values for {t.describe()} "
                           f"({', '.join(m.name for m in t.members)}), found {len(g.items)}",
                           g, file, path)
            return [bind(m.type, m.ndim, item, f"{path}.{m.name}", file, lazy)
                    for m, item in zip(t.members, g.items)]
        if len(t.members) == 1:  # a one-member struct may be written bare
            m = t.members[0]
            return [bind(m.type, m.ndim, g, f"{path}.{m.name}", file, lazy)]
        raise _err(f"expected {{...}} with {len(t.members)} values for {t.describe()}, "
                   f"found {_describe(g)}", g, file, path)
    raise AssertionError(t)


def flatten_leaves(v) -> list:
    if isinstance(v, list):
        out = []
        for x in v:
            out.extend(flatten_leaves(x))
        return out
    return [v]


def _dtype(t):
    kinds = leaf_kinds(t)
    return np.int64 if all(k == "int" for k in kinds) else np.float64


def _bind_array(t, ndim, g, path, file, lazy=None):
    lc = leaf_count(t)
    if isinstance(g, Bulk):
        if lc is None:
            raise _err(f"expected an array of {t.describe()}, found numbers only", g, file, path)
        return _bulk_to_array(t, ndim, lc, g, path, file)
    if not (isinstance(g, Group) and g.kind == "["):
        raise _err(f"expected an array [...], found {_describe(g)}", g, file, path)
    elems = [_bind_array(t, ndim - 1, x, f"{path}[{i}]", file, lazy) if ndim > 1
             else bind(t, 0, x, f"{path}[{i}]", file, lazy) for i, x in enumerate(g.items)]
    if lc is None:
        return elems
    # numeric-flat: one numpy array when the nesting is regular
    if ndim == 1:
        rows = [flatten_leaves(e) for e in elems]
        arr = np.array(rows, dtype=_dtype(t)).reshape(len(elems), lc)
        return arr[:, 0] if isinstance(t, Primitive) else arr
    try:
        arr = np.array([np.asarray(e) for e in elems], dtype=_dtype(t))
    except ValueError:
        raise _err("the array is ragged (its rows differ in length)", g, file, path) from None
    if arr.size == 0:
        shape = (len(elems),) + (0,) * (ndim - 1) + (() if isinstance(t, Primitive) else (lc,))
        return np.zeros(shape, dtype=_dtype(t))
    return arr


def _bulk_to_array(t, ndim, lc, g: Bulk, path, file):
    counts = g.level_counts
    if len(counts) > ndim + 1:
        raise _err(f"array nested {len(counts) - 1} deep, expected {ndim}", g, file, path)
    outer = []
    prev = 1
    for k in range(2, ndim + 1):
        c = int(counts[k]) if k < len(counts) else 0
        if prev and c % prev:
            raise _err("the array is ragged (its rows differ in length)", g, file, path)
        outer.append(c // prev if prev else 0)
        prev = c
    total = g.numbers.size
    block = prev * lc
    if block == 0:
        if total:
            raise _err("malformed nested array", g, file, path)
        inner = 0
    else:
        if total % block:
            raise _err(f"the number of values ({total}) does not fill whole elements of "
                       f"{lc} values each", g, file, path)
        inner = total // block
    shape = tuple(outer) + (inner,) + (() if isinstance(t, Primitive) else (lc,))
    arr = g.numbers.reshape(shape)
    if arr.size and not np.isfinite(arr).all():
        raise _err("a number is beyond the range of a double", g, file, path)
    if arr.size and not isinstance(t, Select):
        kinds = leaf_kinds(t)
        if "float" in kinds:
            cols = arr if isinstance(t, Primitive) else \
                arr[..., [i for i, k in enumerate(kinds) if k == "float"]]
            if np.abs(cols).max() > FLOAT_MAX:
                raise _err(f"a number is beyond the range of a float (|x| <= {FLOAT_MAX:.8g}), "
                           f"the type the define file gives it", g, file, path)
    if _dtype(t) is np.int64:
        if not g.integral and np.any(arr != np.round(arr)):
            raise _err("expected integers, found a fractional value", g, file, path)
        if arr.size and not (INT_MIN <= arr.min() and arr.max() <= INT_MAX):
            raise _err(f"an integer is out of range (a UDF int is 32-bit: {INT_MIN}..{INT_MAX})",
                       g, file, path)
        arr = arr.astype(np.int64)
    return arr


# ---------------------------------------------------------------------------------------
def default(t, ndim: int):
    """The value a freshly created item holds: zeros, empty strings, empty arrays."""
    if ndim:
        lc = leaf_count(t)
        if lc is not None:
            shape = (0,) * ndim + (() if isinstance(t, Primitive) else (lc,))
            return np.zeros(shape, dtype=_dtype(t))
        return []
    if isinstance(t, Primitive):
        return {"int": 0, "float": 0.0, "double": 0.0, "bool": False}.get(t.name, "")
    if isinstance(t, Select):
        return t.choices[0]
    return [default(m.type, m.ndim) for m in t.members]


def from_python(t, ndim: int, v, path: str, copy: bool = True):
    """Convert a user value (lists, numbers, strings, numpy) to storage, checking types.
    ``copy`` False: a numpy array of the storage's dtype is kept as it is (the caller hands
    it over and does not change it afterwards)."""
    if ndim:
        lc = leaf_count(t)
        if lc is not None:
            try:
                arr = np.array(v, dtype=_dtype(t)) if not isinstance(v, np.ndarray) \
                    else v.astype(_dtype(t), copy=copy)
            except (TypeError, ValueError):
                raise UDFError(f"{path}: expected a numeric array, got {type(v).__name__}",
                               path=path) from None
            prim = isinstance(t, Primitive)
            if arr.size == 0:
                return arr.reshape((0,) * ndim + (() if prim else (lc,)))
            if not prim and arr.ndim == ndim and lc == 1:
                arr = arr[..., None]
            if arr.ndim != ndim + (0 if prim else 1) or (not prim and arr.shape[-1] != lc):
                want = f"shape (n1..n{ndim}" + ("" if prim else f", {lc}") + ")"
                raise UDFError(f"{path}: expected a numeric array of {want}, got shape "
                               f"{arr.shape}", path=path)
            return arr
        if not isinstance(v, (list, tuple)):
            raise UDFError(f"{path}: expected a list, got {type(v).__name__}", path=path)
        return [from_python(t, ndim - 1, x, f"{path}[{i}]") for i, x in enumerate(v)]
    if isinstance(t, Primitive):
        if t.name == "int":
            if isinstance(v, (bool, str)) or not float(v) == int(float(v)):
                raise UDFError(f"{path}: expected an integer, got {v!r}", path=path)
            return int(v)
        if t.name in ("float", "double"):
            if isinstance(v, str):
                raise UDFError(f"{path}: expected a number, got {v!r}", path=path)
            return float(v)
        if t.name == "bool":
            return bool(v)
        if not isinstance(v, str):
            raise UDFError(f"{path}: expected a string, got {v!r}", path=path)
        return v
    if isinstance(t, Select):
        if v not in t.choices:
            raise UDFError(f"{path}: {v!r} is not one of {', '.join(t.choices)}", path=path)
        return v
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, (list, tuple)) or len(v) != len(t.members):
        raise UDFError(f"{path}: expected {len(t.members)} values for {t.describe()}",
                       path=path)
    return [from_python(m.type, m.ndim, x, f"{path}.{m.name}") for m, x in zip(t.members, v)]


def nest(leaves, t):
    """Re-nest a flat leaf sequence as the struct lists of type ``t`` (OCTA's get form)."""
    it = iter(leaves)

    def build(tt):
        if isinstance(tt, Primitive):
            x = next(it)
            return int(x) if tt.name == "int" else float(x)
        return [build(m.type) for m in tt.members]
    return build(t)
