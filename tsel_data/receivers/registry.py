"""The receivers by name: :func:`receiver` looks one up, :func:`canonical` resolves an alias."""
from __future__ import annotations

from ..errors import ConfigError
from .builtin import BUILTIN
from .spec import ReceiverSpec

RECEIVERS: dict[str, ReceiverSpec] = {spec.name: spec for spec in BUILTIN}
ALIASES: dict[str, str] = {alias: spec.name for spec in BUILTIN for alias in spec.aliases}
NAMES: tuple[str, ...] = tuple(RECEIVERS)


def canonical(name) -> str | None:
    """A receiver's own name for ``name`` or one of its aliases (TAU's ``mic`` is
    ``tetra``), case-insensitive; None when nothing is called that."""
    key = str(name).lower()
    if key in RECEIVERS:
        return key
    return ALIASES.get(key)


def receiver(name) -> ReceiverSpec:
    """The spec of receiver ``name`` (or an alias); ConfigError naming the known ones."""
    spec = RECEIVERS.get(name)
    if spec is not None:
        return spec
    key = canonical(name)
    if key is None:
        raise ConfigError(f"unknown receiver (array format) {name!r}; known: {', '.join(NAMES)}")
    return RECEIVERS[key]
