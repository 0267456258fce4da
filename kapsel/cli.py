"""The ``kapsel-py`` command: flags -> config -> simulation -> exit code.

    kapsel-py -Iinput.udf -Ooutput.udf -Ddefine.udf -Rrestart.udf [--threads N] [--seed S]

The flags are the original kapsel_u2m's (``-I input.udf`` with a space works too).
Exit codes: 0 success, 1 run failed (instability, solver did not converge, interrupted),
2 bad command line or bad input.  ``--check`` stops after every check (``prepare``) and
prints what the run will be, writing nothing.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

from . import __version__

EXIT_OK, EXIT_RUN_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="kapsel-py",
        description="Colloidal particles in one- or two-component fluids by the Smoothed "
                    "Profile Method: a drop-in replacement for KAPSEL's kapsel_u2m.",
        epilog="Example: kapsel-py -Iinput.udf -Ooutput.udf -Ddefine.udf -Rrestart.udf\n"
               "Analyses: kapsel-py analyze {cna,erotate,sq} ... (see kapsel-py analyze -h)",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-I", dest="input", metavar="INPUT.udf", required=True,
                   help="input UDF (simulation conditions)")
    p.add_argument("-O", dest="output", metavar="OUTPUT.udf", default="output.udf",
                   help="output UDF: the input data plus one record per snapshot "
                        "(default: output.udf)")
    p.add_argument("-D", dest="define", metavar="DEFINE.udf", default="define.udf",
                   help="schema (define.udf) the output and restart files follow "
                        "(default: define.udf)")
    p.add_argument("-R", dest="restart", metavar="RESTART.udf", default="restart.udf",
                   help="restart UDF written at every snapshot and at the end "
                        "(default: restart.udf)")
    p.add_argument("--threads", type=int, default=1, metavar="N",
                   help="threads for FFTs and array work (default: 1)")
    p.add_argument("--seed", type=int, default=None, metavar="S",
                   help="random seed: runs with the same input and seed are identical "
                        "(default: drawn from the OS and reported)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.add_argument("--overwrite", action="store_true",
                   help="replace existing output and restart files")
    p.add_argument("--check", action="store_true",
                   help="read and check the input as a run would, print what the run will be "
                        "(type, mesh, particles, dt, steps, files, memory) and exit: 0 ready, "
                        "2 problems; writes nothing")
    p.add_argument("--version", action="version", version=f"kapsel-py {__version__}")
    return p


def fail(message: str, code: int = EXIT_BAD_INPUT) -> int:
    """Print each problem (one per line of ``message``) and return ``code``."""
    for line in str(message).splitlines() or [""]:
        print(f"kapsel-py: error: {line}", file=sys.stderr)
    return code


class BadInput(Exception):
    """What ``prepare`` found wrong: str() is one line per problem."""


def single_threaded_blas() -> None:
    """BLAS threads only slow our level-1 work (BiCGSTAB dots on a busy machine: measured
    216 vs 34 ms per sample step); parallelism comes from FFTW and our own row blocks.
    Must run before numpy is imported; a user's own setting wins."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def check_output_paths(args) -> str | None:
    """Where output.udf, the field files and restart.udf go must be a writable directory,
    and -O and -R must differ: checked before anything is written."""
    seen = {}
    for flag, path in (("-O", args.output), ("-R", args.restart)):
        d = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(d):
            if os.path.exists(d):
                return f"{flag}{path}: {d} is not a directory"
            return f"{flag}{path}: the directory {d} does not exist"
        if not os.access(d, os.W_OK | os.X_OK):
            return f"{flag}{path}: the directory {d} is not writable"
        if os.path.isdir(path):
            return f"{flag}{path}: is a directory, not a file name"
        real = os.path.realpath(path)
        if real in seen:
            return f"{seen[real]} and {flag} name the same file {path}"
        seen[real] = flag
    return None


def check_define(define, args, model) -> str | None:
    """The -D schema must hold what output.udf and restart.udf will be written with (a
    wrong -D file otherwise fails after output.udf was created)."""
    from .io.records import OUT_FIELDS
    from udf.schema import Struct
    schema = define.schema
    items = model.record_items() if hasattr(model, "record_items") else {}
    particles = getattr(model, "particles", None)
    need = ["E", "t"] + list(items)
    if particles is not None and particles.n:
        need.append("Particles")
    missing = [n for n in need if n not in schema.record_items]
    if missing:
        return (f"-D{args.define}: not a KAPSEL define file for this run: its record "
                f"definitions lack {', '.join(missing)}")
    kind = getattr(model, "restart_kind", None)
    structs = []
    m = schema.record_items.get("Particles")
    if "Particles" in need and isinstance(m.type, Struct):
        structs.append(m.type)
    if kind is not None:
        res = schema.global_items.get("resume")
        i = None
        if res is not None and isinstance(res.type, Struct):
            from .io.restart import schema_kind   # CONTINUE is CONTINUE_ORIGINAL in some
            kind = schema_kind(define, kind)       # define.udf versions
            i = res.type.index(kind)
        sd = res.type.members[i].type.members[0].type if i is not None else None
        if not isinstance(sd, Struct) or sd.index("jikan") is None:
            return f"-D{args.define}: not a KAPSEL define file: it has no resume.{kind}.Saved_Data"
        if "Particles" in need and sd.index("Particles") is not None:
            structs.append(sd.members[sd.index("Particles")].type)
    for st in structs:
        unknown = [x.name for x in getattr(st, "members", ()) if x.name not in OUT_FIELDS]
        if unknown:
            return (f"-D{args.define}: its particle class has members kapsel-py does not "
                    f"know: {', '.join(unknown)}")
    return None


def validate(input_path: str, define_path: str | None = None):
    """Read and check an input as a run would, building nothing and writing nothing:
    returns (cfg, input document, define document or None); raises BadInput listing every
    problem of the input (one per line).  ``prepare`` goes on to build the model."""
    import udf
    from . import config, models  # noqa: F401  (models register their types)
    from .simulation import SOLVERS
    try:
        doc = udf.UDFManager(input_path)
        cfg = config.from_document(doc, input_path)
        define = udf.UDFManager(define_path) if define_path else None
    except (udf.UDFError, config.ConfigError) as e:
        raise BadInput(str(e)) from None
    if cfg.type not in SOLVERS:
        raise BadInput(f"constitutive_eq.type {cfg.type!r} is not implemented yet in kapsel-py "
                       f"(implemented: {', '.join(sorted(SOLVERS)) or 'none'})")
    return cfg, doc, define


def describe_setup(cfg) -> str:
    """What a run builds and about how much memory it takes (config.memory_estimate)."""
    from .config import _size, memory_estimate
    nx, ny, nz = cfg.mesh.shape
    p = cfg.particles
    n = p.count
    what = ""
    if n and p.object_type == "spherical_particle":
        what = f" with {n} particles"
    elif n:
        kind = "chains" if p.object_type == "chain" else "rigid bodies"
        what = f" with {n} beads in {sum(s.number for s in p.species)} {kind}"
    return (f"{cfg.type} on a {nx} x {ny} x {nz} mesh{what}, about "
            f"{_size(memory_estimate(cfg.mesh, cfg.type, n))} of memory")


def build_model(cfg, args, doc, resumed: bool):
    """The model of ``cfg`` (the restart loaded when ``resumed``); raises BadInput.  When
    building takes more than 2 s, says what is being built and its memory estimate."""
    import threading
    import time

    import udf
    from . import config
    from .simulation import SOLVERS
    started = time.perf_counter()
    talked = threading.Event()

    def talk():
        talked.set()
        print(f"#setting up {describe_setup(cfg)} ...", file=sys.stderr, flush=True)

    timer = None
    if not getattr(args, "quiet", False):
        timer = threading.Timer(2.0, talk)
        timer.daemon = True
        timer.start()
    try:
        model = SOLVERS[cfg.type](cfg, args, doc)
        if resumed:
            from .io.restart import read_restart
            saved = read_restart(doc, args.input, cfg.resume.calculation)
            model.load_restart(saved)
            if not args.quiet:       # the original's line after its restore (§1.3)
                print("############################ Parameters are restored.",
                      file=sys.stderr)
            if saved.exact is None and not args.quiet:
                print(f"#{args.input}: no matching state file; continuing from the restart "
                      f"data alone (R_raw from it or else R, the noise stream at the seed)",
                      file=sys.stderr)
        from .io import writers
        writers.check_output(cfg, model)
    except config.ConfigError as e:
        if not e.where:  # raised by a model: say where the item is in the input
            top = e.path.split(".")[0].split("[")[0] if e.path else ""
            raise BadInput(f"{doc.where(top) if top else args.input}: {e}") from None
        raise BadInput(str(e)) from None
    except udf.UDFError as e:
        raise BadInput(str(e)) from None
    finally:
        if timer is not None:
            timer.cancel()
    if talked.is_set():
        print(f"#set-up done in {time.perf_counter() - started:.1f} s", file=sys.stderr)
    return model


def prepare(args):
    """Everything a run does before its first write: read the input and the -D schema,
    build the configuration and the model (every check), check the output paths.
    Returns the exit code of a refusal (the message printed), or
    (cfg, doc, model, resumed, seed_drawn).  Writes nothing."""
    if args.threads < 1:
        return fail(f"--threads must be at least 1, got {args.threads}")
    for flag, path in (("-I", args.input), ("-D", args.define)):
        if not os.path.isfile(path):
            return fail(f"{flag}{path}: no such file")
    try:
        cfg, doc, define = validate(args.input, args.define)
    except BadInput as e:
        return fail(str(e))
    problem = check_output_paths(args)
    if problem:
        return fail(problem)
    resumed = cfg.resume.calculation != "NEW"
    if not resumed and not args.overwrite:
        targets = [(f"-O{args.output}", args.output), (f"-R{args.restart}", args.restart)]
        from .io.writers import new_run_targets
        targets += new_run_targets(cfg, args)
        for what, path in targets:
            if os.path.exists(path):
                return fail(f"{what} exists; pass --overwrite to replace it (or continue a "
                            f"run from its restart file)")
    seed_drawn = args.seed is None
    if args.seed is None:   # drawn here, reported once the input is known to be good
        import secrets
        args.seed = secrets.randbits(63)
    try:
        model = build_model(cfg, args, doc, resumed)
    except BadInput as e:
        return fail(str(e))
    problem = check_define(define, args, model)
    if problem:
        return fail(problem)
    return cfg, doc, model, resumed, seed_drawn


def main(argv=None) -> int:
    from . import progress
    progress.PROGRAM_START = time.perf_counter()
    single_threaded_blas()
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "analyze":
        from .analysis.cli import main as analyze
        return analyze(argv[1:])
    args = build_parser().parse_args(argv)
    prepared = prepare(args)
    if isinstance(prepared, int):
        return prepared
    cfg, doc, model, resumed, seed_drawn = prepared

    from .banner import describe, memory_estimate, print_banner
    from .config import _size
    from .simulation import planned_files, run
    if args.quiet and not args.check:
        return run(cfg, args, doc, model, resumed=resumed)
    lines = describe(cfg, args, model, resumed, planned_files(cfg, args, model, resumed),
                     seed_drawn=seed_drawn and not args.check)
    if args.check:
        if seed_drawn:
            lines[-1] = f"threads {args.threads}, seed drawn at the start of the run " \
                        f"(--seed S fixes it)"
        lines.append(f"memory: about {_size(memory_estimate(cfg))} (the input check's estimate)")
        lines.append(f"check passed: {args.input} is ready to run (nothing was written)")
        print_banner(lines, sys.stdout, prefix="")
        return EXIT_OK
    print_banner(lines, sys.stderr)
    return run(cfg, args, doc, model, resumed=resumed)


if __name__ == "__main__":
    sys.exit(main())
