"""Write one shard: ``{split}/shard-NNNNN.h5`` and its ``.json`` twin.

Both files are written under temporary names and renamed only when complete, JSON
first and HDF5 last, so a shard whose ``.h5`` exists under its final name is whole.
HDF5 bytes are deterministic (``track_times=False``, fixed chunking, no timestamps), so
a resumed or re-run job writes identical files.
"""
from __future__ import annotations

import errno
import glob
import hashlib
import json
import os
from dataclasses import dataclass

import h5py
import numpy as np

from ..errors import DatasetError
from ..jsonable import jsonable
from .dataset import FORMAT_VERSION, ShardEntry
from .layout import shard_names
from .records import LABEL_KEYS, SceneRecord


@dataclass
class RenderedScene:
    """One rendered scene, ready to store.

    audio: float32 [C, T]. azimuth/elevation/distance: float32 [S, F] (NaN where a
    source has no position). active: bool [S, F]. mic_positions: float32 [C, 3] array
    frame. record: the JSON description of the scene (docs/format.md).
    """

    scene_id: str
    query: str
    audio: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    distance: np.ndarray
    active: np.ndarray
    mic_positions: np.ndarray
    record: SceneRecord | None = None


def write_shard(out_dir: str, split: str, shard: int, scenes: list[RenderedScene], attrs: dict,
                checksums: bool = True) -> ShardEntry | None:
    """Write one shard atomically; returns its entry for ``dataset.json`` (None without
    ``checksums``). attrs: :func:`~tsel_data.store.dataset.shard_attrs`."""
    h5_rel, json_rel = shard_names(split, shard)
    h5_path, json_path = os.path.join(out_dir, h5_rel), os.path.join(out_dir, json_rel)
    n_src = max(s.azimuth.shape[0] for s in scenes)

    doc = {"format_version": FORMAT_VERSION, "split": split, "shard": shard, **attrs,
           "scenes": [s.record for s in scenes]}
    what = json_rel
    try:
        os.makedirs(os.path.dirname(h5_path), exist_ok=True)
        remove_stale_tmp(json_path)
        remove_stale_tmp(h5_path)
        atomic_write(json_path, (json.dumps(jsonable(doc), ensure_ascii=False, indent=1) + "\n").encode("utf-8"))
        what = h5_rel
        _atomic_write_h5(h5_path, scenes, n_src, {"split": split, "shard": shard, **attrs})
    except OSError as e:
        raise write_error(what, e, out_dir) from None
    return shard_entry(out_dir, split, shard, len(scenes)) if checksums else None


def shard_entry(out_dir: str, split: str, shard: int, n_scenes: int) -> ShardEntry:
    """A shard's entry in ``dataset.json``: its files and their sha256."""
    h5_rel, json_rel = shard_names(split, shard)
    return ShardEntry(h5_rel, json_rel, n_scenes, sha256_file(os.path.join(out_dir, h5_rel)),
                      sha256_file(os.path.join(out_dir, json_rel)))


def write_text(path: str, text: str) -> None:
    """Write a text file atomically (:func:`atomic_write`), removing temporary files of
    killed writers first; a failed write is one DatasetError line naming the file."""
    remove_stale_tmp(path)
    try:
        atomic_write(path, text.encode("utf-8"))
    except OSError as e:
        raise write_error(os.path.basename(path), e, os.path.dirname(path)) from None


def write_json(path: str, doc) -> None:
    """A JSON document (indent 1, UTF-8), atomically."""
    write_text(path, json.dumps(jsonable(doc), ensure_ascii=False, indent=1) + "\n")


def write_lines(path: str, lines) -> None:
    """One line per item (``lines`` hold no newline), atomically."""
    write_text(path, "".join(line + "\n" for line in lines))


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


def _atomic_write_h5(path: str, scenes: list[RenderedScene], n_src: int, attrs: dict) -> None:
    n = len(scenes)
    c, t = scenes[0].audio.shape
    f_ = scenes[0].azimuth.shape[1]
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with h5py.File(tmp, "w", track_order=False, libver=("earliest", "v110")) as h:
            audio = h.create_dataset("audio", (n, c, t), dtype="float32", chunks=(1, c, t), track_times=False)
            for i, s in enumerate(scenes):
                audio[i] = s.audio
            g = h.create_group("labels")
            for key in LABEL_KEYS:
                g.create_dataset(key, data=_stack_padded([getattr(s, key) for s in scenes], n_src, np.nan, np.float32),
                                 track_times=False)
            g.create_dataset("active", data=_stack_padded([s.active for s in scenes], n_src, False, bool),
                             track_times=False)
            str_t = h5py.string_dtype("utf-8")
            h.create_dataset("query", data=np.array([s.query for s in scenes], dtype=object), dtype=str_t,
                             track_times=False)
            h.create_dataset("scene_id", data=np.array([s.scene_id for s in scenes], dtype=object), dtype=str_t,
                             track_times=False)
            h.create_dataset("mic_positions", data=np.stack([s.mic_positions for s in scenes]).astype(np.float32),
                             track_times=False)
            for k, v in sorted(attrs.items()):
                h.attrs[k] = _attr(v)
            h.attrs["frames"] = f_
        _fsync_file(tmp)
        os.replace(tmp, path)
        _fsync_dir(os.path.dirname(path))
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


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


def write_error(what: str, e: OSError, out_dir: str = "") -> DatasetError:
    """A one-line DatasetError for a failed write (full disk, unwritable folder, ...).

    h5py reports HDF5 failures as OSError without errno; the reason is then read from
    the message.
    """
    text = str(e)
    where = out_dir or "the output folder"
    if e.errno in _NO_SPACE or "No space left" in text or "Disk quota" in text:
        why = (f"no space left on the device; free space (or move {where} elsewhere) and rerun with --resume: "
               f"finished shards are kept")
        reason = "disk full"
    elif e.errno in _NOT_WRITABLE or any(m in text for m in ("Permission denied", "Operation not permitted",
                                                               "Read-only file system")):
        why = f"{where} is not writable; fix its permissions or choose another --out"
        reason = e.strerror or "not writable"
    else:
        why = "check the output folder and rerun with --resume"
        reason = e.strerror or (text.splitlines()[0] if text else type(e).__name__)
    return DatasetError(f"cannot write {what}: {reason}; {why}")


def _stack_padded(arrays, n_src, fill, dtype) -> np.ndarray:
    n_frames = arrays[0].shape[1]
    out = np.full((len(arrays), n_src, n_frames), fill, dtype=dtype)
    for i, a in enumerate(arrays):
        out[i, : a.shape[0]] = a
    return out


def _attr(v):
    if isinstance(v, (list, tuple)):
        if all(isinstance(x, str) for x in v):
            return np.array(v, dtype=h5py.string_dtype("utf-8"))
        return np.asarray(v)
    return v


def sha256_file(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
