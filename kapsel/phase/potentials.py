"""Bulk free-energy densities f(psi) of the Ginzburg-Landau functional (manual §4.2).

* ``Landau``: f = a/4 psi^4 - b/2 psi^2 (eq 18).  psi is an order parameter centred on 0; the
  bulk (equilibrium) values are +-sqrt(b/a), the neutral composition psi_bar is 0.
* ``FloryHuggins``: f = kBT [psi/NA ln psi + (1-psi)/NB ln(1-psi) + chi psi (1-psi)] (eq 19).
  psi is the volume fraction of A.  The neutral composition psi_bar is 0.5, the original's
  (fdm_phase_separation.cxx Init_phase_separation), for any NA, NB; the critical composition
  psi_c = sqrt(NB)/(sqrt(NA)+sqrt(NB)) equals it only for NA = NB.

Decisions
---------
* kBT = 1 in eq 19 (energy unit of the free energy).  The input's ``kBT`` is the particle
  thermostat temperature (eqs 13-14) and is often 0 for noiseless runs, which would make
  f identically 0; the define.udf calls NA, NB "reduced" quantities.  A different value can be
  passed explicitly (``FloryHuggins(..., kBT=...)``).
* Logarithm guard: inside the logarithms (and the 1/psi, 1/(1-psi) of f'') psi is clipped
  into [eps, 1-eps], eps = ``FH_EPS`` = 1e-12, so compositions driven out of (0, 1) by the
  numerics give large finite restoring forces instead of NaN.  The terms outside the logs use
  the unclipped psi, so f, f', f'' are exact for eps <= psi <= 1-eps.

All functions are vectorised over numpy arrays (float64) and accept ``out=``.
"""
import math

import numpy as np

__all__ = ["Landau", "FloryHuggins", "make_potential", "FH_EPS"]

FH_EPS = 1e-12


class Landau:
    """f(psi) = a/4 psi^4 - b/2 psi^2 (eq 18)."""

    name = "Landau"

    def __init__(self, a, b):
        self.a, self.b = float(a), float(b)

    def f(self, psi):
        p2 = np.square(psi)
        return (0.25 * self.a) * p2 * p2 - (0.5 * self.b) * p2

    def df(self, psi, out=None):
        """f'(psi) = a psi^3 - b psi."""
        out = np.multiply(psi, psi, out=out)
        out *= self.a
        out -= self.b
        out *= psi
        return out

    def d2f(self, psi, out=None):
        """f''(psi) = 3 a psi^2 - b."""
        out = np.multiply(psi, psi, out=out)
        out *= 3.0 * self.a
        out -= self.b
        return out

    @property
    def psi_bar(self):
        """Neutral composition (eq 17, fourth term): 0 for the symmetric Landau potential."""
        return 0.0

    @property
    def critical(self):
        return 0.0

    def equilibrium(self):
        """Coexisting bulk values (-sqrt(b/a), +sqrt(b/a)); requires a > 0, b > 0."""
        if not (self.a > 0 and self.b > 0):
            raise ValueError("Landau potential with a=%g, b=%g has no two-phase coexistence "
                             "(needs a > 0 and b > 0)" % (self.a, self.b))
        s = math.sqrt(self.b / self.a)
        return (-s, s)

    def spinodal(self):
        s = math.sqrt(self.b / (3.0 * self.a))
        return (-s, s)


class FloryHuggins:
    """f(psi) = kBT [psi/NA ln psi + (1-psi)/NB ln(1-psi) + chi psi(1-psi)] (eq 19)."""

    name = "Flory_Huggins"

    def __init__(self, na, nb, chi, kBT=1.0, eps=FH_EPS):
        if not (na > 0 and nb > 0):
            raise ValueError("Flory-Huggins NA, NB must be positive (got %g, %g)" % (na, nb))
        self.na, self.nb, self.chi = float(na), float(nb), float(chi)
        self.kBT, self.eps = float(kBT), float(eps)

    def _clip(self, psi):
        return np.clip(psi, self.eps, 1.0 - self.eps)

    def f(self, psi):
        p = np.asarray(psi, dtype=np.float64)
        c = self._clip(p)
        return self.kBT * (p / self.na * np.log(c) + (1.0 - p) / self.nb * np.log1p(-c)
                           + self.chi * p * (1.0 - p))

    def df(self, psi, out=None):
        """f' = kBT [(ln psi + 1)/NA - (ln(1-psi) + 1)/NB + chi (1 - 2 psi)]."""
        p = np.asarray(psi, dtype=np.float64)
        c = self._clip(p)
        r = (np.log(c) + 1.0) / self.na - (np.log1p(-c) + 1.0) / self.nb \
            + self.chi * (1.0 - 2.0 * p)
        r *= self.kBT
        if out is None:
            return r
        out[...] = r
        return out

    def d2f(self, psi, out=None):
        """f'' = kBT [1/(NA psi) + 1/(NB (1-psi)) - 2 chi]."""
        c = self._clip(np.asarray(psi, dtype=np.float64))
        r = 1.0 / (self.na * c) + 1.0 / (self.nb * (1.0 - c)) - 2.0 * self.chi
        r *= self.kBT
        if out is None:
            return r
        out[...] = r
        return out

    @property
    def critical(self):
        """Critical composition psi_c = sqrt(NB) / (sqrt(NA) + sqrt(NB))."""
        sa, sb = math.sqrt(self.na), math.sqrt(self.nb)
        return sb / (sa + sb)

    @property
    def chi_critical(self):
        return 0.5 * (1.0 / math.sqrt(self.na) + 1.0 / math.sqrt(self.nb)) ** 2

    @property
    def psi_bar(self):
        """Neutral composition (eq 17, fourth term): 0.5, whatever NA and NB (the original's
        Init_phase_separation; equal to the critical composition for NA = NB)."""
        return 0.5

    def spinodal(self):
        """Roots of f'' = 0: 2 chi NA NB psi^2 + (NA - NB - 2 chi NA NB) psi + NB = 0."""
        if not self.chi > self.chi_critical:
            raise ValueError("chi=%g <= chi_c=%g: no spinodal" % (self.chi, self.chi_critical))
        q = 2.0 * self.chi * self.na * self.nb
        r = np.roots([q, self.na - self.nb - q, self.nb])
        return tuple(sorted(float(x.real) for x in r))

    def equilibrium(self):
        """Binodal (common-tangent) compositions (psi_A-poor, psi_A-rich); chi > chi_c.

        Equal-area construction: for a slope mu between the spinodal values of f', the
        outer roots psi1 < s1, psi2 > s2 of f' = mu, and brentq on mu for
        f(psi2) - f(psi1) = mu (psi2 - psi1) (unclipped logarithms)."""
        from scipy.optimize import brentq
        s1, s2 = self.spinodal()
        na, nb, chi, T = self.na, self.nb, self.chi, self.kBT

        def f(p):
            return T * (p / na * math.log(p) + (1 - p) / nb * math.log1p(-p) + chi * p * (1 - p))

        def df(p):
            return T * ((math.log(p) + 1) / na - (math.log1p(-p) + 1) / nb + chi * (1 - 2 * p))

        def branches(mu):
            p1 = brentq(lambda p: df(p) - mu, 1e-300, s1, xtol=1e-300, rtol=1e-15)
            p2 = brentq(lambda p: df(p) - mu, s2, 1 - 1e-16, xtol=1e-300, rtol=1e-15)
            return p1, p2

        def tangent(mu):
            p1, p2 = branches(mu)
            return f(p2) - f(p1) - mu * (p2 - p1)
        lo, hi = df(s2), df(s1)
        span = hi - lo
        mu = brentq(tangent, lo + 1e-12 * span, hi - 1e-12 * span, xtol=1e-15, rtol=1e-15)
        return branches(mu)


def make_potential(params, kBT=1.0):
    """Potential of a ``kapsel.config.PhaseField`` (``params.potential``)."""
    if params.potential == "Landau":
        return Landau(params.a, params.b)
    if params.potential == "Flory_Huggins":
        return FloryHuggins(params.na, params.nb, params.chi, kBT=kBT)
    raise ValueError("unknown potential %r (Landau | Flory_Huggins)" % (params.potential,))
