"""The row shifts of kapsel.mesh.regrid in one compiled pass per field (numba).

``shift_rows`` gathers each output point from 2 (linear) or 4 (cubic B-spline) points of its
x row and weights them; numpy does that as whole-array index arithmetic, gathers and
temporaries (four to eight passes over the field).  These kernels do the same floating-point
operations in the same order, point by point: the results are bit-identical.  Loaded with the
other compiled kernels (kapsel.mesh.compiled.enable sets ``kapsel.mesh.regrid.kernels``).
"""
from __future__ import annotations

from numba import njit

__all__ = ["shift_linear", "shift_spline", "spline_coefficients"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "shift_linear": "void(float64[:,:,::1], int64[::1], int64[::1], float64[::1], float64[:,:,::1])",
    "shift_spline": "void(float64[:,:,::1], int64[::1], int64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[:,:,::1], float64[:,::1])",
}

#: the pole of the cubic B-spline's prefilter, sqrt(3) - 2 (as scipy.ndimage rounds it)
POLE = -0.267949192431122706472553658494127633


@njit(cache=True, nogil=True)
def spline_coefficients(f, j, c):
    """c (NX, NZ) = the periodic cubic B-spline coefficients along x of the slab j of ``f``
    (NX, NY, NZ): the gain, then the causal and anticausal recursions with the periodic
    initial values (Unser, Aldroubi and Eden 1991), the operations of
    scipy.ndimage.spline_filter1d(order=3, mode='grid-wrap') in its order (the same bits).
    One slab at a time: it stays in the cache through the recursions and the shift."""
    nx, nz = c.shape
    z = POLE
    gain = (1.0 - z) * (1.0 - 1.0 / z)
    for i in range(nx):
        for k in range(nz):
            c[i, k] = f[i, j, k] * gain
    zi = z
    for i in range(1, nx):                       # c_0 of the causal pass (periodic)
        for k in range(nz):
            c[0, k] += zi * c[nx - i, k]
        zi *= z
    for k in range(nz):
        c[0, k] /= 1 - zi
    for i in range(1, nx):
        for k in range(nz):
            c[i, k] += z * c[i - 1, k]
    zi = z
    for i in range(nx - 1):                      # c_{n-1} of the anticausal pass
        for k in range(nz):
            c[nx - 1, k] += zi * c[i, k]
        zi *= z
    q = z / (zi - 1)
    for k in range(nz):
        c[nx - 1, k] *= q
    for i in range(nx - 2, -1, -1):
        for k in range(nz):
            c[i, k] = z * (c[i + 1, k] - c[i, k])


@njit(cache=True, nogil=True)
def shift_linear(f, rows, base, w, out):
    """out[r, j, k] = (1 - w_j) f[(i - b_j) % nx, j, k] + w_j f[(i - b_j - 1) % nx, j, k],
    i = rows[r]: regrid.shift_rows, method 'linear', of a (NX, NY, NZ) field."""
    nx, ny, nz = f.shape
    for r in range(rows.size):
        i = rows[r]
        for j in range(ny):
            a = (i - base[j]) % nx
            b = (i - base[j] - 1) % nx
            wj = w[j]
            vj = 1.0 - wj
            for k in range(nz):
                out[r, j, k] = vj * f[a, j, k] + wj * f[b, j, k]


@njit(cache=True, nogil=True)
def shift_spline(f, rows, base, w0, w1, w2, w3, out, c):
    """out[r, j, k] = sum_m w_m,j c_j[(p + m - 1) % nx, k], p = rows[r] - b_j - 1, summed in
    the order m = 0..3, c_j the B-spline coefficients of the slab j of ``f`` (NX, NY, NZ)
    (``spline_coefficients`` into the scratch ``c``, (NX, NZ)): regrid.shift_rows, method
    'spline', slab by slab (a whole-field prefilter then a shift read and wrote the field
    five times more)."""
    nx, ny, nz = f.shape
    for j in range(ny):
        spline_coefficients(f, j, c)
        u0, u1, u2, u3 = w0[j], w1[j], w2[j], w3[j]
        for r in range(rows.size):
            p = rows[r] - base[j] - 1
            a0, a1, a2, a3 = (p - 1) % nx, p % nx, (p + 1) % nx, (p + 2) % nx
            for k in range(nz):
                o = u0 * c[a0, k]
                o += u1 * c[a1, k]
                o += u2 * c[a2, k]
                o += u3 * c[a3, k]
                out[r, j, k] = o
