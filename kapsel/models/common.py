"""What every model builds from the configuration: clock, random stream, particles, forces.

Particles: M = MASS_RATIO RHO 4/3 pi A^3, I = 2/5 M A^2 (FORMAT.md conventions); initial
positions by switch.INIT_distribution, orientations by switch.INIT_orientation (table 7).
"""
from __future__ import annotations

import secrets
import sys

import numpy as np

from ..config import ConfigError, RunConfig
from ..typespec import sheared as sheared_type
from ..particles.interactions import make_forces  # noqa: F401  (the models' import)
from ..particles.state import ParticleState
from ..state import ModelState


def time_step(cfg: RunConfig) -> float:
    """dt = factor * T_dump (auto) or delta_t (manual), manual §5.5."""
    if cfg.time.kind == "manual":
        return cfg.time.delta_t
    from ..timestep import auto_dt, electrolyte_dt
    el = cfg.electrolyte
    if el is not None:
        return electrolyte_dt(cfg.time.factor, cfg.fluid.RHO, cfg.fluid.ETA, cfg.fluid.kBT,
                              max(el.onsager), cfg.mesh.DX, cfg.mesh.shape,
                              el.frequency if el.field_kind == "AC" else 0.0)
    return auto_dt(cfg.time.factor, cfg.fluid.RHO, cfg.fluid.ETA, cfg.mesh.DX, cfg.mesh.shape)


def random_seed(args) -> int:
    """The run's seed: --seed, or drawn from the OS and reported so the run can be redone."""
    seed = getattr(args, "seed", None)
    if seed is None:
        seed = secrets.randbits(63)
        if not getattr(args, "quiet", False):
            print(f"#random seed {seed} (rerun with --seed {seed} to reproduce)",
                  file=sys.stderr)
    return int(seed)


def make_particles(cfg: RunConfig, rng: np.random.Generator) -> ParticleState:
    """Spheres, chain beads (kapsel.particles.chains) or rigid-body beads
    (kapsel.particles.rigid) of every species, placed and oriented as the input asks;
    ``constraints`` set for rigid bodies and pinned particles (and OBSTACLE janus spheres),
    ``janus`` for self-propelled spheres (kapsel.particles.janus)."""
    obj = cfg.particles.object_type
    species, ratio = [], []
    for k, s in enumerate(cfg.particles.species):
        species += [k] * s.particles
        ratio += [s.MASS_RATIO] * s.particles
    n = len(species)
    A = cfg.particles.A
    p = ParticleState.spheres(species, [A] * n, ratio, cfg.fluid.RHO)
    if n == 0:
        return p
    from ..particles import placement
    box = cfg.mesh.box
    radius = np.full(n, A)
    kind = cfg.switches.init_distribution
    user = cfg.switches.user_particles
    try:
        if obj == "rigid":
            from ..particles.rigid import build_bodies
            p.constraints = build_bodies(cfg, p, rng)
            if cfg.switches.wall is not None:
                _check_between_walls(cfg, p.R, radius)
            return p
        if obj == "chain":
            from ..particles import chains
            per_chain = [s.beads for s in cfg.particles.species for _ in range(s.number)]
            if kind != "user_specify":
                R = chains.random_walk_chains(per_chain, A, box, rng)
            else:
                R = user[:n, 0:3].copy()
                chains.check_bonds(R, box, A, per_chain)
                p.v[:] = user[:n, 3:6]
                p.omega[:] = user[:n, 10:13]
        elif kind != "user_specify":
            R = _placed(cfg, kind, n, radius, rng)
            p.placement_note = placement.overlap_note(kind, R, radius, box)
        else:
            R = user[:n, 0:3].copy()
            p.v[:] = user[:n, 3:6]
            p.omega[:] = user[:n, 10:13]
    except ValueError as e:
        raise ConfigError(str(e), path="switch.INIT_distribution.type", value=kind) from None
    p.R[:] = np.mod(R, box)
    p.R_raw[:] = R
    if cfg.switches.wall is not None:
        _check_between_walls(cfg, p.R, radius)
    okind = cfg.switches.init_orientation
    if okind == "user_specify" and kind != "user_specify":
        okind = "space_align"  # table 7: user_specify orientations need user_specify positions
    user_q = user[:n, 6:10] if okind == "user_specify" else None
    p.q[:] = placement.orientations(okind, n, rng, user_q)
    p.q_old[:] = p.q
    pin, pin_rot = tuple(cfg.switches.pin), tuple(cfg.switches.pin_rot)
    specs = [s.janus for s in cfg.particles.species]
    if obj == "spherical_particle" and any(j is not None and j.propulsion != "OFF"
                                           for j in specs):
        from ..particles.janus import Janus
        p.janus = Janus(p.species, specs, cfg.switches.SLIP_tol, cfg.switches.SLIP_iter)
        obstacles = tuple(int(i) for i in p.janus.obstacles)   # held like pinned particles
        pin, pin_rot = pin + obstacles, pin_rot + obstacles
    if pin or pin_rot:
        from ..particles.motion import Pinned
        p.constraints = Pinned(pin, pin_rot)
        p.constraints.hold(p)
    return p


def _gap(cfg):
    from ..particles.walls import clear_slab
    return clear_slab(cfg)


def _placed(cfg, kind, n, radius, rng):
    """uniform_random, random_walk, FCC or BCC spheres (kapsel.particles.placement); with
    walls in the slab between them, as the original places them in the box shortened along
    the wall axis (their sub-box along that axis; the tests across its periodic edge only
    reject or push more).  FCC and random_walk relax along the repulsive pair force of the
    run's LJ_powers, as the original's (its LJ diameter in the sheared types; random_walk
    with the 12:6 cutoff 2^(1/6) sigma, FCC with the law's own minimum, or for
    electro_osmotic_flow the run's cutoff)."""
    from ..particles import forces as pf
    from ..particles import placement
    box = cfg.mesh.box.copy()
    lo = 0.0
    axis = None
    if cfg.switches.wall is not None:
        axis, lo, hi = _gap(cfg)
        box[axis] = hi - lo
        if box[axis] <= 0:
            raise ValueError(f"no room between the walls for a particle of radius "
                             f"{cfg.particles.A:g}")
    inter = cfg.interactions
    sigma = None
    if sheared_type(getattr(cfg, "type", None)):
        sigma = pf.sheared_lj_dia(inter.LJ_powers, cfg.particles.A, cfg.particles.A_XI)
    if kind == "uniform_random":
        R = placement.uniform_random(n, radius, box, rng)
    elif kind == "BCC":
        R = placement.bcc(n, radius, box)
    elif kind == "FCC":
        cut = (pf.interaction_range(inter.LJ_powers, inter.LJ_truncate)
               if inter.LJ_powers == pf.EOF else None)
        R = placement.fcc(n, radius, box, rng,
                          placement.repulsion(box, radius, inter.LJ_powers, cut, sigma))
    elif kind == "random_walk":
        R = placement.random_walk(n, radius, box, cfg.switches.random_walk_iterations, rng,
                                  placement.repulsion(box, radius, inter.LJ_powers,
                                                      2.0 ** (1.0 / 6.0), sigma))
    else:
        raise ValueError(f"unknown INIT_distribution {kind!r}")
    if axis is not None:
        R[:, axis] += lo
    return R


def _check_between_walls(cfg, R, radius):
    """Refuse particles placed in (or against) a wall's solid."""
    axis, _, _ = _gap(cfg)
    lo = 0.5 * cfg.switches.wall.DH * cfg.mesh.DX
    x = R[:, axis]
    bad = np.flatnonzero((x - lo < radius) | (cfg.mesh.box[axis] - lo - x < radius))
    if bad.size:
        raise ConfigError(f"particle {bad[0]} at {R[bad[0]].tolist()} overlaps a wall (the "
                          f"fluid lies between {lo:g} and {cfg.mesh.box[axis] - lo:g} along "
                          f"{'XYZ'[axis]})", path="switch.INIT_distribution.type",
                          value=cfg.switches.init_distribution)


def make_noise(cfg: RunConfig, particles: ParticleState, seed: int):
    """Thermal impulses (eqs 13-14) or None at kBT = 0 (no work, no random numbers)."""
    if cfg.fluid.kBT <= 0 or particles.n == 0:
        return None
    from ..particles.noise import ThermalNoise
    noise = ThermalNoise(seed + 1)
    eta = cfg.fluid.ETA
    a = particles.radius
    gamma_v = 6 * np.pi * eta * a
    gamma_o = 8 * np.pi * eta * a ** 3
    f = cfg.fluid

    def impulses(n, dt):
        dP, dL = noise.impulses(n, dt, f.kBT, f.alpha_v, f.alpha_o, gamma_v[:, None],
                                gamma_o[:, None])
        return dP, dL
    impulses.generator = noise
    return impulses


def parallel_hdf5() -> bool:
    """Whether h5py is built with MPI (parallel HDF5): a distributed run then writes its
    per-snapshot field files with every rank writing its block instead of gathering the
    fields to rank 0.  PyPI's h5py wheels are built without it."""
    import h5py
    return bool(getattr(h5py.get_config(), "mpi", False))


def kinetic_energy(rho, dx, u, phi, particles, reduce=None, owned=False) -> float:
    """E: fluid outside the particles, 1/2 RHO sum (1 - phi)|u|^2 dx^3, plus the particles'
    translational and rotational energy.  ``reduce``: sums the fluid part over the ranks of
    a distributed run (u, phi are then this rank's blocks); ``owned``: ``particles`` are
    this rank's owned particles (kapsel.particles.ownership), their part summed alike."""
    w = 1.0 - np.clip(phi, 0.0, 1.0) if phi is not None else 1.0
    e = 0.5 * rho * dx ** 3 * float(np.sum(w * np.einsum("i...,i...->...", u, u)))
    if reduce is not None:
        e = reduce(e)
    if owned:
        ep = 0.0
        if particles.n:
            ep = 0.5 * float(np.sum(particles.mass * np.sum(particles.v ** 2, axis=1)))
            ep += 0.5 * float(np.sum(particles.inertia * np.sum(particles.omega ** 2, axis=1)))
        return e + reduce(ep)
    if particles is not None and particles.n:
        e += 0.5 * float(np.sum(particles.mass * np.sum(particles.v ** 2, axis=1)))
        e += 0.5 * float(np.sum(particles.inertia * np.sum(particles.omega ** 2, axis=1)))
    return e


class Model:
    """What every model shares: the configuration, the clock (dt, time, step_index) and the
    seeded random stream.  Subclasses implement ``advance`` by calling ``tick`` once a step."""

    wall = None     # kapsel.particles.walls.FlatWall of the types that take switch.wall

    def __init__(self, cfg: RunConfig, args):
        self.cfg = cfg
        self.quiet = getattr(args, "quiet", False)
        self.threads = getattr(args, "threads", 1)
        # built for ``kapsel-py --check``: every check, but no work on the fields (no initial
        # rigidity imposition, no FFT plans); such a model is never advanced
        self.dry = bool(getattr(args, "check", False))
        self.dt = time_step(cfg)
        # the fields the model carries from step to step, in one place (its solvers keep
        # their persistent arrays here; the restart reads and writes them by name)
        self.state = ModelState()
        self.spm_drag = getattr(args, "spm_drag", None) or "original"
        self.time = 0.0
        self.step_index = 0
        self.seed = random_seed(args)
        self.rng = np.random.default_rng(self.seed)

        self._clock0 = (0, 0.0)     # (step, time) the clock counts from
        # identity of the run, kept across continuations (state file) and written into
        # output.udf's first line, so a continuation can tell its own output.udf
        self.run_id = secrets.token_hex(8)
        self.run_id_known = False   # True once taken from a restart's state file
        # the run's world (kapsel.parallel: one rank, or a distributed run): rank 0 writes,
        # the others serve its collectives (``lockstep``; with one rank a call runs at once)
        from ..parallel import world
        from ..parallel.lockstep import Lockstep
        self.dist = world(args)
        self.collectives = Lockstep(self.dist)
        self.collectives.register("source", self._gathered_source)
        self.collectives.register("particles", lambda: self.spm.gather())
        self.collectives.register("h5_fields", self.write_h5_fields)
        self._local_sources = {}
        self._gathered_at = None
        self.lockstep = self.collectives

    def spm_radius(self) -> float:
        """The radius of the SPM profile: A, or with ``--spm-drag calibrated`` the radius
        whose hydrodynamic radius is A (kapsel.particles.drag_calibration)."""
        cfg = self.cfg
        A = cfg.particles.A
        if self.spm_drag == "original" or not cfg.particles.count:
            return A
        where = f"--spm-drag {self.spm_drag}"
        if cfg.spec.ions:
            raise ConfigError("not available for Electrolyte (the ions' profile would keep "
                              "the radius A)", where=where)
        from ..particles.drag_calibration import OutOfCalibration, profile_radius
        try:
            return profile_radius(A, cfg.particles.A_XI, cfg.fluid.ETA / cfg.fluid.RHO,
                                  self.dt, cfg.mesh.DX, cfg.fluid.ns_solver)
        except OutOfCalibration as e:
            raise ConfigError(f"{e} (A_XI = {cfg.particles.A_XI:g}, DX = {cfg.mesh.DX:g}, "
                              f"dt = {self.dt:.6g}); run without it", where=where) from None

    def tick(self) -> None:
        self.step_index += 1
        s0, t0 = self._clock0
        self.time = t0 + (self.step_index - s0) * self.dt

    # ------------------------------------------------------------------ outputs
    sheared = False             # a shear type: offers the "shear" record (shear_record())

    def frame_strain(self) -> float:
        """degree_oblique: the strain of the oblique frame (0 for unsheared grids)."""
        return 0.0

    def field_sources(self) -> dict:
        """Field name -> function computing it (kapsel.snapshot lists the names)."""
        return {}

    def snapshot(self):
        """What this model offers the output writers now (kapsel.snapshot.Snapshot)."""
        from ..snapshot import Snapshot
        src = {"E": self.kinetic_energy, "record": self.record_items}
        src.update(self.field_sources())
        if self.sheared:
            src["shear"] = self.shear_record
        self.gather_particles()
        p = self.particles
        if p is not None and p.n:
            from ..particles.rigid import RigidBodies
            if isinstance(p.constraints, RigidBodies):
                src["E_rot"] = p.constraints.rotational_energies
        h5_fields = None
        self._local_sources = src      # every source a collective (gathered to rank 0)
        src = {name: (lambda name=name: self.collectives.call("source", name)) for name in src}
        if self.dist.size > 1 and parallel_hdf5():     # the writer's choice: each rank its block
            h5_fields = (lambda tmp, datasets, attrs:
                         self.collectives.call("h5_fields", tmp, datasets, attrs))
        return Snapshot(step=self.step_index, time=self.time, dt=self.dt,
                        shape=tuple(self.cfg.mesh.shape), dx=self.cfg.mesh.DX, particles=p,
                        strain=float(self.frame_strain()), sheared=self.sheared, sources=src,
                        h5_fields=h5_fields)

    def write_h5_fields(self, tmp, datasets, attrs):
        """Every rank of a distributed run whose h5py has MPI (parallel HDF5): the field
        datasets ``(name, source, component)`` of one HDF5 file, each (NZ, NY, NX) float64
        as a plain run writes them (kapsel.io.fields), every rank writing its block; a source
        computed on rank 0 from gathered fields (``Gathered``) is written by rank 0 alone."""
        import h5py
        from ..mesh.pencil import Gathered
        g = self.grid
        (x0, x1), (y0, y1), _ = g.real_range
        nx, ny, nz = g.shape
        values = {}
        with h5py.File(tmp, "w", driver="mpio", comm=self.dist.comm) as f:
            for name, source, comp in datasets:
                if source not in values:
                    values[source] = self._local_sources[source]()
                v = values[source]
                d = f.create_dataset(name, shape=(nz, ny, nx), dtype="<f8")
                if isinstance(v, Gathered):
                    if self.dist.root:
                        a = v.value if comp is None else v.value[comp]
                        d[...] = np.ascontiguousarray(a.T, dtype=float)
                else:
                    a = v if comp is None else v[comp]
                    d[:, y0:y1, x0:x1] = np.ascontiguousarray(a.T, dtype=float)
            for key, value in attrs.items():
                f.attrs[key] = value

    def _owned(self):
        """The SPM whose particles are owned by ranks (on one process all by this one),
        else None (no particles, no SPM)."""
        spm = getattr(self, "spm", None)
        return spm if getattr(spm, "owned", None) is not None else None

    def _partial_particles(self) -> bool:
        """Whether the SPM's particle table is a rank's part of the run's (kapsel.parallel.
        particles.Owned): its sums (the kinetic energy) are then summed over the ranks; on
        one process (kapsel.particles.ownership.WholeTable) or without particles it is the whole."""
        spm = self._owned()
        return spm is not None and spm.owned.partial

    def gather_particles(self):
        """Distributed run with owned particles: the particle table gathered into
        ``self.particles`` on rank 0 (once per step), asked by rank 0 in a round of output
        (a collective of the lockstep protocol; nothing to do elsewhere)."""
        if self._owned() is None or not self.collectives.leading:
            return
        if self._gathered_at != self.step_index:
            self.collectives.call("particles")
            self._gathered_at = self.step_index

    def whole_particles(self):
        """The whole particle table on every rank: ``particles``, or in a distributed run
        with owned particles gathered to every rank (a collective; the diagnosis of a
        failed step, where every rank must take the same path)."""
        spm = self._owned()
        if spm is None:
            return self.particles
        from ..particles.ownership import restore
        restore(self.particles)
        spm.owned.gather(spm.p, self.particles, everyone=True)
        return self.particles

    def _gathered_source(self, name):
        """A snapshot source (every rank): a field of local blocks gathered to rank 0
        (None elsewhere; on one process the field itself); sources that gather or reduce themselves
        return a ``Gathered`` (taken as is), scalars and particle data are the same
        everywhere."""
        from ..mesh.pencil import Gathered
        v = self._local_sources[name]()
        if isinstance(v, Gathered):
            return v.value
        g = self.grid
        if isinstance(v, np.ndarray) and v.ndim >= 3 and v.shape[-3:] == g.local_shape:
            return g.gather_real(v)
        return v

    # ------------------------------------------------------------------ stability
    cfl_limit = 1.0             # largest max|u| dt / DX the explicit advection takes

    def velocity_field(self) -> np.ndarray:
        """The current fluid velocity (3, NX, NY, NZ)."""
        return self.spm.velocity()

    def stability(self) -> tuple[float, str]:
        """(ratio, what): ratio > 1 means the step is past the scheme's limit; NaN when the
        velocities are not finite.  The CFL number max|u| dt / DX over the fluid and the
        particles, against ``cfl_limit``."""
        u = self.velocity_field()
        umax2 = float(np.max(np.einsum("i...,i...->...", u, u)))
        local = self._owned()          # this rank's particles (owned + ghosts)
        if local is not None and local.p.n:
            umax2 = float(np.max([umax2, np.max(np.einsum("ij,ij->i", local.p.v, local.p.v))]))
        umax2 = self.grid.max(umax2)
        p = self.particles
        if local is None and p is not None and p.n:
            umax2 = max(umax2, float(np.max(np.einsum("ij,ij->i", p.v, p.v))))
        cfl = np.sqrt(umax2) * self.dt / self.cfg.mesh.DX
        return cfl / self.cfl_limit, (f"the CFL number max|u| dt/DX = {cfl:.3g} exceeds "
                                      f"{self.cfl_limit:g}")

    # ------------------------------------------------------------------ restart
    restart_kind = None         # resume.Calculation of this model's restart file

    def restart_fields(self) -> dict:
        """Saved_Data items besides jikan and Particles (arrays by name)."""
        return {}

    def exact_state(self) -> dict:
        """What a bit-exact continuation needs beyond the schema (arrays or JSON values)."""
        return {}

    def load_fields(self, fields: dict, exact: dict | None) -> None:
        """Take the fields of a restart (see read_restart)."""

    def accumulators(self) -> dict:
        """Sums kept between records (e.g. the shear stress), as JSON values: the state file
        carries them, since the restart is written one step after the last record."""
        return {}

    def set_accumulators(self, values: dict) -> None:
        """Restore :meth:`accumulators` (a restart with its state file)."""

    checkpoint_complete = True  # checkpoint_fields() are all of restart_fields()

    def checkpoint_fields(self) -> dict:
        """The Saved_Data items a checkpoint keeps (kapsel.io.restart.write_checkpoint):
        all of them unless a model continues from its exact state alone."""
        return self.restart_fields()

    def restart_state(self, checkpoint=False):
        """(kind, Saved_Data fields, exact state) of the current state (``checkpoint``: the
        fields of checkpoint_fields())."""
        self.gather_particles()
        exact = dict(self.exact_state())
        fields = self.checkpoint_fields() if checkpoint else self.restart_fields()
        if self.particles is not None and self.particles.n:
            exact["R_raw"] = self.particles.R_raw.copy()
            # the other forces of the last step (the next velocity update's trapezoid): an
            # older define.udf's sParticle has no torque_r / fr_previous for them
            exact["f_r"] = self.particles.f_r.copy()
            exact["torque_r"] = self.particles.torque_r.copy()
            bodies = self.particles.constraints
            if hasattr(bodies, "restart_items"):          # rigid bodies: GR_* and body state
                fields = {**fields, **bodies.restart_items()}
                exact.update(bodies.exact_items())
        gen = _noise_generator(self)
        if gen is not None:
            exact["noise"] = gen.get_state()
        acc = self.accumulators()
        if acc:
            exact["accumulators"] = acc
        exact["run_id"] = self.run_id
        exact["seed"] = str(self.seed)
        return self.restart_kind, fields, exact

    def load_restart(self, saved) -> None:
        """Continue from a restart (kapsel.io.restart.Saved): clock, particles, fields, and
        with the state file the noise stream and R_raw."""
        from ..io.restart import same_kind
        if not same_kind(saved.kind, self.restart_kind):
            raise ConfigError(f"{self.cfg.type} continues from a {self.restart_kind} restart, "
                              f"not {saved.kind}", path="resume.Calculation", value=saved.kind)
        arrays = [v for v in saved.fields.values() if isinstance(v, np.ndarray)]
        if not arrays and saved.particles is None and saved.exact is None:
            raise ConfigError(f"resume.{saved.kind}.Saved_Data holds no saved state: this is "
                              f"not a restart file; set resume.Calculation to NEW, or continue "
                              f"from a restart.udf written by a run",
                              path="resume.Calculation", value=saved.kind)
        exact = saved.exact
        if exact and isinstance(exact.get("run_id"), str):
            self.run_id, self.run_id_known = exact["run_id"], True
        self.step_index = saved.step
        self.time = saved.time
        spm = getattr(self, "spm", None)
        if spm is not None:     # a continued run is never at its first step (motion.py)
            spm.step_index = saved.step
        if saved.time != saved.step * self.dt:
            self._clock0 = (saved.step, saved.time)
        p = self.particles
        if p is not None and p.n:
            from ..io.restart import particles_from_table
            if self._owned() is not None:     # the whole table, then this rank's rows
                from ..particles.ownership import restore
                restore(p)
                self._gathered_at = None
            if saved.particles is None:
                raise ConfigError(f"the restart holds no particles, the input describes {p.n}",
                                  path=f"resume.{saved.kind}.Saved_Data.Particles[]", value=0)
            st = saved.particle_struct
            rows = saved.particles.shape[0]
            bodies = p.constraints if hasattr(p.constraints, "restore_rows") else None
            where = f"resume.{saved.kind}.Saved_Data.Particles[]"
            if bodies is not None and rows not in (bodies.nb, p.n):
                raise ConfigError(f"the restart holds {rows} rows, the input describes "
                                  f"{bodies.nb} rigid bodies ({p.n} beads): one row per "
                                  f"body expected", path=where, value=rows)
            per_body = bodies is not None and rows == bodies.nb    # the original's layout
            try:
                if per_body:
                    particles_from_table(bodies.state, saved.particles, st)
                    bodies.restore_rows(p, saved.fields, exact,
                                        raw=st is not None and st.index("R_raw") is not None)
                else:
                    particles_from_table(p, saved.particles, st)
            except ValueError as e:
                raise ConfigError(str(e), path=where, value=rows) from None
            if exact and "R_raw" in exact:
                p.R_raw[:] = exact["R_raw"]
            elif not per_body and (st is None or st.index("R_raw") is None):
                p.R_raw[:] = p.R                               # an sParticle without R_raw
            for name in ("f_r", "torque_r"):
                if exact and name in exact and exact[name].shape == getattr(p, name).shape:
                    getattr(p, name)[:] = exact[name]
            if not exact and not per_body:   # as the original restores (FORMAT-OUTPUT §6.4)
                p.q /= np.linalg.norm(p.q, axis=1, keepdims=True)
            if bodies is not None and not per_body:    # kapsel-py's earlier bead rows
                bodies.restore(p, exact)
        gen = _noise_generator(self)
        if gen is not None and exact and "noise" in exact:
            gen.set_state(exact["noise"])
        self.load_fields(saved.fields, exact)
        if exact and "accumulators" in exact:
            self.set_accumulators(exact["accumulators"])


def _noise_generator(model):
    spm = getattr(model, "spm", None)
    noise = getattr(spm, "noise", None) if spm is not None else None
    return getattr(noise, "generator", None)
