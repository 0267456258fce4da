"""The stencil points of the particles' profiles (kapsel.particles.profile), compiled.

``stencil_points`` makes in one sweep over the (N, S) stencil points what
``particle_profiles`` made in some twenty numpy passes: the flat grid index of each point,
its displacement r from the particle and |r|, with the same floating-point operations in the
same order (the same bits; |r| is correctly rounded either way).  The profile g(|r|) stays
numpy's (its exp is not libm's).  Loaded on demand by kapsel.mesh.compiled (slot
``profile``), ahead of time by kapsel.build_kernels.
"""
from __future__ import annotations

import math

from numba import njit

__all__ = ["stencil_points"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time
SIGNATURES = {
    "stencil_points": "void(int64[:,::1], float64[:,::1], int64[:,::1], float64[:,::1], "
                      "int64[::1], float64, float64, int64[:,::1], float64[:,:,::1], "
                      "float64[:,::1])",
}


@njit(cache=True, nogil=True)
def stencil_points(b, frac, off, off_f, shape, dx, strain, idx, rc, dist):
    """For particle i (base point b[i] (N, 3), fraction frac[i] (N, 3)) and stencil offset j
    (off (S, 3), off_f its floats): idx[i, j] the flat C-order index of (b + o) mod shape,
    rc[:, i, j] = (o - frac) dx [x: + strain r_y] (dx = 1: not multiplied), dist[i, j] =
    sqrt(r_x^2 + r_y^2 + r_z^2) summed in that order: particle_profiles' and _phi_of's
    passes, point by point."""
    n, s = frac.shape[0], off.shape[0]
    n0, n1, n2 = shape[0], shape[1], shape[2]
    for i in range(n):
        f0, f1, f2 = frac[i, 0], frac[i, 1], frac[i, 2]
        b0, b1, b2 = b[i, 0], b[i, 1], b[i, 2]
        for j in range(s):
            r0 = off_f[j, 0] - f0
            r1 = off_f[j, 1] - f1
            r2 = off_f[j, 2] - f2
            if dx != 1.0:
                r0 = r0 * dx
                r1 = r1 * dx
                r2 = r2 * dx
            if strain != 0.0:
                r0 = r0 + strain * r1
            rc[0, i, j] = r0
            rc[1, i, j] = r1
            rc[2, i, j] = r2
            d = r0 * r0
            d = d + r1 * r1
            d = d + r2 * r2
            dist[i, j] = math.sqrt(d)
            k = (b0 + off[j, 0]) % n0
            k = k * n1 + (b1 + off[j, 1]) % n1
            idx[i, j] = k * n2 + (b2 + off[j, 2]) % n2
