"""Thermal random force / torque on particles (G^V, G^Omega of eqs 9, 10, 13, 14).

Over one step dt the white noise integrates to Gaussian impulses
dP = int G^V dt, dL = int G^Omega dt with zero mean and per-component variance

    <dP_a dP_b> = 2 kBT alpha_v gamma_v dt delta_ab,
    <dL_a dL_b> = 2 kBT alpha_o gamma_o dt delta_ab,

the fluctuation-dissipation amplitude for a friction coefficient gamma.  The
caller passes the Stokes frictions gamma_v = 6 pi eta a and gamma_o = 8 pi eta a^3
(translation / rotation of a sphere of radius a); alpha_v and alpha_o are the
manual's dimensionless correction factors (eqs 13, 14, table 2 alpha_v / alpha_o:
tune the particle temperature, normally 1).  Eqs 13-14 as printed write the trace
<G.G> = 3 kBT alpha delta(t), i.e. kBT alpha per component with alpha carrying
the friction; here that strength is 2 kBT alpha gamma, so the manual's alpha
corresponds to 2 alpha gamma of this module (the FDT value for friction gamma).
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
    """Random impulses from numpy Generator(PCG64); state is JSON-serialisable.

    seed_or_generator: None, an int / SeedSequence (-> Generator(PCG64(seed))), or a
    numpy Generator backed by PCG64, which is then used (and advanced) directly.
    """

    def __init__(self, seed_or_generator=None):
        if isinstance(seed_or_generator, np.random.Generator):
            if not isinstance(seed_or_generator.bit_generator, np.random.PCG64):
                raise ValueError("ThermalNoise needs a PCG64-backed Generator, got "
                                 f"{type(seed_or_generator.bit_generator).__name__}")
            self.rng = seed_or_generator
        else:
            self.rng = np.random.Generator(np.random.PCG64(seed_or_generator))

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
