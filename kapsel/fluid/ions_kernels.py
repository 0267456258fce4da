"""Fused element-wise passes of the Electrolyte's ions (kapsel.fluid.ions), compiled.

Each kernel does in one sweep what Ions.step did in two to five whole-field numpy passes, with
the same floating-point operations in the same order: the real ones give the numpy passes'
bits; the complex ones (a complex times i k, or times a real) are computed as the real
products numpy's complex product reduces to when one factor's real or imaginary part is 0,
up to the sign of zero results (as kapsel.fluid.spectral_kernels).  Loaded on demand by
kapsel.mesh.compiled (slot ``ions``), ahead of time by kapsel.build_kernels.
"""
from __future__ import annotations

from numba import njit

__all__ = ["flux_component", "advect_component", "gradient_component"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "flux_component": "void(float64[:,:,::1], float64[:,:,::1], float64, float64[:,:,::1], "
                      "float64, float64)",
    "advect_component": "void(float64[:,:,::1], float64[:,:,::1], float64[:,:,::1])",
    "gradient_component": "void(complex128[:,:,::1], float64[::1], int64, float64, "
                          "complex128[:,:,::1])",
}


@njit(cache=True, nogil=True)
def flux_component(J, g, e, c, a, b):
    """J <- J a + ((g - e) c) b: one axis of a species' diffusive (J = grad c on entry) and
    migrative flux, g that axis of grad Psi, e of the external field, a = L kBT, b = L z."""
    nx, ny, nz = J.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                J[i, j, k] = J[i, j, k] * a + ((g[i, j, k] - e) * c[i, j, k]) * b


@njit(cache=True, nogil=True)
def advect_component(J, c, u):
    """J <- J - c u: the advective flux of one axis."""
    nx, ny, nz = J.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                J[i, j, k] = J[i, j, k] - c[i, j, k] * u[i, j, k]


@njit(cache=True, nogil=True)
def gradient_component(f_hat, k_axis, axis, scale, out):
    """out = (i k_axis f_hat) scale on the half spectrum; k_axis the wavenumbers of ``axis``
    (0, 1, 2) as a 1-d array."""
    nx, ny, nzc = f_hat.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                kk = k_axis[i] if axis == 0 else (k_axis[j] if axis == 1 else k_axis[k])
                f = f_hat[i, j, k]
                out[i, j, k] = complex((-(f.imag * kk)) * scale, (f.real * kk) * scale)
