"""The clip catalog: manifests -> checked clips per split, with the bad-clip policy.

Clips are checked before any scene is planned (``corpus.check``: ``full`` decodes every
clip once to catch NaN and silence, ``header`` reads headers, ``exists`` only looks for
the file, ``none`` trusts the manifest; verdicts are remembered per file, see
:mod:`tsel_data.corpus.clipcache`). A bad clip is either skipped and listed in
``OUT/bad_clips.jsonl`` (``on_bad_clip = "skip"``) or stops the run before any
rendering (``"fail"``). Never silently. A clip whose audio file does not exist is not a
bad clip but a partial download, which is normal (YouTube clips vanish): under
``"skip"`` it is counted per split ("N of M clips present") and its id listed in
``OUT/missing_clips.json``.

:func:`scan_catalog` collects every problem and never raises (``tsel check``);
:func:`build_catalog` is the scan, then the first problem raised (``tsel plan``).
"""
from __future__ import annotations

import json
import os
import unicodedata
from collections import Counter
from dataclasses import dataclass, field, replace

from ..config import Config
from ..core.atomic import write_json, write_lines
from ..core.files import check_input
from ..core.progress import bar
from ..corpus.audio import ClipCheck, check_clip, keep_prepared, prepare_clip, prepared_state, wants_preparing
from ..corpus.clip import Clip
from ..corpus.clipcache import ClipCache, file_key, settings_key
from ..corpus.manifests import AUDIO_EXTENSIONS, detect_format, read_manifest, split_aliases
from ..corpus.prepared import prepared_usage
from ..errors import AudioError, ConfigError, ManifestError, TselError, broken_link, shown_path
from ..runtime.pool import ordered_pool
from ..runtime.runner import Runner
from ..scene.recipe import BUILTIN_DEMO

MIN_CLIPS = 2  # a scene holds a target and at least one interferer, from different clips
# Above this many scenes per usable clip (as target or interferer), a split mostly repeats
# its clips (the paper's AudioCaps val split, 903 scenes of 495 clips, is at 3.6).
REUSE_WARN = 5.0
MANIFEST_EXTENSIONS = (".csv", ".json", ".jsonl", ".ndjson")


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
    bad: every bad clip (present but unusable; missing files are not bad clips under
    ``on_bad_clip = "skip"``). missing: split -> clips whose audio file does not exist
    (a partial download). problems: every TselError that stops a run (unreadable
    manifests, duplicate ids, bad clips under ``on_bad_clip = "fail"``, too few clips).
    warnings: one-line notes that do not stop a run (clips reused by many scenes).
    counts: split -> {"clips": listed, "missing": files absent, "bad": bad clips} for
    the splits that were read. audio_dirs: split -> the folders its audio is looked for in.
    rates: split -> {rate: usable clips} below the scenes' rate. left_out: split -> clips
    below ``corpus.min_samplerate``. hints: split -> where its missing audio files seem
    to be, and the setting.
    """

    clips: dict[str, list[Clip]] = field(default_factory=dict)
    bad: list[BadClip] = field(default_factory=list)
    missing: dict[str, list[Clip]] = field(default_factory=dict)
    problems: list[TselError] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    counts: dict[str, dict] = field(default_factory=dict)
    audio_dirs: dict[str, str] = field(default_factory=dict)
    rates: dict[str, dict[int, int]] = field(default_factory=dict)
    left_out: dict[str, int] = field(default_factory=dict)
    hints: dict[str, str] = field(default_factory=dict)

    def presence_lines(self) -> list[str]:
        """Per split read, ``train: 45,321 of 49,838 clips present (90.9 %)``: what a
        partial download holds, in one line instead of a warning per absent file."""
        out = []
        for split, c in self.counts.items():
            listed, missing = c["clips"], c.get("missing", 0)
            share = 100.0 * (listed - missing) / listed if listed else 0.0
            line = f"{split}: {listed - missing:,} of {listed:,} clips present ({share:.1f} %)"
            if c.get("bad"):
                line += f", {c['bad']:,} of them bad"
            if self.left_out.get(split):
                line += f", {self.left_out[split]:,} left out (recorded below corpus.min_samplerate)"
            if c.get("prepared"):
                line += f", {c['prepared']:,} kept prepared"
            if split in self.hints:
                line += f"; {self.hints[split]}"
            out.append(line)
        if any(c.get("prepared") for c in self.counts.values()):
            out.append(prepared_line())
        return out


def prepared_line(how_not: bool = True) -> str:
    """Where prepared clips are kept and what they cost: files written for the user,
    outside the corpus (``how_not``: said with the way not to)."""
    root, n, size = prepared_usage()
    return (f"prepared clips (decoded at the scenes' rate and channels once, not per scene): {n:,} in "
            f"{shown_path(root)}, {size / 1e6:,.1f} MB"
            + (" (set corpus.prepare_on_check = false to keep none)" if how_not else ""))


def resolve_corpus_dir(cfg: Config, demo_dir: str) -> str:
    """The corpus folder: ``corpus.dir``, or for ``builtin:demo`` the demo corpus,
    synthesised into ``demo_dir`` once."""
    d = cfg.corpus.dir
    if d == BUILTIN_DEMO:
        if not os.path.isfile(os.path.join(demo_dir, "test.csv")):
            from ..corpus.demo import synth_corpus  # its sounds need scipy.signal, ~1-2 s to import: only the demo pays

            synth_corpus(demo_dir, seed=0)
        return demo_dir
    if not d:
        raise ConfigError("no corpus given: pass --corpus-dir DIR (the folder with the manifests and audio) "
                          "or set corpus.dir in the config")
    d = os.path.expanduser(d)
    check_input(d, ConfigError, "pass the folder that holds the manifests", folder=True)
    if not os.path.isdir(d):
        raise ConfigError(f"corpus directory not found: {d}; pass the folder that holds the manifests")
    return d


def manifest_path(cfg: Config, split: str, corpus_dir: str) -> str:
    """The split's manifest file; a ManifestError naming the folder looked in (and the
    manifests it does hold) when it is not there."""
    sp = cfg.splits[split]
    if not sp.manifest:
        raise ConfigError(f"splits.{split}.manifest is not set; name the manifest file for this split")
    path = os.path.expanduser(sp.manifest)
    path = path if os.path.isabs(path) else os.path.join(corpus_dir, path)
    if os.path.exists(path):
        return path
    if broken_link(path):  # it is there, as a link to nowhere: "not found" would send the user looking for it
        raise ManifestError(f"splits.{split}.manifest: {shown_path(path)} {broken_link(path)}; point the link at "
                            f"the manifest, or set splits.{split}.manifest to the file itself")
    folder = os.path.dirname(os.path.abspath(path))
    try:
        there = sorted(n for n in os.listdir(folder) if n.lower().endswith(MANIFEST_EXTENSIONS))
    except OSError:
        raise ManifestError(f"splits.{split}.manifest: {sp.manifest} not found: the folder {folder} does not "
                            f"exist; pass --corpus-dir with the folder that holds the manifests") from None
    held = (f"it holds {', '.join(there[:8])}{', ...' if len(there) > 8 else ''}" if there
            else "it holds no .csv, .json or .jsonl file")
    raise ManifestError(f"splits.{split}.manifest: {sp.manifest} not found in {folder} ({held}); set "
                        f"splits.{split}.manifest to the file's name, or pass the --corpus-dir that holds it")


def split_audio_dirs(cfg: Config, split: str, corpus_dir: str) -> list[str]:
    """The folders a split's relative audio paths are looked for in, in order.

    ``splits.NAME.audio_dir``, else ``corpus.audio_dir`` (both relative to the corpus
    folder; a folder the config names must exist, and is the only one). Else every
    download layout at once: the folders named for the split (``train``, ``training``,
    ``development``; ``val``, ``validation``; ...) that hold audio, in ``audio/`` or the
    corpus folder, then ``audio/`` (else the corpus folder) that all splits share. So
    train files in ``audio/`` and val files in ``audio/val/`` are all found, as are
    ``audio/{split}/``, Clotho's ``development/`` and a flat folder."""
    named = cfg.splits[split].audio_dir or cfg.corpus.audio_dir
    if not named:
        audio = os.path.join(corpus_dir, "audio")
        shared = audio if os.path.isdir(audio) else corpus_dir
        own = [d for folder in dict.fromkeys((shared, corpus_dir)) for name in split_aliases(split)
               if _holds_audio(d := os.path.join(folder, name))]
        rest = [corpus_dir] if shared != corpus_dir and _holds_audio(corpus_dir) else []
        return own + [shared] + rest
    key = f"splits.{split}.audio_dir" if cfg.splits[split].audio_dir else "corpus.audio_dir"
    d = os.path.expanduser(named)
    d = d if os.path.isabs(d) else os.path.join(corpus_dir, d)
    if not os.path.isdir(d):
        folders = sorted(n for n in os.listdir(corpus_dir) if os.path.isdir(os.path.join(corpus_dir, n)))
        raise ManifestError(f"{key}: audio folder {named} not found in {corpus_dir} (its folders: "
                            f"{', '.join(folders[:8]) or 'none'}); set {key} to the folder that holds the audio")
    return [d]


def _holds_audio(folder: str) -> bool:
    try:
        with os.scandir(folder) as it:
            return any(e.name.lower().endswith(AUDIO_EXTENSIONS) for e in it)
    except OSError:
        return False


HINT_FOLDERS = 2000  # folders of the corpus looked into, at most
HINT_DEPTH = 3  # ... and how deep


def missing_hint(split: str, listed: int, missing: list[Clip], audio_dirs: list[str], corpus_dir: str) -> str:
    """What the missing audio files of a split are: every missing clip's file is looked
    for by name (any audio extension, with or without AudioSet's ``Y``) in the folders
    below the corpus. Most of them in one folder the split does not read: the setting
    that reads it. In a folder it reads, under other names: the template. Nowhere: a
    partial download, said as such when the split finds any file (its layout is right),
    else the settings to look at."""
    want: dict[str, int] = {}
    for k, c in enumerate(missing):
        stem = os.path.splitext(os.path.basename(c.audio))[0]
        for name in (stem, "Y" + stem, c.id):
            want.setdefault(name, k)
    searched = {os.path.abspath(d) for d in audio_dirs}
    best, best_found, example = None, set(), ""
    top = corpus_dir.rstrip(os.sep).count(os.sep)
    for k, (folder, dirs, names) in enumerate(os.walk(corpus_dir)):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        if k >= HINT_FOLDERS or folder.count(os.sep) - top >= HINT_DEPTH:
            dirs[:] = []
        found, first = set(), ""
        for m in names:
            stem, ext = os.path.splitext(m)
            if ext.lower() in AUDIO_EXTENSIONS and stem in want:
                found.add(want[stem])
                first = first or m
        if len(found) > len(best_found):
            best, best_found, example = folder, found, first
    present = listed - len(missing)
    if best is None:
        if present:
            others = "the other is" if len(missing) == 1 else f"the {len(missing):,} others are"
            return (f"a partial download: {others} in no folder below {shown_path(corpus_dir)} (looked for by name, "
                    f"any audio extension)")
        return (f"none of them is anywhere below {shown_path(corpus_dir)}: set splits.{split}.audio_dir to the folder that "
                f"holds them, or corpus.audio_template to their names")
    rel = os.path.relpath(best, corpus_dir).replace(os.sep, "/")
    share = f"{len(best_found):,} of the {len(missing):,} missing"
    if os.path.abspath(best) in searched:
        return (f"{share} are in {rel} under other names (e.g. {example}): set corpus.audio_template to their "
                f"names, or convert them to a format listed in docs/config.md")
    return f"{share} are in {rel}: set splits.{split}.audio_dir = \"{rel}\""


def read_split_clips(cfg: Config, split: str, corpus_dir: str, audio_dirs: list[str] | None = None) -> list[Clip]:
    """Every clip of a split's manifest, unchecked (``audio_dirs``: the folders its audio
    is looked for in, :func:`split_audio_dirs` when not given).

    A manifest whose rows name their split (a plain manifest's ``split`` column) gives
    each split its own rows, so one file can serve several splits; a row without a split
    then belongs to the split that reads the file, and is an error in a file several
    splits share.
    """
    sp = cfg.splits[split]
    path = manifest_path(cfg, split, corpus_dir)
    readers = [s for s in cfg.active_splits() if cfg.splits[s].manifest == sp.manifest]
    shared = len(readers) > 1
    opts = {"split": None if shared else split}
    if cfg.corpus.audio_template:
        opts["template"] = cfg.corpus.audio_template
    audio_dirs = audio_dirs or split_audio_dirs(cfg, split, corpus_dir)
    try:
        clips = read_manifest(path, format=cfg.corpus.format, audio_dir=audio_dirs, **opts)
    except ManifestError as e:
        raise _format_hint(path, cfg.corpus.format) or e from None
    if shared:
        untagged = next((c for c in clips if c.split is None), None)
        if untagged is not None:
            raise ManifestError(f"{untagged.origin}: clip {untagged.id!r} has no split, and {sp.manifest} serves "
                                f"splits {', '.join(readers)}; fill in its split column, or give each split its "
                                f"own manifest")
    mine = [c for c in clips if c.split in (split, None)]
    if not mine:
        found = sorted({str(c.split) for c in clips})
        raise ManifestError(f"{path}: no row has split {split!r} (the split column holds {', '.join(found)}); "
                            f"name the splits alike in the config and the manifest")
    return mine


def _format_hint(path: str, fmt: str) -> ManifestError | None:
    """When a manifest the configured reader refuses has another format's header (a
    plain ``path,caption,split`` CSV under a paper preset's ``corpus.format =
    "audiocaps"``): the error that names the format and the setting."""
    if fmt == "auto":
        return None
    try:
        found = detect_format(path)
    except (TselError, OSError):
        return None
    if found == fmt:
        return None
    one = " (or --manifest FILE: one manifest for every split, by its split column)" if found == "plain" else ""
    return ManifestError(f"{path}:1: the header is a {found} manifest's, but corpus.format is \"{fmt}\"; set "
                         f"corpus.format = \"{found}\" or \"auto\"{one}")


def scan_catalog(cfg: Config, corpus_dir: str, workers: int = 1, progress: bool | None = None) -> CatalogScan:
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
    progress : bool or None
        A bar per split while clips are checked (None: when stderr is a terminal).

    Returns
    -------
    CatalogScan
    """
    scan = CatalogScan()
    seen: dict = {}
    for split in cfg.active_splits():
        try:
            scan.audio_dirs[split] = split_audio_dirs(cfg, split, corpus_dir)
            with bar(None, f"read {split}", "clip", progress) as b:  # 50k rows and their file names: a second or more
                clips = read_split_clips(cfg, split, corpus_dir, scan.audio_dirs[split])
                b.update(len(clips))
        except TselError as e:
            scan.problems.append(e)
            continue
        except OSError as e:
            scan.problems.append(ManifestError(f"splits.{split}.manifest: cannot read it ({e.strerror or e}: "
                                               f"{e.filename}); check the file"))
            continue
        scan.problems += [ManifestError(m) for m in duplicate_clips(clips, split, seen)]
        scan.problems += [ManifestError(m) for m in caption_problems(clips)]
        good, missing, n_bad, rates, left_out, kept = [], [], 0, Counter(), 0, 0
        floor = cfg.corpus.min_samplerate
        for clip, chk in zip(clips, check_clips(clips, cfg, workers, progress, desc=f"check {split}")):
            if chk.problem is None:
                if chk.prepared:  # the clip is good; what render would refuse is its prepared form
                    scan.problems.append(AudioError(f"{clip.origin}: clip {clip.id}: {chk.prepared}"))
                rate = chk.samplerate
                if rate and floor and rate < floor:
                    left_out += 1
                    continue
                if rate and rate < cfg.audio.fs:
                    rates[int(rate)] += 1
                kept += chk.kept
                good.append(clip)
                continue
            bad = BadClip(split, clip.id, clip.origin, chk.problem)
            if chk.missing:
                missing.append(clip)
            else:
                scan.bad.append(bad)
                n_bad += 1
            if cfg.on_bad_clip == "fail":
                scan.problems.append(bad.error())
        scan.missing[split] = missing
        scan.counts[split] = {"clips": len(clips), "missing": len(missing), "bad": n_bad,
                              **({"prepared": kept} if kept else {})}
        scan.rates[split] = dict(sorted(rates.items()))
        scan.left_out[split] = left_out
        if missing:
            scan.hints[split] = missing_hint(split, len(clips), missing, scan.audio_dirs[split], corpus_dir)
        if len(good) < MIN_CLIPS:
            absent = f" ({len(missing):,} of {len(clips):,} audio files missing from {_folders(scan.audio_dirs[split])}" \
                     + (f"; {scan.hints[split]}" if split in scan.hints else "") + ")" if missing else ""
            if left_out:
                absent += f" ({left_out:,} left out: recorded below corpus.min_samplerate = {floor} Hz)"
            scan.problems.append(TselError(f"split {split}: only {len(good):,} usable clips in "
                                           f"{cfg.splits[split].manifest}{absent}; a scene needs {MIN_CLIPS}; add "
                                           f"clips or fix the bad ones"))
            continue
        scan.clips[split] = good
        note = reuse_warning(cfg, split, len(good))
        if note:
            scan.warnings.append(note)
    scan.problems = list({str(p): p for p in scan.problems}.values())  # one manifest read by several splits
    return scan


def reuse_warning(cfg: Config, split: str, usable: int) -> str | None:
    """A note when a split asks many scenes of few clips: each clip would then sound in
    more than :data:`REUSE_WARN` scenes on average (as target or interferer), and a model
    learns those clips rather than the task."""
    sources = 1 + int((cfg.scene.interferers.bounds or (1, 1))[1])
    count = cfg.splits[split].count
    uses = count * sources / usable
    if uses <= REUSE_WARN or uses > cfg.corpus.max_reuse:  # beyond the limit: reuse_stop says it, once
        return None
    return (f"split {split}: {count:,} scenes from {usable:,} usable clips: each clip sounds in about {uses:.1f} "
            f"scenes; lower splits.{split}.count to about {int(REUSE_WARN * usable / sources):,} or add clips")


def reuse_stop(cfg: Config, scan: CatalogScan) -> str | None:
    """Why a run must stop before any work: splits whose count would have each usable
    clip sound in more than ``corpus.max_reuse`` scenes on average (a paper preset's
    7,224 scenes over a few clips: hours of rendering, a dataset of repeats)."""
    sources = 1 + int((cfg.scene.interferers.bounds or (1, 1))[1])
    limit = cfg.corpus.max_reuse
    over = []
    for split, clips in scan.clips.items():
        count = cfg.splits[split].count
        uses = count * sources / len(clips)
        if uses > limit:
            over.append((split, count, len(clips), uses, max(1, int(limit * len(clips) / sources))))
    if not over:
        return None
    said = "; ".join(f"split {s}: {n:,} scenes from {u:,} usable clips, each clip in about {x:,.0f} scenes"
                     for s, n, u, x, _ in over)
    fix = " ".join(f"--split {s}={k}" for s, _, _, _, k in over)
    return (f"{said} (more than corpus.max_reuse = {limit:g}); ask fewer scenes ({fix}) or add clips, or pass "
            f"--allow-reuse to make them anyway")


def build_catalog(cfg: Config, corpus_dir: str, workers: int = 1, progress: bool | None = None) -> CatalogScan:
    """:func:`scan_catalog`, raising its first problem.

    Parameters
    ----------
    cfg : Config
    corpus_dir : str
        The resolved corpus folder.
    workers : int
    progress : bool or None
        As for :func:`scan_catalog`.

    Returns
    -------
    CatalogScan
        With no problems: at least two usable clips in every split that makes scenes.

    Raises
    ------
    TselError
        The first problem (ManifestError, AudioError, ...), saying how many more there are.
    """
    scan = scan_catalog(cfg, corpus_dir, workers, progress)
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


def check_clips(clips: list[Clip], cfg: Config, workers: int = 1, progress: bool | None = None,
                desc: str = "check", level: str | None = None, prepare: list[bool] | None = None) -> list[ClipCheck]:
    """The ``corpus.check`` verdict on every clip, in order (``level``: another level;
    ``drawn`` checks headers here, the clips a plan draws in full in plan/drawn.py).

    ``prepare``: per clip, whether a ``full`` check writes its prepared form (default:
    ``corpus.prepare_on_check``, for every clip). Verdicts of ``header`` and ``full``
    checks are remembered (:mod:`tsel_data.corpus.clipcache`), so only new or changed
    files are decoded; a progress bar counts the split's clips, the remembered ones done
    from the start.
    """
    level = level or cfg.corpus.check
    if level == "drawn":
        level = "header"
    if level == "none":
        return [ClipCheck(c.id, None) for c in clips]
    if prepare is None:
        prepare = [level == "full" and cfg.corpus.prepare_on_check] * len(clips)
    args = [(c.id, c.audio, level, cfg.corpus.min_duration, cfg.corpus.max_channels, c.offset, cfg.audio.duration,
             cfg.audio.fs, p and level == "full") for c, p in zip(clips, prepare)]
    if level == "exists":
        with bar(len(args), desc, "clip", progress) as b:
            return list(_counted(map(_check, args), b))
    keys = [file_key(c.audio, settings_key(*a[2:8])) for c, a in zip(clips, args)]
    out: list[ClipCheck | None] = [None] * len(clips)
    with ClipCache() as cache:
        known = cache.get([k for k in keys if k is not None])
        todo = []
        for i, key in enumerate(keys):
            if key is None:
                out[i] = _check(args[i])  # no such file: found missing at once
            elif key in known and (verdict := _remembered(clips[i], ClipCheck(clips[i].id, *known[key]), cfg, level,
                                                          args[i][-1])) is not None:
                out[i] = verdict
            else:  # unknown, or to be prepared: checked (again), in the pool, its prepared form made from the decode
                todo.append(i)
        # the whole split counts, those remembered done at once: the bar says what is left
        # (all remembered: the check is instant, no bar)
        with bar(len(clips), desc, "clip", progress if todo else False, initial=len(clips) - len(todo)) as b:
            jobs = [args[i] for i in todo]
            if workers > 1 and level == "full" and len(jobs) > 64:
                with ordered_pool(workers) as ex:
                    results = list(_counted(ex.map(_check, jobs, chunksize=16), b))
            else:
                results = list(_counted(map(_check, jobs), b))
        for i, r in zip(todo, results):
            out[i] = r
        cache.put([(keys[i], r) for i, r in zip(todo, results)])
    return out


def _counted(results, b):
    for r in results:
        b.update()
        yield r


def _check(a) -> ClipCheck:
    return check_clip(*a)


def _remembered(clip: Clip, verdict: ClipCheck, cfg: Config, level: str, prepare: bool) -> ClipCheck | None:
    """A remembered verdict, with the clip's prepared form kept in step (checked as the
    check would have: audio.keep_prepared); None when the check would make the prepared
    form and it is not there: the clip is checked again, which makes it."""
    if verdict.problem is not None or level != "full":
        return verdict
    fs, duration = cfg.audio.fs, cfg.audio.duration
    wanted = prepare and wants_preparing(verdict.samplerate, verdict.channels, fs)
    if wanted:
        return replace(verdict, kept=True) if prepared_state(clip.audio, fs, duration, clip.offset) == "ok" else None
    problem = keep_prepared(clip.audio, fs, duration, clip.offset, prepare, wanted, deep=not prepare)
    return replace(verdict, prepared=problem) if problem else verdict


def prepare_corpus(cfg: Config, clips: dict[str, list[Clip]], workers: int = 1, progress=None) -> dict:
    """Prepare every clip the splits use (corpus/prepared.py) for scenes of ``cfg``'s rate and
    duration. Returns {"made": n, "kept": n} (kept: already prepared)."""
    jobs = [(c.audio, cfg.audio.fs, cfg.audio.duration, c.offset) for split in clips for c in clips[split]]
    made = 0
    # the runner of the shards: a first SIGINT or SIGTERM lets the clips in flight be
    # written (each whole), then stops; a second stops at once
    with Runner(workers=workers if len(jobs) > 1 else 1, noun="clip") as runner:
        for done in runner.map_unordered(_prepare, jobs):
            made += done
            if progress:
                progress()
    return {"made": made, "kept": len(jobs) - made}


def _prepare(job) -> bool:
    return prepare_clip(*job)


def write_missing_clips(path: str, scan: CatalogScan, root: str = "") -> None:
    """``missing_clips.json``: per split, how many clips the manifest lists, how many
    audio files are absent, where they were looked for (relative to the corpus folder
    ``root``), and their clip ids (compact: ids only, the problem is the same for all)."""
    doc = {"splits": {split: {"listed": scan.counts[split]["clips"], "missing": len(clips),
                              "audio_dir": _relative(scan.audio_dirs[split][0], root),
                              "audio_dirs": [_relative(d, root) for d in scan.audio_dirs[split]],
                              "clip_ids": [c.id for c in clips]}
                      for split, clips in scan.missing.items() if clips}}
    write_json(path, doc)


def write_bad_clips(path: str, bad: list[BadClip], root: str = "") -> None:
    """``bad_clips.jsonl``: one JSON object per bad clip, its paths relative to the corpus
    folder ``root`` (a dataset names no folder of the machine it was made on)."""
    write_lines(path, [json.dumps({**b.to_json(), "origin": _below(b.origin, root),
                                   "problem": _below(b.problem, root)}, ensure_ascii=False) for b in bad])


def _folders(dirs: list[str]) -> str:
    return " or ".join(dirs)


def _relative(path: str, root: str) -> str:
    """A folder's path relative to the corpus folder ``root`` (``/``-separated)."""
    if not root or not path:
        return path
    return os.path.relpath(os.path.abspath(path), os.path.abspath(root)).replace(os.sep, "/")


def _below(text: str, root: str) -> str:
    """``text`` with the corpus folder's path taken off every path below it."""
    if not root or not text:
        return text
    root = os.path.abspath(root)
    if os.path.abspath(text) == root:
        return "."
    return text.replace(root + os.sep, "")
