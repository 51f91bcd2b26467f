"""Room-acoustic descriptors of one source as it was rendered, from its own impulse
responses at the receiver: what the spatial-language exports and users' models ask of a
scene beyond direction and distance.

From an RIR [C, L] at ``fs`` and the receiver's level channels (W for FOA, every capsule
of an array: ``ReceiverSpec.level_slice``), energies summed over those channels:

- the direct sound is the energy peak, ``t0``; its window is ``t0 ± DIRECT_WINDOW``
  (2.5 ms, the usual choice for DRR in the literature; the ISO 3382 reverberation
  measures start after it);
- **DRR** (dB): the direct window's energy against everything after it;
- **C50** (dB): the energy from the start of the direct window to 50 ms after ``t0``
  against the rest (ISO 3382-1's clarity, timed from the direct sound);
- **EDT** and **T30** (s): Schroeder's backward integration from the direct window on
  (as :func:`~tsel_data.acoustics.metrics.edc`), least-squares lines over 0 to -10 dB
  (EDT) and -5 to -35 dB (T30), extrapolated to 60 dB (ISO 3382-1; :func:`decay_time_of`);
- **T30 per octave band** (125 Hz to 8 kHz, the bands whose upper edge lies below
  0.9·fs/2): the first level channel filtered by a 3rd-order Butterworth band-pass of
  one octave, run backwards in time (so the filter's own ringing does not lengthen the
  decay, Kirkeby's time-reversed filtering), then as T30.

A value that cannot be measured is None: DRR and C50 of an anechoic response (no
reverberant energy), a T30 whose decay never reaches -35 dB within the RIR.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np


DIRECT_WINDOW = 0.0025  # s either side of the direct sound's peak
EARLY = 0.050  # s after the direct sound: C50's boundary
OCTAVES = (125, 250, 500, 1000, 2000, 4000, 8000)  # Hz, band centres


def describe_rir(rir: np.ndarray, fs: int, channels=slice(None)) -> dict:
    """The descriptors of one RIR [C, L] (module docstring): ``drr_db``, ``c50_db``,
    ``edt_s``, ``t30_s`` and ``t30_bands_s`` ({band centre Hz as text: s}), rounded as
    the record keeps them; None for what cannot be measured."""
    h = np.asarray(rir, dtype=np.float64)[channels]
    h = h.reshape(-1, h.shape[-1])
    e = np.sum(h * h, axis=0)
    w = int(round(DIRECT_WINDOW * fs))
    t0 = int(np.argmax(e))
    start, direct_end, early_end = max(0, t0 - w), t0 + w + 1, t0 + int(round(EARLY * fs))
    total = float(np.sum(e[start:]))
    direct = float(np.sum(e[start:direct_end]))
    early = float(np.sum(e[start:early_end]))
    tail = _tail(e[start:])
    bands = {}
    for f in OCTAVES:
        if f * np.sqrt(2) < 0.9 * fs / 2:
            band = _band(h[0, start:], fs, f)
            bands[str(f)] = _seconds(decay_time_of(_tail(band * band), fs))
    return {"drr_db": _ratio_db(direct, total - direct), "c50_db": _ratio_db(early, total - early),
            "edt_s": _seconds(decay_time_of(tail, fs, 0.0, -10.0)), "t30_s": _seconds(decay_time_of(tail, fs)),
            "t30_bands_s": bands}


def _tail(energy: np.ndarray) -> np.ndarray:
    """Schroeder's backward integral of an energy [L]: the energy from each sample on."""
    return np.cumsum(energy[::-1])[::-1]


def decay_time_of(tail: np.ndarray, fs: int, lo: float = -5.0, hi: float = -35.0) -> float:
    """The decay time (s, extrapolated to -60 dB) of a backward integral ``tail`` between
    ``lo`` and ``hi`` dB: metrics.decay_time's line, fitted in closed form and in decibels
    only over the samples fitted (polyfit and a whole decay curve in dB cost ten times
    more, and a scene measures a dozen of them). NaN when it never falls to ``hi``."""
    total = tail[0]
    if not total > 0:
        return float("nan")
    below = tail <= total * 10 ** (hi / 10)
    if not below.any():
        return float("nan")
    i0, i1 = int(np.argmax(tail <= total * 10 ** (lo / 10))), int(np.argmax(below))
    if i1 - i0 < 2:
        return float("nan")
    y = 10.0 * np.log10(np.maximum(tail[i0:i1 + 1], np.finfo(float).tiny) / total)
    t = np.arange(i1 - i0 + 1) / fs
    t -= t.mean()
    slope = float(np.sum(t * (y - y.mean())) / np.sum(t * t))  # not BLAS's dot: its threads stall on a busy machine
    return -60.0 / slope if slope < 0 else float("nan")


def _band(x: np.ndarray, fs: int, centre: float) -> np.ndarray:
    from scipy.signal import sosfilt  # scipy.signal takes ~1 s to import: only scenes that measure pay

    return sosfilt(_octave(fs, centre), x[::-1])[::-1]


@lru_cache(maxsize=64)
def _octave(fs: int, centre: float) -> np.ndarray:
    from scipy.signal import butter  # as _band

    return butter(3, [centre / np.sqrt(2), centre * np.sqrt(2)], btype="bandpass", fs=fs, output="sos")


def _ratio_db(a: float, b: float) -> float | None:
    if not (a > 0 and b > 0):
        return None
    return round(float(10.0 * np.log10(a / b)), 2)


def _seconds(t: float) -> float | None:
    return round(float(t), 4) if np.isfinite(t) else None
