"""The row shifts of kapsel.mesh.regrid in one compiled pass per field (numba).

``shift_rows`` gathers each output point from 2 (linear) or 4 (cubic B-spline) points of its
x row and weights them; numpy does that as whole-array index arithmetic, gathers and
temporaries (four to eight passes over the field).  These kernels do the same floating-point
operations in the same order, point by point: the results are bit-identical.  Loaded with the
other compiled kernels (kapsel.mesh.compiled.enable sets ``kapsel.mesh.regrid.kernels``).
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["shift_linear", "shift_spline", "spline_coefficients"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "shift_linear": "void(float64[:,:,::1], int64[::1], int64[::1], float64[::1], "
                    "float64[:,:,::1], b1[:,::1], boolean)",
    "shift_spline": "void(float64[:,:,::1], int64[::1], int64[::1], float64[::1], "
                    "float64[::1], float64[::1], float64[::1], float64[:,:,::1], "
                    "float64[:,::1], b1[:,::1], boolean)",
}

#: the pole of the cubic B-spline's prefilter, sqrt(3) - 2 (as scipy.ndimage rounds it)
POLE = -0.267949192431122706472553658494127633


@njit(cache=True, nogil=True)
def spline_coefficients(f, j, cols, m, c):
    """c[:, :m] (NX, m of NZ) = the periodic cubic B-spline coefficients along x of the
    columns cols[:m] of the slab j of ``f`` (NX, NY, NZ): the gain, then the causal and
    anticausal recursions with the periodic initial values (Unser, Aldroubi and Eden 1991),
    the operations of scipy.ndimage.spline_filter1d(order=3, mode='grid-wrap') in its order
    (the same bits; each column its own, so a subset of columns gives their same bits).
    One slab at a time: it stays in the cache through the recursions and the shift."""
    nx = c.shape[0]
    z = POLE
    gain = (1.0 - z) * (1.0 - 1.0 / z)
    for i in range(nx):
        for k in range(m):
            c[i, k] = f[i, j, cols[k]] * gain
    zi = z
    for i in range(1, nx):                       # c_0 of the causal pass (periodic)
        for k in range(m):
            c[0, k] += zi * c[nx - i, k]
        zi *= z
    for k in range(m):
        c[0, k] /= 1 - zi
    for i in range(1, nx):
        for k in range(m):
            c[i, k] += z * c[i - 1, k]
    zi = z
    for i in range(nx - 1):                      # c_{n-1} of the anticausal pass
        for k in range(m):
            c[nx - 1, k] += zi * c[i, k]
        zi *= z
    q = z / (zi - 1)
    for k in range(m):
        c[nx - 1, k] *= q
    for i in range(nx - 2, -1, -1):
        for k in range(m):
            c[i, k] = z * (c[i + 1, k] - c[i, k])


@njit(cache=True, nogil=True)
def _columns(lines, j, cols):
    """cols[:m] <- the z indices k with lines[j, k] (all of them without ``lines``: an empty
    (0, 0) array), in order; returns m."""
    nz = cols.size
    if lines.shape[0] == 0:
        for k in range(nz):
            cols[k] = k
        return nz
    m = 0
    for k in range(nz):
        if lines[j, k]:
            cols[m] = k
            m += 1
    return m


@njit(cache=True, nogil=True)
def _clear_others(out, r, j, lines, zero):
    """With ``zero``: out[r, j, k] = 0 where not lines[j, k] (the lines not computed)."""
    if zero and lines.shape[0] != 0:
        for k in range(out.shape[2]):
            if not lines[j, k]:
                out[r, j, k] = 0.0


@njit(cache=True, nogil=True)
def shift_linear(f, rows, base, w, out, lines, zero):
    """out[r, j, k] = (1 - w_j) f[(i - b_j) % nx, j, k] + w_j f[(i - b_j - 1) % nx, j, k],
    i = rows[r]: regrid.shift_rows, method 'linear', of a (NX, NY, NZ) field, on the lines
    (j, k) of ``lines`` (NY, NZ) only (every line: a (0, 0) array); the others are set to 0
    with ``zero``, else not written."""
    nx, ny, nz = f.shape
    cols = np.empty(nz, dtype=np.int64)
    for j in range(ny):
        m = _columns(lines, j, cols)
        wj = w[j]
        vj = 1.0 - wj
        for r in range(rows.size):
            i = rows[r]
            a = (i - base[j]) % nx
            b = (i - base[j] - 1) % nx
            _clear_others(out, r, j, lines, zero)
            for q in range(m):
                k = cols[q]
                out[r, j, k] = vj * f[a, j, k] + wj * f[b, j, k]


@njit(cache=True, nogil=True)
def shift_spline(f, rows, base, w0, w1, w2, w3, out, c, lines, zero):
    """out[r, j, k] = sum_m w_m,j c_j[(p + m - 1) % nx, k], p = rows[r] - b_j - 1, summed in
    the order m = 0..3, c_j the B-spline coefficients of the slab j of ``f`` (NX, NY, NZ)
    (``spline_coefficients`` into the scratch ``c``, (NX, NZ)): regrid.shift_rows, method
    'spline', slab by slab (a whole-field prefilter then a shift read and wrote the field
    five times more); on the lines (j, k) of ``lines`` only, as ``shift_linear``.  A slab
    with none of them costs no prefilter."""
    nx, ny, nz = f.shape
    cols = np.empty(nz, dtype=np.int64)
    for j in range(ny):
        m = _columns(lines, j, cols)
        if m:
            spline_coefficients(f, j, cols, m, c)
        u0, u1, u2, u3 = w0[j], w1[j], w2[j], w3[j]
        for r in range(rows.size):
            p = rows[r] - base[j] - 1
            a0, a1, a2, a3 = (p - 1) % nx, p % nx, (p + 1) % nx, (p + 2) % nx
            _clear_others(out, r, j, lines, zero)
            for q in range(m):
                o = u0 * c[a0, q]
                o += u1 * c[a1, q]
                o += u2 * c[a2, q]
                o += u3 * c[a3, q]
                out[r, j, cols[q]] = o
