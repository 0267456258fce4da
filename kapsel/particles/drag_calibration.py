"""The SPM sphere's hydrodynamic radius, measured, and the profile radius that corrects it.

The rigidity of the SPM is imposed once per step (step 4 of kapsel.particles.spm): during a
step the fluid velocity diffuses a length ell = sqrt(NU dt) into the interface of width xi
before the particle's motion is imposed again.  The sphere's effective (Stokes) radius
a_eff therefore depends on ell and xi, not only on A (manual §4.1; issue 17): it equals A
at one time step only, and as dt -> 0 the drag converges (like sqrt(dt)) to that of a
larger sphere.  Measured by the drag of a periodic array (Hasimoto) at 32^3, A = 4
(bench/spm_drag_calibration.py; the table ``MEASURED``), the offset

    d = a_eff - A     (DX = 1 units; lengths scale with DX)

is fitted by ``offset(ell, xi)`` (quadratic in xi / DX and in ell / DX) for the spectral
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
# 32^3, A = 4, F = (1, 0, 0), FIX_CELL on, dt = factor / (NU KMAX2) (kapsel.timestep); the
# SPM step of the original (kapsel.particles.spm), measured 2026-12 (the table of kapsel-py's
# earlier step had V / V_H 1.0266 at XI 2, factor 1)
MEASURED = (
    (1, 0.25, 0.1337, 1.0080, -0.0212),
    (1, 0.5, 0.1890, 1.0437, -0.1128),
    (1, 1, 0.2673, 1.0864, -0.2169),
    (1, 2, 0.3780, 1.1409, -0.3415),
    (1.5, 1, 0.2673, 1.0660, -0.1677),
    (2, 0.1, 0.0845, 0.8743, +0.3651),
    (2, 0.25, 0.1337, 0.9215, +0.2201),
    (2, 0.5, 0.1890, 0.9654, +0.0942),
    (2, 1, 0.2673, 1.0184, -0.0482),
    (2, 2, 0.3780, 1.0860, -0.2159),
    (3, 0.25, 0.1337, 0.7890, +0.6547),
    (3, 0.5, 0.1890, 0.8287, +0.5152),
    (3, 1, 0.2673, 0.8800, +0.3472),
    (3, 2, 0.3780, 0.9492, +0.1397),
)
# (d hardly depends on A: measured with kapsel-py's earlier step, at XI 2, factor 1: -0.077,
# -0.069, -0.062 for A = 3, 4, 6; at factor 0.25: +0.149 for both A = 4 and 6.)

XI_RANGE = (1.0, 3.0)
ELL_RANGE = (0.08, 0.38)    # factor 0.1 to 2 at 32^3 (below 0.13: measured at XI 2 only)

# d = sum C[i, j] xi^i ell^j, quadratic in xi / DX and in ell / DX (least squares over
# MEASURED: bench/spm_drag_calibration.py --fit; largest residual 0.008 DX, i.e. 0.2 % of
# the drag at A = 4; the earlier linear-in-ell form left 0.039 with the original's step)
_C = np.array([[-0.14093, 0.64256, -2.41383],
               [0.35801, -3.45364, 5.15391],
               [0.01056, 0.74088, -1.24367]])


# d(MAC scheme) - d(spectral) measured at the same points, 32^3, A 4
# (bench/spm_drag_calibration.py --solver ...): explicit -0.010, +0.014, +0.001 at
# (XI, factor) = (2, 1), (2, 2), (1, 1): no shift; implicit -0.032, -0.030 at (2, 1),
# (2, 2): their mean
MAC_SHIFT = {"spectral": 0.0, "explicit_scheme": 0.0, "implicit_scheme": -0.031}


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
