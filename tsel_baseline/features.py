"""Audio features of one scene, pooled to the scene's label frames.

What the model sees of a scene (F = label frames, 100 for a 10 s scene at 0.1 s hop):

- ``gcc``  float32 [P, F, 2·max_lag + 1]: the paper's GCC-PHAT of every mic pair
  (:func:`tsel_data.dsp.features.gcc_phat`, n_fft 1024, hop 640, 96 lags), averaged over the
  STFT frames of each label frame and cropped to the lags a sound can actually take
  between two mics of the array (a 0.13 m square at 24 kHz: at most ±13 samples; the
  rest of the 96 lags only holds reverberation and noise).
- ``mel``  float32 [F, n_mels]: log-mel power, averaged over channels. GCC-PHAT whitens
  the spectrum, so it says *where* energy comes from but hardly *what* it is; the
  log-mel is what lets the model match a frame to the words of the query. Averaging
  over channels makes it invariant to the array rotations used for augmentation.
- ``iv``   float32 [3, F, n_mels]: FOA only, the active intensity vector
  ``Re(W* · [X, Y, Z])`` summed in mel bands and divided by the band energy. FOA
  channels are coincident, so GCC-PHAT between them peaks at lag 0 and keeps only a
  sign (the front/back or left/right half-plane); the intensity vector points at the
  source. It is also exactly rotatable (see :mod:`tsel_baseline.augment`).
- ``xspec`` float32 [P, F, B, 2]: the normalised cross-spectrum of every mic pair per
  band (:func:`xspec_features`): a direction per band, so that a model can localise
  only the bands of the queried sound (SelectNet's spatial input on mic arrays).

Pooling to label frames (rather than keeping the 376 STFT frames) makes the features
4x smaller and lines them up with the labels, so a frame-level head predicts one
azimuth per label frame with no resampling.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from tsel_data.dsp.features import gcc_phat, mic_pairs, stft
from tsel_data.receivers import receiver

SPEED_OF_SOUND = 343.0  # m/s
FOA_CHANNELS = ("W", "Y", "Z", "X")  # ACN order (docs/format.md)


SPATIAL = ("gcc", "iv", "xspec")


@dataclass(frozen=True)
class FeatureConfig:
    """How features are computed. The defaults are the paper's STFT and GCC settings.

    spatial:  "gcc" (GCC-PHAT of every pair), "iv" (FOA intensity vectors), "xspec"
              (the normalised cross-spectrum of every pair per band), several joined by
              "+" (e.g. "gcc+xspec": computed from one STFT, cached together), or "auto"
              (gcc for microphone arrays, iv for FOA).
    n_fft, hop: STFT size and hop, samples (paper: 1024, 640).
    n_lags:   lags of the paper's GCC-PHAT (96); max_lag: lags kept either side of 0.
    n_mels, fmin, fmax: log-mel bands and their range, Hz (fmax 0 means fs/2).
    xspec_bands, xspec_fmax: bands of the cross-spectrum (mel-spaced from fmin), their top, Hz.
    """

    spatial: str = "auto"
    n_fft: int = 1024
    hop: int = 640
    n_lags: int = 96
    max_lag: int = 24
    n_mels: int = 64
    fmin: float = 50.0
    fmax: float = 0.0
    xspec_bands: int = 48
    xspec_fmax: float = 4000.0

    def resolve(self, fmt: str) -> list[str]:
        """The spatial features computed for a receiver (its name, e.g. "mic4", "foa")."""
        ambisonic = receiver(fmt).ambisonic
        if self.spatial == "auto":
            return ["iv" if ambisonic else "gcc"]
        names = self.spatial.split("+")
        bad = [n for n in names if n not in SPATIAL]
        if bad or len(set(names)) != len(names):
            raise ValueError(f"spatial features are 'gcc', 'iv', 'xspec' (joined by '+') or 'auto', got {self.spatial!r}")
        if "iv" in names and not ambisonic:
            raise ValueError(f"intensity vectors need FOA audio; this dataset is {fmt!r} (use spatial='gcc')")
        return names

    def to_dict(self) -> dict:
        return asdict(self)


def pool_matrix(n_stft: int, hop: int, fs: int, label_hop: float, n_frames: int) -> np.ndarray:
    """Averaging matrix [n_frames, n_stft]: label frame k is the mean of the STFT frames
    whose centre (j·hop samples, centred STFT) lies in [k·label_hop, (k+1)·label_hop)."""
    centre_s = np.arange(n_stft) * hop / fs
    k = np.floor(centre_s / label_hop + 1e-9).astype(np.int64)
    a = np.zeros((n_frames, n_stft), dtype=np.float64)
    ok = k < n_frames
    a[k[ok], np.flatnonzero(ok)] = 1.0
    counts = a.sum(axis=1, keepdims=True)
    if (counts == 0).any():
        raise ValueError(f"label hop {label_hop} s is shorter than the STFT hop {hop / fs:.4f} s: "
                         "some label frames get no STFT frame; lower FeatureConfig.hop")
    return (a / counts).astype(np.float32)


def mel_filterbank(fs: int, n_fft: int, n_mels: int, fmin: float = 0.0, fmax: float = 0.0) -> np.ndarray:
    """Triangular mel filters (HTK mel scale, unit peak) -> float32 [n_mels, n_fft // 2 + 1]."""
    fmax = fmax or fs / 2.0

    def hz_to_mel(f):
        return 2595.0 * np.log10(1.0 + np.asarray(f) / 700.0)

    def mel_to_hz(m):
        return 700.0 * (10.0 ** (np.asarray(m) / 2595.0) - 1.0)

    edges = mel_to_hz(np.linspace(hz_to_mel(fmin), hz_to_mel(fmax), n_mels + 2))
    bins = np.fft.rfftfreq(n_fft, 1.0 / fs)
    lo, mid, hi = edges[:-2, None], edges[1:-1, None], edges[2:, None]
    up = (bins[None] - lo) / np.maximum(mid - lo, 1e-9)
    down = (hi - bins[None]) / np.maximum(hi - mid, 1e-9)
    return np.clip(np.minimum(up, down), 0.0, None).astype(np.float32)


def max_tdoa_samples(mic_positions: np.ndarray, fs: int) -> float:
    """Largest possible time difference of arrival between two mics, in samples."""
    p = np.asarray(mic_positions, dtype=np.float64)
    d = np.linalg.norm(p[:, None] - p[None], axis=-1).max() if len(p) > 1 else 0.0
    return float(d / SPEED_OF_SOUND * fs)


def crop_lags(gcc: np.ndarray, max_lag: int) -> np.ndarray:
    """[..., n_lags] with zero lag at index n_lags // 2 -> [..., 2·max_lag + 1] centred on 0.

    Symmetric on purpose: reversing the lag axis (swapping the two mics of a pair) must
    map the kept lags onto themselves; see :func:`tsel_baseline.augment.permute_gcc`.
    """
    zero = gcc.shape[-1] // 2
    if not 0 <= max_lag <= min(zero, gcc.shape[-1] - 1 - zero):
        raise ValueError(f"max_lag {max_lag} does not fit in {gcc.shape[-1]} lags")
    return gcc[..., zero - max_lag: zero + max_lag + 1]


def gcc_features(audio: np.ndarray, fs: int, mic_positions: np.ndarray, pool: np.ndarray,
                 cfg: FeatureConfig) -> np.ndarray:
    """GCC-PHAT [C, T] -> float32 [P, F, 2·max_lag + 1] (see the module docstring)."""
    need = max_tdoa_samples(mic_positions, fs)
    if need > cfg.max_lag:
        raise ValueError(f"the array spans {need:.1f} samples of delay at {fs} Hz but only ±{cfg.max_lag} lags "
                         "are kept; raise FeatureConfig.max_lag")
    g = gcc_phat(audio, n_fft=cfg.n_fft, hop=cfg.hop, n_lags=cfg.n_lags)       # [P, frames, n_lags]
    g = crop_lags(g, cfg.max_lag)
    return (pool @ g).astype(np.float32)                                         # [P, F, L]


def mel_features(spec: np.ndarray, fb: np.ndarray, pool: np.ndarray) -> np.ndarray:
    """STFT [C, frames, bins] -> log-mel float32 [F, n_mels] of the channel-mean power."""
    power = (np.abs(spec) ** 2).mean(axis=0)                                     # [frames, bins]
    mel = pool @ (power @ fb.T)                                                  # [F, n_mels]
    return np.log(mel + 1e-10).astype(np.float32)


def intensity_features(spec: np.ndarray, fb: np.ndarray, pool: np.ndarray) -> np.ndarray:
    """FOA STFT [4 (W, Y, Z, X), frames, bins] -> float32 [3 (x, y, z), F, n_mels].

    Sums of ``Re(W* X)`` etc. over each mel band and label frame, divided by the same
    sums of ``(|W|² + |X|² + |Y|² + |Z|²) / 2`` (so a plane wave from the front gives
    x = 1 in SN3D). Sums, not means of ratios: loud bins, where the direct sound is,
    weigh more than quiet reverberant ones.
    """
    w, y, z, x = spec
    iv = np.stack([np.real(np.conj(w) * c) for c in (x, y, z)])                  # [3, frames, bins]
    energy = 0.5 * (np.abs(spec) ** 2).sum(axis=0)                               # [frames, bins]
    num = (pool @ iv) @ fb.T                                                     # [3, F, n_mels]
    den = pool @ (energy @ fb.T)
    return (num / (den[None] + 1e-10)).astype(np.float32)


def band_filters(fs: int, n_fft: int, n_bands: int, fmin: float, fmax: float) -> np.ndarray:
    """Triangular mel bands normalised to sum 1 over their bins: float32 [n_bands, n_fft // 2 + 1]."""
    fb = mel_filterbank(fs, n_fft, n_bands, fmin, fmax)
    return fb / np.maximum(fb.sum(axis=1, keepdims=True), 1e-9)


def xspec_features(spec: np.ndarray, fb: np.ndarray, pool: np.ndarray) -> np.ndarray:
    """Normalised cross-spectrum of every mic pair per band and label frame: STFT
    [C, frames, bins] -> float32 [P, F, B, 2] (real, imaginary), each value in the unit disc.

    For pair (i, j), band b and label frame f: ``Σ X_i X_j* / Σ |X_i X_j*|``, both sums
    over the STFT frames of f and the bins of b (weighted by the band's filter). Its
    phase is the delay between the two mics of whatever dominates the cell; its length
    says how dominant (1: one plane wave; near 0: several directions, or reverberation).

    Why not GCC-PHAT: GCC-PHAT is the inverse FFT of the same normalised cross-spectrum
    summed over *all* frequencies, so when two sources sound at once it shows both
    delays with nothing to say which delay came from which band. Kept per band, the
    direction stays tied to the spectrum, and a model can localise only the bands (and
    frames) that the query's sound occupies. Bands are kept narrow enough (fmax ~4 kHz)
    that the phase hardly turns across one band at the array's largest delay, so
    averaging within a band does not cancel it.

    Sums, not means of per-bin ratios: loud bins, where the direct sound is, weigh more.
    """
    i, j = np.array(mic_pairs(spec.shape[0])).T
    keep = np.flatnonzero(fb.any(axis=0))                                          # bins inside the bands
    s, w = spec[..., keep], fb[:, keep].T.astype(np.float32)                       # [C, frames, K], [K, B]
    cross = s[i] * np.conj(s[j])                                                   # [P, frames, K]
    num = pool @ (cross.real @ w) + 1j * (pool @ (cross.imag @ w))                # [P, F, B]
    den = pool @ (np.abs(cross) @ w)
    band = num / (den + 1e-12)
    return np.stack([band.real, band.imag], axis=-1).astype(np.float32)


def scene_features(scene, cfg: FeatureConfig = FeatureConfig()) -> dict:
    """Features of one :class:`tsel_data.store.Scene` (needs its audio).

    Returns ``{"mel": [F, n_mels]}`` and the spatial features of ``cfg.spatial``:
    ``"gcc"`` [P, F, L] and/or ``"xspec"`` [P, F, B, 2] for microphone arrays,
    ``"iv"`` [3, F, n_mels] for FOA (see the module docstring), float32.
    """
    if scene.audio is None:
        raise ValueError(f"scene {scene.scene_id} was read without audio; read it with audio=True")
    spatial = cfg.resolve(scene.format)
    n_stft = 1 + scene.audio.shape[-1] // cfg.hop
    pool = pool_matrix(n_stft, cfg.hop, scene.fs, scene.label_hop, scene.n_frames)
    fb = mel_filterbank(scene.fs, cfg.n_fft, cfg.n_mels, cfg.fmin, cfg.fmax)
    spec = stft(scene.audio, cfg.n_fft, cfg.hop)
    out = {"mel": mel_features(spec, fb, pool)}
    if "gcc" in spatial:
        out["gcc"] = gcc_features(scene.audio, scene.fs, scene.mic_positions, pool, cfg)
    if "xspec" in spatial:
        bands = band_filters(scene.fs, cfg.n_fft, cfg.xspec_bands, cfg.fmin, min(cfg.xspec_fmax, scene.fs / 2))
        out["xspec"] = xspec_features(spec, bands, pool)
    if "iv" in spatial:
        if scene.audio.shape[0] != 4:
            raise ValueError(f"intensity vectors need 4 FOA channels {FOA_CHANNELS}, got {scene.audio.shape[0]}")
        out["iv"] = intensity_features(spec, fb, pool)
    return out
