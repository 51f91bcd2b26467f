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
once for the whole signal, since each sample feeds two knots.

Where the time goes, for 10 s, 4 channels, 7200-sample RIRs and 108 knots
(benchmarks/bench_banks.py; ~22 ms per source here): FFTs half (the RIR partitions a
third, 6.2M points), complex multiply-adds a quarter (6.2M, bound by memory traffic),
the rest copying RIRs in and overlap-adding blocks out. Large arrays are allocated
once per call; render workers keep freed memory (executors.reuse_freed_memory), since
fresh pages cost ~0.4 ms per MB here.
"""
from __future__ import annotations

import numpy as np

from . import fft
from .geometry import interpolate_positions  # noqa: F401  (labels use the renderer's blend; documented here)

_GROUP_BYTES = 2 << 20  # RIR spectra of one group of knots: about one core's L2


def render_static(signal, rir) -> np.ndarray:
    """Plain convolution, exact: signal [T] * rir [C, L] -> float32 [C, T + L - 1]
    (rows may be strided: a view into the overlap-add buffer, to save a copy).

    Overlap-add of N-point real FFTs (N = 2^15, or the next power of two >= 2L, or one
    transform when the whole output fits), blocks of B = N - L + 1 samples, all blocks and
    channels in one batch (tsel_data.fft).
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
    if nb == 1:
        return y[:, 0, :n_out]
    out = np.zeros((C, nb + 1, B), dtype=np.float32)
    out[:, :nb] += y[:, :, :B]
    out[:, 1:, : N - B] += y[:, :, B:]
    return out.reshape(C, -1)[:, :n_out]


def render_moving(signal, rirs, times, fs: float) -> np.ndarray:
    """Render a moving source: float32 [C, T + L - 1] (rows may be strided, as in
    :func:`render_static`).

    signal: [T] dry mono signal. rirs: [K, C, L] knot RIRs, or a sequence of K [C, L]
    arrays (views into a memory-mapped bank are read in place: Bank.views). times: [K]
    seconds at which each RIR applies fully, strictly increasing (may lie outside the
    clip). fs: Hz. One knot (K = 1) is the static convolution.
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
    if K == 1 or T == 0:
        return render_static(x, h[0])
    p = tau * fs
    # Interval k = samples [e_k, e_{k+1}): from knot k (inclusive) to knot k+1; interval 0
    # also holds the samples before knot 0, interval K-1 those after the last knot.
    e = np.empty(K + 1, dtype=np.int64)
    e[0], e[K] = 0, T
    e[1:K] = np.clip(np.ceil(p[1:]), 0, T)
    return _partitioned(x, p, e, h)


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
    (tsel_data.fft) is ~15% faster throughout; only the ratios between plans matter."""
    return N * (1.2 if N <= 5000 else 1.55 if N <= 25000 else 1.8)


def _sizes(B: int, L: int) -> tuple[int, int, int]:
    """(B, P, N) for blocks of B samples: P = ⌈L/B⌉ RIR partitions, N ≥ B + min(B, L) - 1."""
    return B, -(-L // B), fft.good_size(B + min(B, L) - 1)


def _plan(e: np.ndarray, C: int, L: int, T: int) -> tuple[int, int, int]:
    """(B, P, N): block size B (also the RIR partition length), P = ⌈L/B⌉ partitions,
    N-point FFTs; the candidate with the least estimated time.

    Estimate (ns): FFT rows (RIR partitions, input pieces, inverse transforms at 1.2x)
    times :func:`_fft_ns`, plus 0.9 ns per complex multiply-add, plus Python overhead
    per knot and per block; the number of (block, knot) pieces is counted on the real
    grid. Candidates: about ½–3 knot intervals, L / P for P = 1..3, and plain overlap-add
    (P = 1) at power-of-two FFT sizes.
    """
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
        rows = C * P * used + pairs + 1.2 * C * (nb + P - 1)
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
    for i in range(K - 1):
        a, b = int(e[i]), int(e[i + 1])
        if b > a:
            # n - p_i as (n - e_i) + (e_i - p_i): small numbers, exact enough in float32
            w = np.arange(b - a, dtype=np.float32)
            w += np.float32(a - p[i])
            w *= np.float32(1.0 / (p[i + 1] - p[i]))
            np.clip(w, 0.0, 1.0, out=w)
            np.multiply(w, x[a:b], out=rise[a:b])
    return rise, x - rise


def _partitioned(x: np.ndarray, p: np.ndarray, e: np.ndarray, h) -> np.ndarray:
    """Σ_k ((w_k·x) * h_k): float32 [C, T + L - 1]; w_k·x is zero outside [e_{k-1}, e_{k+1}).

    x: float32 [T]. p: float64 [K] knot positions (samples). e: int [K + 1] interval
    starts (e_0 = 0, e_K = T). h: K RIRs [C, L] (an array [K, C, L] or a sequence).
    """
    C, L = h[0].shape
    T = len(x)
    B, P, N = _plan(e, C, L, T)
    o = _grid_origin(e, T, B)
    nb, F = -(-(T - o) // B), N // 2 + 1
    q = -(-N // B)  # output blocks touched by one frame
    # Knot k has input on samples [lo_k, hi_k) = [e_{k-1}, e_{k+1}) (from 0 for k = 0),
    # which fall in blocks b0..b1: rising weight up to e_k, falling after.
    lo, mid, hi = np.r_[0, e[:-2]], e[:-1], e[1:]
    live = np.nonzero(hi > lo)[0]
    b0 = (lo[live] - o) // B
    nk = (hi[live] - 1 - o) // B - b0 + 1
    rise, fall = _crossfade(x, p, e)
    # Knots are taken a few at a time so that their spectra stay in cache; each knot's
    # RIR partitions are transformed once, from a zero-padded buffer [k, P, C, N].
    Gk = int(max(1, min(len(live), _GROUP_BYTES // (8 * F * P * C))))
    starts = np.arange(0, len(live), Gk)
    pairs = np.add.reduceat(nk, starts)
    hbuf = np.zeros((Gk, P, C, N), dtype=np.float32)
    H = np.empty((Gk, P, C, F), dtype=np.complex64)
    # Each group's input pieces are laid out end to end in `flat` (B per row), then copied
    # into zero-padded rows.
    rows = int(pairs.max())
    flat = np.empty(rows * B, dtype=np.float32)
    stage = np.zeros((rows, N), dtype=np.float32)
    X = np.empty((rows, F), dtype=np.complex64)
    prod = np.empty((P, C, F), dtype=np.complex64)
    xc = np.empty((C, F), dtype=np.complex64)
    # Output blocks, and the spectra of the unfinished ones: acc[i] is block a0 + i.
    out = np.zeros((C, nb + P - 1 + q, B), dtype=np.float32)
    ends = np.maximum.reduceat(b0 + nk, starts)
    acc = np.zeros((int(max(ends - b0[starts])) + P, C, F), dtype=np.complex64)
    y = fft.empty((len(acc), C, N))
    a0, used = 0, 0

    for gi, i in enumerate(starts):
        g = min(Gk, len(live) - i)
        for t in range(g):
            hk = h[int(live[i + t])]
            for j in range(P):
                w = min(B, L - j * B)
                hbuf[t, j, :, :w] = hk[:, j * B : j * B + w]
        fft.rfft(hbuf[:g], out=H[:g])  # [g, P, C, F]
        # Each knot's input, cut at block boundaries: consecutive rows of `stage`.
        r = 0
        for t in range(i, i + g):
            k, n = int(live[t]), int(nk[t])
            s0 = r * B - (o + int(b0[t]) * B)  # flat index of sample 0 for this knot's rows
            a, m, b = int(lo[k]), int(mid[k]), int(hi[k])
            flat[r * B : s0 + a] = 0
            flat[s0 + a : s0 + m] = rise[a:m]
            flat[s0 + m : s0 + b] = fall[m:b]
            flat[s0 + b : (r + n) * B] = 0
            r += n
        stage[:r, :B] = flat[: r * B].reshape(r, B)
        fft.rfft(stage[:r], out=X[:r])
        # Y_m += X_{m-j,k} · H_{k,j}: piece u of a knot feeds blocks b0 + u + (0..P-1)
        r = 0
        for t in range(g):
            m = int(b0[i + t]) - a0
            for u in range(int(nk[i + t])):
                xc[:] = X[r]  # [C, F]: multiplying without broadcasting along C is 25% faster
                np.multiply(xc, H[t], out=prod)
                acc[m + u : m + u + P] += prod
                r += 1
        used = max(used, int(ends[gi]) + P - 1 - a0)
        # Blocks before the next group's first block are complete: inverse transform
        # them and overlap-add at their place.
        done = (int(b0[i + g]) if i + g < len(live) else nb + P - 1) - a0
        if done > 0:
            fft.irfft(acc[:done], N, out=y[:done], overwrite=True)
            yt = y[:done].transpose(1, 0, 2)  # [C, done, N]
            for u in range(q):
                w = min(B, N - u * B)
                out[:, a0 + u : a0 + u + done, :w] += yt[:, :, u * B : u * B + w]
            keep = max(0, used - done)
            acc[:keep] = acc[done : done + keep]
            acc[keep:used] = 0
            a0, used = a0 + done, keep
    return out.reshape(C, -1)[:, -o : -o + T + L - 1]
