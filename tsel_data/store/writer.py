"""Write one shard: ``{split}/shard-NNNNN.h5`` and its ``.json`` twin.

Both files are written under temporary names and renamed only when complete, JSON
first and HDF5 last, so a shard whose ``.h5`` exists under its final name is whole.
HDF5 bytes are deterministic (``track_times=False``, fixed chunking, no timestamps), so
a resumed or re-run job writes identical files.
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
from dataclasses import dataclass

import h5py
import numpy as np

from ..atomic import _fsync_dir, _fsync_file, atomic_write, remove_stale_tmp, write_error
from ..jsonable import jsonable
from .dataset import FORMAT_VERSION, ShardEntry
from .integrity import FileSeal, Seal, sha256_file
from .layout import Layout, shard_names
from .records import LABEL_KEYS, SceneRecord

# Space a shard needs beyond its arrays (JSON records, HDF5 metadata), as a fraction: the
# free-space check before writing leaves this margin (see _check_space).
SPACE_MARGIN = 0.25


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
                fingerprint: str = "") -> ShardEntry:
    """Write one shard atomically and seal it; returns its entry for ``dataset.json``.

    attrs: :func:`~tsel_data.store.dataset.shard_attrs`. fingerprint: what the shard was
    made from (:func:`~tsel_data.store.integrity.shard_fingerprint`), kept in its seal.
    The JSON file is written first, the HDF5 file second and the seal last, each under a
    temporary name renamed when whole: a shard is complete exactly when its seal exists
    and matches (store/integrity.py). A failed write is one DatasetError line naming the
    file; finished shards are never touched.
    """
    layout = Layout(out_dir)
    h5_rel, json_rel = shard_names(split, shard)
    h5_path, json_path = layout.shard_files(split, shard)
    seal_path = layout.seal_file(split, shard)
    n_src = max(s.azimuth.shape[0] for s in scenes)

    doc = {"format_version": FORMAT_VERSION, "split": split, "shard": shard, **attrs,
           "scenes": [s.record for s in scenes]}
    js = (json.dumps(jsonable(doc), ensure_ascii=False, indent=1) + "\n").encode("utf-8")
    what = json_rel
    try:
        os.makedirs(os.path.dirname(h5_path), exist_ok=True)
        for p in (seal_path, json_path, h5_path):
            remove_stale_tmp(p)
        _check_space(os.path.dirname(h5_path), scenes, len(js), what)
        if os.path.exists(seal_path):
            os.remove(seal_path)  # an old seal must never vouch for the new files
        atomic_write(json_path, js)
        json_seal = FileSeal.of(json_path, hashlib.sha256(js).hexdigest())
        what = h5_rel
        h5_sha = _atomic_write_h5(h5_path, scenes, n_src, {"split": split, "shard": shard, **attrs})
        h5_seal = FileSeal.of(h5_path, h5_sha)
        what = os.path.relpath(seal_path, out_dir)
        atomic_write(seal_path, (json.dumps(Seal(fingerprint, h5_seal, json_seal).to_json()) + "\n").encode())
    except (OSError, RuntimeError) as e:  # h5py reports some HDF5 write failures as RuntimeError
        raise write_error(what, e, out_dir) from None
    return ShardEntry(h5_rel, json_rel, len(scenes), h5_seal.sha256, json_seal.sha256)


def _check_space(folder: str, scenes: list[RenderedScene], json_bytes: int, what: str) -> None:
    """Refuse, in one line, a shard the disk cannot hold: a write that runs out of space
    mid-file can take the HDF5 library down with it."""
    need = (sum(s.audio.nbytes + 4 * s.azimuth.size * 4 + s.mic_positions.nbytes for s in scenes) + json_bytes)
    need = int(need * (1 + SPACE_MARGIN))
    free = shutil.disk_usage(folder).free
    if free < need:
        raise OSError(errno.ENOSPC, f"No space left: the shard needs about {need / 1e6:.1f} MB, "
                                    f"{free / 1e6:.1f} MB are free", what)


def _atomic_write_h5(path: str, scenes: list[RenderedScene], n_src: int, attrs: dict) -> str:
    """Write the HDF5 file of a shard under a temporary name, then rename; returns its sha256."""
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
        digest = sha256_file(tmp)  # just written: read back from the page cache
        os.replace(tmp, path)
        _fsync_dir(os.path.dirname(path))
        return digest
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


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
