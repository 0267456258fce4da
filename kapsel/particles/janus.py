"""Self-propelled (Janus) spheres: TUMBLER, SQUIRMER, OBSTACLE (PHYSICS-EXTRA §3).

Per species (``object_type.spherical_particle.Particle_spec[]``, §3.1):

* ``janus_axis`` X / Y / Z: the propulsion axis e3 in the body frame (the particle's
  quaternion rotates it to the space frame, kapsel.particles.quaternion);
* ``janus_propulsion``
  - ``TUMBLER``: a body-frame self force ``janus_force`` and torque ``janus_torque``,
    F_self = R(q) janus_force, T_self = R(q) janus_torque (§3.5), added to the particle only
    (no momentum to the fluid);
  - ``SQUIRMER``: the surface slip of Blake's squirmer (§3.3),
        u_s = B1 (sin t + beta sin 2t) t^ + (C1 sin t + 3/2 C2 sin 2t) tau^,
    B1 = ``janus_slip_vel``, beta = ``janus_slip_mode`` / 2: the input is alpha = B2 / B1
    and the original halves it after reading, so u_theta = B1 sin t + B2 sin t cos t, the
    usual Blake mode (alpha < 0 pusher, alpha > 0 puller); C1 = ``janus_rotlet_C1``,
    C2 = ``janus_rotlet_dipole_C2`` (0 when the define file lacks them, as in the original);
    an isolated neutral squirmer swims at 2/3 B1 along +e3;
  - ``OBSTACLE``: velocity and angular velocity held at 0 (kapsel.particles.motion.Pinned);
    still in phi and the rigidity force, F_H still computed.
* ``switch.SLIP_tol``, ``switch.SLIP_iter``: the self-consistent slip iteration (§3.4).

The slip step (``Janus.update_velocities``, called by spm.SPM in place of the plain velocity
update; spectral fluids only, as the original: TUMBLER and SQUIRMER need Navier_Stokes or
Shear_Navier_Stokes and ROTATION ON).  With u the fluid velocity after the fluid step, for
each squirmer over its stencil (r about its centre), phi_i its profile and the shell weight
phi_s = (1 - phi_i) cos(pi (a - |r|) / XI) for | |r| - a | < XI/2 (0 elsewhere):

    M0 = sum phi, M1 = sum phi r, M2 = sum phi (|r|^2 I - r r); S0, S1, S2 likewise with phi_s;
    dP_s = sum phi_s (u_s - u), dL_s = sum phi_s r x (u_s - u).

From V* = V, Omega* = Omega, iterate: the counter-flow inside the particle
(dV, dOmega) carrying dP = -(S0 V* + Omega* x S1 + dP_s), dL = -(S1 x V* + S2 Omega* + dL_s)
([M2 + (M1 M1^T - |M1|^2 I)/M0] dOmega = dL - M1 x dP / M0, dV = (dP - dOmega x M1)/M0);
u' = sum_i phi_i (dV + dOmega x r) + phi_s (V* + Omega* x r + u_s - u), made solenoidal;
F_slip = RHO DX^3/dt sum phi_i u', T_slip = RHO DX^3/dt sum phi_i r x u' (every particle);
the velocity update of spm.SPM with F_H + F_slip + F_self (kapsel-py's explicit step, the
original's hydro/slip/self terms are explicit too); eps = max over squirmers of
sqrt(|V* - V|^2/|V|^2 + |Omega* - Omega|^2/|Omega|^2) (a ratio divided only where the norm
is > 0); stop when eps < SLIP_tol or after SLIP_iter passes, else V* <- 0.3 V* + 0.7 V
(Omega* likewise), V reset to its value before the update, and repeat.  Then u <- u + u'
(zero net momentum: the two parts cancel exactly) and spm.SPM imposes the rigidity with the
new V, Omega as usual.  ``iterations`` / ``unconverged`` count the passes of the last step
and the steps that hit SLIP_iter.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fluid.spectral import projection_kernels
from ..mesh import compiled as _compiled
from .coupling import clear_points, sample
from .quaternion import to_matrix

_compiled.provide("janus", __name__.rsplit(".", 1)[0] + ".janus_kernels")

__all__ = ["JanusSpec", "Janus", "read_spec", "check_types", "PROPULSIONS"]

PROPULSIONS = ("OFF", "TUMBLER", "SQUIRMER", "OBSTACLE")
AXES = {"X": 0, "Y": 1, "Z": 2}


@dataclass(frozen=True)
class JanusSpec:
    """The janus items of one Particle_spec (§3.1); slip_mode is the input's alpha = B2/B1."""
    axis: str = "NONE"
    propulsion: str = "OFF"
    force: tuple = (0.0, 0.0, 0.0)
    torque: tuple = (0.0, 0.0, 0.0)
    slip_vel: float = 0.0
    slip_mode: float = 0.0
    rotlet_C1: float = 0.0
    rotlet_C2: float = 0.0


def _vec3(r, path):
    v = r.get(path)
    if isinstance(v, dict):
        v = [v.get(k, 0.0) for k in ("x", "y", "z")]
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.size != 3 or not np.all(np.isfinite(v)):
        r.fail(path, list(v), "must be three finite numbers")
    return tuple(float(x) for x in v)


def read_spec(r, p: str, n: int) -> JanusSpec:
    """The janus items of Particle_spec ``p`` as the original reads them (§1.2): axis and
    propulsion (absent: NONE / OFF), force and torque only for TUMBLER, slip items only for
    SQUIRMER (rotlet C1 / C2 only if the define file declares them).  ``r``: config._Reader."""
    axis = r.get(f"{p}.janus_axis") if r.has(f"{p}.janus_axis") else "NONE"
    prop = r.get(f"{p}.janus_propulsion") if r.has(f"{p}.janus_propulsion") else "OFF"
    if axis not in ("NONE", "X", "Y", "Z"):
        r.fail(f"{p}.janus_axis", axis, "must be NONE, X, Y or Z")
    if prop not in PROPULSIONS:
        r.fail(f"{p}.janus_propulsion", prop, "must be OFF, TUMBLER, SQUIRMER or OBSTACLE")
    if prop == "TUMBLER":
        return JanusSpec(axis, prop, force=_vec3(r, f"{p}.janus_force"),
                         torque=_vec3(r, f"{p}.janus_torque"))
    if prop == "SQUIRMER":
        if axis == "NONE" and n > 0:
            r.fail(f"{p}.janus_axis", axis, "a SQUIRMER needs its swimming axis: X, Y or Z")
        b1 = r.get(f"{p}.janus_slip_vel")
        if n > 0 and not (np.isfinite(b1) and b1 > 0):
            r.fail(f"{p}.janus_slip_vel", b1, "B1 of a SQUIRMER must be positive")
        mode = r.get(f"{p}.janus_slip_mode")
        if not np.isfinite(mode):
            r.fail(f"{p}.janus_slip_mode", mode, "must be a finite number")
        c1 = float(r.get(f"{p}.janus_rotlet_C1")) if r.has(f"{p}.janus_rotlet_C1") else 0.0
        c2 = (float(r.get(f"{p}.janus_rotlet_dipole_C2"))
              if r.has(f"{p}.janus_rotlet_dipole_C2") else 0.0)
        return JanusSpec(axis, prop, slip_vel=float(b1), slip_mode=float(mode),
                         rotlet_C1=c1, rotlet_C2=c2)
    return JanusSpec(axis, prop)


def check_types(r, eq_type: str, rotation: bool, specs, counts, path: str) -> None:
    """§3.1: TUMBLER / SQUIRMER only with Navier_Stokes or Shear_Navier_Stokes and ROTATION
    ON (the original exits otherwise)."""
    active = [k for k, (s, n) in enumerate(zip(specs, counts))
              if s is not None and s.propulsion in ("TUMBLER", "SQUIRMER") and n > 0]
    if not active:
        return
    k = active[0]
    where = f"{path}[{k}].janus_propulsion"
    from ..typespec import names, spec
    if not spec(eq_type).self_propelled:           # §3.1 restrictions
        r.fail(where, specs[k].propulsion,
               f"self-propelled particles (TUMBLER, SQUIRMER) need constitutive_eq "
               f"{' or '.join(names(self_propelled=True))}, as in the original (not "
               f"{eq_type})")
    if not rotation:
        r.fail("switch.ROTATION", "OFF", "self-propelled particles (TUMBLER, SQUIRMER) need "
                                         "switch.ROTATION ON, as in the original")


_CYC = ((1, 2), (2, 0), (0, 1))


def _cross(a, b):
    """a x b over the last axis (broadcasting), without np.cross's overhead."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _norm(r):
    """|r| over the last axis, as the compiled kernels make it: sqrt((x x + y y) + z z)."""
    return np.sqrt((r[..., 0] * r[..., 0] + r[..., 1] * r[..., 1]) + r[..., 2] * r[..., 2])


def _second_moment(rr):
    """sum_s w (|r|^2 I - r r) per particle (N, 3, 3) of rr (N, 9) = sum_s (w r_a) r_b."""
    rr = rr.reshape(-1, 3, 3)
    tr = (rr[:, 0, 0] + rr[:, 1, 1]) + rr[:, 2, 2]
    return tr[:, None, None] * np.eye(3) - rr


def _sum_points(terms):
    """(M, K): each of the K terms (M, S) summed over its points in order (numpy's sum over
    the first axis of a C-contiguous array: the order of the compiled kernels' sums)."""
    return np.ascontiguousarray(np.stack(terms).transpose(2, 1, 0)).sum(axis=0)


class Janus:
    """Per-particle janus parameters of a run and the slip step (module docstring).

    species (N,) species index per particle; specs: JanusSpec per species;
    slip_tol, slip_iter: switch.SLIP_tol / SLIP_iter."""

    def __init__(self, species, specs, slip_tol=1e-3, slip_iter=4):
        species = np.asarray(species, dtype=np.int64)
        n = len(species)
        self.n = n
        prop = np.array([specs[s].propulsion for s in species] if n else [], dtype=object)
        self.tumblers = np.flatnonzero(prop == "TUMBLER")
        self.squirmers = np.flatnonzero(prop == "SQUIRMER")
        self.obstacles = np.flatnonzero(prop == "OBSTACLE")
        self.force_body = np.array([specs[s].force for s in species], dtype=float).reshape(n, 3)
        self.torque_body = np.array([specs[s].torque for s in species],
                                    dtype=float).reshape(n, 3)
        e3 = np.zeros((n, 3))
        for i, s in enumerate(species):
            if specs[s].axis in AXES:
                e3[i, AXES[specs[s].axis]] = 1.0
        self.axis_body = e3
        self.B1 = np.array([specs[s].slip_vel for s in species], dtype=float)
        self.beta = 0.5 * np.array([specs[s].slip_mode for s in species], dtype=float)
        self.C1 = np.array([specs[s].rotlet_C1 for s in species], dtype=float)
        self.C2 = np.array([specs[s].rotlet_C2 for s in species], dtype=float)
        self.slip_tol = float(slip_tol)
        self.slip_iter = max(1, int(slip_iter))
        self.iterations = 0
        self.unconverged = 0
        self._bufs = None

    def subset(self, rows) -> "Janus":
        """The parameters of the particles ``rows`` (global indices) as a Janus of their own
        (a rank's table in a distributed run); buffers and counters stay with this one."""
        rows = np.asarray(rows, dtype=np.int64)
        sub = object.__new__(Janus)
        sub.n = len(rows)
        for name in ("force_body", "torque_body", "axis_body", "B1", "beta", "C1", "C2"):
            setattr(sub, name, getattr(self, name)[rows])
        for name in ("tumblers", "squirmers", "obstacles"):
            setattr(sub, name, np.flatnonzero(np.isin(rows, getattr(self, name))))
        sub.slip_tol, sub.slip_iter = self.slip_tol, self.slip_iter
        sub.iterations, sub.unconverged = self.iterations, self.unconverged
        sub._bufs = None
        sub._whole = self
        return sub

    @property
    def active(self) -> bool:
        """Whether the velocity update differs from the plain one (tumblers or squirmers)."""
        return bool(len(self.tumblers) or len(self.squirmers))

    # ------------------------------------------------------------------ kinematics
    def axis(self, q, which=None):
        """e3 in the space frame, (N, 3) (or of the particles ``which``)."""
        which = slice(None) if which is None else which
        return np.einsum("nij,nj->ni", to_matrix(q[which]), self.axis_body[which])

    def self_force(self, q):
        """(F_self, T_self) (N, 3): the tumblers' body-frame force and torque rotated to the
        space frame (§3.5); zero for the others."""
        F = np.zeros((self.n, 3))
        T = np.zeros((self.n, 3))
        t = self.tumblers
        if len(t):
            R = to_matrix(q[t])
            F[t] = np.einsum("nij,nj->ni", R, self.force_body[t])
            T[t] = np.einsum("nij,nj->ni", R, self.torque_body[t])
        return F, T

    def slip_velocity(self, r, q, which):
        """u_s (M, S, 3) at offsets r (M, S, 3) from the squirmers ``which`` (§3.3), written
        without dividing by sin(theta): B1 (1 + 2 beta cos t)(cos t r^ - e3)
        + (C1 + 3 C2 cos t)(e3 x r^)."""
        return self._slip(r, _norm(r), self.axis(q, which), which)

    def _slip(self, r, d, e3, which):
        """slip_velocity with |r| (M, S) and e3 (M, 3) given (the operations of the
        compiled janus_kernels.stencil_sums)."""
        e3 = e3[:, None, :]
        rhat = r / np.where(d > 0, d, 1.0)[..., None]
        c = (rhat[..., 0] * e3[..., 0] + rhat[..., 1] * e3[..., 1]) + rhat[..., 2] * e3[..., 2]
        B1 = self.B1[which][:, None]
        beta = self.beta[which][:, None]
        us = (B1 * (1.0 + (2.0 * beta) * c))[..., None] * (c[..., None] * rhat - e3)
        C1, C2 = self.C1[which][:, None], self.C2[which][:, None]
        if np.any(C1) or np.any(C2):
            us += (C1 + (3.0 * C2) * c)[..., None] * _cross(e3, rhat)
        return us

    @staticmethod
    def shell_weight(r, phi, a, xi, d=None):
        """phi_s = (1 - phi_i) cos(pi (a - |r|)/XI) in | |r| - a | < XI/2, else 0 (§3.3);
        d: |r| if known."""
        x = a - (_norm(r) if d is None else d)
        return np.where(np.abs(x) < 0.5 * xi, (1.0 - phi) * np.cos(np.pi * x / xi), 0.0)

    # ------------------------------------------------------------------ time step
    def update_velocities(self, spm, F_H, T_H, F_o, T_o, dP, dL):
        """The velocity update of one spm.SPM step with self forces and, with squirmers,
        the self-consistent slip (module docstring).  Leaves f_hydro / torque_hydro = F_H /
        T_H and f_slip / torque_slip in the particle state and, with squirmers, adds the
        solenoidal slip flow u' to the fluid (the solver's state, the sampled u* and,
        where the rest of the step reads all of it, spm.u).

        In a distributed run (spm.owned: this Janus is the rank's table's, owned rows first;
        F_H ... dL of the owned rows) the squirmers' stencil sums (moments, shell terms) and
        slip forces of every rank are summed on their owners (reverse sums), the owners'
        iterates go to the ghosts, whose stencils join the slip flow on the other blocks,
        and the convergence test is taken over all ranks (every rank makes the same
        passes).  In a plain run these exchanges are identities."""
        o = spm.owned                               # the layout's table (identities: one process)
        whole = getattr(self, "_whole", self)       # the run's Janus (counters)
        p = spm.p
        n, q = o.n_own, spm.p_own
        T = spm.rows                                # the table rows of the stencil arrays
        is_sq = np.zeros(p.n, dtype=bool)
        is_sq[self.squirmers] = True
        st = np.flatnonzero(is_sq[T])               # stencil rows of the squirmers
        rows = T[st]                                # their table rows
        own_sq = self.squirmers[self.squirmers < n]
        total, spread, to_table = o.reverse_sum, o.refresh, spm.to_table
        worst = lambda e: -o.allmin(-e)[0]          # noqa: E731  (the largest of the ranks)
        F_s, T_s = self.self_force(p.q)
        F_s, T_s = F_s[:n], T_s[:n]
        if not len(whole.squirmers):
            self._update(spm, q, n, F_H + F_s, T_H + T_s, F_o, T_o, dP, dL, F_H, T_H)
            self._set_slip(q, np.zeros((n, 3)), np.zeros((n, 3)))
            return
        a, xi = spm.stencil.A, spm.stencil.xi
        idx, phi = spm.idx[st], spm.phi_i[st]
        rc = np.ascontiguousarray(spm.r.transpose(2, 0, 1)[:, st])   # (3, M, S)
        r = rc.transpose(1, 2, 0)                                     # (M, S, 3) view
        d = _norm(r)
        ws = self.shell_weight(r, phi, a, xi, d)
        ws *= spm.on_block[st]                      # this block's points only (x 1 exact)
        us = getattr(spm, "_us", None)      # an SPM that samples u* at its points once
        sampled = us is not None and us.shape[1:] == spm.idx.shape     # (step 4)
        ul = us[:, st] if sampled and not spm.rect else sample(spm.u, idx)   # u at the points
        shell = np.empty_like(rc)                   # phi_s (u_s - u)
        sums = self._stencil_sums(rc, phi, ws, d, self.axis(p.q, rows), rows, ul, shell)
        part = np.zeros((p.n, 32))                  # the stencil sums (this rank's part)
        part[rows] = sums
        tot = total(part)[own_sq]
        M0, M1, M2 = tot[:, 0], tot[:, 1:4], _second_moment(tot[:, 4:13])
        S0, S1, S2 = tot[:, 13], tot[:, 14:17], _second_moment(tot[:, 17:26])
        dPs, dLs = tot[:, 26:29], tot[:, 29:32]
        K = M2 + (np.einsum("na,nb->nab", M1, M1)
                  - np.einsum("nk,nk->n", M1, M1)[:, None, None] * np.eye(3)) / M0[:, None, None]

        saved = {k: getattr(q, k).copy() for k in _SAVED}
        Vs, Ws = q.v[own_sq].copy(), q.omega[own_sq].copy()
        grid = spm.fluid.grid
        scale = spm.rho * spm.dx ** 3 / spm.dt
        it = np.zeros((p.n, 12))                    # the iterates (dV, dW, V*, W*) per row
        for k in range(self.slip_iter):
            dPk = -(S0[:, None] * Vs + _cross(Ws, S1) + dPs)
            dLk = -(_cross(S1, Vs) + np.einsum("nab,nb->na", S2, Ws) + dLs)
            dW = np.linalg.solve(K, (dLk - _cross(M1, dPk) / M0[:, None])[..., None])[..., 0]
            dV = (dPk - _cross(dW, M1)) / M0[:, None]
            it[own_sq] = np.concatenate([dV, dW, Vs, Ws], axis=1)
            spread(it)                              # the owners' iterates to the ghosts
            up_hat, up = self._solenoidal(grid, idx, phi, ws, rc, it[rows], shell)
            FT = total(to_table(self._slip_force(spm, up, scale)))
            F_sl, T_sl = FT[:, :3], FT[:, 3:]
            if k:
                for name, val in saved.items():
                    getattr(q, name)[...] = val
            self._update(spm, q, n, F_H + F_sl + F_s, T_H + T_sl + T_s, F_o, T_o, dP, dL,
                         F_H, T_H)
            V, W = q.v[own_sq], q.omega[own_sq]
            e = float(np.max(_rel2(Vs, V) + _rel2(Ws, W))) if len(own_sq) else 0.0
            eps = worst(e) ** 0.5
            self.iterations = whole.iterations = k + 1
            if eps < self.slip_tol:
                break
            if k + 1 == self.slip_iter:
                whole.unconverged += 1
                self.unconverged = whole.unconverged
                break
            Vs = 0.3 * Vs + 0.7 * V
            Ws = 0.3 * Ws + 0.7 * W
        self._set_slip(q, F_sl, T_sl)
        spm.fluid.u_hat += up_hat
        if sampled:                         # a step: keep it current (u' at the points of
            us += self._up_at               # the last _slip_force)
        # u* itself: the rest of a spectral step reads it only at the stencil points (the
        # samples above; the walls' increment and the re-gridded u* of a sheared frame read
        # all of it), and the next step makes it anew
        if not sampled or spm.mode != "spectral" or spm.wall is not None or spm.rect:
            spm.u += up

    def _stencil_sums(self, rc, phi, ws, d, e3, rows, ul, shell):
        """The squirmers' stencil sums (M, 32), per particle over its points in order: phi,
        phi r, (phi r_a) r_b, ws, ws r, (ws r_a) r_b, ws du, ws (r x du) with du = u_s - u
        (u_s the slip velocity, ul (3, M, S) u at the points); shell (3, M, S) <- ws du.
        One compiled pass (janus_kernels.stencil_sums) or the same operations in numpy."""
        rot = bool(np.any(self.C1[rows]) or np.any(self.C2[rows]))
        K = _compiled.janus
        if K is not None:
            out = np.empty((len(rows), 32))
            K.stencil_sums(rc, phi, ws, d, np.ascontiguousarray(e3), self.B1[rows],
                           self.beta[rows], self.C1[rows], self.C2[rows], rot,
                           np.ascontiguousarray(ul), shell, out)
            return out
        r = rc.transpose(1, 2, 0)
        du = np.moveaxis(self._slip(r, d, e3, rows), -1, 0) - ul          # (3, M, S)
        np.multiply(ws, du, out=shell)
        pr, wr = phi * rc, ws * rc
        return _sum_points([phi, *pr, *(pr[a] * rc[b] for a in range(3) for b in range(3)),
                            ws, *wr, *(wr[a] * rc[b] for a in range(3) for b in range(3)),
                            *shell, *(ws * (rc[a] * du[b] - rc[b] * du[a]) for a, b in _CYC)])

    def _solenoidal(self, grid, idx, phi, ws, rc, g, shell):
        """u' = P[sum over the squirmers' points of w = phi (dV + dW x r) + ws (V* + W* x r)
        + shell] (g (M, 12): dV, dW, V*, W* per particle): (u'_hat, u') in buffers owned by
        this object (valid until the next call; a rank's blocks of them in a distributed
        run)."""
        holder = getattr(self, "_whole", self)
        shape = tuple(getattr(grid, "local_shape", grid.shape))
        if holder._bufs is None or holder._bufs[0].shape[1:] != shape:
            holder._bufs = (grid.zeros_real(), grid.empty_complex(), grid.empty_complex(),
                            grid.empty_real())
        field, uh, c, up = holder._bufs             # field: 0 but at the last call's points,
        ff = field.reshape(3, -1)                   # cleared after its transform
        Kj = _compiled.janus
        if Kj is not None:
            Kj.slip_scatter(ff, idx, phi, ws, rc, np.ascontiguousarray(g), shell)
        else:                                       # the same sums (np.add.at: in order)
            r = rc.transpose(1, 2, 0)
            w = phi[..., None] * (g[:, None, 0:3] + _cross(g[:, None, 3:6], r))
            w += ws[..., None] * (g[:, None, 6:9] + _cross(g[:, None, 9:12], r))
            w = np.moveaxis(w, -1, 0) + shell
            for k in range(3):
                np.add.at(ff[k], idx.reshape(-1), w[k].reshape(-1))
        K = _compiled.spectral
        if K is not None:               # fused: uh = 0 + P T c, c = uh / N (the numpy
            grid.forward_truncated(field, c)    # passes' numbers; used on the mask)
            clear_points(field, idx)
            projection_kernels(K, grid)[4](c, uh, grid.dealias_f, *grid.k_axes, grid.inv_k2,
                                           1.0 / grid.size)
        else:
            grid.forward_truncated(field, uh)
            clear_points(field, idx)
            uh *= grid.dealias_f        # the 2/3 rule of the original's Solenoidal_u
            grid.project(uh)
            np.multiply(uh, 1.0 / grid.size, out=c)
        grid.backward_truncated(c, up)  # (c is truncated)
        return uh, up

    def _slip_force(self, spm, up, scale):
        """(F_slip, T_slip) (N, 6) of every particle: RHO DX^3/dt sum phi_i u' and
        RHO DX^3/dt sum r x phi_i u' (the sums over the points in order); u' at the points
        kept in ``_up_at`` (3, N, S)."""
        uf = up.reshape(3, -1)
        idx, phi = spm.idx, spm.phi_i
        rc = spm.r.transpose(2, 0, 1)
        if getattr(self, "_up_at", None) is None or self._up_at.shape[1:] != idx.shape:
            self._up_at = np.empty((3,) + idx.shape)
        out = np.empty((idx.shape[0], 6))
        K = _compiled.janus
        if K is not None and rc.flags.c_contiguous:
            K.slip_force(uf, idx, phi, rc, scale, self._up_at, out)
            return out
        w = sample(up, idx, out=self._up_at) * phi
        s = _sum_points([w[0], w[1], w[2],
                         *(x for a, b in _CYC for x in (rc[a] * w[b], rc[b] * w[a]))])
        out[:, 0:3] = s[:, 0:3] * scale
        for c in range(3):
            out[:, 3 + c] = (s[:, 3 + 2 * c] - s[:, 4 + 2 * c]) * scale
        return out

    @staticmethod
    def _update(spm, q, n, F, T, F_o, T_o, dP, dL, F_H, T_H):
        """The velocity update of the rows ``q`` (the first n of the table: all in a plain
        run, the owned ones in a distributed run)."""
        spm.motion.update_velocities(q, F, T, F_o, T_o, spm.dt, spm.rotation, dP, dL,
                                     first=spm.step_index == 0)
        q.f_hydro[...] = F_H           # the records keep F_H; slip and self forces apart
        q.torque_hydro[...] = T_H

    @staticmethod
    def _set_slip(p, F, T):
        p.f_slip_previous[...] = p.f_slip
        p.torque_slip_previous[...] = p.torque_slip
        p.f_slip[...] = F
        p.torque_slip[...] = T


_SAVED = ("v", "omega", "v_old", "omega_old", "f_hydro", "f_hydro_previous", "f_r",
          "f_r_previous", "torque_hydro", "torque_hydro_previous", "torque_r",
          "torque_r_previous")


_TOL_MP = 10.0 * np.finfo(float).eps


def _rel2(a, b):
    """|a - b|^2 / |b|^2 per row, undivided where |b|^2 <= 10 DBL_EPSILON (§3.4 f; the
    original's operate_surface.h Slip_particle_convergence divides only where positive_mp:
    a squirmer that does not turn, |Omega|^2 ~ 1e-36, adds |dOmega|^2, not a ratio of
    round-off)."""
    d = np.einsum("nk,nk->n", a - b, a - b)
    nb = np.einsum("nk,nk->n", b, b)
    big = nb > _TOL_MP
    return np.where(big, d / np.where(big, nb, 1.0), d)
