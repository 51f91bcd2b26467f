"""Sound generators of the demo corpus: one function per sound type, numpy/scipy only.

Every generator has the signature ``gen(rng, fs, n) -> x`` where ``rng`` is a numpy
Generator (the clip's own), ``fs`` the sample rate in Hz, ``n`` the number of samples,
and ``x`` a float64 array of shape (n,) with arbitrary scale (the caller normalises the
peak). All randomness comes from ``rng``, so a clip is a pure function of its seed.

The models are deliberately simple physical caricatures, chosen so that the types differ
in spectrum (where the energy sits) and in time (continuous vs. intermittent), which is
what a text-queried localisation model must use to tell them apart:

========== ============ ================================================================
type       temporal     model
========== ============ ================================================================
siren      continuous   tone whose frequency sweeps between ~600 and ~1400 Hz
engine     continuous   firing pulses at 20-37 Hz exciting a low resonance, plus rumble
bell       continuous   inharmonic partials (hum, prime, tierce, quint, nominal) tolled
footsteps  intermittent heel thud + toe tap every ~0.5 s
rain       continuous   broadband (white) noise plus random droplet pings
birds      intermittent phrases of short 2-5 kHz frequency sweeps
clock      intermittent 2-4 kHz clicks, exactly periodic at 1 or 2 Hz (tick-tock)
knock      intermittent groups of 2-5 low woody thumps
wind       continuous   low band-passed noise with slowly moving bands and gusts
babble     continuous   2-3 formant-filtered pulse trains with syllable rhythm
piano      continuous   chords of slightly inharmonic decaying partials
dog        intermittent groups of harmonic, formant-filtered barks with falling pitch
telephone  intermittent a small bell struck at ~20 Hz, in ring bursts
applause   continuous   dense random hand-clap bursts (band-passed noise)
drill      intermittent bursts of a 120-260 Hz buzzing motor with spin-up/down
========== ============ ================================================================
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import signal

TWO_PI = 2.0 * np.pi


# --------------------------------------------------------------------------- helpers
def _time(n: int, fs: int) -> np.ndarray:
    """Sample times in seconds, shape (n,)."""
    return np.arange(n) / fs


def _add(out: np.ndarray, event: np.ndarray, start: float) -> None:
    """Add ``event`` into ``out`` from sample ``start`` on, cut at the end of ``out``."""
    s = int(round(start))
    if s >= len(out) or s + len(event) <= 0:
        return
    if s < 0:
        event, s = event[-s:], 0
    m = min(len(event), len(out) - s)
    out[s:s + m] += event[:m]


def _sos(fs: int, kind: str, freq, order: int = 2) -> np.ndarray:
    """Butterworth second-order sections; band edges are clamped below Nyquist."""
    nyq = 0.5 * fs
    f = np.clip(np.atleast_1d(np.asarray(freq, dtype=float)), 1.0, 0.45 * fs)
    if kind == "bandpass" and f[1] <= f[0] * 1.05:
        f[0] = min(f[0], f[1] / 1.05)
    wn = f[0] if kind in ("lowpass", "highpass") else f
    assert np.all(np.asarray(wn) < nyq)
    return signal.butter(order, wn, kind, fs=fs, output="sos")


def _filt(x: np.ndarray, fs: int, kind: str, freq, order: int = 2) -> np.ndarray:
    return signal.sosfilt(_sos(fs, kind, freq, order), x)


def _smooth(rng: np.random.Generator, n: int, fs: int, rate: float) -> np.ndarray:
    """A smooth random curve in [0, 1], shape (n,): uniform knots ``rate`` times per
    second joined by raised-cosine interpolation (continuous first derivative at knots
    is not needed; only audible steps are avoided)."""
    k = int(np.ceil(n / fs * rate)) + 2
    knots = rng.uniform(0.0, 1.0, k)
    x = _time(n, fs) * rate
    i = np.floor(x).astype(np.int64)
    w = 0.5 - 0.5 * np.cos(np.pi * (x - i))
    return knots[i] * (1.0 - w) + knots[i + 1] * w


def _damped_sines(fs: int, freqs, amps, taus, dur: float) -> np.ndarray:
    """Sum of exponentially decaying sinusoids, shape (round(dur*fs),).

    x(t) = sum_k a_k exp(-t/tau_k) sin(2 pi f_k t); partials at or above 0.45 fs are
    dropped (they would alias). Computed as Im sum_k a_k z_k^m with z_k =
    exp((-1/tau_k + 2 pi i f_k)/fs) and m = B j + i factored into a block start z^(Bj)
    and an offset z^i, so each partial costs one complex outer product instead of a
    sin and an exp per sample.
    """
    length = int(round(dur * fs))
    f = np.asarray(freqs, float)
    keep = f < 0.45 * fs
    s = (-1.0 / np.asarray(taus, float)[keep] + 1j * TWO_PI * f[keep]) / fs
    a = np.asarray(amps, float)[keep]
    block = 512
    nb = -(-length // block)
    x = np.zeros((nb, block))
    for sk, ak in zip(s, a):
        head = ak * np.exp(sk * block * np.arange(nb))   # (nb,)
        tail = np.exp(sk * np.arange(block))              # (block,)
        x += np.outer(head.real, tail.imag) + np.outer(head.imag, tail.real)
    return x.ravel()[:length]


def _harmonics(phase: np.ndarray, amps) -> np.ndarray:
    """sum_h amps[h-1] sin(h phase), by the Chebyshev recurrence
    sin(h p) = 2 cos(p) sin((h-1) p) - sin((h-2) p) (one multiply-add per harmonic
    and sample instead of a sin)."""
    c2 = 2.0 * np.cos(phase)
    prev, cur = np.zeros_like(phase), np.sin(phase)
    out = np.zeros_like(phase)
    for a in amps:
        out += a * cur
        prev, cur = cur, c2 * cur - prev
    return out


def _scatter(n: int, pos, amps, kernel: np.ndarray) -> np.ndarray:
    """sum_j amps[j] kernel(t - pos[j]), shape (n,): a sparse convolution, faster than
    an FFT for the few hundred events per clip used here."""
    x = np.zeros(n)
    for p, a in zip(np.asarray(pos, dtype=np.int64), np.broadcast_to(amps, np.shape(pos))):
        _add(x, a * kernel, p)
    return x


def _decaying_noise(rng, fs: int, dur: float, tau: float) -> np.ndarray:
    """White noise with an exp(-t/tau) envelope, shape (round(dur*fs),)."""
    t = _time(int(round(dur * fs)), fs)
    return rng.standard_normal(t.size) * np.exp(-t / tau)


def _pulse_times(f_inst: np.ndarray, fs: int, phase0: float = 0.0) -> np.ndarray:
    """Sample indices where a phase accumulator with instantaneous frequency
    ``f_inst`` (Hz, per sample) completes a cycle: a pulse train of varying rate."""
    ph = phase0 + np.cumsum(f_inst) / fs
    return np.flatnonzero(np.diff(np.floor(ph)) > 0) + 1


def _impulses(n: int, pos, amps) -> np.ndarray:
    x = np.zeros(n)
    pos = np.asarray(pos, dtype=np.int64)
    ok = (pos >= 0) & (pos < n)
    np.add.at(x, pos[ok], np.broadcast_to(amps, pos.shape)[ok])
    return x


def _resonator_sos(fs: int, freqs, bws) -> np.ndarray:
    """Cascade of two-pole resonators (Klatt 1980 formant sections), unit gain at DC.

    Section k: H(z) = (1 - a1 - a2) / (1 - a1 z^-1 - a2 z^-2) with
    a1 = 2 r cos(2 pi F/fs), a2 = -r^2, r = exp(-pi B/fs); F, B in Hz.
    """
    rows = []
    for f, b in zip(freqs, bws):
        if f >= 0.45 * fs:
            continue
        r = np.exp(-np.pi * b / fs)
        a1, a2 = 2 * r * np.cos(TWO_PI * f / fs), -r * r
        rows.append([1 - a1 - a2, 0.0, 0.0, 1.0, -a1, -a2])
    return np.asarray(rows)


def _onsets(rng, dur: float, first: tuple[float, float], gap: tuple[float, float]):
    """Event onsets in seconds: the first uniform in ``first``, then gaps uniform in
    ``gap``, until ``dur``."""
    t, out = rng.uniform(*first), []
    while t < dur:
        out.append(t)
        t += rng.uniform(*gap)
    return out


# ------------------------------------------------------------------------ generators
def siren(rng, fs, n):
    """Electronic siren: a tone swept between f_lo ~600 and f_hi ~1400 Hz, either a slow
    "wail" (3-6 s per cycle) or a fast "yelp" (0.25-0.45 s), with weak odd harmonics;
    the fundamental always dominates."""
    t = _time(n, fs)
    f_lo, f_hi = rng.uniform(560, 700), rng.uniform(1250, 1420)
    period = rng.uniform(3.0, 6.0) if rng.random() < 0.7 else rng.uniform(0.25, 0.45)
    sweep = 0.5 - 0.5 * np.cos(TWO_PI * t / period + rng.uniform(0, TWO_PI))
    ph = TWO_PI * np.cumsum(f_lo + (f_hi - f_lo) * sweep) / fs
    x = np.sin(ph) + 0.25 * np.sin(3 * ph) + 0.1 * np.sin(5 * ph)
    # slow level drift, as of a vehicle moving at a distance
    return x * (0.75 + 0.25 * _smooth(rng, n, fs, 0.3))


def engine(rng, fs, n):
    """Idling 4-stroke engine: firing pulses at f = rpm/60*2 (20-37 Hz for 600-1100
    rpm), per-cylinder level differences (the idle "lope"), each pulse ringing a low
    exhaust resonance (55-110 Hz); plus low-passed rumble. Energy mostly < 500 Hz."""
    rpm = rng.uniform(600, 1100)
    f_fire = rpm / 60.0 * 2.0 * (1 + 0.03 * (_smooth(rng, n, fs, 0.5) - 0.5))
    pos = _pulse_times(f_fire, fs, rng.random())
    cyl = 1 + 0.2 * rng.uniform(-1, 1, 4)
    amps = cyl[np.arange(pos.size) % 4] * (1 + 0.1 * rng.standard_normal(pos.size))
    f_res = rng.uniform(55, 110)
    kernel = (_damped_sines(fs, [f_res, 2.1 * f_res], [1.0, 0.4], [0.018, 0.010], 0.12)
              + 0.3 * _filt(_decaying_noise(rng, fs, 0.12, 0.006), fs, "lowpass", 400))
    x = _scatter(n, pos, amps, kernel)
    rumble = _filt(rng.standard_normal(n), fs, "lowpass", rng.uniform(120, 220), 4)
    return x / np.std(x) + 0.4 * rumble / np.std(rumble)


def bell(rng, fs, n):
    """Church bell tolled every 1.6-3.2 s. Partials relative to the strike note f
    (280-520 Hz): hum 0.5, prime 1, tierce 1.19, quint 1.5, nominal 2, and upper
    partials, each decaying exponentially (low ones for seconds)."""
    f = rng.uniform(280, 520)
    ratios = np.array([0.5, 1.0, 1.19, 1.5, 2.0, 2.52, 2.66, 3.01, 4.16, 5.43])
    amps = np.array([0.6, 0.7, 0.6, 0.3, 1.0, 0.35, 0.3, 0.25, 0.15, 0.1])
    taus = np.array([5.0, 3.0, 2.5, 1.8, 2.0, 1.0, 0.9, 0.7, 0.4, 0.3])
    ratios = ratios * (1 + 0.004 * rng.standard_normal(ratios.size))
    strike = _damped_sines(fs, f * ratios, amps, taus, n / fs)
    strike[: int(0.004 * fs)] += _filt(_decaying_noise(rng, fs, 0.004, 0.001), fs,
                                       "highpass", 1500) * 0.5
    x = np.zeros(n)
    for t0 in _onsets(rng, n / fs, (0.0, 0.3), (1.6, 3.2) if rng.random() < 0.6
                      else (2.4, 3.2)):
        _add(x, strike * rng.uniform(0.8, 1.0), t0 * fs)
    return x


def footsteps(rng, fs, n):
    """Walking: a step every 0.45-0.65 s (5 % jitter), left/right alternately louder;
    each step a low heel thud (noise low-passed at 300-600 Hz, ~20 ms decay) and a
    toe tap 40-80 ms later (noise band-passed 1-5 kHz); sometimes one pause."""
    pace = rng.uniform(0.45, 0.65)
    fc_heel, fc_toe = rng.uniform(300, 600), rng.uniform(1000, 1800)
    pause_at = rng.uniform(2.0, 6.0) if rng.random() < 0.5 else np.inf
    x, t, k = np.zeros(n), rng.uniform(0.05, 0.4), 0
    while t < n / fs:
        side = 1.0 if k % 2 == 0 else rng.uniform(0.7, 0.85)
        heel = _filt(_decaying_noise(rng, fs, 0.12, rng.uniform(0.015, 0.025)), fs,
                     "lowpass", fc_heel, 4)
        toe = _filt(_decaying_noise(rng, fs, 0.08, 0.015), fs, "bandpass",
                    (fc_toe, 5000))
        _add(x, side * heel / np.abs(heel).max(), t * fs)
        _add(x, side * rng.uniform(0.5, 0.8) * toe / np.abs(toe).max(),
             (t + rng.uniform(0.04, 0.08)) * fs)
        t += pace * (1 + 0.05 * rng.standard_normal())
        if t > pause_at:
            t, pause_at = t + rng.uniform(0.8, 1.6), np.inf
        k += 1
    return x


def rain(rng, fs, n):
    """Rain: white noise (high-passed at 150 Hz, so the spectrum is flat above it)
    with +-15 % intensity drift, plus Poisson droplet pings (damped sines at
    1.5-6 kHz, 2-6 ms decay) at 20-60 per second."""
    hiss = _filt(rng.standard_normal(n), fs, "highpass", 150, 1)
    hiss *= 0.85 + 0.3 * _smooth(rng, n, fs, 0.4)
    drops = np.zeros(n)
    n_drops = rng.poisson(rng.uniform(20, 60) * n / fs)
    kinds = rng.integers(0, 6, n_drops)
    pos = rng.integers(0, n, n_drops)
    amps = rng.lognormal(0.0, 0.6, n_drops)
    for k in range(6):
        kern = _damped_sines(fs, [rng.uniform(1500, 6000)], [1.0],
                             [rng.uniform(0.002, 0.006)], 0.03)
        drops += _scatter(n, pos[kinds == k], amps[kinds == k], kern)
    return hiss / np.std(hiss) + 0.5 * drops / (np.std(drops) + 1e-12)


def birds(rng, fs, n):
    """Songbird: phrases of 3-8 chirps (40-120 ms each, 30-100 ms apart) separated by
    0.4-1.5 s; each chirp sweeps from f0 (2.5-4.5 kHz) by a factor 0.6-1.5 with a
    sin^2 envelope and a weak second harmonic. One or two birds."""
    x = np.zeros(n)
    for bird in range(1 if rng.random() < 0.6 else 2):
        base = rng.uniform(2500, 4500)
        level = 1.0 if bird == 0 else rng.uniform(0.4, 0.7)
        t = rng.uniform(0.05, 0.5) + bird * rng.uniform(0.3, 1.0)
        while t < n / fs:
            for _ in range(rng.integers(3, 9)):
                d = rng.uniform(0.04, 0.12)
                tc = _time(int(d * fs), fs)
                f0, f1 = base * rng.uniform(0.9, 1.1), base * rng.uniform(0.6, 1.5)
                ph = TWO_PI * np.cumsum(f0 + (f1 - f0) * tc / d) / fs
                ev = np.sin(ph) + (0.2 * np.sin(2 * ph) if 2 * max(f0, f1) < 0.45 * fs
                                   else 0.0)
                _add(x, level * rng.uniform(0.6, 1.0) * ev * np.sin(np.pi * tc / d) ** 2,
                     t * fs)
                t += d + rng.uniform(0.03, 0.1)
            t += rng.uniform(0.4, 1.5)
    return x


def clock(rng, fs, n):
    """Clock: a click exactly every P = 1.0 s or 0.5 s (x(1 +- 0.5 %) per clock),
    alternating "tick" and a lower, softer "tock"; each click a pair of damped sines at
    2-3.5 kHz (~2 ms decay) with a short 1.5-6 kHz noise transient."""
    period = (1.0 if rng.random() < 0.5 else 0.5) * (1 + rng.uniform(-0.005, 0.005))
    f = rng.uniform(2000, 3500)
    x = np.zeros(n)
    t0 = rng.uniform(0.05, 0.4)
    for k, t in enumerate(np.arange(t0, n / fs, period)):
        g = 1.0 if k % 2 == 0 else 0.85
        click = _damped_sines(fs, [f * g, 1.37 * f * g, 0.31 * f], [1.0, 0.5, 0.3],
                              [0.002, 0.0015, 0.006], 0.04)
        click[: int(0.002 * fs)] += _filt(0.3 * rng.standard_normal(int(0.002 * fs)), fs,
                                          "bandpass", (1500, 6000))
        _add(x, (1.0 if k % 2 == 0 else 0.75) * click, t * fs)
    return x


def knock(rng, fs, n):
    """Knocking on a wooden door: groups of 2-5 knocks (0.12-0.22 s apart) every
    1.6-3.5 s; each knock the door's low plate modes (f1 120-220 Hz, 2.3 f1, 3.9 f1,
    30-60 ms decay) plus a 2 ms knuckle click."""
    f1 = rng.uniform(120, 220)
    x = np.zeros(n)
    for t in _onsets(rng, n / fs, (0.05, 0.5), (1.6, 3.5)):
        spacing = rng.uniform(0.12, 0.22)
        for j in range(rng.integers(2, 6)):
            tau = rng.uniform(0.03, 0.06)
            ev = _damped_sines(fs, f1 * np.array([1.0, 2.3, 3.9]) * rng.uniform(0.97, 1.03),
                               [1.0, 0.6, 0.3], [tau, tau * 0.7, tau * 0.5], 0.25)
            ev[: int(0.002 * fs)] += _filt(0.4 * rng.standard_normal(int(0.002 * fs)),
                                           fs, "highpass", 800)
            _add(x, rng.uniform(0.75, 1.0) * ev, (t + j * spacing * (1 - 0.05 * j)) * fs)
    return x


def wind(rng, fs, n):
    """Wind: noise in four bands (centres ~70, 140, 280, 560 Hz, scaled per clip)
    whose gains drift independently (so the spectral peak moves, the "howl"), under a
    gust envelope that never falls below ~40 % of its maximum."""
    scale = rng.uniform(0.8, 1.25)
    x = np.zeros(n)
    for fc, g in zip(np.array([70, 140, 280, 560]) * scale, [1.0, 0.9, 0.6, 0.3]):
        band = _filt(rng.standard_normal(n), fs, "bandpass", (fc / 1.4, fc * 1.4))
        x += g * (0.3 + _smooth(rng, n, fs, rng.uniform(0.3, 0.8))) ** 2 * band
    x += 0.5 * _filt(rng.standard_normal(n), fs, "lowpass", 80, 2)
    return x * (0.4 + 0.6 * _smooth(rng, n, fs, rng.uniform(0.15, 0.35)))


_VOWELS = np.array([  # (F1, F2, F3) in Hz, rough adult averages
    [730, 1090, 2440], [530, 1840, 2480], [270, 2290, 3010], [570, 840, 2410],
    [300, 870, 2240], [660, 1720, 2410], [490, 1350, 1690], [640, 1190, 2390],
])


def _talker(rng, fs, n):
    """One voice: syllables of 120-280 ms in words of 1-3, phrases of 4-9 words with
    0.2-0.6 s pauses; glottal pulses at f0 with slow intonation, tilted by two one-pole
    low-passes (-12 dB/oct) and a difference (+6 dB/oct lip radiation); each syllable
    a vowel (three formant resonators), a third of them preceded by a fricative
    (noise band-passed at 2.5-7 kHz, ~15 dB below the vowels)."""
    female = rng.random() < 0.5
    f0_base = rng.uniform(180, 240) if female else rng.uniform(95, 140)
    fscale = 1.15 if female else 1.0
    f0 = f0_base * (0.8 + 0.4 * _smooth(rng, n, fs, 3.0))
    pulses = _impulses(n, _pulse_times(f0, fs, rng.random()), 1.0)
    pole = np.exp(-TWO_PI * 150.0 / fs)
    exc = signal.lfilter([1.0 - pole], [1.0, -pole], pulses)
    exc = signal.lfilter([1.0 - pole], [1.0, -pole], exc)
    exc = np.diff(exc, prepend=0.0)
    voiced, fric = np.zeros(n), np.zeros(n)
    t, words = rng.uniform(0.0, 0.3), 0
    tail = int(0.03 * fs)
    phrase_len = rng.integers(4, 10)
    while t < n / fs:
        for _ in range(rng.integers(1, 4)):
            d = rng.uniform(0.12, 0.28)
            s, m = int(t * fs), int(d * fs)
            if s >= n:
                break
            seg = exc[s:s + m]
            env = np.sin(np.pi * np.arange(seg.size) / m) ** 0.7
            form = _VOWELS[rng.integers(len(_VOWELS))] * fscale * rng.uniform(0.95, 1.05)
            sos = _resonator_sos(fs, form, [80, 110, 170])
            _add(voiced, signal.sosfilt(sos, np.concatenate([seg * env, np.zeros(tail)])), s)
            if rng.random() < 0.35:
                fr = _filt(rng.standard_normal(int(rng.uniform(0.04, 0.09) * fs)), fs,
                           "bandpass", (rng.uniform(2500, 4000), 7000), 4)
                _add(fric, fr * np.hanning(fr.size), s - fr.size // 2)
            t += d
        t += rng.uniform(0.02, 0.1)
        words += 1
        if words % phrase_len == 0:
            t += rng.uniform(0.2, 0.6)
    # levels from the active parts only: fricative peaks ~15 dB under vowel peaks
    v_peak = np.percentile(np.abs(voiced), 99.9) + 1e-12
    f_peak = np.percentile(np.abs(fric), 99.9) + 1e-12
    return voiced / v_peak + 0.18 * fric / f_peak


def babble(rng, fs, n):
    """Several people talking at once: 2 or 3 independent talkers at different levels
    (each normalised to unit RMS first)."""
    x = np.zeros(n)
    for k in range(int(rng.integers(2, 4))):
        v = _talker(rng, fs, n)
        x += (1.0 if k == 0 else rng.uniform(0.5, 0.9)) * v / (np.std(v) + 1e-12)
    return x


_CHORDS = ([0, 4, 7], [5, 9, 12], [7, 11, 14], [9, 12, 16], [2, 5, 9], [4, 7, 11])


def _piano_note(fs, f, length, release_at, bright):
    """One piano-ish note, shape (round(length*fs),): partials h = 1..12 at
    h f sqrt(1 + B h^2) (string inharmonicity, B = 3e-4), amplitudes (1/h)^bright times
    |sin(pi h / 7)| (hammer striking 1/7 along the string), decay tau_h = tau_1/(1+0.3(h-1))
    with tau_1 longer for lower notes; dampers fall at ``release_at`` (60 ms decay)."""
    h = np.arange(1, 13)
    fh = h * f * np.sqrt(1 + 3e-4 * h ** 2)
    amp = (1.0 / h) ** bright * np.abs(np.sin(np.pi * h / 7))
    tau1 = np.clip(2.5 * np.sqrt(261.6 / f), 0.8, 4.0)
    x = _damped_sines(fs, fh, amp, tau1 / (1 + 0.3 * (h - 1)), length)
    t = _time(x.size, fs)
    x *= np.minimum(1.0, t / 0.003)
    x *= np.where(t < release_at, 1.0, np.exp(-(t - release_at) / 0.06))
    return x


def piano(rng, fs, n):
    """Piano chords: a progression of triads (I, IV, V, vi, ii, iii of a random major
    key, root MIDI 57-66) with a bass note an octave down, one chord every 1.2-2.4 s,
    notes spread by 0-40 ms (slightly rolled)."""
    root = int(rng.integers(57, 67))
    bright = rng.uniform(0.8, 1.2)
    x, t, first = np.zeros(n), rng.uniform(0.0, 0.3), True
    while t < n / fs:
        gap = rng.uniform(1.2, 2.4)
        chord = _CHORDS[0] if first else _CHORDS[rng.integers(len(_CHORDS))]
        first = False
        notes = [root + c for c in chord] + [root + chord[0] - 12]
        for j, m in enumerate(notes):
            f = 440.0 * 2.0 ** ((m - 69) / 12.0)
            dt = j * rng.uniform(0.0, 0.013)
            gain = (0.6 if j == len(notes) - 1 else 1.0) * rng.uniform(0.8, 1.0)
            _add(x, gain * _piano_note(fs, f, gap + 0.3, gap - dt, bright), (t + dt) * fs)
        t += gap
    return x


def dog(rng, fs, n):
    """Dog barks: groups of 1-3 barks (0.25-0.45 s apart) every 0.9-2.5 s. A bark
    lasts 120-220 ms: harmonic source with f0 (350-650 Hz) rising then falling, 30 %
    noise, rough 40-70 Hz amplitude modulation, formants near 700-1000 and
    1400-2000 Hz, 8 ms attack."""
    f0 = rng.uniform(350, 650)
    form = [rng.uniform(700, 1000), rng.uniform(1400, 2000), rng.uniform(2600, 3200)]
    sos = _resonator_sos(fs, form, [250, 350, 500])
    x = np.zeros(n)
    for t in _onsets(rng, n / fs, (0.05, 0.5), (0.9, 2.5)):
        for j in range(rng.integers(1, 4)):
            d = rng.uniform(0.12, 0.22)
            tc = _time(int(d * fs), fs)
            u = tc / d
            fi = f0 * rng.uniform(0.9, 1.1) * (0.85 + 0.35 * np.sin(np.pi * u) - 0.25 * u)
            ph = TWO_PI * np.cumsum(fi) / fs
            hmax = int(min(5000, 0.45 * fs) // (1.2 * f0))
            src = _harmonics(ph, 1.0 / np.arange(1, hmax + 1))
            src = src + 0.3 * rng.standard_normal(tc.size)
            env = (np.minimum(1.0, tc / 0.008) * np.exp(-tc / (d / 2.5))
                   * np.sin(np.pi * u) ** 0.3)
            env *= 1 + 0.3 * np.sin(TWO_PI * rng.uniform(40, 70) * tc)
            bark = signal.sosfilt(sos, np.concatenate([src * env, np.zeros(int(0.02 * fs))]))
            _add(x, rng.uniform(0.7, 1.0) * bark / np.abs(bark).max(),
                 (t + j * rng.uniform(0.25, 0.45)) * fs)
    return x


def telephone(rng, fs, n):
    """Old telephone bell: two small bells (fa 1.5-2.2 kHz and 1.12 fa, partials 1,
    2.32, 4.1, decay 0.25/0.12/0.06 s) struck alternately at 18-24 Hz during ring
    bursts; cadence either long (1.2-2 s on, 2-3 s off) or double (0.4 on, 0.2 off,
    0.4 on, 2 off)."""
    fa, rate = rng.uniform(1500, 2200), rng.uniform(18, 24)
    if rng.random() < 0.5:
        on, off = rng.uniform(1.2, 2.0), rng.uniform(2.0, 3.0)
        cadence = [(0.0, on)], on + off
    else:
        cadence = [(0.0, 0.4), (0.6, 1.0)], 3.0
    strikes = []
    t0 = rng.uniform(0.1, 0.5)
    while t0 < n / fs:
        for a, b in cadence[0]:
            strikes.extend(np.arange(t0 + a, t0 + b, 1.0 / rate))
        t0 += cadence[1]
    pos = np.round(np.asarray(strikes) * fs).astype(np.int64)
    x = np.zeros(n)
    for k, f in enumerate([fa, 1.12 * fa]):
        kern = _damped_sines(fs, f * np.array([1.0, 2.32, 4.1]), [1.0, 0.5, 0.25],
                             [0.25, 0.12, 0.06], 0.8)
        amps = rng.uniform(0.8, 1.0, pos[k::2].size)
        x += _scatter(n, pos[k::2], amps, kern)
    return x


def applause(rng, fs, n):
    """Applause: Poisson hand claps at 60-180 per second; each clap one of six kernels
    (noise band-passed around 0.8-2.5 kHz, 4-10 ms decay) with log-normal amplitude;
    the clap rate swells in over 0.3-1 s and may fade to ~40 % near the end."""
    dur = n / fs
    count = rng.poisson(rng.uniform(60, 180) * dur)
    times = np.sort(rng.uniform(0, dur, count))
    rise = rng.uniform(0.3, 1.0)
    fade_from = rng.uniform(0.6, 0.9) * dur if rng.random() < 0.5 else dur
    env = np.minimum(1.0, (times + 0.05) / rise)
    env *= np.where(times < fade_from, 1.0, 1.0 - 0.6 * (times - fade_from) / dur)
    amps = rng.lognormal(0.0, 0.5, count) * env
    kinds = rng.integers(0, 6, count)
    pos = np.round(times * fs).astype(np.int64)
    x = np.zeros(n)
    for k in range(6):
        c = rng.uniform(800, 2500)
        kern = _filt(_decaying_noise(rng, fs, 0.04, rng.uniform(0.004, 0.01)), fs,
                     "bandpass", (c / 1.8, c * 1.8))
        x += _scatter(n, pos[kinds == k], amps[kinds == k], kern / np.abs(kern).max())
    return x


def drill(rng, fs, n):
    """Electric drill: bursts of 1-3 s with 0.5-1.5 s pauses; the motor frequency f
    (120-260 Hz) spins up over 0.2 s and down over 0.3 s; sawtooth-like harmonics
    (1/h) up to 6 kHz with those near 2.5-4 kHz raised, plus gear noise (2-5 kHz)."""
    f_top = rng.uniform(120, 260)
    speed = np.zeros(n)
    t = rng.uniform(0.1, 0.4)
    while t < n / fs:
        d = rng.uniform(1.0, 3.0)
        tt = _time(n, fs) - t
        up = np.clip(tt / 0.2, 0.0, 1.0)
        down = np.clip(1.0 - (tt - d) / 0.3, 0.0, 1.0)
        speed = np.maximum(speed, np.minimum(up, down) * (tt >= 0))
        t += d + 0.3 + rng.uniform(0.5, 1.5)
    f = f_top * (0.3 + 0.7 * speed) * (1 + 0.01 * _smooth(rng, n, fs, 5.0))
    ph = TWO_PI * np.cumsum(f) / fs
    h = np.arange(1, int(min(6000.0, 0.45 * fs) // f_top) + 1)
    # the motor's whine: harmonics near f_w (2.5-4 kHz) raised, as by a housing resonance
    f_w = rng.uniform(2500, 4000)
    x = _harmonics(ph, 1.0 / h + 0.4 * np.exp(-(((h * f_top - f_w) / 700.0) ** 2)))
    x = x + 0.3 * _filt(rng.standard_normal(n), fs, "bandpass", (2000, 5000))
    return x * speed ** 1.5


# --------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class SoundType:
    """One sound type of the demo corpus.

    name:     short id, also used in seeds (changing it changes the corpus).
    temporal: "continuous" (active in every 0.1 s frame) or "intermittent" (events with
              silent gaps), which is what activity labels will show.
    captions: AudioCaps-style wordings; val/test clips get 5 of them, train clips 1.
    generate: ``generate(rng, fs, n) -> float64 (n,)``, arbitrary scale.
    """

    name: str
    temporal: str
    captions: tuple[str, ...]
    generate: Callable[[np.random.Generator, int, int], np.ndarray]


SOUND_TYPES: tuple[SoundType, ...] = (
    SoundType("siren", "continuous", (
        "A siren wails in the distance",
        "An emergency vehicle siren rises and falls",
        "A police siren sounds continuously",
        "An ambulance siren wails, rising and falling in pitch",
        "A loud siren blares steadily",
        "The siren of a fire truck wails",
        "A warning siren sweeps up and down",
    ), siren),
    SoundType("engine", "continuous", (
        "An engine idles steadily",
        "A vehicle engine runs at idle",
        "A car engine rumbles while idling",
        "A motor idles with a low, steady rumble",
        "The low hum of an idling truck engine",
        "An idling engine chugs and vibrates",
        "A diesel engine idles nearby",
    ), engine),
    SoundType("bell", "continuous", (
        "A church bell rings",
        "A large bell tolls slowly",
        "A church bell chimes repeatedly, ringing out",
        "A bell is struck several times and rings",
        "Heavy bell tolls echo",
        "A bell tolls and its ringing slowly fades",
        "Church bells ring out",
    ), bell),
    SoundType("footsteps", "intermittent", (
        "Footsteps walk across a hard floor",
        "A person walks with steady footsteps",
        "Someone walks slowly on a wooden floor",
        "Footsteps approach on a hard surface",
        "A person is walking, shoes tapping the floor",
        "Steady footsteps of someone walking",
        "Footsteps echo as a person walks by",
    ), footsteps),
    SoundType("rain", "continuous", (
        "Rain falls steadily",
        "Heavy rain pours down",
        "Rain patters on a surface, constant and steady",
        "Rainfall hisses continuously",
        "Rain is falling hard on the ground",
        "Steady rain pours, with drops splattering",
        "A downpour of rain",
    ), rain),
    SoundType("birds", "intermittent", (
        "Birds chirp",
        "A bird chirps and tweets repeatedly",
        "Small birds chirp and sing",
        "A bird sings, chirping in short bursts",
        "Birds tweet in high pitches",
        "High-pitched bird calls chirp on and off",
        "Birdsong with quick chirps",
    ), birds),
    SoundType("clock", "intermittent", (
        "A clock ticks",
        "A clock ticks steadily",
        "The ticking of a clock",
        "A wall clock ticks, tick-tock",
        "A mechanical clock ticks at a steady pace",
        "Regular ticking from a clock",
        "A clock is ticking",
    ), clock),
    SoundType("knock", "intermittent", (
        "Someone knocks on a door",
        "A person knocks on a wooden door several times",
        "Knocking on a door",
        "Several knocks on a wooden door, then a pause",
        "A fist knocks on a door repeatedly",
        "Someone raps their knuckles against a door",
        "Repeated knocking on a wooden door",
    ), knock),
    SoundType("wind", "continuous", (
        "Wind blows",
        "Strong wind blows and gusts",
        "Wind howls and gusts",
        "Gusts of wind blow steadily",
        "The wind is blowing hard",
        "Wind whooshes, rising and falling",
        "A gusty wind roars",
    ), wind),
    SoundType("babble", "continuous", (
        "People talk in the background",
        "Several people are speaking at once",
        "A group of people chatter indistinctly",
        "Men and women talk over each other",
        "People chat in a busy café",
        "Indistinct conversation among a few people",
        "A crowd murmurs as people talk",
    ), babble),
    SoundType("piano", "continuous", (
        "Someone plays chords on a piano",
        "A piano plays a slow sequence of chords",
        "Piano music is playing",
        "A person plays the piano softly",
        "Chords are played on a piano, ringing out",
        "A piano plays gentle chords",
        "Piano chords are played one after another",
    ), piano),
    SoundType("dog", "intermittent", (
        "A dog barks",
        "A dog barks repeatedly",
        "A dog is barking loudly",
        "A dog barks several times, pausing in between",
        "Barking of a dog",
        "A small dog yaps and barks",
        "A dog barks, then barks again",
    ), dog),
    SoundType("telephone", "intermittent", (
        "A telephone rings",
        "An old rotary telephone rings",
        "A phone is ringing",
        "A telephone rings repeatedly",
        "A landline telephone rings, stops and rings again",
        "A ringing telephone",
        "A phone rings loudly and insistently",
    ), telephone),
    SoundType("applause", "continuous", (
        "People applaud",
        "An audience claps and applauds",
        "A crowd applauds",
        "Applause from a large audience",
        "A group of people clap their hands",
        "Clapping and applause fill the room",
        "An audience gives a round of applause",
    ), applause),
    SoundType("drill", "intermittent", (
        "A power drill whirs",
        "An electric drill runs in short bursts",
        "A drill whines, starting and stopping",
        "A power tool buzzes on and off",
        "Someone uses an electric drill",
        "A drill motor whirs loudly",
        "A high-pitched drill spins up and down",
    ), drill),
)

TYPES_BY_NAME = {t.name: t for t in SOUND_TYPES}
