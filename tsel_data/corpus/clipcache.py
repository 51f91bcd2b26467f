"""Remembered clip checks: an unchanged corpus is checked once, not on every run.

Decoding every clip (``corpus.check = "full"``) takes minutes for a full AudioCaps
download. A verdict is a pure function of the file's bytes and the check's settings, so
it is kept in a small SQLite file keyed by the file's ``(path, size, mtime)`` and the
settings (level, minimum duration, channels, offset, scene duration). A file that is
rewritten gets a new size or mtime and is checked again.

Where: ``clip-checks.sqlite`` in the per-user cache (:mod:`tsel_data.core.usercache`).
The cache only ever saves time: an unwritable or damaged cache file is ignored and
every clip is checked.
"""
from __future__ import annotations

import os
import sqlite3

from ..core.usercache import cache_dir
from .audio import ClipCheck

# Bump when check_clip's verdicts change meaning, so old verdicts are not reused.
CHECK_VERSION = 2  # 2: samples above audio.MAX_PEAK are a bad clip
_SCHEMA = ("CREATE TABLE IF NOT EXISTS checks (path TEXT, size INTEGER, mtime_ns INTEGER, settings TEXT, "
           "problem TEXT, duration REAL, samplerate INTEGER, channels INTEGER, "
           "PRIMARY KEY (path, size, mtime_ns, settings))")


def settings_key(level: str, min_duration: float, max_channels: int, offset: float, duration: float | None,
                 fs: int | None = None) -> str:
    """The check's settings as one text key (a verdict holds only for the same settings;
    ``fs``, the scenes' rate, decides whether a clip has content in their band)."""
    return f"v{CHECK_VERSION}|{level}|{min_duration!r}|{max_channels}|{offset!r}|{duration!r}|{fs!r}"


class ClipCache:
    """Verdicts by (path, size, mtime_ns, settings). ``get`` and ``put`` never raise: a
    cache that cannot be opened or written behaves as an empty one."""

    def __init__(self, folder: str | None = None):
        self._db = None
        folder = cache_dir() if folder is None else folder
        if not folder:
            return
        try:
            os.makedirs(folder, exist_ok=True)
            self._db = sqlite3.connect(os.path.join(folder, "clip-checks.sqlite"), timeout=30)
            self._db.execute(_SCHEMA)
        except (OSError, sqlite3.Error):
            self._close()

    def _close(self) -> None:
        if self._db is not None:
            try:
                self._db.close()
            except sqlite3.Error:
                pass
        self._db = None

    def get(self, keys: list[tuple]) -> dict[tuple, tuple]:
        """{key: (problem, duration, samplerate, channels)} for the keys ``(path, size,
        mtime_ns, settings)`` the cache holds."""
        if self._db is None or not keys:
            return {}
        out = {}
        try:
            for path, size, mtime, settings in keys:
                row = self._db.execute("SELECT problem, duration, samplerate, channels FROM checks WHERE path = ? "
                                       "AND size = ? AND mtime_ns = ? AND settings = ?",
                                       (path, size, mtime, settings)).fetchone()
                if row is not None:
                    out[(path, size, mtime, settings)] = row
        except sqlite3.Error:
            self._close()
            return {}
        return out

    def put(self, items: list[tuple[tuple, ClipCheck]]) -> None:
        """Remember verdicts (one transaction)."""
        if self._db is None or not items:
            return
        rows = [(*key, c.problem, c.duration, c.samplerate, c.channels) for key, c in items]
        try:
            with self._db:
                self._db.executemany("INSERT OR REPLACE INTO checks VALUES (?, ?, ?, ?, ?, ?, ?, ?)", rows)
        except sqlite3.Error:
            self._close()

    def close(self) -> None:
        self._close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def file_key(path: str, settings: str) -> tuple | None:
    """The cache key of a file, or None when it does not exist (a missing file is not
    cached: it is found missing again at the cost of one ``stat``)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):  # ValueError: a NUL byte in the name (a clip id from a manifest): no such file
        return None
    return (os.path.abspath(path), st.st_size, st.st_mtime_ns, settings)
