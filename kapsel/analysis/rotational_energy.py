"""Rotational kinetic energy of rigid bodies, as LAMMPS compute erotate/rigid (spec 002).

E_rot,g = 1/2 sum_k m_gk |omega_g x r_gk|^2                      (eq 1)
        = 1/2 omega_g^T I_g omega_g,  I_g = sum_k m_gk [(r.r) 1 - r r^T]   (eqs 2-3)
        = 1/2 omega_g^T R_g I_g^B R_g^T omega_g,  I_g = R_g I_g^B R_g^T   (eqs 4-5)
        = 1/2 I_g |omega_g|^2 when I_g1 = I_g2 = I_g3                    (eq 6)
E_rot   = sum_g E_rot,g                                               (eq 7)

r_gk are bead positions about the body's centre of mass; omega is in the space frame.
R_g maps body-frame vectors to space-frame vectors; quaternions are scalar first
(q0, q1, q2, q3) with R(q) v = q (0, v) q* (the convention of kapsel.particles.quaternion).
Everything is float64 and vectorised over bodies.
"""
from __future__ import annotations

import numpy as np

__all__ = ["inertia_tensor", "principal_frame", "rotational_energy",
           "rotational_energy_body", "rotational_energy_sphere", "body_inertia_tensors",
           "rotational_energies", "total_rotational_energy", "quaternion_to_matrix",
           "matrix_to_quaternion"]


def _vec3(a, name):
    a = np.asarray(a, dtype=np.float64)
    if a.shape[-1:] != (3,):
        raise ValueError(f"{name} needs a last axis of length 3, got shape {a.shape}")
    return a


def inertia_tensor(masses, positions):
    """(I (3, 3), com (3,)): inertia tensor of one body about its centre of mass (eq 2)."""
    m = np.asarray(masses, dtype=np.float64).ravel()
    x = _vec3(positions, "positions").reshape(-1, 3)
    if len(m) != len(x):
        raise ValueError(f"{len(m)} masses for {len(x)} positions")
    com = (m[:, None] * x).sum(axis=0) / m.sum()
    r = x - com
    r2 = np.einsum("ki,ki->k", r, r)
    I = np.eye(3) * (m * r2).sum() - np.einsum("k,ki,kj->ij", m, r, r)
    return I, com


def principal_frame(I):
    """(moments (..., 3) ascending, rotation (..., 3, 3) proper, columns = principal axes)
    with I = R diag(moments) R^T (eq 4)."""
    I = np.asarray(I, dtype=np.float64)
    moments, R = np.linalg.eigh(0.5 * (I + np.swapaxes(I, -1, -2)))
    flip = np.linalg.det(R) < 0
    R = R.copy()
    R[..., :, 2] = np.where(flip[..., None], -R[..., :, 2], R[..., :, 2])
    return moments, R


def rotational_energy(omega, masses, positions):
    """E_rot of one body from its beads, 1/2 omega^T I omega (eq 3)."""
    I, _ = inertia_tensor(masses, positions)
    w = _vec3(omega, "omega")
    return 0.5 * np.einsum("...i,ij,...j->...", w, I, w)


def rotational_energy_sphere(omega, moment):
    """E_rot = 1/2 I |omega|^2 of a body with three equal principal moments (eq 6)."""
    w = _vec3(omega, "omega")
    return 0.5 * np.asarray(moment, dtype=np.float64) * np.einsum("...i,...i->...", w, w)


def rotational_energy_body(omega, moments_body, rotation, rtol=1e-12):
    """E_rot = 1/2 omega^T R I^B R^T omega (eq 5), broadcasting over leading axes.

    moments_body (..., 3) principal moments I_1, I_2, I_3; rotation (..., 3, 3) body->space
    matrix or (..., 4) quaternion.  Bodies whose moments agree to rtol use eq 6.
    """
    w = _vec3(omega, "omega")
    Ib = _vec3(moments_body, "moments_body")
    R = np.asarray(rotation, dtype=np.float64)
    if R.shape[-1:] == (4,):
        R = quaternion_to_matrix(R)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotation must be (..., 3, 3) or a (..., 4) quaternion, got {R.shape}")
    wb = np.einsum("...ji,...j->...i", R, w)                      # R^T omega: body frame
    e = 0.5 * np.einsum("...i,...i->...", Ib, wb * wb)
    spread = Ib.max(axis=-1) - Ib.min(axis=-1)
    sphere = spread <= rtol * np.abs(Ib).max(axis=-1)
    if np.any(sphere):
        e_sph = rotational_energy_sphere(w, Ib.mean(axis=-1))
        e = np.where(sphere, e_sph, e)
    return e if np.ndim(e) else float(e)


def _group(body, n):
    body = np.asarray(body).ravel()
    if len(body) != n:
        raise ValueError(f"{len(body)} body ids for {n} beads")
    ids, inv = np.unique(body, return_inverse=True)
    return ids, inv.ravel()


def body_inertia_tensors(masses, positions, body, box=None):
    """(ids (G,), I (G, 3, 3), com (G, 3)) for beads labelled by body id (eq 2), ids sorted.

    With box (Lx, Ly, Lz) the beads of a body are unwrapped by the minimum image relative
    to its first bead (bodies must be smaller than half the box)."""
    x = _vec3(positions, "positions").reshape(-1, 3)
    m = np.asarray(masses, dtype=np.float64)
    m = np.broadcast_to(m, (len(x),)) if m.ndim == 0 else m.ravel()
    if len(m) != len(x):
        raise ValueError(f"{len(m)} masses for {len(x)} positions")
    ids, inv = _group(body, len(x))
    G = len(ids)
    if box is not None:
        L = np.broadcast_to(np.asarray(box, dtype=np.float64), (3,))
        first = np.full(G, len(x))
        np.minimum.at(first, inv, np.arange(len(x)))
        d = x - x[first][inv]
        x = x[first][inv] + d - L * np.rint(d / L)
    M = np.bincount(inv, weights=m, minlength=G)
    com = np.stack([np.bincount(inv, weights=m * x[:, a], minlength=G) for a in range(3)],
                   axis=1) / M[:, None]
    r = x - com[inv]
    I = np.empty((G, 3, 3))
    r2 = np.einsum("ki,ki->k", r, r)
    for a in range(3):
        for b in range(a, 3):
            w = m * ((r2 if a == b else 0.0) - r[:, a] * r[:, b])
            I[:, a, b] = I[:, b, a] = np.bincount(inv, weights=w, minlength=G)
    return ids, I, com


def rotational_energies(omega, masses, positions, body, box=None):
    """Per-body E_rot,g (G,) (eq 3) with omega (G, 3) given in sorted body-id order."""
    _, I, _ = body_inertia_tensors(masses, positions, body, box)
    w = _vec3(omega, "omega").reshape(-1, 3)
    if len(w) != len(I):
        raise ValueError(f"omega has {len(w)} rows for {len(I)} bodies")
    return 0.5 * np.einsum("gi,gij,gj->g", w, I, w)


def total_rotational_energy(omega, masses=None, positions=None, body=None, *, box=None,
                            moments=None, rotation=None):
    """E_rot = sum_g E_rot,g (eq 7) of many bodies at once, omega (G, 3).

    Either from beads: masses (N,), positions (N, 3), body (N,) ids (omega rows in sorted
    id order; eq 3), or from body frames: moments (G, 3) and rotation (G, 3, 3) or
    quaternions (G, 4) (eq 5, eq 6 for spherical bodies)."""
    if moments is not None:
        if rotation is None:
            raise ValueError("moments need rotation (matrices or quaternions)")
        return float(np.sum(rotational_energy_body(omega, moments, rotation)))
    if masses is None or positions is None:
        raise ValueError("give masses, positions (and body ids), or moments and rotation")
    if body is None:
        body = np.zeros(len(np.asarray(positions).reshape(-1, 3)), dtype=np.int64)
    return float(rotational_energies(omega, masses, positions, body, box).sum())


def quaternion_to_matrix(q):
    """Rotation matrices (..., 3, 3) of scalar-first quaternions (..., 4) (normalised first)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (4,):
        raise ValueError(f"quaternions need a last axis of length 4, got shape {q.shape}")
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm == 0):
        raise ValueError("zero quaternion")
    q0, q1, q2, q3 = np.moveaxis(q / norm, -1, 0)
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    R[..., 0, 1] = 2 * (q1 * q2 - q0 * q3)
    R[..., 0, 2] = 2 * (q1 * q3 + q0 * q2)
    R[..., 1, 0] = 2 * (q1 * q2 + q0 * q3)
    R[..., 1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    R[..., 1, 2] = 2 * (q2 * q3 - q0 * q1)
    R[..., 2, 0] = 2 * (q1 * q3 - q0 * q2)
    R[..., 2, 1] = 2 * (q2 * q3 + q0 * q1)
    R[..., 2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    return R


def matrix_to_quaternion(R):
    """Unit scalar-first quaternions (..., 4) with q0 >= 0 of rotation matrices (..., 3, 3)
    (Shepperd's method: the largest of 4 q0^2, 4 q1^2, ... is taken as pivot)."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices need shape (..., 3, 3), got {R.shape}")
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([1 + tr, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22,
                     1 - m00 - m11 + m22], axis=-1)         # 4 q_k^2
    k = np.argmax(cand, axis=-1)
    s = 2.0 * np.sqrt(np.take_along_axis(cand, k[..., None], axis=-1)[..., 0])  # 4 |q_k|
    a = (R[..., 2, 1] - R[..., 1, 2]) / s          # 4 q0 q1 / s etc. divided by 4|q_k|
    b = (R[..., 0, 2] - R[..., 2, 0]) / s
    c = (R[..., 1, 0] - R[..., 0, 1]) / s
    d = (R[..., 0, 1] + R[..., 1, 0]) / s
    e = (R[..., 0, 2] + R[..., 2, 0]) / s
    f = (R[..., 1, 2] + R[..., 2, 1]) / s
    h = s / 4.0
    q = np.stack([
        np.choose(k, [h, a, b, c]),
        np.choose(k, [a, h, d, e]),
        np.choose(k, [b, d, h, f]),
        np.choose(k, [c, e, f, h])], axis=-1)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)
