"""The config schema: every section and key, declared once.

Each field carries its unit, allowed values, range and help in ``field(metadata=...)``
(:func:`option`, :func:`dist`). Loading (load.py), the per-field checks (rules.py),
``tsel presets NAME`` (toml.py) and the key tables of docs/config.md (doc.py) are
derived from these declarations; checks across fields are written out in rules.py.
A sampled parameter is a :class:`~tsel_data.scene.distributions.Dist`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

from ..choices import (Additive, AudioCoding, BadClipPolicy, Baffle, CheckLevel, CorpusFormat, Fingerprint,
                       HardwareProfile, HrtfInterpolation, LevelModel, Motion, NoiseSpectrum, Pairing, PathKind, QueryType,
                       RecordedSet, Relation, RirMethod, Scenario, SegmentRule, SensorLevel, SimilarityMeasure, values)
from ..core.jsonable import jsonable
from ..receivers import NAMES as RECEIVER_NAMES
from ..scene.distributions import Dist
from ..scene.queries import DEFAULT_MARGINS


def option(default, doc: str, *, unit: str = "", choices=None, ge=None, gt=None, le=None, lt=None, why: str = "",
           path: bool = False, many: bool = False, new: bool = False, former=None):
    """A plain field: ``unit`` (shown in docs and messages), ``choices`` (an enumeration),
    ``ge``/``gt``/``le``/``lt`` (bounds), ``why`` (a reason shown when a bound fails),
    ``path`` (resolved against a config file's folder), ``many`` (a string field that also
    takes a list of strings, kept as a tuple), ``new`` (added after format version 1:
    stored in ``plan/config.json`` and ``dataset.json`` only when it differs from the
    default, so datasets made without it keep their bytes), ``former`` (the default
    before it changed: the key is then always stored, and a stored config without it,
    written before, means this value; ``parse_config(..., stored=True)``)."""
    meta = {"doc": doc, "unit": unit, "choices": values(choices) if choices else None, "ge": ge, "gt": gt, "le": le,
            "lt": lt, "why": why, "path": path, "many": many, "new": new and former is None, "former": former}
    if isinstance(default, (tuple, dict)):
        return field(default_factory=lambda: type(default)(default), metadata=meta)
    return field(default=default, metadata=meta)


def dist(default, doc: str, *, unit: str = "", choices=None, ge=None, gt=None, le=None, why: str = "",
         integer: bool = False, new: bool = False):
    """A sampled field (a constant or a distribution); bounds apply to every value it can
    draw; ``integer``: a count, so a constant or a ``choose`` of whole numbers."""
    meta = {"doc": doc, "unit": unit, "choices": values(choices) if choices else None, "ge": ge, "gt": gt, "le": le,
            "lt": None, "why": why, "path": False, "dist": True, "integer": integer, "new": new}
    return field(default_factory=lambda: Dist.parse(default, "default"), metadata=meta)


@dataclass(frozen=True)
class CorpusConfig:
    """Where the captioned clips come from."""

    format: str = option("audiocaps", "manifest format (see manifests/README.md); `auto` detects it",
                         choices=CorpusFormat)
    dir: str = option("", "folder with the manifests (and audio); `--corpus-dir` sets it; `\"builtin:demo\"` "
                          "synthesises the demo corpus into `OUT/demo-corpus`", path=True)
    audio_dir: str = option("", "audio folder, relative to `dir`; default: each clip is looked for in the folders "
                                "named for its split (`audio/train`, `audio/val`, Clotho's `development`, in `dir/audio` "
                                "or `dir`), then in `dir/audio` if it exists, else `dir`: every download layout, even "
                                "train files in `audio/` and val files in `audio/val/`")
    audio_template: str = option("", "audio file name pattern, or a list of patterns tried in order for each clip "
                                     "(the first file that exists is used); empty means the reader's default (for "
                                     "AudioCaps the usual download names, `{youtube_id}.wav`, `Y{youtube_id}.wav`, "
                                     "`{youtube_id}_{start_time}.wav`, `{audiocap_id}.wav` and the same in `.flac`; "
                                     "fields `{youtube_id}`, `{audiocap_id}`, `{start_time}`), e.g. "
                                     "`\"Y{youtube_id}.wav\"`", many=True)
    check: str = option("drawn", "how much each clip is checked: `drawn` (every header before planning, then the "
                                 "clips the plan draws decoded as `full` does; a scene that drew a bad one is planned "
                                 "again without it: docs/reliability.md), `full` (every clip decoded before planning: "
                                 "catches NaN/Inf, and silence in the `audio.duration` seconds a scene uses), "
                                 "`header`, `exists`, `none` (trust the manifest; a silent source is then an error at "
                                 "render time)", choices=CheckLevel, former="full")
    prepare_on_check: bool = option(True, "write a clip's prepared form (`tsel corpus prepare`) from the decode of its "
                                          "full check, when scenes would resample or mix it down: with `check = "
                                          "\"drawn\"` for the clips the plan uses twice or more (where it pays: "
                                          "benchmarks/bench_prepared.py), with `\"full\"` for every clip. They go "
                                          "to `$TSEL_CLIP_CACHE`, else the per-user cache "
                                          "(`~/.cache/tsel-data/clips`), never into the corpus (`tsel check` never "
                                          "writes them)", new=True)
    fingerprint: str = option("stat", "what a shard's seal records of each clip and bank file it read, so "
                                      "`--resume` renders again the shards whose inputs changed: `stat` (size and "
                                      "modification time; a file rewritten with both kept is not noticed) or `hash` "
                                      "(size and sha256 of the bytes, read again at every resume; catches that "
                                      "too, and a file only touched or copied keeps its shards). Set it when "
                                      "planning (docs/reliability.md)", choices=Fingerprint, new=True)
    min_duration: float = option(1.0, "shorter clips are bad clips", unit="s", ge=0.0, le=3600.0)
    max_channels: int = option(8, "a file with more channels is a bad clip (probably not a recording)",
                               unit="channels", ge=1, le=1024)
    min_samplerate: int = option(0, "clips recorded at a lower rate are left out (counted, not bad clips): a 16 kHz "
                                    "clip is empty above 8 kHz, under the Nyquist of 24 kHz scenes (`tsel check` "
                                    "counts such clips); e.g. the scenes' `audio.fs`; 0 keeps every clip. Needs "
                                    "`check = \"header\"` or `\"full\"`", unit="Hz", ge=0, le=768000, new=True)
    max_reuse: float = option(20.0, "`tsel generate` and `tsel plan` stop before any work when a split's count "
                                    "would have each usable clip sound in more scenes than this on average (as "
                                    "target or interferer), e.g. a paper preset's 7,224 scenes over 8 clips; "
                                    "`--allow-reuse` goes on anyway", unit="scenes per clip", gt=0, le=1e6, new=True)
    caption_embeddings: str = option("", "an `.npz` of caption vectors (`captions` [N] str, `vectors` [N, D]; CLAP or "
                                         "MiniLM embeddings made elsewhere, or by `tsel corpus embed`) for "
                                         "`scene.similarity = \"embeddings\"`; it must hold every caption of the "
                                         "corpus", path=True, new=True)


@dataclass(frozen=True)
class SplitConfig:
    """One split (any name; the presets use `train`, `val`, `test`). Clips are drawn only
    from the split's own manifest, so a corpus' split is kept."""

    manifest: str = option("", "manifest file, relative to `corpus.dir`. Several splits may share one plain "
                               "manifest whose `split` column says which rows are whose")
    audio_dir: str = option("", "this split's audio folder, relative to `corpus.dir` (e.g. Clotho's `development`); "
                                "default `corpus.audio_dir`", new=True)
    count: int = option(0, "scenes to make (`--split NAME=COUNT` overrides); recorded datasets: at most this many, "
                           "every target when there are fewer", unit="scenes", ge=0, le=100_000_000)
    rooms: tuple = option((), "RIR-bank rooms this split may use (bank datasets), by name or number. Empty: the "
                              "rooms no other split names (every room when no split names any), so a split never "
                              "draws another split's rooms; a room named by two splits is an error. Recorded "
                              "datasets: the rooms (`room{R}` of the file names, by number) it takes; empty: all")
    folds: tuple = option((), "recorded datasets: the folds (`fold{N}` of the file names) this split takes; empty: "
                              "the set's own split (STARSS23: train 3, test 4), or every recording when the set has "
                              "none", new=True)


@dataclass(frozen=True)
class AudioConfig:
    """Sample rate, length, label frames and levels of every scene."""

    fs: int = option(24000, "sample rate of the scenes (clips are resampled, polyphase)", unit="Hz", ge=8000,
                     le=192000)
    duration: float = option(10.0, "scene length; clips are zero-padded or cut to it", unit="s", gt=0, le=600.0,
                             why="a scene's audio is held in memory whole")
    label_hop: float = option(0.1, "label frame hop; `duration` must be a whole number of hops", unit="s", gt=0,
                              le=60.0)
    activity_threshold_db: float = option(-30.0, "a frame is active if its energy is within this of the clip's "
                                                 "loudest frame", unit="dB", ge=-200.0, lt=0.0,
                                          why="at 0 dB or above only the loudest frame, or none, is active")
    target_level_dbfs: float = option(-25.0, "active-frame RMS of the target's image at the array", unit="dBFS",
                                      ge=-80.0, le=0.0, why="a level in dBFS: full scale is 0, int16 rounds at -101")


@dataclass(frozen=True)
class SceneConfig:
    """What a scene holds: array format, sources, their separation, motion."""

    format: str = option("mic4", "the receiver: an array, an ambisonic microphone, a stereo pair or two ears "
                                 "(`tsel presets --receivers` lists them; docs/format.md)", choices=RECEIVER_NAMES)
    receivers: tuple = option((), "more receivers to hear every scene in the same pass, at the same place and "
                                  "turn, e.g. `[\"foa\", \"tetra\"]`: same room, sources, clips, paths and gains "
                                  "(levels are set on `format`'s channels), labels identical in each one's frame; "
                                  "each one's audio in the shard's `receivers/NAME/` (docs/format.md)", new=True)
    scenario: Dist = dist(["choose", ["two-directional"]],
                          "`two-directional`, or `directional+additive` (the first interferer added to every "
                          "channel unspatialised), or a `choose` of both", choices=Scenario)
    additive: str = option("coherent", "how the additive source of `directional+additive` is heard: `coherent` "
                                       "(the paper's: the dry clip on every mic channel, on W only for FOA; to a "
                                       "planar array a source straight overhead) or `diffuse` (a diffuse field at "
                                       "the array: mic coherence sinc(kd), FOA W:Y:Z:X energies 1:1/3:1/3:1/3, "
                                       "uncorrelated; docs/acoustics.md); its level is defined the same way",
                           choices=Additive, new=True)
    interferers: Dist = dist(1, "interferers per scene (a distribution is allowed); in `directional+additive` the "
                                "first is additive", unit="sources", ge=1, le=16, why="a scene holds at least two sources",
                     integer=True)
    tir_db: Dist = dist(["uniform", -5.0, 5.0], "target-to-interferer ratio at the array, per interferer "
                                              "(`levels = \"tir\"`; additive sources always)", unit="dB",
                  ge=-60.0, le=60.0)
    levels: str = option("tir", "how source levels are set: `tir` (the paper's: each interferer `tir_db` below the "
                                "target at the array, whatever the distance) or `distance` (each source gets a level "
                                "at 1 m, `sources.power`, and its level at the array follows from its distance and "
                                "the room: nearer is louder)", choices=LevelModel, new=True)
    min_separation: float = option(20.0, "minimum azimuth between directional sources", unit="deg", ge=0.0,
                                   le=360.0)
    separated_frames: float = option(0.8, "fraction of label frames on which `min_separation` must hold; static "
                                          "sources hold it on every frame or none, a moving source may cross "
                                          "another for the rest (at 40 °/s a 10 s walk goes all the way round)",
                                     unit="fraction", gt=0.0, le=1.0)
    caption_similarity: float = option(0.5, "the ambiguity guard: an interferer is rejected if any of its captions is "
                                            "more similar than this to the query caption (`similarity`; `lexicon`: "
                                            "to any caption of the target clip), so the caption picks out one "
                                            "source", unit="similarity 0-1", ge=0.0, le=1.0)
    similarity: str = option("lexicon", "the caption similarity of the guard, pairing and same-kind distractors: "
                                        "`lexicon` (cosine of concept sets: words lemmatised, synonyms and broader "
                                        "terms of sound events joined, so paraphrases meet), `words` (word-set "
                                        "Jaccard, function words ignored; the default before), `tfidf` (TF-IDF "
                                        "cosine over the split's captions, word stems), `embeddings` (cosine of "
                                        "`corpus.caption_embeddings`), `none` (no guard: interferers drawn at "
                                        "random, as the paper did); docs/queries.md", choices=SimilarityMeasure,
                             new=True, former="words")
    query: Dist = dist("caption", "what the query is: `caption` (one caption of the target), `relational` (\"the "
                                  "loudest sound\"), `composite` (a caption plus a relation, with a same-kind "
                                  "distractor), or a `choose` of them with weights; relations are decided on the "
                                  "rendered scene (docs/queries.md)", choices=QueryType, new=True)
    relations: tuple = option(tuple(r.value for r in Relation),
                              "relations relational and composite queries may state (docs/queries.md), tried in "
                              "a random order per scene until one holds with its margin", new=True)
    pairing: str = option("random", "interferers: `random` (any clip passing the guard), `hard` (caption similarity "
                                    "in [`hard_similarity`, `caption_similarity`]: close but not the same sound), "
                                    "`easy` (at most `easy_similarity`)", choices=Pairing, new=True)
    hard_similarity: float = option(0.25, "lower end of the `hard` pairing band (the upper end is "
                                          "`caption_similarity`)", unit="similarity 0-1", gt=0.0, le=1.0,
                                    why="a hard interferer shares something with the query", new=True)
    easy_similarity: float = option(0.05, "an `easy` interferer's captions are at most this similar to the query "
                                          "caption", unit="similarity 0-1", ge=0.0, le=1.0, new=True)
    onset: Dist = dist(0.0, "when each source starts in the scene (silence before; the clip is cut at the scene's "
                            "end): a constant or a distribution, drawn per source. Real clips sound from their "
                            "first frame, so `starts_first` / `starts_last` queries need this, e.g. "
                            "`[\"uniform\", 0.0, 3.0]`", unit="s", ge=0.0, le=600.0, new=True)
    same_kind_distractors: float = option(0.0, "probability that an interferer is a different clip of the target's "
                                               "kind (caption similarity at least `same_kind_similarity`, naming "
                                               "every sound event the query caption names and none the target does "
                                               "not: docs/queries.md); such scenes get a composite or relational "
                                               "query, never a bare caption",
                                          unit="probability", ge=0.0, le=1.0, new=True)
    same_kind_similarity: float = option(0.6, "a same-kind distractor's captions are at least this similar to the "
                                              "query caption", unit="similarity 0-1", gt=0.0, le=1.0, new=True)
    margin_level: float = option(DEFAULT_MARGINS["margin_level"], "loudest / quietest: the target's level at the "
                                 "array differs from every other source's by at least this (same-kind distractors "
                                 "get |TIR| of at least this plus 0.5 dB)", unit="dB", gt=0.0, le=60.0, new=True)
    margin_distance: float = option(DEFAULT_MARGINS["margin_distance"], "nearest / farthest: the target is at least "
                                    "this much nearer / farther than every other directional source, on every label "
                                    "frame", unit="m", gt=0.0, le=100.0, new=True)
    margin_onset: float = option(DEFAULT_MARGINS["margin_onset"], "starts first / last: the target's first active "
                                 "frame is at least this before / after every other source's", unit="s", gt=0.0,
                                 le=600.0, new=True)
    margin_motion: float = option(DEFAULT_MARGINS["margin_motion"], "moving: the target's direction travels at least "
                                  "this far while every other source stays put", unit="deg", gt=0.0, le=360.0, new=True)
    margin_solo: float = option(DEFAULT_MARGINS["margin_solo"], "heard at T: the target is the only active source on "
                                "every label frame within this window centred on T", unit="s", gt=0.0, le=600.0, new=True)
    motion: str = option("static", "`static`, `moving` or `mixed`. In simulated rooms a moving source follows "
                                   "`path`, with an RIR at least every 100 ms, every 4° and every 6 cm (4.5 cm on arcs); "
                                   "with a bank it walks a bank trajectory, starting at a random point in a random "
                                   "direction",
                         choices=Motion)
    moving_fraction: float = option(0.5, "with `mixed`: probability that a directional source moves",
                                    unit="probability", ge=0.0, le=1.0)
    speed: Dist = dist(["choose", [10.0, 20.0, 40.0]],
                       "angular speed of moving sources as seen from the array, great-circle arc (the DCASE "
                       "generator's set), for bank walks and simulated paths alike: a simulated arc at elevation e "
                       "turns its azimuth at speed / cos e", unit="deg/s", ge=0.0, le=360.0,
                  why="a turn a second at most: a moving source is rendered at a knot every 4°")
    path: Dist = dist("arc", "how simulated sources move: `arc` (around the array at constant distance and height) "
                             "or `line` (a straight pass at constant height: closest to the array at a random time "
                             "of the clip, at `sources.distance`, where it sweeps `speed`, so v = speed·distance; "
                             "slower further away; a pass longer than the room walks the whole chord through its "
                             "closest point at that speed and stands at the wall margin before and after), or `[\"choose\", [\"arc\", \"line\"]]`. Bank walks follow the "
                             "bank's own trajectories", choices=PathKind)


@dataclass(frozen=True)
class RoomConfig:
    """Simulated shoebox rooms, or an RIR bank."""

    length: Dist = dist(["uniform", 5.0, 15.0], "shoebox length (the paper's \"each side 5–15 m\")", unit="m",
                        gt=0.0, le=200.0)
    width: Dist = dist(["uniform", 5.0, 15.0], "shoebox width", unit="m", gt=0.0, le=200.0)
    height: Dist = dist(["uniform", 5.0, 15.0], "shoebox height (`realistic-sim` uses 2.5–4 m)", unit="m", gt=0.0,
                        le=200.0)
    rt60: Dist = dist(["uniform", 0.5, 1.0], "requested reverberation time", unit="s", gt=0.0, le=20.0)
    rir_method: str = option("hybrid", "RIR simulator (see acoustics.md; `pyroomacoustics` renders omni capsules "
                                       "only, so not FOA)", choices=RirMethod)
    bank: str = option("", "path of an RIR bank (a TAU-SRIR DB folder, SOFA files or a tsel bank; "
                           "`\"builtin:demo-bank\"` builds a small simulated one into `OUT/demo-bank.h5`); when set, "
                           "scenes use its RIRs instead of simulation (see banks.md)", path=True)


@dataclass(frozen=True)
class ArrayConfig:
    """Where the receiver stands in a simulated room, and what a custom, sphere or binaural
    receiver is made of."""

    side: Dist = dist(["uniform", 0.10, 0.13], "mic4 side length", unit="m", gt=0.0, le=10.0)
    height: Dist = dist(["uniform", 1.0, 1.2], "array centre height above the floor", unit="m", ge=0.0, le=200.0)
    yaw: Dist = dist(["uniform", -180.0, 180.0], "direction of the array's front in the room", unit="deg",
                     ge=-360.0, le=360.0)
    wall_margin: float = option(1.0, "minimum distance from the array centre to the side walls", unit="m", ge=0.0,
                                le=100.0)
    capsules: tuple = option((), "`scene.format = \"custom\"`: capsule positions `[[x, y, z], ...]` in the array "
                                 "frame (x front, y left, z up), 1-64 capsules; labels stay in this frame",
                             unit="m", new=True)
    patterns: tuple = option((), "custom capsules' patterns: one for all or one per capsule, each `omni`, "
                                 "`subcardioid`, `cardioid`, `supercardioid`, `hypercardioid` or `figure8`; empty: "
                                 "all omni", new=True)
    orientations: tuple = option((), "custom capsules' axes `[[azimuth, elevation], ...]` (one for all or one per "
                                     "capsule); empty: each pointing away from the array centre (a capsule at the "
                                     "centre points to the front)", unit="deg", new=True)
    baffle: str = option("rigid", "capsules of a sphere array (`tetra`, `em32`) on a `rigid` sphere (the sphere "
                                  "scatters the sound, as on the real microphone) or `open` (free-field omnis at the "
                                  "capsule positions)", choices=Baffle, new=True)
    hrtf: str = option("", "`scene.format = \"binaural\"`: a SOFA HRTF file (SimpleFreeFieldHRIR), e.g. the MIT "
                           "KEMAR set; the head's yaw is `yaw`", path=True, new=True)
    hrtf_interpolation: str = option("nearest", "binaural: each image source through the `nearest` measured HRIR, "
                                                "or `interpolated` (the measured triangle around its direction, "
                                                "barycentric weights, blended time-aligned: onsets removed, "
                                                "blended, the interpolated ITD put back)", choices=HrtfInterpolation, new=True)


@dataclass(frozen=True)
class SourcesConfig:
    """Where directional sources are placed."""

    distance: Dist = dist(["uniform", 1.0, 3.0], "distance from the array centre", unit="m", ge=0.0, le=200.0)
    height: Dist = dist(["uniform", 0.5, 2.0], "source height above the floor", unit="m", ge=0.0, le=200.0)
    wall_margin: float = option(0.5, "minimum distance from every wall, floor and ceiling", unit="m", ge=0.0,
                                le=100.0)
    power: Dist = dist(["uniform", -5.0, 5.0], "with `scene.levels = \"distance\"`: each directional source's "
                                               "level at 1 m (its direct sound, relative: the scene is then scaled "
                                               "so the target sits at `audio.target_level_dbfs`); its level at the "
                                               "array follows from the room", unit="dB re 1 m", ge=-60.0, le=60.0,
                       new=True)


@dataclass(frozen=True)
class NoiseConfig:
    """What else the receiver hears: the room's ambience, a diffuse noise field, babble,
    sensor noise. None of it is a source: it has no label; its kind, SNR and level are in
    the record (docs/format.md). Every SNR is against the target's omni energy over the
    whole scene, as the DCASE generator defines it (the mean of the level channels: W for
    FOA, the mean of the capsules for arrays)."""

    ambience: str = option("", "recorded ambience: a TAU-SNoise_DB folder (room folders as distributed, matched to "
                               "the bank's rooms by name) or a folder of your multichannel recordings (per-room "
                               "subfolders, or loose files for any room); channels and rate must be the "
                               "receiver's", path=True, new=True)
    ambience_snr: Dist = dist(["uniform", 6.0, 30.0], "SNR of the ambience (the DCASE generator's range)", unit="dB",
                              ge=-20.0, le=100.0, new=True)
    ambience_segments: str = option("random", "which stretch of the recording a scene hears: `random` (an offset "
                                              "drawn per scene) or `consecutive` (the generator's rule: scene i of a "
                                              "split takes block i)", choices=SegmentRule, new=True)
    diffuse: str = option("none", "a simulated diffuse noise field with the receiver's diffuse-field coherence: "
                                  "`white`, `pink`, `brown`, or `clip` (the long-term spectrum of a corpus clip); "
                                  "`none`", choices=NoiseSpectrum, new=True)
    diffuse_snr: Dist = dist(["uniform", 10.0, 30.0], "SNR of the diffuse noise", unit="dB", ge=-20.0, le=100.0,
                             new=True)
    babble: int = option(0, "a background of this many corpus clips, each a plane wave from its own random far "
                            "direction (0: none)", unit="clips", ge=0, le=64, new=True)
    babble_snr: Dist = dist(["uniform", 10.0, 30.0], "SNR of the babble", unit="dB", ge=-20.0, le=100.0, new=True)
    sensor: str = option("none", "independent noise on every channel (the microphones' own): `dbfs` (its RMS per "
                                 "channel is `sensor_level` dBFS), `snr` (`sensor_level` is its SNR) or `none`",
                         choices=SensorLevel, new=True)
    sensor_level: Dist = dist(["uniform", -90.0, -70.0], "sensor noise: dBFS (`sensor = \"dbfs\"`) or SNR in dB "
                                                        "(`sensor = \"snr\"`)", unit="dBFS or dB", ge=-200.0,
                              le=100.0, new=True)


@dataclass(frozen=True)
class HardwareConfig:
    """The microphones as they are built: each capsule's gain, delay, frequency response and
    self-noise off nominal, and each device's clock, drawn per scene and capsule from these
    distributions and applied to the rendered audio of every receiver (each its own draw),
    after the room and before output coding: labels stay the geometric truth. Off by
    default; `profile` fills every key left unset with a typical MEMS board's or a
    measurement-grade array's values (docs/config.md). What was drawn is in the record and
    the shard (docs/format.md). FOA and the stereo pair mixed from it are formats, not
    microphones: refused (put the hardware on `tetra` or `em32`, the capsules FOA is
    encoded from)."""

    profile: str = option("none", "typical values for every key below left unset: `mems` (a MEMS board), "
                                  "`measurement` (a measurement-grade array) or `none`", choices=HardwareProfile,
                          new=True)
    gain_db: Dist = dist(0.0, "each capsule's gain off nominal (its sensitivity's tolerance), per capsule",
                         unit="dB", ge=-20.0, le=20.0, new=True)
    delay_us: Dist = dist(0.0, "each capsule's delay off nominal (its phase mismatch as a delay), per capsule",
                          unit="µs", ge=-1000.0, le=1000.0, new=True)
    highpass_hz: Dist = dist(0.0, "each capsule's high-pass corner (-3 dB; a Butterworth of `highpass_order`, its "
                                  "phase included), per capsule; 0: none", unit="Hz", ge=0.0, le=2000.0, new=True)
    highpass_order: int = option(2, "the high-pass's order (6 dB per octave each)", ge=1, le=4, new=True)
    tilt_db: Dist = dist(0.0, "each capsule's spectral tilt about 1 kHz (magnitude only, flat below 50 Hz), per "
                              "capsule", unit="dB/octave", ge=-6.0, le=6.0, new=True)
    response: str = option("", "a measured frequency response, a CSV of `frequency_hz` and one gain column (dB; "
                               "every capsule) or one per capsule, magnitude only, on top of the rest; read when "
                               "planning, so recipes hold it", path=True, new=True)
    self_noise_dba: Dist = dist(0.0, "each capsule's self-noise (white), A-weighted, as the datasheet gives it; 0: "
                                     "none", unit="dB SPL(A)", ge=0.0, le=120.0, new=True)
    sensitivity_dbfs: float = option(-26.0, "the level a 94 dB SPL (1 Pa) tone reaches in the audio: turns "
                                            "`self_noise_dba` into full scale (a digital MEMS capsule: -26 dBFS)",
                                     unit="dBFS at 94 dB SPL", ge=-80.0, le=0.0, new=True)
    devices: tuple = option((), "the device each capsule belongs to, e.g. `[0, 0, 1, 1]` for two stereo pairs: "
                                "every device after the first gets its own clock (`clock_offset_us`, "
                                "`clock_ppm`); empty: one device", new=True)
    clock_offset_us: Dist = dist(0.0, "how far a device's channels lag the first device's at the start, per device",
                                 unit="µs", ge=-1e6, le=1e6, new=True)
    clock_ppm: Dist = dist(0.0, "how much slower a device's clock runs than the first device's: its lag grows by "
                                "this many µs per second, per device", unit="ppm", ge=-1000.0, le=1000.0, new=True)

    @property
    def on(self) -> bool:
        """Whether any capsule or clock differs from the ideal (the layer runs)."""
        ideal = type(self)()
        return any(getattr(self, k) != getattr(ideal, k) for k in HARDWARE_DRAWN) or bool(self.response)


# what turns the hardware layer on (the rest says how what is drawn is applied)
HARDWARE_DRAWN = ("gain_db", "delay_us", "highpass_hz", "tilt_db", "self_noise_dba", "clock_offset_us", "clock_ppm")

# hardware.profile: the raw values it gives every [hardware] key a config leaves unset
HARDWARE_PROFILES = {
    # digital MEMS capsules on one board, one clock (datasheets of Knowles SPH0645 /
    # Infineon IM69D class parts; boards roll off below 100-200 Hz)
    "mems": {"gain_db": ["uniform", -1.0, 1.0], "delay_us": ["uniform", -5.0, 5.0],
             "highpass_hz": ["uniform", 80.0, 200.0], "tilt_db": ["uniform", -0.5, 0.5],
             "self_noise_dba": ["uniform", 29.0, 33.0], "sensitivity_dbfs": -26.0,
             "clock_offset_us": ["uniform", -100.0, 100.0], "clock_ppm": ["uniform", -20.0, 20.0]},
    # matched measurement capsules on one interface, word clock shared between devices
    "measurement": {"gain_db": ["uniform", -0.2, 0.2], "delay_us": ["uniform", -0.5, 0.5],
                    "highpass_hz": ["uniform", 5.0, 10.0], "tilt_db": ["uniform", -0.05, 0.05],
                    "self_noise_dba": ["uniform", 15.0, 20.0], "sensitivity_dbfs": -32.0,
                    "clock_offset_us": ["uniform", -2.0, 2.0], "clock_ppm": ["uniform", -0.5, 0.5]},
}


@dataclass(frozen=True)
class RecordedConfig:
    """Scenes cut from real recordings of a SELD dataset in the DCASE layout (`corpus.dir`:
    STARSS23 and the like), instead of rendered (docs/recorded.md). Each window of
    `audio.duration` seconds gives a scene per source active long enough in it; the query is
    one of its class's captions, or a relation the labels decide when another source of its
    class is in the window. The receiver is `scene.format` (`foa` reads `foa_dev/`, `tetra`
    `mic_dev/`, `stereo` `stereo_dev/`); scenes keep the recordings' rate (`audio.fs`)."""

    dataset: str = option("none", "the recorded dataset whose layout, columns, classes and splits to use: "
                                  "`starss23`, `starss22`, `tau-nigens-2020`, `tau-nigens-2021`, `dcase2025-stereo`, "
                                  "`custom` (your own recordings: give `ontology`), or `none` (rendered scenes)",
                          choices=RecordedSet, new=True)
    hop: float = option(0.0, "step between windows; 0: the window length (`audio.duration`), so windows do not "
                             "overlap", unit="s", ge=0.0, le=3600.0, new=True)
    min_active: float = option(1.0, "a source becomes a target when it is active at least this long in the window",
                               unit="s", gt=0.0, le=600.0, new=True)
    ontology: str = option("", "a file of your classes and their captions (CSV `index,name,captions` with the captions "
                               "joined by a vertical bar, or JSON); empty: the dataset's built-in classes", path=True, new=True)
    columns: tuple = option((), "the label CSV's columns, when they are not the set's own: names from `frame`, "
                                "`class`, `source`, `azimuth`, `elevation`, `distance` (cm), `ignore`, e.g. "
                                "`[\"frame\", \"class\", \"source\", \"azimuth\", \"elevation\"]`", new=True)

    @property
    def on(self) -> bool:
        return self.dataset != RecordedSet.NONE


@dataclass(frozen=True)
class OutputConfig:
    """How scenes are stored."""

    shard_size: int = option(128, "scenes per shard (a 10 s 4-channel 24 kHz float32 scene is 3.84 MB)",
                             unit="scenes", ge=1, le=100_000)
    audio: str = option("float32", "how shards store audio: `float32`; `int16` (half the bytes, rounding at about "
                                   "-101 dBFS); `flac` (lossless over int16, about a third of float32's bytes); every "
                                   "coding reads back as float32 (docs/format.md)", choices=AudioCoding,
                        new=True)
    descriptors: bool = option(True, "each source's acoustic descriptors measured on its rendered RIRs (DRR, C50, "
                                     "EDT, T30 and T30 per octave band), its motion class (stationary, approaching, "
                                     "receding, passing, circling) and the room's volume and floor area, in the "
                                     "records and the shards (docs/format.md, \"Acoustic descriptors\"); they add about "
                                     "9 % to rendering (benchmarks/bench_descriptors.py)", former=False)


@dataclass(frozen=True)
class Config:
    """A whole dataset job. ``to_dict()`` is the plain form stored in ``plan/config.json``
    and ``dataset.json``."""

    name: str = option("custom", "a label stored in `dataset.json`")
    seed: int = option(0, "the dataset seed: every scene's draws come from (seed, split, index)", ge=0,
                       le=2**32 - 1)
    on_bad_clip: str = option("skip", "`skip`: leave bad clips out and list them in `bad_clips.jsonl`; `fail`: "
                                      "stop before rendering", choices=BadClipPolicy)
    corpus: CorpusConfig = field(default_factory=CorpusConfig)
    splits: dict = field(default_factory=dict)  # name -> SplitConfig
    audio: AudioConfig = field(default_factory=AudioConfig)
    scene: SceneConfig = field(default_factory=SceneConfig)
    room: RoomConfig = field(default_factory=RoomConfig)
    array: ArrayConfig = field(default_factory=ArrayConfig)
    sources: SourcesConfig = field(default_factory=SourcesConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    recorded: RecordedConfig = field(default_factory=RecordedConfig)
    hardware: HardwareConfig = field(default_factory=HardwareConfig)
    output: OutputConfig = field(default_factory=OutputConfig)

    def to_dict(self, every_key: bool = False) -> dict:
        """The config as plain data; keys declared ``new`` only when set (``every_key``:
        all of them, as ``tsel presets NAME`` prints)."""
        d = jsonable(self)
        if not every_key:
            for name, sec in ((sec, getattr(self, sec)) for sec in SECTIONS):
                # keys a hardware profile fills are kept even at their default: read back,
                # the config must not take the profile's value for a key it set to the default
                _drop_unset(sec, d[name], keep=HARDWARE_PROFILES.get(getattr(sec, "profile", None), ()))
                if name in NEW_SECTIONS and not d[name]:
                    del d[name]  # a section added later, left unset: datasets made without it keep their bytes
            for name, sp in self.splits.items():
                _drop_unset(sp, d["splits"][name])
        return d

    def rooms_by_split(self) -> dict:
        """``splits.NAME.rooms`` of every split."""
        return {name: tuple(sp.rooms) for name, sp in self.splits.items()}

    def active_splits(self) -> tuple:
        """The splits that make scenes (count > 0), in config order."""
        return tuple(name for name, sp in self.splits.items() if sp.count)


@dataclass(frozen=True)
class CommandOptions:
    """The numeric options of commands that are no config key, bounded as the keys are
    (``--tolerance``, ``--max-scenes``, ``--workers``, an export's ``--shard-size``, ...):
    the command line reads their bounds here (cli/options.Bounded), so ``nan``, ``inf`` and
    ``-1`` are refused in one line. An option that sets a config key (``--seed``,
    ``bank build --fs``) is bounded by that key."""

    workers: int = option(0, "processes (0: one per core)", unit="processes", ge=0, le=4096)
    tolerance: float = option(20.0, "`tsel verify`'s agreement threshold", unit="deg", gt=0.0, le=180.0)
    max_scenes: int = option(0, "`tsel verify` checks the first N scenes of each split", unit="scenes", ge=1,
                             le=10**9)
    fail_under: float = option(0.0, "`tsel verify` fails under this agreement rate", unit="(0-1)", ge=0.0, le=1.0)
    scenes: int = option(24, "scenes of `tsel inspect --sheet`", unit="scenes", ge=1, le=10_000)
    rooms: int = option(2, "rooms of `tsel bank build`", unit="rooms", ge=1, le=1000)
    step: float = option(5.0, "azimuth step along a ring of `tsel bank build`", unit="deg", gt=0.0, le=90.0)
    rir_seconds: float = option(0.0, "RIR length of `tsel bank build`", unit="s", gt=0.0, le=60.0)
    batch: int = option(256, "captions per batch of `tsel corpus embed`", unit="captions", ge=1, le=1_000_000)
    shard_bytes: int = option(500_000_000, "an export's `--shard-size`", unit="bytes", ge=1000, le=10**13)


def declared(key: str):
    """The schema's field of ``key``: a config key (``audio.fs``, ``seed``) or a command
    option of :class:`CommandOptions` (``tolerance``)."""
    section, _, name = key.rpartition(".")
    owner = SECTIONS.get(section) if section else (Config if key in TOP_FIELDS else CommandOptions)
    found = {f.name: f for f in fields(owner)}.get(name) if owner else None
    if found is None:
        raise KeyError(f"no setting {key!r} in the config schema")
    return found


SECTIONS = {
    "corpus": CorpusConfig, "audio": AudioConfig, "scene": SceneConfig, "room": RoomConfig,
    "array": ArrayConfig, "sources": SourcesConfig, "noise": NoiseConfig, "recorded": RecordedConfig,
    "hardware": HardwareConfig, "output": OutputConfig,
}
NEW_SECTIONS = {"noise", "recorded", "hardware"}
TOP_KEYS = ("name", "seed", "on_bad_clip", "splits", *SECTIONS)
TOP_FIELDS = ("name", "seed", "on_bad_clip")


def _drop_unset(section, d: dict, keep=()) -> None:
    """Remove from ``d`` (a section as plain data) the ``new`` keys left at their default
    (but those in ``keep``)."""
    default = type(section)()
    for f in fields(section):
        if f.metadata.get("new") and f.name not in keep and getattr(section, f.name) == getattr(default, f.name):
            d.pop(f.name, None)
