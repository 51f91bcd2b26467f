"""The per-user cache folder: remembered clip checks and prepared clips live here, never
in the user's corpus.

``$TSEL_CACHE_DIR`` (``off``: no cache at all), else ``$XDG_CACHE_HOME/tsel-data``, else
``~/.cache/tsel-data``. Everything in it only ever saves time: it may be deleted at any
moment, and a run that cannot write it does the work again instead.
"""
from __future__ import annotations

import os

ENV = "TSEL_CACHE_DIR"


def cache_dir() -> str | None:
    """The cache folder, or None when ``TSEL_CACHE_DIR=off``."""
    env = os.environ.get(ENV)
    if env:
        return None if env.lower() == "off" else os.path.expanduser(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "tsel-data")


def folder_usage(folder: str, suffix: str = "") -> tuple[int, int]:
    """(files, bytes) below ``folder`` whose names end with ``suffix`` (0, 0 when it does
    not exist): what a cache holds, for the user to see what it costs."""
    files = size = 0
    stack = [folder]
    while stack:
        try:
            with os.scandir(stack.pop()) as it:
                for e in it:
                    if e.is_dir(follow_symlinks=False):
                        stack.append(e.path)
                    elif e.name.endswith(suffix):
                        try:
                            size += e.stat(follow_symlinks=False).st_size
                        except OSError:  # removed while we looked (another run cleaning up)
                            continue
                        files += 1
        except OSError:
            continue
    return files, size
