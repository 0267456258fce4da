"""Files, safely: the one place where kapsel-py creates temporary files, puts them in place,
and opens files for reading.

Writing.  Every file is written under a temporary name in its own directory
(``.<name>.<pid>.<hex>.kapsel-tmp``, mode 0666 & ~umask), flushed to the disk (fsync), and
renamed over its target; the directory is then synced, so after a kill at any system call
or a power loss the target holds either its old or its new content, never a part.  A
killed write leaves its temporary file behind; :func:`remove_temporaries` deletes them (a
run calls it under its lock, when no other writer can be at work in the directory).

Reading.  :func:`open_regular` refuses what is not a regular file *before* reading: a FIFO
would block for ever, a character device (/dev/zero) never ends.
"""
from __future__ import annotations

import os
import re
import secrets
import stat

TEMP_SUFFIX = ".kapsel-tmp"
# ours, and the names of earlier versions (atomic.py's ".<name>.<pid>.<hex>.tmp",
# restart.py's "<name>.tmp<pid>")
_TEMP_NAMES = re.compile(r"(^\.(?P<a>.+)\.(?P<pa>\d+)\.[0-9a-f]{8}(\.tmp|\.kapsel-tmp)$)"
                         r"|(^(?P<b>[^.].*)\.tmp(?P<pb>\d+)$)")


class NotRegularFile(OSError):
    """A path to be read that names a FIFO, a device, a socket or a directory."""


def user_mode() -> int:
    """The mode a newly created file gets from the user's umask (0666 & ~umask)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def create_temporary(path) -> tuple[int, str]:
    """(descriptor open for writing, name) of a new temporary file next to ``path``."""
    directory, name = os.path.split(os.path.abspath(os.fspath(path)))
    while True:
        tmp = os.path.join(directory, f".{name}.{os.getpid()}.{secrets.token_hex(4)}"
                                      f"{TEMP_SUFFIX}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666)
        except FileExistsError:
            continue
        try:
            os.fchmod(fd, user_mode())
        except OSError:
            pass
        return fd, tmp


def fsync_directory(directory) -> None:
    """Make a rename in ``directory`` durable (no-op where directories cannot be synced)."""
    try:
        fd = os.open(directory or ".", os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def put_in_place(tmp: str, path) -> None:
    """Rename the complete (already synced) ``tmp`` over ``path`` and sync the directory."""
    os.replace(tmp, path)
    fsync_directory(os.path.dirname(os.path.abspath(os.fspath(path))))


def remove(path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def write_file(path, write) -> None:
    """Call ``write(tmp_path)`` to fill a temporary file next to ``path`` (``write`` may
    reopen it by name, e.g. h5py), sync it, and put it in place; on any failure the
    temporary file is removed and ``path`` is untouched."""
    fd, tmp = create_temporary(path)
    os.close(fd)
    try:
        write(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        put_in_place(tmp, path)
    except OSError as e:
        remove(tmp)
        raise OSError(e.errno, e.strerror, os.fspath(path)) from None
    except BaseException:
        remove(tmp)
        raise


def remove_temporaries_of(path) -> list[str]:
    """Delete what killed writes of ``path`` left next to it (:func:`remove_temporaries`)."""
    directory, name = os.path.split(os.path.abspath(os.fspath(path)))
    return remove_temporaries(directory, of={name})


def write_stream(path, write) -> None:
    """:func:`write_file` for a writer of a binary stream: ``write(fh)``."""
    fd, tmp = create_temporary(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        put_in_place(tmp, path)
    except OSError as e:
        remove(tmp)
        raise OSError(e.errno, e.strerror, os.fspath(path)) from None
    except BaseException:
        remove(tmp)
        raise


def _writer_alive(pid: int) -> bool:
    """Whether process ``pid`` (the writer named in a temporary's name) still runs here."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:          # another user's process: alive
        return True
    return True


def remove_temporaries(directory, of=None) -> list[str]:
    """Delete the temporary files killed writes left in ``directory`` (those whose writer,
    the pid in the name, no longer runs: a live writer's file is its work in progress);
    ``of``: only the temporaries of these file names.  Returns their names.  A run calls it
    under its lock of the directory; an analysis for the files it writes."""
    try:
        names = os.listdir(directory)
    except OSError:
        return []
    gone = []
    for name in names:
        m = _TEMP_NAMES.match(name)
        if m is None:
            continue
        target, pid = m.group("a") or m.group("b"), m.group("pa") or m.group("pb")
        if (of is not None and target not in of) or _writer_alive(int(pid)):
            continue
        p = os.path.join(directory, name)
        try:
            if stat.S_ISREG(os.lstat(p).st_mode):
                os.unlink(p)
                gone.append(name)
        except OSError:
            pass
    return gone


def kind_of(mode: int) -> str:
    return ("a FIFO" if stat.S_ISFIFO(mode) else "a character device"
            if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode)
            else "a socket" if stat.S_ISSOCK(mode) else "a directory"
            if stat.S_ISDIR(mode) else "not a regular file")


def check_regular(path) -> None:
    """Raise NotRegularFile (or FileNotFoundError) unless ``path`` is a regular file."""
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        raise NotRegularFile(0, f"is {kind_of(mode)}, not a regular file", os.fspath(path))


def os_open_regular(path, flags: int = os.O_RDONLY, mode: int = 0o666) -> int:
    """``os.open(path, flags, mode)`` of a regular file only: the check and the open are one
    (O_NONBLOCK, so a FIFO is refused, not waited on; a new file made by O_CREAT is regular)."""
    fd = os.open(path, flags | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0), mode)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise NotRegularFile(0, f"is {kind_of(st.st_mode)}, not a regular file",
                                 os.fspath(path))
        os.set_blocking(fd, True)
        return fd
    except BaseException:
        os.close(fd)
        raise


def open_regular(path, mode: str = "rb", **kw):
    """``open(path, mode)`` for reading a regular file only (:func:`os_open_regular`)."""
    fd = os_open_regular(path)
    try:
        return os.fdopen(fd, mode, **kw)
    except BaseException:
        os.close(fd)
        raise


def disk_full(e: OSError) -> bool:
    """Whether a write failed for want of space (ENOSPC, or the quota: EDQUOT)."""
    import errno
    return e.errno in (errno.ENOSPC, errno.EDQUOT) or "No space left" in str(e)


def write_failure(e: OSError) -> str:
    """Why a write failed, in the user's words (the disk is full, the quota is exceeded, or
    the system's own reason)."""
    import errno
    if e.errno == errno.EDQUOT:
        return "the disk quota is exceeded"
    if disk_full(e):
        return "the disk is full (No space left on device)"
    return e.strerror or str(e)


def read_bytes(path) -> bytes:
    with open_regular(path) as fh:
        return fh.read()
