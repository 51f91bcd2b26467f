"""Every built-in receiver, one entry each (``BUILTIN``).

Adding a receiver is one :class:`~tsel_data.receivers.spec.ReceiverSpec` here (and a
test that hears it, docs/design.md "Where things go"): its layout, channel names and
model are all the stages need.
"""
from __future__ import annotations

import numpy as np

from ..choices import ReceiverModel as M
from ..geometry import sph_to_cart
from .spec import PATTERN_ALPHA, ReceiverSpec

# DCASE MIC format (Eigenmike capsules 6, 10, 26, 22): (azimuth, elevation) in degrees.
TETRA_ANGLES = ((45.0, 35.0), (-45.0, -35.0), (135.0, -35.0), (-135.0, 35.0))
TETRA_RADIUS = 0.042  # m


def mic4_positions(side: float) -> np.ndarray:
    """Square array of side ``side`` (m): mic k at azimuth 45° + 90°·k, radius side/√2.

    0 front-left, 1 back-left, 2 back-right, 3 front-right. Returns [4, 3], array frame.
    """
    az = 45.0 + 90.0 * np.arange(4)
    return sph_to_cart(az, 0.0, side / np.sqrt(2.0))


def tetra_positions(radius: float = TETRA_RADIUS) -> np.ndarray:
    """DCASE MIC capsule positions [4, 3] on a sphere of ``radius`` (array frame)."""
    az, el = np.array(TETRA_ANGLES).T
    return sph_to_cart(az, el, radius)


def _fixed(points: np.ndarray):
    """A layout that does not depend on the pose (a fresh copy each call: callers may scale it)."""
    pts = np.asarray(points, dtype=np.float64)
    pts.setflags(write=False)
    return lambda pose: pts.copy()


def _custom_layout(pose) -> np.ndarray:
    return np.asarray(pose.capsules, dtype=np.float64).reshape(-1, 3)


def _custom_patterns(pose):
    n = len(pose.capsules)
    names = pose.patterns or ("omni",) * n
    alpha = np.array([PATTERN_ALPHA[p] for p in names])
    if pose.orientations is None:
        return alpha, np.zeros((n, 3))
    az, el = np.asarray(pose.orientations, dtype=np.float64).reshape(-1, 2).T
    return alpha, sph_to_cart(az, el, 1.0)


MIC4 = ReceiverSpec(
    name="mic4", model=M.SPACED, layout=lambda pose: mic4_positions(pose.side), size_key="side",
    summary="square of 4 omnidirectional mics, side array.side (the paper's simulated array)",
    channel_names=("mic0_front_left", "mic1_back_left", "mic2_back_right", "mic3_front_right"),
    stereo=(0, 3),
    convention="mic k at azimuth 45 + 90k degrees, radius side/sqrt(2): front-left, back-left, back-right, "
               "front-right",
    ambiguity="a planar array cannot tell up from down (elevation is still labelled)",
    source="Zhao et al., Text-Queried Target Sound Event Localization (simulated dataset)")

FOA = ReceiverSpec(
    name="foa", model=M.AMBISONIC, layout=_fixed(np.zeros((4, 3))),
    summary="first-order ambisonics, ACN/SN3D (W, Y, Z, X), as the DCASE FOA format",
    channel_names=("W", "Y", "Z", "X"),
    # two virtual cardioids at ±90°: ½(W ± Y) (stereo.py)
    stereo=((0.5, 0.5, 0.0, 0.0), (0.5, -0.5, 0.0, 0.0)),
    level_channels=(0,), additive=(1.0, 0.0, 0.0, 0.0), localizer="intensity", export_folder="foa",
    convention="ACN (W, Y, Z, X), SN3D",
    source="DCASE SELD FOA format (TAU-SRIR DB, STARSS23)")

TETRA = ReceiverSpec(
    name="tetra", model=M.SPHERE, layout=_fixed(tetra_positions()), radius=TETRA_RADIUS, baffle="rigid",
    summary="the DCASE MIC format: 4 capsules of an Eigenmike on a 4.2 cm rigid sphere (array.baffle)",
    channel_names=("M1", "M2", "M3", "M4"), stereo=(0, 1), aliases=("mic",),
    convention="DCASE MIC format: Eigenmike capsules 6, 10, 26, 22 at (azimuth, elevation) (45, 35), (-45, -35), "
               "(135, -35), (-135, 35) degrees on a 4.2 cm sphere",
    source="DCASE SELD MIC format; TAU-SRIR DB (Politis et al.)")

CUSTOM = ReceiverSpec(
    name="custom", model=M.SPACED, layout=_custom_layout, patterns=_custom_patterns,
    summary="your own array: array.capsules (m, array frame), array.patterns, array.orientations", configured=True,
    stereo="sides",
    convention="capsule k at array.capsules[k] (metres, array frame), pattern array.patterns[k] aimed at "
               "array.orientations[k] (azimuth, elevation degrees)")

BUILTIN = (MIC4, FOA, TETRA, CUSTOM)

