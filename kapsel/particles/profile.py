"""Smoothed particle profile of the SPM (manual §4.1, eqs 1-4).

    h(x)   = exp(-DX^2 / x^2) for x >= 0, else 0                          (3)
    g(x)   = h(A + xi/2 - x) / (h(A + xi/2 - x) + h(x - (A - xi/2)))      (2)
    phi_i  = g(|x - R_i|)                                                 (1)
    phi    = sum_i phi_i                                                  (4)

phi_i is 1 for |x - R_i| <= A - xi/2, 0 for |x - R_i| >= A + xi/2.  Each particle is
represented sparsely on a fixed stencil of integer offsets around its base grid point
floor(R_i / DX): ``particle_profiles`` returns, for all particles at once, the flat grid
indices, the profile values and the minimum-image vectors x - R_i of the stencil points
(arrays (N, S), (N, S), (N, S, 3)).  Points with phi_i = 0 are kept (fixed S, no ragged
arrays); they contribute nothing to any sum.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..mesh import compiled as _compiled

_compiled.provide("profile", __name__.rsplit(".", 1)[0] + ".profile_kernels")

__all__ = ["h", "g", "Stencil", "particle_profiles", "total_phi", "grid_volume"]

_TINY = 1e-150


def h(x, dx=1.0):
    """Eq 3: exp(-DX^2/x^2) for x > 0, 0 otherwise (h(0) = 0 as the limit)."""
    x = np.maximum(np.asarray(x, dtype=float), _TINY)  # exp(-1/tiny^2) == 0.0 exactly
    return np.exp(-(dx * dx) / (x * x))


def g(x, A, xi, dx=1.0):
    """Eq 2: radial profile, 1 inside A - xi/2, 0 beyond A + xi/2, smooth in between.

    The denominator never vanishes: (A + xi/2 - x) + (x - A + xi/2) = xi > 0.
    """
    x = np.asarray(x, dtype=float)
    ho = h(A + 0.5 * xi - x, dx)
    hi = h(x - (A - 0.5 * xi), dx)
    hi += ho
    ho /= hi
    return ho


@lru_cache(maxsize=32)
def _offsets(A, xi, dx, strain_max=0.0):
    """Integer offsets o for which |o - f| DX < A + xi/2 for some f in [0, 1)^3.

    ``strain_max`` > 0: offsets of an oblique grid (x^ = x - g y, |g| <= strain_max), whose
    x offset o_x - f_x + g (o_y - f_y) is bounded conservatively."""
    rc = (A + 0.5 * xi) / dx
    m = int(np.ceil(rc)) + 1
    o = np.arange(-m, m + 2)
    # closest approach of o - f, f in [0, 1): 0 for o in {0, 1}, o - 1 for o > 1, -o for o < 0
    d1 = np.where(o >= 1, o - 1, np.where(o <= 0, -o, 0)).astype(float)
    if strain_max > 0:
        mx = m + int(np.ceil(strain_max * (m + 1)))
        ox1 = np.arange(-mx, mx + 2)
        ox, oy, oz = np.meshgrid(ox1, o, o, indexing="ij")
        spread = strain_max * np.maximum(np.abs(oy), np.abs(oy - 1))
        lo, hi = ox - 1 - spread, ox + spread           # range of the physical x offset
        dx_min = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
        dmin2 = dx_min ** 2 + d1[oy + m] ** 2 + d1[oz + m] ** 2
    else:
        ox, oy, oz = np.meshgrid(o, o, o, indexing="ij")
        dmin2 = (d1[ox + m] ** 2 + d1[oy + m] ** 2 + d1[oz + m] ** 2)
    keep = dmin2 < rc * rc
    off = np.stack([ox[keep], oy[keep], oz[keep]], axis=1).astype(np.int64)
    off.setflags(write=False)
    return off


class Stencil:
    """Offsets around floor(R/DX) that can lie inside radius A + xi/2 of a particle.

    ``offsets`` (S, 3) int64, computed once per (A, xi, DX) (cached).
    """

    def __init__(self, A, xi, dx, strain_max=0.0):
        self.A = float(A)
        self.xi = float(xi)
        self.dx = float(dx)
        if self.xi <= 0 or self.A <= 0.5 * self.xi:
            raise ValueError("need A > xi/2 > 0 for the profile of eqs 1-3")
        self.strain_max = float(strain_max)
        self.offsets = _offsets(self.A, self.xi, self.dx, self.strain_max)
        self.offsets_f = self.offsets.astype(float)
        # contiguous per-component copies for the vectorised index / vector arithmetic
        self.o = [np.ascontiguousarray(self.offsets[:, c]) for c in range(3)]
        self.of = [np.ascontiguousarray(self.offsets_f[:, c]) for c in range(3)]
        #: the lines along x a stencil meets: its distinct (y, z) offsets
        self.lines = len(np.unique(self.offsets[:, 1:], axis=0))

    @property
    def size(self):
        return len(self.offsets)

    def __repr__(self):
        return f"Stencil(A={self.A}, xi={self.xi}, dx={self.dx}, S={self.size})"


def particle_profiles(R, stencil, shape, dx, strain=0.0, origin=0.0):
    """Profiles of all particles (eq 1) on their stencil points.

    ``strain`` g != 0: the grid is the oblique grid of kapsel.fluid.oblique (point (i, j, k)
    at (i DX + g (j DX - origin), j DX, k DX)); ``r`` is then the physical (Cartesian)
    x - R_i, with the Lees-Edwards images; the stencil must be built with strain_max >= |g|.

    Returns ``idx`` (N, S) int64 flat indices into a C-ordered (NX, NY, NZ) field,
    ``phi`` (N, S) phi_i at those points, ``r`` (N, S, 3) minimum-image x - R_i (a view of a
    (3, N, S) array, so r[..., c] is contiguous).
    R must lie in [0, L) (wrapped) or anywhere (it is reduced modulo the grid).
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3)
    n, S = len(R), stencil.size
    s = R / dx
    if strain:
        if abs(strain) > stencil.strain_max:
            raise ValueError(f"frame strain {strain} beyond the stencil's {stencil.strain_max}")
        s[:, 0] = (R[:, 0] - strain * (R[:, 1] - origin)) / dx   # oblique index coordinates
    base = np.floor(s)
    frac = s - base
    with np.errstate(invalid="ignore"):    # NaN positions: caught by the run's checks
        b = base.astype(np.int64)
    # r = (base + o) dx - R = (o - frac) dx, stored component-major: r[..., c] contiguous
    rc = np.empty((3, n, S))
    K = _compiled.profile
    if K is not None:                      # the same operations, point by point
        idx = np.empty((n, S), dtype=np.int64)
        dist = np.empty((n, S))
        K.stencil_points(b, frac, stencil.offsets, stencil.offsets_f,
                         np.asarray(shape[:3], dtype=np.int64), float(dx), float(strain),
                         idx, rc, dist)
        return idx, g(dist, stencil.A, stencil.xi, dx), rc.transpose(1, 2, 0)
    idx = np.zeros((n, S), dtype=np.int64)
    tmp = np.empty((n, S), dtype=np.int64)
    for c in range(3):
        np.subtract(stencil.of[c][None, :], frac[:, c:c + 1], out=rc[c])
        if dx != 1.0:
            rc[c] *= dx
        np.add(b[:, c:c + 1], stencil.o[c][None, :], out=tmp)
        np.remainder(tmp, shape[c], out=tmp)
        if c:
            idx *= shape[c]
        idx += tmp
    if strain:
        rc[0] += strain * rc[1]                          # physical x offset
    return idx, _phi_of(rc, stencil, dx), rc.transpose(1, 2, 0)


def _phi_of(rc, stencil, dx):
    """phi (eq 1) at the stencil points of displacements rc (3, N, S) from the centres."""
    dist = rc[0] * rc[0]
    dist += rc[1] * rc[1]
    dist += rc[2] * rc[2]
    np.sqrt(dist, out=dist)
    return g(dist, stencil.A, stencil.xi, dx)


def lees_edwards_profiles(R, stencil, shape, dx, offset):
    """Profiles of all particles (eq 1) on the rectangular grid under Lees-Edwards images:
    a stencil point beyond the y boundary (above Ly: sign +1, below 0: sign -1) is the
    image of a point of the box whose x is displaced by -sign ``offset`` (g Ly), as the
    original's Relative_coord_check_stepover_Y (make_phi.h): the particle's x index
    coordinate there is R_x / DX - sign offset / DX, and the point's x index and r_x follow
    from that coordinate's floor and fraction.  Returns (idx, phi, r) as
    ``particle_profiles``; r is the displacement from the particle (or its image)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3)
    n, S = len(R), stencil.size
    s = R / dx
    with np.errstate(invalid="ignore"):
        b = np.floor(s).astype(np.int64)
    frac = s - b
    ny = shape[1]
    yu = b[:, 1:2] + stencil.o[1][None, :]                   # unwrapped y index (n, S)
    sign = np.floor_divide(yu, ny)                           # -1, 0, +1
    q = s[:, 0:1] - sign * (float(offset) / dx)              # x index coordinate (n, S)
    with np.errstate(invalid="ignore"):
        bq = np.floor(q).astype(np.int64)
    rc = np.empty((3, n, S))
    np.subtract(stencil.of[0][None, :], q - bq, out=rc[0])
    for c in (1, 2):
        np.subtract(stencil.of[c][None, :], frac[:, c:c + 1], out=rc[c])
    if dx != 1.0:
        rc *= dx
    idx = np.remainder(bq + stencil.o[0][None, :], shape[0])
    idx *= shape[1]
    idx += np.remainder(yu, ny)
    idx *= shape[2]
    idx += np.remainder(b[:, 2:3] + stencil.o[2][None, :], shape[2])
    return idx, _phi_of(rc, stencil, dx), rc.transpose(1, 2, 0)


def total_phi(idx, phi, size):
    """Eq 4: phi = sum_i phi_i as a flat field of ``size`` points (reshape to the grid)."""
    return np.bincount(idx.ravel(), weights=phi.ravel(), minlength=size)


def grid_volume(phi, dx):
    """Discrete particle volumes V_p,i = DX^3 sum_x phi_i (N,)."""
    return phi.sum(axis=1) * dx ** 3
