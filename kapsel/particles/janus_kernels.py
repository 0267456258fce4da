"""Fused passes of the squirmers' slip step (kapsel.particles.janus), compiled.

Each kernel does in one sweep over the stencil points what Janus.update_velocities did in
some thirty numpy passes and einsums over (M, S) arrays, with the floating-point operations
of the numpy forms next to them in janus.py (``_stencil_sums``, ``_slip_scatter``,
``_slip_force``) in the same order: the sums over a stencil run over its points in order, as
numpy's sum over the first axis of a C-contiguous array does, so both forms give the same
bits.  Loaded on demand by kapsel.mesh.compiled (slot ``janus``), ahead of time by
kapsel.build_kernels.

Layouts: rc (3, M, S) the offsets r component-major; phi, ws, d (M, S); e3 (M, 3);
per-particle parameters (M,); fields flat (3, size) with idx (M, S) flat indices.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["stencil_sums", "slip_scatter", "slip_force"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "stencil_sums": "void(float64[:,:,::1], float64[:,::1], float64[:,::1], float64[:,::1], "
                    "float64[:,::1], float64[::1], float64[::1], float64[::1], float64[::1], "
                    "boolean, float64[:,:,::1], float64[:,:,::1], float64[:,::1])",
    "slip_scatter": "void(float64[:,::1], int64[:,::1], float64[:,::1], float64[:,::1], "
                    "float64[:,:,::1], float64[:,::1], float64[:,:,::1])",
    "slip_force": "void(float64[:,::1], int64[:,::1], float64[:,::1], float64[:,:,::1], "
                  "float64, float64[:,:,::1], float64[:,::1])",
}


@njit(cache=True, nogil=True)
def stencil_sums(rc, phi, ws, d, e3, B1, beta, C1, C2, rotlet, ul, shell, out):
    """The squirmers' stencil sums (Janus._stencil_sums): out (M, 32) <- per particle the
    sums over its points of phi, phi r, (phi r_a) r_b, ws, ws r, (ws r_a) r_b, ws du and
    ws (r x du), du = u_s - u (u_s the slip velocity, ul (3, M, S) u at the points);
    shell (3, M, S) <- ws du."""
    m, s = phi.shape
    t = np.empty(32)
    for i in range(m):
        for k in range(32):
            out[i, k] = 0.0
        e0, e1, e2 = e3[i, 0], e3[i, 1], e3[i, 2]
        for j in range(s):
            r0, r1, r2 = rc[0, i, j], rc[1, i, j], rc[2, i, j]
            dd = d[i, j] if d[i, j] > 0 else 1.0
            h0, h1, h2 = r0 / dd, r1 / dd, r2 / dd
            c = (h0 * e0 + h1 * e1) + h2 * e2
            f = B1[i] * (1.0 + (2.0 * beta[i]) * c)
            u0 = f * (c * h0 - e0)
            u1 = f * (c * h1 - e1)
            u2 = f * (c * h2 - e2)
            if rotlet:
                g = C1[i] + (3.0 * C2[i]) * c
                u0 = u0 + g * (e1 * h2 - e2 * h1)
                u1 = u1 + g * (e2 * h0 - e0 * h2)
                u2 = u2 + g * (e0 * h1 - e1 * h0)
            du0, du1, du2 = u0 - ul[0, i, j], u1 - ul[1, i, j], u2 - ul[2, i, j]
            p, w = phi[i, j], ws[i, j]
            sh0, sh1, sh2 = w * du0, w * du1, w * du2
            shell[0, i, j] = sh0
            shell[1, i, j] = sh1
            shell[2, i, j] = sh2
            pr0, pr1, pr2 = p * r0, p * r1, p * r2
            wr0, wr1, wr2 = w * r0, w * r1, w * r2
            t[0] = p
            t[1], t[2], t[3] = pr0, pr1, pr2
            t[4], t[5], t[6] = pr0 * r0, pr0 * r1, pr0 * r2
            t[7], t[8], t[9] = pr1 * r0, pr1 * r1, pr1 * r2
            t[10], t[11], t[12] = pr2 * r0, pr2 * r1, pr2 * r2
            t[13] = w
            t[14], t[15], t[16] = wr0, wr1, wr2
            t[17], t[18], t[19] = wr0 * r0, wr0 * r1, wr0 * r2
            t[20], t[21], t[22] = wr1 * r0, wr1 * r1, wr1 * r2
            t[23], t[24], t[25] = wr2 * r0, wr2 * r1, wr2 * r2
            t[26], t[27], t[28] = sh0, sh1, sh2
            t[29] = w * (r1 * du2 - r2 * du1)
            t[30] = w * (r2 * du0 - r0 * du2)
            t[31] = w * (r0 * du1 - r1 * du0)
            if j == 0:
                for k in range(32):
                    out[i, k] = t[k]
            else:
                for k in range(32):
                    out[i, k] = out[i, k] + t[k]


@njit(cache=True, nogil=True)
def slip_scatter(field, idx, phi, ws, rc, g, shell):
    """field (3, size) += w at idx, point by point in order (np.add.at's order), w =
    phi (dV + dW x r) + ws (V* + W* x r) + shell; g (M, 12) the iterates (dV, dW, V*, W*)
    per particle (Janus._slip_scatter)."""
    m, s = phi.shape
    for i in range(m):
        for j in range(s):
            r0, r1, r2 = rc[0, i, j], rc[1, i, j], rc[2, i, j]
            p, w = phi[i, j], ws[i, j]
            a0 = p * (g[i, 0] + (g[i, 4] * r2 - g[i, 5] * r1))
            a1 = p * (g[i, 1] + (g[i, 5] * r0 - g[i, 3] * r2))
            a2 = p * (g[i, 2] + (g[i, 3] * r1 - g[i, 4] * r0))
            a0 = a0 + w * (g[i, 6] + (g[i, 10] * r2 - g[i, 11] * r1))
            a1 = a1 + w * (g[i, 7] + (g[i, 11] * r0 - g[i, 9] * r2))
            a2 = a2 + w * (g[i, 8] + (g[i, 9] * r1 - g[i, 10] * r0))
            a0 = a0 + shell[0, i, j]
            a1 = a1 + shell[1, i, j]
            a2 = a2 + shell[2, i, j]
            q = idx[i, j]
            field[0, q] = field[0, q] + a0
            field[1, q] = field[1, q] + a1
            field[2, q] = field[2, q] + a2


@njit(cache=True, nogil=True)
def slip_force(up, idx, phi, rc, scale, up_at, out):
    """Per particle (N of them) F = scale sum phi u', T = scale (sum r_a w_b - sum r_b w_a)
    (w = phi u', (a, b) cyclic) into out (N, 6), the sums over the points in order
    (Janus._slip_force); up_at (3, N, S) <- u' at the points."""
    n, s = phi.shape
    t = np.empty(9)
    acc = np.zeros(9)
    for i in range(n):
        for j in range(s):
            q = idx[i, j]
            v0, v1, v2 = up[0, q], up[1, q], up[2, q]
            up_at[0, i, j] = v0
            up_at[1, i, j] = v1
            up_at[2, i, j] = v2
            p = phi[i, j]
            w0, w1, w2 = v0 * p, v1 * p, v2 * p
            r0, r1, r2 = rc[0, i, j], rc[1, i, j], rc[2, i, j]
            t[0], t[1], t[2] = w0, w1, w2
            t[3], t[4] = r1 * w2, r2 * w1
            t[5], t[6] = r2 * w0, r0 * w2
            t[7], t[8] = r0 * w1, r1 * w0
            if j == 0:
                for k in range(9):
                    acc[k] = t[k]
            else:
                for k in range(9):
                    acc[k] = acc[k] + t[k]
        if s == 0:
            for k in range(9):
                acc[k] = 0.0
        out[i, 0] = acc[0] * scale
        out[i, 1] = acc[1] * scale
        out[i, 2] = acc[2] * scale
        out[i, 3] = (acc[3] - acc[4]) * scale
        out[i, 4] = (acc[5] - acc[6]) * scale
        out[i, 5] = (acc[7] - acc[8]) * scale
