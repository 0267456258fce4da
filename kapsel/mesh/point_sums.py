"""Sums of values at grid points, compiled (numba): the one loop behind the particles'
increment scatter and weights (kapsel.particles.coupling_kernels) and the ions' binning
(kapsel.fluid.ions_kernels).  Inlined into those kernels (and into their ahead-of-time
build), not a slot of its own.
"""
from __future__ import annotations

from numba import njit

__all__ = ["add_at"]


@njit(inline="always")
def add_at(out, idx, w):
    """out[idx[i, j]] += w[i, j] for every i, then j, in that order: ``np.add.at(out,
    idx.ravel(), w.ravel())``'s additions in its order (the same bits); out flat."""
    n, s = idx.shape
    for i in range(n):
        for j in range(s):
            out[idx[i, j]] += w[i, j]
