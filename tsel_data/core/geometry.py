"""Coordinate and label conventions (binding: docs/format.md) and the geometry types every
stage shares. The receivers themselves (array layouts, channels) are tsel_data.receivers.

Array frame: right-handed, origin at the array centre, x = front, y = left, z = up.
Azimuth: degrees counter-clockwise from +x seen from above, wrapped to [-180, 180).
Elevation: degrees above the horizontal plane, [-90, 90]. Distance: metres.

Room frame: pyroomacoustics' shoebox frame, origin in a floor corner, z up. An array
with yaw ψ has its +x axis pointing at azimuth ψ in the room frame, so
``p_array = Rz(-ψ) (p_room - centre)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Vec3 = tuple[float, float, float]

SOUND_SPEED = 343.0  # m/s, every simulator and localizer of the package


@dataclass(frozen=True)
class Room:
    """A shoebox room: ``dims`` (Lx, Ly, Lz) in metres and the requested RT60 in seconds."""

    dims: Vec3
    rt60: float


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


def foa_gains(az, el) -> np.ndarray:
    """ACN/SN3D first-order gains (W, Y, Z, X) of a plane wave from (az, el) degrees.

    W = 1, Y = sin φ cos θ, Z = sin θ, X = cos φ cos θ. Shape [..., 4].
    """
    return foa_gains_of(sph_to_cart(az, el, 1.0))


def foa_gains_of(u) -> np.ndarray:
    """The same gains from array-frame unit vectors u [..., 3]: (1, u_y, u_z, u_x)."""
    u = np.asarray(u, dtype=np.float64)
    return np.stack([np.ones_like(u[..., 0]), u[..., 1], u[..., 2], u[..., 0]], axis=-1)


def frame_centres(n_frames: int, hop: float) -> np.ndarray:
    """Label frame k covers [k·hop, (k+1)·hop) and is labelled at its centre (k + 0.5)·hop (s)."""
    return (np.arange(n_frames) + 0.5) * hop


def azimuth_difference(a, b):
    """Absolute angular difference in degrees, with wrap-around: in [0, 180]."""
    d = np.abs(wrap_azimuth(np.asarray(a) - np.asarray(b)))
    return np.minimum(d, 360.0 - d)


def circular_mean(az) -> float:
    """Circular mean of azimuths (deg) -> deg in [-180, 180)."""
    a = np.radians(np.asarray(az, dtype=np.float64))
    m = math.degrees(math.atan2(np.sin(a).mean(), np.cos(a).mean()))
    return float(wrap_azimuth(m))


def interpolate_positions(times, positions, t) -> np.ndarray:
    """Positions (az °, el °, dist m) [len(t), 3] at times ``t`` from knot positions [K, 3].

    The same linear-in-time blend as the moving renderer's crossfade (dsp/timevarying.py;
    constant outside the knots), so labels follow exactly the rendered path; azimuth is
    unwrapped before interpolating and wrapped to [-180, 180) after.
    """
    tau = np.asarray(times, dtype=np.float64).reshape(-1)
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(t, dtype=np.float64)
    if len(tau) == 1:
        return np.broadcast_to(pos[0], t.shape + (3,)).copy()
    az = np.degrees(np.unwrap(np.radians(pos[:, 0])))
    out = np.stack([np.interp(t, tau, az), np.interp(t, tau, pos[:, 1]), np.interp(t, tau, pos[:, 2])], axis=-1)
    out[..., 0] = wrap_azimuth(out[..., 0])
    return out
