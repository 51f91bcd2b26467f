"""Where each scene's audio bytes lie in its HDF5 shard, for exports that copy them as
they are: read straight into a reused buffer (no decoding, no HDF5 machinery), so an
export costs about what copying the shards costs.

Only float32 and int16 shards the writer made qualify (one unfiltered, little-endian chunk
per scene: its bytes are the [C, T] samples in C order, what the reader returns); anything
else has no extents and is read through the reader.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import h5py
import numpy as np

from ..errors import DatasetError
from .dataset import load_dataset_doc
from .layout import RECEIVERS_GROUP
from .reader import open_shard

RAW_DTYPES = (np.dtype("<f4"), np.dtype("<i2"))


@dataclass(frozen=True)
class Extent:
    """``nbytes`` bytes at ``offset`` of ``path``: one scene's samples, ``dtype`` [C, T]."""

    path: str
    offset: int
    nbytes: int
    dtype: np.dtype
    shape: tuple

    def __len__(self) -> int:
        return self.nbytes


def audio_extents(root: str, split: str, receiver: str | None = None) -> list[Extent] | None:
    """The extent of every scene of ``split`` in order (the audio of ``receiver``, of a
    dataset heard by several; default the first), or None when a shard does not store
    that audio as raw chunks (a flac dataset, a rewritten file)."""
    doc = load_dataset_doc(root)
    name = "audio" if receiver is None or receiver == doc.format else f"{RECEIVERS_GROUP}/{receiver}/audio"
    out: list[Extent] = []
    for entry in doc.shards(split):
        path = os.path.join(root, entry.file)
        with open_shard(path) as f:
            d = f.get(name)
            if not isinstance(d, h5py.Dataset):  # a damaged shard: the reader names it
                return None
            if (d.ndim != 3 or d.chunks != (1, *d.shape[1:]) or d.id.get_create_plist().get_nfilters() != 0
                    or d.dtype not in RAW_DTYPES or not np.little_endian):
                return None
            shape = tuple(int(v) for v in d.shape[1:])
            nbytes = int(np.prod(shape)) * d.dtype.itemsize
            for r in range(d.shape[0]):
                info = d.id.get_chunk_info_by_coord((r, 0, 0))
                if info.byte_offset is None or info.size != nbytes:
                    return None
                out.append(Extent(path, int(info.byte_offset), nbytes, np.dtype(d.dtype), shape))
    return out


def read_extent(extent: Extent, src_fd: int, buf: np.ndarray) -> memoryview:
    """``extent``'s bytes, read from ``src_fd`` (an open descriptor of its file) into the
    uint8 buffer ``buf`` (at least ``extent.nbytes`` long); a view of ``buf``, valid until
    the next read into it."""
    view = memoryview(buf)[:extent.nbytes]
    done = 0
    while done < extent.nbytes:
        n = os.preadv(src_fd, [view[done:]], extent.offset + done)
        if n <= 0:
            raise DatasetError(f"{extent.path} ends inside a scene's audio (byte {extent.offset + done}); the "
                               f"shard is damaged: `tsel check` the dataset, render the shard again")
        done += n
    if extent.dtype.kind == "f" and not np.isfinite(np.frombuffer(view, extent.dtype)).all():
        raise DatasetError(f"{extent.path}: damaged shard (a scene's audio holds NaN or Inf samples, at byte "
                           f"{extent.offset}); `tsel check` the dataset, render the shard again")
    return view
