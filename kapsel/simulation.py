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


def run(cfg, args, input_doc, model, resumed: bool = False) -> int:
    """Run ``model`` until step GTS * Num_snap; every GTS steps each writer of
    kapsel.io.writers.make_writers writes the snapshot (output.udf, field files, logs).

    ``resumed``: the model continues a restart (its clock is past 0); output.udf then gets
    the records of the continued run appended (later records of the earlier run, if any,
    are dropped), unless --overwrite asks for a new file."""
    from .io.writers import make_writers
    from .progress import Progress

    writers = make_writers(cfg, args, input_doc, model.snapshot())
    total = cfg.output.total_steps
    start = model.step_index
    progress = Progress(total, quiet=args.quiet, gts=cfg.output.GTS, start_step=start)
    table = None
    if hasattr(model, "shear_table_row"):
        from .progress import ShearTable
        table = ShearTable(model.shear_table, model.shear_table_stream, quiet=args.quiet)
        table.print_header()

    check_every = min(cfg.output.GTS, 10)

    def snapshot(snap=None):
        snap = model.snapshot() if snap is None else snap
        check_finite(model, snap)
        check_step(model)
        for w in writers:
            w.write(snap)
        save_restart()
        if model.step_index != start:
            progress.snapshot(model.step_index)

    saved = {"step": None}

    def save_restart():
        if model.restart_kind is None:
            return
        from .io.restart import write_restart
        kind, data, exact = model.restart_state()
        write_restart(args.restart, args.define, input_doc, kind, model.step_index, model.time,
                      model.particles, data, exact)
        saved["step"] = model.step_index

    stop = {"signal": None}

    def on_signal(signum, frame):
        stop["signal"] = signum

    from .fluid.mac import SolverDidNotConverge
    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    closing = "failed"
    try:
        try:
            first = model.snapshot()
            for w in writers:
                w.open(first, resumed)
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
                    model.advance()
                except (ValueError, IndexError, OverflowError):
                    check_step(model)   # NaN that broke the step: say so; else a real bug
                    raise
                if model.step_index % check_every == 0:
                    check_step(model)
            except (SolverDidNotConverge, FloatingPointError, InstabilityError) as e:
                print(f"kapsel-py: error: the run stopped at step {before + 1}: {e}. "
                      f"{restart_hint(saved['step'], args)}. Try a smaller time_increment "
                      f"factor (or delta_t), or the implicit_scheme.", file=sys.stderr)
                return 1
            if table is not None:
                table.row(model.shear_table_row())
            progress.step(model.step_index, model.time)
            if model.step_index % cfg.output.GTS == 0:
                try:
                    snapshot()
                except InstabilityError as e:
                    print(f"kapsel-py: error: {e} at step {model.step_index}. "
                          f"{restart_hint(saved['step'], args)}. Try a smaller time_increment "
                          f"factor (or delta_t).", file=sys.stderr)
                    return 1
            if stop["signal"] is not None:
                closing = "interrupted"
                check_finite(model)
                save_restart()
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
                model.advance()
                check_step(model)
                check_finite(model)
                if table is not None:
                    table.row(model.shear_table_row())
            except (SolverDidNotConverge, FloatingPointError, InstabilityError, ValueError,
                    IndexError, OverflowError) as e:
                print(f"kapsel-py: error: the step after the last snapshot failed: {e}. "
                      f"{restart_hint(saved['step'], args)}.", file=sys.stderr)
                return 1
            save_restart()
        elif saved["step"] != model.step_index:
            save_restart()
        closing = "end"
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        for w in writers:
            w.close(closing)
    sys.stdout.flush()
    progress.summary(args.output if cfg.output.UDF else None, args.restart)
    return 0
