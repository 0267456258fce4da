"""Smoothed Profile Method time step (manual §4.1, eqs 1-14; §5.2) for any grid solver, the
original's discrete algorithm (sp_3d_ns.cxx Time_evolution_hydro / _hydro_fdm / _hydro_OBL /
_hydro_OBL_fdm).

``SPM(fluid, particles, A, xi, rho, dx, dt, ...)`` composes a fluid solver with the particles
(no I/O).  ``fluid`` is either

* a spectral ``SpectralNS`` (mode 'spectral': the solver holds u; ``step()``,
  ``velocity(out)``, ``add_solenoidal(du)``), or
* a ``MACSolver`` (mode 'mac': u (3, NX, NY, NZ) is held here as ``self.u``; ``step(u)``).

One ``step()``:

1. fluid step without the particles (eq 8 without phi f_p): u^n -> u*; the spectral types'
   u* is 2/3-rule truncated, as their state always is;
2. positions R^{n+1} from V^n, V^{n-1} (kapsel.particles.motion: Euler at a run's first step,
   Adams-Bashforth after), orientations alike;
3. the profiles phi_i (eqs 1-3) at R^{n+1} and phi_sum = sum_i phi_i (+ phi_wall of the
   walls); the coupling weights w_i = phi_i / max(phi_sum, 1) (make_phi.cxx
   Make_u_particle_sum: overlapping profiles share a node);
4. F_H, N_H by momentum exchange (eqs 11-12, md_force.cxx Calc_f_hydro_correct_precision):
   F_i dt = -RHO DX^3 sum_x w_i (V_i^n + Omega_i^n x r - u*);
5. the other forces at R^{n+1} and V, Omega by eqs 9-10 (motion.update_velocities: the
   hydrodynamic force in full, the others by the trapezoid rule), thermal impulses
   (eqs 13-14), pinning;
6. the rigidity force (eq 6 imposed, phi f_p dt of eq 8) with the new velocities at the same
   profiles: du = sum_i w_i (V_i + Omega_i x r) - min(phi_sum, 1) u*, added solenoidal:
   spectral u += P T du (T the 2/3 truncation; f_particle.h Make_f_particle_dt_sole), MAC
   u <- P T (u + du) for the whole field (Make_f_particle_dt_nonsole + Solenoidal_u: the
   spectral projection of the original, applied every step, with or without particles).

``r`` is the minimum-image x - R_i of the stencil point (make_phi.h Relative_coord).  With
no overlap w_i = phi_i and du = -sum_i phi_i (u* - V_i - Omega_i x r).

With self-propelled particles (``particles.janus``, kapsel.particles.janus) step 5 adds the
tumblers' self force and, with squirmers, iterates the slip flow to self-consistency and adds
it to u before step 6.

``wall`` (kapsel.particles.walls.FlatWall): the solid walls are a body at rest in step 6:
phi_sum starts from phi_wall, so du also holds -(phi_wall / max(phi_sum, 1)) u* (done also
without particles); as in the original the projection leaves part of the particles'
pressure gradient in the solid.

Steps 2 and 5 are those of free particles (motion.update_positions / update_velocities) or,
when ``particles.constraints`` is set, its own (motion.Pinned: pinned particles;
rigid.RigidBodies: beads moving as rigid bodies), called with ``first`` (a run's step 0).

Momentum: the fluid step keeps RHO DX^3 sum u; with no external force the particles' and the
fluid's changes cancel up to the change of the grid volume V_p,i = DX^3 sum_x w_i between
the positions of two steps (a sub-grid effect, ~0.1 % of V_p for A = 4, A_XI = 2) and the
first moment sum_x w_i r of the profiles (``total_momentum``).

Distributed runs (kapsel.particles.ownership): every rank moves the particles it owns, sends
them to the ranks that hold them after the move, builds the profiles of its table's
particles on its block, and sums the coupling of the ghosts to their owners; the same step.
A Lees-Edwards run couples on the rectangular grid there too: the layout re-grids the
rank's block (``to_rectangular`` / ``to_oblique`` on the x rows of its column), the table
holds the particles whose stencil images reach the block.
"""
from __future__ import annotations

import numpy as np

from .coupling import (clear_points, hydro_force_torque, particle_velocity_field,
                       rigidity_increment, sample)
from . import motion as _free_motion
from .interactions import as_forces
from .ownership import owned_table
from .profile import Stencil, lees_edwards_profiles, particle_profiles, total_phi
from ..mesh import compiled as _compiled

__all__ = ["SPM"]


class SPM:
    """Fluid + particles by the SPM (see module docstring).  No I/O.

    forces : the non-hydrodynamic forces / torques (N, 3): a force object of
        kapsel.particles.interactions (Interactions, Callback) or a plain function
        ``forces(particles) -> (F, T) or (F, T, ...)`` (made a Callback);
    noise(n, dt) -> (dP, dL) : thermal impulses over one step (eqs 13-14).
    u: initial velocity for the MAC mode (default zero); ignored for 'spectral'.
    impose: make the initial field move with the particles (eq 6) at construction.
    dry: built only to be checked (``kapsel-py --check``), never stepped: no profiles, no
    imposition.
    """

    def __init__(self, fluid, particles, A, xi, rho, dx, dt, rotation=True, forces=None,
                 noise=None, u=None, impose=True, wall=None, dry=False):
        self.fluid = fluid
        self.p = particles
        self.rho = float(rho)
        self.dx = float(dx)
        self.dt = float(dt)
        self.rotation = bool(rotation)
        self.forces = as_forces(forces)
        self.noise = noise
        if hasattr(fluid, "add_solenoidal"):
            self.mode = "spectral"
            self.shape = tuple(fluid.grid.shape)
            # u* and the rigidity increment du live in the solver's two real vector fields,
            # which it only uses inside its own step (``scratch_real``; issue 25)
            self.u, self._du_buf = fluid.scratch_real()
        elif hasattr(fluid, "step"):
            self.mode = "mac"
            self.shape = tuple(fluid.shape)
            ushape = (3,) + tuple(getattr(fluid, "fshape", self.shape))   # a rank's block
            self.u = np.zeros(ushape) if u is None else np.asarray(u, dtype=float)
            if self.u.shape != ushape:
                raise ValueError("u must have shape (3, NX, NY, NZ)")
        else:
            raise TypeError("fluid must be a SpectralNS or a MACSolver")
        self.size = int(np.prod(self.shape))
        # the fluid's layout (kapsel.mesh.grid.Grid; distributed, kapsel.mesh.pencil: this
        # rank's block of the fields)
        g = self.layout = fluid.grid
        if wall is not None and not g.whole_mesh:
            raise ValueError("walls do not run distributed")
        self.fshape = tuple(g.local_shape)
        self.fsize = int(np.prod(self.fshape))
        # the rows of the particles whose stencil meets the block (the layout's near_rows;
        # all of them until the first profiles)
        self._T = np.arange(particles.n)
        self.wall = wall
        self._sole = None       # MAC: the spectral projection of the whole u (step 6)
        if self.mode == "mac" and not dry:
            if getattr(fluid, "oblique", False):
                from ..fluid.oblique import MetricProjector
                self._sole = MetricProjector(g, fluid)
            else:
                from ..fluid.spectral import SpectralProjector
                self._sole = SpectralProjector(g)
        # kept 0 between steps: a step scatters du onto its stencil points and clears them
        # (with walls du is dense: cleared whole at the start of the next step instead)
        self._du = None
        if particles.n or wall is not None:   # spectral: the solver's scratch, zeroed each step
            self._du = (self._du_buf if self.mode == "spectral"
                        else np.zeros((3,) + self.fshape))
        self._psum = np.zeros(self.fsize) if wall is not None else None   # phi_sum (flat)
        self._us = None         # u* at the stencil points, sampled once a step
        self._du_points = None  # du at the stencil points of the last step (last_increment)
        self._du_stepped = False
        self.box = np.array(self.shape, dtype=float) * self.dx
        # oblique fluid (kapsel.fluid.oblique, Lees-Edwards): profiles on the sheared grid,
        # velocities relative to the imposed shear flow, Lees-Edwards images
        self.oblique = getattr(fluid, "oblique", False)
        # an oblique run couples on the rectangular grid as the original (sp_3d_ns.cxx
        # Time_evolution_hydro_OBL[_fdm]): u interpolated from the oblique grid
        # (Transform_obl_u), the profiles there with Lees-Edwards images, the increment
        # interpolated back; the layout re-grids a rank's block (its x rows gathered) and
        # holds the particles whose images reach the block, so a distributed run is the
        # same algorithm.  With walls (one process only) the coupling is on the oblique grid.
        self.rect = bool(self.oblique and wall is None)
        self.interpolation = "linear"       # the original's OBL_INT (models set it)
        smax = fluid.max_frame_strain if self.oblique else 0.0
        self.stencil = (Stencil(A, xi, dx, strain_max=0.0 if self.rect else smax)
                        if particles.n else None)
        self._uc = None         # rect: u* on the rectangular grid
        # spectral and rect: the re-gridding goes through the solver's two scratch fields,
        # with no field of its own: u* (oblique, in self.u) re-gridded into the increment's
        # buffer, the increment made in u*'s (done with once re-gridded), then re-gridded
        # back into the first (issue 25: two fields a step neither allocated nor faulted in)
        self._regrid_in_scratch = bool(self.rect and self.mode == "spectral"
                                       and self._du is not None)
        if self._regrid_in_scratch:
            self._du = self.u
        self.moment = np.zeros((3, 3))    # sum du_a r_b of the last step (particle stress)
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
        # the layout's particle table (``owned``): particles owned by the rank holding their
        # stencil's base point (rigid bodies: that of their first bead), with ghosts
        # (kapsel.particles.ownership); on one process every row, no ghosts (kapsel.mesh.grid
        # WholeTable)
        self.owned = None
        self._bodies = None
        self.p_own = self.whole = particles     # owned rows, whole table (one process: all)
        self.n_global = particles.n
        self._janus_whole = self.janus
        if particles.n:
            self._own(particles)
        if particles.n and not dry:
            self._profiles()
        if (particles.n or wall is not None) and not dry and impose:
            self.impose_particle_velocity()

    # ------------------------------------------------------------------ masses
    @property
    def mass(self):
        """M_i of the particles this rank couples (eq 9: MASS_RATIO RHO 4/3 pi A^3)."""
        return self._sub(self.p.mass)

    @property
    def inertia(self):
        return self._sub(self.p.inertia)

    # ------------------------------------------------------------------ profiles
    def _profiles(self):
        """phi_i, r at the current positions; phi_sum and the weights w_i (step 3)."""
        p = self.p
        g, y0 = (self.fluid.frame_strain, self.fluid.y0) if self.oblique else (0.0, 0.0)
        # the rows whose stencil meets the block (owned first; all on one process)
        if self.rect:                    # the rectangular grid under Lees-Edwards images
            T = self.layout.near_rows(p.R, self.stencil.offsets, self.dx,
                                      images=self.fluid.image_offset)
        else:
            T = self.layout.near_rows(p.R, self.stencil.offsets, self.dx, g, y0)
        n = self.owned.n_own
        if self._bodies is not None:     # every owned bead (a body's may lie elsewhere)
            T = np.concatenate([np.arange(n), T[T >= n]])
        self._T = T
        if self.rect:                    # on the rectangular grid, Lees-Edwards images
            self.idx, self.phi_i, self.r = lees_edwards_profiles(
                p.R[T], self.stencil, self.shape, self.dx, self.fluid.image_offset)
        else:
            self.idx, self.phi_i, self.r = particle_profiles(p.R[T], self.stencil, self.shape,
                                                             self.dx, g, y0)
        # DX^3 sum_x phi_i over the whole profile (before the layout cuts it to the block)
        self.grid_volume = self.phi_i.sum(axis=1) * self.dx ** 3
        self.idx, self.phi_i, self._on = self.layout.cut_stencils(self.idx, self.phi_i)
        self._weights()

    def _weights(self):
        """w_i = phi_i / max(phi_sum, 1) at the stencil points; phi_sum = sum_i phi_i
        (+ phi_wall), on the rank's block (its table holds every particle meeting it)."""
        if self._psum is None:
            self._psum = np.zeros(self.fsize)
        ps = self._psum
        if self.wall is not None:
            ps[...] = self.wall.phi.reshape(-1)
        K = _compiled.coupling
        if (K is not None and self.idx.flags.c_contiguous and self.phi_i.flags.c_contiguous
                and self.idx.dtype == np.int64 and self.idx.ndim == 2):
            w = getattr(self, "w", None)                # the same operations, one call,
            if w is None or w.shape != self.phi_i.shape:    # into the last step's array
                w = np.empty_like(self.phi_i)
            K.weights(ps, self.idx, self.phi_i, w, self.wall is None)
            self.w = w
            return
        np.add.at(ps, self.idx.reshape(-1), self.phi_i.reshape(-1))
        s = ps[self.idx]
        np.maximum(s, 1.0, out=s)
        self.w = self.phi_i / s
        if self.wall is None:
            ps[self.idx.reshape(-1)] = 0.0   # 0 again for the next step (phi_sum is dense
        #                                      and kept only with walls: _wall_increment)

    def _phi_sum(self):
        """phi_sum (flat) of the current profiles, walls included."""
        if self.wall is not None:
            return self._psum
        s = np.zeros(self.fsize)
        if self.p.n:
            np.add.at(s, self.idx.reshape(-1), self.phi_i.reshape(-1))
        return s

    # ------------------------------------------------------------------ the rank's block
    @property
    def rows(self):
        """The table rows of the stencil arrays (idx, phi_i, r, w): the particles this rank
        couples (every row on one process)."""
        return self._T

    @property
    def on_block(self):
        """(rows, S): 1 where a stencil point lies on this rank's block (all 1 on one
        process)."""
        return self._on

    def of_rows(self, a):
        """``a``'s rows of the particles this rank couples (``rows``)."""
        return self._sub(a)

    def to_table(self, a):
        """A per-row array of the coupled particles as a whole-table array (0 elsewhere)."""
        return self._full(a)

    def _sub(self, a):
        """The rows of the particles this rank couples (all of them on one process)."""
        return a[self._T]

    def _full(self, a):
        out = np.zeros((self.p.n,) + a.shape[1:])
        out[self._T] = a
        return out

    def _reduce(self, *arrays):
        """Sum of per-particle arrays over the ranks (the layout's ``reduce``)."""
        return self.layout.reduce(*arrays)

    # ------------------------------------------------------------------ owned particles
    def _own(self, whole):
        """Keep this rank's owned particles and ghosts of the whole table ``whole`` (the
        model's, the same on every rank at the start; kapsel.particles.ownership; on one
        process all of it).  ``self.p`` is then the local table, owned rows first."""
        from .rigid import RigidBodies
        f = self.forces
        cutoff = float(f.cutoff) if f is not None else 0.0
        # the Lees-Edwards images of the rectangular grid the profiles are built on
        images = (lambda: self.fluid.image_offset) if self.rect else None
        c = getattr(whole, "constraints", None)
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
        self.owned = owned_table(self.layout, self.stencil.offsets, self.dx, cutoff, images,
                                 bodies=bodies, extra_width=width)
        self.whole = whole
        self.n_global = whole.n
        self._janus_whole = getattr(whole, "janus", None)   # janus.Janus of all, or None
        self._released = False
        self._take(self.owned.scatter(whole, extra=extra))

    def _take(self, p):
        """Make ``p`` (owned rows first, then ghosts) the local table."""
        o = self.owned
        self.p = p
        self.p_own = o.owned_view(p)            # the owned rows (views: updates write through)
        c = o.local_constraints(self._bodies, self._pins)   # the bodies this rank owns, whole,
        self.motion = _free_motion                          # or its pinned rows
        if c is not None:
            self.p_own.constraints = self.motion = c
        if self._janus_whole is not None:       # the self-propulsion of the table's rows
            self.janus = o.local_janus(self._janus_whole)

    def gather(self):
        """Collective: the owned rows of every rank into the whole table on rank 0 (the
        output writers and the restart read it there)."""
        if not self.n_global:
            return
        root = self.owned.me == 0
        rec = self.owned.gather(self.p, self.whole if root else None, extra=self._records())
        if rec is not None:                     # the bodies' state into the global bodies
            self._bodies.take_records(np.arange(self.n_global), rec)

    def _records(self):
        """The extra columns of the owned rows (the state of rigid bodies), or None."""
        if self._bodies is None:
            return None
        return self.motion.bead_records()

    def owned_particles(self):
        """The particles this rank accounts for in global sums (energies): its owned rows
        (all of them on one process)."""
        return self.p_own

    def _exchange(self):
        """Migration and new halos (kapsel.particles.ownership ``exchange``); the whole
        table's rows are dropped on the ranks other than 0 from the first step on (a
        restart read before fills them on every rank)."""
        if not self._released:
            self._released = True
            self.owned.release(self.whole)
        self._take(self.owned.exchange(self.p, extra=self._records()))

    def refresh(self):
        """Recompute the profiles after the positions were set from outside (a restart)."""
        if self.n_global:
            extra = None if self._bodies is None else self._bodies.bead_records()
            self._take(self.owned.scatter(self.whole, extra=extra))
            self._profiles()

    # ------------------------------------------------------------------ fields
    def phi(self):
        """Total profile phi = sum_i phi_i (eq 4), (NX, NY, NZ), walls not included."""
        if not self.n_global:
            return np.zeros(self.fshape)
        phi = total_phi(self.idx, self.phi_i, self.fsize).reshape(self.fshape)
        if self.rect:       # on the fluid's oblique grid, as the original's phi_obl (a
            #                 collective when distributed: every rank re-grids its block)
            return self._to_oblique(phi, "linear")     # (A2a_oblique: always linear)
        return phi

    def phi_at(self, R):
        """min(sum_i phi_i, 1) of the profiles at positions ``R`` (one per row of the table)
        made on the rectangular grid under the Lees-Edwards images of the frame now,
        re-gridded to the fluid's oblique grid (linear): the original's Make_phi_s_OBL and
        A2a_oblique (a rect-coupled run; on a rank's block, a collective)."""
        off = self.fluid.image_offset
        T = self.layout.near_rows(R, self.stencil.offsets, self.dx, images=off)
        idx, phi_i, _ = lees_edwards_profiles(R[T], self.stencil, self.shape, self.dx, off)
        idx, phi_i, _ = self.layout.cut_stencils(idx, phi_i)
        phi = total_phi(idx, phi_i, self.fsize).reshape(self.fshape)
        np.minimum(phi, 1.0, out=phi)
        return self._to_oblique(phi, "linear")

    def phi_rectangular(self):
        """phi on the rectangular grid (a rect-coupled run: the profiles' own grid)."""
        if self.rect or not self.p.n:
            return total_phi(self.idx, self.phi_i, self.fsize).reshape(self.fshape) \
                if self.p.n else np.zeros(self.fshape)
        return self._to_rect(self.phi())

    # ------------------------------------------------------------------ frames (rect)
    def _to_rect(self, u, out=None, **lines):
        """u* (Cartesian deviation, oblique grid) -> the rectangular grid (Transform_obl_u
        oblique2cartesian without the mean flow: the coupling uses deviations); the
        layout's re-gridding of this process's block (a collective when distributed);
        ``lines``: on some lines only (kapsel.mesh.regrid.shift_rows)."""
        f = self.fluid
        return self.layout.to_rectangular(u, f.frame_strain, self.interpolation,
                                          f.y0 / self.dx, out=out, **lines)

    def _to_oblique(self, a, method=None, out=None, **lines):
        f = self.fluid
        return self.layout.to_oblique(a, f.frame_strain, method or self.interpolation,
                                      f.y0 / self.dx, out=out, **lines)

    def _increment_oblique(self, du):
        """rect: the increment re-gridded onto the fluid's oblique grid (Transform_obl_u
        cartesian2oblique), into the buffer u* on the rectangular grid had (done with); on
        the particles' lines only when u* was (its other lines are 0)."""
        lines = {} if self._lines_now is None else {"lines": self._lines_now, "zero": True}
        return self._to_oblique(du, out=self._regrid_out, **lines)

    @property
    def _regrid_out(self):
        """rect: the buffer a re-gridding writes (the increment's, ``_regrid_in_scratch``),
        or None (a new array)."""
        return self._du_buf if self._regrid_in_scratch else None

    _lines_now = None       # rect: the lines of this step's re-gridding (None: every line)
    _line_mask = None

    def _stencil_lines(self):
        """rect, on one process, with few particles: the lines along x (y, z) of the
        rectangular grid the particles' stencils meet, a bool (NY, NZ) mask.  u* is read at
        the stencil points only and the increment is 0 off them, and each line is re-gridded
        on its own, so these lines alone give the same numbers (kapsel.mesh.regrid).  None
        (every line) when distributed (a line's increment comes from the x blocks of
        several ranks) or when the stencils may meet half the lines or more."""
        ny, nz = self.fshape[1], self.fshape[2]
        if not self.layout.whole_mesh or 2 * self.idx.shape[0] * self.stencil.lines >= ny * nz:
            return None
        if self._line_mask is None:
            self._line_mask = np.zeros((ny, nz), dtype=bool)
        m = self._line_mask
        m[...] = False
        m.reshape(-1)[np.remainder(self.idx.reshape(-1), ny * nz)] = True
        return m

    def _coupling_u(self):
        """The field the particles couple to: u* (rect: on the rectangular grid)."""
        if self.rect:
            self._uc = None                 # the last step's, freed before the new one is made
            self._lines_now = self._stencil_lines() if self._regrid_in_scratch else None
            lines = {} if self._lines_now is None else {"lines": self._lines_now,
                                                        "zero": False}   # (read there only)
            self._uc = self._to_rect(self.u, self._regrid_out, **lines)
            return self._uc
        return self.u

    def particle_velocity(self):
        """phi u_p of eq 6 (sum_i w_i (V_i + Omega_i x r)), (3, NX, NY, NZ)."""
        p = self.p
        return particle_velocity_field(self.idx, self.w, self.r, self._sub(p.v),
                                       self._sub(p.omega), self.fsize, self.fshape)

    # ------------------------------------------------------------------ fluid access
    def velocity(self):
        """Current velocity field u (3, NX, NY, NZ); spectral mode: transformed into the
        solver's scratch (``self.u``), valid until the next step (copy it to keep it)."""
        if self.mode == "spectral":
            return self.fluid.velocity(out=self.u)
        return self.u

    def _fluid_step(self):
        if self.mode == "spectral":               # u* made within the step (a collective
            if self.n_global or self.wall is not None:        # when distributed)
                self.fluid.step(velocity=self.u)
            else:
                self.fluid.step()
        else:
            self.fluid.step(self.u)

    def _add_solenoidal(self, du, start=False):
        """Step 6: spectral u += P T du; MAC u <- P T (u + du) (module docstring).  An
        oblique fluid's projection does not truncate (the original's Solenoidal_uk_OBL),
        except at the ``start`` (the original imposes with its unsheared, truncating
        routines: Make_f_particle_dt_sole)."""
        if self.mode == "spectral":
            if self._regrid_in_scratch and du is self._du_buf:   # (its own: overwritten)
                self.fluid.add_solenoidal(du, overwrite=True)
            else:
                self.fluid.add_solenoidal(du)
            if start and self.oblique:
                self.fluid.truncate()
        else:
            if du is not None:
                self.u += du
            if start and self.oblique:
                self._sole(self.u, truncate=True)
            else:
                self._sole(self.u)

    def _projection(self):
        """f -> P f, the spectral projection of a real field (3, NX, NY, NZ) without the
        truncation and without touching the fluid's state (diagnostics, tests)."""
        grid = self.fluid.grid if self.mode == "spectral" else self._sole.grid

        def project(f):
            h = np.fft.rfftn(f, axes=(1, 2, 3))
            grid.project(h)
            return np.fft.irfftn(h, s=self.shape, axes=(1, 2, 3))
        return project

    def impose_particle_velocity(self, deviation=False):
        """u <- u + P T [sum_i w_i (V_i + Omega_i x r) - min(phi_sum, 1) u] (eq 6; walls at
        rest included), then the mean flow is removed: the original's start
        (sp_3d_ns.cxx main: uk_dc = 0 after the imposition; kapsel-py does the same for the
        FDM types, whose original starts from the Fourier coefficients of this field).
        On an oblique fluid V is a laboratory-frame velocity (V minus the imposed flow is
        imposed on the deviation field), or with ``deviation`` a deviation from the imposed
        flow (the sheared types' start: ``start_sheared``)."""
        u = self.fluid.velocity(out=self.u) if self.mode == "spectral" else self.u
        self._deviation = bool(deviation)
        try:
            du = self._rigidity(self._coupling_u() if self.rect and self.n_global else u)
        finally:
            self._deviation = False
        self._uc = None                     # rect: done with u* (memory for the re-gridding)
        self._add_solenoidal(self._increment_oblique(du) if self.rect and self.n_global else du,
                             start=True)
        if self.p.n and self.wall is None:
            clear_points(du, self.idx)
        if self.mode == "spectral":
            self.fluid.zero_mean()
        else:
            for c in range(3):
                self.u[c] -= self.fluid.mean(self.u[c])

    _deviation = False

    def start_sheared(self, impose=True):
        """The sheared types' start, as the original's: the particle velocities imposed as
        they are given, as deviations from the imposed flow on an oblique grid (sp_3d_ns.cxx
        main imposes them on the deviation field with its unsheared routines), then
        V_x = 0 and Omega_z = 0 (init_particle.cxx Show_parameter), so particles given at
        rest start at rest with the shear flow in them.  Not for a continued run (the
        original zeroes them there too, a bug: the restart's velocities are kept).  Rigid
        bodies keep their velocities (their beads' follow the bodies)."""
        if impose and (self.n_global or self.wall is not None):
            self.impose_particle_velocity(deviation=self.oblique)
        from .rigid import RigidBodies
        if isinstance(getattr(self.p_own, "constraints", None), RigidBodies) or (
                self._bodies is not None):
            return
        for t in (self.p, self.whole):            # (the same table on one process)
            if t.n:
                t.v[:, 0] = 0.0
                t.omega[:, 2] = 0.0

    def _relative_velocity(self):
        """(V relative to the imposed flow at the centres, gamma_dot) for an oblique fluid,
        else (V, 0); V as it is during a deviation imposition (``start_sheared``)."""
        if not self.oblique or self._deviation:
            return self.p.v, 0.0
        return self.p.v - self.fluid.background(self.p.R), self.fluid.shear_rate_now

    # ------------------------------------------------------------------ coupling
    def _hydro_sums(self):
        """(u* at the stencil points, F_H, T_H) of the particles this rank couples (step 4):
        u* sampled once a step (the rigidity increment uses it too), the force and torque
        over this rank's part of their profiles."""
        if self._us is None or self._us.shape[1:] != self.idx.shape:
            self._us = np.empty((3,) + self.idx.shape)
        uc = self._uc if self.rect else self.u
        us = sample(uc, self.idx, out=self._us)
        v, shear = self._relative_velocity()
        F_H, T_H = hydro_force_torque(uc, self.idx, self.w, self.r, self._sub(v),
                                      self._sub(self.p.omega), self.rho, self.dx, self.dt,
                                      shear=shear, sampled=us)
        return us, F_H, T_H

    def _rigidity(self, u, sampled=None):
        """du of step 6 into the (zeroed) du buffer, with the walls' part."""
        p = self.p
        du = self._du
        if self.wall is not None or self.mode == "spectral":
            du.fill(0.0)                      # dense after a wall step; spectral: the
            #                                   solver's scratch, overwritten by its step
        if p.n:
            v, shear = self._relative_velocity()
            du = rigidity_increment(u, self.idx, self.w, self.r, self._sub(v),
                                    self._sub(p.omega), self.fsize, out=du, shear=shear,
                                    moment=self.moment if self.oblique else None,
                                    sampled=sampled, zeroed=True)
        elif self.oblique:
            self.moment[...] = 0.0            # (no particle on this rank's block)
        if self.oblique and self.n_global:    # (a collective when distributed)
            self.moment[...] = self._reduce(self.moment)[0]
        if self.wall is not None:
            self._wall_increment(du, u)
        return du

    def _wall_increment(self, du, u):
        """du -= (phi_wall / max(phi_sum, 1)) u* (the walls at rest, step 6)."""
        if not self.p.n:
            self._psum[...] = self.wall.phi.reshape(-1)
        s = np.maximum(self._psum.reshape(self.fshape), 1.0)
        pw = self.wall.phi / s
        for c in range(3):
            du[c, :self.shape[0], :self.shape[1], :self.shape[2]] -= pw * u[c]

    def _other_forces(self):
        """(F_other, T_other) of the particles this rank moves, at R^{n+1}."""
        if self.forces is None:
            return None, None
        return self.owned.other_forces(self.forces, self.p, self._reduce)

    def _impulses(self):
        if self.noise is None:
            return None, None
        dP, dL = self.noise(self.n_global, self.dt)       # the serial stream, this rank's rows
        return self.owned.own_rows(dP), self.owned.own_rows(dL)

    def _move(self, first):
        """Step 2 for the particles this rank owns (all on one process): positions and
        orientations; Lees-Edwards images in an oblique frame; then the migration and the
        new halos (none on one process)."""
        q = self.p_own
        le = self.oblique and not self._own_images
        if le:                    # Lees-Edwards images instead of the periodic wrap
            self.motion.update_positions(q, self.dt, self.box, self.rotation, first=first,
                                         wrap_box=False)
            self.fluid.wrap_particles(q)
        else:
            self.motion.update_positions(q, self.dt, self.box, self.rotation, first=first)
        self._exchange()

    # ------------------------------------------------------------------ step
    def step(self, **fluid):
        """Advance fluid and particles by dt (steps 1-6 of the module docstring); ``fluid``:
        what this step's fluid solve takes besides u (a subclass's ``_fluid_step``: the
        Model-H force and viscosity field of kapsel.models.fdm)."""
        self._fluid_step(**fluid)
        if self.n_global:
            first = self.step_index == 0
            self._move(first)
            self._profiles()
            uc = self._coupling_u()
            us, F_H, T_H = self._hydro_sums()
            F_H, T_H = self.owned.sum_to_owners(self._full, F_H, T_H)   # ghosts' to owners
            F_o, T_o = self._other_forces()
            dP, dL = self._impulses()
            janus = self._janus_whole
            if janus is not None and janus.active:         # self force, squirmer slip
                self.janus.update_velocities(self, F_H, T_H, F_o, T_o, dP, dL)
            else:
                self.motion.update_velocities(self.p_own, F_H, T_H, F_o, T_o, self.dt,
                                              self.rotation, dP, dL, first=first)
            self.owned.refresh(self.p.v, self.p.omega)   # the owners' velocities to ghosts
            du = self._rigidity(uc, sampled=us)
            if self.rect:                   # u* on the rectangular grid is done with: its
                uc = self._uc = None        # memory serves the re-gridding below
            # rect: the increment back on the oblique grid (Transform_obl_u cartesian2oblique)
            self._add_solenoidal(self._increment_oblique(du) if self.rect else du)
            self._du_stepped = True
            if self.wall is None:
                flat = self.idx.reshape(-1)
                if self._du_points is None or self._du_points.shape[1] != flat.size:
                    self._du_points = np.empty((3, flat.size))
                for c in range(3):            # kept for last_increment (diagnostics)
                    np.take(du[c].reshape(-1), flat, out=self._du_points[c])
                clear_points(du, self.idx)    # du is all 0 again for the next step
        elif self.wall is not None:
            if self.mode == "spectral":
                self.fluid.velocity(out=self.u)
            self._add_solenoidal(self._rigidity(self.u))
            self._du_stepped = True
        elif self.mode == "mac":
            self._add_solenoidal(None)
        self.step_index += 1

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
        if self.rect:                         # on the fluid's (oblique) grid
            return self._to_oblique(du)
        return du

    def fluid_momentum(self):
        """RHO DX^3 sum_x u over the whole field (particle interiors included)."""
        if self.mode == "spectral":
            return np.asarray(self.fluid.momentum(), dtype=float)
        u = self.velocity()
        return self.rho * self.dx ** 3 * u.reshape(3, -1).sum(axis=1)

    def total_momentum(self):
        """P = RHO DX^3 sum u + sum_i (M_i - RHO V_p,i) V_i with V_p,i = DX^3 sum_x w_i at
        the current positions: conserved with no external force, noise or FIX_CELL up to
        the change of V_p,i from step to step and the profiles' first moment (module
        docstring)."""
        P = self.fluid_momentum()
        if self.p.n:
            vp = self.w.sum(axis=1) * self.dx ** 3
            dM = self.mass - self.rho * vp
            P = P + (dM[:, None] * self._sub(self.p.v)).sum(axis=0)
        return P

