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

Implementation: uniformly partitioned overlap-add convolution (frequency-domain delay
line; e.g. Wefers, *Partitioned convolution algorithms for real-time auralization*,
2015, ch. 5), with the crossfade folded into the input side. Between knots k and k+1
(samples [e_k, e_{k+1}), e_k = ⌈τ_k·fs⌉) the signal splits exactly as

    x = x_b + x_a,   x_a = a·x,  x_b = (1 - a)·x,  a(n) = (n - τ_k fs) / ((τ_{k+1} - τ_k) fs),

and knot k's input w_k·x is x_a on interval k-1 followed by x_b on interval k. The
signal is cut into blocks of B samples on a grid aligned with a knot boundary, each RIR
into P = ⌈L/B⌉ partitions of B samples; with N-point real FFTs (N ≥ 2B - 1),

    Y_m = Σ_j Σ_{k active in block m-j} X_{m-j,k} · H_{k,j},     y = overlap-add of irfft(Y_m) at m·B,

X_{m,k} the spectrum of knot k's input in block m, H_{k,j} of partition j of h_k. Blocks
are processed a few at a time so the spectra stay in cache. With B about one knot
interval, each block sees two knots, each knot's RIR is transformed once, and each
output block costs C small inverse FFTs; B is chosen per call from a cost model.
"""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft

_GROUP_BYTES = 1 << 20  # working set of one group of blocks: about half a core's L2
_MAC_COST = 4.5  # one complex multiply-add, in units of one (N log2 N)-FFT "step" (measured)
_BLOCK_COST = 60_000  # Python/numpy overhead per block, same units (measured)


def render_static(signal, rir) -> np.ndarray:
    """Plain convolution, exact: signal [T] * rir [C, L] -> float32 [C, T + L - 1]."""
    x = np.asarray(signal, dtype=np.float32).reshape(-1)
    h = np.asarray(rir, dtype=np.float32)
    if h.ndim == 3 and h.shape[0] == 1:
        h = h[0]
    if h.ndim != 2:
        raise ValueError(f"rir must be [C, L], got shape {h.shape}")
    if len(x) == 0:
        return np.zeros((h.shape[0], h.shape[1] - 1), dtype=np.float32)
    # One knot: a single interval [0, T) whose signal all goes to that knot.
    return _partitioned(np.zeros_like(x), x, np.array([0, len(x)]), h[None])


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
    K, T = len(tau), len(x)
    if K == 1 or T == 0:
        return render_static(x, h[0])
    p = tau * fs
    # Interval k = samples [e_k, e_{k+1}): from knot k (inclusive) to knot k+1; interval 0
    # also holds the samples before knot 0, interval K-1 those after the last knot.
    e = np.empty(K + 1, dtype=np.int64)
    e[0], e[K] = 0, T
    e[1:K] = np.clip(np.ceil(p[1:]), 0, T)
    slope = np.zeros(K)
    slope[:-1] = 1.0 / np.diff(p)
    lens = np.diff(e)
    a = (np.arange(T) - np.repeat(p, lens)) * np.repeat(slope, lens)
    xa = x * np.clip(a, 0.0, 1.0).astype(np.float32)  # weight of knot k+1 on interval k
    return _partitioned(xa, x - xa, e, h)


def _block_grid(e: np.ndarray, T: int, B: int):
    """Block grid aligned with the first interior interval boundary.

    Returns (o, klo, count): blocks m cover [o + mB, o + (m+1)B), -B < o <= 0; knots
    klo[m] .. klo[m] + count[m] - 1 have input in block m.
    """
    K = len(e) - 1
    inner = e[1:K][(e[1:K] > 0) & (e[1:K] < T)]
    o = int(inner[0] % B - B) if inner.size and inner[0] % B else 0
    nb = -(-(T - o) // B)
    start = o + np.arange(nb, dtype=np.int64) * B
    first = np.searchsorted(e, np.maximum(start, 0), "right") - 1
    last = np.searchsorted(e, np.minimum(start + B, T) - 1, "right") - 1
    # block m holds intervals first..last: knot i gets x_b, knot i+1 gets x_a of interval i
    return o, first, np.minimum(last + 1, K - 1) - first + 1


def _plan(e: np.ndarray, C: int, L: int, T: int):
    """Block size B (also the RIR partition length) minimising the estimated cost.

    Cost in FFT steps: (number of FFT rows) · N log2 N plus the frequency-domain
    multiply-adds and a per-block overhead; the pair count comes from the real grid.
    Candidates: about one to four knot intervals, L / P for P = 1..4, and plain
    overlap-add (P = 1) at a few power-of-two FFT sizes.
    """
    K = len(e) - 1
    la = np.diff(e)
    inner = la[1 : K - 1][la[1 : K - 1] > 0]
    D = int(np.median(inner)) if inner.size else T
    cand = {int(round(D * f)) for f in (0.5, 1, 2, 3, 4)}
    cand |= {-(-L // P) for P in (1, 2, 3, 4)}
    cand |= {n - L + 1 for n in (1 << 13, 1 << 14, 1 << 15, 1 << 16)}
    used = int(np.count_nonzero(la + np.r_[0, la[:-1]]))  # knots with input: intervals k-1, k
    best = None
    for B in sorted(b for b in cand if 16 <= b <= max(T, 16)):
        P = -(-L // B)
        N = sfft.next_fast_len(B + min(B, L) - 1, real=True)
        o, _, count = _block_grid(e, T, B)
        pairs, nb = int(count.sum()), len(count)
        rows = C * P * used + pairs + C * (nb + P - 1)
        cost = rows * N * np.log2(N) + _MAC_COST * pairs * P * C * (N // 2 + 1) + _BLOCK_COST * (nb + P)
        if best is None or cost < best[0]:
            best = (cost, B, P, N)
    return best[1:]


def _partitioned(xa: np.ndarray, xb: np.ndarray, e: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Σ_k (z_k * h_k) with z_k = x_a on interval k-1 and x_b on interval k: float32 [C, T + L - 1].

    xa, xb: float32 [T]. e: int [K + 1] interval starts (e_0 = 0, e_K = T). h: [K, C, L].
    """
    K, C, L = h.shape
    T = len(xb)
    B, P, N = _plan(e, C, L, T)
    o, klo, count = _block_grid(e, T, B)
    nb, F, R = len(klo), N // 2 + 1, int(count.max())
    q = -(-N // B)  # output blocks touched by one frame
    # Inputs on the block grid: the signal halves and each sample's interval.
    pad = np.zeros((2, nb * B), dtype=np.float32)
    pad[0, -o : -o + T], pad[1, -o : -o + T] = xa, xb
    xa_b, xb_b = pad.reshape(2, nb, B)
    ival = np.full(nb * B, -K - 2, dtype=np.int32)
    ival[-o : -o + T] = np.repeat(np.arange(K, dtype=np.int32), np.diff(e))
    ival = ival.reshape(nb, B)
    # RIR partitions, zero-padded to P·B samples: [K, C, P, B] (a view when L = P·B).
    hp = h if L == P * B else np.pad(h, ((0, 0), (0, 0), (0, P * B - L)))
    hp = hp.reshape(K, C, P, B)

    bytes_per_block = 8 * F * (R + 2 * C + C * P * (1 + int(np.ceil(np.mean(count))))) + 4 * C * N
    G = int(max(1, min(nb, _GROUP_BYTES // bytes_per_block)))
    out = np.zeros((C, nb + P - 1 + q, B), dtype=np.float32)
    acc = np.zeros((G + P - 1, C, F), dtype=np.complex64)  # Y rows m0 .. m0 + G + P - 2
    tmp = np.empty((G, C, F), dtype=np.complex64)
    H, h_lo = None, 0  # spectra of knots h_lo .. h_lo + len(H) - 1: [k, C, P, F]

    def flush(m0, rows):  # inverse FFT of finished rows Y_m0 .. and overlap-add at (m0 + i)·B
        y = sfft.irfft(acc[:rows], N, axis=-1).transpose(1, 0, 2)  # [C, rows, N]
        for u in range(q):
            w = min(B, N - u * B)
            out[:, m0 + u : m0 + u + rows, :w] += y[:, :, u * B : u * B + w]

    for m0 in range(0, nb, G):
        m1 = min(nb, m0 + G)
        g = m1 - m0
        k0, k1 = int(klo[m0]), int(klo[m1 - 1] + count[m1 - 1])  # knots [k0, k1)
        # RIR spectra, each transformed once: keep the ones the previous group computed.
        n_keep = 0 if H is None else max(0, h_lo + len(H) - k0)
        new = sfft.rfft(hp[k0 + n_keep : k1], N, axis=-1)
        H = np.concatenate([H[k0 - h_lo :], new]) if n_keep else new
        h_lo = k0
        # Knot k = klo + r reads x_b where the interval is k and x_a where it is k - 1.
        rel = ival[m0:m1] - klo[m0:m1, None]
        for r in range(int(count[m0:m1].max())):
            seg = np.where(rel == r, xb_b[m0:m1], np.where(rel == r - 1, xa_b[m0:m1], np.float32(0)))
            live = r < count[m0:m1]
            X = sfft.rfft(seg if live.all() else seg[live], N, axis=-1)[:, None, :]  # [n, 1, F]
            kr = (klo[m0:m1] + r - k0)[live]
            rows = np.nonzero(live)[0]
            step = int(kr[1] - kr[0]) if len(kr) > 1 else 1
            contiguous = rows[-1] - rows[0] + 1 == len(rows) and step > 0 and np.all(np.diff(kr) == step)
            i0 = int(rows[0])
            for j in range(P):
                Hj = H[kr[0] : kr[-1] + 1 : step, :, j] if contiguous else H[kr, :, j]
                t = tmp[: len(kr)]
                np.multiply(X, Hj, out=t)
                if contiguous:
                    acc[i0 + j : i0 + j + len(kr)] += t
                else:
                    acc[rows + j] += t
        flush(m0, g)
        acc[: P - 1] = acc[g : g + P - 1]
        acc[P - 1 :] = 0
    if P > 1:
        flush(nb, P - 1)
    return out.reshape(C, -1)[:, -o : -o + T + L - 1]


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
