"""Text from HDF5: strings, attributes and string datasets come back as ``bytes``,
``str``, numpy scalars or one-element arrays depending on how they were written (h5py,
MATLAB, SOFA tools). One decoder for the bank readers and the shard tools."""
from __future__ import annotations

import numpy as np


def as_str(v, default: str = "") -> str:
    """One text value as ``str`` (UTF-8; bad bytes replaced); ``default`` for None or an
    empty array; the first element of an array."""
    if v is None:
        return default
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray):
        return as_str(v.reshape(-1)[0], default) if v.size else default
    if isinstance(v, np.generic):
        return as_str(v.item(), default)
    return str(v)


def as_strs(values) -> list[str]:
    """Every element of a string dataset or list as ``str``."""
    return [as_str(v) for v in np.asarray(values, dtype=object).reshape(-1)]
