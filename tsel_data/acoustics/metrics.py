"""Room-acoustic measures of impulse responses.

Energy decay curve by Schroeder backward integration (M. R. Schroeder, "New method of
measuring reverberation time", J. Acoust. Soc. Am. 37, 1965) and the reverberation time
from its -5 to -35 dB range (T30, ISO 3382-1: least-squares line, extrapolated to 60 dB).
"""
from __future__ import annotations

from itertools import combinations

import numpy as np

from ..geometry import SOUND_SPEED


def edc(rir: np.ndarray) -> np.ndarray:
    """Schroeder energy decay curve in dB re. the total energy, same shape as ``rir``
    (last axis = time): ``EDC(t) = 10 log10(∫_t^∞ h² / ∫_0^∞ h²)``."""
    e = np.asarray(rir, dtype=np.float64) ** 2
    tail = np.cumsum(e[..., ::-1], axis=-1)[..., ::-1]
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(tail / np.maximum(tail[..., :1], np.finfo(float).tiny))


def decay_time(edc_db: np.ndarray, dt: float, lo: float = -5.0, hi: float = -35.0) -> float:
    """Reverberation time (s) from a 1-D EDC in dB sampled every ``dt`` seconds: the
    least-squares line through the samples between ``lo`` and ``hi`` dB, extrapolated to
    -60 dB. NaN if the curve never reaches ``hi``."""
    edc_db = np.asarray(edc_db, dtype=np.float64)
    below_hi = np.nonzero(edc_db <= hi)[0]
    if not len(below_hi):
        return float("nan")
    i0 = int(np.argmax(edc_db <= lo))
    i1 = int(below_hi[0])
    if i1 - i0 < 2:
        return float("nan")
    t = np.arange(i0, i1 + 1) * dt
    slope = np.polyfit(t, edc_db[i0 : i1 + 1], 1)[0]
    return float(-60.0 / slope) if slope < 0 else float("nan")


def t30(rir: np.ndarray, fs: int) -> float:
    """T30 (s) of a 1-D impulse response at ``fs`` Hz: Schroeder EDC, -5 to -35 dB fit, ×2."""
    return decay_time(edc(np.asarray(rir).reshape(-1)), 1.0 / fs)


def sabine_min_rt60(dims, c: float = SOUND_SPEED) -> float:
    """The shortest RT60 (s) ``pra.inverse_sabine`` accepts for a shoebox of ``dims`` (m):
    Sabine's RT60 with fully absorbing walls, 24 ln(10) V / (c S)."""
    d = [float(v) for v in dims]
    V = float(np.prod(d))
    S = 2.0 * sum(a * b for a, b in combinations(d, 2))
    return 24.0 * np.log(10.0) * V / (c * S)
