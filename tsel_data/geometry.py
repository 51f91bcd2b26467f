"""Coordinate and label conventions (binding; see docs/format.md).

Array frame: right-handed, origin at the array centre, x = front, y = left, z = up.
Azimuth: degrees counter-clockwise from +x seen from above, wrapped to [-180, 180).
Elevation: degrees above the horizontal plane, [-90, 90]. Distance: metres.

Room frame: pyroomacoustics' shoebox frame, origin in a floor corner, z up. An array
with yaw ψ has its +x axis pointing at azimuth ψ in the room frame, so
``p_array = Rz(-ψ) (p_room - centre)``.
"""
from __future__ import annotations

import numpy as np

FORMATS = ("mic4", "foa", "tetra")

CHANNEL_NAMES = {
    "mic4": ("mic0_front_left", "mic1_back_left", "mic2_back_right", "mic3_front_right"),
    "foa": ("W", "Y", "Z", "X"),
    "tetra": ("M1", "M2", "M3", "M4"),
}

# DCASE MIC format (Eigenmike capsules 6, 10, 26, 22): (azimuth, elevation) in degrees.
TETRA_ANGLES = ((45.0, 35.0), (-45.0, -35.0), (135.0, -35.0), (-135.0, 35.0))
TETRA_RADIUS = 0.042


def wrap_azimuth(az):
    """Wrap degrees to [-180, 180)."""
    return (np.asarray(az, dtype=np.float64) + 180.0) % 360.0 - 180.0


def cart_to_sph(xyz):
    """Array-frame cartesian [..., 3] -> (azimuth deg, elevation deg, distance m)."""
    xyz = np.asarray(xyz, dtype=np.float64)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    r_h = np.hypot(x, y)
    az = wrap_azimuth(np.degrees(np.arctan2(y, x)))
    el = np.degrees(np.arctan2(z, r_h))
    return az, el, np.sqrt(r_h**2 + z**2)


def sph_to_cart(az, el, dist=1.0):
    """(azimuth deg, elevation deg, distance m) -> array-frame cartesian [..., 3]."""
    a, e = np.radians(az), np.radians(el)
    d = np.asarray(dist, dtype=np.float64)
    return np.stack(np.broadcast_arrays(d * np.cos(e) * np.cos(a), d * np.cos(e) * np.sin(a), d * np.sin(e)), axis=-1)


def rotz(deg: float) -> np.ndarray:
    """3x3 rotation about +z by ``deg`` degrees (counter-clockwise seen from above)."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def room_to_array(p_room, centre, yaw_deg: float) -> np.ndarray:
    """Room-frame points [..., 3] -> array frame."""
    d = np.asarray(p_room, dtype=np.float64) - np.asarray(centre, dtype=np.float64)
    return d @ rotz(yaw_deg)  # row vectors: d @ R == (R^T d^T)^T == Rz(-yaw) d


def array_to_room(p_array, centre, yaw_deg: float) -> np.ndarray:
    """Array-frame points [..., 3] -> room frame."""
    return np.asarray(p_array, dtype=np.float64) @ rotz(yaw_deg).T + np.asarray(centre, dtype=np.float64)


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


def mic_positions(fmt: str, side: float | None = None) -> np.ndarray:
    """Channel positions [C, 3] in the array frame; FOA channels sit at the centre."""
    if fmt == "mic4":
        return mic4_positions(side)
    if fmt == "tetra":
        return tetra_positions()
    if fmt == "foa":
        return np.zeros((4, 3))
    raise ValueError(f"unknown array format {fmt!r}; expected one of {FORMATS}")


def foa_gains(az, el) -> np.ndarray:
    """ACN/SN3D first-order gains (W, Y, Z, X) of a plane wave from (az, el) degrees.

    W = 1, Y = sin φ cos θ, Z = sin θ, X = cos φ cos θ. Shape [..., 4].
    """
    a, e = np.radians(np.asarray(az, dtype=np.float64)), np.radians(np.asarray(el, dtype=np.float64))
    a, e = np.broadcast_arrays(a, e)
    return np.stack([np.ones_like(a), np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)], axis=-1)


def frame_centres(n_frames: int, hop: float) -> np.ndarray:
    """Label frame k covers [k·hop, (k+1)·hop) and is labelled at its centre (k + 0.5)·hop (s)."""
    return (np.arange(n_frames) + 0.5) * hop


def azimuth_difference(a, b):
    """Absolute angular difference in degrees, with wrap-around: in [0, 180]."""
    d = np.abs(wrap_azimuth(np.asarray(a) - np.asarray(b)))
    return np.minimum(d, 360.0 - d)
