"""Fused element-wise passes of the pseudo-spectral step (kapsel.fluid.spectral), compiled.

Each kernel does in one sweep over the grid what numpy did in 6-12 whole-array passes (each
reading and writing full complex fields), with the same floating-point operations in the same
order: results are bit-identical to the numpy sequence they replace (a complex times a real
is computed as the two real products, which is what numpy's complex product gives when the
imaginary part of one factor is 0, up to the sign of zero results).

The projections come in two forms that give the same bits: a sweep point by point (the
three components of a field read and written at each mode) and ``*_rows``, a sweep of
blocks of ``ROWS`` grid rows, the blocks' coefficients (k.v)/k^2 first, into a small
scratch, then each component along the block.  Which is faster depends on the shape and the
machine: the components of a field lie a multiple of the row length apart, and at some
shapes (64^3 on the development machine: 2.3 ms against 0.5 ms for ``project_add``; 32^3 x
64 and 128 x 64 x 64 likewise) the point-by-point sweep's streams collide in the caches;
at others (32^3, 96^3, 128^3, 64^2 x 128) it is 1.2-1.7x faster than the blocks.
kapsel.fluid.spectral times both once per shape and uses the faster.

Compiled with numba (``cache=True``: the machine code is kept in __pycache__, so only the
first run on a machine pays the JIT); loaded on demand by kapsel.mesh.compiled.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["truncated_component", "scaled_component", "vorticity_component", "cross", "cross_into",
           "project_etd1", "project_etd2", "project_etd1_velocity", "project_add", "project_euler",
           "project_etd1_rows", "project_etd1_velocity_rows", "project_etd2_rows",
           "project_add_rows", "project_euler_rows", "project_set_scaled",
           "project_set_scaled_rows", "frame_component", "frame_vorticity_component",
           "velocity_vorticity", "project_oblique", "project_oblique_etd1",
           "project_oblique_etd1_velocity", "viscous_exponent", "etd1_update", "truncate",
           "cross_contravariant", "contravariant", "contravariant_in_place", "reynolds_terms"]

#: the types each kernel is called with (C-contiguous arrays): what kapsel.build_kernels
#: compiles ahead of time (kapsel.mesh.compiled loads that build when it is current)
SIGNATURES = {
    "truncated_component": "void(complex128[:,:,:,::1], float64[::1], float64[::1], int64, float64, int64, complex128[:,:,::1])",
    "scaled_component": "boolean(complex128[:,:,:,::1], float64[::1], float64[::1], int64, float64, int64, complex128[:,:,::1])",
    "vorticity_component": "void(complex128[:,:,:,::1], float64[::1], float64[::1], int64, float64, float64[::1], float64[::1], float64[::1], int64, complex128[:,:,::1])",
    "cross_into": "void(float64[:,:,:,::1], float64[:,:,:,::1])",
    "cross": "void(float64[:,:,:,::1], float64[:,:,:,::1], float64[:,:,:,::1])",
    "project_etd1": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64[:,:,::1], float64[:,:,::1], float64[::1], float64[::1], float64[::1], float64[:,:,::1], boolean)",
    "project_etd1_velocity": "boolean(complex128[:,:,:,::1], complex128[:,:,:,::1], float64[:,:,::1], float64[:,:,::1], float64[::1], float64[::1], float64[::1], float64[:,:,::1], float64[::1], float64[::1], int64, float64)",
    "project_etd2": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], complex128[:,:,:,::1], float64[:,:,::1], float64[:,:,::1], float64[:,:,::1], float64[::1], float64[::1], float64[::1], float64[:,:,::1])",
    "project_add": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64[:,:,::1], float64[::1], float64[::1], float64[::1], float64[:,:,::1])",
    "project_euler": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64[:,:,::1], float64, float64, float64[:,:,::1], float64[::1], float64[::1], float64[::1], float64[:,:,::1], boolean)",
    "project_set_scaled": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64[:,:,::1], float64[::1], float64[::1], float64[::1], float64[:,:,::1], float64)",
    "frame_component": "boolean(complex128[:,:,:,::1], float64[::1], float64[::1], int64, float64, float64, int64, boolean, complex128[:,:,::1])",
    "velocity_vorticity": "void(complex128[:,:,:,::1], float64[::1], float64[::1], int64, float64, float64, float64[::1], float64[::1], float64[::1], complex128[:,:,:,::1], complex128[:,:,::1], complex128[:,:,::1], complex128[:,:,::1])",
    "frame_vorticity_component": "void(complex128[:,:,:,::1], float64[::1], float64[::1], int64, float64, float64, float64[::1], float64[::1], float64[::1], int64, complex128[:,:,::1])",
    "project_oblique": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64, float64, float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], int64, boolean, boolean)",
    "project_oblique_etd1": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64, float64, float64[::1], float64[::1], float64[::1], int64[::1], int64[::1], int64, float64[:,:,::1], float64[:,:,::1])",
    "project_oblique_etd1_velocity": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64, float64, float64[::1], float64[::1], float64[::1], int64[::1], int64[::1], int64, float64[:,:,::1], float64[:,:,::1], float64, float64)",
    "viscous_exponent": "void(float64[::1], float64[::1], float64[::1], int64[::1], int64[::1], float64, float64, float64[:,:,::1])",
    "truncate": "void(complex128[:,:,:,::1], float64[::1], float64[::1], int64)",
    "cross_contravariant": "void(float64[:,:,:,::1], float64[:,:,:,::1], float64)",
    "contravariant": "void(float64[:,:,:,::1], float64, float64[:,:,:,::1])",
    "contravariant_in_place": "void(float64[:,:,:,::1], float64)",
    "reynolds_terms": "void(complex128[:,:,:,::1], float64, float64[::1], float64[:,:,::1])",
    "etd1_update": "void(complex128[:,:,:,::1], complex128[:,:,:,::1], float64[:,:,::1], float64[:,:,::1])",
}
SIGNATURES.update({n + "_rows": SIGNATURES[n] for n in
                   ("project_etd1", "project_etd1_velocity", "project_etd2", "project_add",
                    "project_euler", "project_set_scaled")})

ROWS = 8        # grid rows per block of the *_rows projections


@njit(cache=True, nogil=True)
def truncated_component(u_hat, mx, my, kz_end, inv_n, c, out):
    """out = u_hat[c] (mask inv_n): component c of the 2/3-truncated velocity (1/N folded in;
    mask inv_n is inv_n to the bit on the mask, whose values are 1).  The mask is the box
    ``Grid.dealias_box`` (mx[i] my[j] for k < kz_end): the rows off it are written +0 (where
    the product's zero could have had either sign) without reading u_hat, the rows on it
    scaled without a test per point."""
    nx, ny, nzc = out.shape
    for i in range(nx):
        for j in range(ny):
            if mx[i] == 0.0 or my[j] == 0.0:
                for k in range(nzc):
                    out[i, j, k] = complex(0.0, 0.0)
                continue
            for k in range(kz_end):
                a = u_hat[c, i, j, k]
                out[i, j, k] = complex(a.real * inv_n, a.imag * inv_n)
            for k in range(kz_end, nzc):
                out[i, j, k] = complex(0.0, 0.0)


@njit(cache=True, nogil=True)
def scaled_component(u_hat, mx, my, kz_end, scale, c, out):
    """out = u_hat[c] scale (numpy's product of a complex field and a real scalar, up to
    the sign of zero results); returns whether u_hat[c] is 0 off the mask (the box
    ``Grid.dealias_box``), i.e. out is a truncated field (kapsel.mesh.grid's truncated
    transforms apply)."""
    nx, ny, nzc = out.shape
    nonzero = 0.0           # the sum of |Re| + |Im| off the mask: 0 only if all are 0
    for i in range(nx):
        for j in range(ny):
            k0 = 0 if (mx[i] == 0.0 or my[j] == 0.0) else kz_end
            for k in range(k0):
                a = u_hat[c, i, j, k]
                out[i, j, k] = complex(a.real * scale, a.imag * scale)
            for k in range(k0, nzc):
                a = u_hat[c, i, j, k]
                nonzero += abs(a.real) + abs(a.imag)
                out[i, j, k] = complex(a.real * scale, a.imag * scale)
    return nonzero == 0.0


@njit(cache=True, nogil=True)
def vorticity_component(u_hat, mx, my, kz_end, inv_n, kx, ky, kz, c, out):
    """out = (i k x (u_hat mask inv_n))[c]: component c of the truncated velocity's vorticity
    (``frame_vorticity_component`` of the unsheared frame)."""
    frame_vorticity_component(u_hat, mx, my, kz_end, inv_n, 0.0, kx, ky, kz, c, out)


@njit(inline="always")
def _cross_point(u, w, n, i, j, k):
    """n = u x w at one point (n may be w: every component is read first)."""
    u0, u1, u2 = u[0, i, j, k], u[1, i, j, k], u[2, i, j, k]
    w0, w1, w2 = w[0, i, j, k], w[1, i, j, k], w[2, i, j, k]
    n[0, i, j, k] = u1 * w2 - u2 * w1
    n[1, i, j, k] = u2 * w0 - u0 * w2
    n[2, i, j, k] = u0 * w1 - u1 * w0


@njit(cache=True, nogil=True)
def cross_into(u, w):
    """w <- u x w, real (3, NX, NY, NZ) arrays (``cross`` without a third field)."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                _cross_point(u, w, w, i, j, k)


@njit(cache=True, nogil=True)
def cross(u, w, n):
    """n = u x w, real (3, NX, NY, NZ) arrays."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                _cross_point(u, w, n, i, j, k)


@njit(inline="always")
def _project_point(a, b, c, ki, kj, kk, inv):
    """P v = v - k (k.v)/k^2 at one mode, as kapsel.mesh.grid.Grid.project computes it."""
    return _project_metric_point(a, b, c, ki, kj, kk, inv, ki, kj)


@njit(inline="always")
def _project_metric_point(a, b, c, ki, kj, kk, inv, g1, g2):
    """v - (g1, g2, k_3) (k.v) inv at one mode: the Cartesian projection with (g1, g2) =
    (k_1, k_2), the oblique frame's metric one with (G k)^1, (G k)^2 (``project_oblique``)."""
    sr = a.real * ki + b.real * kj
    si = a.imag * ki + b.imag * kj
    sr = sr + c.real * kk
    si = si + c.imag * kk
    sr = sr * inv
    si = si * inv
    a = complex(a.real - sr * g1, a.imag - si * g1)
    b = complex(b.real - sr * g2, b.imag - si * g2)
    c = complex(c.real - sr * kk, c.imag - si * kk)
    return a, b, c


@njit(inline="always")
def _scale(z, s):
    return complex(z.real * s, z.imag * s)


@njit(inline="always")
def _etd1(u, p, e, w):
    """E u + a1 P nl at one mode of one component (p = P nl)."""
    return _scale(u, e) + _scale(p, w)


@njit(inline="always")
def _etd2(u, p, o, e, w, v):
    """E u + a2 P nl - b2 P nl_old at one mode of one component."""
    return (_scale(u, e) + _scale(p, w)) - _scale(o, v)


@njit(inline="always")
def _off(w, v, i, j, k):
    """Whether the nonlinear weights are 0 at a mode (w: a1 or a2; v: b2 or None): the 2/3
    mask removes it, and the ETD update is E u_hat there (``_decay_only``)."""
    return w[i, j, k] == 0.0 and (v is None or v[i, j, k] == 0.0)


@njit(inline="always")
def _decay_only(u_hat, i, j, k, e):
    """u_hat <- E u_hat at a mode whose nonlinear weights are 0: E u + 0 p, the same value
    without reading p (nl there may hold the partial sums of a truncated transform,
    kapsel.mesh.grid; nl is neither read nor projected there, and the next step's weights
    are 0 there too); nothing is written where u_hat is 0 (a truncated state's)."""
    for c in range(3):
        u = u_hat[c, i, j, k]
        if u.real != 0.0 or u.imag != 0.0:
            u_hat[c, i, j, k] = _scale(u, e)


@njit(inline="always")
def _decay_one(u_hat, c, i, j, k, e):
    """``_decay_only`` of one component (the sweeps by rows)."""
    u = u_hat[c, i, j, k]
    if u.real != 0.0 or u.imag != 0.0:
        u_hat[c, i, j, k] = _scale(u, e)


@njit(inline="always")
def _less(a, sr, si, kc):
    """a - k_c s: component c of a projection whose coefficient (k.v)/k^2 is (sr, si)."""
    return complex(a.real - sr * kc, a.imag - si * kc)


@njit(cache=True, nogil=True)
def project_etd1(nl, u_hat, E, a1, kx, ky, kz, inv_k2, store):
    """u_hat <- E u_hat + a1 P nl  (slaved Euler, eq 8); nl <- P nl on the mask if ``store``
    (ETD2's first step keeps it; off the mask nl is left as it was, which ETD2's b2 = 0
    there never reads), else nl is left as it was.  Where a1 is 0 (off the 2/3 mask):
    u_hat <- E u_hat, nl not read (``_decay_only``)."""
    _etd1_sweep(nl, u_hat, E, a1, kx, ky, kz, inv_k2, store, kx, kx, 0, 0.0, False)


@njit(cache=True, nogil=True)
def project_etd1_velocity(nl, u_hat, E, a1, kx, ky, kz, inv_k2, mx, my, kz_end, inv_n):
    """``project_etd1`` (nl not stored), then at each mode nl <- the new u_hat inv_n: the
    components of u / N that the c2r of u after the step transforms, as ``scaled_component``
    makes them (the same products of the same values), without a second sweep over u_hat.
    Returns whether the new u_hat is 0 off the mask's box (``Grid.dealias_box``), i.e.
    whether the transforms may skip the lines of zeros."""
    return _etd1_sweep(nl, u_hat, E, a1, kx, ky, kz, inv_k2, False, mx, my, kz_end, inv_n,
                       True)


@njit(inline="always")
def _scaled_out(u_hat, nl, c, i, j, k, s, inbox):
    """nl[c] <- u_hat[c] s at a mode (``scaled_component``'s product); returns |Re| + |Im|
    of u_hat[c] there off the mask's box (``inbox`` False), else 0."""
    u = u_hat[c, i, j, k]
    nl[c, i, j, k] = _scale(u, s)
    if inbox:
        return 0.0
    return abs(u.real) + abs(u.imag)


@njit(inline="always")
def _etd1_sweep(nl, u_hat, E, a1, kx, ky, kz, inv_k2, store, mx, my, kz_end, inv_n,
                velocity):
    """The sweep of ``project_etd1`` (``velocity`` False) and ``project_etd1_velocity``
    (True: a constant of each, folded when inlined); returns whether u_hat is 0 off the
    box (True without ``velocity``)."""
    nx, ny, nzc = E.shape
    nonzero = 0.0
    for i in range(nx):
        ki = kx[i]
        for j in range(ny):
            kj = ky[j]
            row = velocity and mx[i] != 0.0 and my[j] != 0.0
            for k in range(nzc):
                if _off(a1, None, i, j, k):
                    _decay_only(u_hat, i, j, k, E[i, j, k])
                else:
                    kk = kz[k]
                    a, b, c = _project_point(nl[0, i, j, k], nl[1, i, j, k],
                                             nl[2, i, j, k], ki, kj, kk, inv_k2[i, j, k])
                    if store:
                        nl[0, i, j, k] = a
                        nl[1, i, j, k] = b
                        nl[2, i, j, k] = c
                    e = E[i, j, k]
                    w = a1[i, j, k]
                    u_hat[0, i, j, k] = _etd1(u_hat[0, i, j, k], a, e, w)
                    u_hat[1, i, j, k] = _etd1(u_hat[1, i, j, k], b, e, w)
                    u_hat[2, i, j, k] = _etd1(u_hat[2, i, j, k], c, e, w)
                if velocity:
                    inbox = row and k < kz_end
                    for cc in range(3):
                        nonzero += _scaled_out(u_hat, nl, cc, i, j, k, inv_n, inbox)
    return nonzero == 0.0


@njit(cache=True, nogil=True)
def project_etd2(nl, nl_old, u_hat, E, a2, b2, kx, ky, kz, inv_k2):
    """nl <- P nl;  u_hat <- E u_hat + a2 nl - b2 nl_old  (ETD2); where a2 and b2 are 0
    (off the 2/3 mask): u_hat <- E u_hat, nl and nl_old not read (``_decay_only``)."""
    nx, ny, nzc = E.shape
    for i in range(nx):
        ki = kx[i]
        for j in range(ny):
            kj = ky[j]
            for k in range(nzc):
                if _off(a2, b2, i, j, k):
                    _decay_only(u_hat, i, j, k, E[i, j, k])
                    continue
                kk = kz[k]
                a, b, c = _project_point(nl[0, i, j, k], nl[1, i, j, k], nl[2, i, j, k],
                                         ki, kj, kk, inv_k2[i, j, k])
                nl[0, i, j, k] = a
                nl[1, i, j, k] = b
                nl[2, i, j, k] = c
                e = E[i, j, k]
                w = a2[i, j, k]
                v = b2[i, j, k]
                u_hat[0, i, j, k] = _etd2(u_hat[0, i, j, k], a, nl_old[0, i, j, k], e, w, v)
                u_hat[1, i, j, k] = _etd2(u_hat[1, i, j, k], b, nl_old[1, i, j, k], e, w, v)
                u_hat[2, i, j, k] = _etd2(u_hat[2, i, j, k], c, nl_old[2, i, j, k], e, w, v)


@njit(inline="always")
def _project_masked(d, u_hat, mask, kx, ky, kz, inv_k2, scale, add):
    """P (mask d) at every mode: ``add``: u_hat += it; else u_hat <- 0 + it and
    d <- (0 + it) scale (``project_add``, ``project_set_scaled``).  Where the mask is 0,
    d is not read (``_masked_out``)."""
    nx, ny, nzc = inv_k2.shape
    for i in range(nx):
        ki = kx[i]
        for j in range(ny):
            kj = ky[j]
            for k in range(nzc):
                m = mask[i, j, k]
                if m == 0.0:
                    _masked_out(d, u_hat, i, j, k, add)
                    continue
                a = _scale(d[0, i, j, k], m)
                b = _scale(d[1, i, j, k], m)
                c = _scale(d[2, i, j, k], m)
                a, b, c = _project_point(a, b, c, ki, kj, kz[k], inv_k2[i, j, k])
                if add:
                    u_hat[0, i, j, k] += a
                    u_hat[1, i, j, k] += b
                    u_hat[2, i, j, k] += c
                    continue
                a, b, c = _zero_plus(a), _zero_plus(b), _zero_plus(c)
                u_hat[0, i, j, k] = a
                u_hat[1, i, j, k] = b
                u_hat[2, i, j, k] = c
                d[0, i, j, k] = _scale(a, scale)
                d[1, i, j, k] = _scale(b, scale)
                d[2, i, j, k] = _scale(c, scale)


@njit(cache=True, nogil=True)
def project_add(d, u_hat, mask, kx, ky, kz, inv_k2):
    """u_hat += P (mask d)  (d is left unchanged)."""
    _project_masked(d, u_hat, mask, kx, ky, kz, inv_k2, 1.0, True)


@njit(cache=True, nogil=True)
def project_set_scaled(d, u_hat, mask, kx, ky, kz, inv_k2, scale):
    """u_hat <- 0 + P (mask d) and d <- u_hat scale: what a zeroed u_hat, ``project_add``
    and a multiplication by ``scale`` (the 1/N of the c2r that follows) give, in one pass
    (the squirmers' slip flow, kapsel.particles.janus)."""
    _project_masked(d, u_hat, mask, kx, ky, kz, inv_k2, scale, False)


@njit(inline="always")
def _masked_out(d, u_hat, i, j, k, add):
    """A mode the mask removes: P (0 d) is 0 there (the projection acts mode by mode), so
    ``add`` leaves u_hat as it is (u_hat + 0: the same value; a -0 in u_hat stays -0 where
    the sum could give +0) and the set form writes 0 + 0 = +0 and its scaled +0, the bits
    of the full computation.  d is not read: it may hold the partial sums of a truncated
    transform (kapsel.mesh.grid), and the pass reads a third of the memory at 64^3."""
    if add:
        return
    for c in range(3):
        u_hat[c, i, j, k] = complex(0.0, 0.0)
        d[c, i, j, k] = complex(0.0, 0.0)


@njit(inline="always")
def _zero_plus(p):
    """0 + p, as a zeroed array plus p (the sign of a zero result included)."""
    return complex(0.0 + p.real, 0.0 + p.imag)


@njit(inline="always")
def _euler_point(u, p, nk, dt, m):
    """u <- (u + (p - nk u) dt) m for one component at one mode: the Electrolyte's explicit
    Euler update, as SpectralNS.euler_step's numpy passes compute it."""
    xr = p.real - nk * u.real
    xi = p.imag - nk * u.imag
    return complex((u.real + xr * dt) * m, (u.imag + xi * dt) * m)


@njit(cache=True, nogil=True)
def project_euler(nl, u_hat, k2, nu, dt, mask, kx, ky, kz, inv_k2, project):
    """nl <- P nl if ``project``;  u_hat <- T[u_hat + dt (nl - (nu k2) u_hat)] (the
    Electrolyte's explicit Euler, fluid_solver.cxx NSsolute_solver_Euler); nl is left
    holding P nl on the mask.  Where the mask is 0, u_hat <- +0 and nl is not read (it may
    hold the partial sums of a truncated transform): the value of the full computation,
    (...) 0, whose zero could have had either sign."""
    nx, ny, nzc = mask.shape
    for i in range(nx):
        ki = kx[i]
        for j in range(ny):
            kj = ky[j]
            for k in range(nzc):
                m = mask[i, j, k]
                if m == 0.0:
                    for cc in range(3):
                        u_hat[cc, i, j, k] = complex(0.0, 0.0)
                    continue
                a, b, c = nl[0, i, j, k], nl[1, i, j, k], nl[2, i, j, k]
                if project:
                    a, b, c = _project_point(a, b, c, ki, kj, kz[k], inv_k2[i, j, k])
                    nl[0, i, j, k] = a
                    nl[1, i, j, k] = b
                    nl[2, i, j, k] = c
                nk = nu * k2[i, j, k]
                u_hat[0, i, j, k] = _euler_point(u_hat[0, i, j, k], a, nk, dt, m)
                u_hat[1, i, j, k] = _euler_point(u_hat[1, i, j, k], b, nk, dt, m)
                u_hat[2, i, j, k] = _euler_point(u_hat[2, i, j, k], c, nk, dt, m)


@njit(inline="always")
def _pick(c, ki, kj, kz, k):
    return ki if c == 0 else (kj if c == 1 else kz[k])


@njit(inline="always")
def _coefficients(v, i, j0, j1, ki, ky, kz, inv_k2, mask, sr, si, w=None, wv=None):
    """(sr, si)[j - j0, k] = (k.(mask v))/k^2 on rows j0..j1-1 of plane i, summed as
    ``_project_point`` sums it; mask None: v itself.  Not made where the mask is 0, nor
    where the weights ``w``, ``wv`` are (``_off``): the callers skip those modes."""
    nzc = sr.shape[1]
    for j in range(j0, j1):
        kj = ky[j]
        for k in range(nzc):
            if mask is not None and mask[i, j, k] == 0.0:
                continue                # (not used: _project_masked_rows skips the mode)
            if w is not None and _off(w, wv, i, j, k):
                continue
            a = v[0, i, j, k]
            b = v[1, i, j, k]
            c = v[2, i, j, k]
            if mask is None:
                ar, ai, br, bi, cr, ci = a.real, a.imag, b.real, b.imag, c.real, c.imag
            else:
                m = mask[i, j, k]
                ar, ai = a.real * m, a.imag * m
                br, bi = b.real * m, b.imag * m
                cr, ci = c.real * m, c.imag * m
            kk = kz[k]
            r = ar * ki + br * kj
            q = ai * ki + bi * kj
            r = r + cr * kk
            q = q + ci * kk
            inv = inv_k2[i, j, k]
            sr[j - j0, k] = r * inv
            si[j - j0, k] = q * inv


@njit(cache=True, nogil=True)
def project_etd1_rows(nl, u_hat, E, a1, kx, ky, kz, inv_k2, store):
    """``project_etd1`` by blocks of rows (the same bits)."""
    _etd1_sweep_rows(nl, u_hat, E, a1, kx, ky, kz, inv_k2, store, kx, kx, 0, 0.0, False)


@njit(cache=True, nogil=True)
def project_etd1_velocity_rows(nl, u_hat, E, a1, kx, ky, kz, inv_k2, mx, my, kz_end, inv_n):
    """``project_etd1_velocity`` by blocks of rows (the same bits)."""
    return _etd1_sweep_rows(nl, u_hat, E, a1, kx, ky, kz, inv_k2, False, mx, my, kz_end,
                            inv_n, True)


@njit(inline="always")
def _etd1_sweep_rows(nl, u_hat, E, a1, kx, ky, kz, inv_k2, store, mx, my, kz_end, inv_n,
                     velocity):
    """``_etd1_sweep`` by blocks of rows (the same bits)."""
    nx, ny, nzc = E.shape
    sr = np.empty((ROWS, nzc))
    si = np.empty((ROWS, nzc))
    nonzero = 0.0
    for i in range(nx):
        ki = kx[i]
        for j0 in range(0, ny, ROWS):
            j1 = min(j0 + ROWS, ny)
            _coefficients(nl, i, j0, j1, ki, ky, kz, inv_k2, None, sr, si, a1)
            for c in range(3):
                for j in range(j0, j1):
                    kj = ky[j]
                    row = velocity and mx[i] != 0.0 and my[j] != 0.0
                    for k in range(nzc):
                        if _off(a1, None, i, j, k):
                            _decay_one(u_hat, c, i, j, k, E[i, j, k])
                        else:
                            p = _less(nl[c, i, j, k], sr[j - j0, k], si[j - j0, k],
                                      _pick(c, ki, kj, kz, k))
                            if store:
                                nl[c, i, j, k] = p
                            u_hat[c, i, j, k] = _etd1(u_hat[c, i, j, k], p, E[i, j, k],
                                                      a1[i, j, k])
                        if velocity:
                            nonzero += _scaled_out(u_hat, nl, c, i, j, k, inv_n,
                                                   row and k < kz_end)
    return nonzero == 0.0


@njit(cache=True, nogil=True)
def project_etd2_rows(nl, nl_old, u_hat, E, a2, b2, kx, ky, kz, inv_k2):
    """``project_etd2`` by blocks of rows (the same bits)."""
    nx, ny, nzc = E.shape
    sr = np.empty((ROWS, nzc))
    si = np.empty((ROWS, nzc))
    for i in range(nx):
        ki = kx[i]
        for j0 in range(0, ny, ROWS):
            j1 = min(j0 + ROWS, ny)
            _coefficients(nl, i, j0, j1, ki, ky, kz, inv_k2, None, sr, si, a2, b2)
            for c in range(3):
                for j in range(j0, j1):
                    kj = ky[j]
                    for k in range(nzc):
                        if _off(a2, b2, i, j, k):
                            _decay_one(u_hat, c, i, j, k, E[i, j, k])
                            continue
                        p = _less(nl[c, i, j, k], sr[j - j0, k], si[j - j0, k],
                                  _pick(c, ki, kj, kz, k))
                        nl[c, i, j, k] = p
                        u_hat[c, i, j, k] = _etd2(u_hat[c, i, j, k], p, nl_old[c, i, j, k],
                                                  E[i, j, k], a2[i, j, k], b2[i, j, k])


@njit(inline="always")
def _project_masked_rows(d, u_hat, mask, kx, ky, kz, inv_k2, scale, add):
    """``_project_masked`` by blocks of rows (the same bits)."""
    nx, ny, nzc = inv_k2.shape
    sr = np.empty((ROWS, nzc))
    si = np.empty((ROWS, nzc))
    for i in range(nx):
        ki = kx[i]
        for j0 in range(0, ny, ROWS):
            j1 = min(j0 + ROWS, ny)
            _coefficients(d, i, j0, j1, ki, ky, kz, inv_k2, mask, sr, si)
            for c in range(3):
                for j in range(j0, j1):
                    kj = ky[j]
                    for k in range(nzc):
                        if mask[i, j, k] == 0.0:
                            if not add:
                                u_hat[c, i, j, k] = complex(0.0, 0.0)
                                d[c, i, j, k] = complex(0.0, 0.0)
                            continue
                        p = _less(_scale(d[c, i, j, k], mask[i, j, k]), sr[j - j0, k],
                                  si[j - j0, k], _pick(c, ki, kj, kz, k))
                        if add:
                            u_hat[c, i, j, k] += p
                        else:
                            p = _zero_plus(p)
                            u_hat[c, i, j, k] = p
                            d[c, i, j, k] = _scale(p, scale)


@njit(cache=True, nogil=True)
def project_add_rows(d, u_hat, mask, kx, ky, kz, inv_k2):
    """``project_add`` by blocks of rows (the same bits)."""
    _project_masked_rows(d, u_hat, mask, kx, ky, kz, inv_k2, 1.0, True)


@njit(cache=True, nogil=True)
def project_set_scaled_rows(d, u_hat, mask, kx, ky, kz, inv_k2, scale):
    """``project_set_scaled`` by blocks of rows (the same bits)."""
    _project_masked_rows(d, u_hat, mask, kx, ky, kz, inv_k2, scale, False)


@njit(cache=True, nogil=True)
def project_euler_rows(nl, u_hat, k2, nu, dt, mask, kx, ky, kz, inv_k2, project):
    """``project_euler`` by blocks of rows (the same bits)."""
    nx, ny, nzc = mask.shape
    sr = np.zeros((ROWS, nzc))
    si = np.zeros((ROWS, nzc))
    for i in range(nx):
        ki = kx[i]
        for j0 in range(0, ny, ROWS):
            j1 = min(j0 + ROWS, ny)
            if project:     # (masked: the same numbers on the mask, nl not read off it)
                _coefficients(nl, i, j0, j1, ki, ky, kz, inv_k2, mask, sr, si)
            for c in range(3):
                for j in range(j0, j1):
                    kj = ky[j]
                    for k in range(nzc):
                        if mask[i, j, k] == 0.0:
                            u_hat[c, i, j, k] = complex(0.0, 0.0)
                            continue
                        p = nl[c, i, j, k]
                        if project:
                            p = _less(p, sr[j - j0, k], si[j - j0, k], _pick(c, ki, kj, kz, k))
                            nl[c, i, j, k] = p
                        u_hat[c, i, j, k] = _euler_point(u_hat[c, i, j, k], p, nu * k2[i, j, k],
                                                         dt, mask[i, j, k])


# ---------------------------------------------------------------------------- oblique frame
# The Lees-Edwards step (kapsel.fluid.oblique.ObliqueSpectralNS): u_hat holds contravariant
# components u^i; its Cartesian u_1 = u^1 + g u^2 (g the frame strain), the physical
# wavevector K = (k_1, k_2 - g k_1, k_3).  The same operations, in the same order, as that
# class's numpy passes (values equal; the sign of a zero result may differ).  g = 0 is the
# unsheared frame of SpectralNS (``frame_component`` takes the Cartesian kernels there;
# ``vorticity_component`` is ``frame_vorticity_component`` with u_1 = u^1 read alone, K = k
# to the value).

@njit(inline="always")
def _frame_point(u_hat, i, j, k, s, g, c):
    """Component c of the Cartesian u_hat s at one mode (u_1 = u^1 s + (u^2 s) g)."""
    a = u_hat[c, i, j, k]
    if c != 0 or g == 0.0:
        return complex(a.real * s, a.imag * s)
    b = u_hat[1, i, j, k]
    return complex(a.real * s + (b.real * s) * g, a.imag * s + (b.imag * s) * g)


@njit(cache=True, nogil=True)
def frame_component(u_hat, mx, my, kz_end, scale, g, c, truncate, out):
    """out = component c of the Cartesian u_hat scale (u_1 = u^1 + g u^2).  ``truncate``:
    times the 2/3 mask (the box of ``truncated_component``, +0 off it, u_hat not read
    there), returns True; else every mode is scaled and the result tells whether out is 0
    off the mask (``scaled_component``).  u^2, u^3 and g = 0 are those two kernels' (their
    loops vectorise); u_1 of a sheared frame is made here, the same way."""
    if c != 0 or g == 0.0:
        if truncate:
            truncated_component(u_hat, mx, my, kz_end, scale, c, out)
            return True
        return scaled_component(u_hat, mx, my, kz_end, scale, c, out)
    nx, ny, nzc = out.shape
    nonzero = 0.0
    for i in range(nx):
        for j in range(ny):
            k0 = 0 if (mx[i] == 0.0 or my[j] == 0.0) else kz_end
            for k in range(k0):
                out[i, j, k] = _frame_point(u_hat, i, j, k, scale, g, c)
            if truncate:
                for k in range(k0, nzc):
                    out[i, j, k] = complex(0.0, 0.0)
                continue
            for k in range(k0, nzc):
                z = _frame_point(u_hat, i, j, k, scale, g, c)
                nonzero += abs(z.real) + abs(z.imag)
                out[i, j, k] = z
    return nonzero == 0.0


@njit(cache=True, nogil=True)
def frame_vorticity_component(u_hat, mx, my, kz_end, scale, g, kx, ky, kz, c, out):
    """out = (i K x u)[c] of the truncated Cartesian u_hat scale (``frame_component``),
    K = (k_1, k_2 - g k_1, k_3); +0 off the mask (its box), u_hat not read there."""
    nx, ny, nzc = out.shape
    p, q = (c + 1) % 3, (c + 2) % 3          # w_c = i K_p u_q - i K_q u_p
    for i in range(nx):
        for j in range(ny):
            if mx[i] == 0.0 or my[j] == 0.0:
                for k in range(nzc):
                    out[i, j, k] = complex(0.0, 0.0)
                continue
            ky_ = ky[j] - g * kx[i]
            for k in range(kz_end):
                kp = kx[i] if p == 0 else (ky_ if p == 1 else kz[k])
                kq = kx[i] if q == 0 else (ky_ if q == 1 else kz[k])
                a = _frame_point(u_hat, i, j, k, scale, g, q)
                b = _frame_point(u_hat, i, j, k, scale, g, p)
                out[i, j, k] = complex((-(kp * a.imag)) - (-(kq * b.imag)),
                                       (kp * a.real) - (kq * b.real))
            for k in range(kz_end, nzc):
                out[i, j, k] = complex(0.0, 0.0)


@njit(inline="always")
def _curl_point(a0, a1, a2, k0, k1, k2):
    """i K x a at one mode, each component as ``frame_vorticity_component`` makes it
    (w_c = i K_p a_q - i K_q a_p, p = c + 1, q = c + 2)."""
    return (complex((-(k1 * a2.imag)) - (-(k2 * a1.imag)), (k1 * a2.real) - (k2 * a1.real)),
            complex((-(k2 * a0.imag)) - (-(k0 * a2.imag)), (k2 * a0.real) - (k0 * a2.real)),
            complex((-(k0 * a1.imag)) - (-(k1 * a0.imag)), (k0 * a1.real) - (k1 * a0.real)))


@njit(cache=True, nogil=True)
def velocity_vorticity(u_hat, mx, my, kz_end, scale, g, kx, ky, kz, v, a, b, c):
    """v (3 components) <- the truncated Cartesian u_hat scale, (a, b, c) <- its vorticity
    i K x u, in one sweep over the mask's box (``frame_component`` with ``truncate`` and
    ``frame_vorticity_component``, the same products; +0 off the box): the inputs of the
    c2r of the Lees-Edwards u x omega.  (Navier_Stokes keeps the sweeps a component at a
    time: there the c2r reads each from a complex scalar still in the cache, and one sweep
    into five fields made its step 1.4-1.7 % slower, 2026-12-06.)"""
    nx, ny, nzc = a.shape
    zero = complex(0.0, 0.0)
    for i in range(nx):
        k0 = kx[i]
        for j in range(ny):
            k1 = ky[j] - g * kx[i]
            kb = kz_end if (mx[i] != 0.0 and my[j] != 0.0) else 0
            for k in range(kb):
                u0 = _frame_point(u_hat, i, j, k, scale, g, 0)
                u1 = _frame_point(u_hat, i, j, k, scale, g, 1)
                u2 = _frame_point(u_hat, i, j, k, scale, g, 2)
                w0, w1, w2 = _curl_point(u0, u1, u2, k0, k1, kz[k])
                _put_six(v, a, b, c, i, j, k, u0, u1, u2, w0, w1, w2)
            for k in range(kb, nzc):
                _put_six(v, a, b, c, i, j, k, zero, zero, zero, zero, zero, zero)


@njit(inline="always")
def _put_six(v, a, b, c, i, j, k, u0, u1, u2, w0, w1, w2):
    """v[:, i, j, k] <- (u0, u1, u2), a, b, c [i, j, k] <- w0, w1, w2."""
    v[0, i, j, k] = u0
    v[1, i, j, k] = u1
    v[2, i, j, k] = u2
    a[i, j, k] = w0
    b[i, j, k] = w1
    c[i, j, k] = w2


@njit(inline="always")
def _metric_k2(ki, kj, kk, gg, g2):
    """|K|^2 = G^jk k^_j k^_k of the frame strain g at one mode (gg = 1 + g^2, g2 = 2 g), as
    ObliqueSpectralNS._metric computes it: k1^2 gg - g2 k1 k2 + (k2^2 + k3^2)."""
    t = (ki * ki) * gg
    t = t - g2 * (ki * kj)
    return t + (kj * kj + kk * kk)


@njit(inline="always")
def _inverse_metric_row(row, ki, kj, kz, n, gg, g2):
    """row[k] <- 1 / |K|^2 (0 at K = 0) of the modes (i, j, k < n) (a loop of its own:
    SIMD)."""
    for k in range(n):
        K2 = _metric_k2(ki, kj, kz[k], gg, g2)
        row[k] = 1.0 / K2 if K2 > 0.0 else 0.0


@njit(cache=True, nogil=True)
def project_oblique(v, u_hat, r2, g, kx, ky, kz, mx, my, kz_end, masked, add):
    """v <- P^G (v - r2 u^2 e_1) in place (the term only if r2 != 0; ObliqueSpectralNS's
    nonlinear term, ``project_metric``): P^G v = v - G k (k.v) / |K|^2, the contravariant
    (G k)^1 = (1 + g^2) k_1 - g k_2, (G k)^2 = k_2 - g k_1, (G k)^3 = k_3, 1 / |K|^2 made at
    each mode (``_metric_k2``; 0 at K = 0).  ``masked``: of (v - r2 u^2 e_1) times the 2/3
    mask (the box of ``truncated_component``): +0 off it, where neither v (which may hold
    the partial sums of a truncated transform) nor u_hat is read; on it the mask's 1 leaves
    the values as they are.  ``add``: u_hat += P^G v instead (add_solenoidal; v is left as
    it was)."""
    nx, ny, nzc = v.shape[1], v.shape[2], v.shape[3]
    gg = 1.0 + g * g
    g2 = 2.0 * g
    row = np.empty(nzc)                 # 1 / |K|^2 along a row
    for i in range(nx):
        ki = kx[i]
        for j in range(ny):
            kj = ky[j]
            c0 = gg * ki - g * kj
            c1 = kj - g * ki
            k1 = nzc
            if masked:
                k1 = 0 if (mx[i] == 0.0 or my[j] == 0.0) else kz_end
                for k in range(k1, nzc):
                    for cc in range(3):
                        v[cc, i, j, k] = complex(0.0, 0.0)
            _inverse_metric_row(row, ki, kj, kz, k1, gg, g2)
            for k in range(k1):
                a, b, c = v[0, i, j, k], v[1, i, j, k], v[2, i, j, k]
                if r2 != 0.0:
                    u = u_hat[1, i, j, k]
                    a = complex(a.real - r2 * u.real, a.imag - r2 * u.imag)
                a, b, c = _project_metric_point(a, b, c, ki, kj, kz[k], row[k], c0, c1)
                if add:
                    u_hat[0, i, j, k] += a
                    u_hat[1, i, j, k] += b
                    u_hat[2, i, j, k] += c
                else:
                    v[0, i, j, k] = a
                    v[1, i, j, k] = b
                    v[2, i, j, k] = c


@njit(cache=True, nogil=True)
def project_oblique_etd1(v, u_hat, r2, g, kx, ky, kz, cx, cy, kz_end, E, w1):
    """u_hat <- E (T u_hat) + w1 p, p = ``project_oblique`` (masked) of v: the three passes
    of the Lees-Edwards step (the truncation of u_hat, the projection of its nonlinear term,
    ``etd1_update``) in one, with the same operations at each mode (u^2 of the shear term
    read before the mode is updated); off the mask, where E (T u_hat) + w1 p is +0 + +0,
    +0 is written (u_hat is not read there, as the truncation's zero made it); v is not
    written.  The caller does not truncate u_hat first: nothing before this pass reads it
    off the mask (the frame kernels read the box only).  The mask's box as indices: cx[i]
    (cy[j]) the row of i (j) in the box, -1 off it, and k < kz_end; E and w1 are given on
    the box only, (rows of cx, rows of cy, kz_end) (``viscous_exponent``)."""
    _oblique_etd1(v, u_hat, r2, g, kx, ky, kz, cx, cy, kz_end, E, w1, 0.0, 0.0, False)


@njit(cache=True, nogil=True)
def project_oblique_etd1_velocity(v, u_hat, r2, g, kx, ky, kz, cx, cy, kz_end, E, w1, g1,
                                  inv_n):
    """``project_oblique_etd1``, then at each mode v <- the Cartesian components of the new
    u_hat inv_n in the frame of strain g1 (the frame after the step): what
    ``frame_component`` makes for the c2r of u, the same products of the same values, +0
    off the mask's box (where u_hat is +0), without a second sweep over u_hat."""
    _oblique_etd1(v, u_hat, r2, g, kx, ky, kz, cx, cy, kz_end, E, w1, g1, inv_n, True)


@njit(inline="always")
def _oblique_etd1(v, u_hat, r2, g, kx, ky, kz, cx, cy, kz_end, E, w1, g1, inv_n, velocity):
    """The sweep of ``project_oblique_etd1`` (``velocity`` False) and
    ``project_oblique_etd1_velocity`` (True; a constant of each, folded when inlined)."""
    nx, ny, nzc = v.shape[1], v.shape[2], v.shape[3]
    gg = 1.0 + g * g
    g2 = 2.0 * g
    zero = complex(0.0, 0.0)
    row = np.empty(nzc)
    for i in range(nx):
        ki = kx[i]
        a_ = cx[i]
        for j in range(ny):
            kj = ky[j]
            b_ = cy[j]
            c0 = gg * ki - g * kj
            c1 = kj - g * ki
            k1 = 0 if (a_ < 0 or b_ < 0) else kz_end
            _inverse_metric_row(row, ki, kj, kz, k1, gg, g2)
            for k in range(k1):
                a, b, c = v[0, i, j, k], v[1, i, j, k], v[2, i, j, k]   # (project_oblique's
                if r2 != 0.0:                   # lines: as an inline helper of both, the
                    u = u_hat[1, i, j, k]       # shear term's branch made them 3x slower)
                    a = complex(a.real - r2 * u.real, a.imag - r2 * u.imag)
                a, b, c = _project_metric_point(a, b, c, ki, kj, kz[k], row[k], c0, c1)
                e, w = E[a_, b_, k], w1[a_, b_, k]
                u_hat[0, i, j, k] = _etd1(u_hat[0, i, j, k], a, e, w)
                u_hat[1, i, j, k] = _etd1(u_hat[1, i, j, k], b, e, w)
                u_hat[2, i, j, k] = _etd1(u_hat[2, i, j, k], c, e, w)
                if velocity:
                    for cc in range(3):
                        v[cc, i, j, k] = _frame_point(u_hat, i, j, k, inv_n, g1, cc)
            for k in range(k1, nzc):
                for cc in range(3):
                    u_hat[cc, i, j, k] = zero
                    if velocity:
                        v[cc, i, j, k] = zero


@njit(cache=True, nogil=True)
def viscous_exponent(kx, ky, kz, ix, jy, g, s, z):
    """z[a, b, k] <- |K|^2 s at the mode (ix[a], jy[b], k) (``_metric_k2``; s = -nu dt: the
    exponent of the step's viscous factor, ObliqueSpectralNS.step), for the rows ix, jy
    and the first z.shape[2] modes along z: every mode, or the 2/3 mask's box only."""
    na, nb, nk = z.shape
    gg = 1.0 + g * g
    g2 = 2.0 * g
    for a in range(na):
        ki = kx[ix[a]]
        for b in range(nb):
            kj = ky[jy[b]]
            for k in range(nk):
                z[a, b, k] = _metric_k2(ki, kj, kz[k], gg, g2) * s


@njit(cache=True, nogil=True)
def truncate(u_hat, mx, my, kz_end):
    """u_hat <- u_hat times the 2/3 mask (its box, ``truncated_component``): +0 off it
    (where the product's zero could have had either sign), nothing written on it (1 u =
    u)."""
    nc, nx, ny, nzc = u_hat.shape
    for c in range(nc):
        for i in range(nx):
            for j in range(ny):
                k0 = 0 if (mx[i] == 0.0 or my[j] == 0.0) else kz_end
                for k in range(k0, nzc):
                    u_hat[c, i, j, k] = complex(0.0, 0.0)


@njit(cache=True, nogil=True)
def cross_contravariant(u, w, g):
    """w <- u x w in contravariant components: n^1 = n_x - g n_y (numpy's n[0] -= g n[1]
    after ``cross``), in place (into a third array the sweep is 1.8x slower: 0.90 against
    0.51 ms at 64^3)."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                u0, u1, u2 = u[0, i, j, k], u[1, i, j, k], u[2, i, j, k]
                w0, w1, w2 = w[0, i, j, k], w[1, i, j, k], w[2, i, j, k]
                n0 = u1 * w2 - u2 * w1            # (``_cross_point``'s products)
                n1 = u2 * w0 - u0 * w2
                w[0, i, j, k] = n0 - g * n1
                w[1, i, j, k] = n1
                w[2, i, j, k] = u0 * w1 - u1 * w0


@njit(cache=True, nogil=True)
def contravariant(u, g, out):
    """out <- the contravariant components of the Cartesian u (3, NX, NY, NZ) in the frame
    of strain g: u^1 = u_x - g u_y, u^2 = u_y, u^3 = u_z (kapsel.mesh.oblique.contravariant's
    copy and out[0] -= g u[1], in one pass)."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                b = u[1, i, j, k]
                out[0, i, j, k] = u[0, i, j, k] - g * b
                out[1, i, j, k] = b
                out[2, i, j, k] = u[2, i, j, k]


@njit(cache=True, nogil=True)
def contravariant_in_place(u, g):
    """u <- its contravariant components in the frame of strain g: u^1 = u_x - g u_y (as
    ``contravariant`` makes it); u_y and u_z are their own, read and not written."""
    nx, ny, nz = u.shape[1], u.shape[2], u.shape[3]
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                u[0, i, j, k] = u[0, i, j, k] - g * u[1, i, j, k]


@njit(cache=True, nogil=True)
def reynolds_terms(u_hat, g, w, out):
    """out <- w_k (Re u_x Re u_y + Im u_x Im u_y) at each mode, u_x = u^1 + g u^2, u_y = u^2
    of the contravariant u_hat: the terms of the Lees-Edwards table's Reynolds stress, with
    numpy's operations (g u^2 as its complex product by g + 0j, then the sum, the two real
    products, their sum, the weight); their sum stays numpy's (its pairwise order)."""
    nx, ny, nzc = out.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                a = u_hat[0, i, j, k]
                b = u_hat[1, i, j, k]
                xr = a.real + (g * b.real - 0.0 * b.imag)
                xi = a.imag + (g * b.imag + 0.0 * b.real)
                out[i, j, k] = w[k] * (xr * b.real + xi * b.imag)


@njit(cache=True, nogil=True)
def etd1_update(u_hat, nl, E, w1):
    """u_hat <- E u_hat + w1 nl (the slaved Euler update of a projected nl)."""
    nx, ny, nzc = E.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nzc):
                e, w = E[i, j, k], w1[i, j, k]
                for c in range(3):
                    u_hat[c, i, j, k] = _etd1(u_hat[c, i, j, k], nl[c, i, j, k], e, w)
