"""One writer per dataset folder: an advisory lock on ``OUT/.tsel.lock``.

Planning and finalizing hold it exclusively; rendering holds it shared, so the tasks of
a job array (``tsel render --shards``) run side by side while a second ``tsel generate``
into the same folder is refused in one line instead of mixing two plans. The lock file
also marks the folder as a tsel-data dataset (docs/reliability.md, "ownership").
Locks are released when the holder exits, however it exits (``flock``). A process that
holds the lock exclusively may enter it again in any mode (``tsel generate`` holds it from
planning to finalizing, so no other run can slip in between its stages).
"""
from __future__ import annotations

import fcntl
import os

from ..errors import DatasetError
from .layout import Layout


# lock files this process holds exclusively -> how many times entered
_HELD: dict[str, int] = {}


class DatasetLock:
    """``with DatasetLock(layout, exclusive=True): ...`` (DatasetError if another process
    holds it in a conflicting mode; never waits)."""

    def __init__(self, layout: Layout, exclusive: bool, what: str):
        self.layout, self.exclusive, self.what = layout, exclusive, what
        self._fd = None

    def __enter__(self) -> "DatasetLock":
        path = self.layout.lock_file
        self._key = os.path.realpath(path)
        if self._key in _HELD:
            _HELD[self._key] += 1
            return self
        try:
            self._fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            raise DatasetError(f"cannot create {path}: {e.strerror or e}; check that {self.layout.root} is "
                               f"writable") from None
        try:
            fcntl.flock(self._fd, (fcntl.LOCK_EX if self.exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._fd)
            self._fd = None
            other = "is rendering or finalizing" if self.exclusive else "is planning or finalizing"
            raise DatasetError(f"{self.layout.root}: another tsel process {other} this dataset; wait for it to end "
                               f"before you {self.what}, or choose another --out") from None
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
