"""Neighbour pairs in a periodic box (minimum image), vectorised with cKDTree."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["wrap", "minimum_image", "pairs_within"]


def wrap(R, box) -> np.ndarray:
    """Positions wrapped into [0, L) (guarding the float case mod(x, L) == L)."""
    L = np.asarray(box, dtype=float)
    W = np.mod(np.asarray(R, dtype=float), L)
    W[W >= L] = 0.0
    return W


def minimum_image(dr, box) -> np.ndarray:
    """Minimum-image separation vectors dr - L round(dr / L)."""
    L = np.asarray(box, dtype=float)
    return dr - L * np.round(dr / L)


def pairs_within(R, box, rcut):
    """All pairs closer than rcut (|dr| <= rcut) in the periodic box.

    Returns (i, j, dr) with i < j (int arrays, M) sorted by (i, j), and
    dr = minimum-image R[j] - R[i], shape (M, 3).  Uses cKDTree with boxsize;
    if rcut > L/2 in any direction, minimum image is ambiguous for the tree and
    all pairs are scanned instead (each pair counted once, at its minimum image;
    further periodic images of the same pair are ignored).
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3)
    L = np.asarray(box, dtype=float)
    n = len(R)
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
    if n < 2 or rcut <= 0:
        return empty
    W = wrap(R, L)
    if np.any(rcut > 0.5 * L):
        i, j = np.triu_indices(n, k=1)
    else:
        tree = cKDTree(W, boxsize=L)
        p = tree.query_pairs(rcut, output_type="ndarray")
        if len(p) == 0:
            return empty
        i = np.minimum(p[:, 0], p[:, 1]).astype(np.int64)
        j = np.maximum(p[:, 0], p[:, 1]).astype(np.int64)
    dr = minimum_image(W[j] - W[i], L)
    keep = np.einsum("ij,ij->i", dr, dr) <= rcut * rcut
    i, j, dr = i[keep], j[keep], dr[keep]
    order = np.lexsort((j, i))
    return i[order].astype(np.int64), j[order].astype(np.int64), dr[order]
