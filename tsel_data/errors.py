"""User-facing errors.

Anything a user can fix (a bad manifest row, a missing file, an impossible config)
raises a :class:`TselError`. The CLI prints its message on one line and exits with 2;
it never shows a traceback for these. Library callers can catch the subclasses.
Every error class of the package is defined here.
"""


class TselError(Exception):
    """A mistake in user input: the message says what, where and how to fix it."""


class ManifestError(TselError):
    """A manifest file cannot be read or one of its rows is malformed."""


class AudioError(TselError):
    """An audio file is missing, unreadable or unusable."""


class ConfigError(TselError):
    """A config or preset is invalid."""


class GeometryError(ConfigError):
    """A room, array or source layout that cannot be realised (a kind of config error)."""


class BankError(TselError):
    """An RIR bank is missing, of the wrong kind, or does not hold what was asked for."""


class DatasetError(TselError):
    """An output dataset is missing, incomplete or inconsistent."""


class PredictionError(TselError):
    """A prediction file is malformed or does not match the split."""
