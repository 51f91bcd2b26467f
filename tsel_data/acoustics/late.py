"""Stochastic late reverberation with the spatial statistics of a diffuse field.

In an ideal diffuse field (plane waves from all directions, uncorrelated, equal power)
the complex coherence between two omnidirectional microphones d metres apart is real
and equals ``sin(k d) / (k d)``, k = 2π f / c (R. K. Cook et al., J. Acoust. Soc. Am.
27, 1955). The same field seen by a first-order ambisonic (ACN/SN3D) microphone has
uncorrelated W, Y, Z, X with energies 1 : 1/3 : 1/3 : 1/3 (the mean of u_i² over the
sphere is 1/3).

We draw stationary noise with exactly those statistics (independent Gaussian noise,
mixed at each frequency by the Cholesky factor of the coherence matrix, as in
E. A. P. Habets & S. Gannot, "Generating sensor signals in isotropic noise fields",
J. Acoust. Soc. Am. 122, 2007) and impose the energy envelope of the decay afterwards;
the envelope varies over hundreds of milliseconds, so it does not alter the coherence.
"""
from __future__ import annotations

import numpy as np

from ..core.geometry import SOUND_SPEED
from ..dsp import realfft as sfft  # scipy.fft's numbers without its import

FOA_DIFFUSE_GAINS = np.array([1.0, 1.0, 1.0, 1.0]) / np.sqrt([1.0, 3.0, 3.0, 3.0])


def diffuse_coherence(positions: np.ndarray, freqs: np.ndarray, c: float = SOUND_SPEED) -> np.ndarray:
    """Coherence matrices [F, C, C] of omnis at ``positions`` [C, 3] (m) in a diffuse
    field at ``freqs`` [F] (Hz): Γ_ij(f) = sinc(2 f d_ij / c) (numpy's normalised sinc)."""
    pos = np.asarray(positions, dtype=np.float64)
    d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    return np.sinc(2.0 * np.asarray(freqs, dtype=np.float64)[:, None, None] * d[None] / c)


def diffuse_noise(
    rng: np.random.Generator, n_sets: int, n: int, fs: int, positions: np.ndarray | None = None, foa: bool = False
) -> np.ndarray:
    """``n_sets`` independent stationary noises [n_sets, C, n] (float, W / omni variance 1)
    with diffuse-field inter-channel statistics.

    foa=True: 4 uncorrelated channels W, Y, Z, X with variances 1, 1/3, 1/3, 1/3.
    Otherwise omnis at ``positions`` [C, 3] (metres, any frame): per frequency bin the
    independent spectra are mixed by L(f), the Cholesky factor of Γ(f) + εI, so
    E[X_i X_j*] ∝ Γ_ij(f) = sinc(k d_ij).
    """
    if foa:
        return rng.standard_normal((n_sets, 4, n)) * FOA_DIFFUSE_GAINS[None, :, None]
    pos = np.asarray(positions, dtype=np.float64)
    n_ch = len(pos)
    if n_ch == 1:
        return rng.standard_normal((n_sets, 1, n))
    # noise of the full FFT length: the mixing is circular, so the result is stationary
    n_fft = sfft.next_fast_len(n, real=True)
    spec = sfft.rfft(rng.standard_normal((n_sets, n_ch, n_fft), dtype=np.float32), axis=-1, workers=1)
    chol = _coherence_factor(pos, n_fft, fs)  # [C, C, F], lower triangular in (i, j)
    mixed = np.empty_like(spec)
    for i in range(n_ch):
        mixed[:, i] = chol[i, 0] * spec[:, 0]
        for j in range(1, i + 1):
            mixed[:, i] += chol[i, j] * spec[:, j]
    return sfft.irfft(mixed, n=n_fft, axis=-1, workers=1)[..., :n]


def csd_noise(rng: np.random.Generator, n_sets: int, n: int, fs: int, csd, coarse: int = 513) -> np.ndarray:
    """``n_sets`` independent stationary noises [n_sets, C, n] whose cross-spectral
    density is ``csd(freqs) -> [F, C, C]`` (Hermitian, positive semi-definite; e.g. a
    receiver's diffuse field, acoustics/capsules.py), white-noise scaled: channel i has
    PSD Φ_ii(f) (variance 1 where Φ_ii = 1).

    As :func:`diffuse_noise`: independent spectra mixed per bin by the Cholesky factor of
    Φ(f) + εI, computed on ``coarse`` bins and interpolated (real and imaginary parts)."""
    n_fft = sfft.next_fast_len(n, real=True)
    f_coarse = np.linspace(0.0, fs / 2, coarse)
    phi = np.asarray(csd(f_coarse))
    n_ch = phi.shape[-1]
    scale = np.maximum(np.real(np.trace(phi, axis1=1, axis2=2)) / n_ch, 1e-12)
    chol = np.linalg.cholesky(phi + (1e-6 * scale)[:, None, None] * np.eye(n_ch))  # [F, C, C]
    f = sfft.rfftfreq(n_fft, 1.0 / fs)
    cplx = np.iscomplexobj(chol) and np.any(np.imag(chol) != 0)
    factor = np.zeros((n_ch, n_ch, len(f)), dtype=np.complex64 if cplx else np.float32)
    for i in range(n_ch):
        for j in range(i + 1):
            re = np.interp(f, f_coarse, np.real(chol[:, i, j]))
            factor[i, j] = re + 1j * np.interp(f, f_coarse, np.imag(chol[:, i, j])) if cplx else re
    if cplx:  # a real signal's DC and Nyquist bins are real
        factor[..., 0] = factor[..., 0].real
        if n_fft % 2 == 0:
            factor[..., -1] = factor[..., -1].real
    spec = sfft.rfft(rng.standard_normal((n_sets, n_ch, n_fft), dtype=np.float32), axis=-1, workers=1)
    mixed = np.einsum("ijf,sjf->sif", factor, spec)
    return sfft.irfft(mixed, n=n_fft, axis=-1, workers=1)[..., :n]


def _coherence_factor(pos: np.ndarray, n_fft: int, fs: int, coarse: int = 513) -> np.ndarray:
    """Cholesky factors L(f) [C, C, F] (float32) of Γ(f) + εI at the rfft bins of n_fft.

    Γ varies on a scale of c / (2 d_max) ≈ 1 kHz for arrays of ~0.2 m, so the factor is
    computed on ``coarse`` bins and linearly interpolated (error < 1e-3).
    ε keeps the factor defined where Γ is singular (all ones at DC); its effect on the
    coherence is O(ε).
    """
    n_ch = len(pos)
    f_coarse = np.linspace(0.0, fs / 2, coarse)
    chol = np.linalg.cholesky(diffuse_coherence(pos, f_coarse) + 1e-6 * np.eye(n_ch))
    f = sfft.rfftfreq(n_fft, 1.0 / fs)
    out = np.zeros((n_ch, n_ch, len(f)), dtype=np.float32)
    for i in range(n_ch):
        for j in range(i + 1):
            out[i, j] = np.interp(f, f_coarse, chol[:, i, j])
    return out
