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

SOLVERS: dict = {}


def register(type_name: str):
    """Decorator: make ``factory(cfg, args, doc) -> model`` the model of a type."""
    def deco(factory):
        SOLVERS[type_name] = factory
        return factory
    return deco


class Interrupted(Exception):
    pass


def run(cfg, args, input_doc, model) -> int:
    """Run ``model`` for GTS * Num_snap steps, writing a record every GTS steps."""
    from .io.records import OutputUDF
    from .progress import Progress

    out_dir = os.path.dirname(os.path.abspath(args.output))
    output = OutputUDF(args.output, args.define, input_doc) if cfg.output.UDF else None
    fields = None
    if model.fields():
        from .io.fields import FieldWriter
        fields = FieldWriter(out_dir, cfg.mesh.shape, cfg.mesh.DX,
                             fields=tuple(model.fields()))
    total = cfg.output.total_steps
    progress = Progress(total, quiet=args.quiet)

    def snapshot():
        n = model.step_index // cfg.output.GTS
        if output is not None:
            output.add_record(model.step_index, model.time, model.kinetic_energy(),
                              model.particles, model.record_items())
        if fields is not None:
            fields.write(n, model.time, **model.fields())

    stop = {"signal": None}

    def on_signal(signum, frame):
        stop["signal"] = signum

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        snapshot()
        first = model.step_index
        for _ in range(first, total):
            model.advance()
            progress.step(model.step_index, model.time)
            if model.step_index % cfg.output.GTS == 0:
                snapshot()
            if stop["signal"] is not None:
                print(f"kapsel-py: interrupted at step {model.step_index} (t = {model.time:g}); "
                      f"output written up to the last snapshot", file=sys.stderr)
                return 1
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    progress.summary()
    return 0
