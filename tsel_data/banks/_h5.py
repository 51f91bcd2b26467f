"""Lazily opened, fork-safe, read-only HDF5 handles.

Banks are shared by render workers (fork, dask, pickling). An HDF5 handle must not
cross a fork, so handles are opened on first use in each process and dropped when the
bank is pickled.
"""
from __future__ import annotations

import os

import h5py


class H5Pool:
    def __init__(self):
        self._files: dict[str, h5py.File] = {}
        self._pid = os.getpid()

    def get(self, path) -> h5py.File:
        if self._pid != os.getpid():
            # Inherited from the parent: never touch (or close) its handles.
            self._files = {}
            self._pid = os.getpid()
        key = str(path)
        f = self._files.get(key)
        if f is None or not f.id.valid:
            f = h5py.File(key, "r")
            self._files[key] = f
        return f

    def close(self) -> None:
        if self._pid == os.getpid():
            for f in self._files.values():
                try:
                    f.close()
                except Exception:  # already closed
                    pass
        self._files = {}

    def __getstate__(self):
        return {}

    def __setstate__(self, state):
        self._files = {}
        self._pid = os.getpid()
