"""Compiled (numba) stencil kernels of the MAC solver (kapsel.fluid.mac, kapsel.mesh.operators).

One sweep over the grid per operator, periodic neighbours by index wrap, no shifted copies:
the numpy versions in kapsel.mesh.operators make 10-60 whole-field slice copies per call.
Every kernel does the same floating-point operations in the same order as the code it
replaces, so results are bit-identical (tests/unit/test_mac.py).  ``cache=True``: compiled once
per machine, kept in __pycache__; loaded on demand by kapsel.mesh.compiled.
"""
from __future__ import annotations

from numba import njit

__all__ = ["implicit_matvec_nc", "laplacian", "advection", "advection_nc", "div_b",
           "grad_b"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "implicit_matvec_nc": "void(float64[:,:,:,::1], float64[:,:,:,::1], float64, float64, float64[:,:,:,::1])",
    "advection_nc": "void(float64[:,:,:,::1], float64, float64[:,:,:,::1])",
    "laplacian": "void(float64[:,:,:,::1], float64, float64[:,:,:,::1])",
    "advection": "void(float64[:,:,:,::1], float64, float64[:,:,:,::1])",
    "div_b": "void(float64[:,:,:,::1], float64, float64[:,:,::1])",
    "grad_b": "void(float64[:,:,::1], float64, float64[:,:,:,::1])",
    "ab2_update": "void(float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], "
                  "float64, boolean)",
    "sub_scaled": "void(float64[::1], float64[::1], float64)",
}


@njit(cache=True, nogil=True)
def implicit_matvec_nc(x, ustar, a, c, out):
    """out = A x for the implicit MAC operator of the original (non-conservative advection
    u*.grad, fdm_matrix_solver.cxx NS_MAC_solver_implicit), A = I + dt/2 (u*.grad) - dt/2
    nu lap (kapsel.fluid.mac.MACSolver._assemble's slots in the same order: centre, +x, -x,
    +y, -y, +z, -z).  a = dt / (4 DX), c = dt/2 nu / DX^2."""
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
                    u0 = ustar[0, p, q, r]
                    u1 = ustar[1, p, q, r]
                    u2 = ustar[2, p, q, r]
                    s = d0 * x[i, p, q, r]
                    s += (u0 * a - c) * x[i, pp, q, r]
                    s += (u0 * (-a) - c) * x[i, pm, q, r]
                    s += (u1 * a - c) * x[i, p, qp, r]
                    s += (u1 * (-a) - c) * x[i, p, qm, r]
                    s += (u2 * a - c) * x[i, p, q, rp]
                    s += (u2 * (-a) - c) * x[i, p, q, rm]
                    out[i, p, q, r] = s


@njit(cache=True, nogil=True)
def advection_nc(u, scale, out):
    """out_c = u_x D_x u_c + u_y D_y u_c + u_z D_z u_c, D_j f = (f[+e_j] - f[-e_j]) * scale
    (operators.advection_nc_linear's order of operations; scale = 1/(2 DX))."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for p in range(nx):
        pp = p + 1 if p + 1 < nx else 0
        pm = p - 1 if p > 0 else nx - 1
        for q in range(ny):
            qp = q + 1 if q + 1 < ny else 0
            qm = q - 1 if q > 0 else ny - 1
            for r in range(nz):
                rp = r + 1 if r + 1 < nz else 0
                rm = r - 1 if r > 0 else nz - 1
                u0 = u[0, p, q, r]
                u1 = u[1, p, q, r]
                u2 = u[2, p, q, r]
                for c in range(3):
                    s = u0 * ((u[c, pp, q, r] - u[c, pm, q, r]) * scale)
                    s += u1 * ((u[c, p, qp, r] - u[c, p, qm, r]) * scale)
                    s += u2 * ((u[c, p, q, rp] - u[c, p, q, rm]) * scale)
                    out[c, p, q, r] = s


@njit(cache=True, nogil=True)
def laplacian(f, scale, out):
    """out = (-6 f + f[+x] + f[-x] + f[+y] + f[-y] + f[+z] + f[-z]) * scale for (m, NX, NY,
    NZ) arrays (operators.laplacian's order of sums; scale = 1/DX^2)."""
    nc, nx, ny, nz = f.shape
    for c in range(nc):
        for p in range(nx):
            pp = p + 1 if p + 1 < nx else 0
            pm = p - 1 if p > 0 else nx - 1
            for q in range(ny):
                qp = q + 1 if q + 1 < ny else 0
                qm = q - 1 if q > 0 else ny - 1
                for r in range(nz):
                    rp = r + 1 if r + 1 < nz else 0
                    rm = r - 1 if r > 0 else nz - 1
                    s = f[c, p, q, r] * -6.0
                    s += f[c, pp, q, r]
                    s += f[c, pm, q, r]
                    s += f[c, p, qp, r]
                    s += f[c, p, qm, r]
                    s += f[c, p, q, rp]
                    s += f[c, p, q, rm]
                    out[c, p, q, r] = s * scale


@njit(cache=True, nogil=True)
def advection(u, scale, out):
    """out_c = sum_j [(u_c u_j)(n + e_j) - (u_c u_j)(n - e_j)] * scale (operators.advection's
    order of sums; scale = 1/(2 DX))."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for p in range(nx):
        pp = p + 1 if p + 1 < nx else 0
        pm = p - 1 if p > 0 else nx - 1
        for q in range(ny):
            qp = q + 1 if q + 1 < ny else 0
            qm = q - 1 if q > 0 else ny - 1
            for r in range(nz):
                rp = r + 1 if r + 1 < nz else 0
                rm = r - 1 if r > 0 else nz - 1
                for c in range(3):
                    s = 0.0
                    s += u[c, pp, q, r] * u[0, pp, q, r]
                    s -= u[c, pm, q, r] * u[0, pm, q, r]
                    s += u[c, p, qp, r] * u[1, p, qp, r]
                    s -= u[c, p, qm, r] * u[1, p, qm, r]
                    s += u[c, p, q, rp] * u[2, p, q, rp]
                    s -= u[c, p, q, rm] * u[2, p, q, rm]
                    out[c, p, q, r] = s * scale


@njit(inline="always")
def _wrap(i, n):
    if i >= n:
        return i - n
    if i < 0:
        return i + n
    return i


@njit(cache=True, nogil=True)
def div_b(u, scale, out):
    """B-grid divergence (operators.div_b, the same averages in the same order):
    out = [avg_y avg_z d_x u_x + avg_x avg_z d_y u_y  ...] with the association of div_b."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for p in range(nx):
        p1 = _wrap(p + 1, nx)
        for q in range(ny):
            q1 = _wrap(q + 1, ny)
            for r in range(nz):
                r1 = _wrap(r + 1, nz)
                # C(k) = avg_y(d_x u_x) + avg_x(d_y u_y) at z = r and r + 1
                a0 = ((u[0, p1, q1, r] - u[0, p, q1, r]) + (u[0, p1, q, r] - u[0, p, q, r])) * 0.5
                b0 = ((u[1, p1, q1, r] - u[1, p1, q, r]) + (u[1, p, q1, r] - u[1, p, q, r])) * 0.5
                a1 = ((u[0, p1, q1, r1] - u[0, p, q1, r1])
                      + (u[0, p1, q, r1] - u[0, p, q, r1])) * 0.5
                b1 = ((u[1, p1, q1, r1] - u[1, p1, q, r1])
                      + (u[1, p, q1, r1] - u[1, p, q, r1])) * 0.5
                z = ((a1 + b1) + (a0 + b0)) * 0.5
                # avg_y avg_x d_z u_z
                t0 = ((u[2, p1, q, r1] - u[2, p1, q, r]) + (u[2, p, q, r1] - u[2, p, q, r])) * 0.5
                t1 = ((u[2, p1, q1, r1] - u[2, p1, q1, r])
                      + (u[2, p, q1, r1] - u[2, p, q1, r])) * 0.5
                w = (t1 + t0) * 0.5
                out[p, q, r] = (w + z) * scale


@njit(cache=True, nogil=True)
def grad_b(f, scale, out):
    """B-grid gradient (operators.grad_b, the same averages in the same order)."""
    nx, ny, nz = f.shape
    for p in range(nx):
        pm = _wrap(p - 1, nx)
        for q in range(ny):
            qm = _wrap(q - 1, ny)
            for r in range(nz):
                rm = _wrap(r - 1, nz)
                # t0 = avg_z^- f at (p, q), (pm, q), (p, qm), (pm, qm)
                t_pq = (f[p, q, rm] + f[p, q, r]) * 0.5
                t_mq = (f[pm, q, rm] + f[pm, q, r]) * 0.5
                t_pm = (f[p, qm, rm] + f[p, qm, r]) * 0.5
                t_mm = (f[pm, qm, rm] + f[pm, qm, r]) * 0.5
                # x: avg_y^- of bdiff_x t0
                out[0, p, q, r] = ((t_pm - t_mm) + (t_pq - t_mq)) * 0.5 * scale
                # y: avg_x^- of bdiff_y t0
                out[1, p, q, r] = ((t_mq - t_mm) + (t_pq - t_pm)) * 0.5 * scale
                # z: bdiff_z of avg_y^- avg_x^- f
                s_r = ((f[pm, qm, r] + f[p, qm, r]) * 0.5 + (f[pm, q, r] + f[p, q, r]) * 0.5) * 0.5
                s_m = ((f[pm, qm, rm] + f[p, qm, rm]) * 0.5
                       + (f[pm, q, rm] + f[p, q, rm]) * 0.5) * 0.5
                out[2, p, q, r] = (s_r - s_m) * scale


@njit(cache=True, nogil=True)
def ab2_update(u, n, n_old, lap, w, dt, ab2):
    """The explicit MAC step's update (kapsel.fluid.mac MACSolver._explicit) in one pass over
    flat fields, its numpy passes' operations in their order: ``ab2``: u <- u - (n (1.5 dt) -
    (0.5 dt) n_old), else u <- u - dt n; then n_old <- n, u <- u + dt lap, w <- n - lap."""
    a = 1.5 * dt
    b = 0.5 * dt
    for i in range(u.size):
        x = n[i]
        if ab2:
            uu = u[i] - (x * a - b * n_old[i])
        else:
            uu = u[i] - dt * x
        n_old[i] = x
        u[i] = uu + dt * lap[i]
        w[i] = x - lap[i]


@njit(cache=True, nogil=True)
def sub_scaled(u, g, s):
    """u <- u - g s over flat fields."""
    for i in range(u.size):
        u[i] = u[i] - g[i] * s
