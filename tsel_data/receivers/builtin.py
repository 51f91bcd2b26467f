"""Every built-in receiver, one entry each (``BUILTIN``).

Adding a receiver is one :class:`~tsel_data.receivers.spec.ReceiverSpec` here (and a
test that hears it, docs/design.md "Where things go"): its layout, channel names and
model are all the stages need.
"""
from __future__ import annotations

import numpy as np

from ..choices import Localizer as L, ReceiverModel as M
from ..core.geometry import sph_to_cart
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
    # two virtual cardioids at ±90°: ½(W ± Y) (receivers/stereo.py)
    stereo=((0.5, 0.5, 0.0, 0.0), (0.5, -0.5, 0.0, 0.0)),
    level_channels=(0,), additive=(1.0, 0.0, 0.0, 0.0), localizer=L.INTENSITY, export_folder="foa", recorded=True,
    convention="ACN (W, Y, Z, X), SN3D",
    source="DCASE SELD FOA format (TAU-SRIR DB, STARSS23)")

TETRA = ReceiverSpec(
    name="tetra", model=M.SPHERE, layout=_fixed(tetra_positions()), radius=TETRA_RADIUS, baffle="rigid",
    summary="the DCASE MIC format: 4 capsules of an Eigenmike on a 4.2 cm rigid sphere (array.baffle)",
    channel_names=("M1", "M2", "M3", "M4"), stereo=(0, 1), aliases=("mic",), recorded=True,
    convention="DCASE MIC format: Eigenmike capsules 6, 10, 26, 22 at (azimuth, elevation) (45, 35), (-45, -35), "
               "(135, -35), (-135, 35) degrees on a 4.2 cm sphere",
    source="DCASE SELD MIC format; TAU-SRIR DB (Politis et al.)")

CUSTOM = ReceiverSpec(
    name="custom", model=M.SPACED, layout=_custom_layout, patterns=_custom_patterns,
    summary="your own array: array.capsules (m, array frame), array.patterns, array.orientations", configured=True,
    stereo="sides",
    convention="capsule k at array.capsules[k] (metres, array frame), pattern array.patterns[k] aimed at "
               "array.orientations[k] (azimuth, elevation degrees)")

# mh acoustics Eigenmike em32: (colatitude, azimuth) in degrees of capsules 1-32 on a
# 4.2 cm rigid sphere (em32 release notes; the table of ITA-Toolbox / Politis' tools).
EM32_ANGLES = (
    (69, 0), (90, 32), (111, 0), (90, 328), (32, 0), (55, 45), (90, 69), (125, 45),
    (148, 0), (125, 315), (90, 291), (55, 315), (21, 91), (58, 90), (121, 90), (159, 89),
    (69, 180), (90, 212), (111, 180), (90, 148), (32, 180), (55, 225), (90, 249), (125, 225),
    (148, 180), (125, 135), (90, 111), (55, 135), (21, 269), (58, 270), (122, 270), (159, 271),
)
EM32_RADIUS = 0.042  # m


def em32_positions(radius: float = EM32_RADIUS) -> np.ndarray:
    """Eigenmike em32 capsule positions [32, 3] (array frame; the em32's azimuth runs
    counter-clockwise from its front, as ours: capsule 6 is the DCASE MIC format's M1)."""
    col, az = np.array(EM32_ANGLES, dtype=np.float64).T
    return sph_to_cart(az, 90.0 - col, radius)


def circle(radius: float, azimuths, centre: bool = False) -> np.ndarray:
    """Capsules on a horizontal circle at ``azimuths`` (degrees), the first at the centre if asked."""
    pts = sph_to_cart(np.asarray(azimuths, dtype=np.float64), 0.0, radius)
    return np.vstack([np.zeros((1, 3)), pts]) if centre else pts


EM32 = ReceiverSpec(
    name="em32", model=M.SPHERE, layout=_fixed(em32_positions()), radius=EM32_RADIUS, baffle="rigid",
    summary="mh acoustics Eigenmike em32: 32 capsules on a 4.2 cm rigid sphere (array.baffle)",
    channel_names=tuple(f"c{k}" for k in range(1, 33)), stereo=(13, 29),  # capsules 14 (90°) and 30 (270°)
    convention="Eigenmike em32 capsules 1-32 (channel k-1 = capsule k) at their published (colatitude, azimuth) "
               "on a 4.2 cm sphere; azimuth counter-clockwise from the em32's front",
    source="mh acoustics em32 release notes (capsule table as in ITA-Toolbox ita_sph_sampling_eigenmike and "
           "A. Politis' Spherical-Array-Processing)")

# Devices: the board's own channel order; +x is the board's x axis in its vendor's (and
# ODAS') geometry, taken as the front, +y left, z the board normal (up when it lies face up).
RESPEAKER4 = ReceiverSpec(
    name="respeaker-4", model=M.SPACED, layout=_fixed(circle(0.0405, (180.0, 90.0, 0.0, -90.0))),
    summary="Seeed ReSpeaker 4-Mic Array for Raspberry Pi: 4 mics on a 40.5 mm circle (a 57.3 mm square)",
    stereo="sides",
    convention="mic k of the board (ALSA channel k) at azimuth 180, 90, 0, -90 degrees on a 40.5 mm circle, "
               "x = the board's x axis",
    source="introlab/odas config/odaslive/respeaker_4_mic_array.cfg; respeaker/mic_array mic_array.py "
           "(opposite mics 81.3 mm apart)",
    ambiguity="a planar array cannot tell up from down (elevation is still labelled)")

RESPEAKER6 = ReceiverSpec(
    name="respeaker-6", model=M.SPACED,
    layout=_fixed(circle(0.0463, (120.0, 180.0, -120.0, -60.0, 0.0, 60.0))),
    summary="Seeed ReSpeaker 6-Mic Circular Array kit for Raspberry Pi: 6 mics on a 46.3 mm circle",
    stereo="sides",
    convention="mic k of the board (ALSA channel k) at azimuth 120 + 60k degrees (mod 360) on a 46.3 mm circle, "
               "x = the board's x axis",
    source="introlab/odas config/odaslive/respeaker_6_mic_array.cfg (\"Circular shape, R = 0.0463m\"); "
           "voice-engine doa_respeaker_v2_6mic_array.py",
    ambiguity="a planar array cannot tell up from down (elevation is still labelled)")

UMA8 = ReceiverSpec(
    name="uma8", model=M.SPACED,
    layout=_fixed(circle(0.043, (90.0, 30.0, -30.0, -90.0, -150.0, 150.0), centre=True)),
    summary="miniDSP UMA-8: a centre mic and 6 on a 43 mm circle",
    stereo="sides",
    convention="mic 0 at the centre, mics 1-6 at azimuth 90, 30, -30, -90, -150, 150 degrees on a 43 mm circle, "
               "x = the board's x axis",
    source="introlab/odas config/minidsp/uma8.json (the UMA-8's 7 capsules; miniDSP publishes no radius)",
    ambiguity="a planar array cannot tell up from down (elevation is still labelled)")

LINEAR8 = ReceiverSpec(
    name="linear8", model=M.SPACED,
    layout=_fixed(np.stack([np.zeros(8), 0.28 - 0.08 * np.arange(8), np.zeros(8)], axis=1)),
    summary="8-mic uniform linear array, 8 cm pitch (56 cm) along y, broadside to the front "
            "(the Bar-Ilan MIRD bar)",
    stereo="sides",
    convention="mic k at y = 0.28 - 0.08k m on the y axis (mic 0 leftmost); a line hears only the angle to its "
               "axis: azimuth phi and 180 - phi sound alike",
    source="E. Hadad, F. Heese, P. Vary, S. Gannot, \"Multichannel audio database in various acoustic "
           "environments\", IWAENC 2014 (the 8-8-8-8-8-8-8 cm configuration)",
    ambiguity="lateral", localizer=L.SRP)

# DCASE 2025 task 3 (stereo SELD): L = W + Y, R = W - Y of the FOA recording (mid-side
# with an omni mid): coincident cardioids aimed at ±90° with a peak gain of 2.
STEREO = ReceiverSpec(
    name="stereo", model=M.MATRIX, layout=_fixed(np.zeros((2, 3))), base="foa",
    matrix=((1.0, 1.0, 0.0, 0.0), (1.0, -1.0, 0.0, 0.0)), aliases=("dcase-stereo",),
    summary="the DCASE 2025 task 3 stereo pair: L = W + Y, R = W - Y of first-order ambisonics (coincident "
            "cardioids at +-90 degrees)",
    channel_names=("L", "R"), stereo=(0, 1), export_folder="stereo", ambiguity="lateral", recorded=True,
    localizer=L.MID_SIDE,
    convention="L = W + Y, R = W - Y of ACN/SN3D first-order ambisonics (DCASE 2025 task 3); azimuth phi and "
               "180 - phi sound alike, elevation is not heard: DCASE 2025 labels fold azimuth into [-90, 90] "
               "and keep distance",
    source="K. Shimada et al., Stereo Sound Event Localization and Detection with Onscreen/offscreen "
           "Classification, DCASE 2025 task 3 (arXiv:2507.12042); SonyResearch/dcase2025_stereo_seld_data_generator")

HEAD_RADIUS = 0.0875  # m, for wall margins and the ears' place in records (the HRTF holds the head)

BINAURAL = ReceiverSpec(
    name="binaural", model=M.HRTF, layout=_fixed(np.array([[0.0, HEAD_RADIUS, 0.0], [0.0, -HEAD_RADIUS, 0.0]])),
    radius=HEAD_RADIUS, summary="two ears through a SOFA HRTF (array.hrtf, e.g. the MIT KEMAR set); the head "
                                "faces array.yaw", channel_names=("left", "right"), stereo=(0, 1),
    export_folder="binaural", localizer=L.NONE, unjudged="binaural: SRP-PHAT and the intensity vector cannot read "
                                                      "two ears (use the ITD/ILD)",
    convention="left and right ear signals through the HRTF of array.hrtf (SimpleFreeFieldHRIR); head frame = "
               "array frame (x front, y left, z up)",
    source="AES69 SOFA SimpleFreeFieldHRIR; MIT KEMAR (Gardner & Martin 1994)")

BUILTIN = (MIC4, FOA, TETRA, EM32, RESPEAKER4, RESPEAKER6, UMA8, LINEAR8, STEREO, BINAURAL, CUSTOM)

