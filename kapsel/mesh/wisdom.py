"""FFTW wisdom kept on disk: FFT plans measured once per machine and mesh shape, then the
same plans in every process.

FFTW_MEASURE (the planner above 64^3 points or with threads, kapsel.mesh.grid.auto_planner)
picks its algorithm by timing candidates, so two processes planning the same transform may
get different plans, whose results differ at round-off.  With a wisdom file, a process plans
under an exclusive lock on it: it imports the wisdom there, plans (FFTW takes a stored plan
without measuring), and stores what it measured.  Every process on the machine then
transforms a given shape with the same plan: runs, and a run and its continuation, are
reproducible bit for bit at every mesh size, and only the first run of a shape pays the
measuring (about 1 s a plan at 128^3).  FFTW_ESTIMATE plans (up to 64^3, one thread) are
made without the file: FFTW would take a stored measured plan for them too.

The file: ``$KAPSEL_PY_FFTW_WISDOM`` when set ("off" or "" keeps none: the planner of
kapsel.mesh.grid.auto_planner without it), else ``$XDG_CACHE_HOME/kapsel-py/`` (default
``~/.cache/kapsel-py/``) ``fftw-wisdom-<key>``, the key naming the CPU model and the FFTW
and pyfftw versions (a cluster's home directory shared by different nodes keeps one file
per CPU kind).  Deleting it makes the next run measure again (its plans, and so its last
digits, may then differ from the earlier runs').  A directory that cannot be written is
the same as "off".
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import platform

__all__ = ["ENV", "path", "enabled", "planning"]

ENV = "KAPSEL_PY_FFTW_WISDOM"
_state = {"depth": 0, "enabled": None}


def _key() -> str:
    cpu = platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu += line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        import pyfftw
        versions = f"{pyfftw.__version__} {getattr(pyfftw, 'fftw_version', '')}"
    except ImportError:  # pragma: no cover
        versions = ""
    return hashlib.sha256(f"{cpu}|{versions}".encode()).hexdigest()[:16]


def path() -> str | None:
    """The wisdom file, or None when none is kept (module docstring)."""
    v = os.environ.get(ENV)
    if v is not None:
        return None if v.strip().lower() in ("", "off", "0", "no") else v
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "kapsel-py", f"fftw-wisdom-{_key()}")


def enabled() -> bool:
    """A wisdom file is kept: its directory, or the nearest existing one above it (where
    ``planning`` makes it), is a directory that can be written.  Nothing is made here (a
    ``kapsel-py --check`` writes nothing).  Decided once per process (the planner of every
    grid of a run must be the same)."""
    if _state["enabled"] is None:
        p = path()
        ok = False
        if p is not None:
            d = os.path.dirname(os.path.abspath(p))
            while not os.path.lexists(d) and os.path.dirname(d) != d:
                d = os.path.dirname(d)
            ok = os.path.isdir(d) and os.access(d, os.W_OK | os.X_OK)
        _state["enabled"] = ok
    return _state["enabled"]


def _read(p: str) -> bytes:
    try:
        with open(p, "rb") as f:
            return f.read()
    except OSError:
        return b""


def _write(p: str, data: bytes) -> None:
    """Replace the file as every file of a run is replaced (udf.files.write_file: a synced
    temporary file renamed over it), so that a reader never sees half of it; a write that
    fails leaves the old file (the plans are measured again by a later run)."""
    from udf.files import write_file

    def fill(tmp):
        with open(tmp, "wb") as f:
            f.write(data)
    with contextlib.suppress(OSError):
        write_file(p, fill)


@contextlib.contextmanager
def planning(flags=("FFTW_MEASURE",)):
    """Plan FFTW transforms with ``flags`` inside: under the lock of the wisdom file, with its
    wisdom imported, and what was measured stored on leaving.  Nested uses take the lock
    once; with no file kept, or for FFTW_ESTIMATE plans (FFTW would take a stored measured
    plan for them too, and their bits must not depend on the file), it does nothing.  The
    process forgets all wisdom when a measuring ends: FFTW keeps it for the process, and an
    FFTW_ESTIMATE plan made later of a shape it holds would take it (its bits would then
    depend on what the process planned before)."""
    if isinstance(flags, str):
        flags = (flags,)
    estimate = "FFTW_ESTIMATE" in flags
    if _state["depth"] or not enabled() or estimate:
        _state["depth"] += 1
        try:
            yield
        finally:
            _state["depth"] -= 1
            if not _state["depth"] and not estimate:
                _forget()
        return
    import fcntl

    import pyfftw
    p = path()
    try:
        os.makedirs(os.path.dirname(os.path.abspath(p)), exist_ok=True)
        lock = os.open(p + ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:
        lock = None
    if lock is not None:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
        except OSError:             # no locks here (some network file systems): read the
            os.close(lock)          # stored plans, store none
            lock = None
    _state["depth"] += 1
    try:
        before = _read(p)
        if before:
            pyfftw.import_wisdom((before, b"", b""))
        yield
        after = pyfftw.export_wisdom()[0]
        # FFTW exports its entries in the order of its hash table: the same wisdom may come
        # out in another order after an import
        if lock is not None and sorted(after.splitlines()) != sorted(before.splitlines()):
            _write(p, after)
    finally:
        _state["depth"] -= 1
        _forget()
        if lock is not None:
            os.close(lock)              # releases the lock


def _forget():
    try:
        import pyfftw
    except ImportError:  # pragma: no cover
        return
    pyfftw.forget_wisdom()
