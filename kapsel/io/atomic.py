"""Atomic file writes and number formatting shared by the output writers.

Every file a run writes goes through udf.files: written under a temporary name in its
directory, synced, renamed into place, the directory synced; a reader (or a run killed at
any system call) never sees a partial file, and the temporaries of killed writes are
removed by the next run under its lock (kapsel.startup.lock_output_dirs).  Files that grow
(output.udf, the .dat tables) are appended whole or not at all (:func:`append_whole`); the
EXTENDED trajectory, which HDF5 modifies in place, has a rollback journal
(kapsel.io.journal).
"""
from __future__ import annotations

import os

from udf.files import write_file as atomic_write, write_stream  # noqa: F401  (re-exported)
from udf.manager import atomic_write_text  # noqa: F401  (synced, then renamed)


def fmt(x) -> str:
    """Shortest round-tripping text for a float (integers without a trailing '.0')."""
    x = float(x)
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def append_whole(path: str, data: bytes) -> None:
    """Append ``data`` to ``path`` entirely or not at all: one write call (a kill lands
    before or after it), synced; when the write fails (a full disk) the file is cut back
    to its previous end, so no torn line or record is left."""
    fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    try:
        end = os.fstat(fd).st_size
        try:
            view = memoryview(data)
            while view:
                n = os.write(fd, view)
                view = view[n:]
            os.fsync(fd)
        except OSError as e:
            os.ftruncate(fd, end)
            raise OSError(e.errno, e.strerror, path) from None
        except BaseException:
            os.ftruncate(fd, end)
            raise
    finally:
        os.close(fd)
