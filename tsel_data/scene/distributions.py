"""Parameter distributions, scaper-style.

In a config a parameter is either a constant (``0.5``, ``"mic4"``) or a list naming a
distribution: ``["uniform", a, b]``, ``["choose", [x, y, ...]]`` (optionally with
weights: ``["choose", [x, y], [0.7, 0.3]]``), ``["normal", mean, std]``,
``["truncnorm", mean, std, lo, hi]``, ``["const", x]``. Every sample is drawn from a
caller's ``numpy.random.Generator``; nothing here holds random state.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError

KINDS = ("const", "uniform", "choose", "normal", "truncnorm")


@dataclass(frozen=True)
class Dist:
    """A sampled parameter: ``kind`` (one of :data:`KINDS`) and its arguments.

    Parameters
    ----------
    kind : str
        ``const``, ``uniform``, ``choose``, ``normal`` or ``truncnorm``.
    args : tuple
        As written in the config after the kind (``choose``: (options,) or (options,
        weights)).

    ``Dist.parse(value, where)`` validates a config value; ``sample(rng)`` draws from a
    caller's generator; ``bounds`` is the numeric range it can produce (for checks over
    a whole range); ``options`` the values of a const/choose; ``to_json`` the config form.
    """

    kind: str
    args: tuple

    @classmethod
    def parse(cls, value: Any, where: str) -> "Dist":
        if isinstance(value, Dist):
            return value
        if not isinstance(value, (list, tuple)):
            return cls("const", (value,))
        if not value or value[0] not in KINDS:
            raise ConfigError(
                f"{where}: {value!r} is not a distribution; write a constant or "
                f'["uniform", lo, hi], ["choose", [..]], ["normal", mean, std], ["truncnorm", mean, std, lo, hi]'
            )
        kind, args = value[0], tuple(value[1:])
        need = {"const": (1,), "uniform": (2,), "choose": (1, 2), "normal": (2,), "truncnorm": (4,)}[kind]
        if len(args) not in need:
            raise ConfigError(f"{where}: {kind} takes {' or '.join(map(str, need))} argument(s), got {len(args)}: {value!r}")
        if kind == "uniform":
            lo, hi = _numbers(args, where)
            if lo > hi:
                raise ConfigError(f"{where}: uniform range has min {lo} > max {hi}; swap them")
        if kind == "truncnorm":
            m, s, lo, hi = _numbers(args, where)
            if lo > hi or s < 0:
                raise ConfigError(f"{where}: truncnorm needs std >= 0 and lo <= hi, got {value!r}")
        if kind == "normal" and _numbers(args, where)[1] < 0:
            raise ConfigError(f"{where}: normal needs std >= 0, got {value!r}")
        if kind == "choose":
            if not isinstance(args[0], (list, tuple)) or not args[0]:
                raise ConfigError(f"{where}: choose needs a non-empty list of options, got {value!r}")
            if len(args) == 2:
                w = _numbers(args[1], where)
                if len(w) != len(args[0]) or min(w) < 0 or sum(w) <= 0:
                    raise ConfigError(f"{where}: choose weights must be {len(args[0])} non-negative numbers, got {args[1]!r}")
            args = tuple(tuple(a) for a in args)
        return cls(kind, args)

    def sample(self, rng: np.random.Generator):
        k, a = self.kind, self.args
        if k == "const":
            return a[0]
        if k == "uniform":
            return float(rng.uniform(a[0], a[1]))
        if k == "choose":
            if len(a) == 1:
                return a[0][int(rng.integers(len(a[0])))]
            p = np.asarray(a[1], float) / np.sum(a[1])
            return a[0][int(rng.choice(len(a[0]), p=p))]
        if k == "normal":
            return float(rng.normal(a[0], a[1]))
        m, s, lo, hi = a
        for _ in range(1000):
            x = rng.normal(m, s)
            if lo <= x <= hi:
                return float(x)
        return float(np.clip(m, lo, hi))

    @property
    def bounds(self) -> tuple[float, float] | None:
        """(min, max) a numeric distribution can produce, None when unbounded/non-numeric."""
        k, a = self.kind, self.args
        try:
            if k == "const":
                return float(a[0]), float(a[0])
            if k == "uniform":
                return float(a[0]), float(a[1])
            if k == "truncnorm":
                return float(a[2]), float(a[3])
            if k == "choose":
                vals = [float(v) for v in a[0]]
                return min(vals), max(vals)
        except (TypeError, ValueError):
            return None
        return None

    @property
    def options(self) -> tuple:
        """Every value a const/choose distribution can produce."""
        return (self.args[0],) if self.kind == "const" else self.args[0] if self.kind == "choose" else ()

    def to_json(self):
        return self.args[0] if self.kind == "const" else [self.kind, *[list(x) if isinstance(x, tuple) else x for x in self.args]]


def _numbers(args, where):
    try:
        return [float(x) for x in args]
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: expected numbers, got {list(args)!r}") from None
