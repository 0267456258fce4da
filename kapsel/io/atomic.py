"""Atomic file writes and number formatting shared by the output writers.

Every file is written under a temporary name in its directory and moved into place with
:func:`os.replace`, so a reader (or a run killed mid-write) never sees a partial file; the
file gets the usual 0666 & ~umask mode.
"""
from __future__ import annotations

import os
import secrets


def fmt(x) -> str:
    """Shortest round-tripping text for a float (integers without a trailing '.0')."""
    x = float(x)
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def atomic_write(path: str, write) -> None:
    """Call ``write(tmp_path)`` on a temporary file next to ``path``, then rename it to ``path``."""
    directory, name = os.path.split(path)
    while True:
        tmp = os.path.join(directory, f".{name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
        try:  # created with the usual 0666 & ~umask mode (mkstemp would give 0600)
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def atomic_write_text(path: str, text: str) -> None:
    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
    atomic_write(path, write)


