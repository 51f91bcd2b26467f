"""Dataset configuration: TOML presets and files, ``--set`` overrides, validation.

A config is a few sections of typed fields (below); every sampled parameter is a
:class:`~tsel_data.distributions.Dist`. Loading merges, in order: the preset (package
data ``tsel_data/presets/NAME.toml``), a user TOML file, then ``--set section.key=value``
overrides. Unknown keys are errors that name the closest known key. docs/config.md
documents every field.
"""
from __future__ import annotations

import difflib
import os
import tomllib
from dataclasses import dataclass, field, fields
from importlib import resources
from typing import Any

from .distributions import Dist
from .errors import ConfigError


def _d(v):
    return field(default_factory=lambda: Dist.parse(v, "default"))


@dataclass(frozen=True)
class CorpusConfig:
    """Where the captioned clips come from."""

    format: str = "audiocaps"  # audiocaps | clotho | wavcaps | plain | auto
    dir: str = ""  # manifests and audio are relative to this
    audio_dir: str = ""  # default: dir/audio if it exists, else dir
    audio_template: str = ""  # reader default when empty ({youtube_id}.wav for AudioCaps)
    check: str = "full"  # full | header | exists | none: how much to verify each clip up front
    min_duration: float = 1.0  # seconds; shorter clips are bad clips
    max_channels: int = 8  # more channels than this is a bad clip (probably not a recording)


@dataclass(frozen=True)
class SplitConfig:
    manifest: str = ""
    count: int = 0
    rooms: tuple = ()  # RIR-bank rooms for this split (bank scenes)


@dataclass(frozen=True)
class AudioConfig:
    fs: int = 24000
    duration: float = 10.0
    label_hop: float = 0.1
    activity_threshold_db: float = -30.0  # frame active if within this of the clip's loudest frame
    target_level_dbfs: float = -25.0  # active RMS of the target's image at the array


@dataclass(frozen=True)
class SceneConfig:
    format: str = "mic4"  # mic4 | foa | tetra
    scenario: Dist = _d(["choose", ["two-directional"]])
    interferers: Dist = _d(1)
    tir_db: Dist = _d(["uniform", -5.0, 5.0])
    min_separation: float = 20.0  # degrees of azimuth between directional sources
    separated_frames: float = 0.8  # fraction of label frames on which min_separation must hold (moving sources)
    caption_similarity: float = 0.5  # max word-overlap (Jaccard) between query and other sources' captions
    motion: str = "static"  # static | moving | mixed
    moving_fraction: float = 0.5
    speed: Dist = _d(["choose", [10.0, 20.0, 40.0]])  # degrees/s, bank walks and simulated paths
    path: Dist = _d("arc")  # simulated moving sources: one of PATHS (or a choose of them)


@dataclass(frozen=True)
class RoomConfig:
    length: Dist = _d(["uniform", 5.0, 15.0])
    width: Dist = _d(["uniform", 5.0, 15.0])
    height: Dist = _d(["uniform", 5.0, 15.0])
    rt60: Dist = _d(["uniform", 0.5, 1.0])
    rir_method: str = "hybrid"  # hybrid | ism | pyroomacoustics
    bank: str = ""  # path of an RIR bank; when set, scenes use it instead of simulated rooms


@dataclass(frozen=True)
class ArrayConfig:
    side: Dist = _d(["uniform", 0.10, 0.13])
    height: Dist = _d(["uniform", 1.0, 1.2])
    yaw: Dist = _d(["uniform", -180.0, 180.0])
    wall_margin: float = 1.0


@dataclass(frozen=True)
class SourcesConfig:
    distance: Dist = _d(["uniform", 1.0, 3.0])  # metres from the array centre
    height: Dist = _d(["uniform", 0.5, 2.0])  # metres above the floor
    wall_margin: float = 0.5


@dataclass(frozen=True)
class OutputConfig:
    shard_size: int = 128  # scenes per shard (~3.8 MB per 10 s 4-ch 24 kHz scene)


@dataclass(frozen=True)
class Config:
    name: str = "custom"
    seed: int = 0
    on_bad_clip: str = "skip"  # skip | fail
    corpus: CorpusConfig = field(default_factory=CorpusConfig)
    splits: dict = field(default_factory=dict)  # name -> SplitConfig
    audio: AudioConfig = field(default_factory=AudioConfig)
    scene: SceneConfig = field(default_factory=SceneConfig)
    room: RoomConfig = field(default_factory=RoomConfig)
    array: ArrayConfig = field(default_factory=ArrayConfig)
    sources: SourcesConfig = field(default_factory=SourcesConfig)
    output: OutputConfig = field(default_factory=OutputConfig)

    def to_dict(self) -> dict:
        return _to_plain(self)


SECTIONS = {
    "corpus": CorpusConfig, "audio": AudioConfig, "scene": SceneConfig, "room": RoomConfig,
    "array": ArrayConfig, "sources": SourcesConfig, "output": OutputConfig,
}
TOP_KEYS = ("name", "seed", "on_bad_clip", "splits", *SECTIONS)
PATHS = ("arc", "line")  # how simulated moving sources move (plan._moving_path)
CHOICES = {
    ("corpus", "format"): ("audiocaps", "clotho", "wavcaps", "plain", "auto"),
    ("corpus", "check"): ("full", "header", "exists", "none"),
    ("scene", "format"): ("mic4", "foa", "tetra"),
    ("scene", "motion"): ("static", "moving", "mixed"),
    ("room", "rir_method"): ("hybrid", "ism", "pyroomacoustics"),
    (None, "on_bad_clip"): ("skip", "fail"),
}


def preset_names() -> list[str]:
    return sorted(p.name[:-5] for p in resources.files("tsel_data.presets").iterdir() if p.name.endswith(".toml"))


def load_config(preset: str | None = None, path: str | None = None, overrides: list[str] = (),
                validate: bool = True, **flags) -> Config:
    """Build a validated Config from a preset and/or a TOML file, then overrides.

    ``flags`` are the CLI's shortcuts: ``corpus_dir``, ``seed``, ``splits`` ({name: count}),
    ``bank``. ``validate=False`` skips the checks across fields (``tsel check`` then
    collects every problem instead of stopping at the first).
    """
    raw: dict = {}
    if preset:
        if preset not in preset_names():
            raise ConfigError(f"unknown preset {preset!r}; available: {', '.join(preset_names())}")
        raw = _merge(raw, _read_toml(resources.files("tsel_data.presets") / f"{preset}.toml", f"preset {preset}"))
    if path:
        if not os.path.isfile(path):
            raise ConfigError(f"config file not found: {path}")
        user = _read_toml(path, path)
        from .check import check_raw_config

        check_raw_config(user, path)
        for sec, key in (("corpus", "dir"), ("room", "bank")):
            if not isinstance(user.get(sec, {}), dict) or not isinstance(user.get(sec, {}).get(key, ""), str):
                raise ConfigError(f"{path}: [{sec}] must be a table and {sec}.{key} a string path")
        base_dir = os.path.dirname(os.path.abspath(path))
        cdir = user.get("corpus", {}).get("dir")
        if cdir and not cdir.startswith("builtin:"):
            user["corpus"]["dir"] = os.path.join(base_dir, os.path.expanduser(cdir))
        bank = user.get("room", {}).get("bank")
        if bank and not bank.startswith("builtin:"):
            user["room"]["bank"] = os.path.join(base_dir, os.path.expanduser(bank))
        raw = _merge(raw, user)
    for ov in overrides:
        raw = _merge(raw, _parse_override(ov))
    if flags.get("corpus_dir"):
        raw.setdefault("corpus", {})["dir"] = flags["corpus_dir"]
    if flags.get("bank"):
        raw.setdefault("room", {})["bank"] = os.path.abspath(os.path.expanduser(flags["bank"]))
    if flags.get("seed") is not None:
        raw["seed"] = flags["seed"]
    for name, count in (flags.get("splits") or {}).items():
        raw.setdefault("splits", {}).setdefault(name, {})["count"] = count
    return parse_config(raw, where=path or (f"preset {preset}" if preset else "config"), validate=validate)


def parse_config(raw: dict, where: str = "config", validate: bool = True) -> Config:
    from .check import check_raw_config  # the validation module; imported here to avoid a cycle

    check_raw_config(raw, where)
    _check_keys(raw, TOP_KEYS, where, "")
    kw: dict[str, Any] = {}
    for key in ("name", "seed", "on_bad_clip"):
        if key in raw:
            kw[key] = raw[key]
    for sec, cls in SECTIONS.items():
        kw[sec] = _parse_section(raw.get(sec, {}), cls, where, sec)
    splits = {}
    for name, sraw in (raw.get("splits") or {}).items():
        if not isinstance(sraw, dict):
            raise ConfigError(f"{where}: splits.{name} must be a table with manifest and count")
        splits[name] = _parse_section(sraw, SplitConfig, where, f"splits.{name}")
    kw["splits"] = splits
    cfg = Config(**kw)
    if validate:
        validate_config(cfg, where)
    return cfg


def validate_config(cfg: Config, where: str = "config", smallest_room: bool = True) -> None:
    """Checks that need more than one field: ranges, choices, geometry that cannot work.

    smallest_room: also reject layouts that fail in the smallest room the ranges allow
    (check.geometry_problems; ``tsel check`` collects those itself).
    """
    if not isinstance(cfg.seed, int) or cfg.seed < 0:
        raise ConfigError(f"{where}: seed must be a non-negative integer, got {cfg.seed!r}")
    for (sec, key), allowed in CHOICES.items():
        val = getattr(cfg if sec is None else getattr(cfg, sec), key)
        if val not in allowed:
            name = key if sec is None else f"{sec}.{key}"
            raise ConfigError(f"{where}: {name} = {val!r} is not one of {', '.join(allowed)}")
    if cfg.scene.path.kind not in ("const", "choose") or not all(isinstance(o, str) and o in PATHS for o in cfg.scene.path.options):
        raise ConfigError(f"{where}: scene.path must be \"arc\", \"line\" or [\"choose\", [\"arc\", \"line\"]], "
                          f"got {cfg.scene.path.to_json()!r}")
    for sc in cfg.scene.scenario.options:
        if sc not in ("two-directional", "directional+additive"):
            raise ConfigError(f"{where}: scene.scenario option {sc!r} is not two-directional or directional+additive")
    a = cfg.audio
    if a.fs < 8000 or a.duration <= 0 or a.label_hop <= 0 or a.label_hop > a.duration:
        raise ConfigError(f"{where}: audio needs fs >= 8000, duration > 0 and 0 < label_hop <= duration")
    if abs(a.duration / a.label_hop - round(a.duration / a.label_hop)) > 1e-6:
        raise ConfigError(f"{where}: audio.duration {a.duration} is not a whole number of label_hop {a.label_hop}")
    if cfg.output.shard_size < 1:
        raise ConfigError(f"{where}: output.shard_size must be >= 1")
    for name, sp in cfg.splits.items():
        if not isinstance(sp.count, int) or sp.count < 0:
            raise ConfigError(f"{where}: splits.{name}.count must be a non-negative integer, got {sp.count!r}")
    if not 0.0 < cfg.scene.separated_frames <= 1.0:
        raise ConfigError(f"{where}: scene.separated_frames must be in (0, 1], got {cfg.scene.separated_frames}")
    if not 0.0 <= cfg.scene.moving_fraction <= 1.0:
        raise ConfigError(f"{where}: scene.moving_fraction must be in [0, 1], got {cfg.scene.moving_fraction}")
    sb = cfg.scene.speed.bounds
    if sb is None or sb[0] < 0:
        raise ConfigError(f"{where}: scene.speed must be non-negative degrees per second")
    nb = cfg.scene.interferers.bounds
    if nb is None or nb[0] < 1:
        raise ConfigError(f"{where}: scene.interferers must be >= 1 (a scene holds at least two sources)")
    if cfg.scene.min_separation * (nb[1] + 1) > 360:
        raise ConfigError(f"{where}: scene.min_separation {cfg.scene.min_separation}° is impossible with "
                          f"{int(nb[1]) + 1} directional sources")
    if cfg.room.bank:
        return
    if cfg.scene.format == "foa" and cfg.room.rir_method == "pyroomacoustics":
        raise ConfigError(f"{where}: room.rir_method = \"pyroomacoustics\" renders omni capsules only; "
                          f"use \"hybrid\" or \"ism\" for scene.format = \"foa\"")
    _check_geometry(cfg, where)
    if smallest_room:
        from .check import geometry_problems

        problems = geometry_problems(cfg)
        if problems:
            raise problems[0]


def _check_geometry(cfg: Config, where: str) -> None:
    """Reject rooms that can never hold the array and the sources (before any work)."""
    r, arr, src = cfg.room, cfg.array, cfg.sources
    for key in ("length", "width", "height", "rt60"):
        b = getattr(r, key).bounds
        if b is None or b[0] <= 0:
            raise ConfigError(f"{where}: room.{key} must be positive numbers")
    for key, d in (("array.side", arr.side), ("array.height", arr.height), ("sources.distance", src.distance),
                   ("sources.height", src.height)):
        b = d.bounds
        if b is None or b[0] < 0:
            raise ConfigError(f"{where}: {key} must be non-negative numbers")
    min_floor = min(r.length.bounds[1], r.width.bounds[1])
    if min_floor < 2 * arr.wall_margin or min_floor < 2 * src.wall_margin:
        raise ConfigError(
            f"{where}: the largest room ({min_floor} m) is smaller than twice the wall margin "
            f"(array {arr.wall_margin} m, sources {src.wall_margin} m); lower the margins or enlarge the room")
    if arr.height.bounds[0] >= r.height.bounds[1] or src.height.bounds[0] >= r.height.bounds[1] - src.wall_margin:
        raise ConfigError(f"{where}: array or source heights do not fit under the tallest ceiling "
                          f"({r.height.bounds[1]} m)")
    dmin = src.distance.bounds[0]
    reach = max(r.length.bounds[1], r.width.bounds[1]) - arr.wall_margin - src.wall_margin
    if dmin > reach:
        raise ConfigError(f"{where}: sources.distance minimum {dmin} m cannot fit in the largest room "
                          f"(at most {reach:.2f} m from the array); lower it or enlarge the room")


# --- helpers -----------------------------------------------------------------------------


def _read_toml(path, where) -> dict:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{where}: not valid TOML: {e}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{where}: not UTF-8 text") from None


def _parse_override(ov: str) -> dict:
    if "=" not in ov:
        raise ConfigError(f"--set {ov!r}: expected section.key=value, e.g. --set room.rt60=0.6")
    key, value = ov.split("=", 1)
    try:
        parsed = tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError:
        parsed = value  # a bare word: treat as a string
    out: dict = {}
    node = out
    parts = key.strip().split(".")
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = parsed
    return out


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _check_keys(raw: dict, known, where: str, prefix: str) -> None:
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: {prefix.rstrip('.') or 'config'} must be a table")
    for k in raw:
        if k not in known:
            close = difflib.get_close_matches(k, list(known), n=1, cutoff=0.5)
            hint = f"; did you mean {prefix}{close[0]}?" if close else f"; known keys: {', '.join(known)}"
            raise ConfigError(f"{where}: unknown config key {prefix}{k!r}{hint}")


def _parse_section(raw: dict, cls, where: str, sec: str):
    names = [f.name for f in fields(cls)]
    _check_keys(raw, names, where, f"{sec}.")
    kw = {}
    defaults = cls()
    for f in fields(cls):
        if f.name not in raw:
            continue
        v = raw[f.name]
        default = getattr(defaults, f.name)
        if isinstance(default, Dist):
            kw[f.name] = Dist.parse(v, f"{where}: {sec}.{f.name}")
        elif isinstance(default, tuple):
            kw[f.name] = tuple(v) if isinstance(v, list) else (v,)
        elif isinstance(default, bool) or isinstance(default, str):
            if not isinstance(v, type(default)):
                raise ConfigError(f"{where}: {sec}.{f.name} must be a {type(default).__name__}, got {v!r}")
            kw[f.name] = v
        elif isinstance(default, (int, float)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or (isinstance(default, int) and not isinstance(default, bool) and type(default) is int and not float(v).is_integer()):
                raise ConfigError(f"{where}: {sec}.{f.name} must be a number, got {v!r}")
            kw[f.name] = type(default)(v)
        else:
            kw[f.name] = v
    return cls(**kw)


def _to_plain(x):
    if isinstance(x, Dist):
        return x.to_json()
    if hasattr(x, "__dataclass_fields__"):
        return {f.name: _to_plain(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, dict):
        return {k: _to_plain(v) for k, v in x.items()}
    if isinstance(x, tuple):
        return [_to_plain(v) for v in x]
    return x


def to_toml(cfg: Config) -> str:
    """The config as TOML that ``load_config(path=...)`` reads back to the same Config."""
    d = cfg.to_dict()
    lines = [f"{k} = {_toml_value(d[k])}" for k in ("name", "seed", "on_bad_clip")]
    for sec in SECTIONS:
        lines += ["", f"[{sec}]"] + [f"{k} = {_toml_value(v)}" for k, v in d[sec].items()]
    for name, sp in d["splits"].items():
        lines += ["", f"[splits.{name}]"] + [f"{k} = {_toml_value(v)}" for k, v in sp.items()]
    return "\n".join(lines) + "\n"


def _toml_value(v) -> str:
    import json

    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a valid TOML basic string
    return repr(v)
