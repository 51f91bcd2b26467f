"""The direct path between a moving source's knots: how far it moves, and moving it.

:mod:`tsel_data.dsp.timevarying` aligns neighbouring knots' direct paths and moves the direct
path continuously between them (its docstring has the model). This module holds the two
halves of that: estimating the direct path's step between knots from the RIRs themselves
(:func:`delay_steps`, which channels share a step: :func:`_delay_groups`), and warping a
signal by a piecewise-linear, fractional shift with a Farrow fractional delay
(:func:`farrow_coefficients`, :func:`_warp`).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from . import fft

MIN_STEP = 0.25  # samples: where the direct path moves less than this between all knots, no warp
GROUP_TOL = 0.5  # samples: channels whose steps stay this close to the median share one warp
MAX_MACH = 0.03  # a step faster than 3 % of the speed of sound (~10 m/s) is not a direct path
MIN_CORR = 0.7  # normalised correlation of neighbouring direct paths below which a step is not trusted
FD_HALF = 16  # the fractional delay's taps reach FD_HALF samples either side
_FARROW_ORDER = 3  # polynomial order in the fractional delay μ
_FARROW_BAND = 0.9  # of the Nyquist frequency: where the Farrow filter is designed to be a delay
_WIN = (16, 32)  # estimate: samples before / after the direct path's peak in its window
_FIR_HOP = 4096  # output samples per overlap-save frame of the Farrow filters (a power of two)


@lru_cache(maxsize=1)
def farrow_coefficients() -> np.ndarray:
    """C [ORDER + 1, 2·FD_HALF + 1]: the fractional delay by μ ∈ [-1/2, 1/2] is the FIR
    K_μ[j] = Σ_q μ^q C[q, j + FD_HALF], j = -FD_HALF..FD_HALF (a Farrow structure), as
    :func:`design_farrow` designs it (stored: tsel_data/dsp/farrow_table.py)."""
    from .farrow_table import FARROW  # a table of coefficients: loaded by moving scenes only

    return np.array(FARROW, dtype=np.float64)


def design_farrow() -> np.ndarray:
    """The design of :func:`farrow_coefficients`. Least squares on the frequency response: Σ_j K_μ[j] e^{-iωj} ≈ e^{-iωμ} for
    ω ≤ 0.9 π and |μ| ≤ 1/2, a cubic in μ: error ≤ -50 dB below 0.5 π (6 kHz at 24 kHz),
    -39 dB below 0.7 π, -30 dB at 0.9 π; magnitude within ±0.13 dB up to 0.9 π.
    """
    j = np.arange(-FD_HALF, FD_HALF + 1)
    mu = np.linspace(-0.5, 0.5, 41)
    w = np.linspace(0.0, _FARROW_BAND * np.pi, 400)
    basis = np.einsum("mq,wj->mwqj", np.vander(mu, _FARROW_ORDER + 1, increasing=True),
                      np.exp(-1j * np.outer(w, j))).reshape(len(mu) * len(w), -1)
    target = np.exp(-1j * np.outer(mu, w)).reshape(-1)
    a = np.concatenate([basis.real, basis.imag])
    b = np.concatenate([target.real, target.imag])
    return np.linalg.lstsq(a, b, rcond=None)[0].reshape(_FARROW_ORDER + 1, len(j))


@lru_cache(maxsize=8)
def _farrow_spectra(n: int, causal: bool = False) -> np.ndarray:
    """The Farrow filters' n-point spectra [ORDER + 1, n // 2 + 1]: tap j at j mod n, or
    (causal) at j + FD_HALF."""
    buf = np.zeros((_FARROW_ORDER + 1, n))
    buf[:, (np.arange(-FD_HALF, FD_HALF + 1) + (FD_HALF if causal else 0)) % n] = farrow_coefficients()
    return np.fft.rfft(buf, axis=-1)


def fractional_kernel(mu) -> np.ndarray:
    """Taps [len(mu), 2·FD_HALF + 1] of the delay by μ (|μ| ≤ 1/2), j = -FD_HALF..FD_HALF."""
    return np.vander(np.atleast_1d(np.asarray(mu, dtype=np.float64)), _FARROW_ORDER + 1, increasing=True) @ farrow_coefficients()


def _undo_spectra(frac: np.ndarray, n: int) -> np.ndarray:
    """[K, n // 2 + 1] complex64: n-point spectra of the delays by -frac_k."""
    powers = np.vander(-np.asarray(frac, dtype=np.float64), _FARROW_ORDER + 1, increasing=True)
    return (powers @ _farrow_spectra(n)).astype(np.complex64)


def _farrow_filter(x: np.ndarray) -> tuple[np.ndarray, int]:
    """The Farrow filters applied to x: ``(y, N)``, y float32 [ORDER + 1, nb·N] (overlap-save
    frames of N points end to end, _FIR_HOP valid outputs each) holding Σ_j C[q, j] x[n - j]
    for n = -FD_HALF .. T + FD_HALF at flat index ``(m >> 12)·N + 2·FD_HALF + (m & 4095)``,
    m = n + FD_HALF (for _FIR_HOP = 4096); at m = T + 2·FD_HALF it is zero."""
    T, taps, hop = len(x), 2 * FD_HALF + 1, _FIR_HOP
    n = fft.good_size(hop + taps - 1)
    nb = (T + taps) // hop + 1  # frames cover m = 0 .. T + taps - 1
    xp = np.zeros(nb * hop + n, dtype=np.float32)
    xp[taps - 1 : taps - 1 + T] = x
    frames = np.lib.stride_tricks.as_strided(xp, (nb, n), (4 * hop, 4), writeable=False)
    spec = fft.rfft(frames)
    prod = np.empty((_FARROW_ORDER + 1,) + spec.shape, dtype=np.complex64)
    np.multiply(spec[None], _farrow_spectra32(n), out=prod)
    y = np.empty((_FARROW_ORDER + 1, nb, n), dtype=np.float32)
    fft.irfft(prod, n, out=y, overwrite=True)
    return y.reshape(_FARROW_ORDER + 1, -1), n


@lru_cache(maxsize=2)
def _farrow_spectra32(n: int) -> np.ndarray:
    """[ORDER + 1, 1, n // 2 + 1] complex64: the causal Farrow filters' spectra, for broadcasting."""
    return _farrow_spectra(n, True).astype(np.complex64)[:, None, :]


def _warp(fir, t0: int, t1: int, pw: np.ndarray, sig: np.ndarray, T: int) -> np.ndarray:
    """z(t) = x(t - s(t)) for t in [t0, t1), float32: s the piecewise-linear shift through
    (pw_k, σ_k) (constant outside), by the Farrow filters of x (:func:`_farrow_filter`) at
    μ = s - rint(s); zero where t - rint(s) is outside [0, T) (x's band-limited edges are
    not continued)."""
    y, fn = fir
    shift = _FIR_HOP.bit_length() - 1
    n = t1 - t0
    # s(t) per interval between warped knot positions, in the interval's own time (float32 is
    # then exact enough): s = s_i + slope_i · (t - start_i)
    start = np.r_[0, np.clip(np.ceil(pw) - t0, 0, n)].astype(np.int64)
    counts = np.diff(np.r_[start, n])
    slope = np.r_[0.0, np.diff(sig) / np.diff(pw), 0.0]
    s_start = np.interp(start + t0, pw, sig)
    local = np.arange(n, dtype=np.int64)
    local -= np.repeat(start, counts)
    s = local.astype(np.float32)
    s *= np.repeat(slope.astype(np.float32), counts)
    s += np.repeat(s_start.astype(np.float32), counts)
    whole = np.rint(s)
    mu = s - whole
    m = np.arange(t0 + FD_HALF, t1 + FD_HALF, dtype=np.int64)  # m = x index + FD_HALF, non-decreasing
    m -= whole.astype(np.int64)
    a, b = np.searchsorted(m, [FD_HALF, T + FD_HALF])  # m in [a, b) is inside x
    np.clip(m, 0, T + 2 * FD_HALF, out=m)
    idx = (m >> shift) * fn + (m & (_FIR_HOP - 1)) + 2 * FD_HALF
    terms = np.take(y, idx, axis=1)
    z = terms[-1]
    for q in range(_FARROW_ORDER - 1, -1, -1):
        z *= mu
        z += terms[q]
    z[:a] = 0.0  # x's band-limited edges are not continued
    z[b:] = 0.0
    return z


def delay_steps(rirs, times, fs: float) -> np.ndarray:
    """How far the direct path moves between neighbouring knots, as the renderer uses it:
    steps [K-1, C] in samples (d_{k+1} - d_k per channel), estimated from the RIRs.

    The reference channel is the one with the strongest first knot (W for FOA); its peak
    in each knot is the direct path's coarse place, and each channel's own peak is looked
    for within ±64 samples of it. Channels whose peaks coincide with the reference's
    wherever they are at least half as strong (FOA's W, Y, Z, X) are coincident and take
    the reference's steps; otherwise (a spaced array) each channel has its own. A step is
    the lag of the peak of the cross-correlation of the two knots' windows (-16..+32
    samples around the peak, Hann-tapered; band-limited interpolated to 1/4 sample, then a
    parabola), plus the difference of the coarse places. A step is trusted when the
    windows correlate (normalised peak ≥ MIN_CORR), the channel holds at least 1 % of the
    reference's energy there and the implied speed is below MAX_MACH; otherwise the
    channel takes the reference's step, and where the reference's is not trusted either,
    0 (the knots are crossfaded as they are there). Then a median of three neighbouring
    steps removes single outliers. Accuracy on simulated RIRs: ≤ 0.05 sample. A walk whose
    direct path stays within MIN_STEP / 2 at six knots spread over it (a circle) is taken
    as not moving (all steps 0) without estimating the rest.
    """
    h = rirs if isinstance(rirs, np.ndarray) else [np.asarray(r, dtype=np.float32) for r in rirs]
    steps = _steps_from("auto", h, np.asarray(times, dtype=np.float64) * fs)
    return np.zeros((len(h) - 1, h[0].shape[0])) if steps is None else steps


def _delay_steps(h, p: np.ndarray):
    """(steps [K-1, C'], reliable [K-1, C'], reference channel, coincident); C' = 1 for
    coincident channels (the reference's steps), else C."""
    K = len(h)
    C, L = h[0].shape
    W0, W1, R = _WIN[0], _WIN[1], 64
    ref = _reference_channel(h)
    # The reference channel's peak is the direct path. Probing four knots bounds where the
    # peaks are; every knot's is then found in one window around them (widened, once, if a
    # peak is at its edge).
    probe = sorted({0, K // 3, (2 * K) // 3, K - 1})
    at = [int(np.argmax(np.abs(h[k][ref]))) for k in probe]
    # At the probed knots, each channel's own peak within ±R of the reference's: a channel
    # at least half as strong there has its direct path as its peak (a weaker FOA channel's
    # may be a reflection). Channels whose peaks coincide with the reference's are
    # coincident (FOA) and take its steps; otherwise (a spaced array) each is estimated.
    coincident = True
    if C > 1:
        near = np.zeros((len(probe), C, 2 * R + 1), dtype=np.float32)
        for i, (k, c) in enumerate(zip(probe, at)):
            a0, a1 = max(c - R, 0), min(c + R + 1, L)
            np.abs(h[k][:, a0:a1], out=near[i, :, a0 - c + R : a1 - c + R])
        strong = near.max(axis=2) >= 0.5 * near[:, ref, R][:, None]
        same = (np.abs(np.argmax(near, axis=2) - R) <= 1)[strong]
        coincident = bool(same.mean() >= 0.8) if same.size else True
    c0, c1 = (ref, ref + 1) if coincident else (0, C)
    reach = R + (int(np.max(np.abs(np.diff(at)))) if len(at) > 1 else 0)
    r = ref - c0
    for _ in range(2):
        lo, hi = max(min(at) - reach, 0), min(max(at) + reach + 1, L)
        seg = h[:, c0:c1, lo:hi] if isinstance(h, np.ndarray) else np.stack([v[c0:c1, lo:hi] for v in h])  # [K, C', hi - lo]
        mag = np.abs(seg)
        place = np.argmax(mag[:, r], axis=1)
        edge = ((place == 0) & (lo > 0)) | ((place == hi - lo - 1) & (hi < L))
        if not edge.any():
            break
        reach = 4 * reach
    peak = mag[np.arange(K), r, place]
    if coincident:
        centre = place[:, None]
    else:  # each channel's own peak within ±R of the reference's
        near = np.clip(place[:, None] + np.arange(-R, R + 1), 0, hi - lo - 1)
        around = np.take_along_axis(mag, near[:, None, :], axis=2)
        centre = np.take_along_axis(near[:, None, :], np.argmax(around, axis=2)[..., None], axis=2)[..., 0]
    W = W0 + W1
    pos = centre[..., None] - W0 + np.arange(W)  # [K, C', W]
    win = np.take_along_axis(seg, np.clip(pos, 0, hi - lo - 1), axis=2)
    win *= (pos >= 0) & (pos < hi - lo)
    win *= _hann(W)
    # the cross-correlation of neighbouring knots' windows, band-limited interpolated to a
    # quarter sample (zero-padded spectrum), its peak refined by a parabola
    n, up = 2 * W, 4
    buf = np.zeros(win.shape[:-1] + (n,), dtype=np.float32)
    buf[..., :W] = win
    spec = fft.rfft(buf)
    cross = np.zeros((K - 1,) + spec.shape[1:-1] + (n * up // 2 + 1,), dtype=np.complex64)
    np.multiply(spec[1:], np.conj(spec[:-1]), out=cross[..., : n // 2 + 1])
    cc = fft.irfft(cross, n * up)  # [K-1, C', n·up]: lag of knot k+1 against knot k (correlation / up)
    i = np.argmax(cc, axis=-1)
    y0, y1, y2 = np.moveaxis(np.take_along_axis(cc, (i[..., None] + np.arange(-1, 2)) % (n * up), -1), -1, 0)
    curv = y0 - 2 * y1 + y2
    off = np.where(curv < 0, 0.5 * (y0 - y2) / np.where(curv < 0, curv, -1.0), 0.0)
    top = (y1 - 0.25 * (y0 - y2) * off) * up  # the parabola's peak, as an n·up-point irfft (1/(n·up))
    steps = (np.where(i > n * up // 2, i - n * up, i) + off) / up + np.diff(centre, axis=0).astype(np.float64)
    energy = np.sum(np.square(win, dtype=np.float64), axis=-1)
    corr = top / np.maximum(np.sqrt(energy[1:] * energy[:-1]), 1e-300)
    loud = energy >= 0.01 * energy[:, r : r + 1]
    reliable = ((corr >= MIN_CORR) & loud[1:] & loud[:-1] & (peak[1:, None] > 0) & (peak[:-1, None] > 0)
                & (np.abs(steps) <= MAX_MACH * np.diff(p)[:, None]))
    return steps, reliable, ref, coincident


def _reference_channel(h) -> int:
    """The channel with the strongest first knot (W for FOA): its peak is the direct path."""
    return int(np.argmax(np.abs(h[0]).max(axis=1)))


@lru_cache(maxsize=4)
def _hann(n: int) -> np.ndarray:
    return np.hanning(n + 2)[1:-1].astype(np.float32)


def _steps_from(delays, h, p: np.ndarray):
    """Steps [K-1, C] of the direct path between knots, or None (plain crossfade: the
    direct path does not move, or ``delays`` is None)."""
    if delays is None:
        return None
    C = h[0].shape[0]
    if isinstance(delays, str):
        if delays != "auto":
            raise ValueError(f"delays must be 'auto', None or an array of direct-path delays, got {delays!r}")
        K = len(p)
        if K >= 8:
            # A walk at constant distance (a circle) has the direct path at one delay: six
            # knots spread irregularly over the walk tell, for a fraction of the cost
            probe = np.unique(np.round(np.array([0.0, 0.21, 0.43, 0.58, 0.79, 1.0]) * (K - 1)).astype(int))
            # (unless the strongest channel's peaks there already lie samples apart: a line)
            ref = _reference_channel(h)
            peaks = [int(np.argmax(np.abs(h[k][ref]))) for k in probe]
            if max(peaks) - min(peaks) <= 2:
                st, ok, _, _ = _delay_steps([h[k] for k in probe], p[probe])
                if ok.all() and np.max(np.abs(np.cumsum(st, axis=0))) <= MIN_STEP / 2:
                    return None
        steps, ok, ref, coincident = _delay_steps(h, p)
        # where the reference channel is not reliable the knots are crossfaded as they are; a
        # channel of a spaced array that is not reliable itself follows the reference
        r = 0 if coincident else ref
        base = np.where(ok[:, r], steps[:, r], 0.0)
        st = np.broadcast_to(base[:, None], (len(base), C)) if coincident else np.where(ok & ok[:, r : r + 1], steps, base[:, None])
        if len(st) >= 3:  # a step that disagrees with both neighbours is an outlier (or a hole)
            st = np.median(np.stack([np.r_[st[:1], st[:-1]], st, np.r_[st[1:], st[-1:]]]), axis=0)
        bound = MAX_MACH * np.diff(p)[:, None]
        return np.clip(st, -bound, bound)
    d = np.asarray(delays, dtype=np.float64)
    K = len(p)
    if d.ndim == 1:
        d = d[:, None]
    if d.shape not in ((K, 1), (K, C)) or not np.all(np.isfinite(d)):
        raise ValueError(f"delays must be finite, [K] or [K, C] = [{K}] or [{K}, {C}], got shape {d.shape}")
    steps = np.diff(d, axis=0)
    if np.any(np.abs(steps) >= 0.5 * np.diff(p)[:, None]):
        raise ValueError("delays change by half the time between knots or more (a source at half the speed "
                         "of sound); direct-path delays are in samples")
    return np.broadcast_to(steps, (K - 1, C))


def _delay_groups(steps, C: int):
    """Channels that share one warp, with its knot shifts σ [K] (cumulative steps, None
    where no step exceeds MIN_STEP); None when no channel needs a warp.

    Channels whose steps stay within GROUP_TOL of the median over channels (all FOA
    channels, the capsules of a small array) share one warp by their mean steps; the
    rest get their own.
    """
    if steps is None:
        return None
    centre = np.median(steps, axis=1, keepdims=True)
    near = np.max(np.abs(steps - centre), axis=0) <= GROUP_TOL
    groups = []
    if near.any():
        chans = np.nonzero(near)[0]
        groups.append((chans, steps[:, chans].mean(axis=1)))
    groups += [(np.array([c]), steps[:, c]) for c in np.nonzero(~near)[0]]
    out = [(chans, np.r_[0.0, np.cumsum(st)] if np.max(np.abs(st), initial=0.0) > MIN_STEP else None)
           for chans, st in groups]
    return out if any(sig is not None for _, sig in out) else None
