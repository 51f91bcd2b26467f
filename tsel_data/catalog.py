"""The clip catalog: manifests -> checked clips per split, with the bad-clip policy.

Clips are checked before any scene is planned (``corpus.check``: ``full`` decodes every
clip once to catch NaN and silence, ``header`` reads headers, ``exists`` only looks for
the file, ``none`` trusts the manifest). A bad clip is either skipped and listed in
``OUT/bad_clips.jsonl`` (``on_bad_clip = "skip"``) or stops the run before any
rendering (``"fail"``). Never silently.

:func:`scan_catalog` collects every problem and never raises (``tsel check``);
:func:`build_catalog` is the scan, then the first problem raised (``tsel plan``).
"""
from __future__ import annotations

import json
import os
import unicodedata
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

from .atomic import write_lines
from .audio import ClipCheck, check_clip, prepare_clip
from .clip import Clip
from .config import Config
from .errors import AudioError, ConfigError, ManifestError, TselError
from .manifests import read_manifest

BUILTIN_DEMO = "builtin:demo"
MIN_CLIPS = 2  # a scene holds a target and at least one interferer, from different clips


@dataclass(frozen=True)
class BadClip:
    """A clip the bad-clip policy applies to: where it is listed and what is wrong."""

    split: str
    clip_id: str
    origin: str
    problem: str

    def to_json(self) -> dict:
        return {"split": self.split, "clip_id": self.clip_id, "origin": self.origin, "problem": self.problem}

    def error(self) -> AudioError:
        return AudioError(f"{self.origin}: clip {self.clip_id}: {self.problem}; fix or remove it, or set "
                          f"on_bad_clip = \"skip\"")


@dataclass
class CatalogScan:
    """What reading and checking a corpus found.

    clips: split -> usable clips, manifest order (only splits with at least two).
    bad: every bad clip. problems: every TselError that stops a run (unreadable
    manifests, duplicate ids, bad clips under ``on_bad_clip = "fail"``, too few clips).
    counts: split -> {"clips": read, "bad": bad} for the splits that were read.
    """

    clips: dict[str, list[Clip]] = field(default_factory=dict)
    bad: list[BadClip] = field(default_factory=list)
    problems: list[TselError] = field(default_factory=list)
    counts: dict[str, dict] = field(default_factory=dict)


def resolve_corpus_dir(cfg: Config, demo_dir: str) -> str:
    """The corpus folder: ``corpus.dir``, or for ``builtin:demo`` the demo corpus,
    synthesised into ``demo_dir`` once."""
    d = cfg.corpus.dir
    if d == BUILTIN_DEMO:
        if not os.path.isfile(os.path.join(demo_dir, "test.csv")):
            from .demo import synth_corpus  # its sounds need scipy.signal, ~1-2 s to import: only the demo pays

            synth_corpus(demo_dir, seed=0)
        return demo_dir
    if not d:
        raise ConfigError("no corpus given: pass --corpus-dir DIR (the folder with the manifests and audio) "
                          "or set corpus.dir in the config")
    d = os.path.expanduser(d)
    if not os.path.isdir(d):
        raise ConfigError(f"corpus directory not found: {d}; pass the folder that holds the manifests")
    return d


def read_split_clips(cfg: Config, split: str, corpus_dir: str) -> list[Clip]:
    """Every clip of a split's manifest, unchecked."""
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


def scan_catalog(cfg: Config, corpus_dir: str, workers: int = 1) -> CatalogScan:
    """Read and check every split that makes scenes; collect, never raise.

    Parameters
    ----------
    cfg : Config
        Splits, ``corpus.*`` (format, audio folder and template, check level, limits),
        ``on_bad_clip``.
    corpus_dir : str
        The resolved corpus folder (:func:`resolve_corpus_dir`).
    workers : int
        Processes for the ``full`` clip check.

    Returns
    -------
    CatalogScan
    """
    scan = CatalogScan()
    seen: dict = {}
    for split in cfg.active_splits():
        try:
            clips = read_split_clips(cfg, split, corpus_dir)
        except TselError as e:
            scan.problems.append(e)
            continue
        except OSError as e:
            scan.problems.append(ManifestError(f"splits.{split}.manifest: cannot read it ({e.strerror or e}: "
                                               f"{e.filename}); check the file"))
            continue
        scan.problems += [ManifestError(m) for m in duplicate_clips(clips, split, seen)]
        scan.problems += [ManifestError(m) for m in caption_problems(clips)]
        good = []
        for clip, chk in zip(clips, check_clips(clips, cfg, workers)):
            if chk.problem is None:
                good.append(clip)
                continue
            bad = BadClip(split, clip.id, clip.origin, chk.problem)
            scan.bad.append(bad)
            if cfg.on_bad_clip == "fail":
                scan.problems.append(bad.error())
        scan.counts[split] = {"clips": len(clips), "bad": len(clips) - len(good)}
        if len(good) < MIN_CLIPS:
            scan.problems.append(TselError(f"split {split}: only {len(good)} usable clips in "
                                           f"{cfg.splits[split].manifest}; a scene needs {MIN_CLIPS}; add clips or "
                                           f"fix the bad ones"))
            continue
        scan.clips[split] = good
    return scan


def build_catalog(cfg: Config, corpus_dir: str, workers: int = 1) -> CatalogScan:
    """:func:`scan_catalog`, raising its first problem.

    Parameters
    ----------
    cfg : Config
    corpus_dir : str
        The resolved corpus folder.
    workers : int

    Returns
    -------
    CatalogScan
        With no problems: at least two usable clips in every split that makes scenes.

    Raises
    ------
    TselError
        The first problem (ManifestError, AudioError, ...), saying how many more there are.
    """
    scan = scan_catalog(cfg, corpus_dir, workers)
    if scan.problems:
        first, more = scan.problems[0], len(scan.problems) - 1
        if more:
            raise type(first)(f"{first} (and {more} more problem(s); run `tsel check` to list them)")
        raise first
    return scan


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


def caption_problems(clips: list[Clip]) -> list[str]:
    """One-line problems for captions that cannot be a query: control characters (a NUL
    cannot be stored; a newline breaks the one-line formats) or nothing visible (only
    spaces, zero-width or format characters)."""
    out = []
    for c in clips:
        for k, cap in enumerate(c.captions, 1):
            bad = sorted({f"U+{ord(ch):04X}" for ch in cap if unicodedata.category(ch) == "Cc"})
            if bad:
                out.append(f"{c.origin}: clip {c.id}: caption {k} holds control characters ({', '.join(bad)}); "
                           f"remove them from the manifest")
            elif not any(unicodedata.category(ch)[0] in "LNPS" for ch in cap):
                out.append(f"{c.origin}: clip {c.id}: caption {k} has no visible character; write the caption or "
                           f"delete it")
    return out


def check_clips(clips: list[Clip], cfg: Config, workers: int = 1) -> list[ClipCheck]:
    """The ``corpus.check`` verdict on every clip, in order."""
    level = cfg.corpus.check
    if level == "none":
        return [ClipCheck(c.id, None) for c in clips]
    args = [(c.id, c.audio, level, cfg.corpus.min_duration, cfg.corpus.max_channels, c.offset, cfg.audio.duration,
             cfg.audio.fs) for c in clips]
    if workers > 1 and level == "full" and len(clips) > 64:
        with ProcessPoolExecutor(workers) as ex:
            return list(ex.map(_check, args, chunksize=64))
    return [_check(a) for a in args]


def _check(a) -> ClipCheck:
    return check_clip(*a)


def prepare_corpus(cfg: Config, clips: dict[str, list[Clip]], workers: int = 1, progress=None) -> dict:
    """Prepare every clip the splits use (prepared.py) for scenes of ``cfg``'s rate and
    duration. Returns {"made": n, "kept": n} (kept: already prepared)."""
    jobs = [(c.audio, cfg.audio.fs, cfg.audio.duration, c.offset) for split in clips for c in clips[split]]
    made = 0
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(workers) as ex:
            for done in ex.map(_prepare, jobs, chunksize=16):
                made += done
                if progress:
                    progress()
    else:
        for job in jobs:
            made += _prepare(job)
            if progress:
                progress()
    return {"made": made, "kept": len(jobs) - made}


def _prepare(job) -> bool:
    return prepare_clip(*job)


def write_bad_clips(path: str, bad: list[BadClip]) -> None:
    """``bad_clips.jsonl``: one JSON object per bad clip."""
    write_lines(path, [json.dumps(b.to_json(), ensure_ascii=False) for b in bad])
