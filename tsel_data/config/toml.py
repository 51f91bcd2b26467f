"""Writing a config as TOML that loads back to the same Config, optionally with each
key's help and unit from the schema as comments (``tsel presets NAME``)."""
from __future__ import annotations

import json
import textwrap
from dataclasses import fields

from ..core.jsonable import jsonable
from .schema import HARDWARE_PROFILES, SECTIONS, TOP_FIELDS, Config, SplitConfig


def to_toml(cfg: Config, comments: bool = False, header: str = "") -> str:
    """The config as TOML that ``load_config(path=...)`` reads back to the same Config.

    comments: put each key's help (and unit) above it. header: text written first as
    ``#`` comment lines (e.g. a preset's own description).
    """
    d = cfg.to_dict(every_key=True)
    lines = [f"# {line}".rstrip() for line in header.splitlines()] + ([""] if header else [])
    top = {f.name: f for f in fields(Config)}
    for k in TOP_FIELDS:
        lines += _entry(k, d[k], top[k], comments)
    for sec, cls in SECTIONS.items():
        lines += ["", f"[{sec}]"] + (_wrap(cls.__doc__) if comments and cls.__doc__ else [])
        specs = {f.name: f for f in fields(cls)}
        unset = _profile_keys(cfg) if sec == "hardware" else ()
        for k, v in d[sec].items():
            lines += _entry(k, v, specs[k], comments, unset=k in unset)
    split_specs = {f.name: f for f in fields(SplitConfig)}
    for name, sp in d["splits"].items():
        lines += ["", f"[splits.{name}]"]
        for k, v in sp.items():
            lines += _entry(k, v, split_specs[k], comments)
    return "\n".join(lines) + "\n"


def _profile_keys(cfg: Config) -> set:
    """``[hardware]`` keys at their default that a profile would fill: written commented out,
    so setting ``profile`` in the file fills them (no profile: they read back the same)."""
    if cfg.hardware.profile in HARDWARE_PROFILES:
        return set()
    default = jsonable(type(cfg.hardware)())
    now = jsonable(cfg.hardware)
    return {k for k in next(iter(HARDWARE_PROFILES.values())) if now[k] == default[k]}


def _entry(key: str, value, f, comments: bool, unset: bool = False) -> list[str]:
    line = f"{'# ' if unset else ''}{key} = {_toml_value(value)}"
    if not comments:
        return [line]
    unit = f.metadata.get("unit")
    return _wrap(f.metadata.get("doc", "") + (f" [{unit}]" if unit else "")) + [line]


def _wrap(text: str) -> list[str]:
    text = " ".join(text.split())
    return [f"# {line}" for line in textwrap.wrap(text, 96)]


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a JSON string is a valid TOML basic string
    return repr(v)
