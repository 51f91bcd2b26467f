"""One writer per folder a command owns: an advisory lock on a file in it.

A dataset's is ``OUT/.tsel.lock`` (:class:`DatasetLock`): planning and finalizing hold it
exclusively; rendering holds it shared, so the tasks of a job array (``tsel render
--shards``) run side by side while a second ``tsel generate`` into the same folder is
refused in one line instead of mixing two plans. The lock file also marks the folder as
a tsel-data dataset (docs/reliability.md, "ownership"). An export's is
``OUT/.tsel-export.lock`` (:func:`export_lock`, every format): a second export into one
``--out`` is refused instead of reading the first one's journal as an interrupted run.

Locks are released when the holder exits, however it exits (``flock``). A process that
holds a lock exclusively may enter it again in any mode (``tsel generate`` holds it from
planning to finalizing, so no other run can slip in between its stages). Nobody waits:
a lock held elsewhere is a DatasetError at once.
"""
from __future__ import annotations

import fcntl
import os

from ..errors import DatasetError
from .layout import EXPORT_LOCK_FILE, Layout

# lock files this process holds exclusively -> how many times entered
_HELD: dict[str, int] = {}


class FolderLock:
    """``with FolderLock(folder, lock_file, exclusive, busy): ...``: ``busy(exclusive)`` is
    the refusal when another process holds the lock in a conflicting mode."""

    def __init__(self, folder: str, lock_file: str, exclusive: bool, busy):
        self.folder, self.lock_file, self.exclusive, self.busy = folder, lock_file, exclusive, busy
        self._fd = None

    def __enter__(self) -> "FolderLock":
        path = self.lock_file
        self._key = os.path.realpath(path)
        if self._key in _HELD:
            _HELD[self._key] += 1
            return self
        try:
            # O_NOFOLLOW|O_NONBLOCK: a link or a FIFO put under the lock's name is refused, never waited on
            self._fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o644)
        except OSError as e:
            raise DatasetError(f"cannot create {path}: {e.strerror or e}; check that {self.folder} is "
                               f"writable") from None
        try:
            fcntl.flock(self._fd, (fcntl.LOCK_EX if self.exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._fd)
            self._fd = None
            raise DatasetError(self.busy(self.exclusive)) from None
        if self.exclusive:
            _HELD[self._key] = 1
        return self

    def __exit__(self, *exc) -> None:
        if self._key in _HELD:
            _HELD[self._key] -= 1
            if _HELD[self._key]:
                return
            del _HELD[self._key]
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None


class DatasetLock(FolderLock):
    """``with DatasetLock(layout, exclusive=True, what="plan it"): ...`` (DatasetError if
    another process holds it in a conflicting mode; never waits)."""

    def __init__(self, layout: Layout, exclusive: bool, what: str):
        self.layout = layout

        def busy(exclusive: bool) -> str:
            other = "is rendering or finalizing" if exclusive else "is planning or finalizing"
            return (f"{layout.root}: another tsel process {other} this dataset; wait for it to end before you "
                    f"{what}, or choose another --out")

        super().__init__(layout.root, layout.lock_file, exclusive, busy)


def export_lock(out: str) -> FolderLock:
    """The lock of the export folder ``out`` (which exists), held exclusively for a whole
    export run."""
    return FolderLock(out, os.path.join(out, EXPORT_LOCK_FILE), True,
                      lambda _: f"{out}: another tsel export is writing into this folder; wait for it to end, or "
                                f"choose another --out")
