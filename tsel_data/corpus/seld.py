"""Recorded SELD datasets as they are distributed (the DCASE layout): where the recordings
and their label CSVs are, what a CSV row says, and the sources a window of a recording
holds.

Layout (STARSS22/23, TAU-NIGENS 2020/2021, the DCASE 2025 stereo set, your own)::

    ROOT/{foa,mic,stereo}_dev/[SUBFOLDER/]fold{N}_room{R}_mix{NNN}.wav
    ROOT/metadata_dev/[SUBFOLDER/]fold{N}_room{R}_mix{NNN}.csv

(the audio folder is the receiver's: ``foa`` for FOA, ``mic`` for the tetrahedral MIC
format, ``stereo``), or any folder of ``NAME.wav`` beside ``NAME.csv``. A CSV has no header;
each row is one source active on one 100 ms frame, frames numbered from 0: by default
``frame, class, source, azimuth, elevation`` and, in the 2024 edition, ``distance`` in
centimetres (each set's columns: :data:`SETS`). Azimuth is counter-clockwise from the
front, our convention; frames without events are absent; overlapping events repeat a
frame, possibly of one class. ``source`` names an actor (a person's speech and laughter
share it; non-actor sources are 0) in STARSS, an event track in TAU-NIGENS.

A *source* of a window (:func:`window_sources`) is one class of one actor; two sources of
one class and actor at once (two non-actor sources) are told apart by continuity of
direction. Bad input is one :class:`~tsel_data.errors.ConfigError` line naming the file
and the row.
"""
from __future__ import annotations

import csv
import math
import os
import re
from dataclasses import dataclass

import numpy as np

from ..choices import RecordedSet
from ..core.geometry import sph_to_cart
from ..errors import ConfigError
from ..core.files import check_input
from .ontologies import STARSS, TAU_NIGENS_2020, TAU_NIGENS_2021, Ontology

FRAME_HOP = 0.1  # s: every DCASE SELD label frame
LIMIT = 2 ** 31  # a label file's numbers: frames of 100 ms over 6 years, class and source ids, centimetres
COLUMNS = ("frame", "class", "source", "azimuth", "elevation", "distance", "ignore")
_NAME = re.compile(r"fold(\d+)_room(\d+)_", re.IGNORECASE)


@dataclass(frozen=True)
class SeldSet:
    """What one recorded dataset is: its classes, its CSV columns by row width, the folds
    its development splits are made of, and where that is documented."""

    name: str
    summary: str
    ontology: Ontology
    columns: dict  # row width -> column names (COLUMNS)
    folds: dict  # our split -> the set's folds
    documented: str


_STARSS_COLUMNS = {5: ("frame", "class", "source", "azimuth", "elevation"),
                   6: ("frame", "class", "source", "azimuth", "elevation", "distance")}
SETS = {s.name: s for s in (
    SeldSet(RecordedSet.STARSS23, "Sony-TAu Realistic Spatial Soundscapes 2023: 16 rooms, 13 classes, real FOA and "
            "MIC recordings", STARSS, _STARSS_COLUMNS, {"train": (3,), "test": (4,)},
            "STARSS23 README (zenodo 7880637); 6 columns in the DCASE 2024 edition (distance, cm)"),
    SeldSet(RecordedSet.STARSS22, "Sony-TAu Realistic Spatial Soundscapes 2022: 11 rooms, 13 classes",
            STARSS, _STARSS_COLUMNS, {"train": (3,), "test": (4,)}, "STARSS22 README (zenodo 6387880)"),
    SeldSet(RecordedSet.TAU_NIGENS_2020, "TAU-NIGENS Spatial Sound Events 2020: real RIRs, 14 NIGENS classes",
            TAU_NIGENS_2020, {5: ("frame", "class", "source", "azimuth", "elevation")},
            {"train": (3, 4, 5, 6), "val": (2,), "test": (1,)},
            "TAU-NIGENS Spatial Sound Events 2020 README (zenodo 4064792): frame, class, track, azimuth, elevation"),
    SeldSet(RecordedSet.TAU_NIGENS_2021, "TAU-NIGENS Spatial Sound Events 2021: real RIRs, 12 NIGENS classes, "
            "unlabelled interferers", TAU_NIGENS_2021, {5: ("frame", "class", "source", "azimuth", "elevation")},
            {"train": (1, 2, 3, 4), "val": (5,), "test": (6,)},
            "TAU-NIGENS Spatial Sound Events 2021 README (zenodo 5476980): frame, class, track, azimuth, elevation"),
    SeldSet(RecordedSet.DCASE2025_STEREO, "DCASE 2025 task 3 stereo SELD: 5 s stereo clips of STARSS23, azimuth and "
            "distance", STARSS, {5: ("frame", "class", "source", "azimuth", "distance"),
                                 6: ("frame", "class", "source", "azimuth", "distance", "ignore")},
            {"train": (3,), "test": (4,)},
            "DCASE 2025 task 3 documentation: frame, class, source, azimuth, distance (cm), onscreen (ignored)"),
    SeldSet(RecordedSet.CUSTOM, "your own recordings in the DCASE convention, with your ontology (recorded.ontology)",
            STARSS, _STARSS_COLUMNS, {}, "the STARSS23 convention unless recorded.columns says otherwise"),
)}


@dataclass(frozen=True)
class Recording:
    """One recording: its audio and label files relative to the dataset folder (``/``),
    and the fold and room its name says (None when it says none)."""

    audio: str
    metadata: str
    fold: int | None
    room: int | None

    @property
    def name(self) -> str:
        return os.path.splitext(os.path.basename(self.audio))[0]


def find_recordings(root: str, folder: str) -> list[Recording]:
    """Every recording of ``root`` with its label CSV, sorted by path: the DCASE layout
    (``{folder}_dev/``, and ``{folder}_eval/`` when ``metadata_eval/`` is there), else
    WAVs with a CSV of the same name beside them. ConfigError, one line: no recordings, a
    WAV without its CSV or a label file without its WAV (a download cut short), an
    evaluation folder without labels, a folder that cannot be read."""
    if not os.path.isdir(root):
        raise ConfigError(f"recorded dataset folder {root} not found; give --corpus-dir with the dataset's folder")
    found: list[Recording] = []
    layouts = [(f"{folder}_{part}", f"metadata_{part}") for part in ("dev", "eval")]
    dcase = [(a, m) for a, m in layouts if os.path.isdir(os.path.join(root, a))]
    if dcase:
        for audio_dir, meta_dir in dcase:
            wavs = _files(root, audio_dir, ".wav")
            if not os.path.isdir(os.path.join(root, meta_dir)):
                if audio_dir.endswith("_eval") and any(d.endswith("_dev") for d, _ in dcase):
                    continue  # labels of the evaluation set are not distributed: the dev set is read
                others = sorted(d for d in os.listdir(root) if d.startswith("metadata") and d != meta_dir)
                what = ("an evaluation set without labels cannot be a test set; use the development set "
                        f"({folder}_dev/ with metadata_dev/) or add the labels" if audio_dir.endswith("_eval") else
                        f"the labels are distributed in {meta_dir}/ beside {audio_dir}/"
                        + (f" (this folder has {', '.join(o + '/' for o in others)}: rename the one of your "
                           f"edition to {meta_dir}/)" if others else ""))
                raise ConfigError(f"{os.path.join(root, audio_dir)} has no labels ({meta_dir}/ is missing): {what}")
            metas = {os.path.splitext(m)[0].lower(): m for m in _files(root, meta_dir, ".csv")}
            for rel in wavs:
                stem = os.path.splitext(rel)[0]
                meta = metas.pop(stem.lower(), stem + ".csv")
                found.append(_recording(root, os.path.join(audio_dir, rel), os.path.join(meta_dir, meta)))
            if metas and audio_dir.endswith("_dev"):
                lone = os.path.join(root, meta_dir, sorted(metas.values())[0])
                raise ConfigError(f"{lone} has no recording (expected it in {os.path.join(root, audio_dir)}/, as a "
                                  f"WAV file of the same name): a download cut short? restore it, or remove the "
                                  f"label file")
    else:
        if any(os.path.isdir(os.path.join(root, f"{other}_dev")) for other in ("foa", "mic", "stereo")):
            have = [f for f in ("foa", "mic", "stereo") if os.path.isdir(os.path.join(root, f"{f}_dev"))]
            raise ConfigError(f"{root} has no {folder}_dev/ but has {', '.join(f + '_dev/' for f in have)}: set "
                              f"scene.format to the receiver of those recordings (foa, tetra for mic_dev, stereo)")
        base = os.path.basename(os.path.normpath(root))
        if base.endswith("_dev") or base.endswith("_eval"):
            raise ConfigError(f"--corpus-dir {root} is a folder inside a DCASE-layout dataset: give the folder that "
                              f"holds {base}/ (and metadata_dev/), {os.path.dirname(os.path.normpath(root))}")
        nested = sorted(d for d in (os.listdir(root) if os.access(root, os.R_OK) else [])
                        if os.path.isdir(os.path.join(root, d, f"{folder}_dev")))
        if nested:
            raise ConfigError(f"{root} holds no {folder}_dev/ itself; {os.path.join(root, nested[0])} holds it: give "
                              f"that folder as --corpus-dir")
        metas = {os.path.splitext(m)[0].lower(): m for m in _files(root, "", ".csv")}
        for rel in _files(root, "", ".wav"):
            stem = os.path.splitext(rel)[0]
            found.append(_recording(root, rel, metas.get(stem.lower(), stem + ".csv")))
    if not found:
        raise ConfigError(f"no recordings in {root}: expected {folder}_dev/ and metadata_dev/ as distributed "
                          f"(docs/recorded.md), or WAV files with a CSV of the same name beside each")
    return sorted(found, key=lambda r: r.audio)


def _files(root: str, top: str, ext: str) -> list[str]:
    """The files ending in ``ext`` (any case) below ``root/top``, relative to it, through
    linked folders (each real folder once: a link back up is no loop), but hidden ones
    (``._NAME.wav`` of a macOS copy) and anything that is not a regular file (a FIFO would
    block a read). A folder that cannot be read is a ConfigError."""
    out, seen = [], set()

    def refuse(e: OSError):
        raise ConfigError(f"cannot read {e.filename}: {e.strerror or e}; check its permissions")

    start = os.path.join(root, top)
    for d, dirs, names in os.walk(start, followlinks=True, onerror=refuse):
        real = os.path.realpath(d)
        if real in seen:
            dirs[:] = []
            continue
        seen.add(real)
        dirs[:] = sorted(x for x in dirs if not x.startswith("."))
        out += [os.path.relpath(os.path.join(d, f), start) for f in names
                if f.lower().endswith(ext) and not f.startswith(".") and os.path.isfile(os.path.join(d, f))]
    return sorted(out)


def _recording(root: str, audio: str, meta: str) -> Recording:
    if not os.path.isfile(os.path.join(root, meta)):
        raise ConfigError(f"{os.path.join(root, audio)} has no label file (expected {os.path.join(root, meta)}); "
                          f"add it or remove the recording")
    for f in (audio, meta):
        if not os.access(os.path.join(root, f), os.R_OK):
            raise ConfigError(f"cannot read {os.path.join(root, f)}: permission denied; check its permissions")
    m = _NAME.search(os.path.basename(audio))
    fold, room = (int(m.group(1)), int(m.group(2))) if m else (None, None)
    return Recording(audio.replace(os.sep, "/"), meta.replace(os.sep, "/"), fold, room)


@dataclass(frozen=True)
class Labels:
    """A label CSV as arrays, one entry per row (frame order): frame, class, source;
    azimuth and elevation in degrees (NaN: no direction), distance in metres (NaN: not
    given)."""

    frame: np.ndarray
    cls: np.ndarray
    source: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    distance: np.ndarray

    @property
    def has_distance(self) -> bool:
        return bool(len(self.distance)) and bool(np.isfinite(self.distance).any())


def columns_of(seld: SeldSet, width: int, override: tuple = ()) -> tuple | None:
    """The column names of a row ``width`` fields wide (``override``: recorded.columns)."""
    if override:
        return tuple(override) if len(override) == width else None
    return seld.columns.get(width)


def read_labels(path: str, seld: SeldSet, ontology: Ontology | None, override: tuple = ()) -> Labels:
    """A label CSV, checked row by row: ConfigError naming ``path`` and the row when a row
    is not one of the set's widths of whole numbers, a class is not in ``ontology``, a frame
    is negative (``ontology`` None: any class), an azimuth is outside [-180, 180] or an elevation outside [-90, 90], or a
    distance is negative. Azimuth and elevation may be left empty together (a source
    without a direction)."""
    widths = sorted({len(override)} if override else seld.columns)
    want = " or ".join(str(w) for w in widths)
    rows = {k: [] for k in ("frame", "class", "source", "azimuth", "elevation", "distance")}
    seen: set = set()
    check_input(path, ConfigError, "a label file is a CSV file")
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:  # a spreadsheet's byte-order mark
            lines = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{path}: cannot read the label file ({e}); check the file") from None
    for n, raw in enumerate(lines, start=1):
        fields = [c.strip() for c in raw]
        if not any(fields):
            continue
        cols = columns_of(seld, len(fields), override)
        if cols is None:
            raise ConfigError(f"{path}:{n}: a row of {len(fields)} fields; a {seld.name} label row is {want} whole "
                              f"numbers ({', '.join(columns_of(seld, widths[-1], override))})")
        values = dict(zip(cols, fields))
        parsed = {}
        direction_blank = all(values.get(k) == "" for k in ("azimuth", "elevation") if k in values)
        for key in ("frame", "class", "source", "azimuth", "elevation", "distance"):
            if key not in values:  # a column this set does not have
                parsed[key] = 0 if key == "source" else math.nan
                continue
            text = values[key]
            if text == "" and (key == "distance" or (key in ("azimuth", "elevation") and direction_blank)):
                parsed[key] = math.nan
                continue
            try:
                parsed[key] = int(text)
            except ValueError:
                try:
                    v = float(text)
                except ValueError:
                    v = math.nan
                if not math.isfinite(v) or v != int(v):
                    raise ConfigError(f"{path}:{n}: {key} {text!r} is not a whole number; a label row is {want} "
                                      f"whole numbers") from None
                parsed[key] = int(v)
            if abs(parsed[key]) >= LIMIT:
                raise ConfigError(f"{path}:{n}: {key} {text} is out of range (a label row's numbers are below "
                                  f"{LIMIT:,}); the file is damaged")
        if parsed["frame"] < 0:
            raise ConfigError(f"{path}:{n}: frame {parsed['frame']} is negative; frames count from 0")
        if ontology is not None and parsed["class"] not in ontology:
            raise ConfigError(f"{path}:{n}: class {parsed['class']} is not in the ontology ({len(ontology)} classes, "
                              f"{min(ontology)}-{max(ontology)}); give the classes of these recordings with "
                              f"recorded.ontology")
        az, el = parsed["azimuth"], parsed["elevation"]
        if not (math.isnan(az) or -180 <= az <= 180):
            raise ConfigError(f"{path}:{n}: azimuth {az} is outside [-180, 180] (degrees, counter-clockwise from "
                              f"the front)")
        if not (math.isnan(el) or -90 <= el <= 90):
            raise ConfigError(f"{path}:{n}: elevation {el} is outside [-90, 90] degrees")
        if not math.isnan(parsed["distance"]) and parsed["distance"] < 0:
            raise ConfigError(f"{path}:{n}: distance {parsed['distance']} is negative (centimetres)")
        row = tuple(parsed[k] for k in rows)
        if row in seen:
            continue  # the same annotation twice (a file appended to itself) is one source, not two
        seen.add(row)
        for k, v in zip(rows, row):
            rows[k].append(v)
    az = np.array(rows["azimuth"], dtype=np.float64)
    az = np.where(az >= 180.0, az - 360.0, az)  # DCASE writes +180 for -180: ours is [-180, 180)
    return Labels(np.array(rows["frame"], dtype=np.int64), np.array(rows["class"], dtype=np.int64),
                  np.array(rows["source"], dtype=np.int64), az, np.array(rows["elevation"], dtype=np.float64),
                  np.array(rows["distance"], dtype=np.float64) / 100.0)


@dataclass(frozen=True)
class Source:
    """One source of a window: ``key`` (class, source column, ordinal among sources of that
    class and source column at once), its labels [F] over the window's frames (NaN where
    it is not annotated) and its activity [F]."""

    key: tuple[int, int, int]
    azimuth: np.ndarray
    elevation: np.ndarray
    distance: np.ndarray
    active: np.ndarray

    @property
    def cls(self) -> int:
        return self.key[0]

    @property
    def directional(self) -> bool:
        return bool(np.isfinite(self.azimuth[self.active]).any())


def window_sources(labels: Labels, start: int, frames: int) -> list[Source]:
    """The sources of frames ``start`` .. ``start + frames - 1``, sorted by key. Rows of one
    (class, source) on one frame are followed by direction: each goes to the track whose
    last direction is nearest (ties by order), so two simultaneous non-actor sources of one
    class stay two sources for the whole window."""
    inside = (labels.frame >= start) & (labels.frame < start + frames)
    idx = np.flatnonzero(inside)
    by_key: dict[tuple[int, int], list[int]] = {}
    for i in idx:
        by_key.setdefault((int(labels.cls[i]), int(labels.source[i])), []).append(int(i))
    out = []
    for (cls, src), rows in sorted(by_key.items()):
        per_frame: dict[int, list[int]] = {}
        for i in rows:
            per_frame.setdefault(int(labels.frame[i]) - start, []).append(i)
        n_tracks = max(len(v) for v in per_frame.values())
        tracks = [np.full((4, frames), np.nan) for _ in range(n_tracks)]
        last: list[np.ndarray | None] = [None] * n_tracks
        for f in sorted(per_frame):
            rows_f = sorted(per_frame[f], key=lambda i: (labels.azimuth[i], labels.elevation[i], i))
            for i, t in _assign(rows_f, labels, last).items():
                tracks[t][:, f] = (labels.azimuth[i], labels.elevation[i], labels.distance[i], 1.0)
                u = _unit(labels.azimuth[i], labels.elevation[i])
                if u is not None:
                    last[t] = u
        for k, tr in enumerate(tracks):
            active = tr[3] == 1.0
            out.append(Source((cls, src, k), tr[0], tr[1], tr[2], active))
    return out


# a source's annotated direction moves less than this between its observations; a row
# farther from every track is another source (a fresh track) when one is free
MAX_STEP_DEG = 45.0


def _assign(rows: list[int], labels: Labels, last: list) -> dict[int, int]:
    """{row: track} for one frame's rows of one (class, source): the closest (row, track)
    pairs first, each within MAX_STEP_DEG of the track's last direction; then the rest to
    tracks never used (a source appearing), then to the nearest tracks left."""
    units = {i: _unit(labels.azimuth[i], labels.elevation[i]) for i in rows}
    pairs = sorted((float(np.degrees(np.arccos(np.clip(last[t] @ units[i], -1.0, 1.0)))), k, t, i)
                   for k, i in enumerate(rows) for t in range(len(last))
                   if last[t] is not None and units[i] is not None)
    out: dict[int, int] = {}
    for d, _, t, i in pairs:
        if d <= MAX_STEP_DEG and i not in out and t not in out.values():
            out[i] = t
    for i in rows:
        if i in out:
            continue
        free = [t for t in range(len(last)) if t not in out.values()]
        fresh = [t for t in free if last[t] is None]
        if fresh or units[i] is None:
            out[i] = (fresh or free)[0]
        else:
            out[i] = min(free, key=lambda t: -float(last[t] @ units[i]))
    return out


def _unit(az: float, el: float) -> np.ndarray | None:
    """A direction as a unit vector (elevation 0 when a set gives azimuth only), or None."""
    if not math.isfinite(az):
        return None
    return sph_to_cart(az, el if math.isfinite(el) else 0.0, 1.0)
