"""The ``kapsel-py`` command: flags -> config -> simulation -> exit code.

    kapsel-py -Iinput.udf -Ooutput.udf -Ddefine.udf -Rrestart.udf [--threads N] [--seed S]

The flags are the original kapsel_u2m's (``-I input.udf`` with a space works too).
Exit codes: 0 success, 1 run failed (instability, solver did not converge, interrupted),
2 bad command line or bad input.  ``--check`` stops after every check (``prepare``) and
prints what the run will be, writing nothing.
"""
from __future__ import annotations

import sys
import time

from .startup import (  # noqa: F401  (the names tests and scripts know from kapsel.cli)
    EXIT_OK, EXIT_RUN_FAILED, EXIT_BAD_INPUT, BASE_ADDRESS_SPACE, BadInput, StartUpSignals,
    _START, _address_limit, _address_limit_note, build, build_model, build_parser,
    check_address_limit, check_define, check_flags, check_output_paths, check_own_output,
    check_same_schema, describe_setup, existing_outputs, fail, irregular_outputs,
    lock_output_dirs, prepare, single_threaded_blas, validate, written_dirs)


def main(argv=None) -> int:
    from . import progress
    progress.PROGRAM_START = time.perf_counter()
    single_threaded_blas()
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "analyze":
        from .analysis.cli import main as analyze
        return analyze(argv[1:])
    if argv and argv[0] == "example":
        from .examples import main as example
        return example(argv[1:])
    args = build_parser().parse_args(argv)
    limit = _address_limit()
    if limit is not None and limit < BASE_ADDRESS_SPACE and not args.check:
        return fail(f"the address space is limited to {limit / 2 ** 20:.0f} MiB (ulimit -v); "
                    f"kapsel-py needs at least {BASE_ADDRESS_SPACE / 2 ** 20:.0f} MiB for the "
                    f"program and its libraries before any array: raise the limit",
                    EXIT_RUN_FAILED)
    problem = check_flags(args)
    if problem:
        return fail(problem)
    from .parallel import DistError, start
    try:
        args.dist = start(args)      # a plain run: OneRank (mpi4py is not imported)
    except DistError as e:
        return fail(str(e))
    locks: list = []
    try:
        with _START:
            return _main(args, locks)
    except KeyboardInterrupt:
        print("kapsel-py: interrupted during start-up, before the first step; there is "
              "nothing to continue from", file=sys.stderr)
        return EXIT_RUN_FAILED
    except MemoryError:
        return fail(f"out of memory while setting up the run (before its first step; "
                    f"nothing was written){_address_limit_note()}", EXIT_RUN_FAILED)
    except ImportError as e:
        if "failed to map segment" in str(e) or "Cannot allocate memory" in str(e):
            return fail(f"out of memory while loading the program's libraries ({e.name or e}"
                        f"){_address_limit_note()}", EXIT_RUN_FAILED)
        if "Permission denied" in str(e) or "Input/output error" in str(e):
            return fail(f"cannot load a library the program needs: {e}", EXIT_RUN_FAILED)
        raise
    finally:
        for fh in locks:
            fh.close()


def _main(args, locks) -> int:
    prepared = prepare(args, None if args.check else locks)
    if isinstance(prepared, int):
        return prepared
    cfg, doc, model, resumed, seed_drawn, _ = prepared
    if not args.quiet or args.check:
        from .banner import describe, memory_estimate, print_banner
        from .config import _size
        from .simulation import planned_files
        lines = describe(cfg, args, model, resumed, planned_files(cfg, args, model, resumed),
                         seed_drawn=seed_drawn and not args.check)
        if args.check:
            if seed_drawn:
                lines[-1] = f"threads {args.threads}, seed drawn at the start of the run " \
                            f"(--seed S fixes it)"
            lines.append(f"memory: about {_size(memory_estimate(cfg))} (the input check's "
                         f"estimate)")
            lines.append(f"check passed: {args.input} is ready to run (nothing was written)")
            print_banner(lines, sys.stdout, prefix="")
            return EXIT_OK
        print_banner(lines, sys.stderr)
    _START.check()
    return run_to_end(args, prepared)


def run_to_end(args, prepared) -> int:
    """The run of ``prepared`` (``build``'s) as kapsel.api.Simulation, to the end of its
    input; the exit code: 0 at the end (or nothing to do), 1 when it stopped (the
    message of kapsel.simulation.RunError printed).  The caller holds the locks."""
    from .api import Simulation
    from .simulation import NothingToDo, RunError
    try:
        Simulation(args, prepared).run()
    except NothingToDo as e:
        print(f"kapsel-py: {e}", file=sys.stderr)
        return EXIT_OK
    except RunError as e:
        print(e.line, file=sys.stderr)
        return EXIT_RUN_FAILED
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
