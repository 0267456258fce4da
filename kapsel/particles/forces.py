"""Direct particle-particle forces (F_i^other of eq 9) and gravity.

Pair interactions between spheres i, j use sigma = a_i + a_j (as in KAPSEL the
LJ sigma is the contact distance), lengths in DX.

LJ_powers '12:6', '24:12', '36:18' (table 6):
    V(r) = 4 EPSILON [(sigma/r)^(2n) - (sigma/r)^n],  n = 6, 12, 18.
LJ_truncate (table 7):
    'ON'   repulsive only (WCA): cut at r_min = 2^(1/n) sigma and shifted by
           +EPSILON so that V(r_min) = 0 (force and energy continuous).
    'OFF'  full LJ cut at r_c = 2.5 sigma.  This is a *force* cut as in KAPSEL
           (A_R_cutoff = 2.5): V is not shifted, so the energy jumps by
           V(2.5 sigma) (= -0.0163 EPSILON for 12:6) at r_c; forces are -dV/dr
           inside r_c and zero outside.
    'NONE' no interaction (ghost particles): zeros are returned immediately.

LJ_powers 'macro_vdw' (section 5.4, eqs 33-34; EPSILON is the Hamaker constant
H, n = MACRO_VDW_N = 1.1), with x = r / sigma:
    V(x) = H / (48 (n-1)^3) [x^2 - 2x - (3n^2 - 6n + 2)]   x <= n
    V(x) = -H / (24 (x - 1))                              x >  n   (eq 33)

Continuity check of eq 34 as printed (done analytically, also tested):
    value:  x^2 - 2x - 3n^2 + 6n - 2 at x = n equals -2 (n-1)^2, so the inner
            branch gives -2 H (n-1)^2 / (48 (n-1)^3) = -H / (24 (n-1)), which
            equals the outer branch -H / (24 (n-1)).               -> continuous
    slope:  d/dx inner = H (2x - 2) / (48 (n-1)^3) -> H / (24 (n-1)^2) at x = n;
            d/dx outer = H / (24 (x-1)^2)          -> H / (24 (n-1)^2). -> C1
    curvature: inner H / (24 (n-1)^3), outer -H / (12 (n-1)^3): not C2.
So eq 34 is C1 exactly as printed; the prefactor and constant are used unchanged.
The inner branch has its minimum V = -H / (16 (n-1)) at contact x = 1 (soft
repulsion for x < 1, attraction for 1 < x).
macro_vdw cutoff choice: the Hamaker tail decays only like 1/(x-1), so with
'OFF' it is force-cut at r_c = 2.5 sigma (the same A_R_cutoff as LJ 'OFF', as in
KAPSEL).  At r_c the attraction is (n-1)^2 / 1.5^2 = 0.44 % of its maximum (at
r = n sigma) and V(r_c) = -H/36 is 4.4 % of the well depth H / (16 (n-1)); the
energy is not shifted (jump of H/36 at r_c, forces consistent inside).  With 'ON'
only the repulsive part is kept: cut at the minimum r = sigma, shifted by
+H / (16 (n-1)) so that V(sigma) = 0 (C1 at the cut).

LJ_powers 'electro_osmotic_flow' (PHYSICS-EXTRA.md §5; a plain pair force, not the
Electrolyte solver): with lambda = 3 sigma, for r >= EOF_CORE sigma (EOF_CORE = 1.01)
    -dV/dr = -EPSILON exp(-r/lambda) (r/lambda + 2) / r^2          (attractive, range 3 sigma)
    V(r)   = -EPSILON [2 exp(-r/lambda) / r - E1(r/lambda) / lambda]  (E1: exponential integral)
and for r < EOF_CORE sigma the 36:18 LJ force, its energy shifted to meet V at EOF_CORE sigma
(the force jumps there, as in the original).  Cutoff: 'ON' at r = sigma (only the repulsive
core acts; V shifted to 0 there), 'OFF' at LJ_CUTOFF_OFF sigma (force cut, V not shifted).

Sheared types (PHYSICS-EXTRA.md §5): the LJ diameter is LJ_dia = min((2a + XI) / c, 2a), c =
2^(1/n) for the 2n:n laws and 1 for macro_vdw and electro_osmotic_flow (``sheared_lj_dia``),
so the potential minimum c LJ_dia lies no further out than a surface gap of XI; pair_forces
takes it as ``sigma``.  The original's shear-rate-dependent cap on g(r) (Srate_depend_LJ_cap)
is DBL_MAX and no input changes it, so there is no cap here either.
"""
from __future__ import annotations

import numpy as np
from scipy.special import exp1

from .cells import pairs_within

__all__ = ["LJ_POWERS", "MACRO_VDW_N", "EOF", "EOF_CORE", "sheared_lj_dia", "LJ_CUTOFF_OFF", "DEEP_OVERLAP_RATIO", "interaction_range",
           "pair_potential", "pair_force_magnitude", "pair_dVdr", "pair_forces", "gravity_force"]

LJ_POWERS = {"12:6": 6, "24:12": 12, "36:18": 18}
MACRO_VDW_N = 1.1
EOF = "electro_osmotic_flow"
EOF_CORE = 1.01
LJ_CUTOFF_OFF = 2.5
DEEP_OVERLAP_RATIO = 0.5  # suggested stop threshold for min r / sigma


def _norm_key(s) -> str:
    return str(s).strip()


def _truncate_key(truncate) -> str:
    t = _norm_key(truncate).upper()
    if t not in ("ON", "OFF", "NONE"):
        raise ValueError(f"LJ_truncate must be ON, OFF or NONE, got {truncate!r}")
    return t


def _check_powers(powers) -> str:
    p = _norm_key(powers)
    if p not in LJ_POWERS and p not in ("macro_vdw", EOF):
        raise ValueError(f"LJ_powers must be one of 12:6, 24:12, 36:18, macro_vdw, {EOF}; "
                         f"got {powers!r}")
    return p


def interaction_range(kind, truncate, box_min=None, sigma=None) -> float:
    """Cutoff r_c / sigma (0 for 'NONE').  'OFF' with ``box_min`` (the smallest box side
    N_min DX) and ``sigma`` (the particle diameter 2A): min(N_min DX / (2 sigma), 2.5), the
    original's A_R_cutoff (input.cxx, PHYSICS-EXTRA.md §5), so that the cutoff sphere lies
    within half the box, where the minimum image is every pair's only image."""
    p, t = _check_powers(kind), _truncate_key(truncate)
    if t == "NONE":
        return 0.0
    if t == "OFF":
        if box_min is not None and sigma is not None:
            return min(0.5 * float(box_min) / float(sigma), LJ_CUTOFF_OFF)
        return LJ_CUTOFF_OFF
    if p in ("macro_vdw", EOF):
        return 1.0
    return 2.0 ** (1.0 / LJ_POWERS[p])


def sheared_lj_dia(kind, a, xi) -> float:
    """LJ_dia of the sheared types (module docstring): min((2a + XI) / c, 2a)."""
    p = _check_powers(kind)
    c = 2.0 ** (1.0 / LJ_POWERS[p]) if p in LJ_POWERS else 1.0
    return min((2.0 * a + xi) / c, 2.0 * a)


def _eof_outer(r, sigma, epsilon):
    """(V, -dV/dr) of the electro_osmotic_flow tail."""
    lam = 3.0 * sigma
    e = np.exp(-r / lam)
    V = -epsilon * (2.0 * e / r - exp1(r / lam) / lam)
    return V, -epsilon * e * (r / lam + 2.0) / (r * r)


def _eof_core_offset(sigma, epsilon):
    """C with V_core = 4 EPSILON (s^2 - s) + C meeting the tail at EOF_CORE sigma."""
    rc = EOF_CORE * sigma
    s = EOF_CORE ** -18.0
    return _eof_outer(rc, sigma, epsilon)[0] - 4.0 * epsilon * (s * s - s)


def _raw(r, sigma, p, epsilon):
    """Untruncated (V, -dV/dr)."""
    if p == EOF:
        core = r < EOF_CORE * sigma
        ro = np.where(core, 2.0 * sigma, r)
        Vo, Fo = _eof_outer(ro, sigma, epsilon)
        s = (sigma / r) ** 18
        Vc = 4.0 * epsilon * (s * s - s) + _eof_core_offset(sigma, epsilon)
        Fc = 72.0 * epsilon * (2.0 * s * s - s) / r
        return np.where(core, Vc, Vo), np.where(core, Fc, Fo)
    if p == "macro_vdw":
        n = MACRO_VDW_N
        x = r / sigma
        c = epsilon / (48.0 * (n - 1.0) ** 3)
        inner = x <= n
        xo = np.where(inner, n + 1.0, x)  # avoid x = 1 in the outer branch
        V = np.where(inner, c * (x * x - 2.0 * x - (3 * n * n - 6 * n + 2)),
                     -epsilon / (24.0 * (xo - 1.0)))
        F = np.where(inner, -c * (2.0 * x - 2.0) / sigma,
                     -epsilon / (24.0 * sigma * (xo - 1.0) ** 2))
        return V, F
    n = LJ_POWERS[p]
    s = (sigma / r) ** n
    V = 4.0 * epsilon * (s * s - s)
    F = 4.0 * epsilon * n * (2.0 * s * s - s) / r
    return V, F


def _shift(p, epsilon, t, sigma=None):
    if t != "ON":
        return 0.0
    if p == EOF:                     # cut at sigma, where the core's 36:18 LJ part is 0
        return -_eof_core_offset(sigma, epsilon)
    if p == "macro_vdw":
        return epsilon / (16.0 * (MACRO_VDW_N - 1.0))
    return epsilon  # V(r_min) = -EPSILON for every 2n:n LJ


def _within_cutoff(r, sigma, kind, epsilon, truncate):
    """(V, F, shift) of the raw pair law where r is inside the cutoff, 0 elsewhere; None
    for LJ_truncate NONE."""
    p, t = _check_powers(kind), _truncate_key(truncate)
    r = np.asarray(r, dtype=float)
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), r.shape)
    if t == "NONE":
        return None, r
    inside = r < interaction_range(p, t) * sigma
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        V, F = _raw(r, sigma, p, epsilon)
    return (np.where(inside, V + _shift(p, epsilon, t, sigma), 0.0),
            np.where(inside, F, 0.0)), r


def pair_potential(r, sigma, kind="12:6", epsilon=1.0, truncate="ON"):
    """Pair potential V(r) including truncation/shift; 0 beyond the cutoff."""
    VF, r = _within_cutoff(r, sigma, kind, epsilon, truncate)
    return np.zeros_like(r) if VF is None else VF[0]


def pair_force_magnitude(r, sigma, kind="12:6", epsilon=1.0, truncate="ON"):
    """-dV/dr (positive = repulsive); 0 beyond the cutoff."""
    VF, r = _within_cutoff(r, sigma, kind, epsilon, truncate)
    return np.zeros_like(r) if VF is None else VF[1]


def pair_dVdr(r, sigma, kind="12:6", epsilon=1.0, truncate="ON"):
    """dV/dr (= -pair_force_magnitude); 0 beyond the cutoff."""
    return -pair_force_magnitude(r, sigma, kind, epsilon, truncate)


def pair_forces(R, box, radius, kind="12:6", epsilon=1.0, truncate="ON", group=None,
                strain=0.0, virial=None, sigma=None, weight=None, cutoff=None):
    """Pair forces F_i^other (eq 9) -> (F (N, 3), U_total, min_ratio).

    kind is LJ_powers ('12:6', '24:12', '36:18', 'macro_vdw'), epsilon is EPSILON
    (the Hamaker constant H for macro_vdw), truncate is LJ_truncate; sigma = a_i + a_j.
    F_j += f, F_i -= f for every pair (Newton's third law exact per pair, so the
    total force vanishes to round-off), f = (-dV/dr) dr/|dr|, dr = minimum-image
    R_j - R_i.  Nothing is capped (as in KAPSEL); instead min_ratio, the smallest
    r/sigma among the pairs inside the cutoff (inf if none), is returned so the
    caller can stop on deep overlap, e.g. min_ratio < DEEP_OVERLAP_RATIO
    (coincident particles give non-finite F).  ``group`` (N,) ints: pairs i, j with
    group[i] == group[j] >= 0 do not interact (the beads of one rigid body).
    ``strain`` g: Lees-Edwards images (the image across y = Ly displaced by g Ly along x):
    the pairs are found in the oblique coordinates x - g y, where the images are periodic
    (valid while the cutoff (1 + |g|) stays below half the box).
    ``virial``: a (3, 3) array set to sum over pairs of f_a dr_b (f the force on j), or None.
    ``sigma``: one LJ diameter for every pair instead of a_i + a_j (the sheared types'
    LJ_dia, ``sheared_lj_dia``).
    ``weight`` (N,): the virial counts a pair with (weight_i + weight_j) / 2 (a distributed
    run: 1 for the particles a rank owns, 0 for its ghosts, so that the ranks' virials add
    up to every pair once).
    ``cutoff``: r_c / sigma instead of ``interaction_range(kind, truncate)`` (a run passes
    the box-limited one, ``interaction_range(kind, truncate, box_min, 2A)``).
    Each pair is counted once, at its minimum image (the original counts a pair 2^m times
    in boxes under 48 DX, m the axes along which its 16-DX link cells differ: docs/
    physics-spm.md, "Pair forces").
    """
    if virial is not None:
        virial[...] = 0.0
    R = np.asarray(R, dtype=float).reshape(-1, 3)
    n = len(R)
    F = np.zeros((n, 3))
    p, t = _check_powers(kind), _truncate_key(truncate)
    if t == "NONE" or n < 2:
        return F, 0.0, np.inf
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (n,))
    rc = interaction_range(p, t) if cutoff is None else float(cutoff)
    rcut = rc * (2.0 * float(radius.max()) if sigma is None else float(sigma))
    if strain:
        L = np.asarray(box, dtype=float)
        Ro = R.copy()
        Ro[:, 0] = np.mod(R[:, 0] - strain * R[:, 1], L[0])
        Ro[Ro[:, 0] >= L[0], 0] = 0.0
        i, j, dr = pairs_within(Ro, box, rcut * (1.0 + abs(strain)))
        dr = np.array(dr, dtype=float).reshape(-1, 3)
        dr[:, 0] += strain * dr[:, 1]
    else:
        i, j, dr = pairs_within(R, box, rcut)
    if len(i) == 0:
        return F, 0.0, np.inf
    r = np.sqrt(np.einsum("ij,ij->i", dr, dr))
    sigma = radius[i] + radius[j] if sigma is None else np.full(len(i), float(sigma))
    keep = r < rc * sigma
    if group is not None:
        group = np.asarray(group)
        keep &= (group[i] != group[j]) | (group[i] < 0)
    i, j, dr, r, sigma = i[keep], j[keep], dr[keep], r[keep], sigma[keep]
    if len(i) == 0:
        return F, 0.0, np.inf
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        V, fmag = _raw(r, sigma, p, epsilon)
        f = (fmag / r)[:, None] * dr
    U = float(np.sum(V + _shift(p, epsilon, t, sigma)))
    if virial is not None:
        if weight is None:
            virial[...] = f.T @ dr
        else:
            w = np.asarray(weight, dtype=float)
            virial[...] = (f * (0.5 * (w[i] + w[j]))[:, None]).T @ dr
    for k in range(3):
        F[:, k] = np.bincount(j, f[:, k], minlength=n) - np.bincount(i, f[:, k], minlength=n)
    return F, U, float(np.min(r / sigma))


_DIRECTIONS = {"X": 0, "Y": 1, "Z": 2}


def gravity_force(radius, mass_ratio, rho, G, direction="-Z"):
    """Buoyancy-corrected gravity G RHO (4/3) pi a^3 (MASS_RATIO - 1) along direction.

    direction is '-X', '-Y' or '-Z' (table 6); '+X' / 'X' etc. are accepted too.
    Returns (N, 3).
    """
    radius = np.atleast_1d(np.asarray(radius, dtype=float))
    mass_ratio = np.broadcast_to(np.asarray(mass_ratio, dtype=float), radius.shape)
    d = str(direction).strip().upper()
    sign = -1.0 if d.startswith("-") else 1.0
    axis = _DIRECTIONS.get(d.lstrip("+-"))
    if axis is None:
        raise ValueError(f"gravity.direction must be -X, -Y or -Z, got {direction!r}")
    mag = G * rho * (4.0 / 3.0) * np.pi * radius ** 3 * (mass_ratio - 1.0)
    F = np.zeros((len(radius), 3))
    F[:, axis] = sign * mag
    return F
