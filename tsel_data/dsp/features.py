"""Input features as the paper computes them (optional helpers for model builders).

``gcc_phat``: generalised cross-correlation with phase transform (Knapp & Carter,
1976) for every microphone pair, per STFT frame:

    R_ij(τ) = IFFT_k[ X_i(k) X_j*(k) / |X_i(k) X_j*(k)| ](τ)

keeping the ``n_lags`` lags centred on zero (the layout of the DCASE SELD baseline's
GCC features). Paper settings: n_fft 1024, hop 640 samples (at 24 kHz: 42.7 ms
window, 26.7 ms hop), 96 lags, all C(C-1)/2 pairs.
"""
from __future__ import annotations

from itertools import combinations

import numpy as np

_EPS = 1e-12


def stft(audio, n_fft: int = 1024, hop: int = 640, center: bool = True) -> np.ndarray:
    """Hann-window STFT: [C, T] -> complex64 [C, frames, n_fft // 2 + 1].

    center: pad n_fft//2 zeros on both sides, so frame j is centred on sample j·hop and
    there are 1 + T // hop frames (librosa's convention).
    """
    x = np.asarray(audio, dtype=np.float32)
    if x.ndim == 1:
        x = x[None]
    if center:
        x = np.pad(x, ((0, 0), (n_fft // 2, n_fft // 2)))
    if x.shape[1] < n_fft:
        x = np.pad(x, ((0, 0), (0, n_fft - x.shape[1])))
    n_frames = 1 + (x.shape[1] - n_fft) // hop
    idx = np.arange(n_fft)[None, :] + hop * np.arange(n_frames)[:, None]
    win = np.hanning(n_fft + 1)[:-1].astype(np.float32)  # periodic Hann
    return np.fft.rfft(x[:, idx] * win, axis=-1).astype(np.complex64)


def mic_pairs(n_channels: int) -> list[tuple[int, int]]:
    """All pairs (i, j), i < j, in lexicographic order."""
    return list(combinations(range(n_channels), 2))


def gcc_phat(audio, n_fft: int = 1024, hop: int = 640, n_lags: int = 96) -> np.ndarray:
    """GCC-PHAT of every mic pair: audio [C, T] -> float32 [P, frames, n_lags].

    Lag axis: index ``n_lags // 2`` is zero lag; index l is lag ``l - n_lags // 2``
    samples, positive when channel i hears the sound later than channel j. Frames as
    :func:`stft` with ``center=True`` (1 + T // hop of them).
    """
    if n_lags > n_fft:
        raise ValueError("n_lags cannot exceed n_fft")
    spec = stft(audio, n_fft, hop)
    pairs = mic_pairs(spec.shape[0])
    i, j = np.array(pairs).T
    cross = spec[i] * np.conj(spec[j])
    cc = np.fft.irfft(cross / (np.abs(cross) + _EPS), n=n_fft, axis=-1)
    half = n_lags // 2
    return np.concatenate([cc[..., n_fft - half:], cc[..., : n_lags - half]], axis=-1).astype(np.float32)
