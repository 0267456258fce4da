"""What the time loop does besides advancing the model: activities, each on a schedule.

An *activity* (Oceananigans' callbacks and output writers, HOOMD-blue's operations with
triggers) is an object with

    schedule(step) -> bool   is it due after the step that ended at ``step``
    every_rank               True: runs on every rank between steps (checks, tables, the
                             progress line); False: an output activity, run on rank 0
                             inside the round of output of a distributed run
                             (kapsel.parallel.lockstep), with ``loop.snap`` the snapshot
    open(loop)               once, before the first step of the run
    __call__(loop)           when due
    close(loop, reason)      once, reason "end", "interrupted" or "failed"

``loop`` is the kapsel.simulation.TimeLoop that runs them.  The output activities due at a
step run in the order of the list, the checks first and the restart after the writers, as
the original writes its files (FORMAT-OUTPUT.md §1.2).
"""
from __future__ import annotations


class Every:
    """Due at every step divisible by ``n`` (HOOMD's trigger.Periodic, Oceananigans'
    IterationInterval)."""

    def __init__(self, n: int):
        if int(n) < 1:
            raise ValueError(f"a schedule's interval must be at least 1 step, got {n}")
        self.n = int(n)

    def __call__(self, step: int) -> bool:
        return step % self.n == 0

    def __repr__(self):
        return f"Every({self.n})"


class Activity:
    """Base of the activities (the protocol of the module docstring)."""

    name = "activity"
    every_rank = False
    removable = False         # a writer or a user's activity (Simulation.remove)

    def __init__(self, schedule=None):
        self.schedule = Every(1) if schedule is None else schedule

    def open(self, loop) -> None:
        pass

    def before_round(self, loop) -> None:
        """Every rank, before the round of output this activity is due in."""

    def __call__(self, loop) -> None:
        raise NotImplementedError

    def close(self, loop, reason: str) -> None:
        pass

    def __repr__(self):
        return f"<{type(self).__name__} {self.name!r} {self.schedule!r}>"


# --------------------------------------------------------------- between steps, every rank
class StabilityCheck(Activity):
    """Finite velocities and the scheme's CFL limit every min(GTS, 10) steps
    (kapsel.simulation.check_step)."""

    name = "stability check"
    every_rank = True

    def __call__(self, loop):
        from .checks import check_step
        check_step(loop.model)


class StressTable(Activity):
    """The sheared types' stress table (kapsel.progress.ShearTable): the header when made,
    a row after every step, checked first (kapsel.simulation.table_row)."""

    name = "stress table"
    every_rank = True

    def __init__(self, model, quiet):
        super().__init__()
        from .progress import ShearTable
        self.table = ShearTable(model.shear_table, model.shear_table_stream, quiet=quiet)
        self.table.print_header()

    def __call__(self, loop):
        from .checks import table_row
        self.table.row(table_row(loop.model))


class CompiledSwitch(Activity):
    """The compiled kernels switched on before the first step when they are built ahead of
    time (kapsel.mesh.compiled.from_start), else once the run's steps left repay their
    loading by numba (kapsel.mesh.compiled.want: by the steps and the mesh points, no
    clock); they give the same numbers as the numpy ones."""

    name = "compiled kernels"
    every_rank = True

    def __init__(self, start_step, total, points):
        super().__init__()
        from .mesh import compiled
        self.start, self.total, self.points = start_step, total, points
        self.on = compiled.from_start() and (compiled.enable() or True)

    def __call__(self, loop):
        from .mesh import compiled
        if self.on:
            return
        step = loop.model.step_index
        if compiled.want(step - self.start, self.total - step, self.points):
            self.on = compiled.enable() or True


class ProgressLine(Activity):
    """The heartbeat between snapshots (kapsel.progress.Progress.step); its clock starts
    when the run opens."""

    name = "progress"
    every_rank = True

    def __init__(self, total, quiet, gts, start_step):
        super().__init__()
        self.args = (total, quiet, gts, start_step)
        self.progress = None

    def open(self, loop):
        from .progress import Progress
        total, quiet, gts, start = self.args
        self.progress = Progress(total, quiet=quiet, gts=gts, start_step=start)

    def __call__(self, loop):
        self.progress.step(loop.model.step_index, loop.model.time)


# --------------------------------------------------------------- output, rank 0 in the round
class FiniteCheck(Activity):
    """Before anything is written at a snapshot: the fields and particles are finite and
    within the CFL limit (kapsel.checks check_step, a collective: on every rank before the
    round; then check_finite on the snapshot rank 0 writes)."""

    name = "finite check"

    def before_round(self, loop):
        from .checks import check_step
        check_step(loop.model)

    def __call__(self, loop):
        from .checks import check_finite
        check_finite(loop.model, loop.snap)


class WriterActivity(Activity):
    """A writer of kapsel.io.writers (output.udf, field files, EXTENDED / AVS, the .dat
    tables, the electrolyte table) at every snapshot."""

    removable = True

    def __init__(self, writer, schedule, name):
        super().__init__(schedule)
        self.writer, self.name = writer, name

    def open(self, loop):
        self.writer.open(loop.snap, loop.resumed)

    def __call__(self, loop):
        self.writer.write(loop.snap)

    def close(self, loop, reason):
        self.writer.close(reason)


class Restart(Activity):
    """restart.udf and its state file (kapsel.io.restart): the full file at the first
    snapshot of the run, at the end and on interruption, else the cheap checkpoint in the
    state file; it keeps the books of what was saved (``step``: the last saved step)."""

    name = "restart"

    def __init__(self, schedule, args, input_doc, model):
        super().__init__(schedule)
        self.args, self.doc, self.model = args, input_doc, model
        self.base = None         # fingerprint of the restart.udf text on disk
        self.step = None         # step of the last saved state
        self.full = None         # step of the last full restart.udf
        self.define_doc = None   # define.udf's schema, read once here (a run that writes)
        if model.restart_kind is not None:
            import udf
            try:
                self.define_doc = udf.UDFManager(schema_from=args.define)
            except udf.UDFError as e:
                from .errors import RunError
                raise RunError(f"cannot read -D{args.define} for the restart file: {e}") \
                    from None

    def continues(self, fingerprint, step, full):
        """The restart.udf on disk is the one the run continues: checkpoints go on
        against it, as in the run being continued."""
        self.base, self.step, self.full = fingerprint, step, full

    def __call__(self, loop):
        self.save()

    def save(self, full=False):
        model = self.model
        if model.restart_kind is None:
            return
        from .io.restart import write_checkpoint, write_restart
        args = self.args
        full = full or self.base is None
        kind, data, exact = model.restart_state(checkpoint=not full)
        if full:
            self.base = write_restart(args.restart, self.define_doc, self.doc, kind,
                                      model.step_index, model.time, model.particles, data,
                                      exact, previous=self.base)
            self.full = model.step_index
        else:
            write_checkpoint(args.restart, self.define_doc, kind, model.step_index,
                             model.time, model.particles, data, exact, self.base,
                             complete=model.checkpoint_complete)
        self.step = model.step_index

    def complete_after_failure(self, writes):
        """After a failure: restart.udf written in full from the last checkpoint."""
        if writes and self.step is not None and self.full != self.step:
            from .io.restart import complete_restart
            try:
                complete_restart(self.args.restart, self.define_doc, self.doc)
            except OSError:
                pass        # the checkpoint still continues the run from restart.udf


class SnapshotLine(Activity):
    """The original's console line at every snapshot after the first of the run
    (kapsel.progress.Progress.snapshot)."""

    name = "snapshot line"

    def __init__(self, schedule, progress_line, start_step):
        super().__init__(schedule)
        self.line, self.start = progress_line, start_step

    def __call__(self, loop):
        if loop.model.step_index != self.start:
            self.line.progress.snapshot(loop.model.step_index)


class Callback(Activity):
    """A user's callable ``fn(simulation)`` on a schedule, run on rank 0 with the output
    (kapsel.api.Simulation.add)."""

    removable = True

    def __init__(self, fn, schedule, name=None, owner=None):
        super().__init__(schedule)
        self.fn, self.owner = fn, owner
        self.name = name or getattr(fn, "__name__", "callback")

    def __call__(self, loop):
        self.fn(self.owner if self.owner is not None else loop)


def writer_name(writer) -> str:
    """The name of a writer's activity: its first file, e.g. ``output.udf``."""
    files = writer.files(False)
    return files[0][1].split(" (")[0] if files else type(writer).__name__

