"""Label encodings for training, and their decoders.

- **Class**: the paper's 360-way azimuth class ``k = round(φ) mod 360`` (halves round
  up, so 0.5° -> 1 and -0.5° -> 0); class k decodes to azimuth k wrapped to [-180, 180).
- **Gaussian target**: a wrapped Gaussian over the 360 classes, centred on φ with
  standard deviation σ (default 5°), normalised to sum 1 (a distribution, as the EMD
  loss expects): ``p_k ∝ exp(-d(k, φ)² / 2σ²)``, ``d`` the wrap-around distance.
- **ACCDOA** (Shimada et al., ICASSP 2021): activity-coupled Cartesian DOA, the unit
  vector toward the source scaled by its activity (1 active, 0 not): ``[..., 3]``.

All functions are vectorised over leading axes; NaN azimuth (a source with no
position) encodes to class -1, an all-zero Gaussian row and a zero ACCDOA vector.
"""
from __future__ import annotations

import numpy as np

from ..core.geometry import cart_to_sph, sph_to_cart, wrap_azimuth

N_CLASSES = 360


def azimuth_to_class(az) -> np.ndarray:
    """Azimuth (deg) [...] -> int64 class in [0, 360) (-1 where NaN)."""
    az = np.asarray(az, dtype=np.float64)
    ok = np.isfinite(az)
    k = np.floor(np.where(ok, az, 0.0) + 0.5).astype(np.int64) % N_CLASSES
    return np.where(ok, k, -1)


def class_to_azimuth(k) -> np.ndarray:
    """Class index [...] -> azimuth (deg) in [-180, 180)."""
    return wrap_azimuth(np.asarray(k, dtype=np.float64))


def gaussian_target(az, sigma: float = 5.0, n_classes: int = N_CLASSES) -> np.ndarray:
    """Wrapped Gaussian target: azimuth [...] -> float32 [..., n_classes], rows sum to 1.

    Bin k stands for azimuth k·360/n_classes degrees. Rows for NaN azimuths are zero.
    """
    if sigma <= 0:
        raise ValueError("sigma must be positive (degrees)")
    az = np.asarray(az, dtype=np.float64)
    centres = np.arange(n_classes) * (360.0 / n_classes)
    d = np.abs(wrap_azimuth(centres - az[..., None]))
    d = np.minimum(d, 360.0 - d)
    p = np.exp(-0.5 * (d / sigma) ** 2)
    p = np.where(np.isfinite(az)[..., None], p, 0.0)
    s = p.sum(axis=-1, keepdims=True)
    return (p / np.where(s > 0, s, 1.0)).astype(np.float32)


def decode_distribution(p) -> np.ndarray:
    """[..., n_classes] scores -> azimuth (deg) of the argmax bin, in [-180, 180)."""
    p = np.asarray(p)
    return class_to_azimuth(np.argmax(p, axis=-1) * (360.0 / p.shape[-1]))


def accdoa(az, el, active) -> np.ndarray:
    """ACCDOA vectors: (az, el) deg and activity [...] -> float32 [..., 3] (x front, y left, z up)."""
    az, el = np.asarray(az, dtype=np.float64), np.asarray(el, dtype=np.float64)
    on = np.asarray(active, dtype=bool) & np.isfinite(az)
    v = sph_to_cart(np.where(on, az, 0.0), np.where(np.isfinite(el) & on, el, 0.0), 1.0)
    return (v * on[..., None]).astype(np.float32)


def decode_accdoa(v, threshold: float = 0.5):
    """ACCDOA [..., 3] -> (azimuth deg, elevation deg, active = norm > threshold)."""
    v = np.asarray(v, dtype=np.float64)
    az, el, norm = cart_to_sph(v)
    return az, el, norm > threshold


def scene_targets(scene, sigma: float = 5.0) -> dict:
    """Every encoding of a :class:`~tsel_data.store.Scene`'s target (source 0), per frame.

    Returns ``class_index`` int64 [F], ``gaussian`` float32 [F, 360], ``accdoa``
    float32 [S, F, 3] (all sources), ``active`` bool [F] (the target's).
    """
    return {
        "class_index": azimuth_to_class(scene.azimuth[0]),
        "gaussian": gaussian_target(scene.azimuth[0], sigma),
        "accdoa": accdoa(scene.azimuth, scene.elevation, scene.active),
        "active": np.asarray(scene.active[0], dtype=bool),
    }
