"""Compiled (numba) stencil kernels of the MAC solver (kapsel.fluid.mac, kapsel.fluid.operators).

One sweep over the grid per operator, periodic neighbours by index wrap, no shifted copies:
the numpy versions in kapsel.fluid.operators make 10-60 whole-field slice copies per call.
Every kernel does the same floating-point operations in the same order as the code it
replaces, so results are bit-identical (tests/test_mac.py).  ``cache=True``: compiled once
per machine, kept in __pycache__.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["implicit_matvec", "laplacian_nu", "advection", "div_b", "grad_b"]


@njit(cache=True, nogil=True)
def implicit_matvec(x, ustar, a, c, out):
    """out = A x for the implicit MAC operator with constant viscosity, A = I + dt/2 N(u*, .)
    - dt/2 nu lap (kapsel.fluid.mac.MACSolver._assemble, its CSR rows applied slot by slot in
    the same order: centre, +x, -x, +y, -y, +z, -z).

    x, out : (3, NX, NY, NZ);  a = dt / (4 DX)  (the advection weight h / (2 DX));
    c = dt/2 nu / DX^2.
    """
    nc, nx, ny, nz = x.shape
    d0 = 1.0 + 6.0 * c
    for i in range(nc):
        for p in range(nx):
            pp = p + 1 if p + 1 < nx else 0
            pm = p - 1 if p > 0 else nx - 1
            for q in range(ny):
                qp = q + 1 if q + 1 < ny else 0
                qm = q - 1 if q > 0 else ny - 1
                for r in range(nz):
                    rp = r + 1 if r + 1 < nz else 0
                    rm = r - 1 if r > 0 else nz - 1
                    s = d0 * x[i, p, q, r]
                    s += (ustar[0, pp, q, r] * a - c) * x[i, pp, q, r]
                    s += (ustar[0, pm, q, r] * (-a) - c) * x[i, pm, q, r]
                    s += (ustar[1, p, qp, r] * a - c) * x[i, p, qp, r]
                    s += (ustar[1, p, qm, r] * (-a) - c) * x[i, p, qm, r]
                    s += (ustar[2, p, q, rp] * a - c) * x[i, p, q, rp]
                    s += (ustar[2, p, q, rm] * (-a) - c) * x[i, p, q, rm]
                    out[i, p, q, r] = s
