"""Knowing that a shard on disk is the one the plan asks for, and whole.

Every shard is sealed by ``{split}/shard-NNNNN.seal.json``, written after its two files:

- ``fingerprint``: what the shard was made from: its recipes as planned, and the size and
  modification time (``corpus.fingerprint = "hash"``: the size and sha256) of every clip
  and bank file they read (:func:`shard_fingerprint`);
- ``h5`` and ``json``: size, modification time (ns) and sha256 of each file;
- ``renderer``: the renderer that wrote it (core/version.py; a seal without one: 1).

A shard is *complete* when its seal exists, holds the fingerprint the plan asks for now,
its files still match the seal, and this renderer wrote it. So a shard of another plan, of clips that changed
since, or with a flipped bit is re-rendered by ``--resume`` and refused by ``finalize``,
never adopted. The writer hashes each file once as it seals it; ``--resume`` and
``finalize`` then take a file whose size and modification time are the seal's as
sealed and hash only files that changed; ``tsel check DIR`` hashes every file.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass

from ..core.digest import sha256_file
from ..core.files import is_regular
from ..core.version import RENDERER
from .layout import Layout

SEAL_VERSION = 1


def input_stats(inputs, content: bool = False, hashes: dict | None = None) -> list:
    """[(name, size, mtime_ns)] of every file read from ``inputs`` ((name, path) pairs:
    the name a plan gives a file, and where it is here; a folder: every file in it,
    recursively, named below its name), sorted; a missing file is listed with size -1.
    Names, not paths: a dataset and its corpus may move without their shards going stale.

    ``content`` (``corpus.fingerprint = "hash"``): [(name, size, sha256)] instead, the
    bytes read again, so a file rewritten with its old size and mtime is seen, and one
    only touched or copied is not taken for changed. ``hashes``: {path: sha256} shared by
    the calls of one resume check, so a file read by many shards is read once per check
    (never across checks: rereading is what ``hash`` is for)."""
    stat = _hashed if content else _stat
    memo = {} if hashes is None else hashes
    out = set()
    for name, p in set(inputs):
        if os.path.isdir(p):
            for root, _, files in os.walk(p):
                for f in files:
                    full = os.path.join(root, f)
                    out.add(stat(name + "/" + os.path.relpath(full, p).replace(os.sep, "/"), full, memo))
        else:
            out.add(stat(name, p, memo))
    return sorted(out)


def _stat(name: str, path: str, memo=None) -> tuple:
    try:
        st = os.stat(path)
    except OSError:
        return (name, -1, 0)
    return (name, st.st_size, st.st_mtime_ns)


def _hashed(name: str, path: str, memo: dict) -> tuple:
    if path not in memo:
        try:
            memo[path] = (os.path.getsize(path), sha256_file(path))
        except OSError:
            memo[path] = (-1, "")
    size, digest = memo[path]
    return (name, size, digest) if size >= 0 else (name, -1, 0)


def missing_inputs(stats) -> list[str]:
    """The names of the files :func:`input_stats` did not find."""
    return [name for name, size, _ in stats if size < 0]


def shard_fingerprint(recipe_lines, stats) -> str:
    """sha256 of a shard's recipes (their JSON lines, in order) and of the files they read
    as they are now (``stats``: :func:`input_stats`)."""
    doc = {"seal": SEAL_VERSION, "recipes": list(recipe_lines), "inputs": stats}
    return hashlib.sha256(json.dumps(doc, separators=(",", ":")).encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class FileSeal:
    """What a file was when its shard was sealed."""

    sha256: str
    size: int
    mtime_ns: int

    @classmethod
    def of(cls, path: str, sha256: str | None = None) -> "FileSeal":
        st = os.stat(path)
        return cls(sha256 or sha256_file(path), st.st_size, st.st_mtime_ns)

    def unchanged(self, path: str) -> bool:
        """Same size and modification time (no hashing)."""
        try:
            st = os.stat(path)
        except OSError:
            return False
        return st.st_size == self.size and st.st_mtime_ns == self.mtime_ns


@dataclass(frozen=True)
class Seal:
    fingerprint: str
    h5: FileSeal
    json: FileSeal
    renderer: int = RENDERER

    def to_json(self) -> dict:
        return {"seal_version": SEAL_VERSION, "fingerprint": self.fingerprint,
                "h5": vars(self.h5), "json": vars(self.json), "renderer": self.renderer}

    @classmethod
    def from_json(cls, d: dict) -> "Seal":
        renderer = d.get("renderer", 1)
        if not isinstance(renderer, int) or isinstance(renderer, bool):
            raise TypeError("renderer")
        return cls(str(d["fingerprint"]), FileSeal(**d["h5"]), FileSeal(**d["json"]), renderer)


def read_seal(layout: Layout, split: str, shard: int) -> Seal | None:
    """A shard's seal, or None when it is missing or unreadable (or no file: a FIFO)."""
    if not is_regular(layout.seal_file(split, shard)):
        return None
    try:
        with open(layout.seal_file(split, shard), encoding="utf-8") as f:
            return Seal.from_json(json.load(f))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def shard_state(layout: Layout, split: str, shard: int, fingerprint: str, deep: bool = False) -> tuple[str, str]:
    """(state, why) of a shard: ``complete``, ``missing`` (not rendered), ``stale`` (made
    from another plan or from clips that changed since) or ``damaged`` (its files differ
    from its seal). ``deep`` hashes both files; otherwise a file whose size and mtime are
    those of the seal is taken as sealed, and only a changed one is hashed."""
    h5, js = layout.shard_files(split, shard)
    have = [os.path.isfile(p) for p in (h5, js)]
    seal = read_seal(layout, split, shard)
    if seal is None:
        return ("missing", "not rendered") if not any(have) else ("damaged", "no seal (an interrupted write)")
    if seal.fingerprint != fingerprint:
        return "stale", "made from another plan, or from clips or a bank that changed since"
    if seal.renderer != RENDERER:  # a dataset is one renderer's: dataset.json names one
        return "stale", f"rendered by renderer {seal.renderer} (another tsel-data); this one renders with {RENDERER}"
    if not all(have):  # a file of a sealed shard was deleted: render it (again)
        return "missing", "a file is missing"
    for path, fs in ((h5, seal.h5), (js, seal.json)):
        if (deep or not fs.unchanged(path)) and sha256_file(path) != fs.sha256:
            return "damaged", f"{os.path.basename(path)} changed since it was written (sha256 differs from its seal)"
    return "complete", ""
