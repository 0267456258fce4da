"""Smoothed Profile Method time step (manual §4.1, eqs 1-14; §5.2) for any grid solver.

``SPM(fluid, particles, A, xi, rho, dx, dt, ...)`` composes a fluid solver with the particles
(no I/O).  ``fluid`` is either

* a spectral ``SpectralNS`` (mode 'spectral': the solver holds u; ``step()``,
  ``velocity(out)``, ``add_solenoidal(du)``), or
* a ``MACSolver`` (mode 'mac': u (3, NX, NY, NZ) is held here as ``self.u``;
  ``step(u)``, ``project(u)``).

One ``step()``:

1. fluid step (eq 8 without the particle force): u^n -> u*;
2. F_H, N_H by momentum exchange (eqs 11-12, coupling.hydro_force_torque) with the
   profiles phi_i at the current positions R^n;
3. V, Omega by eqs 9-10 with F_H + F_other (+ thermal impulses, eqs 13-14);
4. rigidity increment du = sum_i phi_i (V_i^{n+1} + Omega_i^{n+1} x r) - phi u* at the same
   positions (the phi f_p dt of eq 8), made solenoidal: spectral ``add_solenoidal`` (keeps
   the k = 0 mean of du), MAC ``u += du; project(u)`` (the projection keeps the mean);
5. R, q by Crank-Nicolson (§5.2), new profiles.

With self-propelled particles (``particles.janus``, kapsel.particles.janus) step 3 adds the
tumblers' self force and, with squirmers, iterates the slip flow to self-consistency and adds
it to u before step 4.

``wall`` (kapsel.particles.walls.FlatWall): the solid walls join step 4 with zero
velocity: du -= phi_w u*, with phi_w limited to 1 - phi where particles overlap the wall's
interface (PHYSICS-EXTRA.md §2.3); done also without particles.  The projection of du would
leave the particles' pressure gradient in the solid (a few % of max|u|, as in the original),
so the step ends with the projection onto divergence-free fields that vanish on the solid
(kapsel.particles.wall_rest): the velocity in the solid (phi_w = 1) is 0 to round-off.  The
walls absorb momentum, so P below is then not conserved.

Steps 3 and 5 are those of free particles (motion.update_velocities / update_positions) or,
when ``particles.constraints`` is set, its own (motion.Pinned: pinned particles;
rigid.RigidBodies: beads moving as rigid bodies).

Conserved momentum
------------------
Write V_p,i = DX^3 sum_x phi_i (grid volume) and take r about the discrete centroid of each
profile, r = x - R_i - c_i with c_i = sum phi_i (x - R_i) / sum phi_i, so that
sum_x phi_i r = 0 (c_i is a sub-grid artefact, |c_i| < 0.01 DX for A = 4, xi = 2; without
it a rotation Omega_i would carry linear momentum RHO DX^3 Omega_i x sum phi_i r).
With no external force (F_other = 0, no noise, FIX_CELL off) the fluid step keeps
RHO DX^3 sum u and, with M_i the mass used in eq 9,

    step 2:  M_i dV_i = F_H,i dt = RHO DX^3 (sum_x phi_i u* - V_p,i V_i^n)
    step 4:  RHO DX^3 sum_x du = RHO DX^3 sum_i (V_p,i V_i^{n+1} - sum_x phi_i u*)

(phi = sum_i phi_i, also where particles overlap).  Adding: RHO DX^3 sum du
= -sum_i (M_i - RHO V_p,i) dV_i.  Hence the exactly conserved total momentum is

    P = RHO DX^3 sum_x u + sum_i dM_i V_i,     dM_i = M_i - RHO V_p,i,

the whole velocity field (particle interiors included: the fluid displaced by a particle
moves with it) plus the excess mass of each particle.  It holds to round-off across steps
only if dM_i does not depend on the particle position, while V_p,i varies with the sub-grid
position (by ~0.1 % for A = 4, xi = 2).  So ``mass='grid'`` (default) uses

    M_i = RHO V_p,i(R_i^n) + (M_i^nominal - RHO 4/3 pi a_i^3)

i.e. the displaced-fluid part of the mass is the grid volume of the profile (1.6 % above
4/3 pi A^3 for A = 4, xi = 2) and the excess mass (MASS_RATIO - 1) RHO 4/3 pi a^3 is the
original's; dM_i is then constant and P is conserved to round-off (for MASS_RATIO = 1 it is
simply RHO DX^3 sum u).  ``mass='nominal'`` uses M = MASS_RATIO RHO 4/3 pi a^3 as the
original; P then drifts by RHO DX^3 sum_i (V_p,i(R^n) - V_p,i(R^{n+1})) V_i per step.
The moments of inertia are treated alike (grid 2/3 RHO DX^3 sum phi_i |r|^2 + the nominal
excess) with ``mass='grid'``.  ``total_momentum()`` returns P.
"""
from __future__ import annotations

import numpy as np

from .coupling import (clear_points, hydro_force_torque, particle_velocity_field,
                       rigidity_increment, sample)
from . import motion as _free_motion
from .profile import Stencil, particle_profiles, total_phi

__all__ = ["SPM"]


class SPM:
    """Fluid + particles by the SPM (see module docstring).  No I/O.

    forces(particles) -> (F, T) or (F, T, ...) : non-hydrodynamic forces / torques (N, 3);
    noise(n, dt) -> (dP, dL) : thermal impulses over one step (eqs 13-14).
    u: initial velocity for the MAC mode (default zero); ignored for 'spectral'.
    impose: make the initial field move with the particles (eq 6) at construction.
    dry: built only to be checked (``kapsel-py --check``), never stepped: no profiles, no
    imposition.
    """

    def __init__(self, fluid, particles, A, xi, rho, dx, dt, rotation=True, forces=None,
                 noise=None, mass="grid", center=True, u=None, impose=True, wall=None, dry=False):
        self.fluid = fluid
        self.p = particles
        self.rho = float(rho)
        self.dx = float(dx)
        self.dt = float(dt)
        self.rotation = bool(rotation)
        self.forces = forces
        self.noise = noise
        if mass not in ("grid", "nominal"):
            raise ValueError("mass must be 'grid' or 'nominal'")
        self.mass_mode = mass
        self.center = bool(center)
        if hasattr(fluid, "add_solenoidal"):
            self.mode = "spectral"
            self.shape = tuple(fluid.grid.shape)
            self.u = fluid.grid.empty_real()       # u* buffer (FFT-aligned)
        elif hasattr(fluid, "project"):
            self.mode = "mac"
            self.shape = tuple(fluid.shape)
            ushape = (3,) + tuple(getattr(fluid, "fshape", self.shape))   # a rank's block
            self.u = np.zeros(ushape) if u is None else np.asarray(u, dtype=float)
            if self.u.shape != ushape:
                raise ValueError("u must have shape (3, NX, NY, NZ)")
        else:
            raise TypeError("fluid must be a SpectralNS or a MACSolver")
        self.size = int(np.prod(self.shape))
        # distributed fluid (kapsel.parallel.pencil): this rank's block of the fields; the
        # profiles are computed whole (masses, centroids as in a serial run), then cut to the
        # block (_localize) for every field operation, and the per-particle sums of the
        # coupling are summed over the ranks (_reduce)
        g = getattr(fluid, "grid", None)
        self.dist = g if hasattr(g, "comm") else None
        if self.dist is not None and wall is not None:
            raise ValueError("walls do not run distributed")
        self.fshape = tuple(g.local_shape) if self.dist is not None else self.shape
        self.fsize = int(np.prod(self.fshape))
        self._T = None          # distributed: the particles whose stencil meets the block
        self.wall = wall
        self._rest = self._c = None
        if wall is not None and not dry:      # (its blocks are measured: not for a check)
            from .wall_rest import SolidRest
            self._rest = SolidRest(wall, self._projection())
            self._c = np.zeros((3,) + self.shape)
        # kept 0 between steps: a step scatters du onto its stencil points and clears them
        # (with walls du is dense: cleared whole at the start of the next step instead)
        self._du = None
        if particles.n or wall is not None:   # spectral: FFT-aligned, transformed in place
            self._du = (fluid.grid.zeros_real() if self.mode == "spectral"
                        else np.zeros((3,) + self.fshape))
        self._us = None         # u* at the stencil points, sampled once a step
        self._du_points = None  # du at the stencil points of the last step (last_increment)
        self._du_stepped = False
        self.box = np.array(self.shape, dtype=float) * self.dx
        # oblique fluid (kapsel.fluid.oblique, Lees-Edwards): profiles on the sheared grid,
        # velocities relative to the imposed shear flow, Lees-Edwards images
        self.oblique = getattr(fluid, "oblique", False)
        smax = fluid.max_frame_strain if self.oblique else 0.0
        self.stencil = Stencil(A, xi, dx, strain_max=smax) if particles.n else None
        self.moment = np.zeros((3, 3))    # sum du_a r_b of the last step (particle stress)
        a = np.asarray(particles.radius, dtype=float)
        vol = 4.0 / 3.0 * np.pi * a ** 3
        self.excess_mass = particles.mass - self.rho * vol
        self.excess_inertia = particles.inertia - 0.4 * self.rho * vol * a ** 2
        self.step_index = 0
        self.motion = getattr(particles, "constraints", None) or _free_motion
        # rigid bodies wrap their centres and beads through the Lees-Edwards images themselves
        self._own_images = self.oblique and hasattr(self.motion, "use_lees_edwards")
        if self._own_images:
            self.motion.use_lees_edwards(fluid)
            self.motion.set_bead_velocities(particles)
        self.janus = getattr(particles, "janus", None)      # janus.Janus: self-propulsion
        if self.janus is not None and len(self.janus.squirmers) and (
                self.mode != "spectral" or self.oblique):
            raise ValueError("squirmers need the spectral (rectangular) fluid")
        # distributed: particles owned by the rank holding their stencil's base point (rigid
        # bodies: that of their first bead), with ghosts (kapsel.parallel.particles)
        self.owned = None
        self._bodies = None
        if self.dist is not None and particles.n:
            self._own(particles, smax)
        if particles.n and not dry:
            self._profiles()
            if impose:
                self.impose_particle_velocity()

    # ------------------------------------------------------------------ profiles
    def _profiles(self):
        """phi_i, r at the current positions; grid volumes, centroid-corrected r, masses."""
        p = self.p
        g, y0 = (self.fluid.frame_strain, self.fluid.y0) if self.oblique else (0.0, 0.0)
        R = p.R
        if self.owned is not None:     # the rows whose stencil meets the block (owned first)
            T = self._near(p.R, g, y0)
            n = self.owned.n_own
            if self._bodies is not None:     # every owned bead (a body's may lie elsewhere)
                T = np.concatenate([np.arange(n), T[T >= n]])
            self._T = T
            R = p.R[self._T]
        self.idx, self.phi_i, r = particle_profiles(R, self.stencil, self.shape, self.dx, g,
                                                    y0)
        w = self.phi_i.sum(axis=1)
        self.grid_volume = w * self.dx ** 3
        if self.center:
            c = np.stack([np.einsum("ns,ns->n", self.phi_i, r[..., k]) for k in range(3)],
                         axis=1) / w[:, None]
            r -= c[:, None, :]  # in place: keeps the component-major layout
        self.r = r
        if self.mass_mode == "grid":
            self.mass = self.rho * self.grid_volume + self._sub(self.excess_mass)
            r2 = sum(np.einsum("ns,ns,ns->n", self.phi_i, r[..., k], r[..., k])
                     for k in range(3))
            self.inertia = ((2.0 / 3.0) * self.rho * self.dx ** 3 * r2
                            + self._sub(self.excess_inertia))
        else:
            self.mass, self.inertia = self._sub(p.mass), self._sub(p.inertia)
        if self.owned is not None:
            self._localize()

    # ------------------------------------------------------------------ distributed
    def _near(self, R, strain, origin):
        """Indices of the particles whose stencil meets this rank's block."""
        s = np.asarray(R, dtype=float) / self.dx
        if strain:
            s[:, 0] = (R[:, 0] - strain * (R[:, 1] - origin)) / self.dx
        with np.errstate(invalid="ignore"):
            b = np.floor(s).astype(np.int64)
        near = np.ones(len(s), dtype=bool)
        for axis in (0, 1):                   # the blocks split x and y
            n = self.shape[axis]
            a0, a1 = self.dist.real_range[axis]
            o = self.stencil.offsets[:, axis]
            lo, width = int(o.min()), int(o.max() - o.min()) + 1
            start = np.mod(b[:, axis] + lo, n)
            if width < n:
                near &= (np.mod(a0 - start, n) < width) | (np.mod(start - a0, n) < a1 - a0)
        return np.flatnonzero(near)

    def _sub(self, a):
        """The rows of the particles this rank couples (all of them in a plain run)."""
        return a if self._T is None else a[self._T]

    def _full(self, a):
        out = np.zeros((self.p.n,) + a.shape[1:])
        out[self._T] = a
        return out

    def _localize(self):
        """Cut the stencils to this rank's block of the distributed fields: ``idx`` flat
        indices into the local block (0 off the block), ``phi_i`` 0 off the block, so every
        sum over stencil points is this rank's part of it."""
        nx, ny, nz = self.shape
        (x0, x1), (y0, y1), _ = self.dist.real_range
        ix, rest = np.divmod(self.idx, ny * nz)
        iy, iz = np.divmod(rest, nz)
        ix -= x0
        iy -= y0
        on = (ix >= 0) & (ix < x1 - x0) & (iy >= 0) & (iy < y1 - y0)
        ix *= (y1 - y0)
        ix += iy
        ix *= nz
        ix += iz
        self.idx = np.where(on, ix, 0)
        self.phi_i = np.where(on, self.phi_i, 0.0)
        self._on = on

    def _reduce(self, *arrays):
        """Sum of per-particle arrays over the ranks, the same bits on every rank (MPI
        Reduce to rank 0 in MPI's fixed order for this number of ranks, then Bcast)."""
        if self.dist is None:
            return arrays
        from mpi4py import MPI
        buf = np.concatenate([np.asarray(a, dtype=float).reshape(-1) for a in arrays])
        out = np.empty_like(buf)
        comm = self.dist.comm
        comm.Reduce(buf, out, op=MPI.SUM, root=0)
        comm.Bcast(out, root=0)
        res, i = [], 0
        for a in arrays:
            a = np.asarray(a)
            res.append(out[i:i + a.size].reshape(a.shape))
            i += a.size
        return tuple(res)

    # ------------------------------------------------------------------ owned particles
    def _own(self, whole, strain_max):
        """Distributed run: keep this rank's owned particles and ghosts of the whole table
        ``whole`` (the model's, the same on every rank at the start; kapsel.parallel.
        particles).  ``self.p`` is then the local table, owned rows first."""
        from ..parallel.particles import Owned
        from .rigid import RigidBodies
        f = self.forces
        cutoff = float(getattr(f, "cutoff", 0.0) or 0.0) if f is not None else 0.0
        frame = ((lambda: (self.fluid.frame_strain, self.fluid.y0)) if self.oblique
                 else None)
        c = whole.constraints
        self._bodies = c if isinstance(c, RigidBodies) else None   # global bodies
        self._pins = None if self._bodies is not None else c       # motion.Pinned or None
        bodies, width, extra = None, 0, None
        if self._bodies is not None:
            # a body is owned with its beads by the owner of its first bead; a pair partner
            # of any of its beads lies within cutoff + span of that bead's base point
            b = self._bodies
            bodies, width, extra = (b.body, b.first_beads()), b.RECORD_WIDTH, b.bead_records()
            if cutoff > 0:
                cutoff += b.span()
        self.owned = Owned(self.dist, self.stencil.offsets, self.dx, cutoff, frame,
                           strain_max, bodies=bodies, extra_width=width)
        self.whole = whole
        self.n_global = whole.n
        self._janus_whole = whole.janus             # janus.Janus of all particles, or None
        self._released = False
        self._take(self.owned.scatter(whole, extra=extra))

    def _take(self, p):
        """Make ``p`` (owned rows first, then ghosts) the local table."""
        from ..parallel.particles import view
        from .motion import Pinned
        self.p = p
        o = self.owned
        n = o.n_own
        self.p_own = view(p, n)                 # the owned rows (views: updates write through)
        self.motion = _free_motion
        if self._bodies is not None:            # the bodies this rank owns, whole
            self.p_own.constraints = self.motion = self._bodies.local(o.gid[:n],
                                                                      o.extra[:n])
        if self._pins is not None:
            gid = o.gid[:n]
            self.p_own.constraints = self.motion = Pinned(
                np.flatnonzero(np.isin(gid, self._pins.pin)),
                np.flatnonzero(np.isin(gid, self._pins.pin_rot)))
        a = np.asarray(p.radius, dtype=float)
        vol = 4.0 / 3.0 * np.pi * a ** 3
        self.excess_mass = p.mass - self.rho * vol
        self.excess_inertia = p.inertia - 0.4 * self.rho * vol * a ** 2
        self._own_weight = np.zeros(p.n)
        self._own_weight[:n] = 1.0
        if self._janus_whole is not None:       # the self-propulsion of the table's rows
            self.janus = self._janus_whole.subset(o.gid)

    def gather(self):
        """Collective: the owned rows of every rank into the whole table on rank 0 (the
        output writers and the restart read it there)."""
        if self.owned is not None:
            root = self.owned.me == 0
            extra = self._records()
            rec = self.owned.gather(self.p, self.whole if root else None, extra=extra)
            if rec is not None:                 # the bodies' state into the global bodies
                self._bodies.take_records(np.arange(self.n_global), rec)

    def _records(self):
        """The extra columns of the owned rows (the state of rigid bodies), or None."""
        if self._bodies is None:
            return None
        return self.motion.bead_records()

    def owned_particles(self):
        """The particles this rank accounts for in global sums (energies): its owned rows
        in a distributed run with owned particles, else all."""
        return self.p_own if self.owned is not None else self.p

    def _exchange(self):
        """Migration and new halos (kapsel.parallel.particles ``exchange``); the whole
        table's rows are dropped on the ranks other than 0 from the first step on (a
        restart read before fills them on every rank)."""
        if not self._released:
            self._released = True
            if self.owned.me != 0:
                from ..parallel.particles import release
                release(self.whole)
        self._take(self.owned.exchange(self.p, extra=self._records()))

    def _hydro_sums(self):
        """(u* at the stencil points, F_H, T_H) of the particles this rank couples: u*
        sampled once a step (eqs 9-10 use it, and so does the rigidity increment), the
        hydrodynamic force and torque over this rank's part of their profiles."""
        if self._us is None or self._us.shape[1:] != self.idx.shape:
            self._us = np.empty((3,) + self.idx.shape)
        us = sample(self.u, self.idx, out=self._us)
        v, shear = self._relative_velocity()
        F_H, T_H = hydro_force_torque(self.u, self.idx, self.phi_i, self.r, self._sub(v),
                                      self._sub(self.p.omega), self.rho, self.dx, self.dt,
                                      shear=shear, sampled=us)
        return us, F_H, T_H

    def _step_owned(self):
        """``step`` of a distributed run with owned particles: the same steps 1-5, the
        coupling sums of the ghosts sent to their owners, the owners moving their
        particles, the ghosts refreshed (velocities before the rigidity increment, the
        whole record at the exchange)."""
        o = self.owned
        self._fluid_step()
        if self.oblique:
            self._exchange()                   # the frame moved: owners and halos in it
            self._profiles()
        p, n = self.p, o.n_own
        u = self.u
        us, F_H, T_H = self._hydro_sums()
        FT = o.reverse_sum(self._full(np.concatenate([F_H, T_H], axis=1)))
        F_H, T_H = FT[:, :3], FT[:, 3:]
        F_o = T_o = None
        if self.forces is not None:
            F_o, T_o, ratio, stretch = self.forces.local(
                p, self._own_weight, o.gid, reduce=lambda a: self._reduce(a)[0])
            ratio, stretch = o.allmin(ratio, -stretch)      # the same on every rank
            if hasattr(self.forces, "check"):           # (overlap_guard)
                self.forces.check_bonds(-stretch)
                self.forces.check(ratio)
            virial = getattr(self.forces, "virial", None)
            if virial is not None:
                virial[...] = self._reduce(virial)[0]
            F_o, T_o = F_o[:n], T_o[:n]
        dP = dL = None
        if self.noise is not None:             # the serial stream, this rank's rows
            dP, dL = self.noise(self.n_global, self.dt)
            gid = o.gid[:n]
            dP, dL = dP[gid], dL[gid]
        if self.janus is not None and self._janus_whole.active:  # self force, slip
            self.janus.update_velocities(self, F_H, T_H, F_o, T_o, dP, dL)
        else:
            self.motion.update_velocities(self.p_own, F_H, T_H, F_o, T_o, self.dt,
                                          self.rotation, dP, dL, mass=self.mass[:n],
                                          inertia=self.inertia[:n])
        o.refresh(p.v, p.omega)
        v, shear = self._relative_velocity()
        du = rigidity_increment(u, self.idx, self.phi_i, self.r, self._sub(v),
                                self._sub(p.omega), self.fsize,
                                out=self._du, shear=shear,
                                moment=self.moment if self.oblique else None,
                                sampled=us, zeroed=True)
        if self.oblique:
            self.moment[...] = self._reduce(self.moment)[0]
        self._add_solenoidal(du)
        self._du_stepped = True
        flat = self.idx.reshape(-1)
        if self._du_points is None or self._du_points.shape[1] != flat.size:
            self._du_points = np.empty((3, flat.size))
        for c in range(3):
            np.take(du[c].reshape(-1), flat, out=self._du_points[c])
        clear_points(du, self.idx)
        q = self.p_own
        le = self.oblique and not self._own_images
        if le:                                 # Lees-Edwards images instead of the wrap
            R0, raw0 = q.R.copy(), q.R_raw.copy()
        self.motion.update_positions(q, self.dt, self.box, self.rotation)
        if le:
            q.R[:] = R0 + (q.R_raw - raw0)
            self.fluid.wrap_particles(q)
        self._exchange()
        self._profiles()
        self.step_index += 1

    def refresh(self):
        """Recompute the profiles after the positions were set from outside (a restart)."""
        if self.owned is not None:
            extra = None if self._bodies is None else self._bodies.bead_records()
            self._take(self.owned.scatter(self.whole, extra=extra))
        if self.p.n or self.owned is not None:
            self._profiles()

    def phi(self):
        """Total profile phi (eq 4), (NX, NY, NZ)."""
        if not self.p.n:
            return np.zeros(self.fshape)
        return total_phi(self.idx, self.phi_i, self.fsize).reshape(self.fshape)

    def particle_velocity(self):
        """phi u_p of eq 6, (3, NX, NY, NZ)."""
        p = self.p
        return particle_velocity_field(self.idx, self.phi_i, self.r, self._sub(p.v),
                                       self._sub(p.omega), self.fsize, self.fshape)

    # ------------------------------------------------------------------ fluid access
    def velocity(self):
        """Current velocity field u (3, NX, NY, NZ) (a copy in spectral mode)."""
        if self.mode == "spectral":
            return self.fluid.velocity()
        return self.u

    def _fluid_step(self):
        if self.mode == "spectral":
            self.fluid.step()
            if self.p.n or self.owned is not None:     # (a collective when distributed)
                self.fluid.velocity(out=self.u)
        else:
            self.fluid.step(self.u)

    def _add_solenoidal(self, du):
        if self.mode == "spectral":
            self.fluid.add_solenoidal(du)
        else:
            self.u += du
            self.fluid.project(self.u)

    def _projection(self):
        """f -> P f, the fluid's own projection of a real field (3, NX, NY, NZ), without
        touching the fluid's state."""
        if self.mode == "spectral":
            grid = self.fluid.grid

            def project(f):
                h = np.fft.rfftn(f, axes=(1, 2, 3))
                grid.project(h)
                return np.fft.irfftn(h, s=self.shape, axes=(1, 2, 3))
            return project
        return self.fluid.project

    def _hold_solid(self, du=None):
        """After u = P(u* + du): add P of the walls' holding force (kapsel.particles.
        wall_rest), so that u vanishes on the solid; the force joins du (last_increment)."""
        u = self.fluid.velocity(out=self.u) if self.mode == "spectral" else self.u
        c = self._rest.force(u, self._c)
        self._add_solenoidal(c)
        if du is not None:
            du[:, :self.shape[0], :self.shape[1], :self.shape[2]] += c

    def impose_particle_velocity(self):
        """u <- u + P[sum_i phi_i (V_i + Omega_i x r) - phi u] (rigidity increment, eq 6);
        with walls the fluid in their solid is then held at rest."""
        if not self.p.n and self.owned is None:
            return
        u = self.fluid.velocity(out=self.u) if self.mode == "spectral" else self.u
        p = self.p
        v, shear = self._relative_velocity()
        self._add_solenoidal(rigidity_increment(u, self.idx, self.phi_i, self.r, self._sub(v),
                                                self._sub(p.omega), self.fsize, shear=shear))
        if self._rest is not None:
            self._hold_solid()

    def _relative_velocity(self):
        """(V relative to the imposed flow at the centres, gamma_dot) for an oblique fluid,
        else (V, 0)."""
        if not self.oblique:
            return self.p.v, 0.0
        return self.p.v - self.fluid.background(self.p.R), self.fluid.shear_rate_now

    # ------------------------------------------------------------------ step
    def step(self):
        """Advance fluid and particles by dt (steps 1-5 of the module docstring)."""
        if self.owned is not None:
            return self._step_owned()
        self._fluid_step()
        p = self.p
        if self.wall is not None and self.mode == "spectral" and not p.n:
            self.fluid.velocity(out=self.u)
        if p.n and self.oblique:
            self._profiles()                  # the oblique grid moved with the frame
        if p.n:
            u = self.u
            us, F_H, T_H = self._hydro_sums()
            F_o = T_o = None
            if self.forces is not None:
                res = self.forces(p)
                F_o, T_o = res[0], res[1]
            dP = dL = None
            if self.noise is not None:
                dP, dL = self.noise(p.n, self.dt)
            if self.janus is not None and self.janus.active:   # self force, squirmer slip
                self.janus.update_velocities(self, F_H, T_H, F_o, T_o, dP, dL)
            else:
                self.motion.update_velocities(p, F_H, T_H, F_o, T_o, self.dt, self.rotation,
                                              dP, dL, mass=self.mass, inertia=self.inertia)
            v, shear = self._relative_velocity()
            if self.wall is not None:
                self._du.fill(0.0)            # dense after a wall step
            du = rigidity_increment(u, self.idx, self.phi_i, self.r, self._sub(v),
                                    self._sub(p.omega), self.fsize,
                                    out=self._du, shear=shear,
                                    moment=self.moment if self.oblique else None,
                                    sampled=us, zeroed=True)
            if self.wall is not None:
                self._wall_increment(du)
            self._add_solenoidal(du)
            if self._rest is not None:
                self._hold_solid(du)
            self._du_stepped = True
            if self.wall is None:
                flat = self.idx.reshape(-1)
                if self._du_points is None or self._du_points.shape[1] != flat.size:
                    self._du_points = np.empty((3, flat.size))
                for c in range(3):            # kept for last_increment (diagnostics)
                    np.take(du[c].reshape(-1), flat, out=self._du_points[c])
                clear_points(du, self.idx)    # du is all 0 again for the next step
            le = self.oblique and not self._own_images
            if le:
                R0, raw0 = p.R.copy(), p.R_raw.copy()
            self.motion.update_positions(p, self.dt, self.box, self.rotation)
            if le:                 # Lees-Edwards images instead of the periodic wrap
                p.R[:] = R0 + (p.R_raw - raw0)
                self.fluid.wrap_particles(p)
            self._profiles()
        elif self.wall is not None:
            self._du.fill(0.0)
            self._wall_increment(self._du)
            self._add_solenoidal(self._du)
            self._hold_solid(self._du)
            self._du_stepped = True
        self.step_index += 1

    def _wall_increment(self, du):
        """du -= phi_w u* (the walls at rest), phi_w limited to 1 - phi of the particles."""
        pw = self.wall.phi
        if self.p.n:
            pw = np.minimum(pw, np.maximum(1.0 - self.phi(), 0.0))
        for c in range(3):
            du[c] -= pw * self.u[c]

    def run(self, nsteps):
        for _ in range(int(nsteps)):
            self.step()

    # ------------------------------------------------------------------ diagnostics
    def last_increment(self):
        """The rigidity increment du (eq 6, before projection) of the last step as a full
        (3, NX, NY, NZ) field, zero before the first step (the particles' body force
        f_p = RHO du / dt of kapsel.fluid.diagnostics)."""
        if self.wall is not None:             # dense, kept until the next step
            return (np.array(self._du[:, :self.shape[0], :self.shape[1], :self.shape[2]])
                    if self._du_stepped else np.zeros((3,) + self.shape))
        du = np.zeros((3,) + self.fshape)
        if self._du_points is not None and self.p.n:
            flat = self.idx.reshape(-1)
            if flat.size == self._du_points.shape[1]:
                d = du.reshape(3, -1)
                for c in range(3):
                    d[c][flat] = self._du_points[c]
        return du

    def fluid_momentum(self):
        """RHO DX^3 sum_x u over the whole field (particle interiors included)."""
        if self.mode == "spectral":
            return np.asarray(self.fluid.momentum(), dtype=float)
        u = self.velocity()
        return self.rho * self.dx ** 3 * u.reshape(3, -1).sum(axis=1)

    def total_momentum(self):
        """P = RHO DX^3 sum u + sum_i (M_i - RHO V_p,i) V_i (module docstring), conserved to
        round-off with mass='grid' and no external force, noise or FIX_CELL."""
        P = self.fluid_momentum()
        if self.p.n:
            dM = self.mass - self.rho * self.grid_volume
            P = P + (dM[:, None] * self.p.v).sum(axis=0)
        return P
