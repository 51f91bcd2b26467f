"""Prepared clips: what ``audio.load_clip`` makes of a clip (mono, at the scenes' rate,
the part a scene uses), kept on disk so that no scene decodes and resamples it again.

``tsel corpus prepare`` writes them (and so does the clip check, ``corpus.check =
"full"``, unless ``corpus.prepare_on_check = false``); ``audio.load_clip_cached`` reads
one when it exists. A prepared clip holds exactly the float32 samples ``load_clip``
returns, so scenes are bit for bit the same with or without them; only the time to make
them changes.

Each prepared clip ``NAME.npy`` has a record ``NAME.json`` that ties it to its source:
the source's size, modification time, inode, change time and sha256, and the prepared
file's size, modification time and sha256. A prepared clip is used only when it matches
its record (:func:`lookup`):

- the source's size and mtime are part of the prepared clip's name: a source rewritten
  the usual way is simply not prepared (yet);
- a source whose inode or change time differ from the record (rewritten, then given its
  old mtime back: ``cp -p``, ``rsync -t``, ``touch -r``) is hashed again, and refused
  when its bytes changed;
- the prepared file is hashed whenever it is read (its bytes are read anyway).

sha256, not blake2b: with the SHA extensions of current CPUs it is the faster of the
two (1.6 against 4.5 ms per 2.6 MB here), and the seals use it too.

Where: ``$TSEL_CLIP_CACHE`` when set (a folder of your choice, e.g. on fast local disk,
or one a lab shares), else ``clips/`` in the per-user cache (``~/.cache/tsel-data``,
:mod:`tsel_data.core.usercache`; none at all with ``TSEL_CACHE_DIR=off``). Never in the
corpus unless the user names a folder there: a shared corpus stays as it was, and a
read-only one works the same. Files are named by a hash of the clip's path, size, time
and the scenes' settings, written under a temporary name and renamed, and checked by
sha256 when read: runs and users may share the folder.
"""
from __future__ import annotations

import hashlib
import io
import json
import os

import numpy as np

from ..core.atomic import atomic_output
from ..core.files import is_regular
from ..core.digest import sha256_file
from ..core.usercache import cache_dir, folder_usage

CACHE_ENV = "TSEL_CLIP_CACHE"
RECORD_VERSION = 1
REMAKE = "run `tsel corpus prepare` with the dataset's config to make it again, or delete it"


def stamp_of(st: os.stat_result) -> tuple[int, int, int, int]:
    """What a clip's prepared form is tied to without reading it: (size, mtime_ns, inode,
    ctime_ns). The change time cannot be set back by the user, so a rewrite that restores
    size and mtime still shows."""
    return (st.st_size, st.st_mtime_ns, st.st_ino, st.st_ctime_ns)


def prepared_root() -> str | None:
    """The folder prepared clips live in (None: none are kept, ``TSEL_CACHE_DIR=off``)."""
    named = os.environ.get(CACHE_ENV)
    if named:
        return os.path.abspath(os.path.expanduser(named))
    root = cache_dir()
    return os.path.join(root, "clips") if root else None


def prepared_usage() -> tuple[str | None, int, int]:
    """(folder, prepared clips, bytes) of the prepared-clip folder now."""
    root = prepared_root()
    return (root, *folder_usage(root, ".npy")) if root else (None, 0, 0)


def prepared_path(path: str, stamp: tuple, fs: int, duration: float, offset: float) -> str | None:
    """Where the prepared form of clip ``path`` (as it is: ``stamp`` starts with (size,
    mtime_ns)) for scenes of ``fs`` Hz and ``duration`` s, starting ``offset`` s in, lives
    (None: no prepared clips are kept)."""
    root = prepared_root()
    if root is None:
        return None
    key = f"{os.path.abspath(path)}|{stamp[0]}|{stamp[1]}|{int(fs)}|{float(duration)!r}|{float(offset)!r}"
    digest = hashlib.sha1(key.encode("utf-8")).hexdigest()[:20]
    base = os.path.splitext(os.path.basename(path))[0][:40]  # the clip's name: a user browsing the folder sees what
    return os.path.join(root, digest[:2], f"{base}.{digest}.npy")


def record_path(prepared: str) -> str:
    return os.path.splitext(prepared)[0] + ".json"


def lookup(path: str, stamp: tuple, fs: int, duration: float, offset: float,
           read: bool = True, deep: bool = False) -> tuple[str, np.ndarray | None, str]:
    """(state, samples, why) of a clip's prepared form.

    ``state`` is ``absent`` (none, or one without a readable record: an interrupted
    write or an older toolkit's, never used), ``ok`` or ``changed`` (``why`` says what:
    the clip or the prepared file differs from the record). ``read``: load and hash the
    samples (else a prepared file whose size and mtime match its record is taken as
    recorded); ``deep``: hash the source even when its stamp matches. The samples are
    returned as stored; their plausibility is the caller's (audio.sample_problem).
    """
    p = prepared_path(path, stamp, fs, duration, offset)
    if p is None or not is_regular(p) or not is_regular(record_path(p)):  # a FIFO in the cache is no prepared clip
        return "absent", None, ""
    try:
        with open(record_path(p), encoding="utf-8") as f:
            rec = json.load(f)
        src, mine = rec["source"], rec["prepared"]
        if rec.get("version") != RECORD_VERSION or not isinstance(src, dict) or not isinstance(mine, dict):
            return "absent", None, ""
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return "absent", None, ""
    if [src.get("size"), src.get("mtime_ns")] != list(stamp[:2]):
        return "changed", None, "the clip changed since it was prepared"
    if deep or [src.get("ino"), src.get("ctime_ns")] != list(stamp[2:4]):
        try:
            same = sha256_file(path) == src.get("sha256")
        except OSError:
            same = False
        if not same:
            return "changed", None, "the clip changed since it was prepared (same size and time, other bytes)"
    if not read:
        try:
            st = os.stat(p)
        except OSError:
            return "absent", None, ""
        if st.st_size == mine.get("size") and st.st_mtime_ns == mine.get("mtime_ns"):
            return "ok", None, ""
    try:
        with open(p, "rb") as f:
            data = f.read()
    except OSError:
        return "absent", None, ""
    if hashlib.sha256(data).hexdigest() != mine.get("sha256"):
        return "changed", None, "the prepared file changed since it was written (sha256 differs from its record)"
    try:
        x = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError):
        return "changed", None, "the prepared file is not a NumPy array"
    if not isinstance(x, np.ndarray):  # an .npz archive
        return "changed", None, "the prepared file is not a NumPy array"
    if x.dtype != np.float32 or x.shape != (int(round(duration * fs)),):
        return "changed", None, f"the prepared file holds {x.dtype} {list(x.shape)}, not this scene length"
    return "ok", x, ""


def write_prepared(path: str, stamp: tuple, fs: int, duration: float, offset: float, x: np.ndarray) -> str | None:
    """Keep ``x`` (load_clip's output for the clip as ``stamp`` says it was) as the
    prepared form of the clip, with its record; returns its path, or None when the clip
    changed while it was read (nothing is kept: it would describe neither version)."""
    p = prepared_path(path, stamp, fs, duration, offset)
    if p is None:
        return None
    source = sha256_file(path)
    if stamp_of(os.stat(path)) != tuple(stamp):
        return None
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(x, dtype=np.float32), allow_pickle=False)
    data = buf.getvalue()
    os.makedirs(os.path.dirname(p), exist_ok=True)
    with atomic_output(p) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
    st = os.stat(p)
    rec = {"version": RECORD_VERSION,
           "source": {"size": stamp[0], "mtime_ns": stamp[1], "ino": stamp[2], "ctime_ns": stamp[3],
                      "sha256": source},
           "prepared": {"size": st.st_size, "mtime_ns": st.st_mtime_ns, "sha256": hashlib.sha256(data).hexdigest()},
           "fs": int(fs), "duration": float(duration), "offset": float(offset)}
    # the record last: a prepared file without one is never used
    with atomic_output(record_path(p)) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(rec, f)
    return p
