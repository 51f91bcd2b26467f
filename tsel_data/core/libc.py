"""The C library, loaded once per process, for the few calls Python's ``os`` lacks
(``mallopt``, ``sync_file_range``, ``prctl``); None where it cannot be loaded."""
from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.cache
def libc() -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    except OSError:
        return None
