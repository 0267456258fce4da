"""Particle state shared by every solver: plain arrays, one row per particle.

Lengths are in units of DX, time in units of RHO DX^2 / ETA (manual 5.5).
Positions R are wrapped into the periodic box [0, L); R_raw is never wrapped.
Quaternions are stored scalar-first (q0, q1, q2, q3), as in the UDF `Quaternion` class.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

VECTOR_FIELDS = ("R", "R_raw", "v", "v_old", "omega", "omega_old",
                 "f_hydro", "f_hydro_previous", "f_r", "f_r_previous",
                 "f_slip", "f_slip_previous",
                 "torque_hydro", "torque_hydro_previous", "torque_r", "torque_r_previous",
                 "torque_slip", "torque_slip_previous")


@dataclass
class ParticleState:
    """Dynamic state of N spherical particles (or beads of chains / rigid bodies).

    species[i] indexes the Particle_spec / Chain_spec / Rigid_spec entry of particle i.
    radius, mass and inertia are per particle (M = MASS_RATIO RHO 4/3 pi A^3, I = 2/5 M A^2).
    constraints: None for free particles, else the object whose update_velocities /
    update_positions replace the free ones (motion.Pinned, rigid.RigidBodies).
    """
    n: int
    species: np.ndarray
    radius: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    R: np.ndarray = field(default=None)
    R_raw: np.ndarray = field(default=None)
    v: np.ndarray = field(default=None)
    v_old: np.ndarray = field(default=None)
    omega: np.ndarray = field(default=None)
    omega_old: np.ndarray = field(default=None)
    q: np.ndarray = field(default=None)
    q_old: np.ndarray = field(default=None)
    f_hydro: np.ndarray = field(default=None)
    f_hydro_previous: np.ndarray = field(default=None)
    f_r: np.ndarray = field(default=None)
    f_r_previous: np.ndarray = field(default=None)
    f_slip: np.ndarray = field(default=None)
    f_slip_previous: np.ndarray = field(default=None)
    torque_hydro: np.ndarray = field(default=None)
    torque_hydro_previous: np.ndarray = field(default=None)
    torque_r: np.ndarray = field(default=None)
    torque_r_previous: np.ndarray = field(default=None)
    torque_slip: np.ndarray = field(default=None)
    torque_slip_previous: np.ndarray = field(default=None)
    constraints: object = field(default=None, compare=False)
    janus: object = field(default=None, compare=False)    # janus.Janus (self-propulsion)

    def __post_init__(self):
        for name in VECTOR_FIELDS:
            if getattr(self, name) is None:
                setattr(self, name, np.zeros((self.n, 3)))
        for name in ("q", "q_old"):
            if getattr(self, name) is None:
                q = np.zeros((self.n, 4))
                q[:, 0] = 1.0
                setattr(self, name, q)

    @classmethod
    def spheres(cls, species, radius, mass_ratio, rho):
        """Spheres of the given per-particle species, radius and MASS_RATIO."""
        species = np.asarray(species, dtype=np.int64)
        radius = np.asarray(radius, dtype=float)
        mass = np.asarray(mass_ratio, dtype=float) * rho * (4.0 / 3.0) * np.pi * radius ** 3
        return cls(n=len(species), species=species, radius=radius, mass=mass,
                   inertia=0.4 * mass * radius ** 2)

    def copy(self) -> "ParticleState":
        kw = {name: getattr(self, name).copy() for name in VECTOR_FIELDS + ("q", "q_old")}
        import copy
        return ParticleState(n=self.n, species=self.species.copy(), radius=self.radius.copy(),
                             mass=self.mass.copy(), inertia=self.inertia.copy(),
                             constraints=copy.deepcopy(self.constraints), janus=self.janus,
                             **kw)
