"""One sound as a diffuse field: a clip heard from everywhere at once (``scene.additive =
"diffuse"``).

A diffuse field is uncorrelated plane waves from all directions (Cook et al. 1955): the
cross-spectra between a receiver's channels are its diffuse-field Γ(f) (capsule models,
acoustics/capsules.py: sinc(kd) for omnis, W : Y : Z : X = 1 : 1/3 : 1/3 : 1/3 uncorrelated for
FOA, the sphere's or the head's series). Fixed filters cannot make that of one clip: any
linear time-invariant filtering of a single signal is fully coherent between channels
once the analysis window outlasts the filters (the previous design, delayed copies within
60 ms, measured 0.67 coherence at 171 ms windows above the first sinc zero).

So the clip's short-time spectrum S(t, f) is spread over the channels with a direction
drawn afresh in every time-frequency tile: X(t, f) = L(f) z(t, f) S(t, f), L the Cholesky
factor of Γ(f) and z(t, f) independent complex Gaussian vectors scaled to norm √C. Then
E[X Xᴴ] = Γ(f) |S|², whatever window the coherence is measured with, and a tile's energy
stays the clip's (for omnis Γ_ii = 1): the clip's activity and its level per label frame
are kept, since a tile (about 10 ms, hop 5 ms: 256 and 128 samples at 24 kHz) is a tenth
of a label frame; its random phases spread a tile's energy over its length, so sound
leaks at most one tile past where the clip stops (-17 dB in the first 100 ms frame after
a stop, measured). It is what a very dense reverberation does to a sound (each tile
arriving from a new mix of directions), without its smearing in time. The mixing's
frequency resolution (fs / 256, 94 Hz) holds the coherence within 0.015 of theory even for
the 56 cm linear bar (tests/render/test_render_physics.py).
"""
from __future__ import annotations

import numpy as np

from ..dsp import realfft as sfft  # scipy.fft's numbers without its import

TILE_S = 0.01  # about this long a tile (a power of two of samples); hop half, √Hann analysis and synthesis
_CHUNK = 64  # frames mixed at a time: bounds memory for many channels


def diffuse_image(x: np.ndarray, fs: int, csd, rng: np.random.Generator, n_fft: int | None = None) -> np.ndarray:
    """The clip ``x`` [T] as a diffuse field at a receiver: float32 [C, T].

    csd: freqs [F] (Hz) -> the receiver's diffuse cross-spectra [F, C, C] (Hermitian,
    positive semi-definite, e.g. ``capsule_model(pose, fs).diffuse_csd``). rng: the
    scene's generator for the tiles' directions.
    """
    x = np.asarray(x, dtype=np.float64).reshape(-1)
    t = len(x)
    n_fft = n_fft or 1 << int(round(np.log2(fs * TILE_S)))
    hop = n_fft // 2
    win = np.sqrt(0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n_fft) / n_fft))  # periodic √Hann
    n_frames = -(-(t + hop) // hop) + 1
    padded = np.zeros((n_frames + 1) * hop)
    padded[hop:hop + t] = x
    idx = np.arange(n_frames)[:, None] * hop + np.arange(n_fft)[None, :]
    spec = sfft.rfft(padded[idx] * win, axis=-1, workers=1)  # [J, F]
    freqs = sfft.rfftfreq(n_fft, 1.0 / fs)
    phi = np.asarray(csd(freqs))
    n_ch = phi.shape[-1]
    scale = np.maximum(np.real(np.trace(phi, axis1=1, axis2=2)) / n_ch, 1e-12)
    chol = np.linalg.cholesky(phi + (1e-9 * scale)[:, None, None] * np.eye(n_ch))  # [F, C, C]
    out = np.zeros((n_frames + 1, n_ch, hop))  # hop-long blocks: frame j covers blocks j and j + 1
    for j0 in range(0, n_frames, _CHUNK):
        j1 = min(j0 + _CHUNK, n_frames)
        z = rng.standard_normal((j1 - j0, len(freqs), n_ch, 2)) @ np.array([1.0, 1j])
        z *= np.sqrt(n_ch) / np.linalg.norm(z, axis=-1, keepdims=True)
        mixed = np.einsum("fcd,jfd->jcf", chol, z) * spec[j0:j1, None, :]  # [J, C, F]
        mixed[..., 0] = mixed[..., 0].real  # a real signal's DC and Nyquist bins
        mixed[..., -1] = mixed[..., -1].real
        frames = sfft.irfft(mixed, n=n_fft, axis=-1, workers=1) * win  # [J, C, N]
        out[j0:j1] += frames[..., :hop]
        out[j0 + 1:j1 + 1] += frames[..., hop:]
    # a tile's random phases spread its energy evenly over the frame, of which the √Hann
    # synthesis window keeps half (the mean of Hann): √2 gives the clip its energy back
    return (np.sqrt(2.0) * out.transpose(1, 0, 2).reshape(n_ch, -1)[:, hop:hop + t]).astype(np.float32)
