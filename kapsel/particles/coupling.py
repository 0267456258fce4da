"""Particle-fluid coupling of the SPM on stencil arrays from ``profile.particle_profiles``.

* ``particle_velocity_field``: phi u_p = sum_i (V_i + Omega_i x r) phi_i      (eq 6)
* ``hydro_force_torque``: momentum exchange form of eqs 11-12 (Nakayama, Kim & Yamamoto,
  EPJE 26, 361 (2008)) with u* the fluid velocity after the fluid step,
      F_i dt = RHO DX^3 sum_x phi_i (u* - V_i - Omega_i x r)
      N_i dt = RHO DX^3 sum_x r x phi_i (u* - V_i - Omega_i x r)
* ``rigidity_increment``: du = sum_i phi_i (V_i + Omega_i x r) - phi u, the body force
  phi f_p dt of eq 8 before the pressure (solenoidal) projection.

idx (N, S) flat indices, phi (N, S), r (N, S, 3); u is (3, NX, NY, NZ) (or (3, size)).
"""
from __future__ import annotations

import numpy as np

__all__ = ["rigid_velocity", "particle_velocity_field", "hydro_force_torque",
           "rigidity_increment", "sample"]


def rigid_velocity(r, V, Omega):
    """V_i + Omega_i x r at every stencil point, shape (3, N, S) (component first)."""
    V = np.asarray(V, dtype=float)
    W = np.asarray(Omega, dtype=float)
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    wx, wy, wz = W[:, 0:1], W[:, 1:2], W[:, 2:3]
    return np.stack([V[:, 0:1] + wy * rz - wz * ry,
                     V[:, 1:2] + wz * rx - wx * rz,
                     V[:, 2:3] + wx * ry - wy * rx])


def sample(u, idx):
    """u at the stencil points, (3, N, S)."""
    return u.reshape(3, -1)[:, idx]


def _scatter(w, idx, size, out_shape):
    """sum over particles of the per-point vectors w (3, N, S) -> (3, size) or out_shape."""
    flat = idx.ravel()
    out = np.empty((3, size))
    for c in range(3):
        out[c] = np.bincount(flat, weights=w[c].ravel(), minlength=size)
    return out.reshape((3,) + tuple(out_shape)) if out_shape is not None else out


def particle_velocity_field(idx, phi, r, V, Omega, size, shape=None):
    """Eq 6: phi u_p = sum_i (V_i + Omega_i x r) phi_i, (3, size) or (3, *shape)."""
    w = rigid_velocity(r, V, Omega)
    w *= phi
    return _scatter(w, idx, size, shape)


def _slip(u, idx, phi, r, V, Omega):
    """phi_i (u - V_i - Omega_i x r) at the stencil points, (3, N, S)."""
    w = sample(u, idx)
    w -= rigid_velocity(r, V, Omega)
    w *= phi
    return w


def _force_torque(w, r, scale):
    F = w.sum(axis=2).T * scale
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    T = np.stack([np.einsum("ns,ns->n", ry, w[2]) - np.einsum("ns,ns->n", rz, w[1]),
                  np.einsum("ns,ns->n", rz, w[0]) - np.einsum("ns,ns->n", rx, w[2]),
                  np.einsum("ns,ns->n", rx, w[1]) - np.einsum("ns,ns->n", ry, w[0])],
                 axis=1) * scale
    return F, T


def hydro_force_torque(u, idx, phi, r, V, Omega, rho, dx, dt):
    """Eqs 11-12 by momentum exchange: (F_H (N, 3), N_H (N, 3)) from u* (after the fluid step).

    F_i = RHO DX^3 / dt sum phi_i (u* - V_i - Omega_i x r), N_i = same with r x (...).
    """
    w = _slip(u, idx, phi, r, V, Omega)
    return _force_torque(w, r, rho * dx ** 3 / dt)


def rigidity_increment(u, idx, phi, r, V, Omega, size=None):
    """du = sum_i phi_i (V_i + Omega_i x r) - phi u (eq 6 imposed; phi f_p dt of eq 8).

    Shaped like u.  Still to be made solenoidal by the caller (SpectralNS.add_solenoidal,
    or u += du followed by MACSolver.project(u)).  Computed only at the stencil points:
    du = -sum_i phi_i (u - V_i - Omega_i x r).
    """
    size = u[0].size if size is None else size
    w = _slip(u, idx, phi, r, V, Omega)
    w *= -1.0
    return _scatter(w, idx, size, u.shape[1:])
