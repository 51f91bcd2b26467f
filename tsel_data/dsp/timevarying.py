"""Time-varying convolution: a source moving through a set of RIRs.

Model. Knot k holds RIR h_k [C, L] and applies fully at time τ_k (sample p_k = τ_k·fs).
A sound *emitted* at sample n goes through the linear interpolation of the knots around
it, with hat weights w_k(n) (1 at p_k, 0 at the neighbouring knots, constant before the
first knot and after the last; they sum to 1) — but first the knots' direct paths are
*aligned*, and the direct path moves continuously between them:

    h(n) = Σ_k w_k(n) · S_{d(n) - d_k}[h_k],    d(n) = Σ_k w_k(n) d_k,

d_k the direct path's delay in knot k (samples, per channel group), S_s a delay by s
samples. So the direct path of a sound emitted at n arrives at n + d(n), linear between
knots like the labelled position (:func:`interpolate_positions`): the direct path's
delay changes continuously and the Doppler shift is right. The plain crossfade Σ_k w_k h_k
(``delays=None``) blends two copies of the direct path d_{k+1} - d_k apart instead: a
comb filter at every midpoint between knots (for white noise -3 dB at the midpoint once
the copies are a sample apart, 1.4 cm at 24 kHz), i.e. a level ripple at the knot period
whenever the source's distance changes (line passes, linear bank trajectories). Reflections
keep the crossfade's behaviour: each moves at its own rate, so a part of the RIR ripples
still where its reflections' delays change differently from the direct path's
(docs/acoustics.md has measurements; simulated paths pass only their image-source parts
here, with knots closer on lines, and convolve the tail the knots share apart:
render.path_image).

How the model is computed: y = Σ_k h_k * S_{-σ_k}[w'_k · z], with σ_k = d_k - d_0 the
knot shifts and z the input *warped* by the piecewise-linear shift σ: z(t) = x(t - s(t)),
s linear between the warped knot positions p_k + σ_k (where x[p_k] lands), evaluated with
a Farrow fractional delay (:func:`farrow_coefficients`: K_μ[j] = Σ_q μ^q C[q, j], 33 taps,
μ = s - rint(s)); w'_k are the hat weights on the warped knot positions (= w_k at the
emission times), and S_{-σ_k} moves knot k's piece back by whole samples and the Farrow
kernel K_{-frac(σ_k)}. tests/dsp/test_moving_ripple.py has this sample by sample in float64
(``reference``); the engine equals it to 110-135 dB SNR (float32).

The direct path's steps d_{k+1} - d_k come from the RIRs themselves (:func:`delay_steps`;
for simulated and measured knots alike), or are given (``delays=``). Channels that share
their steps (FOA's coincident W, Y, Z, X; the capsules of a small array within
GROUP_TOL = 0.5 sample of each other) share one warp; others get their own. Where no step
exceeds MIN_STEP = 0.25 sample (arcs and circles at constant distance, identical knots,
knots without a common direct path) nothing is warped and the render is the plain
crossfade, bit for bit: identical RIRs give exactly the static convolution, nothing is
normalised by the clip length, the output keeps the full reverb tail (T + L - 1 samples).
This is exact — not an approximation like the STFT-domain (convolutive transfer
function) interpolation of the DCASE generator and SpatialScaper. Labels: the position
at any time is the same linear blend of knot positions, so the labelled path is the
rendered one (and the direct path arrives after the labelled distance / c).

Implementation: uniformly partitioned overlap-add convolution (a frequency-domain delay
line, e.g. F. Wefers, *Partitioned convolution algorithms for real-time auralization*,
2015), with the crossfade applied to the input: knot k's input w_k·x lives on samples
[e_{k-1}, e_{k+1}), e_k = ⌈τ_k·fs⌉. The signal is cut into blocks of B samples on a grid
aligned with a knot boundary, each RIR into P = ⌈L/B⌉ partitions of B samples; with
N-point real FFTs (N ≥ 2B - 1),

    Y_m = Σ_j Σ_{k with input in block m-j} X_{m-j,k} · H_{k,j},    y = Σ_m irfft(Y_m) placed at m·B,

X_{m,k} the spectrum of w_k·x on block m, H_{k,j} of partition j of h_k. Knots are taken
a few at a time so their spectra stay in cache. With B one knot interval (the bank walks'
0.1 s), a block holds two knots, each RIR is transformed once (P·C rows of N = 2B), and
each output block costs C inverse transforms; per call, B is the candidate with the least
estimated time (:func:`_plan`). The crossfaded input (a·x and (1 - a)·x) is computed
once for the whole signal, since each sample feeds two knots. A warped stream's pieces
reach a few samples past their knot's blocks (the shift moves them by up to a step); the
first and last row of each knot take that spill in margins of M samples (frames start M
before their block, N ≥ 2B + 2M - 1, M ≈ the largest step + 18), and the fractional part
of the knot's shift back is one multiplication of its rows' spectra.

Where the time goes, for 10 s, 4 channels, 7200-sample RIRs and 108 knots
(benchmarks/bench_banks.py; ~22 ms per source here): FFTs half (the RIR partitions a
third, 6.2M points), complex multiply-adds a quarter (6.2M, bound by memory traffic),
the rest copying RIRs in and overlap-adding blocks out. Estimating the direct path's
steps reads a window of each knot (~2 % of a render, less on circles: a six-knot check);
a warp (sources whose distance changes) costs the Farrow filters (one forward and four
inverse FFTs over the signal) and one gather: ~+35 % for such a source (docs/acoustics.md). Large arrays are allocated once per call; render
workers keep freed memory (malloc.reuse_freed_memory), since fresh pages cost ~0.4 ms
per MB here.
"""
from __future__ import annotations


import numpy as np

from ..core.geometry import interpolate_positions  # noqa: F401  (labels use the renderer's blend; documented here)
from . import fft
from .delaypath import FD_HALF, _delay_groups, _farrow_filter, _steps_from, _undo_spectra, _warp

_GROUP_BYTES = 2 << 20  # RIR spectra of one group of knots: about one core's L2


def render_static(signal, rir, out: np.ndarray | None = None) -> np.ndarray:
    """Plain convolution, exact: signal [T] * rir [C, L] -> float32 [C, T + L - 1]
    (rows may be strided: a view into the overlap-add buffer, to save a copy). With
    ``out`` ([C, K] float32, any K): its first K samples, zeros past T + L - 1, written
    there, the same numbers (the blocks are overlap-added into it, not into a buffer of
    their own that is then copied: a pass over the image saved).

    Overlap-add of N-point real FFTs (N = 2^15, or the next power of two >= 2L, or one
    transform when the whole output fits), blocks of B = N - L + 1 samples, all blocks and
    channels in one batch (tsel_data.dsp.fft).
    """
    x = np.asarray(signal, dtype=np.float32).reshape(-1)
    h = np.asarray(rir, dtype=np.float32)
    if h.ndim == 3 and h.shape[0] == 1:
        h = h[0]
    if h.ndim != 2:
        raise ValueError(f"rir must be [C, L], got shape {h.shape}")
    (C, L), T = h.shape, len(x)
    n_out = T + L - 1
    if T == 0:
        if out is not None:
            out[...] = 0.0
            return out
        return np.zeros((C, n_out), dtype=np.float32)
    N = max(1 << 15, 1 << int(np.ceil(np.log2(2 * L))))
    if n_out <= N:
        N = fft.good_size(max(n_out, 1))
    B = N - L + 1  # >= L when there are several blocks: a frame spans two blocks at most
    nb = max(1, -(-T // B))
    xb = np.zeros(nb * B, dtype=np.float32)
    xb[:T] = x
    xp = np.zeros((nb, N), dtype=np.float32)
    xp[:, :B] = xb.reshape(nb, B)
    hp = np.zeros((C, N), dtype=np.float32)
    hp[:, :L] = h
    y = fft.irfft(fft.rfft(hp)[:, None, :] * fft.rfft(xp)[None], N, overwrite=True)  # [C, nb, N]
    if out is not None:
        return _overlap_add_into(y, B, n_out, out)
    if nb == 1:
        return y[:, 0, :n_out]
    full = np.zeros((C, nb + 1, B), dtype=np.float32)
    full[:, :nb] += y[:, :, :B]
    full[:, 1:, : N - B] += y[:, :, B:]
    return full.reshape(C, -1)[:, :n_out]


def _overlap_add_into(y: np.ndarray, B: int, n_out: int, out: np.ndarray) -> np.ndarray:
    """The first K = out.shape[-1] samples of the overlap-add of ``y`` [C, nb, N] (blocks
    B apart, n_out long) into ``out`` [C, K], zeros past n_out: each sample the same float32
    sums as :func:`render_static`'s zero-filled buffer gives, 0 + head (+ the previous
    block's tail), so -0.0 becomes 0.0 there too; one block is copied as it is."""
    _, nb, N = y.shape
    K = out.shape[-1]
    keep = min(K, n_out)
    zero = np.float32(0.0)
    if nb == 1:
        out[:, :keep] = y[:, 0, :keep]
    else:
        tail = N - B
        for m in range(nb + 1):
            a = m * B
            if a >= keep:
                break
            w = min(B, keep - a)
            if m < nb:
                np.add(y[:, m, :w], zero, out=out[:, a:a + w])
                if m:
                    t = min(tail, w)
                    out[:, a:a + t] += y[:, m - 1, B:B + t]
            else:  # past the last block: its tail alone
                t = min(tail, w)
                np.add(y[:, m - 1, B:B + t], zero, out=out[:, a:a + t])
                out[:, a + t:a + w] = 0.0
    out[:, keep:] = 0.0
    return out


def render_moving(signal, rirs, times, fs: float, *, delays="auto", fold: int = 1) -> np.ndarray:
    """Render a moving source: float32 [C, T + L - 1] (rows may be strided, as in
    :func:`render_static`).

    signal: [T] dry mono signal. rirs: [K, C, L] knot RIRs, or a sequence of K [C, L]
    arrays (views into a memory-mapped bank are read in place: Bank.views). times: [K]
    seconds at which each RIR applies fully, strictly increasing (may lie outside the
    clip). fs: Hz. One knot (K = 1) is the static convolution.

    delays: how the direct path moves between knots (module docstring). ``"auto"``
    (default): estimated from the RIRs themselves (:func:`delay_steps`); where it moves
    by more than MIN_STEP samples between knots, the knots' direct paths are aligned and
    the direct path moves continuously. An array of direct-path delays in samples, [K]
    (one for all channels) or [K, C]: these instead of the estimate. ``None``: the plain
    crossfade of the knot RIRs (the delay-unaware model, for comparisons).

    fold: the RIRs' channels are ``fold`` groups of C / fold (group-major; image groups of
    a simulated source, acoustics/image_paths.py), each with its own warp from its own
    ``delays`` columns (as if rendered alone), summed into C / fold output channels in the
    frequency domain: one render instead of ``fold``, whose inverse transforms, overlap-add
    and input filters are shared.
    """
    x = np.asarray(signal, dtype=np.float32).reshape(-1)
    tau = np.asarray(times, dtype=np.float64).reshape(-1)
    if isinstance(rirs, np.ndarray):
        h = rirs.astype(np.float32, copy=False)
        shape = h.shape
    else:
        h = [np.asarray(r, dtype=np.float32) for r in rirs]
        shape = (len(h),) + (h[0].shape if h else ())
        if any(r.shape != shape[1:] for r in h):
            raise ValueError(f"rirs must all have one shape [C, L]; got {sorted({r.shape for r in h})}")
    if len(shape) != 3 or shape[0] != len(tau):
        raise ValueError(f"rirs must be [K, C, L] with K = len(times) = {len(tau)}, got {tuple(shape)}")
    if len(tau) > 1 and np.any(np.diff(tau) <= 0):
        raise ValueError("knot times must be strictly increasing")
    K, T = len(tau), len(x)
    if shape[1] % fold:
        raise ValueError(f"{shape[1]} channels do not fold into {fold} groups")
    if K == 1 or T == 0:
        y = render_static(x, h[0])
        return y if fold == 1 else y.reshape(fold, shape[1] // fold, -1).sum(axis=0)
    p = tau * fs
    # Interval k = samples [e_k, e_{k+1}): from knot k (inclusive) to knot k+1; interval 0
    # also holds the samples before knot 0, interval K-1 those after the last knot.
    e = np.empty(K + 1, dtype=np.int64)
    e[0], e[K] = 0, T
    e[1:K] = np.clip(np.ceil(p[1:]), 0, T)
    steps = _steps_from(delays, h, p)
    if fold == 1:
        groups = _delay_groups(steps, shape[1])
    else:  # each fold's channels grouped as a render of its own would group them
        c = shape[1] // fold
        groups = []
        for f in range(fold):
            mine = _delay_groups(None if steps is None else steps[:, f * c:(f + 1) * c], c)
            groups += [(chans + f * c, sig) for chans, sig in mine] if mine else [(np.arange(c) + f * c, None)]
        if all(sig is None for _, sig in groups):
            groups = None
    return _partitioned(x, p, e, h, groups, fold)


def _grid_origin(e: np.ndarray, T: int, B: int) -> int:
    """Grid origin o, -B < o <= 0: blocks [o + mB, o + (m+1)B) start at the first interior knot boundary."""
    K = len(e) - 1
    inner = e[1:K][(e[1:K] > 0) & (e[1:K] < T)]
    return int(inner[0] % B - B) if inner.size and inner[0] % B else 0


def _pairs_per_block(e: np.ndarray, T: int, B: int) -> tuple[int, int]:
    """(number of blocks, number of (block, knot) pairs with input) on the grid for B."""
    K = len(e) - 1
    o = _grid_origin(e, T, B)
    nb = -(-(T - o) // B)
    start = o + np.arange(nb, dtype=np.int64) * B
    first = np.searchsorted(e, np.maximum(start, 0), "right") - 1
    last = np.searchsorted(e, np.minimum(start + B, T) - 1, "right") - 1
    # block m holds intervals first..last; interval i feeds knots i and i+1
    return nb, int((np.minimum(last + 1, K - 1) - first + 1).sum())


def _fft_ns(N: int) -> float:
    """Time of one N-point float32 real FFT row (ns), batched, measured here with pocketfft:
    ~1.2 ns/point while the row fits in L1, ~1.55 up to 25k points, ~1.8 beyond. ducc0
    (tsel_data.dsp.fft) is ~15% faster throughout; only the ratios between plans matter."""
    return N * (1.2 if N <= 5000 else 1.55 if N <= 25000 else 1.8)


def _sizes(B: int, L: int) -> tuple[int, int, int]:
    """(B, P, N) for blocks of B samples: P = ⌈L/B⌉ RIR partitions, N ≥ B + min(B, L) - 1."""
    return B, -(-L // B), fft.good_size(B + min(B, L) - 1)


def _plan(e: np.ndarray, C: int, L: int, T: int, streams: int = 1, out: int | None = None) -> tuple[int, int, int]:
    """(B, P, N): block size B (also the RIR partition length), P = ⌈L/B⌉ partitions,
    N-point FFTs; the candidate with the least estimated time.

    Estimate (ns): FFT rows (RIR partitions, input pieces of each of ``streams``,
    inverse transforms of the ``out`` output channels (default C) at 1.2x) times
    :func:`_fft_ns`, plus 0.9 ns per complex multiply-add, plus Python overhead per knot
    and per block; the number of (block, knot) pieces is counted on the real grid.
    Candidates: about ½–3 knot intervals, L / P for P = 1..3, and plain overlap-add
    (P = 1) at power-of-two FFT sizes.
    """
    out = C if out is None else out
    K = len(e) - 1
    la = np.diff(e)
    inner = la[1 : K - 1][la[1 : K - 1] > 0]
    D = int(np.median(inner)) if inner.size else T
    cand = {int(round(D * f)) for f in (0.5, 1, 2, 3)}
    cand |= {-(-L // P) for P in (1, 2, 3)}
    cand |= {n - L + 1 for n in (1 << 13, 1 << 14, 1 << 15, 1 << 16)}
    used = int(np.count_nonzero(la + np.r_[0, la[:-1]]))  # knots with input: intervals k-1, k
    best = None
    for B in sorted({min(max(b, 16), max(T, 16)) for b in cand}):
        B, P, N = _sizes(B, L)
        if N > max(1 << 16, 2 * L):  # out of cache: slower than the model says
            continue
        nb, pairs = _pairs_per_block(e, T, B)
        rows = C * P * used + streams * pairs + 1.2 * out * (nb + P - 1)
        cost = rows * _fft_ns(N) + 0.9 * pairs * P * C * (N // 2 + 1) + 10_000 * used + 5_000 * nb
        if best is None or cost < best[0]:
            best = (cost, B, P, N)
    return best[1:]


def _crossfade(x: np.ndarray, p: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a·x, (1 - a)·x), float32 [T]: on interval i (samples [e_i, e_{i+1})) the signal
    reaches knot i with weight 1 - a and knot i + 1 with weight a, a = (n - p_i) / (p_{i+1} - p_i)
    clipped to [0, 1]; on the last interval a = 0. Computed once for all knots.
    """
    K = len(p)
    rise = np.zeros_like(x)
    lo, hi = int(e[0]), int(e[K - 1])  # intervals 0 .. K-2
    if hi > lo:
        # n - p_i as (n - e_i) + (e_i - p_i): small numbers, exact enough in float32
        length = np.diff(e[:K])
        w = (np.arange(lo, hi) - np.repeat(e[: K - 1], length)).astype(np.float32)
        w += np.repeat((e[: K - 1] - p[: K - 1]).astype(np.float32), length)
        w *= np.repeat((1.0 / np.diff(p)).astype(np.float32), length)
        np.clip(w, 0.0, 1.0, out=w)
        np.multiply(w, x[lo:hi], out=rise[lo:hi])
    return rise, x - rise


def _partitioned(x: np.ndarray, p: np.ndarray, e: np.ndarray, h, groups=None, fold: int = 1) -> np.ndarray:
    """Σ_k ((w_k·x) * h_k), or with ``groups`` the delay-aware model (module docstring):
    float32 [C, T + L - 1]; with ``fold``, the C channels summed in ``fold`` groups of C / fold
    (before the inverse transforms): [C / fold, T + L - 1].

    x: float32 [T]. p: float64 [K] knot positions (samples). e: int [K + 1] interval
    starts (e_0 = 0, e_K = T). h: K RIRs [C, L] (an array [K, C, L] or a sequence).
    groups: None, or [(channels, σ [K] or None), ...] from :func:`_delay_groups`.
    """
    C, L = h[0].shape
    T = len(x)
    streams = _streams(x, p, e, groups, C)
    warped = any(s.frac is not None for s in streams)
    # Grid positions of knot k's input: [lo_k, hi_k), the union over streams. Nominally
    # (no warp) [e_{k-1}, e_{k+1}); a warped stream spills a few samples beyond, which the
    # first and last rows of the knot take in margins of Mr samples (M = Mr + the
    # undo kernel's reach: a row's frame starts M samples before its block).
    big = np.iinfo(np.int64).max // 4
    lo = np.min([np.where(s.hi > s.lo, s.lo + s.off, big) for s in streams], axis=0)  # over non-empty pieces
    hi = np.max([np.where(s.hi > s.lo, s.hi + s.off, -big) for s in streams], axis=0)
    live = np.nonzero(hi > lo)[0]
    if warped:
        nom_lo, nom_hi = np.r_[0, e[:-2]][live], e[1:][live]
        spill = int(max(0, np.max(nom_lo - lo[live]), np.max(hi[live] - nom_hi)))
        Mr = spill + 1
        M = Mr + FD_HALF
    else:
        Mr = M = 0
    B, P, N = _plan(e, C, L, T, len(streams), C // fold) if fold > 1 else _plan(e, C, L, T)
    if M:
        N = fft.good_size(B + min(B, L) - 1 + 2 * M)
    o = _grid_origin(e, T, B)
    nb, F = -(-(T - o) // B), N // 2 + 1
    q = -(-N // B)  # output blocks touched by one frame
    b0 = (lo[live] - o + Mr) // B
    b0 = np.minimum.accumulate(b0[::-1])[::-1]  # nondecreasing, so finished blocks stay finished
    nk = -(-(hi[live] - o - Mr) // B) - b0
    nk = np.maximum(nk, 1)
    nb = max(nb, int(np.max(b0 + nk)))  # a warped piece may reach a block past the clip's last
    undo = [None if s.frac is None else _undo_spectra(s.frac, N) for s in streams]
    # Knots are taken a few at a time so that their spectra stay in cache; each knot's
    # RIR partitions are transformed once, from a zero-padded buffer [k, P, C, N].
    Gk = int(max(1, min(len(live), _GROUP_BYTES // (8 * F * P * C))))
    starts = np.arange(0, len(live), Gk)
    pairs = np.add.reduceat(nk, starts)
    hbuf = np.zeros((Gk, P, C, N), dtype=np.float32)
    H = np.empty((Gk, P, C, F), dtype=np.complex64)
    rows = int(pairs.max())
    stage = np.zeros((rows, N), dtype=np.float32)
    flat = np.empty(rows * B, dtype=np.float32)
    X = [np.empty((rows, F), dtype=np.complex64) for _ in streams]
    prod = np.empty((P, C, F), dtype=np.complex64)
    Co = C // fold  # output channels
    folded = np.empty((P, Co, F), dtype=np.complex64) if fold > 1 else prod
    xc = np.empty((C, F), dtype=np.complex64)
    # Output blocks, and the spectra of the unfinished ones: acc[i] is block a0 + i.
    out = np.zeros((Co, nb + P - 1 + q, B), dtype=np.float32)
    ends = np.maximum.reduceat(b0 + nk, starts)
    # acc holds the blocks from the current group's first one to the furthest any knot so
    # far reaches (an earlier knot may reach further than the current ones)
    acc = np.zeros((int(max(np.maximum.accumulate(ends) - b0[starts])) + P, Co, F), dtype=np.complex64)
    y = fft.empty((len(acc), Co, N))
    a0, used = 0, 0
    width = B + 2 * M

    for gi, i in enumerate(starts):
        g = min(Gk, len(live) - i)
        for t in range(g):
            hk = h[int(live[i + t])]
            full = min(P, L // B)  # whole partitions in one strided copy, then the last one
            hbuf[t, :full, :, :B] = hk[:, : full * B].reshape(C, full, B).transpose(1, 0, 2)
            if full < P:
                hbuf[t, full, :, : L - full * B] = hk[:, full * B :]
        fft.rfft(hbuf[:g], out=H[:g])  # [g, P, C, F]
        # Each knot's input, cut at block boundaries: consecutive rows of `stage` (the
        # first and last row of a knot also take its spill, Mr samples either side).
        if not warped:
            # one plain stream: each knot's rows laid out end to end in `flat`, then copied
            s = streams[0]
            r = 0
            for t in range(i, i + g):
                k, n = int(live[t]), int(nk[t])
                s0 = r * B - (o + int(b0[t]) * B)  # flat index of sample 0 for this knot's rows
                a, m, b = int(s.lo[k]), int(s.mid[k]), int(s.hi[k])
                flat[r * B : s0 + a] = 0
                flat[s0 + a : s0 + m] = s.rise[a:m]
                flat[s0 + m : s0 + b] = s.fall[m:b]
                flat[s0 + b : (r + n) * B] = 0
                r += n
            stage[:r, :B] = flat[: r * B].reshape(r, B)
            fft.rfft(stage[:r], out=X[0][:r])
        for s, Xs, us in zip(streams, X, undo) if warped else ():
            stage[: pairs[gi], :width] = 0
            r = 0
            for t in range(i, i + g):
                k, n, base = int(live[t]), int(nk[t]), o + int(b0[t]) * B
                off, a, m, b = int(s.off[k]), int(s.lo[k]), int(s.mid[k]), int(s.hi[k])
                for u in range(n):
                    g_lo = base + u * B - (Mr if u == 0 else 0)
                    g_hi = base + (u + 1) * B + (Mr if u == n - 1 else 0)
                    f0 = base + u * B - M  # grid position of the frame's first sample
                    for src, s_lo, s_hi in ((s.rise, a, m), (s.fall, m, b)):
                        c0, c1 = max(s_lo + off, g_lo), min(s_hi + off, g_hi)
                        if c1 > c0:
                            stage[r + u, c0 - f0 : c1 - f0] = src[c0 - off : c1 - off]
                r += n
            fft.rfft(stage[:r], out=Xs[:r])
            if us is not None:  # the rest of the knot's shift: a fractional advance
                r = 0
                for t in range(i, i + g):
                    n = int(nk[t])
                    Xs[r : r + n] *= us[int(live[t])]
                    r += n
        # Y_m += X_{m-j,k} · H_{k,j}: piece u of a knot feeds blocks b0 + u + (0..P-1)
        r = 0
        for t in range(g):
            m = int(b0[i + t]) - a0
            for u in range(int(nk[i + t])):
                if len(streams) == 1:
                    xc[:] = X[0][r]  # [C, F]: multiplying without broadcasting along C is 25% faster
                else:
                    for s, Xs in zip(streams, X):
                        xc[s.chans] = Xs[r]
                np.multiply(xc, H[t], out=prod)
                if fold > 1:
                    np.add.reduce(prod.reshape(P, fold, Co, F), axis=1, out=folded)
                acc[m + u : m + u + P] += folded
                r += 1
        used = max(used, int(ends[gi]) + P - 1 - a0)
        # Blocks before the next group's first block are complete: inverse transform
        # them and overlap-add at their place.
        done = (int(b0[i + g]) if i + g < len(live) else nb + P - 1) - a0
        if done > 0:
            fft.irfft(acc[:done], N, out=y[:done], overwrite=True)
            yt = y[:done].transpose(1, 0, 2)  # [Co, done, N]
            for u in range(q):
                w = min(B, N - u * B)
                out[:, a0 + u : a0 + u + done, :w] += yt[:, :, u * B : u * B + w]
            keep = max(0, used - done)
            acc[:keep] = acc[done : done + keep]
            acc[keep:used] = 0
            a0, used = a0 + done, keep
    return out.reshape(Co, -1)[:, M - o : M - o + T + L - 1]


class _Stream:
    """One input signal and the channels it feeds: the crossfaded pieces ``rise`` / ``fall``
    of a (warped) signal, knot k's input at indices [lo_k, hi_k) of them (rise up to mid_k),
    which land at grid position index + off_k, then shifted by -frac_k (None: no shift)."""

    __slots__ = ("chans", "rise", "fall", "lo", "mid", "hi", "off", "frac")

    def __init__(self, chans, rise, fall, ends, off, frac):
        self.chans, self.rise, self.fall, self.off, self.frac = chans, rise, fall, off, frac
        self.lo, self.mid, self.hi = np.r_[0, ends[:-2]], ends[:-1], ends[1:]


def _streams(x, p, e, groups, C) -> list:
    """The input streams: one plain stream for all channels without ``groups``; else one
    warped stream per group with a shift σ, and one plain stream for the others."""
    K = len(p)
    if groups is None:
        return [_Stream(slice(None), *_crossfade(x, p, e), e, np.zeros(K, np.int64), None)]
    out, plain = [], []
    v = None
    for chans, sig in groups:
        if sig is None:
            plain.extend(int(c) for c in chans)
            continue
        if v is None:
            v = _farrow_filter(x)
        # x[n], emitted at n, is at n + σ(n) in the warped signal (σ linear between knots,
        # constant outside): x[0] .. x[T - 1] span [t0, t1)
        n0, n1 = 0.0, float(len(x))
        t0 = int(np.floor(n0 + np.interp(n0, p, sig))) - 1
        t1 = int(np.ceil(n1 + np.interp(n1, p, sig))) + 2
        pw = p + sig  # knot k applies fully at time p_k + σ_k of the warped signal
        z = _warp(v, t0, t1, pw, sig, len(x))
        ew = np.empty(K + 1, dtype=np.int64)
        ew[0], ew[K] = 0, t1 - t0
        ew[1:K] = np.clip(np.ceil(pw[1:]) - t0, 0, t1 - t0)
        shift = np.rint(sig)
        ch = slice(None) if len(chans) == C else np.asarray(chans)
        st = _Stream(ch, *_crossfade(z, pw - t0, ew), ew, (t0 - shift).astype(np.int64), sig - shift)
        # knot 1 takes interval 0 only after knot 0 (its weight is 0 before): without this,
        # a first knot after the clip's start would give knot 1 a piece of zeros that its
        # own shift puts anywhere
        st.lo[1] = min(max(int(np.ceil(pw[0])) - t0, 0), int(st.mid[1]))
        out.append(st)
    if plain:
        ch = slice(None) if len(plain) == C else np.asarray(sorted(plain))
        out.append(_Stream(ch, *_crossfade(x, p, e), e, np.zeros(K, np.int64), None))
    return out
