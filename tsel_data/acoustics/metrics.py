"""Room-acoustic measures of impulse responses.

Energy decay curve by Schroeder backward integration (M. R. Schroeder, "New method of
measuring reverberation time", J. Acoust. Soc. Am. 37, 1965) and the reverberation time
from its -5 to -35 dB range (T30, ISO 3382-1: least-squares line, extrapolated to 60 dB).
The level ripple of a moving source at its knot period (:func:`knot_ripple`; the tests
and benchmarks/bench_banks.py measure the moving renderer with it, docs/acoustics.md).
"""
from __future__ import annotations

from itertools import combinations

import numpy as np

from ..core.geometry import SOUND_SPEED


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


# --- level ripple of a moving source -----------------------------------------------------------

RIPPLE_BANDS = (250, 500, 1000, 2000, 4000, 8000)  # Hz: octave bands the ripple is measured in


def knot_profile(y: np.ndarray, times, fs: float, band=None, bins: int = 20) -> np.ndarray:
    """Mean power (linear, relative to the local trend) per phase bin of the knot cycle.

    y [C, T] (channels summed); optionally an octave band around ``band`` Hz (brick-wall).
    Per sample power over its trend (a moving average over one knot interval), binned by
    the phase a = (n - p_i) / (p_{i+1} - p_i) of every knot interval that lies inside the
    clip with a margin.
    """
    y = np.asarray(y, dtype=np.float64)
    T = y.shape[1]
    if band is not None:
        spec = np.fft.rfft(y, axis=-1)
        f = np.fft.rfftfreq(T, 1 / fs)
        spec[:, (f < band / np.sqrt(2)) | (f >= band * np.sqrt(2))] = 0
        y = np.fft.irfft(spec, T, axis=-1)
    power = (y**2).sum(axis=0)
    cum = np.r_[0.0, np.cumsum(power)]
    p = np.asarray(times) * fs
    acc, cnt = np.zeros(bins), np.zeros(bins)
    for a, b in zip(p[:-1], p[1:]):
        D = b - a
        if a < D or b > T - D - 1:
            continue
        n = np.arange(int(np.ceil(a)), int(np.ceil(b)))
        lo = np.clip(np.round(n - D / 2).astype(int), 0, T)
        hi = np.clip(np.round(n + D / 2).astype(int), 0, T)
        ph = np.minimum(((n - a) / D * bins).astype(int), bins - 1)
        acc += np.bincount(ph, power[n] / ((cum[hi] - cum[lo]) / (hi - lo)), bins)
        cnt += np.bincount(ph, None, bins)
    return acc / cnt


def knot_ripple(render, times, fs: float, T: int, reps: int = 6, seed: int = 0) -> dict:
    """Peak-to-peak (dB) over the knot cycle of white noise's frame power through ``render``,
    broadband (key None) and per octave band: the profile's first three harmonics."""
    rng = np.random.default_rng(seed)
    prof = {b: 0.0 for b in (None,) + RIPPLE_BANDS}
    for _ in range(reps):
        y = render(rng.standard_normal(T).astype(np.float32))[:, :T]
        for b in prof:
            prof[b] = prof[b] + knot_profile(y, times, fs, b) / reps
    out = {}
    for b, v in prof.items():
        db = 10 * np.log10(v)
        ph = (np.arange(len(db)) + 0.5) / len(db)
        basis = lambda u: np.stack([np.ones_like(u)] + [f(2 * np.pi * k * u) for k in (1, 2, 3) for f in (np.cos, np.sin)], -1)
        coef = np.linalg.lstsq(basis(ph), db, rcond=None)[0]
        out[b] = float(np.ptp(basis(np.linspace(0, 1, 200)) @ coef))
    return out
