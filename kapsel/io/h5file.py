"""HDF5 files written through Python file objects (h5py's fileobj driver), so that a failed
write (a full disk, a quota) is an OSError naming the file, never a crash.

With HDF5's own driver, a write that fails leaves the library holding dirty metadata that it
tries to write again when each object is freed and at exit: tracebacks from destructors and,
at the end, a segmentation fault (issue 26).  :class:`SafeFile` keeps the first failure in
``error`` and, from then on, takes every write without passing it on (``dead``), so HDF5
closes cleanly; the caller removes or rolls back the file and raises ``error``.
"""
from __future__ import annotations

import io
import os

import h5py

from udf.files import create_temporary, os_open_regular, put_in_place, remove


def _pwrite_all(fd, data, off) -> None:
    view = memoryview(data)
    while view:
        n = os.pwrite(fd, view, off)
        view, off = view[n:], off + n


class SafeFile(io.RawIOBase):
    """A file object on descriptor ``fd`` for ``h5py.File`` (module docstring)."""

    def __init__(self, fd: int, path: str):
        self.fd, self.path = fd, os.fspath(path)
        self.pos = 0
        self.error: OSError | None = None     # the first failed write
        self.dead = False                     # after a failure: writes are dropped

    def fail(self, e: OSError) -> None:
        self.error = self.error or e
        self.dead = True

    def failure(self) -> OSError:
        """The failure as an OSError naming the file."""
        e = self.error
        return OSError(e.errno, e.strerror, self.path)

    def readable(self):
        return True

    def writable(self):
        return True

    def seekable(self):
        return True

    def seek(self, offset, whence=io.SEEK_SET):
        if whence == io.SEEK_SET:
            self.pos = offset
        elif whence == io.SEEK_CUR:
            self.pos += offset
        else:
            self.pos = os.fstat(self.fd).st_size + offset
        return self.pos

    def tell(self):
        return self.pos

    def readinto(self, b):
        view = memoryview(b).cast("B")
        data = os.pread(self.fd, len(view), self.pos)
        view[:len(data)] = data
        self.pos += len(data)
        return len(data)

    def _change(self, start: int, end: int) -> None:
        """Called before bytes [start, end) change (the journal hooks in here)."""

    def write(self, b):
        view = memoryview(b).cast("B")
        if not self.dead:
            try:
                self._change(self.pos, self.pos + len(view))
                _pwrite_all(self.fd, view, self.pos)
            except OSError as e:
                self.fail(e)
        self.pos += len(view)
        return len(view)

    def truncate(self, size=None):
        size = self.pos if size is None else size
        if not self.dead:
            try:
                if size != os.fstat(self.fd).st_size:
                    self._change(size, 1 << 62)
                    os.ftruncate(self.fd, size)
            except OSError as e:
                self.fail(e)
        return size

    def flush(self):
        pass                          # every write is a pwrite

    def sync(self) -> None:
        if not self.dead:
            try:
                os.fsync(self.fd)
            except OSError as e:
                self.fail(e)

    def close(self):
        if not self.closed:
            os.close(self.fd)
        super().close()


def write_h5(path, fill, **kw) -> None:
    """Write the HDF5 file ``path`` atomically: ``fill(h5py.File)`` on a temporary file
    next to it, synced and renamed into place (udf.files).  A failed write raises OSError
    naming ``path``; nothing of the temporary file is left.  ``kw``: h5py.File's options
    (``libver``)."""
    fd, tmp = create_temporary(path)
    target = SafeFile(fd, path)
    try:
        try:
            with h5py.File(target, "w", **kw) as f:
                fill(f)
        except Exception:
            if target.error is None:
                raise
        target.sync()
        if target.error is not None:
            raise target.failure()
        target.close()
        put_in_place(tmp, path)
    except BaseException:
        target.close()
        remove(tmp)
        raise


def append_h5(path, change, **kw) -> None:
    """``change(h5py.File)`` made in place to the existing file ``path`` (small additions to
    a file that is derived data and rebuilt whole when a run starts, such as the XDMF
    sidecars).  A failed write removes the file and raises OSError naming it: never a
    half-written file that a reader trips over, never HDF5's crash at exit."""
    fd = os_open_regular(path, os.O_RDWR)
    target = SafeFile(fd, path)
    try:
        try:
            with h5py.File(target, "a", **kw) as f:
                change(f)
        except Exception:
            if target.error is None:
                raise
        target.sync()
        if target.error is not None:
            raise target.failure()
    except BaseException:
        target.close()
        remove(path)
        raise
    target.close()
