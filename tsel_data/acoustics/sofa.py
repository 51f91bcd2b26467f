"""SOFA (AES69) coordinates, read one way for every SOFA file we take: HRTF sets
(:mod:`tsel_data.acoustics.hrtf`) and measured-RIR rooms (:mod:`tsel_data.banks.sofa`).

A position variable is ``[M or 1, 3]`` with a ``Type`` (``cartesian`` | ``spherical``)
and ``Units`` (spherical: azimuth and elevation in degrees unless the first unit says
radians, radius in metres). SOFA's frame is ours: x front, y left, z up, azimuth
counter-clockwise. ``ListenerView`` / ``ListenerUp`` give the listener's (the array's, the
head's) +x and +z axes. Errors name the file and the variable, in the caller's error class.

The one module outside ``store/``, ``banks/`` and ``formats/`` that imports h5py: SOFA files
are HDF5, and HRTFs are read at render time by the capsule models below the banks.
"""
from __future__ import annotations

import h5py
import numpy as np

from ..core.files import check_input
from ..core.geometry import sph_to_cart
from ..core.h5str import as_str


def open_sofa(path, error: type[Exception], why: str):
    """The SOFA file at ``path`` open for reading (an h5py File, to use as a context
    manager); one ``error`` line "PATH: not a SOFA file (WHY" when it is not HDF5, and
    "PATH is not a regular file: it is a FIFO (a named pipe)" when it is no file to read (core/files.py)."""
    check_input(path, error, "give the SOFA file itself")
    try:
        return h5py.File(path, "r")
    except OSError:
        raise error(f"{path}: not a SOFA file ({why}") from None


def position(f, name: str, M: int, path, error: type[Exception], direction: bool = False) -> np.ndarray | None:
    """The SOFA position variable ``name`` of the open file ``f`` as cartesian [M, 3] (a
    single row broadcast), or None when the file has none. ``direction=True`` ignores a
    spherical radius (unit vectors)."""
    if name not in f:
        return None
    ds = f[name]
    v = np.asarray(ds[()], dtype=np.float64)
    v = v.reshape(1, -1) if v.ndim < 2 else v.reshape(-1, v.shape[-1])
    if v.shape[-1] != 3 and v.shape[0] == 3:
        v = v.T
    if v.shape[0] not in (1, M) or v.shape[1] != 3:
        raise error(f"{path}: {name} has shape {ds.shape}; expected [M or 1, 3]")
    bad = np.nonzero(~np.all(np.isfinite(v), axis=1))[0]
    if len(bad):
        raise error(f"{path}: {name} has NaN or infinite values (rows {rows_text(bad)}); "
                    f"every measurement needs a position")
    kind = as_str(ds.attrs.get("Type")).lower() or "cartesian"
    if kind.startswith("spherical"):
        rad = "rad" in as_str(ds.attrs.get("Units")).lower().split(",")[0]
        ang = np.degrees(v[:, :2]) if rad else v[:, :2]
        v = sph_to_cart(ang[:, 0], ang[:, 1], 1.0 if direction else v[:, 2])
    elif not kind.startswith("cartesian"):
        raise error(f"{path}: {name} has coordinate Type {kind!r}; expected cartesian or spherical")
    return np.broadcast_to(v, (M, 3)).astype(np.float64)


def listener_frames(view: np.ndarray, up: np.ndarray, path, error: type[Exception]) -> np.ndarray:
    """Rotation matrices [M, 3, 3] whose columns are the listener's x, y, z axes, from
    ``ListenerView`` and ``ListenerUp`` (up made orthogonal to view)."""
    x = view / np.linalg.norm(view, axis=1, keepdims=True)
    z = up - np.sum(up * x, axis=1, keepdims=True) * x
    nz = np.linalg.norm(z, axis=1, keepdims=True)
    if np.any(nz < 1e-9) or not np.all(np.isfinite(x)):
        raise error(f"{path}: ListenerView is zero or parallel to ListenerUp; fix the listener orientation")
    z = z / nz
    return np.stack([x, np.cross(z, x), z], axis=-1)


def in_listener_frame(f, rel: np.ndarray, M: int, path, error: type[Exception]) -> np.ndarray:
    """Vectors [M, 3] given in the room turned into the listener's frame when the file
    orients its listener (``ListenerView``; ``ListenerUp`` defaults to +z), else as they are."""
    view = position(f, "ListenerView", M, path, error, direction=True)
    if view is None:
        return rel
    up = position(f, "ListenerUp", M, path, error, direction=True)
    up = np.tile([0.0, 0.0, 1.0], (M, 1)) if up is None else up
    return np.einsum("mij,mi->mj", listener_frames(view, up, path, error), rel)


def rows_text(idx) -> str:
    """Row numbers for a message: the first five, and how many in all."""
    idx = list(map(int, idx))
    return ", ".join(map(str, idx[:5])) + (f", ... ({len(idx)} rows)" if len(idx) > 5 else "")
