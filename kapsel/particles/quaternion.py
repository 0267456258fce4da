"""Scalar-first quaternions q = (q0, q1, q2, q3), vectorised over (N, 4).

Convention: a unit quaternion q rotates a vector v (space frame) as
v' = q (0, v) q*, i.e. to_matrix(q) @ v.  The orientation of a particle maps
body-frame vectors to space-frame vectors.  Angular velocity omega is in the
space frame, so dq/dt = 1/2 (0, omega) ⊗ q (used for eq 10 rotations).
"""
from __future__ import annotations

import numpy as np

__all__ = ["identity", "multiply", "conjugate", "normalise", "to_matrix", "rotate",
           "from_axis_angle", "integrate"]


def _as_q(q):
    q = np.asarray(q, dtype=float)
    if q.shape[-1] != 4:
        raise ValueError(f"quaternions need a last axis of length 4, got shape {q.shape}")
    return q


def identity(n: int) -> np.ndarray:
    """(n, 4) identity quaternions."""
    q = np.zeros((n, 4))
    q[:, 0] = 1.0
    return q


def multiply(p, q) -> np.ndarray:
    """Hamilton product p ⊗ q (broadcasts over leading axes)."""
    p, q = _as_q(p), _as_q(q)
    p0, p1, p2, p3 = np.moveaxis(p, -1, 0)
    q0, q1, q2, q3 = np.moveaxis(q, -1, 0)
    return np.stack([p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
                     p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
                     p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
                     p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0], axis=-1)


def conjugate(q) -> np.ndarray:
    """q* = (q0, -q1, -q2, -q3)."""
    q = _as_q(q).copy()
    q[..., 1:] *= -1.0
    return q


def normalise(q) -> np.ndarray:
    """q / |q|; zero quaternions become the identity."""
    q = _as_q(q)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    out = np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), 0.0)
    zero = norm[..., 0] == 0
    out[zero] = (1.0, 0.0, 0.0, 0.0)
    return out


def to_matrix(q) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (normalised first)."""
    q = normalise(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    m = np.empty(q.shape[:-1] + (3, 3))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - w * z)
    m[..., 0, 2] = 2 * (x * z + w * y)
    m[..., 1, 0] = 2 * (x * y + w * z)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - w * x)
    m[..., 2, 0] = 2 * (x * z - w * y)
    m[..., 2, 1] = 2 * (y * z + w * x)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def rotate(q, v) -> np.ndarray:
    """Rotate vectors v (..., 3) by q: q (0, v) q*."""
    return np.einsum("...ij,...j->...i", to_matrix(q), np.asarray(v, dtype=float))


def from_axis_angle(axis, angle) -> np.ndarray:
    """Quaternion of a rotation by `angle` about `axis` (axis need not be unit)."""
    axis = np.asarray(axis, dtype=float)
    angle = np.asarray(angle, dtype=float)
    norm = np.linalg.norm(axis, axis=-1, keepdims=True)
    unit = axis / np.where(norm > 0, norm, 1.0)
    half = 0.5 * angle[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * unit], axis=-1)


def integrate(q, omega, dt) -> np.ndarray:
    """q(t + dt) = exp(omega dt / 2) ⊗ q(t), exact for a constant space-frame omega.

    exp((0, w) dt/2) = (cos(|w| dt/2), sin(|w| dt/2) w/|w|); result renormalised.
    """
    q = _as_q(q)
    omega = np.asarray(omega, dtype=float)
    rot = omega * dt
    dq = from_axis_angle(rot, np.linalg.norm(rot, axis=-1))
    return normalise(multiply(dq, q))
