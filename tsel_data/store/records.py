"""The per-scene record of a JSON shard (docs/format.md, "JSON shard"), typed.

``render`` builds a :class:`SceneRecord`; the writer stores ``to_json()``; the reader
parses it back with ``from_json``; the tools read attributes. ``to_json()`` gives the
keys in the contract's order, so the JSON bytes are those of format version 1.

Records also answer ``record["key"]`` and ``record.get("key")`` with the JSON value, as
the plain dicts of earlier releases did.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..corpus.captions import answerable_queries
from ..core.jsonable import JsonFields, key, unset
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


def _encoded(v):
    return None if v is None else v.to_json()


@dataclass(frozen=True)
class RoomRecord(JsonFields, _JsonMapping):
    """The room: simulated (``dims`` m, requested ``rt60`` s, ``rt60_measured`` s or None),
    or an RIR-bank room (``name``, ``bank`` path; ``dims``/``rt60`` when the bank knows them).
    ``volume_m3`` and ``floor_area_m2``: with ``output.descriptors``, where the dims are known."""

    name: str | None = key(None, omit=lambda r: not r.is_bank)
    bank: str | None = key(None, omit=lambda r: not r.is_bank)
    dims: list | None = None
    rt60: float | None = None
    rt60_measured: float | None = None
    # with output.descriptors (absent otherwise): the room's size, where its dims are known
    volume_m3: float | None = key(None, omit=unset("volume_m3"))
    floor_area_m2: float | None = key(None, omit=unset("floor_area_m2"))

    @property
    def is_bank(self) -> bool:
        return self.bank is not None


# --- the microphones as built ([hardware]; docs/format.md "Hardware") ---------------------------


@dataclass(frozen=True)
class HardwareRecord(JsonFields, _JsonMapping):
    """One receiver's microphones as drawn for the scene (``[hardware]``; C capsules, D
    devices): ``profile``; per capsule ``gain_db``, ``delay_us`` (µs), ``highpass_hz`` (0:
    none) of ``highpass_order``, ``tilt_db`` (dB per octave about 1 kHz), ``self_noise_dba``
    (dB SPL A-weighted, absent: none) and ``self_noise_dbfs`` (the same in the audio,
    A-weighted, at ``sensitivity_dbfs``, the level of 94 dB SPL); ``devices`` [C] (each
    capsule's device), ``clock_offset_us`` and ``clock_ppm`` [D] (each device's lag behind
    the first at the start and its growth, µs per second), absent for one device;
    ``response_file``: a measured response's file, absent without."""

    profile: str = key(missing="none")
    gain_db: list = key(default_factory=list, decode=lambda v: list(v or []))
    delay_us: list = key(default_factory=list, decode=lambda v: list(v or []))
    highpass_hz: list = key(default_factory=list, decode=lambda v: list(v or []))
    highpass_order: int = 2
    tilt_db: list = key(default_factory=list, decode=lambda v: list(v or []))
    self_noise_dba: list | None = key(None, omit=unset("self_noise_dba"))
    self_noise_dbfs: list | None = key(None, omit=unset("self_noise_dbfs"))
    sensitivity_dbfs: float | None = None
    devices: list | None = key(None, omit=unset("devices"))
    clock_offset_us: list | None = key(None, omit=unset("clock_offset_us"))
    clock_ppm: list | None = key(None, omit=unset("clock_ppm"))
    response_file: str | None = key(None, omit=unset("response_file"))

    @classmethod
    def of(cls, hw) -> "HardwareRecord":
        """The record of a recipe's :class:`~tsel_data.scene.hardware.Hardware`."""
        def lst(v):
            return None if v is None else list(v)

        return cls(hw.profile, list(hw.gain_db), list(hw.delay_us), list(hw.highpass_hz), hw.highpass_order,
                   list(hw.tilt_db), lst(hw.self_noise_dba), lst(hw.self_noise_dbfs()), hw.sensitivity_dbfs,
                   lst(hw.devices), lst(hw.clock_offset_us), lst(hw.clock_ppm), hw.response_file)

    @property
    def n_channels(self) -> int:
        return len(self.gain_db)

    @property
    def response(self):
        """None: a measured response's table is in the recipe (the record names its file), so
        what undoes the hardware from a record (dsp/hardware.py ``unhear``) leaves it."""
        return None

    def channel_clocks(self) -> tuple[tuple, tuple]:
        """(offset µs [C], ppm [C]): each capsule's device clock."""
        dev = self.devices or [0] * self.n_channels
        off, ppm = self.clock_offset_us or [0.0], self.clock_ppm or [0.0]
        return tuple(off[d] for d in dev), tuple(ppm[d] for d in dev)


@dataclass(frozen=True)
class ArrayRecord(JsonFields, _JsonMapping):
    """The receiver: ``format`` (its name); ``centre`` [x, y, z] room frame m and ``yaw``
    degrees (None when a measured bank does not know them); ``side`` m (mic4);
    ``mic_positions`` [[x, y, z]] array frame m. Only for receivers that have them (absent
    otherwise): ``patterns`` and ``orientations`` [[azimuth, elevation]] degrees of a custom
    array's capsules, ``baffle`` of a sphere array, ``hrtf`` (the SOFA file, as the plan
    names it) and ``interpolation`` of a binaural receiver; ``hardware``: its microphones
    as built (:class:`HardwareRecord`), only with ``[hardware]``."""

    format: str = key(missing="")
    centre: list | None = None
    yaw: float | None = None
    side: float | None = None
    mic_positions: list | None = None
    patterns: list | None = key(None, omit=unset("patterns"))
    orientations: list | None = key(None, omit=unset("orientations"))
    baffle: str | None = key(None, omit=unset("baffle"))
    hrtf: str | None = key(None, omit=unset("hrtf"))
    interpolation: str | None = key(None, omit=unset("interpolation"))
    hardware: HardwareRecord | None = key(None, omit=unset("hardware"), encode=_encoded,
                                          decode=lambda v: None if v is None else HardwareRecord.from_json(v))

    @classmethod
    def of(cls, pose, centre, yaw, mic_positions, hardware: HardwareRecord | None = None) -> "ArrayRecord":
        """The record of a scene's :class:`~tsel_data.receivers.ArrayPose` (``centre`` and
        ``yaw`` as the scene knows them) and its ``hardware`` record, if any."""
        return cls(pose.format, centre, yaw, pose.side, mic_positions,
                   None if pose.patterns is None else list(pose.patterns),
                   None if pose.orientations is None else [list(o) for o in pose.orientations],
                   pose.baffle, pose.hrtf, pose.interpolation, hardware)


def _number(v) -> bool:
    return v is None or isinstance(v, (int, float)) and not isinstance(v, bool)


def _acoustics(v: dict | None) -> dict | None:
    """A source's ``acoustics`` as read: each descriptor a number or null, the octave
    bands an object of them (ValueError naming the key otherwise: a damaged record)."""
    for name, x in (v or {}).items():
        bands = x if name == "t30_bands_s" and isinstance(x, dict) else {name: x}
        bad = next((b for b, y in bands.items() if not _number(y)), None)
        if bad is not None:
            raise ValueError(f"key 'acoustics' holds {name} = {str(x)[:40]!r}, not a number")
    return v


def _no_pairing(r) -> bool:
    return r.pairing is None  # extended queries only: default records keep format 1's bytes


@dataclass(frozen=True)
class SourceRecord(JsonFields, _JsonMapping):
    """One source of a scene: its clip, how it was placed, its labels and level.

    azimuth, elevation: [F] degrees, distance: [F] metres (None where positionless);
    active: [F] bool; tir_db, gain_db: dB; level_dbfs: active-frame RMS of its image
    in the mixture (mean over mic channels; W for FOA). acoustics ({drr_db, c50_db, edt_s,
    t30_s, t30_bands_s}, acoustics/descriptors.py) and motion (scene/motion.py): with
    ``output.descriptors``, for directional sources. pairing (``target``, ``random``,
    ``hard``, ``easy``, ``same-kind``) and caption_similarity (of its captions to the query
    caption): only in records of datasets with extended queries (docs/queries.md), else None.
    """

    role: str
    clip_id: str | None = None
    audio: str | None = None
    captions: list = key(default_factory=list, encode=list, decode=lambda v: list(v or []))
    spatial: str = "directional"
    moving: bool = key(False, decode=bool)
    position: list | None = None
    path: list | None = None
    bank: BankWalk | None = key(None, encode=lambda b: None if b is None else b.to_dict(),
                                decode=lambda v: None if v is None else BankWalk.from_dict(v))
    azimuth: list = key(default_factory=list, decode=lambda v: v or [])
    elevation: list = key(default_factory=list, decode=lambda v: v or [])
    distance: list = key(default_factory=list, decode=lambda v: v or [])
    active: list = key(default_factory=list, decode=lambda v: v or [])
    tir_db: float | None = None
    gain_db: float | None = None
    level_dbfs: float | None = None
    pairing: str | None = key(None, omit=_no_pairing)
    caption_similarity: float | None = key(None, omit=_no_pairing)
    power_db: float | None = key(None, omit=unset("power_db"))  # levels that follow distance only
    # with output.descriptors (absent otherwise): acoustic/descriptors.py, scene/motion.py
    acoustics: dict | None = key(None, omit=unset("acoustics"), decode=_acoustics)
    motion: str | None = key(None, omit=unset("motion"))

    @classmethod
    def of(cls, source, azimuth: list, elevation: list, distance: list, active: list, gain_db: float,
           level_dbfs: float, pairing: str | None = None, caption_similarity: float | None = None,
           acoustics: dict | None = None, motion: str | None = None) -> "SourceRecord":
        """The record of a recipe's :class:`~tsel_data.scene.recipe.Source` (its clip, placement
        and requested levels, as planned) with what was rendered: labels, gain and level."""
        return cls(role=source.role, clip_id=source.clip_id, audio=source.audio, captions=list(source.captions),
                   spatial=source.spatial, moving=source.moving,
                   position=None if source.position is None else list(source.position),
                   path=None if not source.path else [list(kn) for kn in source.path], bank=source.bank,
                   azimuth=azimuth, elevation=elevation, distance=distance, active=active, tir_db=source.tir_db,
                   gain_db=gain_db, level_dbfs=level_dbfs, pairing=pairing, caption_similarity=caption_similarity,
                   power_db=source.power_db, acoustics=acoustics, motion=motion)

    @classmethod
    def from_json(cls, d: dict, k: int = 0) -> "SourceRecord":
        """``k``: the source's place in its scene (a record without roles: 0 is the target)."""
        return super().from_json({**d, "role": d.get("role") or ("target" if k == 0 else "interferer")})

    def labels(self, key: str) -> np.ndarray:
        """One label row (``azimuth``, ``elevation`` or ``distance``) as float64 [F], NaN for null."""
        return label_array(getattr(self, key))


@dataclass(frozen=True)
class NoiseRecord(JsonFields, _JsonMapping):
    """One unlabelled part of a scene (``[noise]``): ``kind`` (``ambience``, ``diffuse``,
    ``babble``, ``sensor``), ``snr_db`` against the target's omni energy over the scene
    (None for sensor noise set in dBFS), ``level_dbfs`` (RMS of its level channels in the
    mixture), and what it is: ``file`` and ``offset`` (samples) of an ambience recording,
    ``spectrum`` of diffuse noise, ``clips`` [[audio, offset s]] and ``directions``
    [[azimuth, elevation]] of babble."""

    kind: str = key(missing="")
    snr_db: float | None = None
    level_dbfs: float | None = None
    file: str | None = key(None, omit=unset("file"))
    offset: int | None = key(None, omit=unset("offset"))
    spectrum: str | None = key(None, omit=unset("spectrum"))
    clips: list | None = key(None, omit=unset("clips"))
    directions: list | None = key(None, omit=unset("directions"))

    @classmethod
    def of(cls, item, snr_db: float | None, level_dbfs: float) -> "NoiseRecord":
        """The record of a recipe's :class:`~tsel_data.scene.recipe.NoiseItem` (names as the
        plan gives them) with what was measured in the mix."""
        return cls(str(item.kind), snr_db, level_dbfs, item.file, item.offset, item.spectrum,
                   [list(c) for c in item.clips] or None, [list(d) for d in item.directions] or None)


@dataclass(frozen=True)
class LevelsRecord(JsonFields, _JsonMapping):
    """``target_level_dbfs`` requested, ``peak`` of the mixture, ``normalisation_db``
    (<= 0: the gain applied to the whole mix to avoid clipping)."""

    target_level_dbfs: float | None = None
    peak: float | None = None
    normalisation_db: float | None = None


@dataclass(frozen=True)
class RecordingRecord(JsonFields, _JsonMapping):
    """Where a recorded scene comes from (docs/recorded.md): the ``dataset``, the recording
    ``audio`` and its label file ``metadata`` (relative to the corpus folder) with their
    ``sha256``, the window (``start`` s, ``start_frame`` and ``frames`` label frames), the
    ``fold`` and ``room`` its name says, and per source (target first) its ``classes``
    (names), ``class_indices``, ``actors`` (the CSV's source column) and ``events`` (the
    ordinal among sources of one class and actor at once)."""

    dataset: str = key(missing="")
    audio: str = key(missing="")
    metadata: str = key(missing="")
    sha256: str = key(missing="")
    metadata_sha256: str = key(missing="")
    start: float = key(missing=0.0)
    start_frame: int = key(missing=0)
    frames: int = key(missing=0)
    fold: int | None = None
    room: int | None = None
    classes: list = key(default_factory=list, encode=list, decode=lambda v: list(v or []))
    class_indices: list = key(default_factory=list, encode=list, decode=lambda v: list(v or []))
    actors: list = key(default_factory=list, encode=list, decode=lambda v: list(v or []))
    events: list = key(default_factory=list, encode=list, decode=lambda v: list(v or []))


def _plain(r) -> bool:
    return r.query_wanted is None  # the query fields: extended queries and recorded scenes only


@dataclass(frozen=True, kw_only=True)
class SceneRecord(JsonFields, _JsonMapping):
    """Everything known about one rendered scene (docs/format.md); source 0 is the target.

    The query fields (docs/queries.md) are written only by datasets with extended queries
    (``query_wanted`` is then set); other records read as ``query_type = "caption"``,
    ``pairing = "random"``, so every record answers them. ``receivers``: the further
    receivers of a dataset heard by several (``scene.receivers``), each an ArrayRecord
    (same centre and yaw as ``array``). Fields are in the JSON's key order.
    """

    scene_id: str = key(missing="")
    split: str = key(missing="")
    index: int = key(missing=-1)
    seed: int | None = key(missing=None)
    scenario: str = key(missing="unknown")
    query: str = key(missing="")
    query_type: str = key("caption", omit=_plain, decode=lambda v: v or "caption")
    query_relation: str | None = key(None, omit=_plain)
    query_evidence: dict | None = key(None, omit=_plain)
    query_wanted: str | None = key(None, omit=_plain)
    pairing: str = key("random", omit=_plain, decode=lambda v: v or "random")
    query_alternatives: list | None = key(None, omit=_plain)
    motion: str = key(missing="unknown")
    rir_method: str = key(missing="unknown")
    room: RoomRecord = key(encode=_encoded, decode=RoomRecord.from_json, missing=RoomRecord())
    array: ArrayRecord = key(encode=_encoded, decode=ArrayRecord.from_json, missing=ArrayRecord(""))
    sources: tuple[SourceRecord, ...] = key(
        encode=lambda v: [s.to_json() for s in v], missing=(),
        decode=lambda v: tuple(SourceRecord.from_json(s, k) for k, s in enumerate(v or [])))
    levels: LevelsRecord = key(encode=_encoded, decode=LevelsRecord.from_json, missing=LevelsRecord())
    # further receivers heard in the same pass (scene.receivers), ArrayRecords
    receivers: tuple = key((), omit=lambda r: not r.receivers, encode=lambda v: [a.to_json() for a in v],
                           decode=lambda v: tuple(ArrayRecord.from_json(a) for a in v or ()))
    # NoiseRecords ([noise]): what else the scene holds, unlabelled
    noise: tuple = key((), omit=lambda r: not r.noise, encode=lambda v: [n.to_json() for n in v],
                       decode=lambda v: tuple(NoiseRecord.from_json(n) for n in v or ()))
    # a scene cut from a real recording (docs/recorded.md)
    recording: RecordingRecord | None = key(None, omit=unset("recording"), encode=_encoded,
                                            decode=lambda v: None if v is None else RecordingRecord.from_json(v))

    @property
    def recorded(self) -> bool:
        return self.recording is not None

    def receiver(self, fmt: str) -> ArrayRecord | None:
        """The ArrayRecord of the receiver named ``fmt`` (``array`` or one of ``receivers``), or None."""
        return next((a for a in (self.array, *self.receivers) if a.format == fmt), None)

    @property
    def query_margin(self) -> float:
        """The measured margin of a relation query (its evidence's value), NaN for a caption."""
        return float((self.query_evidence or {}).get("value", math.nan))

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
