"""The Lees-Edwards frame (manual §5.1, eqs 27-29): the imposed shear's rate and strain
(``ShearFlow``: DC, or AC gamma_dot(t) = Shear_rate cos(2 pi Frequency t)) and the particles'
images across the sheared boundary (``lees_edwards_wrap``, ``lees_edwards_displacement``).
At the bottom of the package: the fluids, the particles and the models stand on it."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["ShearFlow", "lees_edwards_wrap", "lees_edwards_displacement"]


class ShearFlow:
    """gamma_dot(t) and the applied strain Gamma(t) of a DC or AC shear (table 4)."""

    def __init__(self, kind="DC", rate=0.0, frequency=0.0):
        if kind not in ("DC", "AC"):
            raise ValueError(f"shear kind must be DC or AC, got {kind!r}")
        self.kind, self.rate0, self.frequency = kind, float(rate), float(frequency)
        self.omega = 2.0 * math.pi * self.frequency

    @classmethod
    def from_config(cls, shear):
        return cls(shear.kind, shear.shear_rate, shear.frequency)

    def rate(self, t: float) -> float:
        if self.kind == "AC":
            return self.rate0 * math.cos(self.omega * t)
        return self.rate0

    def strain(self, t: float) -> float:
        if self.kind == "AC" and self.omega > 0:
            return self.rate0 * math.sin(self.omega * t) / self.omega
        return self.rate0 * t


def lees_edwards_wrap(R, v, box, offset, rate, v_old=None):
    """Wrap positions into the box with Lees-Edwards images: a particle leaving through
    y = Ly re-enters at y = 0 displaced by -offset along x (offset = g Ly, the image shift)
    with its x velocity lowered by rate Ly (and the reverse through y = 0); then x and z are
    wrapped periodically.  R, v (and v_old) are changed in place."""
    L = np.asarray(box, dtype=float)
    n = np.floor(R[:, 1] / L[1])
    if np.any(n):
        R[:, 0] -= n * offset
        R[:, 1] -= n * L[1]
        v[:, 0] -= n * rate * L[1]
        if v_old is not None:
            v_old[:, 0] -= n * rate * L[1]
    np.mod(R, L, out=R)
    R[R >= L] = 0.0


def lees_edwards_displacement(dr, box, offset):
    """Minimum-image displacement under Lees-Edwards images (y first, then x, z)."""
    L = np.asarray(box, dtype=float)
    dr = np.array(dr, dtype=float, copy=True)
    n = np.round(dr[..., 1] / L[1])
    dr[..., 0] -= n * offset
    dr[..., 1] -= n * L[1]
    dr[..., 0] -= np.round(dr[..., 0] / L[0]) * L[0]
    dr[..., 2] -= np.round(dr[..., 2] / L[2]) * L[2]
    return dr
