"""Rigid bodies made of spherical beads (object_type ``rigid``, ``Rigid_spec[]``).

Every bead is an SPM particle (its own profile phi_i, momentum exchange F_H,i, N_H,i); the
beads of a body move together.  Species by species, body by body, the Beads_number beads of
a body are consecutive particles.  All operations are whole-array numpy over beads / bodies.

Body quantities (g a body, k its beads, m_k bead masses, r_k = x_k - R_g):

    M_g = sum_k m_k,  R_g = sum_k m_k x_k / M_g                       (centre of mass)
    I_g = sum_k m_k [(r_k . r_k) 1 - r_k r_k^T] + sum_k I_k 1          (eq 2 of spec 002
          plus the beads' own moments I_k = 2/5 m_k A^2, which keeps a one-bead body regular)
    I_g = R(q_g) I_g^B R(q_g)^T,  r_k = R(q_g) r_k^B                   (eq 4)

The body frame is the space frame of the initial configuration: q_g = identity and
r_k^B = r_k at t = 0 for user-specified bead positions; for generated bodies the
shape (a straight rod of touching beads, spacing 2 A, along the body x axis) is given in
the body frame and q_g by switch.INIT_orientation.  ``body_positions`` (r_k^B, the restart's
GR_body[]), ``masses`` (M_g, GR_masses[]) and ``moments_body`` (I_g^B, GR_moments_body[])
are plain arrays.

One step (called by spm.SPM in place of the free-particle motion.update_velocities /
update_positions):

* forces and torques about the centre of mass summed over the beads,
      F_g = sum_k (F_H,k + F_o,k),   T_g = sum_k (r_k x (F_H,k + F_o,k) + N_H,k + N_o,k)
  (thermal impulses likewise), with the SPM's per-bead masses / moments (grid or nominal);
* rigid_motion ``free``: V_g += dt F_g / M_g,
  Omega_g += I_g^-1 dt (T_g - Omega_g x I_g Omega_g)    (Euler's equations, space frame);
  ``fix``: V_g = Rigid_velocity, Omega_g = Rigid_omega.  switch.free_rigid makes single
  components free or fixed per species (a fixed component keeps the species' prescribed
  value, a free one follows the forces; without a DOF entry ``free`` means all free and
  ``fix`` all fixed).  With switch.ROTATION OFF free Omega components are not integrated;
* bead velocities v_k = V_g + Omega_g x r_k, bead omega_k = Omega_g;
* R_g by Crank-Nicolson (§5.2), q_g by the mean Omega of the step, then the beads are placed
  exactly, x_k = R_g + R(q_g) r_k^B (wrapped into the box), q_k = q_g.

Pair forces between beads of the same body are not computed (forces.pair_forces group=);
they would cancel in F_g and T_g anyway.  ``state`` is a ParticleState with one row per body
(R, R_raw, v, q, omega and the summed forces / torques of the last step): the
RigidParticles[] records.  Its ``inertia`` is trace(I_g^B) / 3, a scalar stand-in; the
tensors are ``moments_body``.  The rotational energy of every body, 1/2 Omega_g . I_g Omega_g
(spec 002 eq 3; eq 6 when the three principal moments agree) is ``rotational_energies()``.
"""
from __future__ import annotations

import numpy as np

from . import quaternion as quat
from .cells import minimum_image
from .motion import update_velocities as _free_velocities
from .state import VECTOR_FIELDS, ParticleState

__all__ = ["RigidBodies", "rod_shape", "place_bodies", "inertia_tensors", "build_bodies"]


def _sum(body, values, nb):
    """Per-body sums of per-bead rows (N, k) -> (B, k)."""
    values = np.asarray(values, dtype=float)
    return np.stack([np.bincount(body, values[:, a], minlength=nb)
                     for a in range(values.shape[1])], axis=1)


def inertia_tensors(body, nb, mass, inertia, r):
    """Space-frame I_g (B, 3, 3) of beads of masses ``mass``, own moments ``inertia`` at
    offsets ``r`` (N, 3) from their body's centre of mass."""
    r2 = np.einsum("nk,nk->n", r, r)
    per = (mass * r2 + inertia)[:, None, None] * np.eye(3) - \
        mass[:, None, None] * r[:, :, None] * r[:, None, :]
    return _sum(body, per.reshape(-1, 9), nb).reshape(nb, 3, 3)


def rod_shape(beads, a) -> np.ndarray:
    """Body-frame bead offsets (beads, 3) of a straight rod of touching beads along x."""
    return np.stack([(np.arange(beads) - 0.5 * (beads - 1)) * 2.0 * a,
                     np.zeros(beads), np.zeros(beads)], axis=1)


def place_bodies(offsets, radius, box, rng, candidates=64, attempts=200,
                 slab=None) -> np.ndarray:
    """Random centres (B, 3) for bodies whose space-frame bead offsets are ``offsets``
    (list of (n_g, 3)) such that no two beads of different bodies are closer than 2 A
    (minimum image).  Each body tries ``candidates`` centres at once, ``attempts`` times;
    ValueError if the box is too crowded.  ``slab`` (axis, lo, hi): every bead centre must lie
    between lo and hi along axis (walls, kapsel.particles.walls.clear_slab)."""
    L = np.asarray(box, dtype=float).reshape(3)
    limit = 2.0 * float(radius) * (1.0 - 1e-9)
    placed = np.zeros((0, 3))
    centres = np.empty((len(offsets), 3))
    for g, off in enumerate(offsets):
        for _ in range(attempts):
            c = rng.random((candidates, 3)) * L
            beads = c[:, None, :] + off[None, :, :]                        # (C, n_g, 3)
            if len(placed):
                d = np.linalg.norm(minimum_image(beads[:, :, None, :] - placed, L), axis=3)
                ok = np.flatnonzero((d >= limit).all(axis=(1, 2)))
            else:
                ok = np.arange(candidates)
            if slab is not None:
                x = np.mod(beads[ok, :, slab[0]], L[slab[0]])
                ok = ok[((x >= slab[1]) & (x <= slab[2])).all(axis=1)]
            if len(ok):
                centres[g] = c[ok[0]]
                placed = np.concatenate([placed, np.mod(beads[ok[0]], L)])
                break
        else:
            raise ValueError(f"could not place rigid body {g} ({len(off)} beads of radius "
                             f"{radius:g}) without overlap in the box "
                             f"{' x '.join(f'{float(x):g}' for x in np.ravel(L))}")
    return centres


class RigidBodies:
    """Rigid bodies of beads (see module docstring); the motion of spm.SPM for them.

    body (N,): body index of every bead (bodies numbered 0..B-1, beads of a body consecutive);
    body_positions (N, 3): r_k^B; bead_mass (N,): nominal bead masses (define the COM and
    ``moments_body``); bead_inertia (N,): nominal bead moments; species (B,): Rigid_spec
    index of each body; free_v, free_o (B, 3) bool: free components; v_fixed, o_fixed (B, 3):
    prescribed values of the other components; R (B, 3) centres; q (B, 4) orientations.
    """

    def __init__(self, body, body_positions, bead_mass, bead_inertia, species, R, q,
                 free_v, free_o, v_fixed, o_fixed, box):
        self.body = np.asarray(body, dtype=np.int64)
        self.nb = int(self.body.max()) + 1 if len(self.body) else 0
        self.body_positions = np.asarray(body_positions, dtype=float)
        self.bead_mass = np.asarray(bead_mass, dtype=float)
        self.bead_inertia = np.asarray(bead_inertia, dtype=float)
        self.box = np.asarray(box, dtype=float)
        self.free_v = np.asarray(free_v, dtype=bool)
        self.free_o = np.asarray(free_o, dtype=bool)
        self.v_fixed = np.asarray(v_fixed, dtype=float)
        self.o_fixed = np.asarray(o_fixed, dtype=float)
        self.masses = np.bincount(self.body, self.bead_mass, minlength=self.nb)
        self.moments_body = inertia_tensors(self.body, self.nb, self.bead_mass,
                                            self.bead_inertia, self.body_positions)
        com = _sum(self.body, self.bead_mass[:, None] * self.body_positions, self.nb)
        if np.abs(com).max(initial=0.0) > 1e-9 * max(1.0, np.abs(self.body_positions).max()):
            raise ValueError("body_positions must be taken about each body's centre of mass")
        s = ParticleState(n=self.nb, species=np.asarray(species, dtype=np.int64),
                          radius=np.zeros(self.nb), mass=self.masses.copy(),
                          inertia=np.trace(self.moments_body, axis1=1, axis2=2) / 3.0)
        s.R[:] = np.mod(R, self.box)
        s.R_raw[:] = R
        s.q[:] = quat.normalise(q)
        s.q_old[:] = s.q
        s.v[:] = np.where(self.free_v, 0.0, self.v_fixed)
        s.omega[:] = np.where(self.free_o, 0.0, self.o_fixed)
        self.state = s
        self.lees_edwards = None          # the oblique fluid under Lees-Edwards images
        self.image = np.zeros(len(self.body))

    @classmethod
    def from_beads(cls, X, body, bead_mass, bead_inertia, species, free_v, free_o, v_fixed,
                   o_fixed, box):
        """Bodies from bead positions X (N, 3) (the initial configuration defines the body
        frame, q = identity); beads are unwrapped by the minimum image about the first bead
        of their body, so a body must be smaller than half the box."""
        X = np.asarray(X, dtype=float)
        body = np.asarray(body, dtype=np.int64)
        L = np.asarray(box, dtype=float)
        nb = int(body.max()) + 1
        first = np.full(nb, len(X))
        np.minimum.at(first, body, np.arange(len(X)))
        X = X[first][body] + minimum_image(X - X[first][body], L)
        m = np.asarray(bead_mass, dtype=float)
        R = _sum(body, m[:, None] * X, nb) / np.bincount(body, m, minlength=nb)[:, None]
        return cls(body, X - R[body], m, bead_inertia, species, R, quat.identity(nb),
                   free_v, free_o, v_fixed, o_fixed, L)

    # ------------------------------------------------------------------ Lees-Edwards
    def use_lees_edwards(self, fluid):
        """Lees-Edwards images (PHYSICS-EXTRA.md §7) of the oblique ``fluid`` (its
        frame_box, image_offset, shear_rate_now): the centre of mass is wrapped by the
        Lees-Edwards rule, its x velocity (and the stored old one) shifted by the boundary
        velocity jump gamma_dot Ly at a crossing of the y boundary; each bead x_k = R_g + r_k
        is wrapped by the same rule on its own, its image count n_k (-1, 0, 1: across which
        y boundary from its centre of mass) kept in ``image``, and its velocity is
        V_g + Omega_g x r_k - n_k gamma_dot Ly e_x: the velocity of the body at the bead's
        image, continuous relative to the imposed flow.  Sets the images of the beads where
        they are and their velocities (positions unchanged)."""
        self.lees_edwards = fluid
        self._set_images()

    def _set_images(self, r=None, p=None):
        """n_k of the beads from the centres and offsets; bead velocities when ``p``."""
        r = self.offsets() if r is None else r
        Ly = float(self.lees_edwards.frame_box[1])
        self.image = np.floor((self.state.R[self.body, 1] + r[:, 1]) / Ly)
        if p is not None:
            self.set_bead_velocities(p, r)

    def _le_rate_jump(self) -> float:
        fl = self.lees_edwards
        return fl.shear_rate_now * float(fl.frame_box[1])

    # ------------------------------------------------------------------ beads
    def offsets(self) -> np.ndarray:
        """Space-frame r_k = R(q_g) r_k^B (N, 3)."""
        return quat.rotate(self.state.q[self.body], self.body_positions)

    def set_bead_velocities(self, p, r=None):
        r = self.offsets() if r is None else r
        s = self.state
        p.v[:] = s.v[self.body] + np.cross(s.omega[self.body], r)
        if self.lees_edwards is not None:
            p.v[:, 0] -= self.image * self._le_rate_jump()
        p.omega[:] = s.omega[self.body]

    def place_beads(self, p):
        """Bead positions, orientations and velocities from the bodies (x_k = R_g + r_k)."""
        r = self.offsets()
        s = self.state
        p.R_raw[:] = s.R_raw[self.body] + r
        if self.lees_edwards is not None:
            X = s.R[self.body] + r
            Ly = float(self.lees_edwards.frame_box[1])
            self.image = np.floor(X[:, 1] / Ly)
            X[:, 0] -= self.image * self.lees_edwards.image_offset
            X[:, 1] -= self.image * Ly
            p.R[:] = np.mod(X, self.box)
        else:
            p.R[:] = np.mod(s.R[self.body] + r, self.box)
        p.R[p.R >= self.box] = 0.0
        p.q_old[:] = p.q
        p.q[:] = s.q[self.body]
        self.set_bead_velocities(p, r)

    # ------------------------------------------------------------------ SPM motion
    def update_velocities(self, p, F_H, T_H, F_other, T_other, dt, rotation, dP_noise=None,
                          dL_noise=None, mass=None, inertia=None, first=False):
        """Body V, Omega from the summed bead forces (module docstring); bead v, omega."""
        # stores the bead forces, v_old, omega_old (the free bead velocities are overwritten)
        _free_velocities(p, F_H, T_H, F_other, T_other, dt, rotation, dP_noise, dL_noise,
                         first=first)
        m = p.mass if mass is None else np.asarray(mass, dtype=float)
        Ik = p.inertia if inertia is None else np.asarray(inertia, dtype=float)
        b, nb, s = self.body, self.nb, self.state
        r = self.offsets()
        F_Hg = _sum(b, p.f_hydro, nb)
        F_og = _sum(b, p.f_r, nb)
        T_Hg = _sum(b, np.cross(r, p.f_hydro) + p.torque_hydro, nb)
        T_og = _sum(b, np.cross(r, p.f_r) + p.torque_r, nb)
        for name, new in (("f_hydro", F_Hg), ("torque_hydro", T_Hg), ("f_r", F_og),
                          ("torque_r", T_og)):
            getattr(s, name + "_previous")[...] = getattr(s, name)
            getattr(s, name)[...] = new
        s.v_old[...] = s.v
        s.omega_old[...] = s.omega
        M = np.bincount(b, m, minlength=nb)
        dPg = (F_Hg + F_og) * dt
        if dP_noise is not None:
            dPg += _sum(b, dP_noise, nb)
        v = s.v + dPg / M[:, None]
        s.v[:] = np.where(self.free_v, v, self.v_fixed)
        om = s.omega
        if rotation:
            I = inertia_tensors(b, nb, m, Ik, r)
            dL = (T_Hg + T_og - np.cross(s.omega, np.einsum("gij,gj->gi", I, s.omega))) * dt
            if dL_noise is not None:
                dL += _sum(b, np.cross(r, dP_noise) + dL_noise, nb)
            om = s.omega + np.linalg.solve(I, dL[:, :, None])[:, :, 0]
        s.omega[:] = np.where(self.free_o, om, self.o_fixed)
        self.set_bead_velocities(p, r)
        return p

    def update_positions(self, p, dt, box, rotation, first=False):
        """R_g by Crank-Nicolson, q_g by the step's mean Omega; beads placed rigidly."""
        s = self.state
        dR = 0.5 * dt * (s.v_old + s.v)
        s.R_raw += dR
        if self.lees_edwards is not None:
            from ..fluid.oblique import lees_edwards_wrap
            fl = self.lees_edwards
            s.R += dR
            lees_edwards_wrap(s.R, s.v, fl.frame_box, fl.image_offset, fl.shear_rate_now,
                              s.v_old)
        else:
            s.R[:] = np.mod(s.R + dR, self.box)
            s.R[s.R >= self.box] = 0.0
        s.q_old[...] = s.q
        s.q[...] = quat.integrate(s.q, 0.5 * (s.omega_old + s.omega), dt)
        self.place_beads(p)
        return p

    # ------------------------------------------------------------------ distributed
    # a distributed run (kapsel.parallel.particles, kapsel.particles.spm ``_own``): a body
    # is owned, with all its beads, by the rank owning its first bead; each bead's record
    # carries the state of its body (BODY_FIELDS) and its Lees-Edwards image count
    BODY_FIELDS = tuple((name, 3) for name in VECTOR_FIELDS) + (("q", 4), ("q_old", 4))
    RECORD_WIDTH = sum(w for _, w in BODY_FIELDS) + 1

    def first_beads(self) -> np.ndarray:
        """Index of the first bead of every body (B,)."""
        first = np.full(self.nb, len(self.body))
        np.minimum.at(first, self.body, np.arange(len(self.body)))
        return first

    def span(self) -> float:
        """The largest distance of a bead from its body's first bead (any orientation)."""
        if not len(self.body):
            return 0.0
        d = self.body_positions - self.body_positions[self.first_beads()][self.body]
        return float(np.sqrt(np.einsum("nk,nk->n", d, d).max()))

    def bead_records(self) -> np.ndarray:
        """(N, RECORD_WIDTH): the state of each bead's body, then the bead's image count."""
        out = np.empty((len(self.body), self.RECORD_WIDTH))
        c = 0
        for name, w in self.BODY_FIELDS:
            out[:, c:c + w] = getattr(self.state, name)[self.body]
            c += w
        out[:, c] = self.image
        return out

    def take_records(self, beads, records) -> None:
        """Set the state of the bodies of ``beads`` (global bead indices, whole bodies) and
        the beads' image counts from their ``records`` (bead_records rows)."""
        beads = np.asarray(beads, dtype=np.int64)
        bodies, first = np.unique(self.body[beads], return_index=True)
        c = 0
        for name, w in self.BODY_FIELDS:
            getattr(self.state, name)[bodies] = records[first, c:c + w]
            c += w
        self.image[beads] = records[:, c]

    def local(self, beads, records) -> "RigidBodies":
        """The bodies of ``beads`` (global bead indices, sorted, whole bodies) as a
        RigidBodies of their own (body index 0.. in order, bead rows as ``beads``), their
        state from the beads' ``records`` (bead_records rows of the bodies' owner)."""
        beads = np.asarray(beads, dtype=np.int64)
        sub = object.__new__(RigidBodies)
        bodies, first, inverse = np.unique(self.body[beads], return_index=True,
                                           return_inverse=True)
        sub.body = inverse.reshape(-1).astype(np.int64)
        sub.nb = len(bodies)
        sub.global_bodies = bodies
        sub.body_positions = self.body_positions[beads]
        sub.bead_mass = self.bead_mass[beads]
        sub.bead_inertia = self.bead_inertia[beads]
        sub.box = self.box
        for name in ("free_v", "free_o", "v_fixed", "o_fixed", "masses", "moments_body"):
            setattr(sub, name, getattr(self, name)[bodies])
        s = self.state
        sub.state = ParticleState(n=sub.nb, species=s.species[bodies],
                                  radius=s.radius[bodies], mass=s.mass[bodies],
                                  inertia=s.inertia[bodies])
        sub.lees_edwards = self.lees_edwards
        sub.image = np.zeros(len(beads))
        sub.take_records(np.arange(len(beads)), records)
        return sub

    # ------------------------------------------------------------------ restart
    def restart_items(self) -> dict:
        """The restart schema's GR_body[] (N, 3), GR_masses[] (B,), GR_moments_body[] (B, 9)."""
        return {"GR_body": self.body_positions.copy(), "GR_masses": self.masses.copy(),
                "GR_moments_body": self.moments_body.reshape(-1, 9).copy()}

    def exact_items(self) -> dict:
        """The body state by name ('rigid_<field>'), for a bit-identical continuation."""
        s = self.state
        return {f"rigid_{k}": getattr(s, k).copy() for k in VECTOR_FIELDS + ("q", "q_old")}

    def restore(self, p, exact=None):
        """Body state after the beads ``p`` were read back from a restart: from
        ``exact_items`` when given, else from the beads (q and Omega of each body's first
        bead, V the mass-weighted mean bead velocity, R_g the centre of the beads)."""
        s = self.state
        if exact and all(k in exact for k in self.exact_items()):
            for k, v in self.exact_items().items():
                getattr(s, k[len("rigid_"):])[...] = exact[k]
            return
        first = np.full(self.nb, len(self.body))
        np.minimum.at(first, self.body, np.arange(len(self.body)))
        m, b, nb = self.bead_mass, self.body, self.nb
        s.q[:] = quat.normalise(p.q[first])
        s.q_old[:] = quat.normalise(p.q_old[first])
        s.omega[:] = p.omega[first]
        s.omega_old[:] = p.omega_old[first]
        if self.lees_edwards is not None:     # centre from the first bead, through the images
            from ..fluid.oblique import lees_edwards_wrap
            fl = self.lees_edwards
            X = p.R[first] - self.offsets()[first]
            lees_edwards_wrap(X, np.zeros_like(X), fl.frame_box, fl.image_offset, 0.0)
            s.R[:] = X
            self._set_images()                # the beads' velocities are at their own images
        for k in ("v", "v_old"):
            v = getattr(p, k).copy()
            if self.lees_edwards is not None:
                v[:, 0] += self.image * self._le_rate_jump()
            getattr(s, k)[:] = _sum(b, m[:, None] * v, nb) / self.masses[:, None]
        est = p.R_raw - self.offsets()                 # each bead's idea of its centre
        est = est[first][b] + minimum_image(est - est[first][b], self.box)
        s.R_raw[:] = _sum(b, m[:, None] * est, nb) / self.masses[:, None]
        if self.lees_edwards is None:
            s.R[:] = np.mod(s.R_raw, self.box)
        r = self.offsets()
        s.f_hydro[:] = _sum(b, p.f_hydro, nb)
        s.f_r[:] = _sum(b, p.f_r, nb)
        s.torque_hydro[:] = _sum(b, np.cross(r, p.f_hydro) + p.torque_hydro, nb)
        s.torque_r[:] = _sum(b, np.cross(r, p.f_r) + p.torque_r, nb)

    # ------------------------------------------------------------------ diagnostics
    def inertia_space(self) -> np.ndarray:
        """I_g = R(q) I_g^B R(q)^T (B, 3, 3) (eq 4)."""
        Rm = quat.to_matrix(self.state.q)
        return np.einsum("gij,gjk,glk->gil", Rm, self.moments_body, Rm)

    def rotational_energies(self) -> np.ndarray:
        """E_rot,g = 1/2 Omega_g . I_g Omega_g (B,) (spec 002 eqs 3-6)."""
        from ..analysis.rotational_energy import rotational_energy_body
        if self.nb == 0:
            return np.zeros(0)
        moments, axes = np.linalg.eigh(self.moments_body)
        axes[:, :, 2] *= np.sign(np.linalg.det(axes))[:, None]
        Rm = np.einsum("gij,gjk->gik", quat.to_matrix(self.state.q), axes)
        return np.atleast_1d(rotational_energy_body(self.state.omega, moments, Rm))


def build_bodies(cfg, p, rng) -> RigidBodies:
    """The bodies of ``cfg`` (object_type rigid) over the beads ``p`` (species, masses set);
    places the beads.  ValueError when they cannot be placed.

    switch.INIT_distribution user_specify: the Particles[] positions of the beads give each
    body's shape and place (body frame = that configuration, q = identity; the free
    velocity components start at the mean of the beads' v and omega); INIT_orientation
    random turns each body about its centre by a random rotation, space_align and
    user_specify keep the positions as given.  uniform_random / random_walk: straight rods
    of touching beads (``rod_shape``) at random non-overlapping places, along x
    (space_align, and user_specify without user positions, as table 7) or randomly oriented.
    """
    spec = cfg.particles.species
    A = cfg.particles.A
    box = np.asarray(cfg.mesh.box, dtype=float)
    counts = [s.number for s in spec]
    body_species = np.repeat(np.arange(len(spec)), counts)
    beads = np.repeat(np.array([s.beads for s in spec], dtype=np.int64), counts)
    nbodies = len(body_species)
    body = np.repeat(np.arange(nbodies), beads)
    free_v = np.array([[s.rigid_motion == "free"] * 3 for s in spec], dtype=bool)
    free_o = free_v.copy()
    for sid, vel, om in cfg.switches.free_rigid:
        free_v[sid], free_o[sid] = vel, om
    v_fixed = np.array([s.rigid_velocity for s in spec], dtype=float).reshape(-1, 3)
    o_fixed = np.array([s.rigid_omega for s in spec], dtype=float).reshape(-1, 3)
    per_body = dict(free_v=free_v[body_species], free_o=free_o[body_species],
                    v_fixed=v_fixed[body_species], o_fixed=o_fixed[body_species])
    kind, okind = cfg.switches.init_distribution, cfg.switches.init_orientation
    if kind != "user_specify" and beads.max() * 2.0 * A > box.min():
        # (kapsel.config refuses it first; user_specify shapes are checked by their extent)
        raise ValueError(f"a rigid body of {int(beads.max())} beads of radius {A:g} does not "
                         f"fit in the box {' x '.join(f'{x:g}' for x in box.tolist())}")
    if kind == "user_specify":
        user = cfg.switches.user_particles[:p.n]
        bodies = RigidBodies.from_beads(user[:, 0:3], body, p.mass, p.inertia, body_species,
                                        box=box, **per_body)
        s = bodies.state
        nb = np.bincount(body, minlength=nbodies)[:, None]
        s.v[:] = np.where(bodies.free_v, _sum(body, user[:, 3:6], nbodies) / nb, s.v)
        s.omega[:] = np.where(bodies.free_o, _sum(body, user[:, 10:13], nbodies) / nb,
                              s.omega)
        if okind == "random":
            from .placement import orientations
            s.q[:] = orientations("random", nbodies, rng)
            s.q_old[:] = s.q
    else:
        from .placement import orientations
        q = orientations("random" if okind == "random" else "space_align", nbodies, rng)
        shape = np.concatenate([rod_shape(int(k), A) for k in beads])
        offsets = quat.rotate(q[body], shape)
        starts = np.concatenate([[0], np.cumsum(beads)[:-1]])
        from .walls import clear_slab
        R = place_bodies(np.split(offsets, starts[1:]), A, box, rng, slab=clear_slab(cfg))
        bodies = RigidBodies(body, shape, p.mass, p.inertia, body_species, R, q, box=box,
                             **per_body)
    bodies.place_beads(p)
    p.q_old[:] = p.q
    return bodies
