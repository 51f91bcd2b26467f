"""Prepared clips: what ``audio.load_clip`` makes of a clip (mono, at the scenes' rate,
the part a scene uses), kept on disk so that no scene decodes and resamples it again.

``tsel corpus prepare`` writes them; ``audio.load_clip_cached`` reads one when it exists
and its source has not changed since (size and modification time are part of its name).
A prepared clip holds exactly the float32 samples ``load_clip`` returns, so scenes are
bit for bit the same with or without them; only the time to make them changes.

Where: ``$TSEL_CLIP_CACHE`` when set (a folder of your choice, e.g. on fast local disk),
else ``.tsel-clips/`` beside each audio file.
"""
from __future__ import annotations

import hashlib
import os

import numpy as np

from .atomic import atomic_output

CACHE_ENV = "TSEL_CLIP_CACHE"
FOLDER = ".tsel-clips"


def prepared_path(path: str, stamp: tuple[int, int], fs: int, duration: float, offset: float) -> str:
    """Where the prepared form of clip ``path`` (as it is: ``stamp`` = (size, mtime_ns))
    for scenes of ``fs`` Hz and ``duration`` s, starting ``offset`` s in, lives."""
    key = f"{os.path.abspath(path)}|{stamp[0]}|{stamp[1]}|{int(fs)}|{float(duration)!r}|{float(offset)!r}"
    digest = hashlib.sha1(key.encode("utf-8")).hexdigest()[:20]
    root = os.environ.get(CACHE_ENV)
    if root:
        return os.path.join(root, digest[:2], f"{digest}.npy")
    base = os.path.splitext(os.path.basename(path))[0]
    return os.path.join(os.path.dirname(path), FOLDER, f"{base}.{digest}.npy")


def read_prepared(path: str, stamp, fs: int, duration: float, offset: float) -> np.ndarray | None:
    """The prepared samples, or None when there are none (or they cannot be read)."""
    p = prepared_path(path, stamp, fs, duration, offset)
    try:
        x = np.load(p, allow_pickle=False)
    except (OSError, ValueError):
        return None
    n = int(round(duration * fs))
    return x if x.dtype == np.float32 and x.shape == (n,) else None


def write_prepared(path: str, stamp, fs: int, duration: float, offset: float, x: np.ndarray) -> str:
    """Keep ``x`` (load_clip's output) as the prepared form of the clip; returns its path."""
    p = prepared_path(path, stamp, fs, duration, offset)
    os.makedirs(os.path.dirname(p), exist_ok=True)
    with atomic_output(p) as tmp:
        with open(tmp, "wb") as f:
            np.save(f, np.ascontiguousarray(x, dtype=np.float32), allow_pickle=False)
    return p
