"""Fused element-wise passes of the Electrolyte's ions (kapsel.fluid.ions), compiled.

Each kernel does in one sweep what Ions.step did in two to five whole-field numpy passes, with
the same floating-point operations in the same order: the real ones give the numpy passes'
bits; the complex ones (a complex times i k, or times a real) are computed as the real
products numpy's complex product reduces to when one factor's real or imaginary part is 0,
up to the sign of zero results (as kapsel.fluid.spectral_kernels).  Loaded on demand by
kapsel.mesh.compiled (slot ``ions``), ahead of time by kapsel.build_kernels.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..mesh.point_sums import add_at

__all__ = ["gradient_component", "charge_density",
           "scale_potential", "coulomb_force", "mask_scaled", "divergence_accumulate",
           "divergence_euler", "flux", "bin_sum"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "gradient_component": "void(complex128[:,:,::1], float64[::1], int64, float64, "
                          "complex128[:,:,::1])",
    "charge_density": "void(float64[:,:,:,::1], float64[::1], float64[:,:,::1], "
                      "float64[:,:,::1], float64[:,:,::1])",
    "scale_potential": "void(complex128[:,:,::1], float64[:,:,::1], float64, "
                       "float64[:,:,::1], boolean)",
    "coulomb_force": "void(float64[::1], float64[:,:,:,::1], float64[:,:,::1], "
                     "float64[:,:,::1], float64, float64[:,:,:,::1])",
    "mask_scaled": "void(complex128[:,:,::1], float64[:,:,::1], float64, complex128[:,:,::1])",
    "divergence_accumulate": "void(complex128[:,:,::1], float64[::1], int64, "
                             "complex128[:,:,::1])",
    "divergence_euler": "void(complex128[:,:,::1], float64[::1], complex128[:,:,::1], "
                        "float64[:,:,::1], float64, float64, boolean, complex128[:,:,::1])",
    "flux": "void(float64[:,:,:,::1], float64[:,:,:,::1], float64[::1], float64[:,:,::1], "
            "float64, float64, float64[:,:,:,::1], boolean, int64[::1], float64[:,::1], "
            "float64[::1])",
    "bin_sum": "void(int64[:,::1], float64[:,::1], float64[:,:,::1])",
}


@njit(inline="always")
def _k_of(k_axis, axis, i, j, k):
    """The wavenumber of ``axis`` (0, 1, 2) at mode (i, j, k), k_axis its 1-d array."""
    return k_axis[i] if axis == 0 else (k_axis[j] if axis == 1 else k_axis[k])


@njit(inline="always")
def _times_ik(f, kk):
    """i kk f, as numpy's complex product with (0, kk) (up to the sign of zero results)."""
    return complex(-(f.imag * kk), f.real * kk)


@njit(inline="always")
def _scale(z, s):
    return complex(z.real * s, z.imag * s)


@njit(cache=True, nogil=True)
def gradient_component(f_hat, k_axis, axis, scale, out):
    """out = (i k_axis f_hat) scale on the half spectrum; k_axis the wavenumbers of ``axis``
    (0, 1, 2) as a 1-d array."""
    nx, ny, nzc = f_hat.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                out[i, j, k] = _scale(_times_ik(f_hat[i, j, k], _k_of(k_axis, axis, i, j, k)),
                                      scale)


@njit(cache=True, nogil=True)
def charge_density(c, z, phi, rho_surf, out):
    """out <- (sum_s z_s c_s) (1 - phi) + rho_surf: rho_e of Ions.charge_density, the sum
    over the species in their order from 0 (from 0.0), made along a row at a time in the
    scratch ``acc`` (the species' loop innermost did not vectorise: 3x slower at 64^3)."""
    ns = c.shape[0]
    nx, ny, nz = out.shape
    acc = np.empty(nz)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                acc[k] = 0.0
            for s in range(ns):
                zs = z[s]
                for k in range(nz):
                    acc[k] = acc[k] + zs * c[s, i, j, k]
            for k in range(nz):
                out[i, j, k] = acc[k] * (1.0 - phi[i, j, k]) + rho_surf[i, j, k]


@njit(cache=True, nogil=True)
def scale_potential(h, inv_k2, eps, mask, truncate):
    """h <- ((h inv_k2) / eps) (mask if ``truncate``): Psi_hat of rho_e_hat (Ions.potential)."""
    nx, ny, nzc = h.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                f = h[i, j, k]
                w = inv_k2[i, j, k]
                re = (f.real * w) / eps
                im = (f.imag * w) / eps
                if truncate:
                    m = mask[i, j, k]
                    re = re * m
                    im = im * m
                h[i, j, k] = complex(re, im)


@njit(cache=True, nogil=True)
def coulomb_force(E, g, rho_e, rho_surf, scale, out):
    """out_d <- ((E_d - g_d) (rho_e - rho_surf)) scale, d = 0, 1, 2: the ions' Coulomb
    force density (Ions.coulomb_force) times ``scale``; rho_e may be out[0] (each point's
    rho_e is read before its force is written)."""
    nx, ny, nz = rho_e.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                rho = rho_e[i, j, k] - rho_surf[i, j, k]
                for d in range(3):
                    out[d, i, j, k] = ((E[d] - g[d, i, j, k]) * rho) * scale


@njit(cache=True, nogil=True)
def mask_scaled(h, mask, scale, out):
    """h <- h mask (in place) and out <- h mask scale (the 1/N of a c2r)."""
    nx, ny, nzc = h.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                f = _scale(h[i, j, k], mask[i, j, k])
                h[i, j, k] = f
                out[i, j, k] = _scale(f, scale)


@njit(cache=True, nogil=True)
def divergence_accumulate(cs, k_axis, axis, ch):
    """The divergence i k . J_hat a component at a time, cs = FFT(J_axis): axis 0:
    ch <- i k_0 cs; axis 1: ch <- ch + i k_1 cs (axis 2: divergence_euler)."""
    nx, ny, nzc = cs.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                p = _times_ik(cs[i, j, k], _k_of(k_axis, axis, i, j, k))
                if axis == 0:
                    ch[i, j, k] = p
                else:
                    a = ch[i, j, k]
                    ch[i, j, k] = complex(a.real + p.real, a.imag + p.imag)


@njit(cache=True, nogil=True)
def divergence_euler(cs, k_axis, ch, mask, dt, scale, zero_mode, c_hat):
    """The divergence's last component and the Euler step of a species' spectrum: with
    cs = FFT(J_2), d = (ch + i k_2 cs) mask (the k = 0 mode 0 when ``zero_mode``: this block
    holds it), c_hat <- c_hat + d dt and cs <- c_hat scale (the 1/N of the c2r of c)."""
    nx, ny, nzc = cs.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                p = _times_ik(cs[i, j, k], k_axis[k])
                a = ch[i, j, k]
                p = _scale(complex(a.real + p.real, a.imag + p.imag), mask[i, j, k])
                if zero_mode and i == 0 and j == 0 and k == 0:
                    p = complex(0.0, 0.0)
                p = _scale(p, dt)
                h = c_hat[i, j, k]
                h = complex(h.real + p.real, h.imag + p.imag)
                c_hat[i, j, k] = h
                cs[i, j, k] = _scale(h, scale)


@njit(cache=True, nogil=True)
def flux(J, g, E, c, a, b, u, advect, at, n, inv_n2):
    """A species' flux in one pass, as Ions.step's numpy passes make it: J_d <- J_d a +
    ((g_d - E_d) c) b (J = grad c on entry, g = grad Psi); at the surface points ``at``
    (flat indices, ascending) J <- J - n (J.n) / |n|^2 (n (3, P), inv_n2 = 1 / |n|^2);
    then, with ``advect``, J_d <- J_d - c u_d.  A row without surface points is swept
    without their test (vectorised: 1.6x faster at 64^3), the same operations."""
    nx, ny, nz = c.shape
    P = at.shape[0]
    e0, e1, e2 = E[0], E[1], E[2]
    q = 0
    for i in range(nx):
        for j in range(ny):
            base = (i * ny + j) * nz
            surface = q < P and at[q] < base + nz     # a surface point in this row
            for k in range(nz):
                cc = c[i, j, k]
                j0 = J[0, i, j, k] * a + ((g[0, i, j, k] - e0) * cc) * b
                j1 = J[1, i, j, k] * a + ((g[1, i, j, k] - e1) * cc) * b
                j2 = J[2, i, j, k] * a + ((g[2, i, j, k] - e2) * cc) * b
                if surface and q < P and at[q] == base + k:
                    tn = j0 * n[0, q]
                    tn = tn + j1 * n[1, q]
                    tn = tn + j2 * n[2, q]
                    tn = tn * inv_n2[q]
                    j0 = j0 - tn * n[0, q]
                    j1 = j1 - tn * n[1, q]
                    j2 = j2 - tn * n[2, q]
                    q += 1
                if advect:
                    j0 = j0 - cc * u[0, i, j, k]
                    j1 = j1 - cc * u[1, i, j, k]
                    j2 = j2 - cc * u[2, i, j, k]
                J[0, i, j, k] = j0
                J[1, i, j, k] = j1
                J[2, i, j, k] = j2


@njit(cache=True, nogil=True)
def bin_sum(idx, w, out):
    """out (a field) <- 0, then out.flat[idx[i, j]] += w[i, j] in the order of the points:
    ``np.bincount(idx.ravel(), weights=w.ravel(), minlength=out.size)`` (its additions in its
    order from 0, so the same bits) written into the field, with no full-mesh temporary."""
    flat = out.reshape(-1)
    for p in range(flat.size):
        flat[p] = 0.0
    add_at(flat, idx, w)
