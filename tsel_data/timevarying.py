"""Time-varying convolution: a source moving through a set of RIRs.

Model. Knot k holds RIR h_k [C, L] and applies fully at time τ_k. The RIR of a sound
*emitted* at sample n is the linear interpolation between the knots around it,

    h(n) = Σ_k w_k(n) h_k,    w_k = hat function: 1 at τ_k, 0 at τ_{k-1} and τ_{k+1},

(constant before the first knot and after the last), and the output is

    y[c, m] = Σ_n x[n] h_c(n)[m - n] = Σ_k ( (w_k · x) * h_{k,c} )[m].

So each knot's RIR convolves one crossfaded stretch of the signal (the support of w_k,
two knot intervals), and the pieces are overlap-added. The weights sum to 1 at every
sample, so identical RIRs give exactly the static convolution; nothing is normalised by
the clip length; the output keeps the full reverb tail (T + L - 1 samples). This is
exact — it equals the sample-by-sample time-varying convolution above — unlike the
STFT-domain (convolutive transfer function) interpolation of the DCASE generator and
SpatialScaper, which approximates it frame by frame. Labels use the same weights:
:func:`interpolate_positions` gives the position at any time as the same linear blend
of knot positions, so the labelled path is the rendered one.

Implementation: the crossfaded stretches are packed into frames; per frame, each
stretch's spectrum times its RIR's spectrum is summed and inverse transformed once
(batched real FFTs, float32), then the frames are overlap-added into the output.
"""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft

_BATCH_BYTES = 32 << 20  # bound on one batch's complex spectra


def render_static(signal, rir) -> np.ndarray:
    """Plain FFT convolution: signal [T] * rir [C, L] -> float32 [C, T + L - 1]."""
    x = np.asarray(signal, dtype=np.float32).reshape(-1)
    h = np.asarray(rir, dtype=np.float32)
    if h.ndim == 3 and h.shape[0] == 1:
        h = h[0]
    if h.ndim != 2:
        raise ValueError(f"rir must be [C, L], got shape {h.shape}")
    n_out = len(x) + h.shape[1] - 1
    nfft = sfft.next_fast_len(n_out, real=True)
    y = sfft.irfft(sfft.rfft(x, nfft)[None, :] * sfft.rfft(h, nfft, axis=-1), nfft, axis=-1)
    return np.ascontiguousarray(y[:, :n_out], dtype=np.float32)


def knot_weights(times, fs: float, n: np.ndarray, k: np.ndarray) -> np.ndarray:
    """w_k(n): the crossfade weight of knot ``k`` at sample ``n`` (broadcasting arrays).

    Linear between neighbouring knots, 1 before the first and after the last knot; the
    weights of all knots sum to 1 at every sample.
    """
    p = np.asarray(times, dtype=np.float64) * fs
    K = len(p)
    k = np.asarray(k)
    n = np.asarray(n, dtype=np.float64)
    pk = p[k]
    left = p[np.maximum(k - 1, 0)]
    right = p[np.minimum(k + 1, K - 1)]
    with np.errstate(divide="ignore", invalid="ignore"):
        rise = np.where(k == 0, 1.0, (n - left) / (pk - left))
        fall = np.where(k == K - 1, 1.0, (right - n) / (right - pk))
    return np.clip(np.where(n <= pk, rise, fall), 0.0, 1.0)


def render_moving(signal, rirs, times, fs: float) -> np.ndarray:
    """Render a moving source: float32 [C, T + L - 1].

    signal: [T] dry mono signal. rirs: [K, C, L] knot RIRs. times: [K] seconds at which
    each RIR applies fully, strictly increasing (may lie outside the clip). fs: Hz.
    One knot (K = 1) is the static convolution.
    """
    x = np.asarray(signal, dtype=np.float32).reshape(-1)
    h = np.asarray(rirs, dtype=np.float32)
    tau = np.asarray(times, dtype=np.float64).reshape(-1)
    if h.ndim != 3 or h.shape[0] != len(tau):
        raise ValueError(f"rirs must be [K, C, L] with K = len(times) = {len(tau)}, got {h.shape}")
    if len(tau) > 1 and np.any(np.diff(tau) <= 0):
        raise ValueError("knot times must be strictly increasing")
    K, C, L = h.shape
    T = len(x)
    if K == 1 or T == 0:
        return render_static(x, h[0])
    p = tau * fs
    # Support of w_k: the open interval (p_{k-1}, p_{k+1}), clipped to the signal.
    ar = np.arange(K)
    lo = np.where(ar == 0, 0, np.floor(np.r_[p[0], p[:-1]]) + 1)
    hi = np.where(ar == K - 1, T - 1, np.ceil(np.r_[p[1:], p[-1]]) - 1)
    lo, hi = np.clip(lo, 0, T).astype(np.int64), np.clip(hi, -1, T - 1).astype(np.int64)
    live = np.nonzero(hi >= lo)[0]
    support = hi[live] - lo[live] + 1
    # One FFT size for all: a power of two (fastest here) holding a typical knot's
    # stretch convolved with the RIR. Longer stretches are cut into pieces of at most
    # `span`; pieces are packed into frames of `span` samples, and all pieces of a frame
    # share one inverse FFT per channel (their spectra are summed first).
    nfft = sfft.next_fast_len(int(max(np.median(support) + L - 1, 2 * L, 64)), real=True)
    span = nfft - L + 1
    n_pieces = -(-support // span)
    knot = np.repeat(live, n_pieces)
    first = np.repeat(np.cumsum(n_pieces) - n_pieces, n_pieces)
    plo = lo[knot] + (np.arange(len(knot)) - first) * span
    phi = np.minimum(plo + span - 1, hi[knot])
    order = np.argsort(plo, kind="stable")
    knot, plo, phi = knot[order], plo[order], phi[order]
    frame_of = np.empty(len(knot), dtype=np.int64)
    frame_lo = []
    for j in range(len(knot)):  # greedy packing, one step per piece (not per sample)
        if not frame_lo or phi[j] >= frame_lo[-1] + span:
            frame_lo.append(plo[j])
        frame_of[j] = len(frame_lo) - 1
    frame_lo = np.asarray(frame_lo, dtype=np.int64)

    out = np.zeros((C, T + L - 1 + nfft), dtype=np.float32)
    rows_per_batch = max(1, _BATCH_BYTES // ((C + 1) * (nfft // 2 + 1) * 8))
    j = 0
    while j < len(knot):
        # whole frames per batch, so each frame's spectra are summed in one place
        end = min(len(knot), j + rows_per_batch)
        if end < len(knot):
            end = max(j + 1, int(np.searchsorted(frame_of, frame_of[end], "left")))
        sl = slice(j, end)
        seg = np.zeros((end - j, nfft), dtype=np.float32)
        for r in range(end - j):  # one slice per piece
            a, b, k = plo[j + r], phi[j + r] + 1, knot[j + r]
            n = np.arange(a, b)
            c0 = a - frame_lo[frame_of[j + r]]
            seg[r, c0 : c0 + b - a] = x[a:b] * knot_weights(tau, fs, n, k).astype(np.float32)
        hpad = np.zeros((end - j, C, nfft), dtype=np.float32)
        hpad[:, :, :L] = h[knot[sl]]
        spec = sfft.rfft(seg, axis=-1)[:, None, :] * sfft.rfft(hpad, axis=-1)
        frames, starts = np.unique(frame_of[sl], return_index=True)
        # Sum each frame's rows (contiguous): one vectorised add per row rank, since
        # np.add.reduceat is slow on complex arrays.
        rank = np.arange(end - j) - starts[np.searchsorted(frames, frame_of[sl])]
        acc = spec[starts].copy()
        for q in range(1, int(rank.max()) + 1):
            r = np.nonzero(rank == q)[0]
            acc[np.searchsorted(frames, frame_of[sl][r])] += spec[r]
        y = sfft.irfft(acc, nfft, axis=-1)
        for f, yf in zip(frames, y):
            out[:, frame_lo[f] : frame_lo[f] + nfft] += yf
        j = end
    return out[:, : T + L - 1]


def interpolate_positions(times, positions, t) -> np.ndarray:
    """Positions (az °, el °, dist m) [len(t), 3] at times ``t`` from knot positions [K, 3].

    The same linear-in-time blend as the renderer's crossfade (constant outside the
    knots); azimuth is unwrapped before interpolating and wrapped to [-180, 180) after.
    """
    tau = np.asarray(times, dtype=np.float64).reshape(-1)
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t, dtype=np.float64)
    if len(tau) == 1:
        return np.broadcast_to(pos[0], t.shape + (3,)).copy()
    az = np.degrees(np.unwrap(np.radians(pos[:, 0])))
    out = np.stack([np.interp(t, tau, az), np.interp(t, tau, pos[:, 1]), np.interp(t, tau, pos[:, 2])], axis=-1)
    out[..., 0] = (out[..., 0] + 180.0) % 360.0 - 180.0
    return out
