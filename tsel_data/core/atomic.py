"""Writing files whole or not at all, and saying in one line why a write failed.

Every file the toolkit writes (shards, plans, ``dataset.json``, exports, pictures, WAVs,
banks, the demo corpus) goes through here or through the same steps: a temporary name
``PATH.tmp-PID``, flushed to disk, renamed over ``PATH`` (atomic on POSIX), the folder
synced. A killed writer leaves only a temporary file, which the next writer of the same
path removes. A failure (full disk, read-only folder) is one :class:`WriteError` line
naming the file; nothing under a final name is ever partial.
"""
from __future__ import annotations

import ctypes
import errno
import glob
import json
import os
from contextlib import contextmanager

from ..errors import TselError, WriteError, broken_link, shown_path
from .files import blocked_folder, replace_problem
from .jsonable import jsonable
from .libc import libc


@contextmanager
def atomic_output(path: str, what: str | None = None):
    """``with atomic_output(path) as tmp:`` write ``tmp``; it becomes ``path`` when the
    block ends without error, and disappears otherwise. Write failures (OSError, and the
    RuntimeError some libraries raise for a full disk) become one WriteError line
    naming ``what`` (default: the path). A device, FIFO, socket or folder at ``path`` is
    never replaced (core/files.replace_problem)."""
    refuse_special(path, what)
    remove_stale_tmp(path)
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        yield tmp
        _fsync_file(tmp)
        os.replace(tmp, path)
        _fsync_dir(os.path.dirname(path))
    except (OSError, RuntimeError) as e:
        if isinstance(e, RuntimeError) and not _looks_like_io(e):
            raise
        raise write_error(what or shown_path(path), e, os.path.dirname(os.path.abspath(path))) from None
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def refuse_special(path: str, what: str | None = None) -> None:
    """A TselError when ``path`` is a device, FIFO, socket or folder: whatever asked for
    the write (``--force`` too), a file never takes its place."""
    why = replace_problem(path)
    if why:
        raise TselError(f"{what or shown_path(path)} {why}")


def _looks_like_io(e: Exception) -> bool:
    text = str(e)
    return any(m in text for m in ("No space left", "Disk quota", "write failed", "Permission denied",
                                   "Read-only file system", "errno"))


def atomic_write(path: str, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all: ``path.tmp-PID``, fsync, rename."""
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        _fsync_dir(os.path.dirname(path))
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def write_text(path: str, text: str) -> None:
    """Write a text file atomically (:func:`atomic_write`), removing temporary files of
    killed writers first; a failed write is one WriteError line naming the file."""
    refuse_special(path)
    remove_stale_tmp(path)
    try:
        atomic_write(path, text.encode("utf-8"))
    except OSError as e:
        raise write_error(shown_path(path), e, os.path.dirname(os.path.abspath(path))) from None


def write_json(path: str, doc) -> None:
    """A JSON document (indent 1, UTF-8; :func:`~tsel_data.core.jsonable.jsonable` first), atomically."""
    write_text(path, json.dumps(jsonable(doc), ensure_ascii=False, indent=1) + "\n")


def write_lines(path: str, lines) -> None:
    """One line per item (``lines`` hold no newline), atomically."""
    write_text(path, "".join(line + "\n" for line in lines))


def start_writeback(fd: int, offset: int, nbytes: int) -> None:
    """Start writing ``nbytes`` at ``offset`` of ``fd`` to disk without waiting for it
    (Linux ``sync_file_range``), so that the fsync that ends a long write waits for the
    last part only, the disk busy while the writer works on; a no-op elsewhere."""
    fn = getattr(libc(), "sync_file_range", None)  # Linux only
    if fn is not None:
        # SYNC_FILE_RANGE_WRITE; a failure shows at the fsync that follows
        fn(fd, ctypes.c_int64(offset), ctypes.c_int64(nbytes), 2)


def _fsync_file(path: str) -> None:
    """Flush a closed file's data to disk, so a rename never exposes unwritten blocks."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(path: str) -> None:
    """Make a rename durable (POSIX); silently skipped where directories cannot be opened."""
    try:
        fd = os.open(path or ".", os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def remove_stale_tmp(path: str) -> list[str]:
    """Delete ``path.tmp-PID`` files left by killed writers (PID not alive here); returns them.

    A killed run cannot clean up after itself; the next writer of the same file does.
    Files of live processes are kept (another job may be writing the same shard).
    """
    removed = []
    for tmp in glob.glob(glob.escape(path) + ".tmp-*"):
        pid = tmp.rsplit(".tmp-", 1)[1]
        if pid.isdigit() and int(pid) != os.getpid() and _alive(int(pid)):
            continue
        try:
            os.remove(tmp)
            removed.append(tmp)
        except FileNotFoundError:
            pass
    return removed


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs here. A zombie (killed, not yet reaped: common in
    containers whose PID 1 reaps slowly) counts as dead: it writes nothing any more."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            state = f.read().rsplit(b")", 1)[1].split()[0]
        return state not in (b"Z", b"X")
    except (OSError, IndexError):
        return True


_NO_SPACE = (errno.ENOSPC, errno.EDQUOT)
_NOT_WRITABLE = (errno.EACCES, errno.EPERM, errno.EROFS)
_NOT_WRITABLE_TEXT = ("Permission denied", "Operation not permitted", "Read-only file system")
# a write that fails for no reason its library gives (libsndfile's "System error.") with
# less than this free on the disk failed for want of space
_NEARLY_FULL = 1 << 20


def write_error(what: str, e: OSError, out_dir: str = "", resumable: bool = False) -> WriteError:
    """A one-line WriteError for a failed write of ``what`` (a file, named as the message
    names it) into ``out_dir``: a full disk, a folder not writable or not there.

    The reason comes from the errno; h5py reports HDF5 failures without one and
    libsndfile says only "System error.", so then it is read from the message, and
    failing that from the folder itself (missing, a link to nowhere, not writable, a disk
    with next to no space). ``resumable``: what was written before stays (a dataset's
    shards), and the message says to rerun with ``--resume``.
    """
    text = str(e)
    errno_ = getattr(e, "errno", None)  # RuntimeError from h5py has none
    folder = out_dir or os.path.dirname(os.path.abspath(getattr(e, "filename", None) or what))
    where = shown_path(folder) if folder else "the output folder"
    elsewhere = "choose another --out" if resumable else "write elsewhere"
    full = errno_ in _NO_SPACE or "No space left" in text or "Disk quota" in text or "errno = 28" in text
    not_writable = errno_ in _NOT_WRITABLE or any(m in text for m in _NOT_WRITABLE_TEXT)
    gone = None
    if not full and not not_writable:
        gone = _missing_folder(getattr(e, "filename", None) or "", folder)
        full = gone is None and _nearly_full(folder)
        not_writable = gone is None and not full and _exists_unwritable(folder)
    if full:
        reason, why = "disk full", "no space left on the device; free space" + ("" if resumable else
                                                                               " or write to another disk")
    elif not_writable:
        reason = getattr(e, "strerror", None) or next((m for m in _NOT_WRITABLE_TEXT if m in text), "not writable")
        why = f"{where} is not writable; fix its permissions or {elsewhere}"
    elif gone is not None:
        reason, why = gone
    else:
        reason = getattr(e, "strerror", None) or (text.splitlines()[0][:200] if text else type(e).__name__)
        why = f"check {where}"
    return WriteError(f"cannot write {what}: {reason}; {why}", resumable)


def _existing(folder: str) -> str:
    """``folder``, or the nearest folder above it that exists."""
    folder = os.path.abspath(folder or ".")
    while not os.path.isdir(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    return folder


def _missing_folder(filename: str, folder: str) -> tuple[str, str] | None:
    """(reason, fix) when the file's folder is not there: a symbolic link to nothing on the
    way to it, or a folder that does not exist."""
    for start in (filename, folder):
        p = os.path.abspath(start) if start else ""
        while p and os.path.dirname(p) != p:
            link = broken_link(p)
            if link:
                return f"{shown_path(p)} {link}", "create what it points to, or remove the link"
            p = os.path.dirname(p)
    if folder and not os.path.isdir(folder):
        blocked = blocked_folder(folder)  # a file, a FIFO, a device where a folder should be
        if blocked:
            return blocked, "choose a folder, or write elsewhere"
        return f"the folder {shown_path(folder)} does not exist", "create it or write elsewhere"
    return None


def _nearly_full(folder: str) -> bool:
    try:
        st = os.statvfs(_existing(folder))
    except OSError:
        return False
    return st.f_bavail * st.f_frsize < _NEARLY_FULL


def _exists_unwritable(folder: str) -> bool:
    return os.path.isdir(folder) and not os.access(folder, os.W_OK)
