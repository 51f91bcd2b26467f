"""The planner of recorded datasets (docs/recorded.md): windows of real recordings become
scene recipes whose query the labels make true.

Each recording of a split (its folds and rooms) is cut into windows of ``audio.duration``
seconds every ``recorded.hop`` seconds, on label-frame boundaries. In a window, every
directional source active for at least ``recorded.min_active`` seconds is a target once;
every other source of the window is an interferer. The query is one of the target's class
captions when no other source of the window has its class; otherwise a composite query
("A man speaks: the one that starts first") with the first relation, in a random order,
that the labels decide between the sources of that class with its margin. Loudness is
never used: a recording's sources cannot be measured apart. A target no relation tells
apart is skipped and counted with why (``plan/config.json``, ``dataset.json``, ``tsel
stats``).

Every candidate is decided in a fixed order with its own generator, then the kept ones are
taken in a seeded permutation of the split, as many as ``splits.NAME.count`` asks: the
same config gives the same scenes, and a larger count keeps the scenes already planned.
"""
from __future__ import annotations

import math
import os
import zlib
from collections import Counter
from dataclasses import dataclass

import numpy as np
import soundfile as sf

from ..choices import Relation
from ..config import Config
from ..corpus.ontologies import Ontology, read_ontology
from ..corpus.seld import SETS, FRAME_HOP, Labels, Recording, Source, find_recordings, read_labels, window_sources
from ..errors import ConfigError
from ..core.files import check_input
from ..receivers import receiver
from ..scene.queries import RELATIONS, Truth, check, composite_wordings, held, margins
from ..scene.recipe import BUILTIN_DEMO_RECORDED, plan_roots
from ..scene.recorded import RecordedRecipe, SourceRef

SKIP_NO_RELATION = "another source of its class is in the window and no relation tells them apart"
SKIP_NO_DIRECTION = "it has no direction"


@dataclass(frozen=True)
class Candidate:
    recording: Recording
    start: int
    target: Source
    others: tuple[Source, ...]


def recorded_setup(cfg: Config, corpus_dir: str):
    """(set spec, ontology, receiver spec, recordings) of a recorded config; ConfigError
    when the labels cannot be a test set of this config (frames other than the set's)."""
    rec = cfg.recorded
    seld = SETS[rec.dataset]
    ontology = read_ontology(rec.ontology) if rec.ontology else seld.ontology
    spec = receiver(cfg.scene.format)
    if abs(cfg.audio.label_hop - FRAME_HOP) > 1e-9:
        raise ConfigError(f"audio.label_hop = {cfg.audio.label_hop}: recorded datasets are labelled on "
                          f"{FRAME_HOP} s frames; set audio.label_hop = {FRAME_HOP}")
    return seld, ontology, spec, find_recordings(corpus_dir, spec.export_folder)


def split_recordings(cfg: Config, split: str, recordings: list[Recording]) -> list[Recording]:
    """The recordings of ``split``: its folds (the set's own split by default) and rooms."""
    sp = cfg.splits[split]
    folds = tuple(int(f) for f in sp.folds) or SETS[cfg.recorded.dataset].folds.get(split, ())
    rooms = tuple(_room_number(r, split) for r in sp.rooms)
    out = [r for r in recordings if (not folds or r.fold in folds) and (not rooms or r.room in rooms)]
    if not out:
        what = " and ".join(x for x in (f"folds {list(folds)}" if folds else "",
                                        f"rooms {list(rooms)}" if rooms else "") if x)
        raise ConfigError(f"splits.{split}: no recording of {what or 'the dataset'} (recordings are named "
                          f"fold{{N}}_room{{R}}_...); set splits.{split}.folds or splits.{split}.rooms")
    return out


def _room_number(room, split: str) -> int:
    text = str(room).lower().removeprefix("room")
    if not text.isdigit():
        raise ConfigError(f"splits.{split}.rooms: {room!r} is not a room of a recorded dataset (a number, or room{{R}})")
    return int(text)


def recorded_corpus(cfg: Config, home) -> str:
    """The recordings' folder: ``corpus.dir``, or for ``builtin:demo-recorded`` the STARSS23
    stand-in, synthesised into the dataset folder once (``home``: its Layout)."""
    if cfg.corpus.dir == BUILTIN_DEMO_RECORDED:
        if not os.path.isdir(os.path.join(home.demo_recordings, "metadata_dev")):
            from ..corpus.demo.recordings import synth_recordings  # the demo alone pays for writing it

            synth_recordings(home.demo_recordings, seed=0)
        return home.demo_recordings
    if not cfg.corpus.dir:
        raise ConfigError("no recorded dataset given: pass --corpus-dir DIR (the folder holding foa_dev/ and "
                          "metadata_dev/, e.g. your STARSS23) or set corpus.dir")
    return plan_roots(cfg, home).corpus


def plan_recorded(cfg: Config, corpus_dir: str, report=None) -> tuple[dict[str, list[str]], dict]:
    """({split: recipe lines}, summary) of a recorded config. The summary, per split:
    recordings, windows, sources, candidates, kept (planned), skipped ({why: count}),
    too_short (sources active less than ``recorded.min_active``), and ``asked`` (the
    count the config asked, a cap)."""
    seld, ontology, spec, recordings = recorded_setup(cfg, corpus_dir)
    window = int(round(cfg.audio.duration / FRAME_HOP))
    hop = int(round((cfg.recorded.hop or cfg.audio.duration) / FRAME_HOP))
    min_frames = int(math.ceil(cfg.recorded.min_active / FRAME_HOP - 1e-9))
    plans, summary = {}, {}
    labels_of: dict[str, Labels] = {}
    taken: dict[str, str] = {}  # recording -> the split that took it
    for split, sp in cfg.splits.items():
        if not sp.count:
            continue
        recs = split_recordings(cfg, split, recordings)
        shared = next((r for r in recs if r.audio in taken), None)
        if shared is not None:
            raise ConfigError(f"splits {taken[shared.audio]} and {split} both take {shared.audio}: a test set must "
                              f"not hold what training heard; give each split its folds or rooms "
                              f"(splits.NAME.folds, splits.NAME.rooms)")
        taken.update((r.audio, split) for r in recs)
        stats = Counter()
        candidates: list[Candidate] = []
        for r in recs:
            frames = _audio_frames(corpus_dir, r, cfg.audio.fs, spec)
            if window > frames:
                raise ConfigError(f"{r.audio}: the window (audio.duration = {cfg.audio.duration:g} s) is longer "
                                  f"than the recording ({frames * FRAME_HOP:g} s); set audio.duration to at most "
                                  f"{frames * FRAME_HOP:g}")
            if r.metadata not in labels_of:
                labels_of[r.metadata] = read_labels(os.path.join(corpus_dir, r.metadata), seld, ontology,
                                                    tuple(cfg.recorded.columns))
            labels = labels_of[r.metadata]
            if len(labels.frame) and labels.frame.max() >= frames + int(round(1.0 / FRAME_HOP)):
                raise ConfigError(f"{r.metadata} labels {labels.frame.max() * FRAME_HOP:g} s but {r.audio} is "
                                  f"{frames * FRAME_HOP:g} s long: the recording is cut short (a download that "
                                  f"stopped?) or the labels are another recording's; restore the file")
            stats["recordings"] += 1
            for start in range(0, frames - window + 1, hop):
                sources = window_sources(labels, start, window)
                stats["windows"] += 1
                stats["sources"] += len(sources)
                for t in sources:
                    if int(t.active.sum()) < min_frames:
                        stats["too_short"] += 1
                        continue
                    candidates.append(Candidate(r, start, t, tuple(s for s in sources if s is not t)))
        skipped, kept = Counter(), []
        for n, c in enumerate(candidates):
            rng = np.random.default_rng([cfg.seed, zlib.crc32(split.encode("utf-8")), n, 1])
            query = decide_recorded_query(c, ontology, cfg, rng, labels_of[c.recording.metadata].has_distance)
            if isinstance(query, str):
                skipped[query] += 1
            else:
                kept.append((c, query))
        order = np.random.default_rng([cfg.seed, zlib.crc32(split.encode("utf-8")), 2]).permutation(len(kept))
        lines = []
        for k in order[:sp.count]:
            c, query = kept[int(k)]
            lines.append(_recipe(cfg, seld.name, split, len(lines), c, query, ontology, spec.name).to_json())
        plans[split] = lines
        summary[split] = {"recordings": stats["recordings"], "windows": stats["windows"], "sources": stats["sources"],
                          "candidates": len(candidates), "kept": len(lines), "asked": sp.count,
                          "too_short": stats["too_short"], "skipped": dict(sorted(skipped.items()))}
        if report:
            line = (f"{split}: {len(lines)} recorded scenes from {stats['windows']} windows of "
                    f"{stats['recordings']} recordings ({len(candidates)} targets")
            why = "; ".join(f"{n} skipped: {reason}" for reason, n in sorted(skipped.items()))
            report(line + (f", {why})" if why else ")"))
    return plans, summary


def _audio_frames(corpus_dir: str, r: Recording, fs: int, spec) -> int:
    """The recording's length in label frames, after checking its rate and channels."""
    path = os.path.join(corpus_dir, r.audio)
    check_input(path, ConfigError, "a recording is an audio file")
    try:
        info = sf.info(path)
    except (RuntimeError, sf.LibsndfileError) as e:
        raise ConfigError(f"{path}: cannot read the recording ({e}); check the file") from None
    if info.frames == 0:
        raise ConfigError(f"{path} holds no samples (an empty or damaged file); restore it or remove it with its "
                          f"label file")
    if info.samplerate != fs:
        raise ConfigError(f"{path} is {info.samplerate} Hz but the scenes are audio.fs = {fs} Hz; set audio.fs = "
                          f"{info.samplerate} (recorded scenes keep the recording's rate)")
    if info.channels != len(spec.channels()):
        raise ConfigError(f"{path} has {info.channels} channels; scene.format = \"{spec.name}\" has "
                          f"{len(spec.channels())}: set scene.format to the recordings' receiver")
    return int(math.floor(info.frames / (fs * FRAME_HOP) + 1e-9))


# relations the labels of a recording decide (its sources' levels cannot be told apart)
def decidable(cfg: Config, distances: bool) -> list[str]:
    return [r for r in cfg.scene.relations
            if RELATIONS[Relation(r)].needs != "level" and (distances or RELATIONS[Relation(r)].needs != "distance")]


def decide_recorded_query(c: Candidate, ontology: Ontology, cfg: Config, rng: np.random.Generator,
                          distances: bool):
    """(type, relation, text, evidence, alternatives) of a candidate's query, or the reason
    it is skipped (a string)."""
    if not c.target.directional:
        return SKIP_NO_DIRECTION
    captions = ontology[c.target.cls].captions
    caption = captions[int(rng.integers(len(captions)))]
    same = [k + 1 for k, o in enumerate(c.others) if o.cls == c.target.cls]
    if not same:
        return ("caption", None, caption, None, tuple(captions))
    truth = recorded_truth([c.target, *c.others])
    margin = margins(cfg.scene)
    for rel in rng.permutation(decidable(cfg, distances)):
        ev = check(str(rel), truth, same, margin[Relation(rel)])
        if ev is not None:
            words = composite_wordings(Relation(rel), caption, len(same) + 1, ev)
            return ("composite", str(rel), words[int(rng.integers(len(words)))], ev, words)
    return SKIP_NO_RELATION


def recorded_truth(sources) -> Truth:
    """What the relations are decided on: activity as labelled, and each source's direction
    and distance held from its nearest labelled frame where it is not labelled (a recording
    says where a source is only while it sounds). Levels: unknown (NaN)."""
    el = [held(s.elevation) if np.isfinite(s.elevation).any() else np.where(np.isfinite(held(s.azimuth)), 0.0, np.nan)
          for s in sources]
    return Truth(level_db=np.full(len(sources), np.nan), active=np.array([s.active for s in sources]),
                 azimuth=np.array([held(s.azimuth) for s in sources]), elevation=np.array(el),
                 distance=np.array([held(s.distance) for s in sources]), hop=FRAME_HOP)


def _recipe(cfg: Config, dataset: str, split: str, index: int, c: Candidate, query, ontology: Ontology,
            fmt: str) -> RecordedRecipe:
    qtype, relation, text, evidence, alternatives = query
    refs = tuple(SourceRef(s.key[0], s.key[1], s.key[2], ontology[s.cls].name, ontology[s.cls].captions)
                 for s in (c.target, *c.others))
    window = int(round(cfg.audio.duration / FRAME_HOP))
    return RecordedRecipe(scene_id=f"{split}-{index:06d}", split=split, index=index, seed=cfg.seed, dataset=dataset,
                          audio=c.recording.audio, metadata=c.recording.metadata, format=fmt, start=c.start,
                          frames=window, fs=cfg.audio.fs, label_hop=FRAME_HOP, sources=refs, query=text,
                          query_type=qtype, query_relation=relation, query_evidence=evidence,
                          query_alternatives=tuple(alternatives), fold=c.recording.fold, room=c.recording.room,
                          columns=tuple(cfg.recorded.columns))
