"""Quincke rollers and point dipoles (switch.quincke, switch.multipole; PHYSICS-EXTRA.md §4).

Quincke constraint (§4.1): with n the field direction (space frame) and e = R(q) e_w the
body's intended rotation axis, U = (K/2)(n.e)^2 and the torque T = K (n.e)(n x e) keeps e
perpendicular to the field.  It does not drive rotation itself.

Dipoles (§4.2), Gaussian-like units (U = mu.mu/r^3 - ..., no 4 pi epsilon):
  FIXED:   mu = R(q) p0 e_dir (a body-frame axis), every particle of every species;
  QUINCKE: mu = p0 (n x e)/|n x e| - p0 Pz n  (n = z: e_dir must be Z);
  images (QUINCKE with_mirror_image): the electrode is the lower surface of the FLAT Z wall,
  z_w = DH DX / 2; each dipole at (x, y, z) has the conducting-plane image
  (-mu_x, -mu_y, +mu_z) of its rotating part, minus p0 Pz z, at (x, y, 2 z_w - z).
The dipoles (and images) are summed periodically by kapsel.particles.ewald; every real
dipole gets F_i and T_i = mu_i x E_i (images get none; a real dipole feels its own image).

Differences from the original, on purpose (docs/physics-quincke.md): the original puts every image
at a fixed 4.1 length units below its particle instead of reflecting it in the electrode
plane, and fills the dipoles species by species from offset 0 each time, so with more than
one species the particles of species >= 1 carry no dipole.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import ewald
from . import quaternion as quat

AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


@dataclass(frozen=True)
class Quincke:
    """switch.quincke ON: field direction n (space frame), body axis e_w, amplitude K."""
    field_dir: tuple
    body_axis: tuple
    torque_amp: float


@dataclass(frozen=True)
class Dipoles:
    """switch.multipole ON with Dipole ON.  kind 'FIXED' (body-frame ``axis``) or 'QUINCKE'
    (``pz_factor``; images in the plane z = ``mirror_z`` when not None); Ewald accuracy
    ``tol`` and the surrounding dielectric ``epsilon_surface`` (inf: tin-foil)."""
    kind: str
    magnitude: float
    axis: tuple = (0.0, 0.0, 1.0)
    pz_factor: float = 0.0
    mirror_z: float | None = None
    tol: float = 1e-8
    epsilon_surface: float = np.inf


def body_axes(q, axis) -> np.ndarray:
    """e = R(q) e_body (N, 3) for one body-frame axis."""
    q = np.asarray(q, dtype=float)
    return quat.rotate(q, np.broadcast_to(np.asarray(axis, dtype=float), (len(q), 3)))


def quincke_torque(q, quincke: Quincke) -> np.ndarray:
    """T = K (n.e)(n x e) (N, 3), e = R(q) e_w: the constraint torque of §4.1."""
    n = np.asarray(quincke.field_dir, dtype=float)
    e = body_axes(q, quincke.body_axis)
    return quincke.torque_amp * (e @ n)[:, None] * np.cross(n, e)


def quincke_energy(q, quincke: Quincke) -> np.ndarray:
    """U = (K/2)(n.e)^2 per body."""
    e = body_axes(q, quincke.body_axis)
    return 0.5 * quincke.torque_amp * (e @ np.asarray(quincke.field_dir, dtype=float)) ** 2


def rotating_part(q, dip: Dipoles, quincke: Quincke | None) -> np.ndarray:
    """The dipole without the static Pz term: R(q) p0 e_dir (FIXED) or p0 (n x e)/|n x e|
    (QUINCKE; zero when e is along the field)."""
    q = np.asarray(q, dtype=float)
    if dip.kind == "FIXED":
        return dip.magnitude * body_axes(q, dip.axis)
    n = np.asarray(quincke.field_dir, dtype=float)
    c = np.cross(n, body_axes(q, quincke.body_axis))
    norm = np.linalg.norm(c, axis=1)
    safe = np.where(norm > 1e-12, norm, 1.0)
    return dip.magnitude * np.where((norm > 1e-12)[:, None], c / safe[:, None], 0.0)


def static_part(dip: Dipoles) -> np.ndarray:
    """-p0 Pz z of the QUINCKE dipoles (zero for FIXED)."""
    if dip.kind != "QUINCKE":
        return np.zeros(3)
    return np.array([0.0, 0.0, -dip.magnitude * dip.pz_factor])


def moments(q, dip: Dipoles, quincke: Quincke | None = None) -> np.ndarray:
    """Space-frame dipoles of all particles (N, 3)."""
    return rotating_part(q, dip, quincke) + static_part(dip)


def sources(R, q, dip: Dipoles, quincke: Quincke | None = None):
    """(positions, dipoles) of the Ewald sum: the N real dipoles, then their images."""
    R = np.asarray(R, dtype=float)
    rot = rotating_part(q, dip, quincke)
    mu = rot + static_part(dip)
    if dip.mirror_z is None:
        return R, mu
    Ri = R.copy()
    Ri[:, 2] = 2.0 * dip.mirror_z - R[:, 2]
    mui = rot * np.array([-1.0, -1.0, 1.0]) + static_part(dip)
    return np.concatenate([R, Ri]), np.concatenate([mu, mui])


def ewald_box(box, dip: Dipoles):
    """The periodic cell of the Ewald sum: the box, doubled along z with mirror images (the
    images of a slab above the electrode plane lie below it, z' = 2 z_w - z: in the box's own
    period along z they would land on the real particles, e.g. z = 18.7 -> -13.7 = 18.3 mod
    32; in a cell of height 2 Lz they keep their distance 2 (z - z_w))."""
    box = np.array(box, dtype=float)
    if dip.mirror_z is not None:
        box[2] *= 2.0
    return box


def dipole_forces(R, q, box, dip: Dipoles, quincke: Quincke | None = None,
                  params: ewald.EwaldParameters | None = None, strain: float = 0.0):
    """(F, T) on the N real dipoles (N, 3 each): Ewald forces and mu x E (``strain``: the
    Lees-Edwards lattice of the sheared types, kapsel.particles.ewald)."""
    n = len(R)
    box = ewald_box(box, dip)
    X, mu = sources(R, q, dip, quincke)
    if params is None:
        params = ewald.choose_parameters(box, len(X), dip.tol)
    _, F, E = ewald.dipolar_ewald(X, mu, box, params, dip.epsilon_surface, strain=strain)
    return F[:n], np.cross(mu[:n], E[:n])


def dipole_forces_owned(R, q, n_own, box, dip: Dipoles, quincke: Quincke | None, params,
                        reduce, strain: float = 0.0):
    """``dipole_forces`` of a distributed run (kapsel.particles.ewald
    ``dipolar_ewald_owned``): (F, T) (n_own, 3) of the first ``n_own`` of a rank's
    particles (its owned ones; the rest are ghosts within the real-space cutoff), their
    mirror images made from the rank's particles as in the serial sum."""
    n = len(R)
    box = ewald_box(box, dip)
    X, mu = sources(R, q, dip, quincke)
    own = np.zeros(len(X), dtype=bool)
    own[:n_own] = True
    if len(X) > n:
        own[n:n + n_own] = True
    F, E = ewald.dipolar_ewald_owned(X, mu, own, n_own, box, params, reduce,
                                     dip.epsilon_surface, strain=strain)
    return F, np.cross(mu[:n_own], E)


def make_electric(dip: Dipoles | None, quincke: Quincke | None, box, n: int, strain=None):
    """``electric(p) -> (F, T)`` of dipoles and the Quincke constraint on the particles
    ``p`` (positions R, orientations q), or None when neither is on.  The Ewald split is
    chosen once for the box and the number of dipoles.  ``strain()``: the Lees-Edwards
    strain of the sheared lattice now (the Lees-Edwards types)."""
    if dip is None and quincke is None:
        return None
    box = np.asarray(box, dtype=float)
    params = None
    if dip is not None:
        params = ewald.choose_parameters(ewald_box(box, dip),
                                         2 * n if dip.mirror_z is not None else n, dip.tol)

    def electric(p):
        F = np.zeros((p.n, 3))
        T = np.zeros((p.n, 3))
        if quincke is not None:
            T += quincke_torque(p.q, quincke)
        if dip is not None and p.n:
            Fd, Td = dipole_forces(p.R, p.q, box, dip, quincke, params,
                                   strain=strain() if strain is not None else 0.0)
            F += Fd
            T += Td
        return F, T

    def local(p, n_own, reduce):
        """``electric`` of a rank's table in a distributed run (owned rows first, then
        ghosts; ``reduce``: sum over the ranks, a collective): complete on the owned rows."""
        F = np.zeros((p.n, 3))
        T = np.zeros((p.n, 3))
        if quincke is not None:
            T += quincke_torque(p.q, quincke)
        if dip is not None:
            Fd, Td = dipole_forces_owned(p.R, p.q, n_own, box, dip, quincke, params, reduce,
                                         strain=strain() if strain is not None else 0.0)
            F[:n_own] += Fd
            T[:n_own] += Td
        return F, T
    electric.local = local
    electric.reach = params.r_cut if params is not None else 0.0   # (length) for the halos
    return electric
