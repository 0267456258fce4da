"""From the command's flags and the input files to a built model: every check made before
anything is written (the flags, the input and define.udf, the output paths and their locks,
the memory under ``ulimit -v``), each problem reported once (``BadInput``).  The
``kapsel-py`` command (kapsel.cli) and kapsel.api.Simulation.from_udf both start here."""
from __future__ import annotations

import argparse
import os
import sys

from . import __version__

EXIT_OK, EXIT_RUN_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="kapsel-py",
        description="Colloidal particles in one- or two-component fluids by the Smoothed "
                    "Profile Method: a drop-in replacement for KAPSEL's kapsel_u2m.",
        epilog="Example: kapsel-py -Iinput.udf -Ooutput.udf -Ddefine.udf -Rrestart.udf\n"
               "Analyses: kapsel-py analyze {cna,erotate,sq} ... (see kapsel-py analyze -h)\n"
               "Examples: kapsel-py example sample DIR copies the manual's sample to DIR",
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
    p.add_argument("-X", dest="X", type=int, default=None, metavar="PX",
                   help="distributed runs (mpirun -n P kapsel-py ...): ranks along x of the "
                        "px x py process grid, the original kapsel_u2m_mpi's flag "
                        "(default: P, with -Y: P / Y)")
    p.add_argument("-Y", dest="Y", type=int, default=None, metavar="PY",
                   help="ranks along y of the process grid (default: 1, with -X: P / X)")
    p.add_argument("--threads", type=int, default=1, metavar="N",
                   help="threads for FFTs and array work (default: 1)")
    p.add_argument("--seed", type=int, default=None, metavar="S",
                   help="random seed: runs with the same input and seed are identical "
                        "(default: drawn from the OS and reported)")
    p.add_argument("--spm-drag", choices=("original", "calibrated"), default="original",
                   help="original: the SPM profile has the radius A, as the original (its "
                        "drag depends on the time step: 2.7%% fast at A 4, A_XI 2, factor 1); "
                        "calibrated: the profile radius whose measured hydrodynamic radius is "
                        "A (docs/numerics.md)")
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
    """What ``prepare`` found wrong: str() is one line per problem; ``code`` the exit
    code (2, or 1 for a refusal that is not the input's fault)."""

    def __init__(self, message: str = "", code: int = EXIT_BAD_INPUT):
        super().__init__(message)
        self.code = code


def single_threaded_blas() -> None:
    """BLAS threads only slow our level-1 work (BiCGSTAB dots on a busy machine: measured
    216 vs 34 ms per sample step); parallelism comes from FFTW and our own row blocks.
    Must run before numpy is imported; a user's own setting wins."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def check_output_paths(args) -> str | None:
    """Where output.udf, the field files and restart.udf go must be a writable directory,
    and -O and -R must differ: checked before anything is written.  -O and -R must name
    regular files (or nothing yet): a symbolic link would be replaced by the atomic
    rename, a FIFO or device node (e.g. /dev/null) must never be replaced."""
    import stat
    from .io.restart import state_path
    seen = {}
    state = state_path(args.restart)
    if os.path.isdir(state) and not os.path.islink(state):
        return (f"-R{args.restart}: its state file {state} is a directory; remove or rename "
                f"it")
    for flag, path in (("-O", args.output), ("-R", args.restart), ("-R", state)):
        if os.path.islink(path):
            return (f"{flag}{path}: is a symbolic link (to {os.readlink(path)}); kapsel-py "
                    f"replaces its files atomically and would replace the link: give the "
                    f"target's path")
        if os.path.exists(path) and not os.path.isdir(path):
            mode = os.stat(path).st_mode
            if not stat.S_ISREG(mode):
                kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a device node"
                        if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a socket"
                        if stat.S_ISSOCK(mode) else "not a regular file")
                return f"{flag}{path}: is {kind}, not a regular file; it is never replaced"
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
        if path == state:
            continue
        if real in seen:
            return f"{seen[real]} and {flag} name the same file {path}"
        seen[real] = flag
    return None


def _layout(t, ndim=0):
    """The structure of a schema type that decides whether its data, written positionally,
    reads back (array ranks, member counts, primitive kinds; not names, select choices,
    units or comments: e.g. resume.CONTINUE may be called CONTINUE_ORIGINAL)."""
    from udf.schema import Primitive, Select, Struct
    if isinstance(t, Struct):
        return ndim, tuple(_layout(m.type, m.ndim) for m in t.members)
    if isinstance(t, Select):
        return ndim, "select"
    if isinstance(t, Primitive):
        return ndim, t.name
    return ndim, repr(t)


def check_same_schema(doc, define, args) -> str | None:
    """Every item of the input that output.udf and restart.udf copy must be defined alike in
    the -D schema: otherwise those files hold data their own schema cannot read (issue 12),
    and a continued run would replace a good restart file with an unreadable one."""
    differ, lacks = [], []
    for name in doc.common:
        mine = doc.schema.global_items.get(name)
        theirs = define.schema.global_items.get(name)
        if mine is None:
            continue
        if theirs is None:
            lacks.append(name)
        elif _layout(mine.type, mine.ndim) != _layout(theirs.type, theirs.ndim):
            differ.append(name)
    if lacks:
        return (f"-D{args.define}: has no place for {', '.join(lacks)} of {args.input}: the "
                f"restart file would not hold the whole input. Pass the define file the "
                f"input includes")
    if differ:
        return (f"-D{args.define}: defines {', '.join(differ)} differently from the schema "
                f"{args.input} was written with; output and restart files would not be "
                f"readable. Pass the define file the input includes")
    return None


def check_own_output(args, model) -> str | None:
    """A continued run appends to -O only if that file is its own: the run id in its first
    line (kapsel.io.records.run_id) must be the one in the restart's state file."""
    from .io.records import run_id
    if args.overwrite or not model.run_id_known or not os.path.exists(args.output):
        return None
    theirs = run_id(args.output)
    if theirs is not None and theirs != model.run_id:
        return (f"-O{args.output} belongs to another run (run {theirs}); {args.input} "
                f"continues run {model.run_id}: give that run's output file, or pass "
                f"--overwrite to start a new {args.output}")
    return None


def existing_outputs(args, cfg) -> str | None:
    """A new run refuses to replace existing output unless --overwrite (checked under the
    run lock, so two runs cannot both pass it)."""
    from .io.writers import new_run_targets
    targets = [(f"-O{args.output}", args.output), (f"-R{args.restart}", args.restart)]
    targets += new_run_targets(cfg, args)
    for what, path in targets:
        if os.path.exists(path):
            return (f"{what} exists; pass --overwrite to replace it (or continue a run from "
                    f"its restart file)")
    return None


def irregular_outputs(args, cfg) -> str | None:
    """The files a run replaces besides -O and -R (the field series' .xmf, output.AVS's
    file) must be regular files if they exist: a FIFO or a device there is never replaced
    (as -O and -R, check_output_paths)."""
    import stat

    from udf.files import kind_of
    from .io.writers import new_run_targets
    for what, path in new_run_targets(cfg, args):
        try:
            mode = os.stat(path).st_mode
        except OSError:
            continue
        if not stat.S_ISREG(mode):
            return f"{what}: is {kind_of(mode)}, not a regular file; it is never replaced"
    return None


class _DirLock:
    """flock(2) on a directory's own descriptor: no file is created, and the system drops
    the lock however the process ends."""

    def __init__(self, fd):
        self.fd = fd

    def close(self):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def written_dirs(args, cfg=None) -> list[str]:
    """Every directory a run writes into: that of -O (with the FDM types' field files and
    the .dat tables), that of -R, and output.AVS's Out_dir (with its avs/ of the legacy
    AVS files)."""
    paths = [os.path.dirname(os.path.abspath(p)) for p in (args.output, args.restart)]
    if cfg is not None and cfg.output.fields is not None:
        from .io.writers import field_directory
        out_dir = os.path.abspath(field_directory(cfg, args))
        paths.append(out_dir)
        if cfg.output.fields.FileType != "EXTENDED":
            paths.append(os.path.join(out_dir, "avs"))
    return sorted({os.path.realpath(d) for d in paths})


def lock_output_dirs(args, cfg=None):
    """Hold an exclusive lock on every directory kapsel-py writes into (written_dirs; an
    Out_dir that does not exist yet is made) for the whole run, so that two runs cannot
    write into one directory at once; then remove the temporary files that killed writes
    left there (udf.files.remove_temporaries).  Returns (locks, None) or (None, message)."""
    import fcntl

    from udf.files import remove_temporaries
    held = []
    dirs = written_dirs(args, cfg)

    def refuse(message):
        for h in held:
            h.close()
        return None, message
    for d in dirs:
        try:
            os.makedirs(d, exist_ok=True)
            fd = os.open(d, os.O_RDONLY)
        except OSError as e:
            return refuse(f"cannot open {d} to lock it for the run: {e.strerror}")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            return refuse(f"another kapsel-py run is writing into {d}; two runs must not "
                          f"write into one directory (-O, -R or output.AVS's Out_dir): wait "
                          f"for it to end, or give another directory")
        held.append(_DirLock(fd))
    from .io.journal import recover_all
    gone, back = [], []
    for d in dirs:
        gone += remove_temporaries(d) + remove_temporaries(os.path.join(d, "avs"))
        try:
            back += recover_all(d)
        except OSError as e:
            return refuse(f"cannot put back {d}'s file that a killed run was writing: "
                          f"{e.strerror}")
    if back and not getattr(args, "quiet", False):
        print(f"#{', '.join(back)}: put back to its last complete frame (a run was stopped "
              f"while writing it)", file=sys.stderr)
    if gone and not getattr(args, "quiet", False):
        print(f"#removed {len(gone)} temporary file{'s' * (len(gone) > 1)} that interrupted "
              f"writes had left ({', '.join(sorted(gone)[:3])}{', ...' * (len(gone) > 3)})",
              file=sys.stderr)
    return held, None


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


def validate(input_path: str, define_path: str | None = None, overrides: dict | None = None):
    """Read and check an input as a run would, building nothing and writing nothing:
    returns (cfg, input document, define document or None); raises BadInput listing every
    problem of the input (one per line).  ``overrides``: {item path: value} put into the
    input document first (the run, output.udf and restart.udf then hold those values).
    ``prepare`` goes on to build the model."""
    import udf
    from . import config, models  # noqa: F401  (models register their types)
    from .typespec import SOLVERS
    try:
        doc = udf.UDFManager(input_path)
        bad = []
        for path, value in (overrides or {}).items():
            try:
                doc.put(value, path)
            except (udf.UDFError, ValueError, TypeError, KeyError, IndexError) as e:
                bad.append(f"{input_path}: cannot set {path} to {value!r}: {e}")
        if bad:
            raise BadInput("\n".join(bad))
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
            f"{_size(memory_estimate(cfg.mesh, cfg.type, n, p.A, p.A_XI, program=False))} of "
            f"memory")


def build_model(cfg, args, doc, resumed: bool, origin: dict | None = None):
    """The model of ``cfg`` (the restart loaded when ``resumed``); raises BadInput.  When
    building takes more than 2 s, says what is being built and its memory estimate.
    ``origin`` (a dict) gets "source": the (path, fingerprint, step) of the restart text a
    continued model was loaded from (kapsel.simulation.TimeLoop)."""
    import threading
    import time

    import udf
    from . import config
    from .typespec import SOLVERS
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
            if saved.state_damaged:
                from .io.restart import state_path
                print(f"#{state_path(args.input)} is damaged ({saved.state_damaged}) and is "
                      f"not used: continuing from the restart data alone", file=sys.stderr)
            if saved.checkpoint_of is not None and not args.quiet:
                print(f"#{args.input} holds step {saved.checkpoint_of}, its state file the "
                      f"later snapshot at step {saved.step} (the run ended before rewriting "
                      f"{args.input}): continuing from step {saved.step}", file=sys.stderr)
            model.load_restart(saved)
            # the text this run continues: checkpoints go on against it (TimeLoop)
            if origin is not None:
                origin["source"] = (args.input, saved.text_fingerprint,
                                    saved.step if saved.checkpoint_of is None
                                    else saved.checkpoint_of)
            adopted = getattr(args, "adopted_run_id", None)
            if not model.run_id_known and adopted:      # no state file: output.udf's run
                model.run_id, model.run_id_known = adopted, True
            if saved.exact and "seed" in saved.exact:
                # the time line's seed (its noise state is restored), the one output.udf's
                # first line names, not one drawn for this continuation
                model.seed = args.seed = int(saved.exact["seed"])
            if not args.quiet:       # the original's line after its restore (§1.3)
                print("############################ Parameters are restored.",
                      file=sys.stderr)
            if saved.exact is None and not args.quiet and not saved.state_damaged:
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


class StartUpSignals:
    """SIGINT / SIGTERM during start-up are noted and acted on between its stages
    (``check``), never raised inside a C extension's import or set-up: a KeyboardInterrupt
    there can leave it half initialised (a crash at exit was seen).  The time loop then
    installs its own handlers (kapsel.simulation.run)."""

    got = None

    def __enter__(self):
        import signal
        self.got = None
        try:
            # SIGTERM (a batch system's stop) ends the process at once, in the kernel: start-
            # up has written nothing, and a Python handler would wait for a C library that
            # spins (OpenBLAS retrying an allocation under ulimit -v) or blocks
            self.old = {signal.SIGINT: signal.signal(signal.SIGINT, self._note),
                        signal.SIGTERM: signal.signal(signal.SIGTERM, signal.SIG_DFL)}
        except ValueError:              # not the main thread: leave the handlers alone
            self.old = {}
        return self

    def _note(self, signum, frame):
        self.got = signum

    def check(self):
        if self.got is not None:
            raise KeyboardInterrupt

    def __exit__(self, *exc):
        import signal
        for s, h in self.old.items():
            signal.signal(s, h)
        return False


_START = StartUpSignals()


def prepare(args, locks: list | None = None):
    """Everything a run does before its first write: read the input and the -D schema,
    build the configuration and the model (every check), check the output paths.  With a
    ``locks`` list (a run, not --check) the output directories are locked first
    (lock_output_dirs; the caller releases them when the run ends).  Returns the exit code
    of a refusal (the message printed), or (cfg, doc, model, resumed, seed_drawn, source):
    ``build``'s.  Writes nothing."""
    try:
        return build(args, locks)
    except BadInput as e:
        return fail(str(e), e.code) if str(e) else e.code


def build(args, locks: list | None = None, overrides: dict | None = None):
    """``prepare`` raising BadInput (every problem, one per line; ``code`` the exit code;
    empty on the ranks of a distributed run that did not find the problem themselves)
    instead of printing it.  ``overrides``: {item path: value} put into the input as read
    (kapsel.api).  Returns (cfg, doc, model, resumed, seed_drawn, source), ``source`` the
    (path, fingerprint, step) of the restart text a continued run was loaded from."""
    from .parallel import OneRank, world
    args.dist = dist = world(args)
    try:
        checked, problem = _check_inputs(args, locks, dist, overrides), None
    except BadInput as e:
        checked, problem = None, e
    # every rank stops if one refuses, before any collective work
    code = dist.agree(problem.code if problem is not None else None)
    if code:
        raise problem if problem is not None else BadInput("", code)
    args.seed = dist.bcast(args.seed)
    args.adopted_run_id = dist.bcast(getattr(args, "adopted_run_id", None))
    if _not_distributed(checked[0]):
        args.dist = dist = OneRank()      # one rank (refused with more): a plain run
    cfg, doc, define, resumed, seed_drawn = checked
    origin: dict = {}
    model = build_model(cfg, args, doc, resumed, origin)
    _START.check()
    problem = (check_define(define, args, model) or check_same_schema(doc, define, args)
               or (resumed and check_own_output(args, model)))
    code = dist.agree(EXIT_BAD_INPUT if problem else None)
    if code:
        raise BadInput(problem or "", code)
    return cfg, doc, model, resumed, seed_drawn, origin.get("source")


def _not_distributed(cfg):
    from .parallel import not_distributed
    return not_distributed(cfg)


def _check_inputs(args, locks, dist, overrides=None):
    """The checks of ``build`` before the model is built: raises BadInput, or returns
    (cfg, doc, define, resumed, seed_drawn).  In a distributed run the output paths are
    checked and locked by rank 0 only (the one that writes)."""
    from udf.files import check_regular
    for flag, path in (("-I", args.input), ("-D", args.define)):
        try:
            check_regular(path)
        except FileNotFoundError:
            raise BadInput(f"{flag}{path}: no such file") from None
        except OSError as e:
            raise BadInput(f"{flag}{path}: {e.strerror}") from None
    cfg, doc, define = validate(args.input, args.define, overrides)
    from .parallel import refuse
    problem = refuse(dist, cfg)
    if problem:
        raise BadInput(problem)
    problem = check_address_limit(cfg)
    if problem:
        raise BadInput(problem)
    _START.check()
    writes = dist.root
    problem = (check_output_paths(args) or irregular_outputs(args, cfg)) if writes else None
    if problem:
        raise BadInput(problem)
    resumed = cfg.resume.calculation != "NEW"
    if locks is not None and writes:
        held, problem = lock_output_dirs(args, cfg)    # from here to the end of the run
        if problem:
            raise BadInput(problem)
        locks.extend(held)
    if not resumed and not args.overwrite and writes:
        problem = existing_outputs(args, cfg)
        if problem:
            raise BadInput(problem)
    args.adopted_run_id = None
    if resumed and args.seed is None and writes and not args.overwrite:
        # a continuation whose restart has no usable state file (its seed and run id are
        # there otherwise) appends to the output.udf of its time line: that file's seed
        # and run id go on, so its first line stays true
        from .io.records import run_line
        named = run_line(args.output) if os.path.exists(args.output) else None
        if named is not None:
            args.adopted_run_id, args.seed = named
    seed_drawn = args.seed is None
    if args.seed is None:   # drawn here, reported once the input is known to be good
        import secrets
        args.seed = secrets.randbits(63)
    return cfg, doc, define, resumed, seed_drawn


def check_flags(args) -> str | None:
    """The flags checked before anything is read: --threads, --seed."""
    if args.threads < 1:
        return f"--threads must be at least 1, got {args.threads}"
    if args.seed is not None and not 0 <= args.seed < 2 ** 63:
        return f"--seed must be an integer from 0 to 2^63 - 1, got {args.seed}"
    return None


def _address_limit():
    """The soft address-space limit (ulimit -v) in bytes, or None."""
    try:
        import resource
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        return None
    return None if soft == resource.RLIM_INFINITY else soft


def _address_limit_note() -> str:
    limit = _address_limit()
    return "" if limit is None else (f"; the address space is limited to "
                                     f"{limit / 2 ** 20:.0f} MiB (ulimit -v)")


# address space a run takes besides its arrays: the interpreter, numpy, scipy, h5py,
# pyFFTW, numba and OpenBLAS's buffers (measured VmPeak of 8^3 runs: 255 MiB spectral,
# 286 MiB Navier_Stokes_FDM; under ulimit -v 200000 (195 MiB) OpenBLAS spins, at 280000 it
# gives up with exit 1)
BASE_ADDRESS_SPACE = 300 * 2 ** 20


def check_address_limit(cfg) -> str | None:
    """Under ``ulimit -v``, refuse a run whose estimated memory does not fit: below the
    limit OpenBLAS retries a failed allocation for ever and numpy raises MemoryError in
    the middle of the set-up."""
    limit = _address_limit()
    if limit is None:
        return None
    from .config import _size, memory_estimate
    need = BASE_ADDRESS_SPACE + memory_estimate(cfg.mesh, cfg.type, cfg.particles.count,
                                                cfg.particles.A, cfg.particles.A_XI,
                                                program=False)
    if need > limit:
        return (f"the address space is limited to {_size(limit)} (ulimit -v), this run "
                f"needs about {_size(need)} ({describe_setup(cfg)} plus "
                f"{_size(BASE_ADDRESS_SPACE)} for the program and its libraries): raise "
                f"the limit (ulimit -v {int(need / 1024) + 1}) or make the run smaller")
    return None
