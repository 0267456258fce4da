"""Driving a run from Python: ``Simulation`` (HOOMD-blue's and Oceananigans' ``Simulation``,
ESPResSo's ``System``).

    from kapsel import Simulation
    sim = Simulation.from_udf("input.udf", overrides={"output.Num_snap": 4}, seed=1)
    sim.run(10)                       # 10 steps; the snapshots fall every output.GTS steps
    sim.particles.R, sim.field("u")   # numpy arrays of the state now
    sim.add(lambda s: print(s.step), every=5)
    sim.run()                         # to the input's end (output.GTS x output.Num_snap)

It is the command line without the flags: the same checks and messages at the start
(kapsel.startup.build: a bad input raises BadInput carrying every message, nothing
written), the same time loop (kapsel.simulation.TimeLoop), the same files.  A run stopped
by an instability, a full disk or SIGINT / SIGTERM raises kapsel.simulation.RunError
(Interrupted) with the message the command line prints; the restart holds the last good
state.  ``kapsel.cli.main`` builds this object and runs it to the end.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .activities import Activity, Callback, Every
from .startup import BadInput
from .simulation import Interrupted, NothingToDo, RunError, TimeLoop

__all__ = ["Simulation", "Particles", "BadInput", "RunError", "Interrupted", "NothingToDo",
           "Activity", "Every"]

#: the snapshot names that are fields on the mesh (kapsel.snapshot)
FIELD_NAMES = ("u", "phi", "psi", "psi_all", "flux", "pressure", "tau")


@dataclass(frozen=True)
class Particles:
    """A copy of the particles now (float64, one row per particle): positions R (the
    periodic box), velocities v, angular velocities omega, orientations q (quaternions),
    hydrodynamic forces and torques f_hydro, torque_hydro, and the forces and torques of
    the interactions (pair, bond, gravity, ...) f_r, torque_r."""

    R: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    q: np.ndarray
    f_hydro: np.ndarray
    f_r: np.ndarray
    torque_hydro: np.ndarray
    torque_r: np.ndarray

    @property
    def n(self) -> int:
        return len(self.R)


class Simulation:
    """One run of kapsel-py (module docstring); build it with ``from_udf``."""

    def __init__(self, args, prepared, locks=()):
        """From ``args`` (kapsel.cli's flags) and ``kapsel.startup.build``'s result; ``locks``
        (the output directories' locks) are released when the run ends or is closed."""
        cfg, doc, model, resumed, self.seed_drawn, source = prepared
        self.args, self.cfg, self.input_doc, self.model, self.resumed = (args, cfg, doc, model,
                                                                           resumed)
        self._locks = list(locks)
        try:
            self.loop = TimeLoop(cfg, args, doc, model, resumed, source)
        except BaseException:
            self._release()
            raise

    @classmethod
    def from_udf(cls, input: str, output: str = "output.udf", define: str = "define.udf",
                 restart: str = "restart.udf", *, overrides: dict | None = None,
                 seed: int | None = None, threads: int = 1, quiet: bool = True,
                 overwrite: bool = False, spm_drag: str = "original") -> "Simulation":
        """The run ``kapsel-py -I<input> -O<output> -D<define> -R<restart>`` would do, with
        ``overrides`` ({item path: value}, e.g. {"constitutive_eq.type": "Navier_Stokes"})
        put into the input first; the keywords are the command line's flags (``quiet``:
        no console lines on stderr, the default here).  A restart file as ``input``
        continues its run (ours or the original's).  Raises BadInput listing every
        problem; then nothing was written."""
        from . import startup
        from .parallel import DistError, start
        args = startup.build_parser().parse_args([f"-I{input}"])
        args.output, args.define, args.restart = str(output), str(define), str(restart)
        args.input = str(input)
        args.seed, args.threads, args.quiet, args.overwrite = seed, threads, quiet, overwrite
        if spm_drag not in ("original", "calibrated"):
            raise BadInput(f"spm_drag must be 'original' or 'calibrated', got {spm_drag!r}")
        args.spm_drag = spm_drag
        problem = startup.check_flags(args)
        if problem:
            raise BadInput(problem)
        try:
            args.dist = start(args)
        except DistError as e:
            raise BadInput(str(e)) from None
        locks: list = []
        try:
            prepared = startup.build(args, locks, overrides)
        except BaseException:
            for lock in locks:
                lock.close()
            raise
        return cls(args, prepared, locks)

    from_restart = from_udf

    # ----------------------------------------------------------------- running
    def run(self, steps: int | None = None, until: float | None = None) -> "Simulation":
        """Advance ``steps`` steps, or to the first step at or after time ``until``, or
        (neither given) to the input's end.  The snapshots and the restart fall where the
        command line's do, so run(10) then run(10) writes what run(20) writes.  Reaching
        the last step GTS * Num_snap ends the run as the command line does (one more step,
        the full restart, the files closed); a run cannot go past it (raise
        output.Num_snap)."""
        if steps is not None and until is not None:
            raise ValueError("give steps or until, not both")
        now, total = self.step, self.total_steps
        if until is not None:
            steps = max(0, math.ceil((until - self.time) / self.dt - 1e-9))
        target = total if steps is None else now + int(steps)
        if steps is not None and steps < 0:
            raise ValueError(f"steps must be at least 0, got {steps}")
        if target > total and not self.loop.nothing_to_do:
            raise ValueError(f"this run ends at step {total} (output.Num_snap "
                             f"{self.cfg.output.Num_snap} x output.GTS {self.cfg.output.GTS}), "
                             f"it is at step {now}: {target} is past it; raise "
                             f"output.Num_snap to run longer")
        try:
            self.loop.advance_to(target)
        finally:
            if self.loop.state == "closed":
                self._release()
        return self

    def close(self) -> None:
        """End the run here: a paused run's state saved in full to the restart (as on an
        interruption, so it continues from this step) and every file closed."""
        try:
            self.loop.close()
        finally:
            self._release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def _release(self):
        for lock in self._locks:
            lock.close()
        self._locks = []

    # ----------------------------------------------------------------- activities
    @property
    def activities(self) -> list:
        """The output activities in the order they run at a snapshot (checks, writers,
        restart, console line, the user's)."""
        return list(self.loop.outputs)

    def add(self, activity, every: int | None = None, name: str | None = None):
        """Add an output activity: a kapsel.activities.Activity, or a callable
        ``fn(simulation)`` run every ``every`` steps (default output.GTS) after the
        writers; returns the activity (for ``remove``)."""
        if not isinstance(activity, Activity):
            if not callable(activity):
                raise TypeError(f"add() takes an Activity or a callable, got {activity!r}")
            activity = Callback(activity, Every(every or self.cfg.output.GTS), name, self)
        elif every is not None:
            activity.schedule = Every(every)
        if self.loop.state == "closed":
            raise RuntimeError("this run has ended")
        if self.loop.state == "open":
            activity.open(self.loop)
        self.loop.outputs.append(activity)
        return activity

    def remove(self, activity) -> None:
        """Remove a writer or a user's activity (the object, or its name such as
        "output.udf"); an open writer is closed first."""
        found = [a for a in self.loop.outputs if a is activity or a.name == activity]
        if not found:
            raise KeyError(f"no activity {activity!r} (there are: "
                           f"{', '.join(a.name for a in self.loop.outputs)})")
        for a in found:
            if not a.removable:
                raise ValueError(f"{a.name} is part of the run, not an output to remove")
            if self.loop.state == "open":
                a.close(self.loop, "end")
            self.loop.outputs.remove(a)

    # ----------------------------------------------------------------- reading the state
    @property
    def step(self) -> int:
        return int(self.model.step_index)

    @property
    def time(self) -> float:
        return float(self.model.time)

    @property
    def dt(self) -> float:
        return float(self.model.dt)

    @property
    def total_steps(self) -> int:
        """The input's last snapshot step, output.GTS x output.Num_snap."""
        return int(self.cfg.output.total_steps)

    @property
    def ended(self) -> bool:
        return self.loop.state == "closed"

    @property
    def particles(self) -> Particles:
        """A copy of the particles now (Particles)."""
        p = self.model.whole_particles()
        n = 0 if p is None else int(p.n)

        def take(a, width=3):
            return np.zeros((n, width)) if a is None or n == 0 else np.array(a, dtype=float)
        return Particles(*(take(getattr(p, k) if n else None, 4 if k == "q" else 3)
                           for k in ("R", "v", "omega", "q", "f_hydro", "f_r",
                                     "torque_hydro", "torque_r")))

    @property
    def fields(self) -> tuple:
        """The names of the fields this type offers (of u, phi, psi, psi_all, flux,
        pressure, tau; kapsel.snapshot)."""
        snap = self.model.snapshot()
        return tuple(n for n in FIELD_NAMES if snap.offers(n))

    def field(self, name: str) -> np.ndarray:
        """A copy of the field ``name`` now: float64 indexed [component,] x, y, z in the
        rectangular frame (kapsel.snapshot); KeyError naming what the type offers."""
        if name not in FIELD_NAMES:
            raise KeyError(f"{name!r} is not a field (fields: {', '.join(FIELD_NAMES)})")
        return np.array(self.model.snapshot().get(name), dtype=float)

    def records(self) -> list[dict]:
        """The records of output.udf written so far: per record its step ("t"), kinetic
        energy "E" and, with particles, their "R", "v", "omega" (single precision as
        stored, then float64)."""
        import os

        from udf import UDFManager
        if not self.cfg.output.UDF or not os.path.exists(self.args.output):
            return []
        doc = UDFManager(self.args.output)
        out = []
        for i in range(doc.totalRecord()):
            doc.jump(i)
            rec = {"t": doc.get("t"), "E": doc.get("E")}
            if doc.size("Particles[]"):
                for k in ("R", "v", "omega"):
                    rec[k] = np.asarray(doc.getArray(f"Particles[].{k}"), dtype=float)
            out.append(rec)
        return out

    def __repr__(self):
        return (f"<Simulation {self.cfg.type} step {self.step}/{self.total_steps} "
                f"t={self.time:g}{' ended' if self.ended else ''}>")
