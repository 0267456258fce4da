"""UDF text -> sections: schema definitions and generic (untyped) data values.

Parsing is done by the Lark grammar in ``grammar.lark``.  Before Lark sees the text, every
long purely numeric bracketed array (``[[[{0.1}{0.2}...]...]...]``) is cut out, parsed by
numpy in one call, and replaced by a ``@k@`` placeholder padded with blanks so that every
line and column of the rest of the file stays where it was.
"""
from __future__ import annotations

import hashlib
import mmap
import os
import pickle
import re
import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import lark
import numpy as np

from .errors import UDFError
from .files import check_regular, read_bytes
from .schema import Member, Primitive, Schema, Select, Struct

BULK_MIN_CHARS = 256
_BULK_RUN = re.compile(rb"\[[\s0-9.eE+\-,{}\[\]]{%d,}" % BULK_MIN_CHARS)
_NUMBER_B = re.compile(rb"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
_DELIMS = bytes.maketrans(b"{}[],", b"     ")
_DIGIT_B = re.compile(rb"\d")


@lru_cache(maxsize=1)
def grammar() -> lark.Lark:
    path = os.path.join(os.path.dirname(__file__), "grammar.lark")
    with open(path, encoding="utf-8") as fh:
        return lark.Lark(fh.read(), parser="lalr", propagate_positions=True,
                         maybe_placeholders=False)


# ---------------------------------------------------------------------------------------
# generic values
@dataclass
class Group:
    """A ``{...}`` (kind '{') or ``[...]`` (kind '[') group of generic values."""
    kind: str
    items: list
    line: int
    column: int


@dataclass
class Bulk:
    """A numeric array lifted out of the text: flat numbers and bracket-level counts."""
    numbers: np.ndarray
    level_counts: np.ndarray  # level_counts[k] = number of '[' at nesting level k (1 = outer)
    integral: bool  # no '.', 'e' or 'E' appeared
    line: int
    column: int


@dataclass
class Section:
    kind: str  # 'header' | 'def' | 'global_def' | 'data' | 'record' | 'unit'
    file: str
    text: str = ""          # raw source text (definitions and units)
    members: list = field(default_factory=list)   # definitions
    classes: list = field(default_factory=list)   # (name, Struct)
    items: list = field(default_factory=list)     # data: (name, ndim, value, line, col)
    comment: str | None = None
    header_members: list = field(default_factory=list)
    header_items: list = field(default_factory=list)


def _unquote(tok) -> str:
    from .values import string_value
    return string_value(tok)


# ---------------------------------------------------------------------------------------
def extract_bulk(data: bytes, file: str):
    """Cut long numeric arrays out of the file's bytes.

    Returns (reduced text, list of Bulk).  Each array becomes ``@k@`` followed by as many
    newlines as it spanned, so line numbers of everything after it are unchanged.
    """
    spans = []      # (g0, g1) byte offsets of each bulk group
    pieces = []
    pos = 0
    search_from = 0
    while True:
        m = _BULK_RUN.search(data, search_from)
        if m is None:
            break
        start, run_end = m.start(), m.end()
        b = np.frombuffer(data, dtype=np.uint8, count=run_end - start, offset=start)
        step = (b == 91).view(np.int8) - (b == 93).view(np.int8)
        depth = np.cumsum(step, dtype=np.int8)
        # every top-level bracket group inside this run of numeric characters
        closes = np.flatnonzero(depth <= 0)
        search_from = run_end
        g_start = 0
        for c in closes.tolist():
            if depth[c] < 0:          # a ']' closing something opened before the run
                search_from = start + c + 1
                break
            if b[g_start] != 91:      # the next group starts at the next '['
                nxt = data.find(b"[", start + g_start, start + c + 1)
                if nxt < 0:
                    continue
                g_start = nxt - start
            if c + 1 - g_start >= BULK_MIN_CHARS:
                levels = depth[g_start:c + 1][b[g_start:c + 1] == 91]
                if g_start:
                    levels = levels - depth[g_start - 1]
                g0, g1 = start + g_start, start + c + 1
                newlines = data.count(b"\n", g0, g1)
                spans.append((g0, g1, np.bincount(levels.astype(np.int64)), newlines))
                pieces.append(data[pos:g0])
                pieces.append(b"@%d@" % (len(spans) - 1) + b"\n" * newlines)
                pos = g1
            g_start = c + 1
            if g_start >= len(b):
                break
    if not spans:
        return data.decode("utf-8", errors="replace"), []
    pieces.append(data[pos:])
    numbers = _parse_spans(data, spans)
    bulks = []
    line, lpos = 1, 0
    for (g0, g1, counts, newlines), nums in zip(spans, numbers):
        line += data.count(b"\n", lpos, g0)
        lpos = g0
        column = g0 - (data.rfind(b"\n", 0, g0) + 1) + 1
        if nums is None:
            raise _bad_number(data[g0:g1], file, line, column)
        integral = not any(ch in data[g0:g1] for ch in (b".", b"e", b"E"))
        bulks.append(Bulk(nums, counts, integral, line, column))
    return b"".join(pieces).decode("utf-8", errors="replace"), bulks


PARALLEL_BYTES = 32 << 20


def _parse_spans(data: bytes, spans: list) -> list:
    """The numbers of every span.  Large inputs are split over two processes: numpy's text
    parser is the floor (about 0.1 us per number); the forked child writes its numbers
    straight into shared memory, so nothing is pickled back."""
    total = sum(g1 - g0 for g0, g1, *_ in spans)
    if total < PARALLEL_BYTES or len(spans) < 2 or (os.cpu_count() or 1) < 2 \
            or not hasattr(os, "fork"):
        return [_parse_one(data[g0:g1]) for g0, g1, *_ in spans]
    # split by bytes; the child takes the second half
    sizes = np.cumsum([g1 - g0 for g0, g1, *_ in spans])
    half = int(np.searchsorted(sizes, sizes[-1] / 2)) + 1
    theirs = spans[half:]
    # upper bound of the child's numbers: separators + 1 per span
    bound = sum(data.count(b",", g0, g1) + data.count(b"\n", g0, g1) + data.count(b" ", g0, g1)
                + 1 for g0, g1, *_ in theirs)
    shared = mmap.mmap(-1, 8 * bound + 8 * (len(theirs) + 1))
    counts = np.frombuffer(shared, dtype=np.int64, count=len(theirs) + 1)
    values = np.frombuffer(shared, dtype=np.float64, offset=8 * (len(theirs) + 1))
    pid = os.fork()
    if pid == 0:  # child: parse, write into shared memory, exit without cleanup
        code = 0
        try:
            at = 0
            for k, (g0, g1, *_) in enumerate(theirs):
                nums = _parse_one(data[g0:g1])
                if nums is None:
                    counts[k] = -1
                    continue
                values[at:at + nums.size] = nums
                counts[k] = nums.size
                at += nums.size
        except BaseException:
            code = 1
        os._exit(code)
    mine = [_parse_one(data[g0:g1]) for g0, g1, *_ in spans[:half]]
    _, status = os.waitpid(pid, 0)
    if status != 0:  # the child failed: parse its half here
        return mine + [_parse_one(data[g0:g1]) for g0, g1, *_ in theirs]
    out, at = [], 0
    for k in range(len(theirs)):
        n = int(counts[k])
        if n < 0:
            out.append(None)
            continue
        out.append(values[at:at + n].copy())
        at += n
    return mine + out


def _parse_one(span: bytes):
    """The numbers of one bracket group, or None if a token is not a number.
    numpy's text parser is the floor here: about 0.1 us per number."""
    flat = span.translate(_DELIMS)
    if not _DIGIT_B.search(flat):
        return np.zeros(0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return np.fromstring(flat, dtype=np.float64, sep=" ")
        except (DeprecationWarning, ValueError):
            return None


def _bad_number(span: bytes, file, line, column) -> UDFError:
    for m in re.finditer(rb"[^\s,{}\[\]]+", span):
        if not _NUMBER_B.fullmatch(m.group()):
            before = span[:m.start()]
            ln = line + before.count(b"\n")
            col = (m.start() - before.rfind(b"\n")) if b"\n" in before else column + m.start()
            tok = m.group().decode("ascii", errors="replace")
            return UDFError(f"malformed number {tok!r} in an array", file, ln, col)
    return UDFError("malformed numeric array", file, line, column)


# ---------------------------------------------------------------------------------------
class _Builder:
    """Turns a Lark tree into Sections, resolving includes."""

    def __init__(self, file: str, text: str, bulks: list, loader):
        self.file = file
        self.text = text
        self.bulks = bulks
        self.loader = loader

    # --- definitions ---
    def type_of(self, node):
        kind = node.data
        if kind == "primitive":
            return Primitive(str(node.children[0]))
        if kind == "select":
            return Select(tuple(_unquote(c) for c in node.children))
        if kind == "struct":
            return Struct(tuple(self.member(c) for c in node.children))
        if kind == "class_ref":
            return ("ref", str(node.children[0]), node.children[0].line, node.children[0].column)
        raise AssertionError(kind)

    def _unit_desc(self, children):
        unit = desc = None
        for c in children:
            if isinstance(c, lark.Tree) and c.data == "unit":
                unit = str(c.children[0])[1:-1]
            elif isinstance(c, lark.Tree) and c.data == "description":
                desc = _unquote(c.children[0])
        return unit, desc

    def member(self, node) -> Member:
        name, dims, typ, *rest = node.children
        unit, desc = self._unit_desc(rest)
        return Member(str(name), len(dims.children),
                      self.type_of(typ), unit, desc)

    def definitions(self, node, kind):
        sec = Section(kind, self.file, text=self.raw(node))
        for d in node.children:
            if d.data == "class_def":
                name, typ, *rest = d.children
                unit, desc = self._unit_desc(rest)
                t = self.type_of(typ)
                if isinstance(t, Struct):
                    t = Struct(t.members, name=str(name), unit=unit)
                sec.classes.append((str(name), t, name.line, name.column))
            else:
                sec.members.append(self.member(d))
        return sec

    def raw(self, node) -> str:
        return self.text[node.meta.start_pos:node.meta.end_pos]

    # --- data ---
    def value(self, node):
        if isinstance(node, lark.Token):
            return node
        kind = node.data
        if kind in ("number", "string"):
            return node.children[0]
        if kind == "bulk":
            tok = node.children[0]
            return self.bulks[int(str(tok)[1:-1])]
        if kind in ("group", "array"):
            return Group("{" if kind == "group" else "[", [self.value(c) for c in node.children],
                         node.meta.line, node.meta.column)
        raise AssertionError(kind)

    def data_items(self, node):
        items = []
        for it in node.children:
            name, dims, val = it.children[0], it.children[1], it.children[2]
            items.append((str(name), len(dims.children), self.value(val), name.line, name.column))
        return items

    def sections(self, tree) -> list[Section]:
        out = []
        for node in tree.children:
            kind = node.data
            if kind == "include":
                target = _unquote(node.children[0])
                path = os.path.join(os.path.dirname(self.file), target)
                tok = node.children[0]
                if not os.path.exists(path):
                    raise UDFError(f'included file "{target}" not found (looked for {path})',
                                   self.file, tok.line, tok.column)
                try:
                    check_regular(path)
                except OSError as e:
                    raise UDFError(f'included file "{target}" ({path}) {e.strerror}',
                                   self.file, tok.line, tok.column) from None
                try:
                    out.extend(self.loader(path))
                except UDFError as e:
                    if e.file and os.path.normpath(e.file) == os.path.normpath(path) \
                            and e.line is not None:
                        e.message += f" (included from {self.file}:{node.children[0].line})"
                        e.args = (e.format(),)
                    raise
            elif kind in ("def_block", "global_def_block"):
                out.append(self.definitions(node, "def" if kind == "def_block" else "global_def"))
            elif kind == "data_block":
                out.append(Section("data", self.file, items=self.data_items(node)))
            elif kind == "record_block":
                comment = None
                data = node.children[-1]
                if len(node.children) == 2:
                    comment = _unquote(node.children[0].children[0])
                out.append(Section("record", self.file, items=self.data_items(data),
                                   comment=comment))
            elif kind == "unit_block":
                out.append(Section("unit", self.file, text=self.raw(node)))
            elif kind == "header":
                sec = Section("header", self.file, text=self.raw(node))
                for c in node.children:
                    if c.data == "def_block":
                        sec.header_members = self.definitions(c, "def").members
                    else:
                        sec.header_items = self.data_items(c)
                out.append(sec)
        return out


_TERMINAL_NAMES = {"LBRACE": "'{'", "RBRACE": "'}'", "LSQB": "'['", "RSQB": "']'",
                   "COMMA": "','", "SEMICOLON": "';'", "COLON": "':'", "NUMBER": "a number",
                   "STRING": "a string", "NAME": "a name", "BULK": "a number array",
                   "DIM": "'[]'", "UNIT": "a [unit]", "PRIMITIVE": "a type"}


def _terminal_name(name: str) -> str:
    if name in _TERMINAL_NAMES:
        return _TERMINAL_NAMES[name]
    try:
        pattern = grammar().get_terminal(name).pattern
        return f"'{pattern.value}'" if pattern.type == "str" else name
    except KeyError:
        return name.strip('"')


def _syntax_error(e: lark.exceptions.UnexpectedInput, file: str, text: str) -> UDFError:
    line, col = e.line, e.column
    if isinstance(e, lark.exceptions.UnexpectedCharacters):
        ch = text[e.pos_in_stream] if e.pos_in_stream < len(text) else "end of file"
        if ch == '"':
            if '"' not in text[e.pos_in_stream + 1:]:
                return UDFError("unexpected end of file inside a string (its closing \" is "
                                "missing)", file, line, col)
            return UDFError("a string is not closed (its closing \" is missing)", file, line, col)
        if len(ch) == 1 and not ch.isprintable() and ch not in "\t\r\n":
            return UDFError(f"unexpected character {ch!r} (binary data: a UDF file is text)",
                            file, line, col)
        return UDFError(f"unexpected character {ch!r}", file, line, col)
    if isinstance(e, lark.exceptions.UnexpectedToken):
        tok = e.token
        if tok.type == "$END":
            return UDFError("unexpected end of file (a block or bracket is not closed)",
                            file, line if line and line > 0 else text.count("\n") + 1, None)
        exp = sorted({_terminal_name(x) for x in e.expected})[:8]
        if "'\\include'" in exp and "'\\begin{data}'" in exp:
            return UDFError(f"unexpected {str(tok)!r} where a section (\\begin{{...}}) or "
                            f"\\include should start (is this a UDF file?)", file, line, col)
        return UDFError(f"unexpected {str(tok)!r}; expected one of: {', '.join(exp)}",
                        file, line, col)
    return UDFError(str(e).splitlines()[0], file, line, col)


MAX_INCLUDE_DEPTH = 100


def load_sections(path: str, _stack=(), data: bytes | None = None) -> list[Section]:
    """Parse ``path`` (and, recursively, what it includes) into a list of Sections
    (``data``: the file's bytes, if already read)."""
    path = os.path.normpath(path)
    if path in _stack:
        raise UDFError(f"include cycle: {' -> '.join(_stack + (path,))}", path)
    if len(_stack) >= MAX_INCLUDE_DEPTH:
        raise UDFError(f"includes are nested more than {MAX_INCLUDE_DEPTH} deep (from "
                       f"{_stack[0]}); is there an include loop through different names?",
                       _stack[-1])
    if data is None:
        try:
            data = read_bytes(path)
        except OSError as e:
            raise UDFError(f"cannot read file: {e.strerror}", path) from None
    key = (path, hashlib.sha256(data).digest())
    hit = _PARSED.get(key)
    if hit is not None and all(_digest(p) == d for p, d in hit[1]):
        return pickle.loads(hit[0])             # a fresh copy: callers may change it
    reduced, bulks = extract_bulk(data, path)
    try:
        tree = grammar().parse(reduced)
    except lark.exceptions.UnexpectedInput as e:
        raise _syntax_error(e, path, reduced) from None
    included = []

    def include(p):
        got = load_sections(p, _stack + (path,))
        included.append((os.path.normpath(p), _digest(p)))
        return got
    sections = _Builder(path, reduced, bulks, include).sections(tree)
    if len(data) <= _PARSED_MAX_BYTES:
        _PARSED[key] = (pickle.dumps(sections), tuple(included))
        while len(_PARSED) > _PARSED_MAX_FILES:
            _PARSED.pop(next(iter(_PARSED)))        # the oldest
    return sections


# load_sections' parses of this process, by (path, SHA-256 of its bytes): a file read
# again unchanged (define.udf: by the input's check, output.udf's and restart.udf's
# writers; 0.12 s of parsing each at the sample's size) is a copy of the first parse,
# as long as what it includes is unchanged too.  Files up to 1 MB of text, the last 16.
_PARSED: dict = {}
_PARSED_MAX_BYTES = 1 << 20
_PARSED_MAX_FILES = 16


def _digest(path: str) -> bytes | None:
    try:
        return hashlib.sha256(read_bytes(path)).digest()
    except OSError:
        return None


def build_schema(sections: list[Section]) -> Schema:
    """Collect definitions from all sections, resolving class references."""
    schema = Schema()
    pending = []
    for sec in sections:
        if sec.kind == "header":
            schema.header_items.update({m.name: m for m in sec.header_members})
        for name, t, line, col in sec.classes:
            schema.classes[name] = t
        if sec.kind in ("def", "global_def"):
            target = schema.record_items if sec.kind == "def" else schema.global_items
            for m in sec.members:
                target[m.name] = m
        pending.append(sec)

    def resolve(t, file):
        if isinstance(t, tuple) and t[0] == "ref":
            _, name, line, col = t
            if name not in schema.classes:
                raise UDFError(f"unknown type or class {name!r}", file, line, col)
            return resolve(schema.classes[name], file)
        if isinstance(t, Struct):
            members = tuple(Member(m.name, m.ndim, resolve(m.type, file), m.unit, m.description)
                            for m in t.members)
            if all(a.type is b.type for a, b in zip(members, t.members)):
                return t
            return Struct(members, name=t.name, unit=t.unit)
        return t

    # classes may refer to classes defined later: resolve repeatedly
    files = {name: sec.file for sec in sections for name, *_ in sec.classes}
    for name in list(schema.classes):
        schema.classes[name] = resolve(schema.classes[name], files.get(name))
    for items, secs in ((schema.global_items, "global_def"), (schema.record_items, "def")):
        for name, m in list(items.items()):
            f = next((s.file for s in sections if s.kind == secs and m in s.members), None)
            items[name] = Member(m.name, m.ndim, resolve(m.type, f), m.unit, m.description)
    return schema
