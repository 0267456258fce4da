"""A file that can be put back to its last committed state: for the EXTENDED trajectory,
which HDF5 changes in place (superblock, B-trees, heaps), so that neither a temporary copy
(the file grows with the run) nor a plain append can keep it whole across a kill.

:class:`JournaledFile` is the file object h5py is given (``h5py.File(JournaledFile(...))``,
the fileobj driver).  Before the first change of a transaction (since the last
:meth:`~JournaledFile.commit`) it writes the journal ``.<name>.kapsel-journal`` with the
committed size; before it overwrites any byte below that size, it copies the 4 KiB pages
concerned into the journal and syncs it (an undo journal).  ``commit`` syncs the file and
deletes the journal.  :func:`recover` (run before the file is opened again) writes the
saved pages back and cuts the file to the committed size: after a kill at any system call,
the file is exactly as it was at its last commit.  A write that fails (a full disk) is kept
in ``error`` for the caller, which then rolls back at once (:meth:`JournaledFile.rollback`).
"""
from __future__ import annotations

import os
import struct
import zlib

from udf.files import fsync_directory, open_regular, os_open_regular

from .h5file import SafeFile, _pwrite_all

PAGE = 4096
MAGIC = b"kapsel-journal 1\n"
_HEAD = struct.Struct("<Q")          # committed size
_ENTRY = struct.Struct("<QQ")        # offset, length; then the bytes and their crc32


SUFFIX = ".kapsel-journal"


def journal_path(path) -> str:
    d, name = os.path.split(os.path.abspath(os.fspath(path)))
    return os.path.join(d, f".{name}{SUFFIX}")


def recover(path) -> bool:
    """Put ``path`` back to its state at the last commit if a journal is there (a writer
    was killed or failed mid-transaction); True if it did."""
    jpath = journal_path(path)
    try:
        with open_regular(jpath) as fh:
            data = fh.read()
    except FileNotFoundError:
        return False
    if not data.startswith(MAGIC) or len(data) < len(MAGIC) + _HEAD.size:
        os.unlink(jpath)              # killed before the journal held its size: the file
        fsync_directory(os.path.dirname(jpath))   # was not changed yet
        return False
    pos = len(MAGIC)
    (size,) = _HEAD.unpack_from(data, pos)
    pos += _HEAD.size
    entries = []
    while pos + _ENTRY.size <= len(data):
        off, n = _ENTRY.unpack_from(data, pos)
        end = pos + _ENTRY.size + n + 4
        if end > len(data):
            break                     # torn: its page was not changed yet
        body = data[pos + _ENTRY.size:end - 4]
        if zlib.crc32(data[pos:end - 4]) != struct.unpack_from("<I", data, end - 4)[0]:
            break
        entries.append((off, body))
        pos = end
    fd = os_open_regular(path, os.O_RDWR)
    try:
        for off, body in entries:
            _pwrite_all(fd, body, off)
        os.ftruncate(fd, size)
        os.fsync(fd)
    finally:
        os.close(fd)
    os.unlink(jpath)
    fsync_directory(os.path.dirname(jpath))
    return True


def recover_all(directory) -> list[str]:
    """:func:`recover` every journaled file of ``directory`` (a run does it under its lock,
    before anything else: also when it has nothing left to write); returns their names."""
    try:
        names = os.listdir(directory)
    except OSError:
        return []
    done = []
    for name in names:
        if name.startswith(".") and name.endswith(SUFFIX) and len(name) > len(SUFFIX) + 1:
            target = os.path.join(directory, name[1:-len(SUFFIX)])
            if os.path.isfile(target) and recover(target):
                done.append(os.path.basename(target))
    return done


def discard(path) -> None:
    """Drop the journal of a file that is being replaced by a new one."""
    try:
        os.unlink(journal_path(path))
    except FileNotFoundError:
        pass


class JournaledFile(SafeFile):
    """The file object of a journaled file (module docstring)."""

    def __init__(self, path, create: bool = False):
        flags = os.O_RDWR | (os.O_CREAT | os.O_TRUNC if create else 0)
        super().__init__(os_open_regular(os.fspath(path), flags), path)
        self.jpath = journal_path(path)
        self.committed = os.fstat(self.fd).st_size
        self.jfd = None
        self.saved: set[int] = set()

    # ------------------------------------------------------------ the journal
    def _begin(self) -> None:
        if self.jfd is not None:
            return
        fd = os.open(self.jpath, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        try:
            view = memoryview(MAGIC + _HEAD.pack(self.committed))
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        except BaseException:
            os.close(fd)
            raise
        fsync_directory(os.path.dirname(self.jpath))
        self.jfd = fd

    def _change(self, start: int, end: int) -> None:
        """Journal the committed pages [start, end) touches that are not saved yet."""
        self._begin()
        end = min(end, self.committed)
        if start >= end:
            return
        out = []
        for page in range(start // PAGE, (end - 1) // PAGE + 1):
            if page in self.saved:
                continue
            off = page * PAGE
            body = os.pread(self.fd, min(PAGE, self.committed - off), off)
            head = _ENTRY.pack(off, len(body))
            out.append(head + body + struct.pack("<I", zlib.crc32(head + body)))
            self.saved.add(page)
        if out:
            view = memoryview(b"".join(out))
            while view:
                view = view[os.write(self.jfd, view):]
            os.fsync(self.jfd)

    def commit(self) -> None:
        """The file as it is now becomes the state :func:`recover` returns to; raises the
        failure of an earlier write instead (the caller rolls back)."""
        self.sync()
        if self.error is not None:
            raise self.failure()
        if self.jfd is not None:
            os.close(self.jfd)
            self.jfd = None
            os.unlink(self.jpath)
            fsync_directory(os.path.dirname(self.jpath))
        self.committed = os.fstat(self.fd).st_size
        self.saved = set()

    def rollback(self) -> None:
        """Back to the last commit, at once (after a failed write); from now on writes
        are dropped (HDF5 may still write when its objects are freed)."""
        self.dead = True
        if self.jfd is not None:
            os.close(self.jfd)
            self.jfd = None
        try:
            recover(self.path)
        except OSError:
            pass                       # the journal stays: the next open recovers

    def close(self):
        if self.jfd is not None:
            os.close(self.jfd)
            self.jfd = None
        super().close()
