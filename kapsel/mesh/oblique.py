"""Operators of the oblique (sheared) frame (manual §5.1, eqs 27-29): a vector's contravariant
and Cartesian components in the frame of strain g (u^1 = u_x - g u_y), and the metric's
central differences on the oblique grid, G^jk d^_j d^_k and the physical gradient
(d_y = D_2 - g D_1).  What the Lees-Edwards fluids (kapsel.fluid.oblique) and the oblique
Cahn-Hilliard step (kapsel.phase.oblique) both stand on."""
from __future__ import annotations

import numpy as np

__all__ = ["contravariant", "cartesian", "oblique_laplacian", "oblique_gradient",
           "oblique_viscous_variable"]


def contravariant(u, g, out=None):
    """Cartesian (3, ...) -> contravariant components of the frame with strain g."""
    out = np.array(u, dtype=float, copy=True) if out is None else out
    if out is not u:
        np.copyto(out, u)
    out[0] -= g * u[1]
    return out


def cartesian(u, g, out=None):
    """Contravariant (3, ...) -> Cartesian components."""
    out = np.array(u, dtype=float, copy=True) if out is None else out
    if out is not u:
        np.copyto(out, u)
    out[0] += g * u[1]
    return out


def _d11(f, dx, out):
    """Second difference along x (periodic), f[i+1] - 2 f[i] + f[i-1] over DX^2."""
    from .operators import shift_add
    np.multiply(f, -2.0, out=out)
    shift_add(out, f, 1, 0)
    shift_add(out, f, -1, 0)
    out *= 1.0 / (dx * dx)
    return out


def _d12(f, dx, out, work=None):
    """Mixed central difference d^2 f / dx dy on the nodes (4 diagonal neighbours):
    the central y difference of the central x difference."""
    from .operators import cdiff_acc
    t = np.empty_like(f) if work is None else work
    t[...] = 0.0
    cdiff_acc(t, f, 0)
    out[...] = 0.0
    cdiff_acc(out, t, 1)
    out *= 1.0 / (4.0 * dx * dx)
    return out


def oblique_laplacian(f, dx, g, out, work=None):
    """G^jk d^_j d^_k f = (lap + g^2 D_xx - 2 g D_xy) f on the oblique grid (sums to zero)."""
    from .operators import laplacian
    laplacian(f, dx, out)
    if g:
        t = np.empty_like(f) if work is None else work
        _d11(f, dx, t)
        out += (g * g) * t
        _d12(f, dx, t)
        out -= (2.0 * g) * t
    return out


def oblique_gradient(f, dx, g, out):
    """Physical (Cartesian) central gradient on the oblique grid: d_x = D_1,
    d_y = D_2 - g D_1, d_z = D_3."""
    from .operators import cdiff_acc
    for ax in range(3):
        out[ax] = 0.0
        cdiff_acc(out[ax], f, ax)
    out *= 0.5 / dx
    if g:
        out[1] -= g * out[0]
    return out


def oblique_viscous_variable(u, eta, dx, g):
    """div(eta (grad u + grad u^T)) of the Cartesian u on the oblique grid with the physical
    central gradient (``oblique_gradient``), Cartesian result."""
    grads = np.empty((3, 3) + u.shape[1:])
    for a in range(3):
        oblique_gradient(u[a], dx, g, grads[a])      # grads[a, b] = d_b u_a
    out = np.zeros_like(u)
    t = np.empty((3,) + u.shape[1:])
    for a in range(3):
        for b in range(3):
            tau = eta * (grads[a, b] + grads[b, a])
            oblique_gradient(tau, dx, g, t)
            out[a] += t[b]
    return out
