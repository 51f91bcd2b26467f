"""The per-scene record of a JSON shard (docs/format.md, "JSON shard"), typed.

``render`` builds a :class:`SceneRecord`; the writer stores ``to_json()``; the reader
parses it back with ``from_json``; the tools read attributes. ``to_json()`` gives the
keys in the contract's order, so the JSON bytes are those of format version 1.

Records also answer ``record["key"]`` and ``record.get("key")`` with the JSON value, as
the plain dicts of earlier releases did.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..corpus.captions import answerable_queries
from ..scene.recipe import BankWalk

# Labels in the JSON are rounded: angles to 3 decimals, distances to 4, so the HDF5
# (float32) and the JSON agree within this.
LABEL_DECIMALS = {"azimuth": 3, "elevation": 3, "distance": 4}
LABEL_ATOL = 2e-3
LABEL_KEYS = ("azimuth", "elevation", "distance")


def label_list(a: np.ndarray, decimals: int = 3) -> list:
    """A label row as JSON: rounded numbers, null for NaN."""
    # Python floats, not numpy scalars, through the loop: the same numbers, twice as fast
    return [round(v, decimals) if math.isfinite(v) else None for v in np.asarray(a).tolist()]


def label_array(values) -> np.ndarray:
    """A JSON label row back to float64 with NaN for null."""
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


class _JsonMapping:
    """``record["key"]`` / ``record.get("key")`` on the JSON form (compatibility)."""

    @cached_property
    def _json(self) -> dict:
        return self.to_json()

    def __getitem__(self, key):
        return self._json[key]

    def get(self, key, default=None):
        return self._json.get(key, default)

    def __contains__(self, key) -> bool:
        return key in self._json

    def keys(self):
        return self._json.keys()


@dataclass(frozen=True)
class RoomRecord(_JsonMapping):
    """The room: simulated (``dims`` m, requested ``rt60`` s, ``rt60_measured`` s or None),
    or an RIR-bank room (``name``, ``bank`` path; ``dims``/``rt60`` when the bank knows them)."""

    dims: list | None = None
    rt60: float | None = None
    rt60_measured: float | None = None
    name: str | None = None
    bank: str | None = None

    @property
    def is_bank(self) -> bool:
        return self.bank is not None

    def to_json(self) -> dict:
        if self.is_bank:
            return {"name": self.name, "bank": self.bank, "dims": self.dims, "rt60": self.rt60,
                    "rt60_measured": self.rt60_measured}
        return {"dims": self.dims, "rt60": self.rt60, "rt60_measured": self.rt60_measured}

    @classmethod
    def from_json(cls, d: dict | None) -> "RoomRecord":
        d = d or {}
        return cls(d.get("dims"), d.get("rt60"), d.get("rt60_measured"), d.get("name"), d.get("bank"))


@dataclass(frozen=True)
class ArrayRecord(_JsonMapping):
    """The receiver: ``format`` (its name); ``centre`` [x, y, z] room frame m and ``yaw``
    degrees (None when a measured bank does not know them); ``side`` m (mic4);
    ``mic_positions`` [[x, y, z]] array frame m. Only for receivers that have them (absent
    otherwise): ``patterns`` and ``orientations`` [[azimuth, elevation]] degrees of a custom
    array's capsules, ``baffle`` of a sphere array, ``hrtf`` (the SOFA file, as the plan
    names it) and ``interpolation`` of a binaural receiver."""

    format: str
    centre: list | None = None
    yaw: float | None = None
    side: float | None = None
    mic_positions: list | None = None
    patterns: list | None = None
    orientations: list | None = None
    baffle: str | None = None
    hrtf: str | None = None
    interpolation: str | None = None

    @classmethod
    def of(cls, pose, centre, yaw, mic_positions) -> "ArrayRecord":
        """The record of a scene's :class:`~tsel_data.receivers.ArrayPose` (``centre`` and
        ``yaw`` as the scene knows them)."""
        return cls(pose.format, centre, yaw, pose.side, mic_positions,
                   None if pose.patterns is None else list(pose.patterns),
                   None if pose.orientations is None else [list(o) for o in pose.orientations],
                   pose.baffle, pose.hrtf, pose.interpolation)

    def to_json(self) -> dict:
        d = {"format": self.format, "centre": self.centre, "yaw": self.yaw, "side": self.side,
             "mic_positions": self.mic_positions}
        for key in _ARRAY_OPTIONAL:  # only when set: records of mic4/foa keep format 1's bytes
            if getattr(self, key) is not None:
                d[key] = getattr(self, key)
        return d

    @classmethod
    def from_json(cls, d: dict | None) -> "ArrayRecord":
        d = d or {}
        return cls(d.get("format", ""), d.get("centre"), d.get("yaw"), d.get("side"), d.get("mic_positions"),
                   *(d.get(k) for k in _ARRAY_OPTIONAL))


_ARRAY_OPTIONAL = ("patterns", "orientations", "baffle", "hrtf", "interpolation")


@dataclass(frozen=True)
class SourceRecord(_JsonMapping):
    """One source of a scene: its clip, how it was placed, its labels and level.

    azimuth, elevation: [F] degrees, distance: [F] metres (None where positionless);
    active: [F] bool; tir_db, gain_db: dB; level_dbfs: active-frame RMS of its image
    in the mixture (mean over mic channels; W for FOA). pairing (``target``, ``random``,
    ``hard``, ``easy``, ``same-kind``) and caption_similarity (of its captions to the query
    caption): only in records of datasets with extended queries (docs/queries.md), else None.
    """

    role: str
    clip_id: str | None = None
    audio: str | None = None
    captions: list = field(default_factory=list)
    spatial: str = "directional"
    moving: bool = False
    position: list | None = None
    path: list | None = None
    bank: BankWalk | None = None
    azimuth: list = field(default_factory=list)
    elevation: list = field(default_factory=list)
    distance: list = field(default_factory=list)
    active: list = field(default_factory=list)
    tir_db: float | None = None
    gain_db: float | None = None
    level_dbfs: float | None = None
    pairing: str | None = None
    caption_similarity: float | None = None
    power_db: float | None = None

    def to_json(self) -> dict:
        d = {"role": self.role, "clip_id": self.clip_id, "audio": self.audio, "captions": list(self.captions),
             "spatial": self.spatial, "moving": self.moving, "position": self.position, "path": self.path,
             "bank": None if self.bank is None else self.bank.to_dict(),
             "azimuth": self.azimuth, "elevation": self.elevation, "distance": self.distance,
             "active": self.active, "tir_db": self.tir_db, "gain_db": self.gain_db, "level_dbfs": self.level_dbfs}
        if self.pairing is not None:  # extended queries only: default records keep format 1's bytes
            d["pairing"] = self.pairing
            d["caption_similarity"] = self.caption_similarity
        if self.power_db is not None:  # levels that follow distance only
            d["power_db"] = self.power_db
        return d

    @classmethod
    def from_json(cls, d: dict, k: int = 0) -> "SourceRecord":
        bank = d.get("bank")
        return cls(role=d.get("role") or ("target" if k == 0 else "interferer"), clip_id=d.get("clip_id"),
                   audio=d.get("audio"), captions=list(d.get("captions") or []),
                   spatial=d.get("spatial", "directional"), moving=bool(d.get("moving", False)),
                   position=d.get("position"), path=d.get("path"),
                   bank=None if bank is None else BankWalk.from_dict(bank),
                   azimuth=d.get("azimuth") or [], elevation=d.get("elevation") or [],
                   distance=d.get("distance") or [], active=d.get("active") or [], tir_db=d.get("tir_db"),
                   gain_db=d.get("gain_db"), level_dbfs=d.get("level_dbfs"), pairing=d.get("pairing"),
                   caption_similarity=d.get("caption_similarity"), power_db=d.get("power_db"))

    def labels(self, key: str) -> np.ndarray:
        """One label row (``azimuth``, ``elevation`` or ``distance``) as float64 [F], NaN for null."""
        return label_array(getattr(self, key))


@dataclass(frozen=True)
class NoiseRecord(_JsonMapping):
    """One unlabelled part of a scene (``[noise]``): ``kind`` (``ambience``, ``diffuse``,
    ``babble``, ``sensor``), ``snr_db`` against the target's omni energy over the scene
    (None for sensor noise set in dBFS), ``level_dbfs`` (RMS of its level channels in the
    mixture), and what it is: ``file`` and ``offset`` (samples) of an ambience recording,
    ``spectrum`` of diffuse noise, ``clips`` [[audio, offset s]] and ``directions``
    [[azimuth, elevation]] of babble."""

    kind: str
    snr_db: float | None = None
    level_dbfs: float | None = None
    file: str | None = None
    offset: int | None = None
    spectrum: str | None = None
    clips: list | None = None
    directions: list | None = None

    @classmethod
    def of(cls, item, snr_db: float | None, level_dbfs: float) -> "NoiseRecord":
        """The record of a recipe's :class:`~tsel_data.scene.recipe.NoiseItem` (names as the
        plan gives them) with what was measured in the mix."""
        return cls(str(item.kind), snr_db, level_dbfs, item.file, item.offset, item.spectrum,
                   [list(c) for c in item.clips] or None, [list(d) for d in item.directions] or None)

    def to_json(self) -> dict:
        d = {"kind": self.kind, "snr_db": self.snr_db, "level_dbfs": self.level_dbfs}
        for key in ("file", "offset", "spectrum", "clips", "directions"):
            if getattr(self, key) is not None:
                d[key] = getattr(self, key)
        return d

    @classmethod
    def from_json(cls, d: dict) -> "NoiseRecord":
        return cls(d.get("kind", ""), d.get("snr_db"), d.get("level_dbfs"), d.get("file"), d.get("offset"),
                   d.get("spectrum"), d.get("clips"), d.get("directions"))


@dataclass(frozen=True)
class LevelsRecord(_JsonMapping):
    """``target_level_dbfs`` requested, ``peak`` of the mixture, ``normalisation_db``
    (<= 0: the gain applied to the whole mix to avoid clipping)."""

    target_level_dbfs: float | None = None
    peak: float | None = None
    normalisation_db: float | None = None

    def to_json(self) -> dict:
        return {"target_level_dbfs": self.target_level_dbfs, "peak": self.peak,
                "normalisation_db": self.normalisation_db}

    @classmethod
    def from_json(cls, d: dict | None) -> "LevelsRecord":
        d = d or {}
        return cls(d.get("target_level_dbfs"), d.get("peak"), d.get("normalisation_db"))


@dataclass(frozen=True)
class RecordingRecord(_JsonMapping):
    """Where a recorded scene comes from (docs/recorded.md): the ``dataset``, the recording
    ``audio`` and its label file ``metadata`` (relative to the corpus folder) with their
    ``sha256``, the window (``start`` s, ``start_frame`` and ``frames`` label frames), the
    ``fold`` and ``room`` its name says, and per source (target first) its ``classes``
    (names), ``class_indices``, ``actors`` (the CSV's source column) and ``events`` (the
    ordinal among sources of one class and actor at once)."""

    dataset: str
    audio: str
    metadata: str
    sha256: str
    metadata_sha256: str
    start: float
    start_frame: int
    frames: int
    fold: int | None = None
    room: int | None = None
    classes: list = field(default_factory=list)
    class_indices: list = field(default_factory=list)
    actors: list = field(default_factory=list)
    events: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {"dataset": self.dataset, "audio": self.audio, "metadata": self.metadata, "sha256": self.sha256,
                "metadata_sha256": self.metadata_sha256, "start": self.start, "start_frame": self.start_frame,
                "frames": self.frames, "fold": self.fold, "room": self.room, "classes": list(self.classes),
                "class_indices": list(self.class_indices), "actors": list(self.actors), "events": list(self.events)}

    @classmethod
    def from_json(cls, d: dict) -> "RecordingRecord":
        return cls(d.get("dataset", ""), d.get("audio", ""), d.get("metadata", ""), d.get("sha256", ""),
                   d.get("metadata_sha256", ""), d.get("start", 0.0), d.get("start_frame", 0), d.get("frames", 0),
                   d.get("fold"), d.get("room"), list(d.get("classes") or []), list(d.get("class_indices") or []),
                   list(d.get("actors") or []), list(d.get("events") or []))


@dataclass(frozen=True)
class SceneRecord(_JsonMapping):
    """Everything known about one rendered scene (docs/format.md); source 0 is the target.

    The query fields (docs/queries.md) are written only by datasets with extended queries
    (``query_wanted`` is then set); other records read as ``query_type = "caption"``,
    ``pairing = "random"``, so every record answers them. ``receivers``: the further
    receivers of a dataset heard by several (``scene.receivers``), each an ArrayRecord
    (same centre and yaw as ``array``).
    """

    scene_id: str
    split: str
    index: int
    seed: int | None
    scenario: str
    query: str
    motion: str
    rir_method: str
    room: RoomRecord
    array: ArrayRecord
    sources: tuple[SourceRecord, ...]
    levels: LevelsRecord
    query_type: str = "caption"
    query_relation: str | None = None
    query_evidence: dict | None = None
    query_alternatives: list | None = None
    pairing: str = "random"
    query_wanted: str | None = None
    receivers: tuple = ()  # ArrayRecords of further receivers heard in the same pass
    noise: tuple = ()  # NoiseRecords: what else the scene holds, unlabelled
    recording: RecordingRecord | None = None  # a scene cut from a real recording (docs/recorded.md)

    @property
    def recorded(self) -> bool:
        return self.recording is not None

    @property
    def target(self) -> SourceRecord:
        return self.sources[0]

    @property
    def extended(self) -> bool:
        """Whether the record carries the query fields (extended queries, docs/queries.md)."""
        return self.query_wanted is not None

    def query_pool(self, caption_similarity: float = 0.5) -> list[str]:
        """Every query as true and unambiguous as ``query``: the recorded alternatives
        (other wordings of the same relation, or the captions that pass the dataset's
        own similarity guard), or for records without them the target's captions that
        pass the word-set and the lexicon guard ``caption_similarity`` against every
        other source (:func:`~tsel_data.corpus.captions.answerable_queries`)."""
        if self.extended:
            return list(self.query_alternatives or ()) or [self.query]
        return answerable_queries(self.sources[0].captions, [s.captions for s in self.sources[1:]],
                                  caption_similarity) or [self.query]

    def to_json(self) -> dict:
        d = {"scene_id": self.scene_id, "split": self.split, "index": self.index, "seed": self.seed,
             "scenario": self.scenario, "query": self.query}
        if self.extended:
            d.update(query_type=self.query_type, query_relation=self.query_relation,
                     query_evidence=self.query_evidence, query_wanted=self.query_wanted, pairing=self.pairing,
                     query_alternatives=self.query_alternatives)
        d.update(motion=self.motion, rir_method=self.rir_method, room=self.room.to_json(), array=self.array.to_json(),
                 sources=[s.to_json() for s in self.sources], levels=self.levels.to_json())
        if self.receivers:  # only with scene.receivers: other records keep format 1's bytes
            d["receivers"] = [r.to_json() for r in self.receivers]
        if self.noise:  # only with [noise]
            d["noise"] = [n.to_json() for n in self.noise]
        if self.recording is not None:  # recorded scenes only
            d["recording"] = self.recording.to_json()
        return d

    @classmethod
    def from_json(cls, d: dict) -> "SceneRecord":
        """Parse a record; keys a record lacks take their 'unknown' value (None, "unknown")."""
        return cls(scene_id=d.get("scene_id", ""), split=d.get("split", ""), index=d.get("index", -1),
                   seed=d.get("seed"), scenario=d.get("scenario", "unknown"), query=d.get("query", ""),
                   motion=d.get("motion", "unknown"), rir_method=d.get("rir_method", "unknown"),
                   room=RoomRecord.from_json(d.get("room")), array=ArrayRecord.from_json(d.get("array")),
                   sources=tuple(SourceRecord.from_json(s, k) for k, s in enumerate(d.get("sources") or [])),
                   levels=LevelsRecord.from_json(d.get("levels")), query_type=d.get("query_type") or "caption",
                   query_relation=d.get("query_relation"), query_evidence=d.get("query_evidence"),
                   query_alternatives=d.get("query_alternatives"), pairing=d.get("pairing") or "random",
                   query_wanted=d.get("query_wanted"),
                   receivers=tuple(ArrayRecord.from_json(r) for r in d.get("receivers") or ()),
                   noise=tuple(NoiseRecord.from_json(n) for n in d.get("noise") or ()),
                   recording=None if d.get("recording") is None else RecordingRecord.from_json(d["recording"]))
