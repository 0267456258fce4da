"""Thermal random force / torque on particles (G^V, G^Omega of eqs 9, 10, 13, 14).

Over one step dt the white noise integrates to Gaussian impulses
dP = ∫ G^V dt, dL = ∫ G^Omega dt with zero mean and per-component variance

    <dP_a dP_b> = 2 kBT alpha_v gamma_v dt delta_ab,
    <dL_a dL_b> = 2 kBT alpha_o gamma_o dt delta_ab,

the fluctuation-dissipation amplitude for a friction coefficient gamma
(the caller passes gamma_v = 6 pi eta a, gamma_o = 8 pi eta a^3).  alpha_v and
alpha_o are the manual's temperature correction factors (eqs 13, 14, table 2:
usually 1).  Summed over the 3 components this is 3 * (2 kBT alpha gamma dt),
matching the "3 kBT alpha" trace form of eqs 13-14 up to the friction factor.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ThermalNoise"]


def _per_particle(g, n):
    g = np.asarray(g, dtype=float)
    if g.ndim == 1:
        g = g[:, None]
    return np.broadcast_to(g, (n, 3))


class ThermalNoise:
    """Random impulses from numpy Generator(PCG64(seed)); state is JSON-serialisable."""

    def __init__(self, seed=None):
        self.rng = np.random.Generator(np.random.PCG64(seed))

    def get_state(self) -> dict:
        """Generator state as plain JSON types (128-bit integers as decimal strings)."""
        s = self.rng.bit_generator.state
        return {"bit_generator": s["bit_generator"],
                "state": {"state": str(s["state"]["state"]), "inc": str(s["state"]["inc"])},
                "has_uint32": int(s["has_uint32"]), "uinteger": int(s["uinteger"])}

    def set_state(self, d: dict) -> None:
        """Restore a state from get_state() (exact restart)."""
        if d.get("bit_generator", "PCG64") != "PCG64":
            raise ValueError(f"noise state is for {d.get('bit_generator')!r}, expected PCG64")
        self.rng.bit_generator.state = {
            "bit_generator": "PCG64",
            "state": {"state": int(d["state"]["state"]), "inc": int(d["state"]["inc"])},
            "has_uint32": int(d["has_uint32"]), "uinteger": int(d["uinteger"])}

    def impulses(self, n, dt, kBT, alpha_v=1.0, alpha_o=1.0, gamma_v=1.0, gamma_o=1.0):
        """(dP (n,3), dL (n,3)) over one step; gamma_* scalars, (n,), (n,1) or (n,3).

        With kBT == 0 zeros are returned and no random numbers are drawn.
        """
        if kBT == 0:
            return np.zeros((n, 3)), np.zeros((n, 3))
        if kBT < 0 or dt < 0:
            raise ValueError("kBT and dt must be non-negative")
        sv = np.sqrt(2.0 * kBT * alpha_v * dt * _per_particle(gamma_v, n))
        so = np.sqrt(2.0 * kBT * alpha_o * dt * _per_particle(gamma_o, n))
        dP = sv * self.rng.standard_normal((n, 3))
        dL = so * self.rng.standard_normal((n, 3))
        return dP, dL
