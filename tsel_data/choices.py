"""Every set of allowed values, declared once.

Config validation, recipe validation, the CLI's ``click.Choice`` lists and the docs
all take their choices from these enumerations. Members are strings (``StrEnum``), so
they compare equal to, hash like and serialise as their plain values: a recipe or
record that holds ``Role.TARGET`` writes ``"target"``.
"""
from __future__ import annotations

import re
from enum import StrEnum

# a split's name: it names a folder of the dataset and of its exports, so a plain name only
SPLIT_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")


class ReceiverModel(StrEnum):
    """How a receiver's channels hear a wave (receivers/spec.py; acoustics/capsules.py).
    The receivers themselves are a registry (tsel_data.receivers), not a set of values."""

    SPACED = "spaced"
    AMBISONIC = "ambisonic"
    SPHERE = "sphere"
    HRTF = "hrtf"
    MATRIX = "matrix"


class LevelModel(StrEnum):
    """``scene.levels``: interferers at a target-to-interferer ratio, or levels that follow distance."""

    TIR = "tir"
    DISTANCE = "distance"


class NoiseSpectrum(StrEnum):
    """``noise.diffuse``: the spectrum of a simulated diffuse noise field."""

    NONE = "none"
    WHITE = "white"
    PINK = "pink"
    BROWN = "brown"
    CLIP = "clip"


class SensorLevel(StrEnum):
    """``noise.sensor``: sensor noise off, at a level in dBFS, or at an SNR."""

    NONE = "none"
    DBFS = "dbfs"
    SNR = "snr"


class HardwareProfile(StrEnum):
    """``hardware.profile``: the microphones as built, typical values for every key left unset
    (config/schema.py ``HARDWARE_PROFILES``), or none (ideal capsules unless keys are set)."""

    NONE = "none"
    MEMS = "mems"
    MEASUREMENT = "measurement"


class SegmentRule(StrEnum):
    """``noise.ambience_segments``: which stretch of an ambience recording a scene hears."""

    RANDOM = "random"
    CONSECUTIVE = "consecutive"


class Baffle(StrEnum):
    """``array.baffle``: capsules of a sphere array on a rigid sphere (scattering) or open."""

    RIGID = "rigid"
    OPEN = "open"


class Pattern(StrEnum):
    """First-order capsule patterns (receivers/spec.py, PATTERN_ALPHA)."""

    OMNI = "omni"
    SUBCARDIOID = "subcardioid"
    CARDIOID = "cardioid"
    SUPERCARDIOID = "supercardioid"
    HYPERCARDIOID = "hypercardioid"
    FIGURE8 = "figure8"


class HrtfInterpolation(StrEnum):
    """``array.hrtf_interpolation``: each image source through the nearest measured HRIR,
    or the HRIRs of the measured triangle around its direction, weighted."""

    NEAREST = "nearest"
    INTERPOLATED = "interpolated"


class RirMethod(StrEnum):
    """Shoebox RIR simulators (docs/acoustics.md). Bank scenes record ``"bank"`` instead."""

    HYBRID = "hybrid"
    ISM = "ism"
    PYROOMACOUSTICS = "pyroomacoustics"


class Scenario(StrEnum):
    """The paper's two scene types: every source directional, or the first interferer additive."""

    TWO_DIRECTIONAL = "two-directional"
    DIRECTIONAL_ADDITIVE = "directional+additive"


class Additive(StrEnum):
    """``scene.additive``: how the additive source of ``directional+additive`` is heard."""

    COHERENT = "coherent"
    DIFFUSE = "diffuse"


class Role(StrEnum):
    TARGET = "target"
    INTERFERER = "interferer"


class Spatial(StrEnum):
    """How a source is rendered: through the room, added to every channel unspatialised, or as a
    diffuse field at the array (``scene.additive = "diffuse"``)."""

    DIRECTIONAL = "directional"
    ADDITIVE = "additive"
    DIFFUSE = "diffuse"


class NoiseKind(StrEnum):
    """What a scene hears besides its sources (``[noise]``; render/noise.py ``NOISE_KINDS``)."""

    AMBIENCE = "ambience"
    DIFFUSE = "diffuse"
    BABBLE = "babble"
    SENSOR = "sensor"


class Localizer(StrEnum):
    """How ``tsel verify`` reads a receiver's directions (receivers/spec.py ``localizer``):
    steered response power, the intensity vector of first-order ambisonics, the mid/side
    level difference of the DCASE stereo pair, or none (binaural)."""

    SRP = "srp"
    INTENSITY = "intensity"
    MID_SIDE = "mid-side"
    NONE = ""


class Motion(StrEnum):
    """``scene.motion``: every directional source static, moving, or each moving with a probability."""

    STATIC = "static"
    MOVING = "moving"
    MIXED = "mixed"


class PathKind(StrEnum):
    """How a simulated moving source moves: around the array, or on a straight pass."""

    ARC = "arc"
    LINE = "line"


class CorpusFormat(StrEnum):
    """Manifest formats (tsel_data/manifests); ``auto`` detects them."""

    AUDIOCAPS = "audiocaps"
    CLOTHO = "clotho"
    WAVCAPS = "wavcaps"
    PLAIN = "plain"
    AUTO = "auto"


class RecordedSet(StrEnum):
    """``recorded.dataset``: recorded SELD datasets in the DCASE layout (corpus/seld.py)."""

    NONE = "none"
    STARSS23 = "starss23"
    STARSS22 = "starss22"
    TAU_NIGENS_2020 = "tau-nigens-2020"
    TAU_NIGENS_2021 = "tau-nigens-2021"
    DCASE2025_STEREO = "dcase2025-stereo"
    CUSTOM = "custom"


class CheckLevel(StrEnum):
    """``corpus.check``: how much of each clip is verified before planning."""

    FULL = "full"
    DRAWN = "drawn"
    HEADER = "header"
    EXISTS = "exists"
    NONE = "none"


class Fingerprint(StrEnum):
    """``corpus.fingerprint``: what a shard's seal says of each input it read (store/integrity.py)."""

    STAT = "stat"
    HASH = "hash"


class BadClipPolicy(StrEnum):
    SKIP = "skip"
    FAIL = "fail"


class MissingClipPolicy(StrEnum):
    """What ``tsel generate --from REL`` does with a scene whose clip is missing."""

    SKIP = "skip"
    SUBSTITUTE = "substitute"


class Executor(StrEnum):
    """Where shards render (runtime/runner.py)."""

    LOCAL = "local"
    DASK = "dask"
    DASK_LOCAL = "dask-local"


class AudioCoding(StrEnum):
    """How shards store audio (``output.audio``; store/codings.py)."""

    FLOAT32 = "float32"
    INT16 = "int16"
    FLAC = "flac"


class WavSubtype(StrEnum):
    """WAV sample formats of ``tsel export``."""

    PCM_16 = "PCM_16"
    PCM_24 = "PCM_24"
    FLOAT = "FLOAT"


class QueryType(StrEnum):
    """``scene.query``: what a scene's query is (docs/queries.md)."""

    CAPTION = "caption"
    RELATIONAL = "relational"
    COMPOSITE = "composite"


class Relation(StrEnum):
    """Relations a relational or composite query states, each decided on the rendered scene."""

    LOUDEST = "loudest"
    QUIETEST = "quietest"
    NEAREST = "nearest"
    FARTHEST = "farthest"
    STARTS_FIRST = "starts_first"
    STARTS_LAST = "starts_last"
    MOVING = "moving"
    HEARD_AT = "heard_at"


class Pairing(StrEnum):
    """``scene.pairing``: how similar an interferer's captions are to the query caption."""

    RANDOM = "random"
    HARD = "hard"
    EASY = "easy"


class SimilarityMeasure(StrEnum):
    """``scene.similarity``: the caption similarity of the guard, pairing and same-kind distractors
    (``none``: no guard, the paper's random pairing)."""

    LEXICON = "lexicon"
    WORDS = "words"
    TFIDF = "tfidf"
    EMBEDDINGS = "embeddings"
    NONE = "none"


def values(choices) -> tuple[str, ...]:
    """The plain string values of an enumeration (or of a tuple of names), in declaration order."""
    return tuple(m.value if isinstance(m, StrEnum) else str(m) for m in choices)
