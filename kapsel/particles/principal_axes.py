"""The body frame of a rigid body: principal axes of its inertia tensor, chosen as the
original chooses them (rigid.h init_Rigid_Coordinates).

The original diagonalises the space-frame tensor I of each body by cyclic Jacobi rotations
(matrix_diagonal.cxx ``jacobi``, the classic threshold scheme), sorts the eigenvalues in
decreasing order, and builds the rotation body -> space from the eigenvectors e_1 >= e_2 >=
e_3 as R = [e_1', e_3 x e_1', e_3] with e_1' = e_1 made orthogonal to e_3 (lad3.h
M_coordinate_frame called on (e_3, e_1, e_2)): body z is the axis of the smallest moment
(a rod's long axis), body x that of the largest.  The eigenvectors' signs are those the
Jacobi rotations produce, so the same algorithm is used here (vectorised over bodies):
the body frame, the quaternion of every body and hence the body-frame meaning of
Rigid_omega and of the fixed angular-velocity components follow the original's.

``principal_frame(I)`` -> R (B, 3, 3) with columns the body axes in the space frame.
"""
from __future__ import annotations

import numpy as np

__all__ = ["jacobi_eigen", "principal_frame"]

_SWEEPS = 50
_NEGLIGIBLE = 1e-17            # relative size of an off-diagonal element treated as zero
_TOL = 10.0 * np.finfo(float).eps   # the sum of |off-diagonals| that ends the iteration
_PAIRS = ((0, 1), (0, 2), (1, 2))


def _rotate_pair(M, s, tau, i, j, k, l, on):
    """One Jacobi update of the elements (i, j), (k, l) of the matrices M (B, 3, 3) where
    ``on``: g = M_ij, h = M_kl -> g - s (h + g tau), h + s (g - h tau)."""
    g = M[:, i, j].copy()
    h = M[:, k, l].copy()
    M[:, i, j] = np.where(on, g - s * (h + g * tau), g)
    M[:, k, l] = np.where(on, h + s * (g - h * tau), h)


def jacobi_eigen(I):
    """Eigenvalues (B, 3) in decreasing order and eigenvectors (B, 3, 3) (row k the
    eigenvector of eigenvalue k) of the symmetric matrices I (B, 3, 3) by the original's
    cyclic Jacobi scheme (module docstring); a tie keeps the later of equal eigenvalues
    first.  ValueError if a matrix does not converge in 50 sweeps."""
    I = np.asarray(I, dtype=float)
    B = len(I)
    scale = np.abs(I).reshape(B, -1).max(axis=1, initial=0.0)
    scale = np.where(scale > 0.0, scale, 1.0)
    A = I / scale[:, None, None]
    V = np.broadcast_to(np.eye(3), (B, 3, 3)).copy()
    b = np.einsum("bii->bi", A).copy()
    d = b.copy()
    z = np.zeros((B, 3))
    active = np.ones(B, dtype=bool)
    for sweep in range(1, _SWEEPS + 1):
        sm = np.abs(A[:, 0, 1]) + np.abs(A[:, 0, 2]) + np.abs(A[:, 1, 2])
        active &= ~(np.abs(sm) <= _TOL)
        if not active.any():
            break
        tresh = 0.2 * sm / 9.0 if sweep < 4 else np.zeros(B)
        for p, q in _PAIRS:
            apq = A[:, p, q].copy()
            g = 100.0 * np.abs(apq)
            drop = active & (sweep > 4) & (g <= _NEGLIGIBLE * np.abs(d[:, p])) & (
                g <= _NEGLIGIBLE * np.abs(d[:, q]))
            on = active & ~drop & (np.abs(apq) > tresh)
            h = d[:, q] - d[:, p]
            with np.errstate(divide="ignore", invalid="ignore"):
                small = g <= _NEGLIGIBLE * np.abs(h)
                theta = 0.5 * h / np.where(apq != 0.0, apq, 1.0)
                t = 1.0 / (np.abs(theta) + np.sqrt(1.0 + theta * theta))
                t = np.where(small, apq / np.where(h != 0.0, h, 1.0),
                             np.where(theta < 0.0, -t, t))
            t = np.where(on, t, 0.0)
            c = 1.0 / np.sqrt(1.0 + t * t)
            s = t * c
            tau = s / (1.0 + c)
            h = t * apq
            z[:, p] -= h
            z[:, q] += h
            d[:, p] -= h
            d[:, q] += h
            A[:, p, q] = np.where(on | drop, 0.0, apq)
            # the rest of the rotation of A (3 x 3: one element pair per rotation) and of V
            r = 3 - p - q                     # the index that is neither p nor q
            if r < p:
                _rotate_pair(A, s, tau, r, p, r, q, on)
            elif r < q:
                _rotate_pair(A, s, tau, p, r, r, q, on)
            else:
                _rotate_pair(A, s, tau, p, r, q, r, on)
            for j in range(3):
                _rotate_pair(V, s, tau, j, p, j, q, on)
        b = np.where(active[:, None], b + z, b)
        d = np.where(active[:, None], b, d)
        z[...] = 0.0
    else:
        if active.any():
            raise ValueError("the Jacobi diagonalisation of an inertia tensor did not converge")
    vec = np.swapaxes(V, 1, 2).copy()          # rows: eigenvectors
    rows = np.arange(B)
    for i in range(2):                          # selection sort, decreasing; ties: later first
        k = np.full(B, i)
        best = d[rows, i].copy()
        for j in range(i, 3):
            take = d[:, j] >= best
            k = np.where(take, j, k)
            best = np.where(take, d[:, j], best)
        swap = k != i
        di, dk = d[rows, i].copy(), d[rows, k].copy()
        d[rows, i] = np.where(swap, dk, di)
        d[rows, k] = np.where(swap, di, dk)
        vi, vk = vec[rows, i].copy(), vec[rows, k].copy()
        vec[rows, i] = np.where(swap[:, None], vk, vi)
        vec[rows, k] = np.where(swap[:, None], vi, vk)
    return d * scale[:, None], vec


def principal_frame(I):
    """R (B, 3, 3), body -> space, of the inertia tensors I (B, 3, 3) (module docstring)."""
    _, e = jacobi_eigen(I)
    ex = e[:, 2] / np.linalg.norm(e[:, 2], axis=1, keepdims=True)
    ey = e[:, 0] - np.einsum("bk,bk->b", ex, e[:, 0])[:, None] * ex
    ey /= np.linalg.norm(ey, axis=1, keepdims=True)
    ez = np.cross(ex, ey)
    ez /= np.linalg.norm(ez, axis=1, keepdims=True)
    return np.stack([ey, ez, ex], axis=2)
