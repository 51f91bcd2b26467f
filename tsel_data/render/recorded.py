"""A recorded scene from its recipe (docs/recorded.md): the window's samples of the
recording as they are (no gain, no resampling), and its labels from the recording's label
file, frame by frame, in the recipe's source order (target first).

Positions are labelled only where a source is annotated, so they are NaN on a recorded
source's inactive frames (a rendered source has a position on every frame).
"""
from __future__ import annotations

import functools
import os

import numpy as np
import soundfile as sf

from ..core.digest import sha256_file
from ..core.geometry import azimuth_difference
from ..corpus.seld import SETS, read_labels, window_sources
from ..errors import AudioError, TselError
from ..core.files import check_input
from ..receivers import mic_positions, receiver
from ..scene.recipe import Roots
from ..scene.recorded import RecordedRecipe
from ..store.records import (ArrayRecord, LevelsRecord, RecordingRecord, RoomRecord, SceneRecord, SourceRecord,
                             label_list)
from ..store.scene import Scene

# a recorded source is "moving" when its labelled direction travels more than this: the
# annotations of a still source wander by a few degrees
MOVING_DEG = 10.0


# every recording a process renders from is hashed once (a file of a few hours is a few GB:
# seconds), its labels read once
@functools.lru_cache(maxsize=None)
def _digest(path: str, size: int, mtime_ns: int) -> str:
    return sha256_file(path)


@functools.lru_cache(maxsize=256)
def _labels(path: str, dataset: str, columns: tuple, size: int, mtime_ns: int):
    return read_labels(path, SETS[dataset], None, columns)


def _stat(path: str) -> tuple[int, int]:
    try:
        st = os.stat(path)
    except OSError as e:
        raise AudioError(f"cannot read {path}: {e.strerror or e}; check that the recording is there") from None
    return st.st_size, st.st_mtime_ns


def render_recorded(recipe: RecordedRecipe, roots: Roots) -> Scene:
    """The scene of a recorded recipe (AudioError naming the file when the recording or its
    labels are not what the plan read)."""
    path, meta = roots.clip(recipe.audio), roots.clip(recipe.metadata)
    audio = read_window(path, recipe)
    labels = _labels(meta, recipe.dataset, tuple(recipe.columns), *_stat(meta))
    found = {s.key: s for s in window_sources(labels, recipe.start, recipe.frames)}
    missing = [s.key for s in recipe.sources if s.key not in found]
    if missing:
        raise AudioError(f"{recipe.metadata}: the labels of {recipe.scene_id} changed since it was planned (no "
                         f"source {missing[0]} in its window); plan again")
    srcs = [found[s.key] for s in recipe.sources]
    az = np.array([s.azimuth for s in srcs], dtype=np.float32)
    el = np.array([s.elevation for s in srcs], dtype=np.float32)
    dist = np.array([s.distance for s in srcs], dtype=np.float32)
    active = np.array([s.active for s in srcs], dtype=bool)
    mics = mic_positions(recipe.format).astype(np.float32)
    record = _record(recipe, path, meta, srcs, az, el, dist, active, mics)
    return Scene(scene_id=recipe.scene_id, split=recipe.split, index=recipe.index, query=recipe.query, audio=audio,
                 azimuth=az, elevation=el, distance=dist, active=active, mic_positions=mics, fs=recipe.fs,
                 label_hop=recipe.label_hop, format=recipe.format, record=record)


def recorded_problem(recipe: RecordedRecipe, roots: Roots) -> str | None:
    """Why the recipe's scene cannot be cut from the files at ``roots`` (its recording is
    shorter, of another rate or channel count, or its labels no longer hold its sources),
    or None. What a rebuild from a release says scene by scene instead of failing."""
    try:
        check_input(roots.clip(recipe.audio), AudioError, "a recording is an audio file")
        info = sf.info(roots.clip(recipe.audio))
        labels = _labels(roots.clip(recipe.metadata), recipe.dataset, tuple(recipe.columns),
                         *_stat(roots.clip(recipe.metadata)))
    except (RuntimeError, sf.LibsndfileError, TselError) as e:
        return str(e)
    if info.samplerate != recipe.fs or info.channels != len(recipe_channels(recipe)):
        return f"{recipe.audio} is {info.samplerate} Hz, {info.channels} channels, not {recipe.fs} Hz, " \
               f"{len(recipe_channels(recipe))}"
    if info.frames < recipe.first_sample + recipe.n_samples:
        return f"{recipe.audio} ends before the scene's window ({info.frames / info.samplerate:g} s)"
    found = {s.key for s in window_sources(labels, recipe.start, recipe.frames)}
    gone = [s.key for s in recipe.sources if s.key not in found]
    return f"{recipe.metadata} no longer labels source {gone[0]} in the scene's window" if gone else None


def read_window(path: str, recipe: RecordedRecipe) -> np.ndarray:
    """The window's samples, float32 [C, T], as the file holds them."""
    check_input(path, AudioError, "a recording is an audio file")
    try:
        with sf.SoundFile(path) as f:
            if f.samplerate != recipe.fs or f.channels != len(recipe_channels(recipe)):
                raise AudioError(f"{path} is {f.samplerate} Hz, {f.channels} channels; the plan read "
                                 f"{recipe.fs} Hz, {len(recipe_channels(recipe))} channels: plan again")
            f.seek(recipe.first_sample)
            x = f.read(recipe.n_samples, dtype="float32", always_2d=True)
    except (RuntimeError, sf.LibsndfileError) as e:
        raise AudioError(f"cannot read {path} ({e}); check the recording") from None
    if len(x) != recipe.n_samples:
        raise AudioError(f"{path} ends before {recipe.scene_id}'s window ({len(x)} of {recipe.n_samples} samples "
                         f"from {recipe.first_sample}); the recording changed since it was planned")
    return np.ascontiguousarray(x.T)


def recipe_channels(recipe: RecordedRecipe) -> tuple:
    return receiver(recipe.format).channels()


def _record(recipe: RecordedRecipe, path: str, meta: str, srcs, az, el, dist, active, mics) -> SceneRecord:
    sources = []
    for k, (ref, s) in enumerate(zip(recipe.sources, srcs)):
        seen = np.isfinite(s.azimuth)
        moving = bool(seen.sum() > 1 and np.max(azimuth_difference(s.azimuth[seen], s.azimuth[seen][0])) > MOVING_DEG)
        sources.append(SourceRecord(
            role="target" if k == 0 else "interferer",
            clip_id=f"{ref.name} ({os.path.splitext(os.path.basename(recipe.audio))[0]}, source {ref.source}"
                    f"{'' if ref.ordinal == 0 else '.' + str(ref.ordinal)})", audio=recipe.audio,
            captions=list(ref.captions),
            spatial="directional" if s.directional else "additive", moving=moving,
            azimuth=label_list(az[k]), elevation=label_list(el[k]), distance=label_list(dist[k], 4),
            active=active[k].tolist()))
    motion = "moving" if any(s.moving for s in sources) else "static"
    recording = RecordingRecord(
        recipe.dataset, recipe.audio, recipe.metadata, _digest(path, *_stat(path)), _digest(meta, *_stat(meta)),
        round(recipe.start * recipe.label_hop, 6), recipe.start, recipe.frames, recipe.fold, recipe.room,
        [r.name for r in recipe.sources], [r.cls for r in recipe.sources], [r.source for r in recipe.sources],
        [r.ordinal for r in recipe.sources])
    return SceneRecord(
        scene_id=recipe.scene_id, split=recipe.split, index=recipe.index, seed=recipe.seed, scenario="recorded",
        query=recipe.query, motion=motion, rir_method="recorded", room=RoomRecord(),
        array=ArrayRecord(recipe.format, mic_positions=np.round(mics, 6).tolist()), sources=tuple(sources),
        levels=LevelsRecord(), query_type=recipe.query_type, query_relation=recipe.query_relation,
        query_evidence=recipe.query_evidence, query_alternatives=list(recipe.query_alternatives),
        pairing="recorded", query_wanted=recipe.query_type, recording=recording)
