"""Loading a config: preset, file, ``--set`` overrides and the CLI's shortcuts, merged in
that order into a typed, validated :class:`~tsel_data.config.schema.Config`.

Unknown keys are errors that name the closest known key. Paths declared ``path=True``
in the schema (``corpus.dir``, ``room.bank``) resolve against the config file's folder.
"""
from __future__ import annotations

import difflib
import os
import tomllib
from dataclasses import fields
from importlib import resources
from typing import Any

from ..core.files import check_input
from ..errors import ConfigError
from ..scene.distributions import Dist
from .rules import MAX_DEPTH, Where, at, check_raw_config, validate_config
from .schema import HARDWARE_PROFILES, SECTIONS, TOP_FIELDS, TOP_KEYS, Config, SplitConfig

BUILTIN_PREFIX = "builtin:"  # corpus.dir / room.bank values the run builds itself


def preset_names() -> list[str]:
    return sorted(p.name[:-5] for p in resources.files("tsel_data.config.presets").iterdir() if p.name.endswith(".toml"))


def preset_text(name: str) -> str:
    """The TOML text of a built-in preset (ConfigError naming the presets if unknown)."""
    if name not in preset_names():
        raise ConfigError(f"unknown preset {name!r}; available: {', '.join(preset_names())}")
    return (resources.files("tsel_data.config.presets") / f"{name}.toml").read_text(encoding="utf-8")


def load_config(preset: str | None = None, path: str | None = None, overrides=(), *,
                corpus_dir: str | None = None, bank: str | None = None, seed: int | None = None,
                splits: dict | None = None, validate: bool = True, manifest: str | None = None) -> Config:
    """Build a Config from a preset and/or a TOML file, then ``--set`` overrides, then the
    CLI's shortcuts (later ones win).

    Parameters
    ----------
    preset : str, optional
        A built-in preset name (:func:`preset_names`).
    path : str, optional
        A TOML file; its relative paths resolve against its folder.
    overrides : iterable of str
        ``section.key=value`` (value in TOML syntax, or a bare word).
    corpus_dir, bank : str, optional
        Set ``corpus.dir`` and ``room.bank``.
    seed : int, optional
    splits : dict, optional
        {split name: scene count}.
    manifest : str, optional
        One manifest for every split (``--manifest``): ``splits.NAME.manifest`` of every
        split, and ``corpus.format = "auto"``.
    validate : bool
        Raise the first problem of the parsed config; ``tsel check`` passes False and
        collects every problem itself.

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        One line naming the file or preset, the key and the fix.
    """
    # (label, raw table) in the order they apply; an error about a key names the last
    # source that set it (rules.Where), so a bad --set value is not blamed on the preset
    layers: list[tuple[str, dict]] = []
    if preset:
        layers.append((f"preset {preset}", _parse_toml(preset_text(preset), f"preset {preset}")))
    if path:
        layers.append((path, _read_user_file(path)))
    layers += [(f"--set {_printable(ov.strip())}", _parse_override(ov)) for ov in overrides]
    if corpus_dir:
        layers.append(("--corpus-dir", {"corpus": {"dir": corpus_dir}}))
    if bank:
        layers.append(("--bank", {"room": {"bank": bank}}))
    if seed is not None:
        layers.append(("--seed", {"seed": seed}))
    defined = _split_names(layers)
    for name, count in (splits or {}).items():
        if defined and name not in defined and not manifest:
            # a new name would be a split without a manifest; most likely a misspelt one
            raise ConfigError(f"--split {_printable(name)}={count}: there is no split {name!r}; the splits are "
                              f"{', '.join(defined)} (to make a new one, add a [splits.{_printable(name)}] table to "
                              f"the config)")
        layers.append((f"--split {name}={count}", {"splits": {name: {"count": count}}}))
    if manifest:
        named = set(_split_names(layers))
        layers.append(("--manifest", {"corpus": {"format": "auto"},
                                      "splits": {n: {"manifest": manifest} for n in sorted(named)}}))
    raw: dict = {}
    origins: dict[str, str] = {}
    for label, table in layers:
        clash = _table_over_value(raw, table)
        if clash:
            hint = f"; set the keys inside it instead (e.g. {clash}.count)" if clash.startswith("splits.") else ""
            raise ConfigError(f"{label}: {clash} is set to a value, not a table (by {origins.get(clash, 'the config')})"
                              f"{hint}")
        raw = _merge(raw, table)
        origins.update((key, label) for key in _leaf_keys(table))
    base = path or (f"preset {preset}" if preset else "config")
    # keys the base file or preset sets are labelled by it (the default label)
    origins = {k: v for k, v in origins.items() if v != base}
    return parse_config(raw, where=Where(base, origins), validate=validate)


def parse_config(raw: dict, where: str = "config", validate: bool = True, stored: bool = False) -> Config:
    """Raw (TOML-shaped) data -> Config; ``validate`` raises its first problem. ``stored``:
    ``raw`` is a dataset's own config (``plan/config.json``), in which a key whose default
    changed and is absent means its ``former`` default, the one it was planned with."""
    check_raw_config(raw, where)
    _check_keys(raw, TOP_KEYS, where, "")
    kw: dict[str, Any] = {}
    top = {f.name: f for f in fields(Config)}
    for key in TOP_FIELDS:
        if key in raw:
            kw[key] = _parse_value(raw[key], top[key], Config(), where, key)
    for sec, cls in SECTIONS.items():
        kw[sec] = _parse_section(_with_profile(raw.get(sec, {})) if sec == "hardware" else raw.get(sec, {}), cls,
                                 where, sec, stored)
    splits = {}
    for name, sraw in (raw.get("splits") or {}).items():
        if not isinstance(sraw, dict):
            raise ConfigError(f"{at(where, f'splits.{name}')}: splits.{name} must be a table with manifest and count")
        splits[name] = _parse_section(sraw, SplitConfig, where, f"splits.{name}")
    kw["splits"] = splits
    cfg = Config(**kw)
    # where each value came from, for the messages of checks run later (`tsel check`)
    object.__setattr__(cfg, "_where", where)
    if validate:
        validate_config(cfg, where)
    return cfg


# --- helpers -----------------------------------------------------------------------------


def _with_profile(hardware):
    """``[hardware]`` with its profile's values (schema.HARDWARE_PROFILES) under every key it
    leaves unset, so the parsed config, and the config a dataset stores, hold what is drawn."""
    profile = hardware.get("profile") if isinstance(hardware, dict) else None
    if not isinstance(profile, str) or profile not in HARDWARE_PROFILES:
        return hardware  # the schema says what is wrong with a profile of another type
    return {**HARDWARE_PROFILES[hardware["profile"]], **hardware}


def _split_names(layers) -> list[str]:
    """The split names the (label, table) layers define, in the order they first appear."""
    names: dict[str, None] = {}
    for _, table in layers:
        if isinstance(table.get("splits"), dict):
            names.update(dict.fromkeys(table["splits"]))
    return list(names)


def _read_user_file(path: str) -> dict:
    check_input(path, ConfigError, "give the TOML config file itself")
    if not os.path.isfile(path):
        raise ConfigError(f"config file not found: {path}")
    try:
        with open(path, "rb") as f:
            text = f.read().decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not UTF-8 text") from None
    user = _parse_toml(text, path)
    check_raw_config(user, path)
    base_dir = os.path.dirname(os.path.abspath(path))
    for sec, cls in SECTIONS.items():
        table = user.get(sec, {})
        for f in fields(cls):
            if not f.metadata.get("path"):
                continue
            if not isinstance(table, dict) or not isinstance(table.get(f.name, ""), str):
                raise ConfigError(f"{path}: [{sec}] must be a table and {sec}.{f.name} a string path")
            value = table.get(f.name)
            if value and not value.startswith(BUILTIN_PREFIX):
                table[f.name] = os.path.join(base_dir, os.path.expanduser(value))
    return user


def _parse_toml(text: str, where: str) -> dict:
    _check_depth(text, where)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{where}: not valid TOML: {e}") from None
    except RecursionError:  # what _check_depth's scan missed
        raise ConfigError(f"{where}: values nested too deeply; no config value nests more than {MAX_DEPTH} "
                          f"levels") from None


def _check_depth(text: str, where: str) -> None:
    """ConfigError when brackets or braces outside strings nest deeper than MAX_DEPTH:
    the TOML parser would recurse until Python stops it (a 5,000-deep list)."""
    depth = deepest = 0
    quote = ""
    escaped = False
    for c in text:
        if quote:
            if escaped:
                escaped = False
            elif c == "\\" and quote == '"':
                escaped = True
            elif c == quote:
                quote = ""
        elif c in "\"'":
            quote = c
        elif c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth -= 1
    if deepest > MAX_DEPTH:
        raise ConfigError(f"{where}: values nested {deepest} levels deep; no config value nests more than "
                          f"{MAX_DEPTH} (array.capsules is [[x, y, z], ...]): check the brackets")


def _parse_override(ov: str) -> dict:
    if "=" not in ov:
        raise ConfigError(f"--set {ov!r}: expected section.key=value, e.g. --set room.rt60=0.6")
    key, value = ov.split("=", 1)
    try:
        _check_depth(value, f"--set {key.strip()}")
        parsed = tomllib.loads(f"v = {value}")["v"]
    except RecursionError:
        raise ConfigError(f"--set {key.strip()}: values nested too deeply; no config value nests more than {MAX_DEPTH} "
                          f"levels") from None
    except tomllib.TOMLDecodeError:
        parsed = value  # a bare word: treat as a string
    out: dict = {}
    node = out
    parts = key.strip().split(".")
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = parsed
    return out


def _printable(text: str) -> str:
    """``text`` with control characters escaped, so a label keeps an error on one line."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


def _leaf_keys(table, prefix: str = ""):
    """Dotted keys of a raw table's values (``room.rt60``), tables descended into."""
    if not isinstance(table, dict):
        return
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v:
            yield from _leaf_keys(v, key + ".")
        else:
            yield key


def _table_over_value(a: dict, b: dict, prefix: str = "") -> str | None:
    """The first key that ``b`` sets keys inside while ``a`` holds a plain value there."""
    for k, v in b.items():
        if isinstance(v, dict) and k in a:
            if not isinstance(a[k], dict):
                return prefix + str(k)
            inner = _table_over_value(a[k], v, f"{prefix}{k}.")
            if inner:
                return inner
    return None


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _check_keys(raw: dict, known, where: str, prefix: str) -> None:
    if not isinstance(raw, dict):
        raise ConfigError(f"{at(where, prefix.rstrip('.'))}: {prefix.rstrip('.') or 'config'} must be a table")
    for k in raw:
        if k not in known:
            close = difflib.get_close_matches(k, list(known), n=1, cutoff=0.5)
            hint = f"; did you mean {prefix}{close[0]}?" if close else f"; known keys: {', '.join(known)}"
            raise ConfigError(f"{at(where, prefix + str(k))}: unknown config key {prefix}{k!r}{hint}")


def _parse_section(raw: dict, cls, where: str, sec: str, stored: bool = False):
    _check_keys(raw, [f.name for f in fields(cls)], where, f"{sec}.")
    defaults = cls()
    kw = {f.name: _parse_value(raw[f.name], f, defaults, where, f"{sec}.{f.name}") for f in fields(cls)
          if f.name in raw}
    if stored:
        kw.update({f.name: f.metadata["former"] for f in fields(cls)
                   if f.name not in raw and f.metadata.get("former") is not None})
    return cls(**kw)


def _parse_value(v, f, defaults, where: str, key: str):
    """One raw value, typed like the field's default."""
    if f.metadata.get("dist"):
        return Dist.parse(v, f"{at(where, key)}: {key}")
    default = getattr(defaults, f.name)
    if f.metadata.get("many") and isinstance(v, list):
        if not v or not all(isinstance(x, str) and x for x in v):
            raise ConfigError(f"{at(where, key)}: {key} must be a string or a list of non-empty strings, got {v!r}")
        return tuple(v)
    if isinstance(default, tuple):
        return _frozen(v) if isinstance(v, list) else (v,)
    if isinstance(default, (bool, str)):
        if not isinstance(v, type(default)):
            raise ConfigError(f"{at(where, key)}: {key} must be a {type(default).__name__}, got {v!r}")
        return v
    if isinstance(default, (int, float)):
        whole = not isinstance(default, int) or float(v).is_integer() if isinstance(v, (int, float)) else False
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not whole:
            kind = "a whole number" if isinstance(default, int) else "a number"
            raise ConfigError(f"{at(where, key)}: {key} must be {kind}, got {v!r}")
        return type(default)(v)
    return v


def _frozen(v):
    """Lists as tuples, all the way down (a config is frozen and hashable)."""
    return tuple(_frozen(x) for x in v) if isinstance(v, list) else v
