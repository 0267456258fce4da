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

__all__ = ["ThermalNoise", "kinetic_temperature_ratios", "temperature_alphas"]


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


def kinetic_temperature_ratios(a, rho=1.0, eta=1.0, mass_ratio=1.0):
    """(<M V^2>/3kT, <I W^2>/3kT) of a sphere of radius a (M = mass_ratio rho 4/3 pi a^3,
    I = 2/5 M a^2) driven by the white noise of eqs 13-14 with alpha = 1 (strength
    2 kT gamma_0, gamma_0 = 6 pi eta a, 8 pi eta a^3) in an unbounded fluid that does not
    fluctuate itself: the kicks are shared with the fluid through the frequency-dependent
    friction (added mass and Basset memory; the rotational kernel), so these ratios, not 1,
    are the particle temperature in units of T.  For A = 4, RHO = ETA = 1: 0.206 and 0.460
    (the SPM measures 0.208 and 0.477 at L = 32)."""
    from scipy.integrate import quad
    nu = eta / rho
    vol = 4.0 / 3.0 * np.pi * a ** 3
    M = mass_ratio * rho * vol
    I = 0.4 * M * a * a
    g0, g1 = 6 * np.pi * eta * a, 8 * np.pi * eta * a ** 3

    def ft(w):
        lam = np.sqrt(-1j * w / nu)
        return 2 * g0 / abs(-1j * w * (M + 0.5 * rho * vol) + g0 * (1 + a * lam)) ** 2 / np.pi

    def fr(w):
        la = np.sqrt(-1j * w / nu) * a
        return 2 * g1 / abs(-1j * w * I + g1 * (1 + la ** 2 / (3 * (1 + la)))) ** 2 / np.pi
    return M * quad(ft, 0, np.inf, limit=500)[0], I * quad(fr, 0, np.inf, limit=500)[0]


def temperature_alphas(a, rho=1.0, eta=1.0, mass_ratio=1.0):
    """(alpha_v, alpha_o) of eqs 13-14 that bring the particle temperature to T: the
    inverses of :func:`kinetic_temperature_ratios` (the noise is linear in alpha).  4.85 and
    2.17 for A = 4, RHO = ETA = MASS_RATIO = 1.  The long-time diffusion is then alpha kT /
    gamma_0, i.e. alpha = 1 gets diffusion right, these get the kinetic temperature right."""
    rv, ro = kinetic_temperature_ratios(a, rho, eta, mass_ratio)
    return 1.0 / rv, 1.0 / ro
