"""UDF definitions -> a typed schema.

Types are small immutable objects:

* ``Primitive('int' | 'float' | 'double' | 'string' | 'bool')``
* ``Select(choices)`` -- a string restricted to its choices.  In the data the chosen string
  stands where the select is; the alternatives' data are ordinary sibling members of the
  enclosing struct (so "the chosen string followed by the data of all alternatives").
* ``Struct(members)`` -- inline ``{...}`` or a named class.
* ``Member(name, ndim, type, unit, description)`` -- ``ndim`` counts the ``[]`` after the name.

A struct whose leaves are all numbers and of fixed count is *numeric-flat*: arrays of it are
stored as one numpy array with a trailing axis of ``leaf_count`` (or no trailing axis for an
array of a bare number).
"""
from __future__ import annotations

from dataclasses import dataclass, field

NUMERIC = ("int", "float", "double")


@dataclass(frozen=True)
class Primitive:
    name: str

    @property
    def numeric(self) -> bool:
        return self.name in NUMERIC

    def describe(self) -> str:
        return self.name


@dataclass(frozen=True)
class Select:
    choices: tuple

    numeric = False

    def describe(self) -> str:
        return "select {" + ", ".join(repr(c) for c in self.choices) + "}"


@dataclass(frozen=True)
class Member:
    name: str
    ndim: int
    type: object
    unit: str | None = None
    description: str | None = None


@dataclass(frozen=True)
class Struct:
    members: tuple
    name: str | None = None  # class name, if any
    unit: str | None = None
    _index: dict = field(default=None, compare=False, hash=False, repr=False)

    numeric = False

    def __post_init__(self):
        object.__setattr__(self, "_index", {m.name: i for i, m in enumerate(self.members)})

    def index(self, name: str) -> int | None:
        return self._index.get(name)

    def describe(self) -> str:
        return self.name or "struct"


# answers of leaf_count and leaf_slice per type object (types are immutable and live as long
# as their schema; an entry keeps its type, so its id is not reused): a record's particle
# table asks them for every column, at every snapshot.  Bounded: a script reading many
# schemas starts the table again.
_MEMO: dict = {}
_MEMO_MAX = 1 << 17


def _memo(t, key, compute):
    hit = _MEMO.get(key)
    if hit is not None and hit[0] is t:
        return hit[1]
    value = compute()
    if len(_MEMO) > _MEMO_MAX:
        _MEMO.clear()
    _MEMO[key] = (t, value)
    return value


def leaf_count(t) -> int | None:
    """Number of numeric leaves if ``t`` is numeric-flat, else None."""
    return _memo(t, id(t), lambda: _leaf_count(t))


def _leaf_count(t) -> int | None:
    if isinstance(t, Primitive):
        return 1 if t.numeric else None
    if isinstance(t, Struct):
        n = 0
        for m in t.members:
            if m.ndim:
                return None
            c = leaf_count(m.type)
            if c is None:
                return None
            n += c
        return n
    return None


def leaf_kinds(t) -> list:
    """Primitive names of the leaves of a numeric-flat type, in order."""
    if isinstance(t, Primitive):
        return [t.name]
    out = []
    for m in t.members:
        out.extend(leaf_kinds(m.type))
    return out


def leaf_slice(t, names: list) -> tuple:
    """(offset, count, type) of the sub-path ``names`` inside numeric-flat ``t``."""
    return _memo(t, (id(t), tuple(names)), lambda: _leaf_slice(t, names))


def _leaf_slice(t, names: list) -> tuple:
    offset = 0
    for name in names:
        if not isinstance(t, Struct):
            raise KeyError(name)
        for m in t.members:
            if m.name == name:
                t = m.type
                break
            offset += leaf_count(m.type)
        else:
            raise KeyError(name)
    return offset, leaf_count(t), t


class Schema:
    """The schema of a document: classes, global (common) items and record items."""

    def __init__(self):
        self.classes: dict[str, Struct] = {}
        self.global_items: dict[str, Member] = {}
        self.record_items: dict[str, Member] = {}
        self.header_items: dict[str, Member] = {}

    def item(self, name: str) -> tuple[Member, bool] | tuple[None, None]:
        """(member, is_global) for a top-level name."""
        if name in self.global_items:
            return self.global_items[name], True
        if name in self.record_items:
            return self.record_items[name], False
        return None, None
