"""Rigid bodies made of spherical beads (object_type ``rigid``, ``Rigid_spec[]``), as the
original moves them (rigid.h, particle_solver.cxx, particle_rotation_solver.h).

Every bead is an SPM particle (its own profile phi_i, momentum exchange F_H,i, N_H,i); the
beads of a body move together.  Species by species, body by body, the Beads_number beads of
a body are consecutive particles.  All operations are whole-array numpy over beads / bodies.

Body set-up (init_particle.cxx Init_Particle, rigid.h init_*; g a body, k its beads, x_k the
bead positions, unwrapped by the minimum image about the body's first bead):

* user_specify (and Quincke rollers placed at random): the mass, centre and inertia tensor
  are the integrals of the profiles over the grid, overlapping beads sharing a node
  (w_k = phi_k / max(sum_all phi, 1), make_phi.cxx Make_phi_rigid_mass / _inertia):
      M_g = RHO_p DX^3 sum_k sum_x w_k,   R_g = X_g + sum w_k (x_k - X_g + r) / sum w_k
      I_g = RHO_p DX^3 sum_k sum_x w_k (|d|^2 1 - d d^T),  d = x_k - R_g + r
  with X_g the mean bead position, r the stencil offset from the bead centre and
  RHO_p = MASS_RATIO RHO; beads of one body may overlap (ex10's arch);
* generated rods (uniform_random / random_walk, straight rods of touching beads): the
  nominal M_g = sum_k m_k, I_g = sum_k (I_k 1 + m_k (|d|^2 1 - d d^T)) with
  m_k = MASS_RATIO RHO 4/3 pi A^3, I_k = 2/5 m_k A^2 (rigid.h set_Rigid_MMs);
* the body frame: the principal axes of I_g by the original's Jacobi diagonalisation
  (kapsel.particles.principal_axes), q_g its quaternion; with switch.quincke ON (one-bead
  bodies) q_g is the bead's orientation instead (user_specify q, identity, or a random
  rotation about the field axis: quaternion.h get_quaternion_xy_random_Quincke);
  I_g^B = R(q)^T I_g R(q) (its diagonal is used), r_k^B = R(q)^T (x_k - R_g) (the restart's
  GR_body[]);
* V_g = Rigid_velocity (space frame), Omega_g = R(q) Rigid_omega (Rigid_omega is body-frame),
  for ``free`` and ``fix`` bodies alike (input.cxx, rigid.h init_set_vGs); the beads keep the
  given positions, v_k = V_g + Omega_g x r_k, omega_k = Omega_g.

One SPM step (spm.SPM calls update_positions, then, after the forces at the new positions,
update_velocities; ``first``: the run's step 0):

* positions (rigid.h solver_Rigid_Position): R_g += dt V_g (first) or dt/2 (3 V_g - V_g^old),
  q_g by the additive quaternion Euler / Adams-Bashforth step with the space-frame Omega
  (quaternion.euler_step / ab2_step), r_k = R(q_g) r_k^B, x_k = R_g + r_k (wrapped),
  v_k = V_g + Omega_g x r_k, omega_k = Omega_g;
* forces about the centre of mass, F_g = sum_k F_H,k, T_g = sum_k (r_k x F_H,k + N_H,k)
  (md_force.cxx Calc_f_hydro_correct_precision) and the other forces likewise, plus the net
  gravity G RHO (M_g / RHO_p)(MASS_RATIO - 1) of the body (md_force.cxx Add_f_gravity: the
  bead-level gravity is not applied to rigid beads, kapsel.models.common.make_forces);
* velocities (rigid.h calc_Rigid_VOGs): V_g += dt/M_g (F_H + F_o) (first) or
  dt/(2 M_g) (2 F_H + F_o + F_o^prev), free components only (``fix`` and switch.free_rigid
  NO components keep their value); Omega by Euler's equations in the body frame with the
  diagonal of I_g^B (particle_rotation_solver.h MD_solver_omega_Euler / _AB2):
      w_b = R(q)^T Omega,  t_b = R(q)^T (T_H + T_o)   (first)
      w_b,i += dt/I_i (t_b,i + (I_j - I_k) w_b,j w_b,k)
  or, after the first step, with t_b = R(q)^T (2 T_H + T_o) + R(q^old)^T T_o^prev and
  dt/(2 I_i) (t_b,i + 2 (I_j - I_k) w_b,j w_b,k); only the free components (switch.free_rigid
  DOF omega flags act in the *body* frame, as in the original), then Omega = R(q) w_b;
* thermal impulses (fluct.cxx, rigid branch): V_g += sum_k dP_k / M_g,
  Omega_g += I_g^-1 sum_k (dL_k + r_k x dP_k) (space frame, free components by the space
  axes, as the original); then the beads' v_k, omega_k.

The body rotates whatever switch.ROTATION says (the original's rigid solvers do not read
it).  Pair forces between beads of the same body are not computed (forces.pair_forces
group=).  ``state`` is a ParticleState with one row per body (R, R_raw, v, q, omega and the
summed forces / torques of the last step): the RigidParticles[] records.  Its ``inertia`` is
trace(I_g^B) / 3, a scalar stand-in; the tensors are ``moments_body``.  The rotational energy
of every body, 1/2 Omega_g . I_g Omega_g (spec 002 eq 3; eq 6 when the three principal
moments agree) is ``rotational_energies()``.
"""
from __future__ import annotations

import numpy as np

from . import quaternion as quat
from .cells import minimum_image
from .principal_axes import principal_frame
from .state import VECTOR_FIELDS, ParticleState

__all__ = ["RigidBodies", "rod_shape", "place_bodies", "inertia_tensors", "grid_integrals",
           "build_bodies"]

_FORCES = ("f_hydro", "torque_hydro", "f_r", "torque_r")


def _sum(body, values, nb):
    """Per-body sums of per-bead rows (N, k) -> (B, k)."""
    values = np.asarray(values, dtype=float)
    return np.stack([np.bincount(body, values[:, a], minlength=nb)
                     for a in range(values.shape[1])], axis=1)


def inertia_tensors(body, nb, mass, inertia, r):
    """Space-frame I_g (B, 3, 3) of beads of masses ``mass``, own moments ``inertia`` at
    offsets ``r`` (N, 3) from their body's centre of mass (rigid.h set_Rigid_MMs)."""
    r2 = np.einsum("nk,nk->n", r, r)
    per = (mass * r2 + inertia)[:, None, None] * np.eye(3) - \
        mass[:, None, None] * r[:, :, None] * r[:, None, :]
    return _sum(body, per.reshape(-1, 9), nb).reshape(nb, 3, 3)


def grid_integrals(X, body, nb, rho_p, A, xi, dx, shape):
    """(M (B,), R_g (B, 3), I_g (B, 3, 3) space frame) of bodies whose beads sit at the
    unwrapped positions X (N, 3), from their profiles on the grid, overlapping beads sharing
    a node by phi_k / max(phi_sum, 1) (module docstring; make_phi.cxx Make_phi_rigid_mass /
    Make_phi_rigid_inertia).  rho_p (B,): MASS_RATIO RHO of each body."""
    from .profile import Stencil, particle_profiles
    box = np.asarray(shape, dtype=float) * dx
    idx, phi, r = particle_profiles(np.mod(X, box), Stencil(A, xi, dx), tuple(shape), dx)
    phi_sum = np.bincount(idx.ravel(), weights=phi.ravel(), minlength=int(np.prod(shape)))
    w = phi / np.maximum(phi_sum[idx], 1.0)                     # (N, S)
    trial = _sum(body, X, nb) / np.bincount(body, minlength=nb)[:, None]
    wk = w.sum(axis=1)
    vol = np.bincount(body, wk, minlength=nb)
    gr = X - trial[body]                                        # about the trial centre
    first = _sum(body, gr * wk[:, None] + np.einsum("ns,nsk->nk", w, r), nb)
    R = trial + first / vol[:, None]
    d = (X - R[body])[:, None, :] + r                           # (N, S, 3) about R_g
    dd = np.einsum("ns,nsa,nsb->nab", w, d, d)
    per = np.einsum("nkk->n", dd)[:, None, None] * np.eye(3) - dd
    scale = np.asarray(rho_p, dtype=float) * dx ** 3
    I = _sum(body, per.reshape(-1, 9), nb).reshape(nb, 3, 3) * scale[:, None, None]
    return vol * scale, R, I


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


def _wrap(R, box):
    """R into [0, L) (in place)."""
    np.mod(R, box, out=R)
    R[R >= box] = 0.0
    return R


class RigidBodies:
    """Rigid bodies of beads (see module docstring); the motion of spm.SPM for them.

    body (N,): body index of every bead (bodies numbered 0..B-1, beads of a body
    consecutive); body_positions (N, 3): r_k^B about each body's centre of mass, in its body
    frame; masses (B,) M_g; moments_body (B, 3, 3) I_g^B (principal: its diagonal is used);
    species (B,): Rigid_spec index of each body; R_raw (B, 3) unwrapped centres; q (B, 4);
    v, omega (B, 3) space-frame initial velocities; free_v (B, 3) bool: free velocity
    components (space frame); free_o (B, 3) bool: free angular-velocity components (body
    frame); gravity (B, 3): the net gravity on each body (or None).
    """

    def __init__(self, body, body_positions, masses, moments_body, species, R_raw, q, v,
                 omega, free_v, free_o, box, gravity=None):
        self.body = np.asarray(body, dtype=np.int64)
        self.nb = int(self.body.max()) + 1 if len(self.body) else 0
        self.body_positions = np.asarray(body_positions, dtype=float)
        self.masses = np.asarray(masses, dtype=float).reshape(self.nb)
        self.moments_body = np.asarray(moments_body, dtype=float).reshape(self.nb, 3, 3)
        self.box = np.asarray(box, dtype=float)
        self.free_v = np.asarray(free_v, dtype=bool).reshape(self.nb, 3)
        self.free_o = np.asarray(free_o, dtype=bool).reshape(self.nb, 3)
        self.gravity = (np.zeros((self.nb, 3)) if gravity is None
                        else np.asarray(gravity, dtype=float).reshape(self.nb, 3))
        s = ParticleState(n=self.nb, species=np.asarray(species, dtype=np.int64),
                          radius=np.zeros(self.nb), mass=self.masses.copy(),
                          inertia=np.trace(self.moments_body, axis1=1, axis2=2) / 3.0)
        s.R_raw[:] = R_raw
        s.R[:] = _wrap(np.array(R_raw, dtype=float), self.box)
        s.q[:] = quat.normalise(q)
        s.q_old[:] = s.q
        s.v[:] = v
        s.v_old[:] = s.v
        s.omega[:] = omega
        s.omega_old[:] = s.omega
        self.state = s
        self.lees_edwards = None          # the oblique fluid under Lees-Edwards images
        self.image = np.zeros(len(self.body))
        self.gravity_of = None            # masses -> net gravity (build_bodies), for a restart

    @classmethod
    def assemble(cls, X, body, species, masses, centres, inertia, q, v, omega_body, free_v,
                 free_o, box, gravity=None):
        """Bodies of beads at the unwrapped positions X (N, 3) with masses (B,), centres of
        mass (B, 3) and space-frame inertia tensors I_g (B, 3, 3) at that configuration, in
        the body frames ``q`` (B, 4) (None: the principal axes of I_g); ``omega_body`` (B, 3)
        the body-frame angular velocities (Rigid_omega), ``v`` (B, 3) space-frame."""
        body = np.asarray(body, dtype=np.int64)
        inertia = np.asarray(inertia, dtype=float)
        if q is None:
            Rm = principal_frame(inertia)
            q = quat.from_matrix(Rm)
        Rm = quat.to_matrix(q)
        Ib = np.einsum("gji,gjk,gkl->gil", Rm, inertia, Rm)
        gr = np.asarray(X, dtype=float) - np.asarray(centres, dtype=float)[body]
        rb = np.einsum("nji,nj->ni", Rm[body], gr)
        omega = np.einsum("gij,gj->gi", Rm, np.asarray(omega_body, dtype=float))
        return cls(body, rb, masses, Ib, species, centres, q, v, omega, free_v, free_o, box,
                   gravity)

    @classmethod
    def nominal(cls, body, shape, bead_mass, bead_inertia, species, R, q, free_v, free_o,
                v_fixed, o_fixed, box, gravity=None):
        """Bodies of beads at R_g + R(q) shape_k (``shape`` (N, 3), ``q`` (B, 4) the placing
        rotation, R (B, 3) the centres) with the nominal masses and moments of the beads
        (module docstring: generated rods), their principal body frames, V = v_fixed and the
        body-frame Omega = o_fixed."""
        body = np.asarray(body, dtype=np.int64)
        nb = int(body.max()) + 1
        m = np.asarray(bead_mass, dtype=float)
        q = quat.normalise(np.asarray(q, dtype=float).reshape(nb, 4))
        shape = np.asarray(shape, dtype=float)
        com = _sum(body, m[:, None] * shape, nb) / np.bincount(body, m, minlength=nb)[:, None]
        off = quat.rotate(q[body], shape - com[body])
        R = np.asarray(R, dtype=float).reshape(nb, 3)
        M = np.bincount(body, m, minlength=nb)
        I = inertia_tensors(body, nb, m, np.asarray(bead_inertia, dtype=float), off)
        return cls.assemble(R[body] + off, body, species, M, R, I, None, v_fixed, o_fixed,
                            free_v, free_o, box, gravity)

    # ------------------------------------------------------------------ Lees-Edwards
    def use_lees_edwards(self, fluid):
        """Lees-Edwards images (PHYSICS-EXTRA.md §7) of the oblique ``fluid`` (its
        frame_box, image_offset, shear_rate_now): the centre of mass is wrapped by the
        Lees-Edwards rule, its x velocity (and the stored old one) shifted by the boundary
        velocity jump gamma_dot Ly at a crossing of the y boundary; each bead x_k = R_g + r_k
        is wrapped by the same rule on its own, its image count n_k (-1, 0, 1: across which
        y boundary from its centre of mass) kept in ``image``, and its velocity is
        V_g + Omega_g x r_k - n_k gamma_dot Ly e_x: the velocity of the body at the bead's
        image, continuous relative to the imposed flow (rigid.h
        update_Particle_Configuration_OBL).  Sets the images of the beads where they are
        and their velocities (positions unchanged)."""
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
        """v_k = V_g + Omega_g x r_k (minus the image's velocity jump), omega_k = Omega_g."""
        r = self.offsets() if r is None else r
        s = self.state
        p.v[:] = s.v[self.body] + np.cross(s.omega[self.body], r)
        if self.lees_edwards is not None:
            p.v[:, 0] -= self.image * self._le_rate_jump()
        p.omega[:] = s.omega[self.body]

    def place_beads(self, p):
        """Bead positions, orientations and velocities from the bodies (x_k = R_g + r_k);
        the beads' v_old / omega_old take their velocities before."""
        r = self.offsets()
        s = self.state
        p.R_raw[:] = s.R_raw[self.body] + r
        if self.lees_edwards is not None:
            X = s.R[self.body] + r
            Ly = float(self.lees_edwards.frame_box[1])
            self.image = np.floor(X[:, 1] / Ly)
            X[:, 0] -= self.image * self.lees_edwards.image_offset
            X[:, 1] -= self.image * Ly
            p.R[:] = _wrap(X, self.box)
        else:
            p.R[:] = _wrap(s.R[self.body] + r, self.box)
        p.q_old[:] = s.q_old[self.body]
        p.q[:] = s.q[self.body]
        p.v_old[:] = p.v
        p.omega_old[:] = p.omega
        self.set_bead_velocities(p, r)

    # ------------------------------------------------------------------ SPM motion
    def update_positions(self, p, dt, box, rotation, first=False, wrap_box=True):
        """R_g, q_g by Euler (first step) or Adams-Bashforth; beads placed rigidly (module
        docstring).  ``rotation`` is not read (the original turns rigid bodies always)."""
        s = self.state
        if first:
            dR = dt * s.v
            q = quat.euler_step(s.q, s.omega, dt)
        else:
            dR = (0.5 * dt) * (3.0 * s.v - s.v_old)
            q = quat.ab2_step(s.q, s.q_old, s.omega, s.omega_old, dt)
        s.R_raw += dR
        s.R += dR
        if self.lees_edwards is not None:
            from ..frame import lees_edwards_wrap
            fl = self.lees_edwards
            lees_edwards_wrap(s.R, s.v, fl.frame_box, fl.image_offset, fl.shear_rate_now,
                              s.v_old)
        else:
            _wrap(s.R, self.box)
        s.q_old[...] = s.q
        s.q[...] = q
        self.place_beads(p)
        return p

    def update_velocities(self, p, F_H, T_H, F_other, T_other, dt, rotation, dP_noise=None,
                          dL_noise=None, first=False):
        """Body V, Omega from the summed bead forces (module docstring); bead v, omega.
        The beads keep their own F_H, N_H and other forces (the records' Particles[])."""
        n = p.n
        zeros = np.zeros((n, 3))
        bead = {"f_hydro": F_H, "torque_hydro": T_H, "f_r": F_other, "torque_r": T_other}
        for name, new in bead.items():
            getattr(p, name + "_previous")[...] = getattr(p, name)
            getattr(p, name)[...] = zeros if new is None else new
        b, nb, s = self.body, self.nb, self.state
        r = self.offsets()
        new = {"f_hydro": _sum(b, p.f_hydro, nb),
               "torque_hydro": _sum(b, np.cross(r, p.f_hydro) + p.torque_hydro, nb),
               "f_r": _sum(b, p.f_r, nb) + self.gravity,
               "torque_r": _sum(b, np.cross(r, p.f_r) + p.torque_r, nb)}
        for name in _FORCES:
            getattr(s, name + "_previous")[...] = getattr(s, name)
            getattr(s, name)[...] = new[name]
        s.v_old[...] = s.v
        s.omega_old[...] = s.omega
        im = (1.0 / self.masses)[:, None]
        Ib = np.einsum("gii->gi", self.moments_body)
        Rm = quat.to_matrix(s.q)
        wb = np.einsum("gji,gj->gi", Rm, s.omega)
        cyc = ([1, 2, 0], [2, 0, 1])              # (j, k) of every i: (I_j - I_k) w_j w_k
        euler = (Ib[:, cyc[0]] - Ib[:, cyc[1]]) * wb[:, cyc[0]] * wb[:, cyc[1]]
        if first:
            dv = (dt * im) * (s.f_hydro + s.f_r)
            tb = np.einsum("gji,gj->gi", Rm, s.torque_hydro + s.torque_r)
            dw = (dt / Ib) * (tb + euler)
        else:
            h = 0.5 * dt
            dv = (h * im) * (2.0 * s.f_hydro + s.f_r + s.f_r_previous)
            tb = np.einsum("gji,gj->gi", Rm, 2.0 * s.torque_hydro + s.torque_r)
            tb += np.einsum("gji,gj->gi", quat.to_matrix(s.q_old), s.torque_r_previous)
            dw = (h / Ib) * (tb + 2.0 * euler)
        s.v += np.where(self.free_v, dv, 0.0)
        wb += np.where(self.free_o, dw, 0.0)
        s.omega[...] = np.einsum("gij,gj->gi", Rm, wb)
        if dP_noise is not None:
            dP = np.asarray(dP_noise, dtype=float)
            dL = np.zeros_like(dP) if dL_noise is None else np.asarray(dL_noise, dtype=float)
            s.v += np.where(self.free_v, _sum(b, dP, nb) * im, 0.0)
            L = _sum(b, dL + np.cross(r, dP), nb)
            s.omega += np.where(self.free_o,
                                np.linalg.solve(self.inertia_space(), L[:, :, None])[:, :, 0],
                                0.0)
        self.set_bead_velocities(p, r)
        return p

    # ------------------------------------------------------------------ distributed
    # a distributed run (kapsel.particles.ownership, kapsel.particles.spm ``_own``): a body
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
        sub.box = self.box
        for name in ("free_v", "free_o", "masses", "moments_body", "gravity"):
            setattr(sub, name, getattr(self, name)[bodies])
        s = self.state
        sub.state = ParticleState(n=sub.nb, species=s.species[bodies],
                                  radius=s.radius[bodies], mass=s.mass[bodies],
                                  inertia=s.inertia[bodies])
        sub.lees_edwards = self.lees_edwards
        sub.gravity_of = None
        sub.image = np.zeros(len(beads))
        sub.take_records(np.arange(len(beads)), records)
        return sub

    # ------------------------------------------------------------------ restart
    # The restart's Saved_Data.Particles[] holds one row per body, as the original writes it
    # (resume.cxx Save_Restart_udf: Get_Rigid_Particle_Data, then Save_Rigid_Particle_udf):
    # the body's centre R (R_raw unwrapped), V, V_old, Omega, Omega_old (space frame), q,
    # q_old and the summed forces and torques in the after-step convention (current 0, the
    # step's in *_previous: rigid.h calc_Rigid_VOGs resets them), then GR_body[] per bead,
    # GR_masses[] and GR_moments_body[] per body.
    def restart_rows(self) -> ParticleState:
        """The rows of the restart's Particles[]: the body state (one row per body)."""
        return self.state

    def restart_items(self) -> dict:
        """The restart schema's GR_body[] (N, 3), GR_masses[] (B,), GR_moments_body[] (B, 9)."""
        return {"GR_body": self.body_positions.copy(), "GR_masses": self.masses.copy(),
                "GR_moments_body": self.moments_body.reshape(-1, 9).copy()}

    def exact_items(self) -> dict:
        """The body state by name ('rigid_<field>'), for a bit-identical continuation (the
        state file: what an sParticle without R_raw or *_previous members cannot hold)."""
        s = self.state
        return {f"rigid_{k}": getattr(s, k).copy() for k in VECTOR_FIELDS + ("q", "q_old")}

    def restore_rows(self, p, fields=None, exact=None, raw=True):
        """Continue from a restart in the original's layout, ``state`` already read from its
        rows (one per body): the geometry GR_body[], GR_masses[], GR_moments_body[] of
        ``fields`` (resume.cxx Read_Rigid_Particle_udf; the net gravity follows the masses),
        the state file's body state over the rows when ``exact`` has it, else the
        quaternions normalised and, without an R_raw column (``raw`` False), R_raw = R, as
        the original reads them; then the beads ``p`` placed from the bodies
        (Set_Rigid_Particle_Data): x_k = R_g + R(q) r_k^B, q, v_k = V + Omega x r_k,
        omega_k = Omega, v_old and omega_old equal to them.

        The original's Set_Rigid_Particle_Data also sets the beads' omega_old to Omega and
        its first Adams-Bashforth quaternion step after the restore reads the first bead's
        omega_old, not the body's Omega_old (rigid.h solver_Rigid_Position): its continued
        run of a body whose Omega changes leaves its uninterrupted one.  kapsel-py turns
        the body with Omega_old of the row, as an uninterrupted run does."""
        fields = fields or {}
        nb, n = self.nb, len(self.body)
        for name, shape in (("GR_body", (n, 3)), ("GR_masses", (nb,)),
                            ("GR_moments_body", (nb, 9))):
            if name in fields and np.shape(fields[name]) != shape:
                raise ValueError(f"{name}[] has shape {np.shape(fields[name])}, the input's "
                                 f"{nb} rigid bodies of {n} beads need {shape}")
        s = self.state
        if "GR_body" in fields:
            self.body_positions = np.array(fields["GR_body"], dtype=float)
        if "GR_masses" in fields:
            self.masses = np.array(fields["GR_masses"], dtype=float)
            s.mass[:] = self.masses
            if self.gravity_of is not None:
                self.gravity = self.gravity_of(self.masses)
        if "GR_moments_body" in fields:
            self.moments_body = np.array(fields["GR_moments_body"],
                                         dtype=float).reshape(nb, 3, 3)
            s.inertia[:] = np.trace(self.moments_body, axis1=1, axis2=2) / 3.0
        if exact and all(k in exact for k in self.exact_items()):
            for k in self.exact_items():
                getattr(s, k[len("rigid_"):])[...] = exact[k]
        else:
            s.q[:] = quat.normalise(s.q)
            s.q_old[:] = quat.normalise(s.q_old)
            if not raw:
                s.R_raw[:] = s.R
        self.place_beads(p)
        p.v_old[:] = p.v
        p.omega_old[:] = p.omega
        for name in ("f_hydro", "torque_hydro", "f_r", "torque_r"):
            getattr(p, name)[:] = 0.0
            getattr(p, name + "_previous")[:] = 0.0

    def restore(self, p, exact=None):
        """Body state after the beads ``p`` were read back from a restart of kapsel-py before
        2026-12 (one Particles[] row per bead): from ``exact_items`` when given, else from
        the beads (q and Omega of each body's first
        bead, V = v_k - Omega x r_k averaged over the beads, R_g the centre of the beads)."""
        s = self.state
        if exact and all(k in exact for k in self.exact_items()):
            for k in self.exact_items():
                getattr(s, k[len("rigid_"):])[...] = exact[k]
            return
        first = self.first_beads()
        b, nb = self.body, self.nb
        m = np.ones(len(b))                # the beads' weights in the body's mean
        s.q[:] = quat.normalise(p.q[first])
        s.q_old[:] = quat.normalise(p.q_old[first])
        s.omega[:] = p.omega[first]
        s.omega_old[:] = p.omega_old[first]
        cnt = np.bincount(b, m, minlength=nb)[:, None]
        if self.lees_edwards is not None:     # centre from the first bead, through the images
            from ..frame import lees_edwards_wrap
            fl = self.lees_edwards
            X = p.R[first] - self.offsets()[first]
            lees_edwards_wrap(X, np.zeros_like(X), fl.frame_box, fl.image_offset, 0.0)
            s.R[:] = X
            self._set_images()                # the beads' velocities are at their own images
        for k in ("v", "v_old"):
            v = getattr(p, k).copy()
            if self.lees_edwards is not None:
                v[:, 0] += self.image * self._le_rate_jump()
            w = _sum(b, v - np.cross(getattr(p, "omega" if k == "v" else "omega_old"),
                                     self.offsets()), nb)
            getattr(s, k)[:] = w / cnt
        est = p.R_raw - self.offsets()                 # each bead's idea of its centre
        est = est[first][b] + minimum_image(est - est[first][b], self.box)
        s.R_raw[:] = _sum(b, est, nb) / cnt
        if self.lees_edwards is None:
            s.R[:] = _wrap(s.R_raw.copy(), self.box)
        r = self.offsets()
        s.f_hydro[:] = _sum(b, p.f_hydro, nb)
        s.f_r[:] = _sum(b, p.f_r, nb) + self.gravity
        s.torque_hydro[:] = _sum(b, np.cross(r, p.f_hydro) + p.torque_hydro, nb)
        s.torque_r[:] = _sum(b, np.cross(r, p.f_r) + p.torque_r, nb)
        for k in _FORCES:
            getattr(s, k + "_previous")[:] = getattr(s, k)

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


def _gravity(cfg, masses, rho_p):
    """The net gravity G RHO (M_g / RHO_p)(MASS_RATIO - 1) along G_direction (B, 3)
    (md_force.cxx Add_f_gravity, rigid branch)."""
    inter = cfg.interactions
    out = np.zeros((len(masses), 3))
    if inter.G == 0:
        return out
    axis = {"-X": 0, "-Y": 1, "-Z": 2}[inter.G_direction]
    rho = cfg.fluid.RHO
    out[:, axis] = -inter.G * rho * (masses / rho_p) * (rho_p / rho - 1.0)
    return out


def build_bodies(cfg, p, rng) -> RigidBodies:
    """The bodies of ``cfg`` (object_type rigid) over the beads ``p`` (species, masses set);
    places the beads (module docstring).  ValueError when they cannot be placed.

    switch.INIT_distribution user_specify: the Particles[] positions of the beads (their v
    and omega are not read: the bodies start with Rigid_velocity / Rigid_omega); the
    user's q only for Quincke rollers with INIT_orientation user_specify.  uniform_random /
    random_walk: straight rods of touching beads (``rod_shape``) at random non-overlapping
    places, along x (space_align, and user_specify without user positions, as table 7) or
    randomly oriented."""
    spec = cfg.particles.species
    A = cfg.particles.A
    dx = cfg.mesh.DX
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
    v0 = np.array([s.rigid_velocity for s in spec], dtype=float).reshape(-1, 3)
    w0 = np.array([s.rigid_omega for s in spec], dtype=float).reshape(-1, 3)
    rho_p = np.array([s.MASS_RATIO for s in spec], dtype=float)[body_species] * cfg.fluid.RHO
    per_body = dict(free_v=free_v[body_species], free_o=free_o[body_species])
    kind, okind = cfg.switches.init_distribution, cfg.switches.init_orientation
    quincke = getattr(cfg.switches, "quincke", None)
    if kind != "user_specify" and beads.max() * 2.0 * A > box.min():
        # (kapsel.config refuses it first; user_specify shapes are checked by their extent)
        raise ValueError(f"a rigid body of {int(beads.max())} beads of radius {A:g} does not "
                         f"fit in the box {' x '.join(f'{x:g}' for x in box.tolist())}")
    user = cfg.switches.user_particles[:p.n] if kind == "user_specify" else None
    if user is not None:
        X = np.asarray(user[:, 0:3], dtype=float)
        first = np.full(nbodies, len(X))
        np.minimum.at(first, body, np.arange(len(X)))
        X = X[first][body] + minimum_image(X - X[first][body], box)
    else:
        from .placement import orientations
        q_place = orientations("random" if okind == "random" else "space_align", nbodies, rng)
        shape = np.concatenate([rod_shape(int(k), A) for k in beads])
        offsets = quat.rotate(q_place[body], shape)
        starts = np.concatenate([[0], np.cumsum(beads)[:-1]])
        from .walls import clear_slab
        R = place_bodies(np.split(offsets, starts[1:]), A, box, rng, slab=clear_slab(cfg))
        X = R[body] + offsets
    q = None
    if quincke is not None:                   # one-bead bodies keep the beads' orientation
        if user is not None and okind == "user_specify":
            q = quat.normalise(np.asarray(user[:, 6:10], dtype=float))
        elif okind == "random":
            axis = int(np.argmax(np.abs(np.asarray(quincke.field_dir, dtype=float))))
            x = rng.random(nbodies) * 2.0 * np.pi
            q = np.zeros((nbodies, 4))
            q[:, 0] = np.cos(0.5 * x)
            q[:, 1 + axis] = np.sin(0.5 * x)
        else:
            q = quat.identity(nbodies)
    if user is not None or quincke is not None:
        M, R, I = grid_integrals(X, body, nbodies, rho_p, A, cfg.particles.A_XI, dx,
                                 cfg.mesh.shape)
    else:
        M = np.bincount(body, p.mass, minlength=nbodies)
        R = _sum(body, p.mass[:, None] * X, nbodies) / M[:, None]
        I = inertia_tensors(body, nbodies, p.mass, p.inertia, X - R[body])
    bodies = RigidBodies.assemble(X, body, body_species, M, R, I, q, v0[body_species],
                                  w0[body_species], box=box,
                                  gravity=_gravity(cfg, M, rho_p), **per_body)
    bodies.gravity_of = lambda masses: _gravity(cfg, masses, rho_p)
    p.R_raw[:] = X
    p.R[:] = _wrap(X.copy(), box)
    p.q[:] = bodies.state.q[body]
    p.q_old[:] = p.q
    bodies.set_bead_velocities(p)
    p.v_old[:] = p.v
    p.omega_old[:] = p.omega
    return bodies
