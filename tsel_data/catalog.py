"""The clip catalog: manifests -> checked clips per split, with the bad-clip policy.

Clips are checked before any scene is planned (``corpus.check``: ``full`` decodes every
clip once to catch NaN and silence, ``header`` reads headers, ``exists`` only looks for
the file, ``none`` trusts the manifest). A bad clip is either skipped and listed in
``OUT/bad_clips.jsonl`` (``on_bad_clip = "skip"``) or stops the run before any
rendering (``"fail"``). Never silently.
"""
from __future__ import annotations

import json
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

from .audio import ClipCheck, check_clip
from .clip import Clip
from .config import Config
from .errors import AudioError, ConfigError, ManifestError, TselError

BUILTIN_DEMO = "builtin:demo"


@dataclass
class Catalog:
    clips: dict[str, list[Clip]]  # split -> good clips, manifest order
    bad: list[dict] = field(default_factory=list)  # {"split", "clip_id", "origin", "problem"}

    def summary(self) -> str:
        parts = [f"{s}: {len(c)} clips" for s, c in self.clips.items()]
        return ", ".join(parts) + (f"; {len(self.bad)} bad clips skipped (bad_clips.jsonl)" if self.bad else "")


def resolve_corpus_dir(cfg: Config, out_dir: str) -> str:
    d = cfg.corpus.dir
    if d == BUILTIN_DEMO:
        from .demo import synth_corpus

        d = os.path.join(out_dir, "demo-corpus")
        if not os.path.isfile(os.path.join(d, "test.csv")):
            synth_corpus(d, seed=0)
        return d
    if not d:
        raise ConfigError("no corpus given: pass --corpus-dir DIR (the folder with the manifests and audio) "
                          "or set corpus.dir in the config")
    d = os.path.expanduser(d)
    if not os.path.isdir(d):
        raise ConfigError(f"corpus directory not found: {d}; pass the folder that holds the manifests")
    return d


def read_split_clips(cfg: Config, split: str, corpus_dir: str) -> list[Clip]:
    from .manifests import read_manifest

    sp = cfg.splits[split]
    if not sp.manifest:
        raise ConfigError(f"splits.{split}.manifest is not set; name the manifest file for this split")
    path = sp.manifest if os.path.isabs(sp.manifest) else os.path.join(corpus_dir, sp.manifest)
    audio_dir = cfg.corpus.audio_dir or (os.path.join(corpus_dir, "audio") if os.path.isdir(
        os.path.join(corpus_dir, "audio")) else corpus_dir)
    if cfg.corpus.audio_dir and not os.path.isabs(audio_dir):
        audio_dir = os.path.join(corpus_dir, audio_dir)
    opts = {"split": split}
    if cfg.corpus.audio_template:
        opts["template"] = cfg.corpus.audio_template
    return read_manifest(path, format=cfg.corpus.format, audio_dir=audio_dir, **opts)


def build_catalog(cfg: Config, out_dir: str, workers: int = 1) -> Catalog:
    corpus_dir = resolve_corpus_dir(cfg, out_dir)
    clips: dict[str, list[Clip]] = {}
    bad: list[dict] = []
    seen: dict = {}
    for split, sp in cfg.splits.items():
        if sp.count == 0:
            continue
        all_clips = read_split_clips(cfg, split, corpus_dir)
        dup = duplicate_clips(all_clips, split, seen)
        if dup:
            raise ManifestError(dup[0] + (f" (and {len(dup) - 1} more)" if len(dup) > 1 else ""))
        checks = check_clips(all_clips, cfg, workers)
        good = []
        for clip, chk in zip(all_clips, checks):
            if chk.problem is None:
                good.append(clip)
            else:
                bad.append({"split": split, "clip_id": clip.id, "origin": clip.origin, "problem": chk.problem})
        if bad and cfg.on_bad_clip == "fail":
            b = bad[0]
            more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
            raise AudioError(f"{b['origin']}: clip {b['clip_id']}: {b['problem']}{more}; fix or remove it, "
                             f"or set on_bad_clip = \"skip\"")
        if len(good) < 2:
            raise TselError(f"split {split}: only {len(good)} usable clips in {sp.manifest}; a scene needs two")
        clips[split] = good
    return Catalog(clips, bad)


def duplicate_clips(clips: list[Clip], split: str, seen: dict) -> list[str]:
    """One-line problems for clip ids that repeat within ``clips`` or occur in an earlier
    split (a clip in two splits leaks into evaluation). ``seen`` ({id: (split, origin)})
    carries ids across splits; it is updated."""
    out = []
    for c in clips:
        prev = seen.get(c.id)
        if prev is None:
            seen[c.id] = (split, c.origin)
            continue
        where = prev[1] if prev[0] == split else f"{prev[1]}, split {prev[0]}"
        out.append(f"{c.origin}: duplicate clip id {c.id!r} (also at {where}); a clip may appear once and in one "
                   f"split: remove the duplicate")
    return out


def check_clips(clips: list[Clip], cfg: Config, workers: int = 1) -> list[ClipCheck]:
    level = cfg.corpus.check
    if level == "none":
        return [ClipCheck(c.id, None) for c in clips]
    args = [(c.id, c.audio, level, cfg.corpus.min_duration, cfg.corpus.max_channels, c.offset, cfg.audio.duration)
            for c in clips]
    if workers > 1 and level == "full" and len(clips) > 64:
        with ProcessPoolExecutor(workers) as ex:
            return list(ex.map(_check, args, chunksize=64))
    return [_check(a) for a in args]


def _check(a) -> ClipCheck:
    return check_clip(*a)


def write_bad_clips(path: str, bad: list[dict]) -> None:
    from .store.writer import atomic_write

    atomic_write(path, "".join(json.dumps(b, ensure_ascii=False) + "\n" for b in bad).encode("utf-8"))

