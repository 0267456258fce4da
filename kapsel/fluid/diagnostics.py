"""Derived fluid fields for output: pressure at the nodes, viscous stress, spectral pressure.

All fields are float64 arrays indexed [x, y, z]; vectors (3, NX, NY, NZ); the stress is
(5, NX, NY, NZ) with the components xx, xy, xz, yy, yz of

    tau_ab = eta (d_a u_b + d_b u_a)          (viscous stress, pressure not included)

(FORMAT-OUTPUT.md §2.4: the original's AVS / EXTENDED ``tau_*``).
"""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft

PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2))       # xx, xy, xz, yy, yz


def pressure_at_nodes(p_cells: np.ndarray) -> np.ndarray:
    """B-grid pressure (cell centres (i+1/2, j+1/2, k+1/2) DX, kapsel.mesh.operators) at the
    nodes i DX: the mean of the 8 cells around each node."""
    q = p_cells + np.roll(p_cells, 1, axis=0)
    q = q + np.roll(q, 1, axis=1)
    q = q + np.roll(q, 1, axis=2)
    q *= 0.125
    return q


def stress_from_gradient(grad: np.ndarray, eta) -> np.ndarray:
    """tau (5, ...) from grad[a, b] = d_b u_a (shape (3, 3, NX, NY, NZ)) and eta (scalar or
    field)."""
    tau = np.empty((5,) + grad.shape[2:])
    for n, (a, b) in enumerate(PAIRS):
        np.add(grad[a, b], grad[b, a], out=tau[n])
        tau[n] *= eta
    return tau


def velocity_gradient_central(u: np.ndarray, dx: float, gradient=None) -> np.ndarray:
    """grad[a, b] = d_b u_a by central differences at the nodes (periodic grid);
    ``gradient(f, out)`` replaces the central gradient (e.g. the oblique frame's)."""
    from ..mesh.operators import grad_central
    g = np.empty((3, 3) + u.shape[1:])
    for a in range(3):
        if gradient is None:
            grad_central(u[a], dx, out=g[a])
        else:
            gradient(u[a], g[a])
    return g


def _wavenumbers(shape, dx):
    """Integer-mode wavenumbers of rfftn over [x, y, z], Nyquist modes set to 0 (a first
    derivative of a real field has no Nyquist part)."""
    ks = []
    for ax, n in enumerate(shape):
        k = (2 * np.pi / (n * dx)) * (np.fft.rfftfreq(n) * n if ax == 2 else np.fft.fftfreq(n) * n)
        if n % 2 == 0:
            k[n // 2] = 0.0
        sh = [1, 1, 1]
        sh[ax] = -1
        ks.append(k.reshape(sh))
    return ks


def velocity_gradient_spectral(u: np.ndarray, dx: float, strain: float = 0.0) -> np.ndarray:
    """grad[a, b] = d_b u_a (Cartesian derivatives) of a periodic field by FFT.

    ``strain`` g: u lives on the oblique grid x^ = x - g y (periodic in x^, y, z), where
    d_x = d_x^, d_y = d_y^ - g d_x^, d_z = d_z^."""
    shape = u.shape[1:]
    kx, ky, kz = _wavenumbers(shape, dx)
    ky = ky - strain * kx
    g = np.empty((3, 3) + shape)
    for a in range(3):
        uh = sfft.rfftn(u[a])
        for b, k in enumerate((kx, ky, kz)):
            g[a, b] = sfft.irfftn(1j * k * uh, s=shape, axes=(0, 1, 2))
    return g


def viscous_stress_spectral(u: np.ndarray, dx: float, eta: float,
                            strain: float = 0.0) -> np.ndarray:
    """tau (5, ...) of a periodic field by FFT: tau_ab^ = i eta (k_a u_b^ + k_b u_a^), five
    inverse transforms (``strain``: as velocity_gradient_spectral)."""
    shape = u.shape[1:]
    kx, ky, kz = _wavenumbers(shape, dx)
    ks = (kx, ky - strain * kx, kz)
    uh = [sfft.rfftn(u[a]) for a in range(3)]
    tau = np.empty((5,) + shape)
    for n, (a, b) in enumerate(PAIRS):
        th = (1j * eta) * (ks[a] * uh[b] + ks[b] * uh[a])
        tau[n] = sfft.irfftn(th, s=shape, axes=(0, 1, 2))
    return tau


def spectral_pressure(u: np.ndarray, du: np.ndarray | None, rho: float, dt: float,
                      dx: float, rate: float = 0.0, strain: float = 0.0) -> np.ndarray:
    """Pressure of the incompressible flow u on a periodic grid (zero mean):

        lap p = -RHO d_i d_j (u_i u_j) + div f,   f = RHO du / dt

    with du the particles' rigidity increment of the last step (the SPM body force, whose
    longitudinal part the projection removes); in Fourier space
    p^ = -(RHO k_i k_j (u_i u_j)^ + i k . f^) / k^2  (k = 0: 0).

    Lees-Edwards (``rate`` gamma_dot, ``strain`` g of the oblique grid, u the deviation from
    U = gamma_dot y e_x on that grid): the advection by U and the term u_y dU/dx add
    div(U . grad u + u_y gamma_dot e_x) = 2 gamma_dot d_x u_y to the divergence of the
    momentum equation, so p^ gets + 2 i RHO gamma_dot k_x u_y^ / k^2 (k the Cartesian wave
    vector, k_y = k_y^ - g k_x^)."""
    shape = u.shape[1:]
    kx, ky, kz = _wavenumbers(shape, dx)
    ks = (kx, ky - strain * kx, kz)
    k2 = ks[0] ** 2 + ks[1] ** 2 + ks[2] ** 2
    zero = k2 == 0.0                       # the mean and the all-Nyquist modes
    k2[zero] = 1.0
    ph = np.zeros(k2.shape, dtype=complex)
    for a in range(3):
        for b in range(a, 3):
            w = (1.0 if a == b else 2.0) * rho
            ph -= w * ks[a] * ks[b] * sfft.rfftn(u[a] * u[b])
    if rate != 0.0:
        ph += (2j * rho * rate) * ks[0] * sfft.rfftn(u[1])
    if du is not None:
        for a in range(3):
            ph -= 1j * (rho / dt) * ks[a] * sfft.rfftn(du[a])
    ph /= k2
    ph[zero] = 0.0
    return sfft.irfftn(ph, s=shape, axes=(0, 1, 2))
