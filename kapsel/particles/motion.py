"""Equations of motion of the particles (manual eqs 9-10, §5.2).

    M dV/dt = F^H + F^other + G^V          (9)
    I dOmega/dt = N^H + N^other + G^Omega  (10)

Velocities by an explicit step with the momentum-exchange force of the step (plus thermal
impulses dP = ∫G^V dt, dL = ∫G^Omega dt); positions by Crank-Nicolson,
R^{n+1} = R^n + dt (V^n + V^{n+1}) / 2 (§5.2, as the original); orientations by
kapsel.particles.quaternion.integrate with the mean angular velocity of the step.

``Pinned`` (switch.pin): the motion of free particles with the velocities of the ``pin[]``
particles and the angular velocities of the ``pin_rot[]`` particles held at zero, so they
neither move nor turn (their hydrodynamic force and torque are still computed and recorded).
spm.SPM uses ``ParticleState.constraints`` (a Pinned, a rigid.RigidBodies, or None for
these free-particle functions) for the velocity and position updates.
"""
from __future__ import annotations

import numpy as np

try:
    from .quaternion import integrate as _integrate_q
except ImportError:  # pragma: no cover - the quaternion module is in the repo
    _integrate_q = None

__all__ = ["update_velocities", "update_positions", "Pinned"]


def _q_integrate(q, omega, dt):
    if _integrate_q is not None:
        return _integrate_q(q, omega, dt)
    # private fallback: q <- exp((0, omega) dt / 2) q
    rot = omega * dt
    ang = np.linalg.norm(rot, axis=1)
    unit = rot / np.where(ang > 0, ang, 1.0)[:, None]
    c, s = np.cos(0.5 * ang), np.sin(0.5 * ang)
    a0, av = c, s[:, None] * unit
    b0, bv = q[:, 0], q[:, 1:]
    out = np.empty_like(q)
    out[:, 0] = a0 * b0 - np.einsum("nk,nk->n", av, bv)
    out[:, 1:] = a0[:, None] * bv + b0[:, None] * av + np.cross(av, bv)
    return out / np.linalg.norm(out, axis=1)[:, None]


def _as(a, n):
    return np.zeros((n, 3)) if a is None else np.asarray(a, dtype=float)


def update_velocities(p, F_H, T_H, F_other, T_other, dt, rotation, dP_noise=None,
                      dL_noise=None, mass=None, inertia=None):
    """Eqs 9-10: V += dt/M (F_H + F_other) + dP/M; Omega likewise with I (if ``rotation``).

    Keeps v_old / omega_old and stores f_hydro, torque_hydro, f_r (= F_other),
    torque_r (= T_other) in ``p``, the previous values going to *_previous.
    ``mass`` / ``inertia`` (N,) override p.mass / p.inertia (e.g. the grid mass of spm.SPM).
    """
    n = p.n
    F_H, T_H = _as(F_H, n), _as(T_H, n)
    F_o, T_o = _as(F_other, n), _as(T_other, n)
    M = (p.mass if mass is None else np.asarray(mass, dtype=float))[:, None]
    I = (p.inertia if inertia is None else np.asarray(inertia, dtype=float))[:, None]
    for name, new in (("f_hydro", F_H), ("torque_hydro", T_H), ("f_r", F_o),
                      ("torque_r", T_o)):
        getattr(p, name + "_previous")[...] = getattr(p, name)
        getattr(p, name)[...] = new
    p.v_old[...] = p.v
    p.omega_old[...] = p.omega
    dv = (F_H + F_o) * (dt / M)
    if dP_noise is not None:
        dv += np.asarray(dP_noise) / M
    p.v += dv
    if rotation:
        dw = (T_H + T_o) * (dt / I)
        if dL_noise is not None:
            dw += np.asarray(dL_noise) / I
        p.omega += dw
    return p


def update_positions(p, dt, box, rotation):
    """R += dt (V_old + V) / 2 (Crank-Nicolson, §5.2), R wrapped into [0, L), R_raw not;
    q advanced by exp(Omega_mean dt / 2) with Omega_mean = (Omega_old + Omega) / 2."""
    dR = 0.5 * dt * (p.v_old + p.v)
    p.R_raw += dR
    p.R += dR
    L = np.asarray(box, dtype=float)
    np.mod(p.R, L, out=p.R)
    p.R[p.R >= L] = 0.0  # mod can round up to L for tiny negative values
    if rotation:
        p.q_old[...] = p.q
        p.q[...] = _q_integrate(p.q, 0.5 * (p.omega_old + p.omega), dt)
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

    def update_positions(self, p, dt, box, rotation):
        return update_positions(p, dt, box, rotation)
