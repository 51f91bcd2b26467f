"""Lazily opened, fork-safe, read-only HDF5 handles.

Banks are shared by render workers (fork, dask, pickling). An HDF5 handle must not
cross a fork, so handles are opened on first use in each process and dropped when the
bank is pickled.
"""
from __future__ import annotations

import mmap
import os

import h5py
import numpy as np

from ..core.files import check_input
from ..errors import BankError


class H5Pool:
    def __init__(self):
        self._files: dict[str, h5py.File] = {}
        self._maps: dict[tuple[str, str], MappedRows | None] = {}
        self._pid = os.getpid()

    def _own(self) -> None:
        if self._pid != os.getpid():
            # Inherited from the parent: never touch (or close) its handles.
            self._files, self._maps = {}, {}
            self._pid = os.getpid()

    def get(self, path) -> h5py.File:
        self._own()
        key = str(path)
        f = self._files.get(key)
        if f is None or not f.id.valid:
            check_input(key, BankError, "copy or download the bank again")  # a FIFO keeps HDF5 waiting
            try:
                f = h5py.File(key, "r")
            except OSError as e:
                why = str(e).split("(")[-1].rstrip(")") if "(" in str(e) else str(e)
                raise BankError(f"{key}: cannot be read as HDF5 ({why}); the file is damaged or incomplete, "
                                f"copy or download it again") from None
            self._files[key] = f
        return f

    def mapped(self, path, name: str) -> "MappedRows | None":
        """The rows of dataset ``name`` of ``path`` as read-only arrays memory-mapped from
        the file, or None where its bytes are not plain float32 rows (see :func:`map_rows`).

        Reading a mapped RIR costs nothing until it is used, and pages already in the
        page cache are shared by every worker; a bank.read() of the same RIRs through
        HDF5 costs ~70 µs per RIR (a 115 KB chunk) here.
        """
        self._own()
        key = (str(path), name)
        if key not in self._maps:
            self._maps[key] = map_rows(path, self.get(path)[name])
        return self._maps[key]

    def close(self) -> None:
        if self._pid == os.getpid():
            for f in self._files.values():
                try:
                    f.close()
                except Exception:  # already closed
                    pass
        # mapped views may still be in use: dropping them lets the mapping go with the last one
        self._files, self._maps = {}, {}

    def __getstate__(self):
        return {}

    def __setstate__(self, state):
        self._files, self._maps = {}, {}
        self._pid = os.getpid()


class MappedRows:
    """Rows of a float32 dataset as read-only arrays viewing a memory map of its file."""

    def __init__(self, buffer, offsets: np.ndarray, inner: tuple):
        self._buf, self._off, self._inner = buffer, offsets, inner
        self._count = int(np.prod(inner, dtype=np.int64))

    def __len__(self) -> int:
        return len(self._off)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return MappedRows(self._buf, self._off[i], self._inner)
        return np.frombuffer(self._buf, dtype="<f4", count=self._count, offset=int(self._off[i])).reshape(self._inner)


def map_rows(path, ds) -> MappedRows | None:
    """The rows of dataset ``ds`` (in file ``path``) as views into a memory map of the
    file, or None unless each row is stored as plain little-endian float32 bytes:
    contiguous layout, or one unfiltered chunk per row (our own banks). The views are
    checked against an HDF5 read of the first and last rows.
    """
    if ds.dtype.str != "<f4" or ds.shape == () or ds.shape[0] == 0 or ds.id.get_create_plist().get_nfilters():
        return None
    n, inner = ds.shape[0], tuple(ds.shape[1:])
    row = 4 * int(np.prod(inner, dtype=np.int64))
    if ds.chunks is None:
        start = ds.id.get_offset()
        if start is None:  # never written
            return None
        offsets = start + row * np.arange(n, dtype=np.int64)
    elif ds.chunks == (1,) + inner:
        offsets = _chunk_offsets(ds)
        if offsets is None:
            return None
    else:
        return None
    try:
        with open(path, "rb") as fh:
            rows = MappedRows(mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ), offsets, inner)
        ok = np.array_equal(rows[0], ds[0]) and np.array_equal(rows[n - 1], ds[n - 1])
    except (OSError, ValueError):  # a file the map cannot cover
        return None
    return rows if ok else None


def _chunk_offsets(ds) -> np.ndarray | None:
    """File offsets of the chunks of a dataset chunked one row per chunk, in row order."""
    n = ds.shape[0]
    out = np.full(n, -1, dtype=np.int64)

    def visit(info):
        out[info.chunk_offset[0]] = info.byte_offset

    try:
        ds.id.chunk_iter(visit)
    except AttributeError:  # HDF5 < 1.12.3
        for i in range(ds.id.get_num_chunks()):
            visit(ds.id.get_chunk_info(i))
    return None if np.any(out < 0) else out


def read_rows(ds, rows) -> "np.ndarray":
    """``ds[rows]`` for sorted unique ``rows`` along axis 0, one contiguous run at a time.

    h5py's fancy (list) selection builds a point/hyperslab union that is ~15x slower
    than reading the runs directly; walks along a trajectory are strided runs.
    """
    rows = np.asarray(rows, dtype=np.int64)
    out = np.empty((len(rows),) + tuple(ds.shape[1:]), dtype=np.float32 if ds.dtype.kind == "f" else ds.dtype)
    if _one_raw_chunk_per_row(ds):
        # our own banks: one unfiltered float32 chunk per RIR, read as bytes (3x faster
        # than a hyperslab read per run, measured on walks of ~100 knots)
        flat = out.reshape(len(rows), -1).view(np.uint8)
        for i, r in enumerate(rows):
            read_chunk(ds, int(r), flat[i])
        return out
    cuts = np.nonzero(np.diff(rows) != 1)[0] + 1
    start = 0
    for run in np.split(rows, cuts):
        a, n = int(run[0]), len(run)
        if ds.dtype == out.dtype:
            ds.read_direct(out, np.s_[a : a + n], np.s_[start : start + n])
        else:
            out[start : start + n] = ds[a : a + n]
        start += n
    return out


def read_chunk(ds, row: int, out) -> None:
    """Read row ``row``'s raw chunk into the byte buffer ``out`` (datasets with one
    unfiltered chunk per row; no intermediate copy)."""
    ds.id.read_direct_chunk((row,) + (0,) * (ds.ndim - 1), out=out)


def _one_raw_chunk_per_row(ds) -> bool:
    return (ds.chunks == (1,) + tuple(ds.shape[1:]) and ds.dtype.str == "<f4"
            and ds.id.get_create_plist().get_nfilters() == 0)
