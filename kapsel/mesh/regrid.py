"""Re-gridding between the oblique (sheared) grid and the rectangular one: a field's rows
shifted along x by a y-dependent amount, periodic, ``linear`` (2 points) or ``spline``
(periodic cubic B-spline), switch.ns_solver.OBL_INT (the original's Transform_obl_u,
A2a_oblique, A_oblique2a).  The bottom of the discrete calculus: numpy and scipy only; the
layouts (kapsel.mesh.grid, kapsel.mesh.pencil) and the oblique solvers (kapsel.fluid.oblique)
stand on it."""
from __future__ import annotations

import numpy as np

__all__ = ["INTERPOLATIONS", "shift_rows", "to_rectangular", "to_oblique"]

INTERPOLATIONS = ("linear", "spline")

#: kapsel.mesh.regrid_kernels once the compiled kernels are enabled (kapsel.mesh.compiled): the
#: same shifts in one pass, the same bits; None: the numpy passes below
kernels = None


def shift_rows(f, shift, method="linear", rows=None, out=None, lines=None, zero=True):
    """g[i, j, ...] = f(x_i - shift_j) along axis 0, periodic; ``shift`` (NY,) in grid points.

    f: (NX, NY, ...) or (c, NX, NY, ...) with a leading component axis (then ``f.ndim == 4``).
    Integer shifts are exact permutations for both methods.  ``rows`` (a slice of x): only
    those rows of g (the same values as those rows of the whole g).  ``out``: g written
    there (returned; an array of g's shape that is not ``f``) instead of a new array.
    ``lines`` (bool (NY, NZ) of a 3-D field's lines along x; with ``out``): only those lines
    of g are made (the same values); the others are set to 0 with ``zero``, else left as
    they are in ``out`` (a field read on some lines only, a sparse field whose other lines
    are 0: each line along x is shifted on its own).
    """
    if method not in INTERPOLATIONS:
        raise ValueError(f"OBL_INT must be one of {INTERPOLATIONS}, got {method!r}")
    f = np.asarray(f, dtype=float)
    if lines is not None:
        if out is None or f.ndim not in (3, 4) or lines.shape != f.shape[-2:]:
            raise ValueError("lines: a (NY, NZ) mask of a 3-D field's lines, with out")
        lines = np.ascontiguousarray(lines, dtype=bool)
    if f.ndim == 4:
        if kernels is not None:
            return _shift_compiled(f, shift, method, rows, out, lines, zero)
        if out is None:
            return np.stack([shift_rows(c, shift, method, rows) for c in f])
        for c in range(f.shape[0]):
            shift_rows(f[c], shift, method, rows, out[c], lines, zero)
        return out
    if kernels is not None and f.ndim == 3:
        return _shift_compiled(f[None], shift, method, rows,
                               None if out is None else out[None], lines, zero)[0]
    if out is not None:
        g = shift_rows(f, shift, method, rows)
        if lines is None:
            out[...] = g
        else:
            out[:, lines] = g[:, lines]
            if zero:
                out[:, ~lines] = 0.0
        return out
    nx, ny = f.shape[0], f.shape[1]
    b, frac = _split(shift, ny)              # g_i = f(i - b - frac)
    i = np.arange(nx)[:, None] if rows is None else np.arange(nx)[rows][:, None]
    j = np.arange(ny)[None, :]
    b = b[None, :]
    w = frac[None, :]
    if method == "linear":
        # f(i - b - w) = (1 - w) f[i - b] + w f[i - b - 1]
        f0 = f[(i - b) % nx, j]
        f1 = f[(i - b - 1) % nx, j]
        wb = w.reshape(w.shape + (1,) * (f.ndim - 2))
        return (1.0 - wb) * f0 + wb * f1
    from scipy.ndimage import spline_filter1d
    c = spline_filter1d(f, order=3, axis=0, mode="grid-wrap")
    w0, w1, w2, w3 = (a.reshape((1, ny) + (1,) * (f.ndim - 2)) for a in _spline_weights(frac))
    p = i - b - 1
    out = w0 * c[(p - 1) % nx, j]
    out += w1 * c[p % nx, j]
    out += w2 * c[(p + 1) % nx, j]
    out += w3 * c[(p + 2) % nx, j]
    return out


def _split(shift, ny):
    """The row shifts (NY,) as whole grid points b (int) and the fraction left, in [0, 1)."""
    shift = np.asarray(shift, dtype=float).reshape(ny)
    base = np.floor(shift)
    return base.astype(np.int64), shift - base


def _spline_weights(frac):
    """The cubic B-spline weights of the 4 points around x = i - b - frac, per row: the point
    is (i - b - 1) + t, t = 1 - frac."""
    t = 1.0 - frac
    return ((1.0 - t) ** 3 / 6.0, (3 * t ** 3 - 6 * t ** 2 + 4) / 6.0,
            (-3 * t ** 3 + 3 * t ** 2 + 3 * t + 1) / 6.0, t ** 3 / 6.0)


_EVERY_LINE = np.zeros((0, 0), dtype=bool)


def _shift_compiled(f, shift, method, rows, out=None, lines=None, zero=True):
    """shift_rows of the components of ``f`` (c, NX, NY, NZ) by the compiled kernels: the
    weights as the numpy passes compute them, then one pass per component, into ``out``
    (c-contiguous components) or a new array; on ``lines`` only (``shift_rows``)."""
    nx, ny = f.shape[1], f.shape[2]
    b, frac = _split(shift, ny)
    idx = np.arange(nx, dtype=np.int64)
    idx = np.ascontiguousarray(idx if rows is None else idx[rows])
    shape = (f.shape[0], idx.size) + f.shape[2:]
    if out is None:
        out = np.empty(shape)
    elif out.shape != shape or not all(o.flags.c_contiguous for o in out):
        raise ValueError(f"out must be {shape} with contiguous components, got {out.shape}")
    lines = _EVERY_LINE if lines is None else lines
    if method == "linear":
        for c in range(f.shape[0]):
            kernels.shift_linear(np.ascontiguousarray(f[c]), idx, b, frac, out[c], lines,
                                 bool(zero))
        return out
    w0, w1, w2, w3 = _spline_weights(frac)
    slab = np.empty((nx, f.shape[3]))
    for c in range(f.shape[0]):
        kernels.shift_spline(np.ascontiguousarray(f[c]), idx, b, w0, w1, w2, w3, out[c], slab,
                             lines, bool(zero))
    return out


def _ny(f):
    return np.shape(f)[2] if np.ndim(f) == 4 else np.shape(f)[1]


def to_rectangular(f, g, method="linear", origin=0.0, out=None, lines=None, zero=True):
    """A field on the oblique grid of strain g -> the rectangular grid (same shape):
    rect[i, j] = f at oblique x^ = i - g (j - origin) (grid units; origin = y0 / DX);
    into ``out`` if given, on ``lines`` only (``shift_rows``)."""
    return shift_rows(f, g * (np.arange(_ny(f)) - origin), method, out=out, lines=lines,
                      zero=zero)


def to_oblique(f, g, method="linear", origin=0.0, out=None, lines=None, zero=True):
    """Inverse of ``to_rectangular``: obl[i, j] = rect at x = i + g (j - origin)."""
    return shift_rows(f, -g * (np.arange(_ny(f)) - origin), method, out=out, lines=lines,
                      zero=zero)
