"""Rotate and mirror a scene's features and labels together (training augmentation).

A scene turned about the vertical axis, or mirrored left-right, is another valid scene
(only the room's walls would be in other places, and rooms are random anyway). For the
arrays of tsel-data the turned scene's features follow exactly from the original's:

- **mic4** (square, mic k at azimuth 45° + 90°·k): turning the scene by +90° moves every
  mic's signal to the next mic, ``new[k] = old[k - 1]``; mirroring (φ -> -φ) swaps
  left and right mics, ``new[k] = old[3 - k]``. These 8 channel permutations (the
  symmetries of a square) permute the GCC-PHAT pairs and reverse the lag axis of the
  pairs whose mic order flips. Only these 8 angles: a square is not round.
- **FOA**: the intensity vector's x and y turn like the source direction, by any angle.

The log-mel features average all channels and are unchanged. The azimuth label maps as
``φ' = sign·φ + angle``. Transforms act on one scene's features (no batch axis).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tsel_data.dsp.features import mic_pairs

MIC4_AZIMUTHS = 45.0 + 90.0 * np.arange(4)  # docs/format.md: mic k at 45° + 90°·k


@dataclass(frozen=True)
class Transform:
    """``φ' = sign·φ + angle`` (degrees); for mic4, ``perm`` is the channel map new[k] = old[perm[k]]."""

    sign: int = 1
    angle: float = 0.0
    perm: tuple[int, ...] | None = None

    def azimuth(self, az: np.ndarray) -> np.ndarray:
        """Map azimuths (deg, NaN kept) to [-180, 180)."""
        a = self.sign * np.asarray(az, dtype=np.float64) + self.angle
        return ((a + 180.0) % 360.0 - 180.0).astype(np.float32)


def mic4_transforms() -> list[Transform]:
    """The 8 symmetries of the mic4 square: turns by 0/90/180/270°, each with or without mirroring."""
    out = []
    for mirror in (False, True):
        for r in range(4):
            base = [3 - k for k in range(4)] if mirror else list(range(4))
            perm = tuple(base[(k - r) % 4] for k in range(4))
            out.append(Transform(sign=-1 if mirror else 1, angle=90.0 * r, perm=perm))
    return out


def is_mic4_square(mic_positions: np.ndarray, tol_deg: float = 1.0) -> bool:
    """Whether channels sit where the mic4 permutations assume (mic k at 45° + 90°·k, in a plane)."""
    p = np.asarray(mic_positions, dtype=np.float64)
    if p.shape != (4, 3) or np.abs(p[:, 2]).max() > 1e-6 or np.allclose(p, 0):
        return False
    az = np.degrees(np.arctan2(p[:, 1], p[:, 0]))
    err = np.abs((az - MIC4_AZIMUTHS + 180.0) % 360.0 - 180.0)
    radius = np.hypot(p[:, 0], p[:, 1])
    return bool(err.max() < tol_deg and np.ptp(radius) < 1e-3 * radius.max())


def permute_gcc(gcc: np.ndarray, perm) -> np.ndarray:
    """GCC features of channel-permuted audio: [P, ..., L] -> [P, ..., L].

    ``audio[perm]`` has pair (i, j) = original pair (perm[i], perm[j]); when that pair
    is stored the other way round, its lag axis is reversed (needs a symmetric lag
    window, as :func:`tsel_baseline.features.crop_lags` makes).
    """
    n_ch = len(perm)
    pairs = mic_pairs(n_ch)
    index = {p: n for n, p in enumerate(pairs)}
    out = np.empty_like(gcc)
    for n, (i, j) in enumerate(pairs):
        a, b = perm[i], perm[j]
        out[n] = gcc[index[(a, b)]] if a < b else gcc[index[(b, a)]][..., ::-1]
    return out


def permute_xspec(x: np.ndarray, perm) -> np.ndarray:
    """Cross-spectrum features [P, F, M, 2 (re, im)] of channel-permuted audio: pairs permuted,
    conjugated (imaginary part negated) where a pair's mic order flips."""
    pairs = mic_pairs(len(perm))
    index = {p: n for n, p in enumerate(pairs)}
    out = np.empty_like(x)
    for n, (i, j) in enumerate(pairs):
        a, b = perm[i], perm[j]
        out[n] = x[index[(a, b)]] if a < b else x[index[(b, a)]] * np.array([1.0, -1.0], dtype=x.dtype)
    return out


def rotate_iv(iv: np.ndarray, t: Transform) -> np.ndarray:
    """FOA intensity vectors [3 (x, y, z), ...] under ``t`` (mirror first, then turn)."""
    x, y, z = iv[0], t.sign * iv[1], iv[2]
    c, s = np.cos(np.radians(t.angle)), np.sin(np.radians(t.angle))
    return np.stack([c * x - s * y, s * x + c * y, z]).astype(np.float32)


def apply(features: dict, t: Transform) -> dict:
    """Transform one scene's feature dict (``gcc``, ``iv``, ``mel``; others unchanged)."""
    out = dict(features)
    if "gcc" in out:
        if t.perm is None:
            raise ValueError("GCC features only turn by channel permutations (mic4); this transform has none")
        out["gcc"] = permute_gcc(out["gcc"], t.perm)
    if "xspec" in out:
        out["xspec"] = permute_xspec(out["xspec"], t.perm)
    if "iv" in out:
        out["iv"] = rotate_iv(out["iv"], t)
    return out


def random_transform(rng: np.random.Generator, spatial: str) -> Transform:
    """A random symmetry: one of the 8 mic4 ones for GCC, any turn ± a mirror for FOA."""
    if spatial in ("gcc", "xspec"):
        ts = mic4_transforms()
        return ts[int(rng.integers(len(ts)))]
    return Transform(sign=-1 if rng.random() < 0.5 else 1, angle=float(rng.uniform(-180.0, 180.0)))
