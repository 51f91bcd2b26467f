"""Whether a room of a bank can be trusted: its positions are where a source in that room
can be, and its RIRs have the channels its format has.

A bank's numbers are not checked by anything else: positions written in millimetres
give labels 1500 m away in a 7.5 m room, positions scaled by 10^6 an azimuth of
-3e7°, and 3-channel RIRs in a mic4 bank pass until render mixes them. So, per room:

- every position is finite, at a positive distance, with angles in degrees (azimuth
  within ±360°, elevation within ±90°);
- no source is farther from the array than the room allows: its diagonal when the room
  info gives its dimensions (``dims``, or TAU's ``dimensions``), else
  :data:`MAX_DISTANCE_M`; when the info also places the array (``array.centre`` and
  ``yaw``, as ``tsel bank build`` writes), every source is inside the room;
- a few RIRs read along every trajectory have the format's channels, are 3-D
  ``[N, channels, samples]`` and, where asked, are not empty, NaN or all zero.

Each problem is one BankError line naming the bank, the room and the fix. ``tsel check``
runs these on every room a config uses (banks/scenes.py); ``write_bank`` on every room it
imports.
"""
from __future__ import annotations

import numpy as np

from ..core.geometry import array_to_room, sph_to_cart
from ..errors import BankError, TselError
from ..receivers import receiver

MAX_DISTANCE_M = 100.0  # farther than any room's RIRs are measured (the TAU-SRIR DB's: 1-4 m)
WALL_TOLERANCE_M = 0.05  # a source on a wall, rounded, is still in the room
RIR_SAMPLES_PER_TRAJECTORY = 8  # RIRs read per trajectory to judge a room (a damaged bank is damaged throughout)


def positions_problem(bank, room: str) -> TselError | None:
    """The first thing wrong with the positions of ``room`` (None: nothing)."""
    try:
        trajs = bank.trajectories(room)
    except TselError as e:
        return e
    if not trajs or sum(len(t) for t in trajs) == 0:
        return BankError(f"{bank.source}: room {room} has no RIR positions (no trajectories); re-import the room or "
                         f"remove it from the split's rooms")
    info = bank.room_info(room)
    dims = _dims(info)
    for t in trajs:
        where = f"{bank.source}: room {room} trajectory {t.id}"
        p = np.asarray(t.positions, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
            return BankError(f"{where}: positions missing (shape {p.shape}, expected [N, 3] azimuth, elevation, "
                             f"distance); re-import the bank")
        bad = ~np.all(np.isfinite(p), axis=1) | (p[:, 2] <= 0)
        if bad.any():
            i = int(np.argmax(bad))
            return BankError(f"{where}: {int(bad.sum())} of {len(p)} positions missing or invalid (first at index "
                             f"{i}: {p[i].tolist()}); re-import the bank or drop the room")
        e = _angles_problem(where, p) or _distance_problem(where, p, dims) or _inside_problem(where, p, dims, info)
        if e:
            return e
    return None


# a room's response peaks far above this (1/(4πr) at 100 m is 8e-4); below it an RIR is damage
SILENT_RIR = 1e-10


def rirs_problem(bank, room: str, content: bool = True) -> TselError | None:
    """The first thing wrong with a few RIRs read along every trajectory of ``room``: their
    shape and channels; with ``content``, also empty, NaN/Inf or all-zero RIRs (render
    names any the sample missed)."""
    want = receiver(bank.format).channel_names or tuple(bank.channel_names)
    for t in bank.trajectories(room):
        idx = np.unique(np.linspace(0, len(t) - 1, min(len(t), RIR_SAMPLES_PER_TRAJECTORY)).astype(int))
        try:
            rirs = bank.read(room, t.id, idx)
        except TselError as e:
            return e
        where = f"{bank.source}: room {room} trajectory {t.id}"
        if rirs.ndim != 3:
            return BankError(f"{where}: RIRs of shape {rirs.shape[1:]} per position, expected [channels, samples]; "
                             f"re-import the bank")
        if rirs.shape[1] != len(want):
            return BankError(f"{where}: RIRs have {rirs.shape[1]} channels, but a {bank.format} bank's have "
                             f"{len(want)} ({', '.join(want)}); re-import the bank with its own format, or rebuild it")
        if not content:
            continue
        if rirs.shape[-1] == 0:
            return BankError(f"{where}: the RIRs are empty (length 0); re-import the bank or drop the room")
        finite = np.isfinite(rirs).all(axis=(1, 2))
        if not finite.all():
            return BankError(f"{where}: RIR {int(idx[np.argmin(finite)])} holds NaN or Inf; re-import the bank or drop "
                             f"the room")
        peaks = np.max(np.abs(rirs), axis=(1, 2))
        silent = peaks < SILENT_RIR
        if silent.any():
            k = int(np.argmax(silent))
            what = "is all zero" if peaks[k] == 0 else \
                f"is all but silent (peak {peaks[k]:.2g}, below {SILENT_RIR:g}: scenes would need a gain that overflows)"
            return BankError(f"{where}: RIR {int(idx[k])} {what}; re-import the bank or drop the room")
    return None


def _dims(info: dict) -> np.ndarray | None:
    """The room's size (m) as its info gives it, when it gives one that can be a room."""
    for key in ("dims", "dimensions"):
        try:
            d = np.asarray(info.get(key), dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            continue
        if d.shape == (3,) and np.all(np.isfinite(d)) and np.all(d > 0):
            return d
    return None


def _angles_problem(where: str, p: np.ndarray) -> TselError | None:
    bad = (np.abs(p[:, 0]) > 360.0) | (np.abs(p[:, 1]) > 90.0 + 1e-6)
    if not bad.any():
        return None
    i = int(np.argmax(bad))
    return BankError(f"{where}: position {i} has azimuth {p[i, 0]:.4g}° and elevation {p[i, 1]:.4g}°, which are not "
                     f"angles in degrees (azimuth within ±360°, elevation within ±90°): were the positions scaled? "
                     f"re-import the bank with (azimuth °, elevation °, distance m)")


def _distance_problem(where: str, p: np.ndarray, dims) -> TselError | None:
    reach = float(np.linalg.norm(dims)) if dims is not None else MAX_DISTANCE_M
    far = p[:, 2] > reach + WALL_TOLERANCE_M
    if not far.any():
        return None
    i = int(np.argmax(far))
    room = (f"the room is {' x '.join(f'{d:g}' for d in dims)} m (nothing in it is more than {reach:.1f} m from the "
            f"array)" if dims is not None else f"no room's RIRs are measured more than {MAX_DISTANCE_M:g} m away")
    return BankError(f"{where}: position {i} is {p[i, 2]:.4g} m from the array, but {room}: are the distances in "
                     f"millimetres? re-import the bank with distances in metres")


def _inside_problem(where: str, p: np.ndarray, dims, info: dict) -> TselError | None:
    array = info.get("array") if isinstance(info.get("array"), dict) else {}
    try:
        centre = np.asarray(array.get("centre"), dtype=np.float64).reshape(3)
        yaw = float(array.get("yaw", 0.0))
    except (TypeError, ValueError):
        return None  # the info does not place the array: the distance check is all there is
    if dims is None or not np.all(np.isfinite(centre)) or not np.isfinite(yaw):
        return None
    xyz = array_to_room(sph_to_cart(p[:, 0], p[:, 1], p[:, 2]), centre, yaw)
    out = np.maximum(-xyz, xyz - dims).max(axis=1)
    if not (out > WALL_TOLERANCE_M).any():
        return None
    i = int(np.argmax(out))
    return BankError(f"{where}: position {i} is {out[i]:.2f} m outside the room ({' x '.join(f'{d:g}' for d in dims)} "
                     f"m, the array at {np.round(centre, 2).tolist()}): are the positions in the array frame, in "
                     f"metres? re-import the bank")
