"""A receiver's microphones as built for one scene (``[hardware]``): what the planner drew
per capsule and per device, as plain data in the recipe, so rendering stays a function of
the recipe (:class:`Hardware`); and the measured response file it may name
(:func:`read_response`).

What each number does to the audio is dsp/hardware.py; how it is drawn, render/hardware.py.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass

from ..core.jsonable import JsonFields, key, unset
from ..errors import ConfigError

MAX_RESPONSE_ROWS = 512  # a measured response is a few dozen to a few hundred points


def _floats(v):
    return None if v is None else tuple(float(x) for x in v)


def _rows(v):
    return None if v is None else tuple(tuple(float(x) for x in row) for row in v)


@dataclass(frozen=True)
class Hardware(JsonFields):
    """One receiver's capsules and clocks as drawn for one scene (C capsules, D devices).

    gain_db [C]: each capsule's gain off nominal. delay_us [C]: its delay off nominal.
    highpass_hz [C]: its high-pass corner (0: none), a Butterworth of ``highpass_order``.
    tilt_db [C]: its spectral tilt, dB per octave about 1 kHz. self_noise_dba [C]: its
    self-noise, dB SPL A-weighted (None: none), at ``sensitivity_dbfs`` (the level of
    94 dB SPL in the audio). devices [C]: each capsule's device (None: one device);
    clock_offset_us, clock_ppm [D]: each device's lag behind the first at the start and its
    growth, µs per second (device 0: 0, 0). response: a measured response, rows
    (frequency Hz, gain dB for every capsule or one per capsule), with ``response_file``
    its file's name. profile: ``hardware.profile``. seed: the self-noise's draws.
    """

    profile: str
    seed: int = key(decode=int)
    gain_db: tuple = key(encode=list, decode=_floats)
    delay_us: tuple = key(encode=list, decode=_floats)
    highpass_hz: tuple = key(encode=list, decode=_floats)
    highpass_order: int = key(2, decode=int)
    tilt_db: tuple = key((), encode=list, decode=_floats)
    self_noise_dba: tuple | None = key(None, omit=unset("self_noise_dba"), encode=list, decode=_floats)
    sensitivity_dbfs: float = -26.0
    devices: tuple | None = key(None, omit=unset("devices"), encode=list,
                                decode=lambda v: None if v is None else tuple(int(x) for x in v))
    clock_offset_us: tuple | None = key(None, omit=unset("clock_offset_us"), encode=list, decode=_floats)
    clock_ppm: tuple | None = key(None, omit=unset("clock_ppm"), encode=list, decode=_floats)
    response_file: str | None = key(None, omit=unset("response_file"))
    response: tuple | None = key(None, omit=unset("response"), encode=lambda v: [list(r) for r in v],
                                 decode=_rows)

    @property
    def n_channels(self) -> int:
        return len(self.gain_db)

    def self_noise_dbfs(self) -> tuple | None:
        """Each capsule's self-noise in the audio, dBFS A-weighted: dB SPL(A) - 94 + sensitivity."""
        if self.self_noise_dba is None:
            return None
        return tuple(round(v - 94.0 + self.sensitivity_dbfs, 3) for v in self.self_noise_dba)

    def device_of(self) -> tuple:
        """Each capsule's device [C] (all 0 for one device)."""
        return self.devices if self.devices is not None else (0,) * self.n_channels

    def channel_clocks(self) -> tuple[tuple, tuple]:
        """(offset µs [C], ppm [C]): each capsule's device clock."""
        dev = self.device_of()
        off = self.clock_offset_us or (0.0,)
        ppm = self.clock_ppm or (0.0,)
        return tuple(off[d] for d in dev), tuple(ppm[d] for d in dev)


def read_response(path: str, n_channels: int | None = None) -> tuple:
    """A measured response file (``hardware.response``): rows (frequency Hz, gain dB, ...)
    sorted by frequency; one gain column for every capsule, or one per capsule (``n_channels``
    when known). A header row is allowed. One ConfigError line names the file and what is
    wrong."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            lines = [row for row in csv.reader(f) if row and any(c.strip() for c in row)]
    except OSError as e:
        raise ConfigError(f"hardware.response {path}: cannot read it ({e.strerror or e}); give a CSV of "
                          f"frequency_hz and gain_db") from None
    except UnicodeDecodeError:
        raise ConfigError(f"hardware.response {path}: not UTF-8 text; give a CSV of frequency_hz and gain_db") from None
    rows = []
    for n, row in enumerate(lines, 1):
        try:
            vals = tuple(float(c) for c in row)
        except ValueError:
            if n == 1:
                continue  # a header
            raise ConfigError(f"hardware.response {path}:{n}: {','.join(row)[:60]!r} is not numbers; each row is "
                              f"frequency_hz,gain_db[,gain_db ...]") from None
        if len(vals) < 2 or not all(math.isfinite(v) for v in vals) or vals[0] <= 0:
            raise ConfigError(f"hardware.response {path}:{n}: expected a frequency > 0 Hz and finite gains in dB, "
                              f"got {','.join(row)[:60]!r}")
        rows.append(vals)
    if len(rows) < 2:
        raise ConfigError(f"hardware.response {path}: needs at least two rows of frequency_hz,gain_db")
    if len(rows) > MAX_RESPONSE_ROWS:
        raise ConfigError(f"hardware.response {path}: {len(rows)} rows; give at most {MAX_RESPONSE_ROWS} "
                          f"(recipes hold the response: thin it, e.g. to third octaves)")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise ConfigError(f"hardware.response {path}: rows have {sorted(widths)} columns; give every row the same")
    cols = widths.pop() - 1
    if n_channels is not None and cols not in (1, n_channels):
        raise ConfigError(f"hardware.response {path}: {cols} gain columns for {n_channels} capsules; give one "
                          f"(every capsule) or one per capsule")
    rows.sort(key=lambda r: r[0])
    if any(b[0] <= a[0] for a, b in zip(rows, rows[1:])):
        raise ConfigError(f"hardware.response {path}: a frequency appears twice; give each once")
    return tuple(rows)
