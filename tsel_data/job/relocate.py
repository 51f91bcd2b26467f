"""Find a recipe release's clips in the user's copy of the corpus, however it is laid out.

Every download of AudioCaps differs (``Y{id}.wav`` or ``{id}.wav``, one folder or one
per split), so a clip is looked for, in order: at the name the release gives it (its
path in the maker's corpus); through the copy's own manifests, read with the release's
config (the search ``tsel generate`` makes: every file-name template, the split folders
and the shared one, :func:`~tsel_data.plan.catalog.split_audio_dirs`); by its file name
anywhere below the copy (with or without AudioSet's ``Y``, any audio extension). A file
found is the clip only when its size and sha256 are the release's; when no file found
is, the first one found stands (the scene then ``differs``).

A copy laid out otherwise is read through a *view*: a folder in the rebuilt dataset
(``corpus-view/``) that holds, under each release name, a link to the file found. The
recipes, and so the scenes' records, keep the release's names: a rebuild from a flat
copy is bit for bit the release.
"""
from __future__ import annotations

import os
import unicodedata
from dataclasses import dataclass, replace

from ..core.digest import sha256_file
from ..core.files import unicode_match
from ..core.progress import bar
from ..corpus.manifests import AUDIO_EXTENSIONS
from ..errors import TselError
from ..plan.catalog import read_split_clips, split_audio_dirs

VIEW = "corpus-view"  # the folder of links, in the rebuilt dataset


@dataclass(frozen=True)
class Found:
    """Where a release clip is in the copy: ``path`` (absolute; None: nowhere), whether
    its bytes are the release's (``same``) and how it was found (``how``: ``name``,
    ``manifest``, ``file name``)."""

    path: str | None
    same: bool = False
    how: str = ""


def locate_clips(entries: dict, copy: str, cfg, progress=None, skip: str = "") -> dict[str, Found]:
    """{release name: :class:`Found`} for every entry of a release's ``clips.jsonl``
    (``entries``: {name: {"clip_id", "sha256", "bytes", ...}}) in the copy at ``copy``;
    ``cfg``: the release's config with ``copy`` as its corpus (its manifests are read
    when a clip is not at its name); ``skip``: a folder below ``copy`` not to search (the
    dataset being rebuilt)."""
    search = _Search(copy, cfg, entries, skip)
    out = {}
    with bar(len(entries), "find clips", "clip", progress) as b:
        for name, entry in entries.items():
            out[name] = search.find(name, entry)
            b.update()
    return out


class _Search:
    """The three places a clip is looked for, the costly ones read only when needed."""

    def __init__(self, copy: str, cfg, entries: dict, skip: str):
        self.copy, self.cfg, self.entries, self.skip = copy, cfg, entries, os.path.abspath(skip) if skip else ""
        self._by_id: dict[str, str] | None = None
        self._by_stem: dict[str, list[str]] | None = None

    def find(self, name: str, entry: dict) -> Found:
        first = None
        for how, path in self._candidates(name, entry):
            if not os.path.isfile(path):
                continue
            if _same(path, entry):
                return Found(path, True, how)
            first = first or Found(path, False, how)
        return first or Found(None)

    def _candidates(self, name: str, entry: dict):
        yield "name", unicode_match(os.path.join(self.copy, name)) or os.path.join(self.copy, name)
        if self.cfg.recorded.on:  # a recording's folders are the dataset's own layout, not a download tool's
            return
        by_id = self.by_id()
        if entry.get("clip_id") in by_id:
            yield "manifest", by_id[entry["clip_id"]]
        for stem in _stems(name):
            for path in self.by_stem().get(stem, ()):
                yield "file name", path

    def by_id(self) -> dict[str, str]:
        """{clip id: audio file} as the copy's manifests say (the splits' manifests the
        release's config names; one that cannot be read is passed over)."""
        if self._by_id is None:
            self._by_id = {}
            for split in self.cfg.active_splits():
                for cfg in (self.cfg, _searching(self.cfg)):  # the folders the maker named; else every layout
                    try:
                        clips = read_split_clips(cfg, split, self.copy, split_audio_dirs(cfg, split, self.copy))
                    except (TselError, OSError):
                        continue
                    self._by_id.update((c.id, c.audio) for c in clips if c.id not in self._by_id
                                       and os.path.isfile(c.audio))
        return self._by_id

    def by_stem(self) -> dict[str, list[str]]:
        """{file name without extension (and without a leading ``Y``): audio files} below
        the copy, hidden folders and the dataset being rebuilt left out; only the names
        of the release's clips are kept."""
        if self._by_stem is None:
            wanted = {s for name in self.entries for s in _stems(name)}
            self._by_stem = {}
            for folder, dirs, names in os.walk(self.copy):
                dirs[:] = sorted(d for d in dirs if not d.startswith(".")
                                 and os.path.abspath(os.path.join(folder, d)) != self.skip)
                for n in sorted(names):
                    stem, ext = os.path.splitext(unicodedata.normalize("NFC", n))  # a copy from macOS: NFD
                    if ext.lower() not in AUDIO_EXTENSIONS:
                        continue
                    for s in dict.fromkeys((stem, stem[1:] if stem.startswith("Y") else stem)):
                        if s in wanted:
                            self._by_stem.setdefault(s, []).append(os.path.join(folder, n))
        return self._by_stem


def _searching(cfg):
    """``cfg`` without the audio folders its maker named: the copy's are looked for."""
    return replace(cfg, corpus=replace(cfg.corpus, audio_dir=""),
                   splits={k: replace(v, audio_dir="") for k, v in cfg.splits.items()})


def _stems(name: str) -> tuple[str, ...]:
    """The file names (no extension) a clip called ``name`` may have in another download."""
    stem = unicodedata.normalize("NFC", os.path.splitext(os.path.basename(name))[0])
    return tuple(dict.fromkeys((stem, stem[1:] if stem.startswith("Y") else stem)))


def _same(path: str, entry: dict) -> bool:
    try:
        return os.path.getsize(path) == entry.get("bytes") and sha256_file(path) == entry.get("sha256")
    except OSError:
        return False


def write_view(root: str, found: dict[str, Found]) -> None:
    """Links ``root/NAME`` -> the file found for each clip found (a link already there
    and right is kept: a resumed rebuild)."""
    for name, f in found.items():
        if f.path is None:
            continue
        link = os.path.join(root, name)
        target = os.path.abspath(f.path)
        if os.path.islink(link):
            if os.readlink(link) == target:
                continue
            os.remove(link)
        os.makedirs(os.path.dirname(link), exist_ok=True)
        os.symlink(target, link)
