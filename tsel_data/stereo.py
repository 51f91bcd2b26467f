"""A two-channel preview of a scene (or of one source) for listening on headphones.

A scene's channels are array signals, not a stereo pair: four FOA components or four
closely spaced capsules played to two ears sound wrong. The preview decodes them to a
left and a right channel, per array format:

- ``foa``: two virtual cardioid microphones, one pointing left (+y, azimuth +90°) and
  one right (-y). With ACN/SN3D (W, Y, Z, X) a plane wave from the unit vector u has
  W = 1 and (X, Y, Z) = u, so a cardioid aimed at d picks up ½(1 + u·d):
  left = ½(W + Y), right = ½(W − Y). A coincident pair: the direction is heard as a level
  difference (a source at +90° is in the left ear only, one in front in both equally).
- ``mic4``: the front pair as a spaced pair of omnis, mic 0 (front-left) to the left
  ear and mic 3 (front-right) to the right; they are ``side`` (0.10-0.13 m) apart across
  the y axis, so the direction is heard as a time difference, about half a head's.
- ``tetra``: capsule 0 (front-left-up) to the left ear and capsule 1 (front-right-down)
  to the right, 5.9 cm apart across y.

No level is changed (a float WAV of the preview is not clipped).
"""
from __future__ import annotations

import numpy as np

# channel index of (left, right) for the spaced-pair formats
PAIRS = {"mic4": (0, 3), "tetra": (0, 1)}


def stereo_preview(audio: np.ndarray, fmt: str) -> np.ndarray:
    """audio float [..., C, T] of array format ``fmt`` -> float32 [..., 2, T] (left, right)."""
    a = np.asarray(audio, dtype=np.float32)
    if fmt == "foa":
        w, y = a[..., 0, :], a[..., 1, :]
        return np.stack([0.5 * (w + y), 0.5 * (w - y)], axis=-2).astype(np.float32)
    if fmt not in PAIRS:
        raise ValueError(f"no stereo preview for array format {fmt!r}; known: foa, {', '.join(PAIRS)}")
    left, right = PAIRS[fmt]
    return np.stack([a[..., left, :], a[..., right, :]], axis=-2).astype(np.float32)
