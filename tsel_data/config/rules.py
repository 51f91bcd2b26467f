"""Every rule a config must satisfy, next to the schema it judges.

- :func:`check_raw_config`: the *shape* of raw data (TOML tables, ``--set`` values,
  ``dataset.json``'s config) before typed parsing;
- :func:`field_problems`: each field against its declared choices and bounds (schema.py);
- :func:`cross_field_problems`: rules that need more than one field;
- :func:`geometry_problems`: layouts no scene drawn from the ranges could realise, in the
  largest and in the smallest room the ranges allow;
- :func:`rooms_without_bank`: bank rooms named without a bank.

The ``*_problems`` functions collect (``tsel check`` shows every problem at once);
:func:`validate_config` raises the first.
"""
from __future__ import annotations

import json
import math
from dataclasses import fields

from ..acoustics.metrics import sabine_min_rt60
from ..choices import (SPLIT_NAME, LevelModel, NoiseKind, Pairing, QueryType, RecordedSet, Relation, SensorLevel,
                       SimilarityMeasure, values)
from ..errors import ConfigError, GeometryError
from ..receivers import RECEIVERS, canonical, receiver
from ..scene.distributions import Dist
from ..scene.hardware import read_response
from ..scene.queries import RELATIONS
from .receiver import array_poses, receiver_problems
from .schema import SECTIONS, TOP_FIELDS, Config, SplitConfig, declared

MAX_NUMBER = 1e9  # larger config numbers are typos (seeds excepted)
MAX_DEPTH = 16  # tables and lists nest no deeper in a config (array.capsules: 3 levels under the root)
MAX_NOISE_OVER_TARGET_DB = 20.0  # every noise's SNR is at least -20 dB (schema: noise.*_snr)
RELATION_NAMES = values(Relation)


class Where(str):
    """The label errors start with (``preset demo``, ``my.toml``), knowing which keys a
    later source set: ``--set scene.min_separation=200``, ``--corpus-dir``, ``--split
    train=5``. So an error about a value names the place the user wrote it.

    ``origins`` maps dotted keys (``room.rt60``, ``splits.train``) to their label; a
    key's origin is its own entry or its nearest ancestor's.
    """

    def __new__(cls, base: str, origins: dict | None = None):
        w = super().__new__(cls, base)
        w.origins = dict(origins or {})
        return w

    def of(self, key: str) -> str:
        parts = key.split(".")
        for n in range(len(parts), 0, -1):
            label = self.origins.get(".".join(parts[:n]))
            if label is not None:
                return label
        # a table named whole (``splits.train``) was set by whoever set a key inside it
        inside = [label for k, label in self.origins.items() if k.startswith(key + ".")]
        return inside[-1] if inside else str(self)


def origin(cfg, where: str | None) -> str:
    """``where``, or the label :func:`~tsel_data.config.load.parse_config` gave ``cfg``
    (a :class:`Where` knowing which keys ``--set`` and the CLI options set)."""
    return where if where is not None else getattr(cfg, "_where", "config")


def at(where: str, *keys: str) -> str:
    """The label of an error about ``keys``: the first of them a later source (``--set``,
    a CLI option) set, else ``where`` itself."""
    if isinstance(where, Where):
        for k in keys:
            label = where.of(k)
            if label != str(where):
                return label
    return str(where)


# --- raw structure -----------------------------------------------------------------------


def check_raw_config(raw, where: str = "config") -> None:
    """Reject raw config data whose *shape* the typed parser does not expect, with a
    one-line ConfigError naming the key: a config or ``splits`` that is not a table, keys
    with control characters (they would break the one-line messages), and numbers that
    are not finite (TOML allows ``inf`` and ``nan``) or larger than MAX_NUMBER (the seed
    excepted), which would overflow ratios such as duration / label_hop.
    """
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: a config must be a table of sections, got {type(raw).__name__}")
    splits = raw.get("splits")
    if splits is not None and not isinstance(splits, dict):
        raise ConfigError(f"{at(where, 'splits')}: splits must be a table of [splits.NAME] with manifest and count, "
                          f"got {splits!r}")
    _finite(raw, where, "")


def _finite(x, where: str, key: str, depth: int = 0) -> None:
    if depth > MAX_DEPTH:
        raise ConfigError(f"{at(where, key)}: {key or 'config'} holds values nested more than {MAX_DEPTH} levels "
                          f"deep; no config value nests so deep: check the brackets")
    if isinstance(x, dict):
        for k, v in x.items():
            if not isinstance(k, str) or any(ord(c) < 32 or ord(c) == 127 for c in k):
                shown = f"{key}.{k!r}" if key else repr(k)
                raise ConfigError(f"{where}: config key {shown} is not a plain name (control characters or not a "
                                  f"string); keys are names such as room.rt60")
            _finite(v, where, f"{key}.{k}" if key else str(k), depth + 1)
    elif isinstance(x, (list, tuple)):
        for v in x:
            _finite(v, where, key, depth + 1)
    elif isinstance(x, bool):
        return
    elif isinstance(x, (int, float)):
        key = key.encode("unicode_escape").decode("ascii")  # odd keys stay on one line
        try:
            ok = math.isfinite(float(x))
        except OverflowError:
            ok = False
        if not ok:
            raise ConfigError(f"{at(where, key)}: {key or 'config'} = {x!r} is not a finite number; write a number "
                              f"within float range")
        if key != "seed" and abs(x) > MAX_NUMBER:
            # no physical quantity, count or rate here comes near; ratios of such numbers overflow
            raise ConfigError(f"{at(where, key)}: {key} = {x!r} is out of range (|x| > {MAX_NUMBER:g}); check the value")


# --- single fields, from the schema's declarations -----------------------------------------------


def field_problems(cfg: Config, where: str | None = None) -> list[ConfigError]:
    """Each field against its declared choices and bounds, in schema order."""
    where = origin(cfg, where)
    out: list[ConfigError] = []
    for f in fields(Config):
        if f.name in TOP_FIELDS:
            out += _judge(getattr(cfg, f.name), f, f.name, where)
    for sec in SECTIONS:
        section = getattr(cfg, sec)
        for f in fields(section):
            out += _judge(getattr(section, f.name), f, f"{sec}.{f.name}", where)
    for name, sp in cfg.splits.items():
        if not isinstance(name, str) or not SPLIT_NAME.fullmatch(name):
            out.append(ConfigError(f"{where}: split name {name!r} is not a plain name (1-64 letters, digits, _ or -, "
                                   f"starting with a letter or digit): it names a folder inside --out"))
            continue
        for f in fields(SplitConfig):
            out += _judge(getattr(sp, f.name), f, f"splits.{name}.{f.name}", where)
    return out


def _judge(value, f, key: str, where: str) -> list[ConfigError]:
    m = f.metadata
    choices = m.get("choices")
    if isinstance(value, Dist):
        return _judge_dist(value, m, key, where)
    if choices and value not in choices:
        return [ConfigError(f"{at(where, key)}: {key} = {value!r} is not one of {', '.join(choices)}")]
    if _bounded(m) and isinstance(value, (int, float)) and not _within(value, m):
        return [ConfigError(f"{at(where, key)}: {key} must be {_condition(m)}, got {value!r}")]
    return []


def _judge_dist(d: Dist, m: dict, key: str, where: str) -> list[ConfigError]:
    choices = m.get("choices")
    if choices:
        if d.kind not in ("const", "choose") or not all(isinstance(o, str) and o in choices for o in d.options):
            names = ", ".join(json.dumps(c) for c in choices)
            return [ConfigError(f"{at(where, key)}: {key} must be {names} or [\"choose\", [...]] of them, got "
                                f"{json.dumps(d.to_json())}")]
        return []
    if m.get("integer") and (d.kind not in ("const", "choose") or not all(
            isinstance(o, (int, float)) and not isinstance(o, bool) and float(o).is_integer() for o in d.options)):
        return [ConfigError(f"{where}: {key} is a count: write a whole number or [\"choose\", [whole numbers]], "
                            f"got {json.dumps(d.to_json())}")]
    if not _bounded(m):
        return []
    b = d.bounds
    if b is None:
        return [ConfigError(f"{at(where, key)}: {key} must be numbers ({_condition(m)}), got {json.dumps(d.to_json())}")]
    if not (_within(b[0], m) and _within(b[1], m)):
        return [ConfigError(f"{at(where, key)}: {key} must be {_condition(m)}, got {json.dumps(d.to_json())}")]
    return []


_BOUNDS = (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"))


def _bounded(m: dict) -> bool:
    return any(m.get(k) is not None for k, _ in _BOUNDS)


def _within(v: float, m: dict) -> bool:
    return ((m.get("ge") is None or v >= m["ge"]) and (m.get("gt") is None or v > m["gt"])
            and (m.get("le") is None or v <= m["le"]) and (m.get("lt") is None or v < m["lt"]))


def _condition(m: dict) -> str:
    parts = [f"{op} {m[k]:g}" if isinstance(m[k], float) else f"{op} {m[k]}" for k, op in _BOUNDS
             if m.get(k) is not None]
    unit = f" {m['unit']}" if m.get("unit") else ""
    why = f" ({m['why']})" if m.get("why") else ""
    return " and ".join(parts) + unit + why


def option_problem(key: str, value) -> str | None:
    """Why ``value`` cannot be the setting ``key`` (a config key or a command option of
    schema.CommandOptions): not a number, not finite, a fraction for a count, or out of
    the declared bounds ("must be > 0 and <= 180 deg"); None when it can."""
    m = declared(key).metadata
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f"must be a number ({_condition(m)})"
    if not math.isfinite(value):
        return f"must be a finite number, {_condition(m)}"
    if not _within(value, m):
        return f"must be {_condition(m)}"
    return None


# --- across fields ------------------------------------------------------------------------------


def cross_field_problems(cfg: Config, where: str | None = None) -> list[ConfigError]:
    """Rules that need more than one field."""
    where = origin(cfg, where)
    out: list[ConfigError] = []
    a = cfg.audio
    if a.label_hop > 0 and a.fs > 0 and a.label_hop * a.fs < 1:
        out.append(ConfigError(f"{at(where, 'audio.label_hop', 'audio.fs')}: audio.label_hop {a.label_hop} s is shorter than one sample at audio.fs "
                               f"{a.fs} Hz; a label frame must hold samples"))
    elif a.duration > 0 and a.label_hop > 0:  # (a hop under a sample may make duration / hop infinite)
        if a.label_hop > a.duration:
            out.append(ConfigError(f"{at(where, 'audio.label_hop', 'audio.duration')}: audio.label_hop {a.label_hop} s is longer than audio.duration "
                                   f"{a.duration} s"))
        elif abs(a.duration / a.label_hop - round(a.duration / a.label_hop)) > 1e-6:
            out.append(ConfigError(f"{at(where, 'audio.duration', 'audio.label_hop')}: audio.duration {a.duration} is not a whole number of label_hop "
                                   f"{a.label_hop}"))
    nb = cfg.scene.interferers.bounds
    if nb is not None and cfg.scene.min_separation * (nb[1] + 1) > 360:
        # k sources pairwise min_separation apart on a circle need k·min_separation <= 360°
        k = int(nb[1]) + 1
        out.append(ConfigError(f"{at(where, 'scene.min_separation', 'scene.interferers')}: scene.min_separation "
                               f"{cfg.scene.min_separation:g}° is impossible with {k} directional sources: the "
                               f"largest possible is {360 / k:g}° (360° / {k}); lower scene.min_separation"))
    if cfg.corpus.min_samplerate and cfg.corpus.check in ("exists", "none"):
        out.append(ConfigError(f"{at(where, 'corpus.min_samplerate', 'corpus.check')}: corpus.min_samplerate "
                               f"needs the clips' rates, which corpus.check = \"{cfg.corpus.check}\" does not read; "
                               f"set corpus.check = \"header\" (or \"full\")"))
    out += _query_problems(cfg, where)
    out += _noise_problems(cfg, where)
    out += _recorded_problems(cfg, where)
    out += _hardware_problems(cfg, where)
    receiver_errors = receiver_problems(cfg, at(where, "array.capsules", "array.patterns", "array.orientations",
                                                "array.hrtf", "scene.receivers", "scene.format"))
    out += receiver_errors
    if receiver_errors or canonical(cfg.scene.format) is None:
        return out  # the rest needs a receiver that can be built (field_problems names an unknown one)
    not_omni = [p.format for p in array_poses(cfg) if not p.free_field_omnis]
    if not cfg.room.bank and cfg.room.rir_method == "pyroomacoustics" and not_omni:
        out.append(ConfigError(f"{at(where, 'room.rir_method', 'scene.format')}: room.rir_method = \"pyroomacoustics\" renders free-field omni "
                               f"capsules only; use \"hybrid\" or \"ism\" for {not_omni[0]}"))
    if not cfg.room.bank and cfg.room.rir_method == "pyroomacoustics":
        dims = [getattr(cfg.room, k).bounds for k in ("length", "width", "height")]
        rt = cfg.room.rt60.bounds
        if rt is not None and all(b is not None and b[0] > 0 for b in dims):
            # the largest room decays slowest with fully absorbing walls: it sets the limit
            limit = sabine_min_rt60([b[1] for b in dims])
            if rt[0] < limit:
                out.append(ConfigError(
                    f"{where}: room.rt60 minimum {rt[0]} s is below what pyroomacoustics can make in the largest "
                    f"room ({limit:.2f} s: Sabine's RT60 with fully absorbing walls); raise room.rt60, shrink the "
                    f"room, or use room.rir_method = \"hybrid\""))
    return out


RECORDED_COLUMNS = ("frame", "class", "source", "azimuth", "elevation", "distance", "ignore")


def _recorded_problems(cfg: Config, where: str) -> list[ConfigError]:
    """What a recorded dataset (docs/recorded.md) cannot take: anything that renders."""
    rec = cfg.recorded
    if not rec.on:
        return []
    out = []
    if cfg.room.bank:
        out.append(ConfigError(f"{at(where, 'room.bank', 'recorded.dataset')}: recorded scenes are cut from "
                               f"recordings, not rendered through an RIR bank; remove room.bank"))
    if cfg.scene.receivers:
        out.append(ConfigError(f"{at(where, 'scene.receivers')}: a recording is heard by the one receiver it was "
                               f"made with (scene.format); remove scene.receivers"))
    noisy = [str(k) for k in NoiseKind if getattr(cfg.noise, k) not in ("", "none", 0)]  # a kind's switch key
    if noisy:
        out.append(ConfigError(f"{at(where, 'noise.' + noisy[0])}: a recording holds the room's own noise; "
                               f"[noise] does not apply to recorded scenes"))
    if canonical(cfg.scene.format) is not None and not receiver(cfg.scene.format).recorded:
        known = ", ".join(f"{r.name} ({r.export_folder}_dev/)" for r in RECEIVERS.values() if r.recorded)
        out.append(ConfigError(f"{at(where, 'scene.format')}: recorded datasets are distributed as {known}; "
                               f"{cfg.scene.format!r} is not one"))
    frames = rec.hop / cfg.audio.label_hop if cfg.audio.label_hop > 0 else 0.0
    if rec.hop and (frames < 1 - 1e-6 or abs(frames - round(frames)) > 1e-6):
        out.append(ConfigError(f"{at(where, 'recorded.hop')}: recorded.hop {rec.hop:g} s is not a whole number of "
                               f"label frames ({cfg.audio.label_hop:g} s); use 0 (the window) or e.g. "
                               f"{max(1, round(frames)) * cfg.audio.label_hop:g}"))
    if rec.min_active > cfg.audio.duration:
        out.append(ConfigError(f"{at(where, 'recorded.min_active', 'audio.duration')}: recorded.min_active "
                               f"{rec.min_active:g} s is longer than the window (audio.duration {cfg.audio.duration:g}"
                               f" s): no source could be a target"))
    sc, plain = cfg.scene, type(cfg.scene)()
    rendered_only = [k for k in ("query", "pairing", "same_kind_distractors", "onset", "motion", "levels",
                                 "interferers", "scenario") if getattr(sc, k) != getattr(plain, k)]
    if rendered_only:
        out.append(ConfigError(f"{at(where, 'scene.' + rendered_only[0])}: scene.{rendered_only[0]} shapes rendered "
                               f"scenes; a recorded scene's sources, timing and query come from its recording and "
                               f"labels (docs/recorded.md): leave it unset"))
    if not any(RELATIONS[Relation(r)].needs != "level" for r in sc.relations if r in RELATION_NAMES):
        out.append(ConfigError(f"{at(where, 'scene.relations')}: none of {list(sc.relations)} can be decided on a "
                               f"recording (its sources' levels cannot be measured apart); give starts_first, "
                               f"starts_last, heard_at, nearest, farthest or moving"))
    bad = [c for c in rec.columns if c not in RECORDED_COLUMNS]
    if bad or (rec.columns and not {"frame", "class"} <= set(rec.columns)):
        out.append(ConfigError(f"{at(where, 'recorded.columns')}: columns are named from "
                               f"{', '.join(RECORDED_COLUMNS)} and include frame and class"
                               + (f"; {bad[0]!r} is not one" if bad else "")))
    if rec.dataset == RecordedSet.CUSTOM and not rec.ontology:
        out.append(ConfigError(f"{at(where, 'recorded.ontology')}: recorded.dataset = \"custom\" needs your "
                               f"classes: recorded.ontology = FILE (docs/recorded.md)"))
    return out


def _hardware_problems(cfg: Config, where: str) -> list[ConfigError]:
    """[hardware] with the receivers: capsules to put it on (not a format such as FOA), a
    device per capsule, a response file that reads."""
    hw = cfg.hardware
    if not hw.on and not hw.devices:
        return []
    if cfg.recorded.on:
        return [ConfigError(f"{at(where, 'hardware.profile', 'recorded.dataset')}: recorded scenes were made with real "
                            f"microphones; [hardware] does not apply to them: leave it unset")]
    names = [n for n in (cfg.scene.format, *cfg.scene.receivers) if canonical(n) is not None]
    out = []
    for name in names:
        spec = receiver(name)
        if spec.coincident:
            base = f" (mixed from {spec.base})" if spec.base else ""
            out.append(ConfigError(f"{at(where, 'hardware.profile', 'scene.format', 'scene.receivers')}: [hardware] "
                                   f"cannot go on {spec.name}{base}: it is a format, not a microphone, its channels "
                                   f"encoded from capsules; put it on the capsules (scene.format = \"tetra\" or "
                                   f"\"em32\") or leave [hardware] unset"))
            return out
    if hw.devices:
        devs = hw.devices
        if not all(isinstance(d, int) and not isinstance(d, bool) and 0 <= d < MAX_CHANNELS_DEVICES for d in devs) \
                or 0 not in devs:
            out.append(ConfigError(f"{at(where, 'hardware.devices')}: hardware.devices gives each capsule's device as a "
                                   f"whole number from 0 (the first device, whose clock the others are timed "
                                   f"against), e.g. [0, 0, 1, 1]; got {list(devs)!r}"))
        else:
            for name in names:
                if receiver(name).configured and not cfg.array.capsules:
                    continue  # receiver_problems names a custom array without capsules
                n = array_poses(cfg)[names.index(name)].n_channels
                if n != len(devs):
                    out.append(ConfigError(f"{at(where, 'hardware.devices', 'scene.format')}: hardware.devices names "
                                           f"{len(devs)} capsules but {name} has {n}; give one device per capsule"))
                    break
    if hw.response:
        try:
            read_response(hw.response)
        except ConfigError as e:
            out.append(ConfigError(f"{at(where, 'hardware.response')}: {e}"))
    return out


MAX_CHANNELS_DEVICES = 64  # a device index is below the most capsules a receiver has


def _noise_problems(cfg: Config, where: str) -> list[ConfigError]:
    """[noise] and scene.levels with the rest of the config."""
    out = []
    if cfg.noise.ambience and cfg.scene.receivers:
        out.append(ConfigError(f"{at(where, 'noise.ambience', 'scene.receivers')}: noise.ambience is a recording made "
                               f"with one receiver, so it cannot be heard by scene.receivers too; make one dataset per "
                               f"receiver, or use noise.diffuse (simulated for every receiver)"))
    if cfg.scene.levels == LevelModel.DISTANCE and (cfg.scene.same_kind_distractors > 0
                                                     or QueryType.COMPOSITE in set(cfg.scene.query.options)):
        out.append(ConfigError(f"{at(where, 'scene.levels')}: same-kind distractors (composite queries) are told "
                               f"apart by their TIR, which scene.levels = \"distance\" does not set; use "
                               f"scene.levels = \"tir\" with them"))
    sensor = cfg.noise.sensor_level.bounds
    if cfg.noise.sensor == SensorLevel.DBFS and sensor is not None and \
            sensor[1] > min(0.0, cfg.audio.target_level_dbfs + MAX_NOISE_OVER_TARGET_DB):
        # the other noises are set by an SNR of at least -20 dB; sensor noise in dBFS is held to the same
        top = min(0.0, cfg.audio.target_level_dbfs + MAX_NOISE_OVER_TARGET_DB)
        out.append(ConfigError(f"{at(where, 'noise.sensor_level', 'noise.sensor')}: noise.sensor_level up to "
                               f"{sensor[1]:g} dBFS would bury the target at audio.target_level_dbfs = "
                               f"{cfg.audio.target_level_dbfs:g} dBFS (more than {MAX_NOISE_OVER_TARGET_DB:g} dB above "
                               f"it, as no other noise may be); keep it at most {top:g} dBFS, e.g. "
                               f"[\"uniform\", -90.0, -70.0]"))
    return out


def _query_problems(cfg: Config, where: str) -> list[ConfigError]:
    """Queries, pairing and similarity (docs/queries.md)."""
    sc, out = cfg.scene, []
    known = values(Relation)
    bad = [r for r in sc.relations if r not in known]
    if bad or not sc.relations:
        out.append(ConfigError(f"{where}: scene.relations = {list(sc.relations)!r}: "
                               f"{'unknown ' + repr(bad[0]) if bad else 'empty'}; choose among {', '.join(known)}"))
    wants = {o for o in sc.query.options if isinstance(o, str)}  # field_problems names any other value
    same_kind = sc.same_kind_distractors > 0 or QueryType.COMPOSITE in wants
    if not bad and same_kind and not {Relation.LOUDEST, Relation.QUIETEST} & set(sc.relations):
        out.append(ConfigError(f"{where}: scene.relations must include loudest or quietest when scenes hold same-kind "
                               f"distractors (composite queries or scene.same_kind_distractors > 0): the planner "
                               f"guarantees those scenes a true query through the distractors' TIR"))
    if sc.hard_similarity >= sc.caption_similarity and sc.pairing == Pairing.HARD:
        out.append(ConfigError(f"{where}: scene.hard_similarity {sc.hard_similarity} must be below "
                               f"scene.caption_similarity {sc.caption_similarity}: the hard band lies between them"))
    if sc.easy_similarity > sc.caption_similarity:
        out.append(ConfigError(f"{where}: scene.easy_similarity {sc.easy_similarity} is above the guard "
                               f"scene.caption_similarity {sc.caption_similarity}; lower it"))
    if same_kind and sc.same_kind_similarity <= sc.caption_similarity:
        out.append(ConfigError(f"{where}: scene.same_kind_similarity {sc.same_kind_similarity} must be above "
                               f"scene.caption_similarity {sc.caption_similarity}: a same-kind distractor is one the "
                               f"caption also describes"))
    ob = sc.onset.bounds
    if ob is not None and ob[1] >= cfg.audio.duration:
        out.append(ConfigError(f"{where}: scene.onset can reach {ob[1]} s, but scenes last audio.duration = "
                               f"{cfg.audio.duration} s; a source must start before the scene ends"))
    if sc.similarity == SimilarityMeasure.NONE and (sc.pairing != Pairing.RANDOM or same_kind):
        what = f"scene.pairing = {str(sc.pairing)!r}" if sc.pairing != Pairing.RANDOM else "same-kind distractors"
        out.append(ConfigError(f"{where}: with {what}, clips are drawn by caption similarity, but "
                               f"scene.similarity = \"none\" measures none; choose \"lexicon\" (the default) or "
                               f"another measure"))
    emb = cfg.corpus.caption_embeddings
    if sc.similarity == SimilarityMeasure.EMBEDDINGS and not emb:
        out.append(ConfigError(f"{where}: scene.similarity = \"embeddings\" needs corpus.caption_embeddings = "
                               f"FILE.npz (write one with `tsel corpus embed`), or use \"lexicon\""))
    if emb and sc.similarity != SimilarityMeasure.EMBEDDINGS:
        out.append(ConfigError(f"{where}: corpus.caption_embeddings is set but scene.similarity is "
                               f"{sc.similarity!r}; set scene.similarity = \"embeddings\" to use it"))
    return out


def rooms_without_bank(cfg: Config) -> ConfigError | None:
    """A split that makes scenes names bank rooms but ``room.bank`` is empty (a recorded
    dataset's rooms are its recordings')."""
    roomed = [n for n, sp in cfg.splits.items() if sp.rooms and sp.count and not cfg.recorded.on]
    if roomed and not cfg.room.bank:
        return ConfigError(f"splits.{roomed[0]}.rooms names RIR-bank rooms but room.bank is not set; pass --bank "
                           f"PATH (a TAU-SRIR DB folder, SOFA files or a tsel bank) or remove the rooms")
    return None


# --- geometry -------------------------------------------------------------------------------------


def geometry_problems(cfg: Config, where: str | None = None) -> list[GeometryError]:
    """Layouts no scene drawn from the config's ranges could realise (simulated rooms
    only). First the *largest* room the ranges allow: it must hold the wall margins, the
    heights and the minimum source distance; if it does, the *smallest* room: the array
    (its radius plus ``array.wall_margin``) fits its floor, sources fit between their
    wall margins, heights fit under its ceiling, and the minimum source distance is
    reachable in it (diagonal of the floor area left by the margins, with the largest
    height difference). Returns GeometryErrors naming the keys to change.
    """
    where = origin(cfg, where)
    r, arr, src = cfg.room, cfg.array, cfg.sources
    if r.bank:
        return []
    bounds = {k: getattr(r, k).bounds for k in ("length", "width", "height")}
    if (any(b is None or b[0] <= 0 for b in bounds.values()) or arr.height.bounds is None
            or src.height.bounds is None or src.distance.bounds is None):
        return []  # field_problems reports non-numeric and non-positive ranges
    out = _largest_room_problems(cfg, bounds, where)
    return out or _smallest_room_problems(cfg, bounds, where)


def _largest_room_problems(cfg: Config, bounds: dict, where: str) -> list[GeometryError]:
    arr, src = cfg.array, cfg.sources
    lmax, wmax, hmax = bounds["length"][1], bounds["width"][1], bounds["height"][1]
    out = []
    floor = min(lmax, wmax)
    if floor < 2 * arr.wall_margin or floor < 2 * src.wall_margin:
        out.append(GeometryError(
            f"{at(where, 'array.wall_margin', 'sources.wall_margin', 'room.length', 'room.width')}: the largest room ({floor} m) is smaller than twice the wall margin (array "
            f"{arr.wall_margin} m, sources {src.wall_margin} m); lower the margins or enlarge the room"))
    if arr.height.bounds[0] >= hmax or src.height.bounds[0] >= hmax - src.wall_margin:
        out.append(GeometryError(f"{at(where, 'array.height', 'sources.height', 'room.height')}: array or source heights do not fit under the tallest ceiling "
                                 f"({hmax} m); lower array.height or sources.height, or raise room.height"))
    dmin = src.distance.bounds[0]
    reach = max(lmax, wmax) - arr.wall_margin - src.wall_margin
    if dmin > reach:
        out.append(GeometryError(f"{at(where, 'sources.distance', 'room.length', 'room.width')}: sources.distance minimum {dmin} m cannot fit in the largest room "
                                 f"(at most {reach:.2f} m from the array); lower it or enlarge the room"))
    return out


def _smallest_room_problems(cfg: Config, bounds: dict, where: str) -> list[GeometryError]:
    arr, src = cfg.array, cfg.sources
    lmin, wmin, hmin = bounds["length"][0], bounds["width"][0], bounds["height"][0]
    out = []
    floor = min(lmin, wmin)
    radius = max(p.radius() for p in array_poses(cfg, side=arr.side.bounds[1] if arr.side.bounds else 0.0))
    need = 2 * (arr.wall_margin + radius)
    if floor < need:
        key = "room.length" if lmin <= wmin else "room.width"
        out.append(GeometryError(
            f"{at(where, key, 'array.wall_margin', 'array.side')}: {key} minimum {floor} m is smaller than the array plus its margins ({need:.2f} m = 2 x "
            f"(array.wall_margin {arr.wall_margin} + array radius {radius:.3f})); raise the minimum to at least "
            f"{need:.2f} m or lower array.wall_margin"))
    if floor <= 2 * src.wall_margin:
        out.append(GeometryError(
            f"{at(where, 'sources.wall_margin', 'room.length', 'room.width')}: the smallest room ({floor} m) leaves no floor between the sources' wall margins "
            f"(2 x sources.wall_margin = {2 * src.wall_margin} m); raise the room minimum or lower "
            f"sources.wall_margin"))
    if arr.height.bounds[0] >= hmin:
        out.append(GeometryError(
            f"{at(where, 'array.height', 'room.height')}: array.height minimum {arr.height.bounds[0]} m does not fit under the lowest ceiling "
            f"(room.height minimum {hmin} m); lower array.height or raise room.height"))
    top = hmin - src.wall_margin
    if src.height.bounds[0] > top:
        out.append(GeometryError(
            f"{at(where, 'sources.height', 'sources.wall_margin', 'room.height')}: sources.height minimum {src.height.bounds[0]} m is above the highest source position in the "
            f"lowest room ({hmin} m - sources.wall_margin {src.wall_margin} m = {top:.2f} m); lower sources.height "
            f"or raise room.height"))
    if not out:
        reach_xy = math.hypot(max(lmin - arr.wall_margin - src.wall_margin, 0.0),
                              max(wmin - arr.wall_margin - src.wall_margin, 0.0))
        dz = max(abs(src.height.bounds[1] - arr.height.bounds[0]), abs(arr.height.bounds[1] - src.height.bounds[0]))
        reach = math.hypot(reach_xy, min(dz, hmin))
        dmin = src.distance.bounds[0]
        if dmin > reach:
            out.append(GeometryError(
                f"{at(where, 'sources.distance', 'room.length', 'room.width', 'room.height')}: sources.distance minimum {dmin} m cannot fit in the smallest room ({lmin} x {wmin} x "
                f"{hmin} m; at most {reach:.2f} m from the array given the wall margins); lower sources.distance or "
                f"raise the room minimum"))
    return out


# --- all of them ------------------------------------------------------------------------------------


def config_problems(cfg: Config, where: str | None = None, geometry: bool = True) -> list[ConfigError]:
    """Every problem of a parsed config: fields, then across fields, then (if the fields
    are sound) geometry."""
    where = origin(cfg, where)
    out = field_problems(cfg, where)
    out += cross_field_problems(cfg, where)
    if geometry and not out:
        out += geometry_problems(cfg, where)
    return out


def validate_config(cfg: Config, where: str | None = None, geometry: bool = True) -> None:
    """Raise the first problem of :func:`config_problems`."""
    where = origin(cfg, where)
    problems = config_problems(cfg, where, geometry)
    if problems:
        raise problems[0]
