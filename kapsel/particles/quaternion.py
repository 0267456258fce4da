"""Scalar-first quaternions q = (q0, q1, q2, q3), vectorised over (N, 4).

Convention: a unit quaternion q rotates a vector v (space frame) as
v' = q (0, v) q*, i.e. to_matrix(q) @ v.  The orientation of a particle maps
body-frame vectors to space-frame vectors.  Angular velocity omega is in the
space frame, so dq/dt = 1/2 (0, omega) ⊗ q (used for eq 10 rotations).
"""
from __future__ import annotations

import numpy as np

__all__ = ["identity", "multiply", "conjugate", "normalise", "to_matrix", "rotate",
           "to_body", "from_matrix", "from_axis_angle", "integrate", "qdot", "euler_step",
           "ab2_step"]


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


def to_body(q, v) -> np.ndarray:
    """Space-frame vectors v (..., 3) in the body frame of q: to_matrix(q)^T v."""
    return np.einsum("...ji,...j->...i", to_matrix(q), np.asarray(v, dtype=float))


def from_matrix(R) -> np.ndarray:
    """Unit quaternions (..., 4) of rotation matrices R (..., 3, 3), as the original
    converts (quaternion.h rm_rqtn): from the largest of 4 q_0^2, 4 q_1^2, 4 q_2^2, 4 q_3^2
    (1 +- R_00 +- R_11 +- R_22, the first of equal ones), whose component is taken
    positive, and the off-diagonal sums and differences for the others (so q and -q are
    not chosen by any convention of q_0's sign)."""
    R = np.asarray(R, dtype=float)
    r00, r11, r22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    sq = np.stack([1.0 + r00 + r11 + r22, 1.0 + r00 - r11 - r22,
                   1.0 - r00 + r11 - r22, 1.0 - r00 - r11 + r22], axis=-1)
    k = np.zeros(sq.shape[:-1], dtype=np.int64)
    for j in (1, 2, 3):                     # the first largest (strictly greater replaces)
        k = np.where(sq[..., j] > np.take_along_axis(sq, k[..., None], -1)[..., 0], j, k)
    big = 0.5 * np.sqrt(np.take_along_axis(sq, k[..., None], -1)[..., 0])
    f = 1.0 / (4.0 * big)
    d21, d02, d10 = R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], \
        R[..., 1, 0] - R[..., 0, 1]
    s10, s20, s21 = R[..., 1, 0] + R[..., 0, 1], R[..., 2, 0] + R[..., 0, 2], \
        R[..., 2, 1] + R[..., 1, 2]
    cand = np.stack([np.stack([big, d21 * f, d02 * f, d10 * f], axis=-1),
                     np.stack([d21 * f, big, s10 * f, s20 * f], axis=-1),
                     np.stack([d02 * f, s10 * f, big, s21 * f], axis=-1),
                     np.stack([d10 * f, s20 * f, s21 * f, big], axis=-1)], axis=-2)
    return np.take_along_axis(cand, k[..., None, None], -2)[..., 0, :]


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


def qdot(q, omega) -> np.ndarray:
    """dq/dt = 1/2 (0, omega) ⊗ q for space-frame angular velocities omega (..., 3)
    (rigid_body.cxx qdot, SPACE_FRAME)."""
    q = _as_q(q)
    w = np.asarray(omega, dtype=float)
    w4 = np.concatenate([np.zeros(w.shape[:-1] + (1,)), w], axis=-1)
    return 0.5 * multiply(w4, q)


def euler_step(q, omega, dt) -> np.ndarray:
    """q + dt dq/dt, normalised: the original's first-step orientation update
    (particle_rotation_solver.h MD_solver_orientation_Euler)."""
    new = _as_q(q) + dt * qdot(q, omega)
    return new / np.linalg.norm(new, axis=-1, keepdims=True)


def ab2_step(q, q_old, omega, omega_old, dt) -> np.ndarray:
    """q + dt/2 (3 dq/dt(q, omega) - dq/dt(q_old, omega_old)), normalised: the original's
    Adams-Bashforth orientation update (particle_rotation_solver.h
    MD_solver_orientation_AB2)."""
    h = 0.5 * dt
    new = _as_q(q) + (3.0 * h) * qdot(q, omega) - h * qdot(q_old, omega_old)
    return new / np.linalg.norm(new, axis=-1, keepdims=True)
