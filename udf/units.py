"""Unit conversion for ``UDFManager.get(path, "[unit]")``.

Units are SI quantities (a factor and exponents of m, kg, s, K, mol, A, cd).  A document's
``\\begin{unit}`` block adds its own: ``[L]={$Unit_Parameter.Length}[nm]``,
``[tau]=[mass^0.5*L*epsilon^-0.5]``, ``PI=3.14...`` (a constant), and so on.
"""
from __future__ import annotations

import math
import re

from .errors import UDFError

BASE = ("m", "kg", "s", "K", "mol", "A", "cd")


class Q:
    """A quantity: factor times a product of SI base units."""
    __slots__ = ("f", "d")

    def __init__(self, f=1.0, d=None):
        self.f = float(f)
        self.d = tuple(d) if d is not None else (0,) * len(BASE)

    def __mul__(self, o):
        o = _q(o)
        return Q(self.f * o.f, [a + b for a, b in zip(self.d, o.d)])

    __rmul__ = __mul__

    def __truediv__(self, o):
        o = _q(o)
        return Q(self.f / o.f, [a - b for a, b in zip(self.d, o.d)])

    def __rtruediv__(self, o):
        return _q(o) / self

    def __pow__(self, p):
        p = _q(p)
        if any(p.d):
            raise ValueError("an exponent must be a pure number")
        return Q(self.f ** p.f, [a * p.f for a in self.d])


def _q(x):
    return x if isinstance(x, Q) else Q(x)


def _dim(**kw):
    return tuple(kw.get(b, 0) for b in BASE)


_SI = {
    "m": Q(1, _dim(m=1)), "g": Q(1e-3, _dim(kg=1)), "s": Q(1, _dim(s=1)), "K": Q(1, _dim(K=1)),
    "mol": Q(1, _dim(mol=1)), "A": Q(1, _dim(A=1)), "cd": Q(1, _dim(cd=1)), "rad": Q(1),
    "sr": Q(1), "N": Q(1, _dim(kg=1, m=1, s=-2)), "J": Q(1, _dim(kg=1, m=2, s=-2)),
    "W": Q(1, _dim(kg=1, m=2, s=-3)), "Pa": Q(1, _dim(kg=1, m=-1, s=-2)),
    "C": Q(1, _dim(A=1, s=1)), "V": Q(1, _dim(kg=1, m=2, s=-3, A=-1)), "Hz": Q(1, _dim(s=-1)),
    "L": Q(1e-3, _dim(m=3)), "eV": Q(1.602176634e-19, _dim(kg=1, m=2, s=-2)),
    "min": Q(60, _dim(s=1)), "h": Q(3600, _dim(s=1)), "P": Q(0.1, _dim(kg=1, m=-1, s=-1)),
}
_PREFIX = {"y": 1e-24, "z": 1e-21, "a": 1e-18, "f": 1e-15, "p": 1e-12, "n": 1e-9, "u": 1e-6,
           "µ": 1e-6, "m": 1e-3, "c": 1e-2, "d": 1e-1, "da": 1e1, "h": 1e2, "k": 1e3,
           "M": 1e6, "G": 1e9, "T": 1e12}
_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)|"
                    r"([A-Za-zµ_][A-Za-z0-9µ_]*)|(\{\$[^}]*\})|(\[[^\]]*\])|([-+*/^()]))")


class UnitSystem:
    def __init__(self, doc=None):
        self.units: dict[str, Q] = {}
        self.consts: dict[str, Q] = {"PI": Q(math.pi)}
        self.doc = doc
        if doc is not None:
            for text in doc.schema_texts:
                if text.lstrip().startswith("\\begin{unit}"):
                    self._load(text)

    def _load(self, text):
        body = text.split("\\begin{unit}", 1)[1].rsplit("\\end{unit}", 1)[0]
        for line in body.splitlines():
            line = line.split("//")[0].strip()
            if "=" not in line:
                continue
            lhs, rhs = (s.strip() for s in line.split("=", 1))
            try:
                value = self.evaluate(rhs)
            except (ValueError, KeyError, ZeroDivisionError, UDFError):
                continue  # a definition we cannot evaluate is simply unavailable
            if lhs.startswith("[") and lhs.endswith("]"):
                self.units[lhs[1:-1].strip()] = value
            else:
                self.consts[lhs] = value

    def unit(self, name: str) -> Q:
        if name in self.units:
            return self.units[name]
        if name in _SI:
            return _SI[name]
        for p in sorted(_PREFIX, key=len, reverse=True):
            if name.startswith(p) and name[len(p):] in _SI:
                base = _SI[name[len(p):]]
                return Q(base.f * _PREFIX[p], base.d)
        if name in self.consts:
            return self.consts[name]
        raise KeyError(name)

    def evaluate(self, expr: str, in_unit=False) -> Q:
        """Evaluate ``10^3[cal]``, ``[mass*L*tau^-2]``, ``{$Unit_Parameter.Length}[nm]``."""
        toks = []
        pos = 0
        expr = expr.strip()
        while pos < len(expr):
            m = _TOKEN.match(expr, pos)
            if not m or m.end() == pos:
                raise ValueError(f"cannot read unit expression {expr!r}")
            toks.append(m.groups())
            pos = m.end()
        self._toks, self._i, self._in_unit = toks, 0, in_unit
        v = self._expr()
        if self._i != len(toks):
            raise ValueError(f"cannot read unit expression {expr!r}")
        return v

    # expr := term (('*'|'/') term | term)*  ;  term := atom ('^' signed)?
    def _peek(self):
        return self._toks[self._i] if self._i < len(self._toks) else (None,) * 5

    def _expr(self):
        v = self._term()
        while True:
            t = self._peek()
            if t[4] in ("*", "/"):
                self._i += 1
                r = self._term()
                v = v * r if t[4] == "*" else v / r
            elif t[0] or t[1] or t[2] or t[3] or t[4] == "(":
                v = v * self._term()  # juxtaposition: 10^3[cal]
            else:
                return v

    def _term(self):
        v = self._atom()
        if self._peek()[4] == "^":
            self._i += 1
            sign = 1.0
            if self._peek()[4] in ("-", "+"):
                sign = -1.0 if self._peek()[4] == "-" else 1.0
                self._i += 1
            e = self._atom()
            v = v ** (sign * e.f)
        return v

    def _atom(self):
        num, name, ref, bracket, op = self._peek()
        self._i += 1
        if num:
            return Q(float(num))
        if name:
            return self.unit(name) if self._in_unit else self.consts.get(name) or self.unit(name)
        if ref:
            path = ref[2:-1].strip()
            if self.doc is None:
                raise KeyError(path)
            return Q(float(self.doc.get(path)))
        if bracket:
            saved = (self._toks, self._i, self._in_unit)
            v = self.evaluate(bracket[1:-1], in_unit=True)
            self._toks, self._i, self._in_unit = saved
            return v
        if op == "(":
            v = self._expr()
            if self._peek()[4] != ")":
                raise ValueError("unbalanced parentheses")
            self._i += 1
            return v
        if op == "-":
            return Q(-1.0) * self._atom()
        raise ValueError("unexpected token in unit expression")


def convert(value, src: str | None, dst: str, doc):
    """Convert ``value`` (number or nested lists) from unit ``src`` to ``dst``."""
    dst_name = dst.strip()
    if dst_name.startswith("[") and dst_name.endswith("]"):
        dst_name = dst_name[1:-1]
    if not src:
        raise UDFError(f"the item has no unit; cannot convert to [{dst_name}]")
    system = UnitSystem(doc)
    try:
        a = system.evaluate(src, in_unit=True)
        b = system.evaluate(dst_name, in_unit=True)
    except (KeyError, ValueError) as e:
        raise UDFError(f"unknown unit in [{src}] -> [{dst_name}]: {e}") from None
    if any(abs(x - y) > 1e-9 for x, y in zip(a.d, b.d)):
        raise UDFError(f"cannot convert [{src}] to [{dst_name}]: different dimensions")
    factor = a.f / b.f

    def scale(v):
        if isinstance(v, list):
            return [scale(x) for x in v]
        return v * factor
    return scale(value)
