"""Which keys two configs set differently: what a refused ``--resume`` names, and what
``--grow`` may change (the scene counts)."""
from __future__ import annotations

from dataclasses import dataclass

from .load import parse_config
from .schema import Config


@dataclass(frozen=True)
class Difference:
    """One key set differently: its dotted name, the stored value and the new one
    (None where a key or split is absent)."""

    key: str
    before: object
    after: object

    def __str__(self) -> str:
        return f"{self.key} (planned {_show(self.before)}, now {_show(self.after)})"


def config_differences(stored: dict, cfg: Config, where: str = "stored config") -> list[Difference]:
    """The keys where ``cfg`` differs from ``stored`` (a config as plain data, e.g. from
    ``plan/config.json``), in config order. ``stored`` is parsed first, so a key added to
    the schema since it was written compares as its default (or, for a key whose default
    changed, as the former one). Raises ConfigError if it does not parse."""
    before = parse_config(stored, where=where, validate=False, stored=True).to_dict(every_key=True)
    return _diff(before, cfg.to_dict(every_key=True), "")


def _diff(a, b, prefix: str) -> list[Difference]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in list(a) + [k for k in b if k not in a]:
            out += _diff(a.get(k), b.get(k), f"{prefix}{k}" if not prefix else f"{prefix}.{k}")
        return out
    return [] if a == b else [Difference(prefix, a, b)]


def _show(v) -> str:
    return "nothing" if v is None else repr(v) if isinstance(v, str) else str(v)
