"""Fused passes of the SPM coupling (kapsel.particles.coupling), compiled.

``slip`` does in one sweep over the stencil points what ``coupling._slip`` did in some fifteen
numpy passes over (N, S) arrays (at 32^3 with one particle the step's Python and numpy
overhead: about 15 us a call), with the same floating-point operations in the same order,
so the same bits.  Loaded on demand by kapsel.mesh.compiled (slot ``coupling``), ahead of
time by kapsel.build_kernels.
"""
from __future__ import annotations

from numba import njit

from ..mesh.point_sums import add_at

__all__ = ["slip", "scatter_add", "weights"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "slip": "void(float64[:,:,::1], float64[:,:,::1], float64[:,::1], float64[:,::1], "
            "float64[:,::1], float64)",     # rc is (3, N, S): the profiles' own layout
    "scatter_add": "void(float64[:,::1], int64[:,::1], float64[:,:,::1])",
    "weights": "void(float64[::1], int64[:,::1], float64[:,::1], float64[:,::1], boolean)",
}


@njit(cache=True, nogil=True)
def slip(u_s, rc, V, W, phi, shear):
    """u_s (3, N, S), u at the stencil points on entry, <- phi (u_s - V - W x r [+ shear
    r_y e_x]); rc (3, N, S) the offsets r component-major (kapsel.particles.profile keeps r
    as a view of such an array), V and W (N, 3), phi (N, S).  Component c as ``_slip`` makes
    it: (a, b) = (c+1, c+2) mod 3, w = ((((u - r_b W_a) + r_a W_b) - V_c) [+ shear r_y]) phi."""
    n, s = phi.shape
    for i in range(n):
        for j in range(s):
            p = phi[i, j]
            for c in range(3):
                a = (c + 1) % 3
                b = (c + 2) % 3
                w = u_s[c, i, j] - rc[b, i, j] * W[i, a]
                w = w + rc[a, i, j] * W[i, b]
                w = w - V[i, c]
                if c == 0 and shear != 0.0:
                    w = w + shear * rc[1, i, j]
                u_s[c, i, j] = w * p


@njit(cache=True, nogil=True)
def scatter_add(out, idx, w):
    """out[c, idx[i, j]] += w[c, i, j] for every component c, particle i and stencil point j,
    in that order: ``np.add.at(out[c], idx.ravel(), w[c].ravel())`` for c = 0, 1, 2 (the same
    additions in the same order, so the same bits), in one call.  out (3, size) flat."""
    for c in range(3):
        add_at(out[c], idx, w[c])


@njit(cache=True, nogil=True)
def weights(ps, idx, phi, w, clear):
    """w = phi / max(phi_sum, 1) at the stencil points (spm.SPM._weights): phi_sum into the
    flat ``ps`` (0, or the walls' phi, on entry) by ``np.add.at``'s additions in its order,
    read back at the points, raised to 1 as np.maximum does (NaN kept), divided; then with
    ``clear`` the points of ``ps`` are 0 again."""
    n, s = idx.shape
    add_at(ps, idx, phi)
    for i in range(n):
        for j in range(s):
            t = ps[idx[i, j]]
            if t < 1.0:
                t = 1.0
            w[i, j] = phi[i, j] / t
    if clear:
        for i in range(n):
            for j in range(s):
                ps[idx[i, j]] = 0.0
