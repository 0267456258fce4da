"""Kill a run at exact system calls (strace's fault injection) and continue it.

A run is traced once (``strace -y``, main thread: the one that writes every file); the
system calls of a *window* -- everything one snapshot writes, or the final restart and the
closing of the files -- are numbered by kind.  For a kill point (kind, n) the run is
started again under ``strace -e inject=<kind>:signal=KILL:when=<n>``: SIGKILL arrives as
the n-th call of that kind enters the kernel, so that call never happens.  The continuation
(``-Irestart.udf ... -Rrestart.udf``, no --seed) must exit 0 and leave the files of an
uninterrupted run (:func:`compare_runs`), with no temporary file or journal left.

The same machinery injects ENOSPC (``error=ENOSPC``) instead of the kill: the run must end
with exit 1 and one line naming the full disk, and lose nothing it had written.

PYTHONDONTWRITEBYTECODE keeps the interpreter's own writes out of the numbering; the trace is
taken twice and must agree (the numbering is then that of every run of the input).
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import zipfile

import h5py
import numpy as np

KINDS = ("write", "pwrite64", "rename", "fsync")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KAPSEL = [sys.executable, "-c", "import sys; from kapsel.cli import main; sys.exit(main())"]
TIMESTAMPED = ()          # files that carry a time stamp: none (see compare_runs)


def env():
    return dict(os.environ, PYTHONPATH=os.pathsep.join([ROOT] + sys.path),
                PYTHONDONTWRITEBYTECODE="1", OMP_NUM_THREADS="1")


def have_strace() -> bool:
    return shutil.which("strace") is not None


def command(inp="input.udf", seed=3):
    return KAPSEL + [f"-I{inp}", "-Ooutput.udf", "-Ddefine.udf", "-Rrestart.udf", "--quiet"] \
        + (["--seed", str(seed)] if seed is not None else [])


def mpiexec():
    """The mpiexec of the `mpi` extra (next to the interpreter), else the system's."""
    here = os.path.dirname(sys.executable)
    return shutil.which("mpiexec", path=here) or shutil.which("mpiexec")


def run(d, cmd, strace=None, timeout=300, ranks=1):
    """``cmd`` in directory ``d``, under ``strace strace...`` if given; with ``ranks`` > 1
    a distributed run (mpiexec, MPMD: strace on rank 0 only, the rank that writes)."""
    pre = ["strace", "-qq", *strace] if strace else []
    argv = pre + cmd
    if ranks > 1:
        argv = [mpiexec(), "-n", "1"] + argv + [":", "-n", str(ranks - 1)] + cmd
    return subprocess.run(argv, cwd=d, capture_output=True, text=True, env=env(),
                          timeout=timeout)


_CALL = re.compile(r"^(\w+)\((.*)$")


def trace(d, cmd, ranks=1):
    """[(kind, n, text)] of the run's write/pwrite64/rename/fsync calls in order, n
    counting from 1 per kind (of rank 0 in a distributed run)."""
    log = os.path.abspath(d) + ".strace"
    r = run(d, cmd, ["-y", "-o", log, "-e", "trace=" + ",".join(KINDS)], ranks=ranks)
    assert r.returncode == 0, r.stderr
    calls, count = [], dict.fromkeys(KINDS, 0)
    with open(log) as fh:
        for line in fh:
            m = _CALL.match(line)
            if m and m.group(1) in count:
                count[m.group(1)] += 1
                calls.append((m.group(1), count[m.group(1)], line.strip()))
    os.unlink(log)
    return calls


def windows(calls, snapshot_step):
    """(one snapshot, final restart): the calls from the output.udf record of
    ``snapshot_step`` to the state file's rename that ends that snapshot, and the calls
    after the last snapshot's state rename (the final restart, the files' close)."""
    first = next(i for i, c in enumerate(calls)
                 if c[0] == "write" and f'{{\\"step {snapshot_step}\\"}}' in c[2])
    renames = [i for i, c in enumerate(calls)
               if c[0] == "rename" and _STATE_RENAME.search(c[2])]
    end = next(i for i in renames if i > first)
    return calls[first:end + 1], calls[renames[-2] + 1:]


_STATE_RENAME = re.compile(r', "[^"]*restart\.udf\.state\.npz"\) = 0')


def temporaries(d):
    out = []
    for root, _dirs, files in os.walk(d):
        out += [os.path.join(root, f) for f in files
                if "kapsel-tmp" in f or "kapsel-journal" in f or re.search(r"\.tmp\d*$", f)]
    return out


def _npz(path):
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
    with np.load(path) as z:
        return names, {k: z[k] for k in z.files if k != "run_id"}


def _h5(path):
    out = {}

    def visit(name, obj):
        attrs = {k: np.asarray(v).tobytes() for k, v in obj.attrs.items()}
        data = obj[()].tobytes() if isinstance(obj, h5py.Dataset) else None
        out[name] = (attrs, data)
    with h5py.File(path, "r") as f:
        out["/"] = ({k: np.asarray(v).tobytes() for k, v in f.attrs.items()}, None)
        f.visititems(visit)
    return out


def compare_runs(a, b) -> list[str]:
    """What differs between the files of run directories ``a`` and ``b``: every file byte
    for byte, except: output.udf's first line and the state file's ``run_id`` (the identity
    of a run, not its result: two runs of one input differ there), and the EXTENDED
    trajectory, compared by content (groups, datasets, attributes; a continued run that
    dropped a frame written after its restart leaves HDF5 free space where it was)."""
    diffs = []
    fa = sorted(os.path.relpath(os.path.join(r, f), a) for r, _, fs in os.walk(a) for f in fs)
    fb = sorted(os.path.relpath(os.path.join(r, f), b) for r, _, fs in os.walk(b) for f in fs)
    if fa != fb:
        diffs.append(f"file lists differ: {sorted(set(fa) ^ set(fb))}")
    for rel in sorted(set(fa) & set(fb)):
        pa, pb = os.path.join(a, rel), os.path.join(b, rel)
        if rel == "output.udf":
            same = open(pa, "rb").read().split(b"\n", 1)[1] == \
                open(pb, "rb").read().split(b"\n", 1)[1]
        elif rel.endswith(".state.npz"):
            (na, xa), (nb, xb) = _npz(pa), _npz(pb)
            same = na == nb and xa.keys() == xb.keys() and all(
                xa[k].dtype == xb[k].dtype and np.array_equal(xa[k], xb[k]) for k in xa)
        elif rel.endswith(".h5") and rel.startswith("output"):
            same = _h5(pa) == _h5(pb)
        else:
            same = open(pa, "rb").read() == open(pb, "rb").read()
        if not same:
            diffs.append(rel)
    return diffs


def kill_and_continue(base, ref, cmd, kind, n, inject="signal=KILL", ranks=1):
    """Copy the fresh input directory ``base``, run it with the fault (kind, n), continue
    if killed; returns (fault run, continuation or None, directory)."""
    d = os.path.join(os.path.dirname(ref), f"kill-{kind}-{n}-{inject.split('=')[-1]}")
    if os.path.exists(d):
        shutil.rmtree(d)
    shutil.copytree(base, d)
    first = run(d, cmd, ["-o", "/dev/null", "-e", f"inject={kind}:{inject}:when={n}"],
                ranks=ranks)
    if inject != "signal=KILL":
        return first, None, d
    cont = run(d, command("restart.udf", seed=None), ranks=ranks)
    return first, cont, d
