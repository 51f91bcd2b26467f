"""A two-channel preview of a scene (or of one source) for listening on headphones.

A scene's channels are receiver signals, not a stereo pair: four FOA components or four
closely spaced capsules played to two ears sound wrong. The preview decodes them to a
left and a right channel as the receiver's spec says (``ReceiverSpec.stereo``):

- a decode matrix, e.g. ``foa``: two virtual cardioid microphones, one pointing left
  (+y, azimuth +90°) and one right (-y). With ACN/SN3D (W, Y, Z, X) a plane wave from the
  unit vector u has W = 1 and (X, Y, Z) = u, so a cardioid aimed at d picks up ½(1 + u·d):
  left = ½(W + Y), right = ½(W − Y). A coincident pair: the direction is heard as a level
  difference (a source at +90° is in the left ear only, one in front in both equally).
- a pair of channels, e.g. ``mic4``: the front pair as a spaced pair of omnis, mic 0
  (front-left) to the left ear and mic 3 (front-right) to the right; they are ``side``
  (0.10-0.13 m) apart across the y axis, so the direction is heard as a time difference,
  about half a head's. ``tetra``: capsule 0 (front-left-up) left, capsule 1
  (front-right-down) right, 5.9 cm apart across y. A custom array: its outermost capsules
  along y. Two-channel receivers (ears, a stereo pair) are their own preview.

No level is changed (a float WAV of the preview is not clipped).
"""
from __future__ import annotations

import numpy as np

from . import receiver


def stereo_preview(audio: np.ndarray, fmt: str, mic_positions=None) -> np.ndarray:
    """audio float [..., C, T] of receiver ``fmt`` -> float32 [..., 2, T] (left, right).
    mic_positions [C, 3]: the scene's capsules (a custom array's preview pair follows them)."""
    a = np.asarray(audio, dtype=np.float32)
    spec = receiver(fmt)
    m = spec.stereo_matrix()
    if m is not None:
        return np.einsum("lc,...ct->...lt", m, a).astype(np.float32)
    left, right = spec.stereo_pair(mic_positions)
    return np.stack([a[..., left, :], a[..., right, :]], axis=-2).astype(np.float32)
