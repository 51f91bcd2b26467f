"""Microphones as built, applied to audio: what each capsule does to the sound (gain, delay,
high-pass, tilt, a measured response), its self-noise, and each device's clock.

Every function takes the receiver's hardware as drawn for the scene (an object with the
fields of :class:`tsel_data.scene.hardware.Hardware`, read here by attribute) and audio
[C, T] at ``fs``. The renderer (render/mix.py) applies, to the mixture of one receiver:

    y = clock( capsules(x) · norm + self_noise )

- :func:`through_capsules`: channel c through H_c(f) = g_c · exp(-j 2π f τ_c) · HP_c(f)
  · T_c(f) · R_c(f): its gain, its delay, an analog Butterworth high-pass of corner f_c
  (its phase too: capsules whose corners differ disagree in phase below a few corners),
  a tilt 10^(t_c log2(f / 1 kHz) / 20) (magnitude only, flat below 50 Hz) and a measured
  magnitude response (interpolated in log frequency, flat beyond its ends). One FFT over
  the scene with 0.5 s of padding, so nothing wraps.
- :func:`self_noise`: white Gaussian noise per capsule, scaled so that its A-weighted level
  (IEC 61672-1 weighting, expected over the whole scene) is the capsule's self-noise in
  dBFS: self_noise_dba - 94 + sensitivity_dbfs.
- :func:`clock_warp`: the channels of device d lag the first device's by
  offset_d + ppm_d · 10⁻⁶ · t (a band-limited, time-varying fractional delay: the Farrow
  filter of dsp/delaypath.py, accurate to -50 dB below half the Nyquist frequency).

:func:`unhear` undoes the linear parts (clock, then capsules; a high-pass no deeper than
-20 dB), which ``tsel verify`` uses to tell how much the capsules cost its localizer.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from . import fft, realfft as sfft
from .delaypath import FD_HALF, fractional_kernel

PAD_S = 0.5  # s of zeros after the scene: the high-pass's tail and the tilt's ringing do not wrap
TILT_FLOOR_HZ = 50.0  # the tilt is flat below (no infinite gain at DC)
UNDO_FLOOR = 0.1  # undoing a response divides by at most 1 / 0.1 (+20 dB)
SMOOTH_POINTS = 8193  # frequencies the smooth parts of a response are evaluated at (then interpolated)
_CHUNK = 16384  # samples per block of the clock warp


def a_weighting(freqs) -> np.ndarray:
    """The A-weighting's magnitude (linear, 1 at 1 kHz) at ``freqs`` Hz (IEC 61672-1:
    R_A(f) = 12194² f⁴ / ((f² + 20.6²) √((f² + 107.7²)(f² + 737.9²)) (f² + 12194²)))."""
    f2 = np.asarray(freqs, dtype=np.float64) ** 2

    def ra(q):
        return 12194.0 ** 2 * q ** 2 / ((q + 20.6 ** 2) * np.sqrt((q + 107.7 ** 2) * (q + 737.9 ** 2))
                                          * (q + 12194.0 ** 2))

    return ra(f2) / ra(1000.0 ** 2)


def a_weighted_dbfs(audio, fs: float) -> np.ndarray:
    """Each channel's A-weighted RMS level [C] in dBFS (Parseval over one FFT of the whole signal)."""
    x = np.atleast_2d(np.asarray(audio, dtype=np.float64))
    n = x.shape[-1]
    spec = np.abs(sfft.rfft(x, n)) * a_weighting(sfft.rfftfreq(n, 1.0 / fs))
    w = np.full(spec.shape[-1], 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    ms = (spec ** 2 @ w) / n ** 2
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(ms)


def highpass(freqs, corner: float, order: int) -> np.ndarray:
    """An analog Butterworth high-pass of ``order`` and -3 dB ``corner`` (Hz) at ``freqs``,
    complex: H(s) = s^n / Π_k (s - p_k), s = j f / corner, p_k its poles on the unit circle."""
    f = np.asarray(freqs, dtype=np.float64)
    if corner <= 0:
        return np.ones(f.shape, dtype=np.complex128)
    s = 1j * f / corner
    h = np.ones(f.shape, dtype=np.complex128)
    for k in range(1, order + 1):
        p = np.exp(1j * math.pi * (2 * k + order - 1) / (2 * order))
        h *= s / (s - p)
    return h


def capsule_responses(hw, freqs) -> np.ndarray:
    """H_c(f) [C, F] complex of every capsule (module docstring): magnitudes and phases
    summed apart, one complex exponential at the end. The delay's phase is exact at every
    frequency; the smooth rest (high-pass, tilt, measured response) is evaluated on at
    most :data:`SMOOTH_POINTS` frequencies and interpolated (their log magnitude and phase
    change by far less than a grid step of fs / 16k allows to see)."""
    f = np.asarray(freqs, dtype=np.float64)
    C = hw.n_channels
    coarse = f if len(f) <= SMOOTH_POINTS else np.linspace(f[0], f[-1], SMOOTH_POINTS)
    log_mag = np.repeat((np.asarray(hw.gain_db, dtype=np.float64) * (math.log(10.0) / 20.0))[:, None],
                        len(coarse), 1)
    smooth_phase = np.zeros((C, len(coarse)))
    for c in range(C):
        if hw.highpass_hz[c] > 0:
            hp = highpass(coarse, hw.highpass_hz[c], hw.highpass_order)
            log_mag[c] += np.log(np.maximum(np.abs(hp), 1e-300))
            smooth_phase[c] = np.angle(hp)
    if hw.tilt_db and any(hw.tilt_db):
        octaves = np.log2(np.maximum(coarse, TILT_FLOOR_HZ) / 1000.0)
        log_mag += (np.asarray(hw.tilt_db, dtype=np.float64) * (math.log(10.0) / 20.0))[:, None] * octaves[None, :]
    if hw.response:
        log_mag += np.log(_measured(hw.response, coarse, C))
    if coarse is not f:
        log_mag = np.stack([np.interp(f, coarse, row) for row in log_mag])
        smooth_phase = np.stack([np.interp(f, coarse, row) for row in smooth_phase])
    # float32 from here (the spectrum it multiplies is complex64): a phase of at most
    # 2π · fs/2 · 1 ms (the largest delay) keeps 1e-5 rad of precision
    phase = (smooth_phase + (-2.0 * np.pi * np.asarray(hw.delay_us, dtype=np.float64) * 1e-6)[:, None]
             * f[None, :]).astype(np.float32)
    mag = np.exp(log_mag.astype(np.float32))
    out = np.empty(phase.shape, dtype=np.complex64)
    out.real = mag * np.cos(phase)
    out.imag = mag * np.sin(phase)
    return out


def _measured(rows, f: np.ndarray, C: int) -> np.ndarray:
    """A measured magnitude response [C, F]: dB interpolated in log frequency, flat beyond its ends."""
    table = np.asarray(rows, dtype=np.float64)
    logf = np.log(np.maximum(f, 1e-3))
    cols = table[:, 1:]
    db = np.stack([np.interp(logf, np.log(table[:, 0]), cols[:, min(c, cols.shape[1] - 1)]) for c in range(C)])
    return 10.0 ** (db / 20.0)


def _filter(audio: np.ndarray, fs: float, response) -> np.ndarray:
    """``audio`` [C, T] through ``response(freqs) -> [C, F]``, zero-padded by PAD_S: float32
    [C, T] (float32 transforms, dsp/fft.py: errors near 1e-7 of full scale)."""
    x = np.asarray(audio, dtype=np.float32)
    T = x.shape[-1]
    n = fft.good_size(T + int(PAD_S * fs))
    padded = fft.empty(x.shape[:-1] + (n,))
    padded[..., :T] = x
    padded[..., T:] = 0.0
    spec = fft.rfft(padded)
    spec *= response(np.arange(n // 2 + 1) * (fs / n)).astype(np.complex64)
    return fft.irfft(spec, n, overwrite=True)[..., :T]


def through_capsules(audio, hw, fs: float) -> np.ndarray:
    """The sound at every capsule as its channel carries it: float32 [C, T]."""
    return np.ascontiguousarray(_filter(audio, fs, lambda f: capsule_responses(hw, f)))


@lru_cache(maxsize=8)
def white_a_weighted_dbfs(n: int, fs: float) -> float:
    """The expected A-weighted level (dBFS) of n samples of white noise of unit variance:
    Parseval over the n-point spectrum, E|X_k|² = n."""
    a2 = a_weighting(np.arange(n // 2 + 1) * (fs / n)) ** 2
    w = np.full(len(a2), 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    return 10.0 * math.log10(float(a2 @ w) / n)


def self_noise(hw, n: int, fs: float) -> np.ndarray | None:
    """Every capsule's self-noise, float32 [C, n] (None without): white, from ``hw.seed``,
    each channel at its A-weighted level :meth:`~tsel_data.scene.hardware.Hardware.self_noise_dbfs`
    (scaled by the expected level of white noise; a 10 s scene's own is within 0.01 dB)."""
    levels = hw.self_noise_dbfs()
    if levels is None:
        return None
    w = np.random.default_rng([hw.seed, 0]).standard_normal((hw.n_channels, n), dtype=np.float32)
    gain = 10.0 ** ((np.asarray(levels) - white_a_weighted_dbfs(n, fs)) / 20.0)
    return w * gain.astype(np.float32)[:, None]


def clock_warp(audio, hw, fs: float, undo: bool = False) -> np.ndarray:
    """``audio`` [C, T] with every device's channels lagging the first device's by its
    offset + ppm · 10⁻⁶ · t (``undo``: the reverse, to first order in ppm); float32."""
    x = np.asarray(audio, dtype=np.float32)
    offset, ppm = hw.channel_clocks()
    if not any(offset) and not any(ppm):
        return x
    out = x.copy()
    t = np.arange(x.shape[-1], dtype=np.float64)
    sign = -1.0 if undo else 1.0
    for c in range(x.shape[0]):
        if offset[c] or ppm[c]:
            lag = sign * (offset[c] * 1e-6 * fs + ppm[c] * 1e-6 * t)
            out[c] = _delayed(x[c].astype(np.float64), lag)
    return out


def _delayed(x: np.ndarray, lag: np.ndarray) -> np.ndarray:
    """y[n] = x(n - lag[n]) (band-limited): the Farrow fractional delay at each sample."""
    T = len(x)
    whole = np.rint(lag).astype(np.int64)
    mu = lag - whole
    pad = FD_HALF + int(np.abs(whole).max()) + 1
    xp = np.pad(x, (pad, pad))
    taps = np.arange(-FD_HALF, FD_HALF + 1)
    out = np.empty(T)
    for s in range(0, T, _CHUNK):
        n = np.arange(s, min(s + _CHUNK, T))
        idx = n[:, None] - whole[n][:, None] - taps[None, :] + pad
        out[n] = np.einsum("mj,mj->m", fractional_kernel(mu[n]), xp[idx])
    return out


def hear(audio, hw, fs: float, norm: float = 1.0) -> np.ndarray:
    """The whole layer on a receiver's mixture: clock(capsules(audio) · norm + self-noise)."""
    y = through_capsules(audio, hw, fs) * np.float32(norm)
    noise = self_noise(hw, y.shape[-1], fs)
    if noise is not None:
        y += noise
    return clock_warp(y, hw, fs)


def unhear(audio, hw, fs: float) -> np.ndarray:
    """The linear parts of :func:`hear` undone: the clocks, then each capsule's response
    (divided by at most 1 / UNDO_FLOOR where a high-pass is deeper); the self-noise stays."""
    x = clock_warp(audio, hw, fs, undo=True)

    def inverse(f):
        h = capsule_responses(hw, f)
        mag = np.abs(h)
        return np.where(mag >= UNDO_FLOOR, 1.0 / np.where(mag > 0, h, 1.0), np.exp(-1j * np.angle(h)) / UNDO_FLOOR)

    return _filter(x, fs, inverse).astype(np.float32)
