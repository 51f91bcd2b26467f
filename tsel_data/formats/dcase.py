"""The DCASE SELD label CSV (DCASE 2019-2024 Task 3, STARSS23), both directions: a scene's
rows as the DCASE export writes them, and a label CSV read back (``tsel eval --dcase``).

Rows have no header: ``frame,class,source,azimuth,elevation,distance`` — frame index of
100 ms frames, class index, source index, azimuth and elevation in integer degrees (array
frame, azimuth counter-clockwise from the front, [-180, 180)), distance in integer
centimetres (DCASE 2024; older sets have five columns).
"""
from __future__ import annotations

import numpy as np

from ..errors import DatasetError

FRAME_HOP = 0.1  # the DCASE label resolution, s


def dcase_rows(scene, frame_hop: float = FRAME_HOP) -> list[tuple[int, int, int, int, int, int]]:
    """DCASE label rows of one scene, sorted by frame then class then source; five
    numbers for a source without a distance, else six.

    Our label frames must already be ``frame_hop`` long (the DCASE 100 ms resolution).
    """
    if abs(scene.label_hop - frame_hop) > 1e-9:
        raise DatasetError(f"{scene.scene_id}: label_hop is {scene.label_hop} s; DCASE export needs {frame_hop} s "
                           f"frames (set label_hop = {frame_hop} and regenerate)")
    rows = []
    per_class = {0: 0, 1: 0}
    for s in range(scene.n_sources):
        az = scene.azimuth[s]
        if not np.isfinite(az).any():
            continue  # additive / positionless source: nothing to localise
        cls = 0 if s == 0 else 1
        src_idx = per_class[cls]
        per_class[cls] += 1
        frames = np.flatnonzero(scene.active[s] & np.isfinite(az))
        az_i = _round_half_up(az[frames])
        az_i = np.where(az_i >= 180, az_i - 360, az_i)  # 179.6 rounds to 180 == -180
        el_i = _round_half_up(np.nan_to_num(scene.elevation[s][frames]))  # azimuth-only labels: the horizon
        dist = scene.distance[s][frames]
        if np.isfinite(dist).all():
            d_cm = _round_half_up(100.0 * dist)
            rows.extend(zip(frames.tolist(), [cls] * len(frames), [src_idx] * len(frames), az_i.tolist(),
                            el_i.tolist(), d_cm.tolist()))
        else:  # no distance (a recording labelled in five columns): the DCASE 2023 row
            rows.extend(zip(frames.tolist(), [cls] * len(frames), [src_idx] * len(frames), az_i.tolist(),
                            el_i.tolist()))
    rows.sort()
    return rows


def _round_half_up(x) -> np.ndarray:
    return np.floor(np.asarray(x, dtype=np.float64) + 0.5).astype(np.int64)


def read_dcase_csv(path: str) -> np.ndarray:
    """Read a DCASE label CSV -> int64 [N, 6] (frame, class, source, az, el, dist)."""
    rows = np.loadtxt(path, delimiter=",", dtype=np.int64, ndmin=2)
    return rows.reshape(-1, 6) if rows.size else np.zeros((0, 6), np.int64)
