"""The time loop: composes a model (fluid, phase field, particles) with the outputs.

A *model* is the physics of one ``constitutive_eq.type``; it does no I/O and offers:

    model.dt, model.time, model.step_index      the clock
    model.advance()                             one time step
    model.particles                             ParticleState (n may be 0)
    model.snapshot() -> Snapshot                what it offers the output writers
                                                (kapsel.snapshot: fields, particles, E, ...)

``SOLVERS`` maps each implemented ``constitutive_eq.type`` to a factory
``make(cfg, args, input_doc) -> model``; ``run`` drives any of them.
"""
from __future__ import annotations

import errno
import os
import signal
import sys

import numpy as np

SOLVERS: dict = {}


def register(type_name: str):
    """Decorator: make ``factory(cfg, args, doc) -> model`` the model of a type."""
    def deco(factory):
        SOLVERS[type_name] = factory
        return factory
    return deco


class InstabilityError(Exception):
    """NaN or infinity in the fields or particles."""


def check_finite(model, snap=None) -> None:
    """NaN or infinity in the model's own fields (u, psi, phi) or particles."""
    import numpy as np
    snap = model.snapshot() if snap is None else snap
    for name in ("u", "psi", "phi"):
        if snap.offers(name) and not np.isfinite(snap.get(name)).all():
            raise InstabilityError(f"the field {name} is not finite (NaN or infinity)")
    p = model.particles
    if p is not None and p.n and not (np.isfinite(p.R).all() and np.isfinite(p.v).all()):
        raise InstabilityError("particle positions or velocities are not finite")


def advance(model) -> None:
    """One time step, without numpy's floating-point warnings: a step that overflows or
    makes NaN is named by the run's own checks (check_step, check_finite), with the restart
    to continue from, not by a screen of RuntimeWarnings before that message.  The values
    computed are the same."""
    import numpy as np
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        model.advance()


def check_step(model) -> None:
    """Cheap checks between snapshots: finite velocities and the scheme's CFL limit
    (Model.stability); InstabilityError names the quantity."""
    import numpy as np
    ratio, what = model.stability()
    if not np.isfinite(ratio):
        raise InstabilityError("the fluid or particle velocities are not finite "
                               "(NaN or infinity)")
    if ratio > 1.0:
        raise InstabilityError(what)


def first_blow_up(model) -> str | None:
    """What went out of bounds first in a failed step, in the order of the step: the
    particle forces (pair, bond, gravity: EPSILON, G), the particle velocities, the fluid
    velocity; None if all are finite and within the step's reach."""
    whole = getattr(model, "whole_particles", None)     # (a collective when distributed)
    p = whole() if whole is not None else model.particles
    dx, dt = model.cfg.mesh.DX, model.dt
    if p is not None and p.n:
        f = getattr(p, "f_r", None)
        mass = np.asarray(p.mass, dtype=float)
        if f is not None and f.size:
            if not np.isfinite(f).all():
                return ("the particle forces (pair, bond or gravity) are not finite; EPSILON "
                        "or G is far too large for this time step")
            reach = float(np.max(np.linalg.norm(f, axis=1) / mass)) * dt * dt / dx
            if reach > 1.0:
                return (f"the particle forces (pair, bond or gravity) move a particle "
                        f"{reach:.3g} DX in one step (|F| dt^2 / (M DX) > 1); EPSILON or G is "
                        f"too large for this time step")
        if not (np.isfinite(p.v).all() and np.isfinite(p.R).all()):
            return "the particle velocities or positions are not finite"
        vmax = float(np.max(np.linalg.norm(p.v, axis=1)))
        if vmax * dt / dx > 1.0:
            return (f"the particle velocities: max |V| dt / DX = {vmax * dt / dx:.3g} exceeds 1 "
                    f"(a particle crosses a mesh cell in one step)")
    try:
        ratio, what = model.stability()
    except Exception:                                   # noqa: BLE001 - diagnosis only
        return None
    if not np.isfinite(ratio):
        return "the fluid velocity is not finite (NaN or infinity)"
    if ratio > 1.0:
        return what
    return None


def table_row(model) -> list:
    """This step's row of the sheared types' stress table, checked first: the table is
    printed every step, the blow-up checks run only every few steps (InstabilityError)."""
    row = model.shear_table_row()
    values = np.asarray(row, dtype=float)
    if values[1] == 0.0:                # at rate 0 the viscosity column is NaN, as the
        values = values[:-1]            # original's (stress / rate)
    if not np.isfinite(values).all():
        check_step(model)               # names the quantity when it is the velocity
        raise InstabilityError("the shear stress table row is not finite (NaN or infinity)")
    return row


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


def _write_error(e: OSError) -> str:
    if e.errno == errno.ENOSPC or "No space left" in str(e):
        return "the disk is full (No space left on device)"
    if e.errno == errno.EDQUOT:
        return "the disk quota is exceeded"
    return e.strerror or str(e)


def run(cfg, args, input_doc, model, resumed: bool = False) -> int:
    """Run ``model`` until step GTS * Num_snap; every GTS steps each writer of
    kapsel.io.writers.make_writers writes the snapshot (output.udf, field files, logs).

    ``resumed``: the model continues a restart (its clock is past 0); output.udf then gets
    the records of the continued run appended (later records of the earlier run, if any,
    are dropped), unless --overwrite asks for a new file.

    A file that cannot be written (a full disk) stops the run with exit 1, naming the file;
    records are appended whole or not at all and the restart pair is replaced only once
    both new files are complete, so the last good restart and every complete record stay."""
    saved = {"step": None}
    try:
        return _run(cfg, args, input_doc, model, resumed, saved)
    except MemoryError:
        print(f"kapsel-py: error: out of memory at step {model.step_index}. "
              f"{restart_hint(saved['step'], args)}. Run it where more memory is free "
              f"(or with a higher ulimit -v).", file=sys.stderr)
        return 1
    except OSError as e:
        what = e.filename or f"an output file in {os.path.dirname(os.path.abspath(args.output))}"
        print(f"kapsel-py: error: cannot write {what} at step {model.step_index}: "
              f"{_write_error(e)}. {restart_hint(saved['step'], args)}. Free some space and "
              f"continue from it.", file=sys.stderr)
        return 1


def _run(cfg, args, input_doc, model, resumed, saved) -> int:
    from .io.records import run_comment
    from .io.writers import make_writers
    from .progress import Progress

    total = cfg.output.total_steps
    if resumed and model.step_index > total:
        source = getattr(model, "restart_source", None)
        if source is not None and source[2] != model.step_index \
                and _same_file(source[0], args.restart):
            # killed between the two renames of its last restart write: the text
            from .io.restart import complete_restart   # from the state file's copy
            complete_restart(args.restart, args.define, input_doc)
        print(f"kapsel-py: {args.input} holds the end of its run (its last snapshot at step "
              f"{total} = output.Num_snap {cfg.output.Num_snap} x output.GTS "
              f"{cfg.output.GTS}): nothing to do. To run longer, raise output.Num_snap in "
              f"{args.input} and run kapsel-py -I{args.input} -O{args.output} "
              f"-D{args.define} -R{args.restart}", file=sys.stderr)
        return 0
    # a distributed run (kapsel.parallel.lockstep): rank 0 writes, the others serve
    lockstep = getattr(model, "lockstep", None)
    writes = lockstep is None or lockstep.dist.root
    writers = (make_writers(cfg, args, input_doc, model.snapshot(),
                            comment=run_comment(model.run_id, model.seed)) if writes else [])

    def output(body):
        """Run ``body`` (writers, restart) alone, or on rank 0 as a round of output."""
        if lockstep is None:
            return body()
        model.snapshot()          # every rank: the sources rank 0 may ask for
        return lockstep.round(body)
    start = model.step_index
    progress = Progress(total, quiet=args.quiet, gts=cfg.output.GTS, start_step=start)
    table = None
    if hasattr(model, "shear_table_row"):
        from .progress import ShearTable
        table = ShearTable(model.shear_table, model.shear_table_stream, quiet=args.quiet)
        table.print_header()

    check_every = min(cfg.output.GTS, 10)
    from . import compiled
    compiled_on = compiled.mode() == "1" and (compiled.enable() or True)

    def snapshot(snap=None):
        if lockstep is not None:
            check_step(model)     # collective: every rank, before the round of output

        def body(snap=snap):
            snap = model.snapshot() if snap is None else snap
            check_finite(model, snap)
            if lockstep is None:
                check_step(model)
            for w in writers:
                w.write(snap)
            save_restart()
            if model.step_index != start:
                progress.snapshot(model.step_index)
        output(body)

    define_doc = [None]
    source = getattr(model, "restart_source", None)     # (path, fingerprint) of -I's text
    if resumed and writes and source is not None and _same_file(source[0], args.restart):
        # the restart.udf on disk is the one this run continues: checkpoints go on against
        # it, as in the run being continued (whose files this run's then equal)
        saved.update(base=source[1], step=start, full=source[2])

    def save_restart(full=False):
        """The full restart.udf (first snapshot of the run, end, interruption), else the
        cheap checkpoint in its state file (kapsel.io.restart.write_checkpoint)."""
        if model.restart_kind is None:
            return
        from .io.restart import write_checkpoint, write_restart
        full = full or saved.get("base") is None
        kind, data, exact = model.restart_state(checkpoint=not full)
        if full:
            saved["base"] = write_restart(args.restart, args.define, input_doc, kind,
                                          model.step_index, model.time, model.particles,
                                          data, exact, previous=saved.get("base"))
            saved["full"] = model.step_index
        else:
            if define_doc[0] is None:
                from udf import UDFManager
                define_doc[0] = UDFManager(schema_from=args.define)
            write_checkpoint(args.restart, define_doc[0], kind, model.step_index, model.time,
                             model.particles, data, exact, saved["base"],
                             complete=model.checkpoint_complete)
        saved["step"] = model.step_index

    def complete_restart():
        """After a failure: restart.udf written in full from the last checkpoint."""
        if writes and saved.get("step") is not None and saved.get("full") != saved["step"]:
            from .io.restart import complete_restart as complete
            try:
                complete(args.restart, args.define, input_doc)
            except OSError:
                pass        # the checkpoint still continues the run from restart.udf

    stop = {"signal": None}

    def on_signal(signum, frame):
        stop["signal"] = signum

    from .fluid.mac import SolverDidNotConverge
    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    closing = "failed"
    try:
        try:
            def open_writers():
                first = model.snapshot()
                for w in writers:
                    w.open(first, resumed)
                return first
            first = output(open_writers)
            if model.step_index % cfg.output.GTS == 0 and model.step_index <= total:
                snapshot(first)          # the writers skip what the continued run wrote
        except InstabilityError as e:
            print(f"kapsel-py: error: {e} in the initial state (step {model.step_index})",
                  file=sys.stderr)
            return 1
        for _ in range(start, total):
            before = model.step_index
            try:
                try:
                    advance(model)
                except (ValueError, IndexError, OverflowError):
                    check_step(model)   # NaN that broke the step: say so; else a real bug
                    raise
                if model.step_index % check_every == 0:
                    check_step(model)
                row = table_row(model) if table is not None else None
            except (SolverDidNotConverge, FloatingPointError, InstabilityError) as e:
                cause = first_blow_up(model)
                if cause is not None and not isinstance(e, InstabilityError):
                    e = f"{cause} (then: {e})"
                complete_restart()
                print(f"kapsel-py: error: the run stopped at step {before + 1}: {e}. "
                      f"{restart_hint(saved['step'], args)}. {stability_advice(cfg)}",
                      file=sys.stderr)
                return 1
            if row is not None:
                table.row(row)
            if not compiled_on and compiled.want(model.step_index - start,
                                                 total - model.step_index):
                compiled_on = compiled.enable() or True   # bit-identical kernels from here
            progress.step(model.step_index, model.time)
            if model.step_index % cfg.output.GTS == 0:
                try:
                    snapshot()
                except InstabilityError as e:
                    complete_restart()
                    print(f"kapsel-py: error: {e} at step {model.step_index}. "
                          f"{restart_hint(saved['step'], args)}. Try a smaller time_increment "
                          f"factor (or delta_t).", file=sys.stderr)
                    return 1
            if lockstep is not None:     # every rank stops at the same step
                stop["signal"] = lockstep.dist.comm.allreduce(stop["signal"] or 0,
                                                              op=_mpi_max()) or None
            if stop["signal"] is not None:
                closing = "interrupted"

                def last():
                    check_finite(model)
                    save_restart(full=True)
                try:
                    output(last)
                except InstabilityError as e:    # blew up since the last check: not saved
                    complete_restart()
                    print(f"kapsel-py: interrupted at step {model.step_index}, where {e}: "
                          f"that state is not saved. {restart_hint(saved['step'], args)}. "
                          f"{stability_advice(cfg)}", file=sys.stderr)
                    return 1
                print(f"kapsel-py: interrupted at step {model.step_index} (t = {model.time:g}); "
                      f"{args.output} holds every snapshot so far and {args.restart} this "
                      f"step. Continue with: kapsel-py -I{args.restart} -O{args.output} "
                      f"-D{args.define} -R{args.restart}", file=sys.stderr)
                return 1
        if model.step_index == total:
            # like the original's last loop iteration, one more step after the last
            # snapshot, and the restart holds that state (ts = MSTEP after MSTEP + 1 steps,
            # FORMAT-OUTPUT.md §1.2, §6.3), so either program continues it without
            # repeating a snapshot
            try:
                advance(model)
                check_step(model)
                output(lambda: check_finite(model))
                if table is not None:
                    table.row(table_row(model))
            except (SolverDidNotConverge, FloatingPointError, InstabilityError, ValueError,
                    IndexError, OverflowError) as e:
                complete_restart()
                print(f"kapsel-py: error: the step after the last snapshot failed: {e}. "
                      f"{restart_hint(saved['step'], args)}.", file=sys.stderr)
                return 1
        need = saved.get("full") != model.step_index
        if lockstep is not None:         # rank 0 keeps the books of the restart
            need = lockstep.dist.bcast(need)
        if need:
            output(lambda: save_restart(full=True))
        closing = "end"
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        for w in writers:
            w.close(closing)
    sys.stdout.flush()
    progress.summary(args.output if cfg.output.UDF else None, args.restart)
    return 0


def _same_file(a, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _mpi_max():
    from mpi4py import MPI
    return MPI.MAX
