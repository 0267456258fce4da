"""The time loop: composes a model (fluid, phase field, particles) with the activities
of a run (kapsel.activities: writers, restart, checks, tables, progress) in TimeLoop.

A *model* is the physics of one ``constitutive_eq.type``; it does no I/O and offers:

    model.dt, model.time, model.step_index      the clock
    model.advance()                             one time step
    model.particles                             ParticleState (n may be 0)
    model.snapshot() -> Snapshot                what it offers the output writers
                                                (kapsel.snapshot: fields, particles, E, ...)

What a model offers is declared on kapsel.models.common.Model: ``lockstep`` (the output
protocol of the run's world, kapsel.parallel.lockstep; with one rank its calls run at once), ``sheared`` (a per-step stress table: ``shear_table``, ``shear_table_row``),
``restart_kind`` (None: no restart file), ``whole_particles()``, ``stability()``.

``kapsel.typespec.SOLVERS`` maps each implemented ``constitutive_eq.type`` to a factory
``make(cfg, args, input_doc) -> model``; ``TimeLoop`` drives any of them.
"""
from __future__ import annotations

import os
import signal
import sys

import numpy as np

from udf.files import disk_full, write_failure

from .checks import check_finite, check_step, first_blow_up, table_row  # noqa: F401
from .errors import InstabilityError, Interrupted, NothingToDo, RunError  # noqa: F401

def advance(model) -> None:
    """One time step, without numpy's floating-point warnings: a step that overflows or
    makes NaN is named by the run's own checks (check_step, check_finite), with the restart
    to continue from, not by a screen of RuntimeWarnings before that message.  The values
    computed are the same."""
    import numpy as np
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        model.advance()


def stability_advice(cfg) -> str:
    """What to try after a blow-up: a smaller step, and the implicit schemes the run's type
    offers and does not use yet."""
    schemes = []
    if cfg.is_fdm and cfg.fluid.ns_solver == "explicit_scheme":
        schemes.append("NS_solver implicit_scheme")
    if cfg.phase is not None and cfg.phase.ch_solver == "explicit_scheme":
        schemes.append("CH_solver implicit_scheme")
    return ("Try a smaller time_increment factor (or delta_t)"
            + (f", or the {' and '.join(schemes)}" if schemes else "") + ".")


def restart_hint(step, args=None) -> str:
    if step is None:
        return "No restart file was written"
    how = ""
    if args is not None:
        how = (f" Continue with: kapsel-py -I{args.restart} -O{args.output} -D{args.define} "
               f"-R{args.restart}")
    return f"{args.restart if args else 'The restart file'} holds the last good state (step {step}).{how}"


def planned_files(cfg, args, model, resumed: bool = False) -> list[tuple[str, str]]:
    """(directory, what) of every file ``run`` will write, for the banner and --check: the
    files of the writers ``run`` makes (kapsel.io.writers.make_writers), and the restart."""
    from .io.writers import make_writers
    files = [f for w in make_writers(cfg, args, None, model.snapshot(), announce=False)
             for f in w.files(resumed)]
    if model.restart_kind is not None:
        restart = os.path.abspath(args.restart)
        files.append((os.path.dirname(restart), f"{os.path.basename(restart)} + "
                      f"{os.path.basename(restart)}.state.npz (restart)"))
    return files


class TimeLoop:
    """A run of ``model``: set up (its activities, kapsel.activities); ``advance_to(step)``
    loops (advance; each due activity) and, at the input's last step GTS * Num_snap, ends
    the run as the original does; ``close(reason)`` closes every activity.

    ``resumed``: the model continues a restart (its clock is past 0); output.udf then gets
    the records of the continued run appended (later records of the earlier run, if any,
    are dropped), unless --overwrite asks for a new file.  ``source``: (path, fingerprint,
    step) of the restart text the model was loaded from (kapsel.startup.build_model).

    Every run is a run of the lockstep protocol (kapsel.parallel.lockstep; a plain run
    is its one-rank case): the same loop on every rank, the
    activities between steps on every rank, the output activities on rank 0 in a round of
    output the others serve.  A file that cannot be written (a full disk) stops the run,
    naming the file; records are appended whole or not at all and the restart pair is
    replaced only once both new files are complete, so the last good restart and every
    complete record stay."""

    def __init__(self, cfg, args, input_doc, model, resumed=False, source=None):
        from . import activities as act
        self.cfg, self.args, self.doc, self.model = cfg, args, input_doc, model
        self.resumed, self.source = resumed, source
        self.total = cfg.output.total_steps
        self.start = model.step_index
        self.lockstep = model.lockstep
        self.writes = self.lockstep.dist.root
        self.snap = None
        self.state = "new"       # "opening" the writers, "open" once they are, then "closed"
        self.closing = "failed"            # the reason the activities are closed with
        self.stop = None                   # the signal that asks the run to stop
        self.between, self.outputs = [], []
        gts = cfg.output.GTS
        snapshots = act.Every(gts)
        self.restart = act.Restart(snapshots, args, input_doc, model)
        self.nothing_to_do = resumed and self.start > self.total
        if self.nothing_to_do:
            self.state = "closed"
            return
        from .io.records import run_comment
        from .io.writers import make_writers
        writers = (make_writers(cfg, args, input_doc, model.snapshot(),
                                comment=run_comment(model.run_id, model.seed))
                   if self.writes else [])
        self.progress = act.ProgressLine(self.total, args.quiet, gts, self.start)
        self.between.append(act.StabilityCheck(act.Every(min(gts, 10))))
        self.table = act.StressTable(model, args.quiet) if model.sheared else None
        if self.table is not None:
            self.between.append(self.table)
        points = int(np.prod(model.cfg.mesh.shape))     # the whole mesh's
        self.between += [act.CompiledSwitch(self.start, self.total, points), self.progress]
        if resumed and self.writes and source is not None and _same_file(source[0],
                                                                         args.restart):
            self.restart.continues(source[1], self.start, source[2])
        self.outputs = [act.FiniteCheck(snapshots)]
        self.outputs += [act.WriterActivity(w, snapshots, act.writer_name(w)) for w in writers]
        self.outputs += [self.restart, act.SnapshotLine(snapshots, self.progress, self.start)]

    # ----------------------------------------------------------------- the loop
    def advance_to(self, target: int) -> None:
        """Run to step ``target`` (at most the last step); there, end the run."""
        model = self.model
        try:
            self._guarded(target)
        except MemoryError:
            self._close("failed")
            raise RunError(f"out of memory at step {model.step_index}. "
                           f"{restart_hint(self.restart.step, self.args)}. Run it where more "
                           f"memory is free (or with a higher ulimit -v).") from None
        except OSError as e:
            self._close("failed")
            args = self.args
            what = e.filename or (f"an output file in "
                                  f"{os.path.dirname(os.path.abspath(args.output))}")
            verb = "open" if getattr(e, "kapsel_opening", False) else "write"
            raise RunError(f"cannot {verb} {what} at step {model.step_index}: "
                           f"{write_failure(e)}. {restart_hint(self.restart.step, args)}."
                           + (" Free some space and continue from it." if disk_full(e)
                              else "")) from None

    def _guarded(self, target):
        if self.nothing_to_do:
            raise NothingToDo(self._nothing_to_do())
        if self.state == "closed":
            raise RuntimeError("this run has ended; build a new one to continue it from "
                               "its restart file")
        with _StopSignals(self):
            try:
                if self.state == "new":
                    self._open()
                while self.model.step_index < target:
                    self._step()
                    self._poll_stop()
                if self.model.step_index == self.total:
                    self._end()
            except BaseException:          # a RunError, or anything else: closed first
                self._close(self.closing)
                raise

    def _open(self):
        """The writers opened on the initial (or restored) state, and its snapshot when
        its step is one."""
        import udf
        model = self.model
        self.state = "opening"

        def open_outputs():
            self.snap = model.snapshot()
            for a in self.outputs:
                a.open(self)
            return self.snap
        try:
            for a in self.between:
                a.open(self)
            first = self._output(open_outputs)
        except OSError as e:            # a file that cannot be opened (advance_to says so)
            e.kapsel_opening = True
            raise
        except udf.UDFError as e:       # output.udf (or what it includes) unreadable
            raise RunError(f"cannot continue {self.args.output}: {e}. "
                           f"{restart_hint(self.restart.step, self.args)}.") from None
        self.state = "open"
        if model.step_index % self.cfg.output.GTS == 0 and model.step_index <= self.total:
            try:
                self._output_round(self._due(self.outputs), first)
            except InstabilityError as e:
                raise RunError(f"{e} in the initial state (step {model.step_index})") from None

    def _step(self):
        """One step, then each activity due after it."""
        from .errors import SolverDidNotConverge
        model = self.model
        before = model.step_index
        try:
            try:
                advance(model)
            except (ValueError, IndexError, OverflowError):
                check_step(model)   # NaN that broke the step: say so; else a real bug
                raise
            for a in self._due(self.between):
                a(self)
        except (SolverDidNotConverge, FloatingPointError, InstabilityError) as e:
            cause = first_blow_up(model)
            if cause is not None and not isinstance(e, InstabilityError):
                e = f"{cause} (then: {e})"
            self.restart.complete_after_failure(self.writes)
            raise RunError(f"the run stopped at step {before + 1}: {e}. "
                           f"{restart_hint(self.restart.step, self.args)}. "
                           f"{stability_advice(self.cfg)}") from None
        due = self._due(self.outputs)
        if due:
            try:
                self._output_round(due)
            except InstabilityError as e:
                self.restart.complete_after_failure(self.writes)
                raise RunError(f"{e} at step {model.step_index}. "
                               f"{restart_hint(self.restart.step, self.args)}. Try a smaller "
                               f"time_increment factor (or delta_t).") from None

    def _poll_stop(self):
        """SIGINT / SIGTERM: the state of this step saved in full, then Interrupted."""
        model, args = self.model, self.args
        # every rank stops at the same step
        self.stop = self.lockstep.dist.allmax(self.stop or 0) or None
        if self.stop is None:
            return
        self.closing = "interrupted"

        def last():
            check_finite(model)
            self.restart.save(full=True)
        try:
            self._output(last)
        except InstabilityError as e:    # blew up since the last check: not saved
            self.restart.complete_after_failure(self.writes)
            err = Interrupted(f"interrupted at step {model.step_index}, where {e}: that state "
                              f"is not saved. {restart_hint(self.restart.step, args)}. "
                              f"{stability_advice(self.cfg)}")
            raise err from None
        raise Interrupted(f"interrupted at step {model.step_index} (t = {model.time:g}); "
                          f"{args.output} holds every snapshot so far and {args.restart} this "
                          f"step. Continue with: kapsel-py -I{args.restart} -O{args.output} "
                          f"-D{args.define} -R{args.restart}")

    def _end(self):
        """Like the original's last loop iteration, one more step after the last snapshot,
        and the restart holds that state (ts = MSTEP after MSTEP + 1 steps, FORMAT-OUTPUT.md
        §1.2, §6.3), so either program continues it without repeating a snapshot; then
        every activity closed, and the closing lines."""
        from .errors import SolverDidNotConverge
        model = self.model
        try:
            advance(model)
            check_step(model)
            self._output(lambda: check_finite(model))
            if self.table is not None:
                self.table(self)
        except (SolverDidNotConverge, FloatingPointError, InstabilityError, ValueError,
                IndexError, OverflowError) as e:
            self.restart.complete_after_failure(self.writes)
            raise RunError(f"the step after the last snapshot failed: {e}. "
                           f"{restart_hint(self.restart.step, self.args)}.") from None
        need = self.restart.full != model.step_index
        need = self.lockstep.dist.bcast(need)    # rank 0 keeps the books of the restart
        if need:
            self._output(lambda: self.restart.save(full=True))
        self._close("end")
        sys.stdout.flush()
        self.progress.progress.summary(self.args.output if self.cfg.output.UDF else None,
                                       self.args.restart)

    def close(self, reason: str = "interrupted") -> None:
        """Stop a paused run here: the state of this step saved in full (as on an
        interruption), every activity closed with ``reason``."""
        if self.state != "open":
            self.state = "closed"
            return
        self.closing = reason
        with _StopSignals(self):
            try:
                self._output(lambda: (check_finite(self.model), self.restart.save(full=True)))
            except InstabilityError as e:
                self.restart.complete_after_failure(self.writes)
                raise RunError(f"{e} at step {self.model.step_index}: that state is not "
                               f"saved. {restart_hint(self.restart.step, self.args)}.") from None
            finally:
                self._close(reason)

    def _close(self, reason):
        if self.state == "closed":
            return
        opened = self.state in ("open", "opening")
        self.state = "closed"
        if opened:
            for a in self.between + self.outputs:
                a.close(self, reason)

    # ----------------------------------------------------------------- the pieces
    def _due(self, activities):
        step = self.model.step_index
        return [a for a in activities if a.schedule(step)]

    def _output(self, body):
        """Run ``body`` (writers, restart) on rank 0 as a round of output (one rank: at once)."""
        self.model.snapshot()          # every rank: the sources rank 0 may ask for
        return self.lockstep.round(body)

    def _output_round(self, due, snap=None):
        """The due output activities on one snapshot (``snap``, else the model's now)."""
        for a in due:
            a.before_round(self)

        def body():
            self.snap = self.model.snapshot() if snap is None else snap
            for a in due:
                a(self)
        self._output(body)

    def _nothing_to_do(self) -> str:
        cfg, args, model = self.cfg, self.args, self.model
        source = self.source
        if source is not None and source[2] != model.step_index \
                and _same_file(source[0], args.restart):
            # killed between the two renames of its last restart write: the text
            from .io.restart import complete_restart   # from the state file's copy
            complete_restart(args.restart, self.restart.define_doc or args.define, self.doc)
        return (f"{args.input} holds the end of its run (its last snapshot at step "
                f"{self.total} = output.Num_snap {cfg.output.Num_snap} x output.GTS "
                f"{cfg.output.GTS}): nothing to do. To run longer, raise output.Num_snap in "
                f"{args.input} and run kapsel-py -I{args.input} -O{args.output} "
                f"-D{args.define} -R{args.restart}")


class _StopSignals:
    """SIGINT / SIGTERM noted while the loop runs (acted on at the end of a step,
    TimeLoop._poll_stop); the previous handlers back afterwards.  Outside the main thread
    the handlers are left alone."""

    def __init__(self, loop):
        self.loop = loop

    def _note(self, signum, frame):
        self.loop.stop = signum

    def __enter__(self):
        try:
            self.old = {s: signal.signal(s, self._note) for s in (signal.SIGINT,
                                                                   signal.SIGTERM)}
        except ValueError:
            self.old = {}
        return self

    def __exit__(self, *exc):
        for s, h in self.old.items():
            signal.signal(s, h)
        return False


def run(cfg, args, input_doc, model, resumed: bool = False, source=None) -> None:
    """Run ``model`` to the end of its input (TimeLoop); raises RunError, Interrupted or
    NothingToDo."""
    TimeLoop(cfg, args, input_doc, model, resumed, source).advance_to(cfg.output.total_steps)


def _same_file(a, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False
