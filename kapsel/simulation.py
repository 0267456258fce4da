"""The time loop: composes a model (fluid, phase field, particles) with the outputs.

A *model* is the physics of one ``constitutive_eq.type``; it does no I/O and offers:

    model.dt, model.time, model.step_index      the clock
    model.advance()                             one time step
    model.particles                             ParticleState (n may be 0)
    model.kinetic_energy()                      E of the output record
    model.record_items() -> dict                further record items (e.g. PSI)
    model.fields() -> dict                      psi / phi / u for HDF5 snapshots ({} if none)

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


def check_finite(model) -> None:
    import numpy as np
    for name, arr in model.fields().items():
        if not np.isfinite(arr).all():
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


def run(cfg, args, input_doc, model, resumed: bool = False) -> int:
    """Run ``model`` until step GTS * Num_snap, writing a record every GTS steps.

    ``resumed``: the model continues a restart (its clock is past 0); output.udf then gets
    the records of the continued run appended (later records of the earlier run, if any,
    are dropped), unless --overwrite asks for a new file."""
    from .io.records import OutputUDF
    from .progress import Progress

    out_dir = os.path.dirname(os.path.abspath(args.output))
    append = resumed and os.path.exists(args.output) and not args.overwrite
    output = None
    record_now = True
    if cfg.output.UDF:
        output = OutputUDF(args.output, args.define, input_doc, append=append)
        if append:
            kept, dropped, last = output.truncate_after(model.time)
            record_now = last is None or abs(last - model.time) > 1e-6 * max(1.0, model.time)
            if not args.quiet:
                print(f"#continuing at step {model.step_index} (t = {model.time:g}): appending "
                      f"to {args.output} ({kept} records kept"
                      + (f", {dropped} later ones dropped" if dropped else "") + ")",
                      file=sys.stderr)
    fields = None
    if model.fields():
        from .io.fields import FieldWriter
        fields = FieldWriter(out_dir, cfg.mesh.shape, cfg.mesh.DX,
                             fields=tuple(model.fields()), resume=resumed)
    shear_log = None
    if hasattr(model, "shear_record"):
        from .io.records import ShearLog
        shear_log = ShearLog(os.path.join(out_dir, "shear_stress.dat"), append=resumed,
                             until_step=model.step_index)
    rot_log = None
    bodies = getattr(model.particles, "constraints", None) if model.particles is not None \
        else None
    if hasattr(bodies, "rotational_energies"):
        from .io.records import RotationalEnergyLog
        rot_log = RotationalEnergyLog(os.path.join(out_dir, "rotational_energy.dat"),
                                      len(bodies.rotational_energies()), append=resumed,
                                      until_step=model.step_index)
    total = cfg.output.total_steps
    progress = Progress(total, quiet=args.quiet)
    start = model.step_index

    check_every = min(cfg.output.GTS, 10)
    from . import compiled
    compiled_on = compiled.mode() == "1" and (compiled.enable() or True)

    def snapshot(record=True):
        n = model.step_index // cfg.output.GTS
        check_finite(model)
        check_step(model)
        items = model.record_items()
        if shear_log is not None and record:
            shear = model.shear_record()
            shear_log.write(model.step_index, model.time, shear)
            if output is not None:
                items.update({k: v for k, v in shear.items() if output.has_record_item(k)})
        if rot_log is not None and record:
            e_rot = bodies.rotational_energies()
            rot_log.write(model.step_index, model.time, e_rot)
            if output is not None and output.has_record_item("E_rot"):
                items["E_rot"] = float(np.sum(e_rot))
        if output is not None and record:
            output.add_record(model.step_index, model.time, model.kinetic_energy(),
                              model.particles, items)
        if fields is not None:
            fields.write(n, model.time, **model.fields())
        save_restart()

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
    try:
        try:
            if not resumed:
                snapshot()
            elif model.step_index % cfg.output.GTS == 0:
                snapshot(record=record_now)
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
            if not compiled_on and compiled.want(model.step_index - start,
                                                 total - model.step_index):
                compiled_on = compiled.enable() or True   # bit-identical kernels from here
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
                check_finite(model)
                save_restart()
                print(f"kapsel-py: interrupted at step {model.step_index} (t = {model.time:g}); "
                      f"{args.output} holds every snapshot so far and {args.restart} this "
                      f"step. Continue with: kapsel-py -I{args.restart} -O{args.output} "
                      f"-D{args.define} -R{args.restart}", file=sys.stderr)
                return 1
        if saved["step"] != model.step_index:
            save_restart()
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    progress.summary()
    return 0
