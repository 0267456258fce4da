"""The SPM sphere's hydrodynamic radius, measured, and the profile radius that corrects it.

The rigidity of the SPM is imposed once per step (step 4 of kapsel.particles.spm): during a
step the fluid velocity diffuses a length ell = sqrt(NU dt) into the interface of width xi
before the particle's motion is imposed again.  The sphere's effective (Stokes) radius
a_eff therefore depends on ell and xi, not only on A (manual §4.1; issue 17): it equals A
at one time step only, and as dt -> 0 the drag converges (like sqrt(dt)) to that of a
larger sphere.  Measured by the drag of a periodic array (Hasimoto) at 32^3, A = 4
(bench/spm_drag_calibration.py; the table ``MEASURED``), the offset

    d = a_eff - A     (DX = 1 units; lengths scale with DX)

is fitted by ``offset(ell, xi)`` (quadratic in xi / DX, linear in ell / DX) for the spectral
solver; the MAC schemes diffuse differently within a step and add ``MAC_SHIFT``.

``--spm-drag calibrated`` (kapsel.cli) gives the SPM the profile radius
``profile_radius(A, xi, nu, dt, dx, solver) = A - d``, so that the hydrodynamic radius is
the input's A; everything else (pair forces, masses, the output's radius) keeps A.  The fit
holds for xi / DX in XI_RANGE and ell / DX in ELL_RANGE; outside them the option is refused
(``OutOfCalibration``), never extrapolated.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["MEASURED", "MAC_SHIFT", "XI_RANGE", "ELL_RANGE", "offset", "profile_radius",
           "OutOfCalibration"]

# (xi, factor, ell = sqrt(nu dt) / DX, V / V_Hasimoto, d = a_eff - A): spectral solver,
# 32^3, A = 4, F = (1, 0, 0), FIX_CELL on, dt = factor / (NU KMAX2) (kapsel.timestep)
MEASURED = (
    (1, 0.25, 0.1337, 1.0533, -0.1367),
    (1, 0.5, 0.1890, 1.0727, -0.1839),
    (1, 1, 0.2673, 1.1053, -0.2610),
    (1, 2, 0.3780, 1.1507, -0.3631),
    (1.5, 1, 0.2673, 1.0802, -0.2019),
    (2, 0.1, 0.0845, 0.9142, +0.2421),
    (2, 0.25, 0.1337, 0.9459, +0.1493),
    (2, 0.5, 0.1890, 0.9812, +0.0507),
    (2, 1, 0.2673, 1.0266, -0.0693),
    (2, 2, 0.3780, 1.0895, -0.2240),
    (3, 0.25, 0.1337, 0.8049, +0.5979),
    (3, 0.5, 0.1890, 0.8386, +0.4818),
    (3, 1, 0.2673, 0.8850, +0.3315),
    (3, 2, 0.3780, 0.9510, +0.1347),
)
# d hardly depends on A: at XI 2, factor 1: -0.077, -0.069, -0.062 for A = 3, 4, 6; at
# factor 0.25: +0.149 for both A = 4 and 6.

XI_RANGE = (1.0, 3.0)
ELL_RANGE = (0.08, 0.38)    # factor 0.1 to 2 at 32^3 (below 0.13: measured at XI 2 only)

# d = sum C[i, j] xi^i ell^j (least squares over MEASURED: bench/spm_drag_calibration.py
# --fit; largest residual 0.015 DX, i.e. 0.4 % of the drag at A = 4)
_C = np.array([[-0.27594, 0.07344],
               [0.21129, -1.18944],
               [0.05395, 0.17871]])


# d(MAC scheme) - offset(ell, xi), 32^3, A 4 (bench/spm_drag_calibration.py --solver ...):
# explicit -0.022, +0.031, -0.017 at (XI, factor) = (2, 1), (2, 2), (1, 1): no shift;
# implicit -0.051, -0.020 at (2, 1), (2, 2): their mean
MAC_SHIFT = {"spectral": 0.0, "explicit_scheme": 0.0, "implicit_scheme": -0.036}


class OutOfCalibration(ValueError):
    """xi or ell outside the range the offset was measured in."""


def offset(ell, xi):
    """d = a_eff - A (DX units) of the SPM sphere for ell = sqrt(NU dt) / DX, xi / DX."""
    return float(sum(_C[i, j] * xi ** i * ell ** j
                     for i in range(_C.shape[0]) for j in range(_C.shape[1])))


def profile_radius(A, xi, nu, dt, dx=1.0, solver="spectral"):
    """The profile radius whose hydrodynamic radius is A: A - DX d(sqrt(NU dt) / DX, xi / DX)
    (+ MAC_SHIFT[solver]: 'spectral', 'explicit_scheme', 'implicit_scheme').  Raises
    OutOfCalibration outside XI_RANGE / ELL_RANGE."""
    ell = math.sqrt(nu * dt) / dx
    x = xi / dx
    if not (XI_RANGE[0] <= x <= XI_RANGE[1]):
        raise OutOfCalibration(
            f"the SPM drag is calibrated for A_XI / DX from {XI_RANGE[0]:g} to "
            f"{XI_RANGE[1]:g}, not {x:g}")
    if not (ELL_RANGE[0] <= ell <= ELL_RANGE[1]):
        raise OutOfCalibration(
            f"the SPM drag is calibrated for sqrt(NU dt) / DX from {ELL_RANGE[0]:g} to "
            f"{ELL_RANGE[1]:g} (time_increment factor about 0.1 to 2), not {ell:.3g}")
    return A - dx * (offset(ell, x) + MAC_SHIFT[solver])
