"""The run's checks of a model's state: finite fields and particles, the scheme's CFL limit,
what blew up first in a failed step, the sheared types' table row (each raises
kapsel.errors.InstabilityError naming the quantity)."""
from __future__ import annotations

import numpy as np

from .errors import InstabilityError

__all__ = ["check_finite", "check_step", "first_blow_up", "table_row"]


def check_finite(model, snap=None) -> None:
    """NaN or infinity in the model's own fields (u, psi, phi) or particles."""
    snap = model.snapshot() if snap is None else snap
    for name in ("u", "psi", "phi"):
        if snap.offers(name) and not np.isfinite(snap.get(name)).all():
            raise InstabilityError(f"the field {name} is not finite (NaN or infinity)")
    p = model.particles
    if p is not None and p.n and not (np.isfinite(p.R).all() and np.isfinite(p.v).all()):
        raise InstabilityError("particle positions or velocities are not finite")


def check_step(model) -> None:
    """Cheap checks between snapshots: finite velocities and the scheme's CFL limit
    (Model.stability); InstabilityError names the quantity."""
    ratio, what = model.stability()
    if not np.isfinite(ratio):
        raise InstabilityError("the fluid or particle velocities are not finite "
                               "(NaN or infinity)")
    if ratio > 1.0:
        raise InstabilityError(what)


def first_blow_up(model) -> str | None:
    """What went out of bounds first in a failed step, in the order of the step: the
    particle forces (pair, bond, gravity: EPSILON, G), the particle velocities, the fluid
    velocity; None if all are finite and within the step's reach."""
    p = model.whole_particles()                         # (a collective when distributed)
    dx, dt = model.cfg.mesh.DX, model.dt
    if p is not None and p.n:
        f = p.f_r
        mass = np.asarray(p.mass, dtype=float)
        if f is not None and f.size:
            if not np.isfinite(f).all():
                return ("the particle forces (pair, bond or gravity) are not finite; EPSILON "
                        "or G is far too large for this time step")
            reach = float(np.max(np.linalg.norm(f, axis=1) / mass)) * dt * dt / dx
            if reach > 1.0:
                return (f"the particle forces (pair, bond or gravity) move a particle "
                        f"{reach:.3g} DX in one step (|F| dt^2 / (M DX) > 1); EPSILON or G is "
                        f"too large for this time step")
        if not (np.isfinite(p.v).all() and np.isfinite(p.R).all()):
            return "the particle velocities or positions are not finite"
        vmax = float(np.max(np.linalg.norm(p.v, axis=1)))
        if vmax * dt / dx > 1.0:
            return (f"the particle velocities: max |V| dt / DX = {vmax * dt / dx:.3g} exceeds 1 "
                    f"(a particle crosses a mesh cell in one step)")
    try:
        ratio, what = model.stability()
    except Exception:                                   # noqa: BLE001 - diagnosis only
        return None
    if not np.isfinite(ratio):
        return "the fluid velocity is not finite (NaN or infinity)"
    if ratio > 1.0:
        return what
    return None


def table_row(model) -> list:
    """This step's row of the sheared types' stress table, checked first: the table is
    printed every step, the blow-up checks run only every few steps (InstabilityError)."""
    row = model.shear_table_row()
    values = np.asarray(row, dtype=float)
    if values[1] == 0.0:                # at rate 0 the viscosity column is NaN, as the
        values = values[:-1]            # original's (stress / rate)
    if not np.isfinite(values).all():
        check_step(model)               # names the quantity when it is the velocity
        raise InstabilityError("the shear stress table row is not finite (NaN or infinity)")
    return row
