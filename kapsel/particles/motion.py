"""Equations of motion of the particles (manual eqs 9-10, §5.2), the original's integrators.

    M dV/dt = F^H + F^other + G^V          (9)
    I dOmega/dt = N^H + N^other + G^Omega  (10)

with M = MASS_RATIO RHO 4/3 pi A^3 and I = 2/5 M A^2 (input.cxx: MASS, MOI).  Within one
SPM step (kapsel.particles.spm) the positions move first, with the velocities of the last
step; the velocities then take the forces computed at the new positions:

* positions (particle_solver.cxx MD_solver_position_Euler / _AB2): the first step of a run
  R^{n+1} = R^n + dt V^n, after it the Adams-Bashforth R^{n+1} = R^n + dt/2 (3 V^n - V^{n-1});
  orientations alike by the additive quaternion step q += dt dq/dt (first step) or
  q += dt/2 (3 dq/dt(q^n, Omega^n) - dq/dt(q^{n-1}, Omega^{n-1})), dq/dt = 1/2 (0, Omega) q
  (space-frame Omega), then normalised (particle_rotation_solver.h
  MD_solver_orientation_Euler / _AB2);
* velocities (MD_solver_velocity_Euler / _AB2_hydro): the first step
  V += dt/M (F^H + F^other), after it V += dt/(2M) (2 F^H + F^other,n+1 + F^other,n): the
  hydrodynamic force (a momentum exchange over the step, eq 11) in full, the other forces by
  the trapezoid rule; Omega likewise with I, N^H (0 without ROTATION) and N^other.  Thermal
  impulses dP = ∫G^V dt, dL = ∫G^Omega dt are added after (fluct.cxx
  Add_random_force_thermostat; dL only with ROTATION).

``first``: the step is the run's step 0 (jikan.ts == 0); a continued run is never first.

``Pinned`` (switch.pin): the motion of free particles with the velocities of the ``pin[]``
particles and the angular velocities of the ``pin_rot[]`` particles held at zero after the
velocity update (particle_solver.h Pinning), so they neither move nor turn (their
hydrodynamic force and torque are still computed and recorded).

A *constraint* (``ParticleState.constraints``: a Pinned, rigid.RigidBodies) offers
``update_positions(p, dt, box, rotation, first=False)`` and
``update_velocities(p, F_H, T_H, F_other, T_other, dt, rotation, dP, dL, first=False)`` in
place of the free-particle functions of this module; spm.SPM calls them in that order.
"""
from __future__ import annotations

import numpy as np

__all__ = ["update_velocities", "update_positions", "advance_orientation", "wrap", "Pinned"]


def _as(a, n):
    return np.zeros((n, 3)) if a is None else np.asarray(a, dtype=float)


def _qdot(q, w):
    """dq/dt = 1/2 (0, w) q for space-frame angular velocities w (N, 3), q (N, 4)
    (rigid_body.cxx qdot, SPACE_FRAME)."""
    out = np.empty_like(q)
    q0, q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    w0, w1, w2 = w[:, 0], w[:, 1], w[:, 2]
    out[:, 0] = 0.5 * (0.0 * q0 - (w0 * q1 + w1 * q2 + w2 * q3))
    out[:, 1] = 0.5 * (0.0 * q1 + q0 * w0 + w1 * q3 - w2 * q2)
    out[:, 2] = 0.5 * (0.0 * q2 + q0 * w1 + w2 * q1 - w0 * q3)
    out[:, 3] = 0.5 * (0.0 * q3 + q0 * w2 + w0 * q2 - w1 * q1)
    return out


def advance_orientation(p, dt, first, rows=None):
    """q^{n+1} from q^n, q^{n-1} (``q_old``) and Omega^n, Omega^{n-1} (module docstring);
    ``q_old`` becomes q^n.  ``rows``: only those particles."""
    sl = slice(None) if rows is None else rows
    q, w = p.q[sl], p.omega[sl]
    if first:
        new = q + _qdot(q, w) * dt
    else:
        new = q + _qdot(q, w) * (3.0 * (0.5 * dt))
        new += _qdot(p.q_old[sl], p.omega_old[sl]) * (-(0.5 * dt))
    new *= (1.0 / np.sqrt(np.einsum("ij,ij->i", new, new)))[:, None]
    p.q_old[sl] = q
    p.q[sl] = new


def wrap(R, box):
    """R into [0, L) (periodic_boundary.h PBC: fmod(x + L, L))."""
    L = np.asarray(box, dtype=float)
    R += L
    np.fmod(R, L, out=R)
    R[R >= L] = 0.0
    R[R < 0] = 0.0
    return R


def update_velocities(p, F_H, T_H, F_other, T_other, dt, rotation, dP_noise=None,
                      dL_noise=None, first=False):
    """Eqs 9-10 (module docstring); keeps v_old / omega_old and stores f_hydro,
    torque_hydro, f_r (= F_other), torque_r (= T_other) in ``p``, the previous values going
    to *_previous (the trapezoid of the other forces uses f_r_previous)."""
    n = p.n
    F_H, F_o = _as(F_H, n), _as(F_other, n)
    T_H = _as(T_H, n) if rotation else np.zeros((n, 3))
    T_o = _as(T_other, n)
    for name, new in (("f_hydro", F_H), ("torque_hydro", T_H), ("f_r", F_o),
                      ("torque_r", T_o)):
        getattr(p, name + "_previous")[...] = getattr(p, name)
        getattr(p, name)[...] = new
    p.v_old[...] = p.v
    p.omega_old[...] = p.omega
    im = (1.0 / np.asarray(p.mass, dtype=float))[:, None]
    ii = (1.0 / np.asarray(p.inertia, dtype=float))[:, None]
    if first:
        p.v += (dt * im) * (F_H + F_o)
        p.omega += (dt * ii) * (T_H + T_o)
    else:
        h = 0.5 * dt
        p.v += (h * im) * ((2.0 * F_H + F_o) + p.f_r_previous)
        p.omega += (h * ii) * ((2.0 * T_H + T_o) + p.torque_r_previous)
    if dP_noise is not None:
        p.v += np.asarray(dP_noise) * im
    if rotation and dL_noise is not None:
        p.omega += np.asarray(dL_noise) * ii
    return p


def update_positions(p, dt, box, rotation, first=False, wrap_box=True):
    """R^{n+1} (Euler at the first step, else AB2; module docstring), R wrapped into
    [0, L) (``wrap_box``; the sheared types wrap by the Lees-Edwards rule themselves), R_raw
    not; q advanced alike when ``rotation``."""
    if first:
        dR = dt * p.v
    else:
        dR = (0.5 * dt) * (3.0 * p.v - p.v_old)
    p.R_raw += dR
    p.R += dR
    if wrap_box:
        wrap(p.R, box)
    if rotation:
        advance_orientation(p, dt, first)
    return p


class Pinned:
    """Free particles except that pin[] velocities and pin_rot[] angular velocities are 0."""

    def __init__(self, pin=(), pin_rot=()):
        self.pin = np.asarray(pin, dtype=np.int64)
        self.pin_rot = np.asarray(pin_rot, dtype=np.int64)

    def hold(self, p):
        p.v[self.pin] = 0.0
        p.omega[self.pin_rot] = 0.0

    def update_velocities(self, p, *args, **kwargs):
        update_velocities(p, *args, **kwargs)
        self.hold(p)
        return p

    def update_positions(self, p, dt, box, rotation, first=False, wrap_box=True):
        return update_positions(p, dt, box, rotation, first, wrap_box)
