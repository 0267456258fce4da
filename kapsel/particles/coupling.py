"""Particle-fluid coupling of the SPM on stencil arrays from ``profile.particle_profiles``.

* ``particle_velocity_field``: phi u_p = sum_i (V_i + Omega_i x r) phi_i      (eq 6)
* ``hydro_force_torque``: momentum exchange form of eqs 11-12 (Nakayama, Kim & Yamamoto,
  EPJE 26, 361 (2008)) with u* the fluid velocity after the fluid step,
      F_i dt = RHO DX^3 sum_x phi_i (u* - V_i - Omega_i x r)
      N_i dt = RHO DX^3 sum_x r x phi_i (u* - V_i - Omega_i x r)
* ``rigidity_increment``: du = sum_i phi_i (V_i + Omega_i x r) - phi u, the body force
  phi f_p dt of eq 8 before the pressure (solenoidal) projection.

idx (N, S) flat indices, phi (N, S), r (N, S, 3); u is (3, NX, NY, NZ) (or (3, size)).

``shear`` (gamma_dot, default 0): u is the deviation from an imposed shear flow
gamma_dot (y - y0) e_x and V the particle velocity minus that flow at its centre; the rigid
motion then deviates from the imposed flow by V + Omega x r - gamma_dot r_y e_x
(kapsel.fluid.oblique, the Lees-Edwards types).
"""
from __future__ import annotations

import numpy as np

from ..mesh import compiled as _compiled

_compiled.provide("coupling", __name__.rsplit(".", 1)[0] + ".coupling_kernels")

__all__ = ["rigid_velocity", "particle_velocity_field", "hydro_force_torque",
           "rigidity_increment", "sample"]


_CYC = ((1, 2), (2, 0), (0, 1))  # (a, b) with (V + W x r)_c = V_c + W_a r_b - W_b r_a
_work = {}


def _buf(key, shape):
    """Reused scratch array (never returned to callers): avoids re-faulting fresh pages."""
    a = _work.get(key)
    if a is None or a.shape != shape:
        a = _work[key] = np.empty(shape)
    return a


def rigid_velocity(r, V, Omega):
    """V_i + Omega_i x r at every stencil point, shape (3, N, S) (component first)."""
    V = np.asarray(V, dtype=float)
    W = np.asarray(Omega, dtype=float)
    out = np.empty((3,) + r.shape[:2])
    for c, (a, b) in enumerate(_CYC):
        np.multiply(r[..., b], W[:, a:a + 1], out=out[c])
        out[c] -= r[..., a] * W[:, b:b + 1]
        out[c] += V[:, c:c + 1]
    return out


def sample(u, idx, out=None):
    """u at the stencil points, (3, N, S)."""
    uf = u.reshape(3, -1)
    out = np.empty((3,) + idx.shape) if out is None else out
    for c in range(3):
        np.take(uf[c], idx, out=out[c])
    return out


def _scatter(w, idx, size, shape=None, out=None, zeroed=False):
    """sum over particles of the per-point vectors w (3, N, S) -> (3, size) or (3, *shape).

    Zero-fill + np.add.at into the (reused) output: no full-grid temporaries (bincount
    allocates a fresh full-grid array per component, whose page faults cost more than the
    sums at 64^3).  ``zeroed``: ``out`` is known to be 0 everywhere (the caller cleared the
    points of the last scatter, ``clear_points``), so the full-grid fill is skipped."""
    if out is None:
        out = np.zeros((3, size))
    elif not zeroed:
        out.fill(0.0)
    of = out.reshape(3, -1)
    K = _compiled.coupling
    if (K is not None and of.flags.c_contiguous and idx.ndim == 2 and idx.flags.c_contiguous
            and w.ndim == 3 and w.flags.c_contiguous and idx.dtype == np.int64):
        K.scatter_add(of, idx, w)             # the same additions in the same order
    else:
        flat = idx.reshape(-1)
        for c in range(3):
            np.add.at(of[c], flat, w[c].reshape(-1))
    if shape is not None and out.ndim == 2:
        out = out.reshape((3,) + tuple(shape))
    return out


def clear_points(out, idx):
    """out[:, idx] = 0 for a (3, ...) field: undoes a scatter onto a zeroed field."""
    of = out.reshape(3, -1)
    flat = idx.reshape(-1)
    for c in range(3):
        of[c][flat] = 0.0


def particle_velocity_field(idx, phi, r, V, Omega, size, shape=None):
    """Eq 6: phi u_p = sum_i (V_i + Omega_i x r) phi_i, (3, size) or (3, *shape)."""
    w = rigid_velocity(r, V, Omega)
    w *= phi
    return _scatter(w, idx, size, shape)


def _slip(u, idx, phi, r, V, Omega, shear=0.0, sampled=None):
    """phi_i (u - V_i - Omega_i x r [+ shear r_y e_x]) at the stencil points, (3, N, S)
    scratch buffer.  ``sampled``: u at the stencil points already (``sample``)."""
    V = np.asarray(V, dtype=float)
    W = np.asarray(Omega, dtype=float)
    w = _buf("w", (3,) + idx.shape)
    if sampled is None:
        sample(u, idx, out=w)
    else:
        np.copyto(w, sampled)
    K = _compiled.coupling
    if K is not None and V.ndim == 2 and phi.flags.c_contiguous:
        rc = r.transpose(2, 0, 1)             # (3, N, S): the profiles' r is a view of one
        K.slip(w, np.ascontiguousarray(rc), np.ascontiguousarray(V), np.ascontiguousarray(W),
               phi, float(shear))             # the same operations, one pass
        return w
    t = _buf("t", idx.shape)
    for c, (a, b) in enumerate(_CYC):
        wc = w[c]
        np.multiply(r[..., b], W[:, a:a + 1], out=t)
        wc -= t
        np.multiply(r[..., a], W[:, b:b + 1], out=t)
        wc += t
        wc -= V[:, c:c + 1]
        if c == 0 and shear:
            wc += shear * r[..., 1]
        wc *= phi
    return w


def _force_torque(w, r, scale):
    F = w.sum(axis=2).T * scale
    T = np.empty_like(F)
    for c, (a, b) in enumerate(_CYC):
        T[:, c] = (np.einsum("ns,ns->n", r[..., a], w[b])
                   - np.einsum("ns,ns->n", r[..., b], w[a])) * scale
    return F, T


def hydro_force_torque(u, idx, phi, r, V, Omega, rho, dx, dt, shear=0.0, sampled=None):
    """Eqs 11-12 by momentum exchange: (F_H (N, 3), N_H (N, 3)) from u* (after the fluid step).

    F_i = RHO DX^3 / dt sum phi_i (u* - V_i - Omega_i x r), N_i = same with r x (...).
    ``sampled``: u* at the stencil points, if the caller has it (``sample``).
    """
    w = _slip(u, idx, phi, r, V, Omega, shear, sampled)
    return _force_torque(w, r, rho * dx ** 3 / dt)


def rigidity_increment(u, idx, phi, r, V, Omega, size=None, out=None, shear=0.0, moment=None,
                       sampled=None, zeroed=False):
    """du = sum_i phi_i (V_i + Omega_i x r) - phi u (eq 6 imposed; phi f_p dt of eq 8).

    Shaped like u (written into ``out`` if given).  Still to be made solenoidal by the
    caller (SpectralNS.add_solenoidal, or u += du followed by MACSolver.project(u)).
    Computed only at the stencil points: du = -sum_i phi_i (u - V_i - Omega_i x r).
    ``moment`` (3, 3) array: receives sum_i sum_x du_a r_b, the first moment of the increment
    about each particle (the particle stress, kapsel.models.shear).
    ``sampled``: u at the stencil points (``sample``); ``zeroed``: ``out`` is all 0 already.
    """
    size = u[0].size if size is None else size
    w = _slip(u, idx, phi, r, V, Omega, shear, sampled)
    w *= -1.0
    if moment is not None:
        for a in range(3):
            for b in range(3):
                moment[a, b] = float(np.einsum("ns,ns->", w[a], r[..., b]))
    return _scatter(w, idx, size, u.shape[1:], out=out, zeroed=zeroed)
