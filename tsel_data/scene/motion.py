"""How a source moves, decided on its labels: stationary, approaching, receding, passing
or circling.

The labels are the truth (array frame, every frame a position is known); only the frames
where the source sounds count, since a listener hears nothing of the rest. From the
positions over those frames, with the thresholds below (metres, degrees):

- **stationary**: no position is more than :data:`STILL_M` from the first, and the
  azimuth spans less than :data:`STILL_DEG`;
- **passing**: the nearest point lies inside the path, :data:`CHANGE_M` nearer than both
  ends (it comes close, then goes away);
- **approaching** / **receding**: the last position is :data:`CHANGE_M` nearer / farther
  than the first, and the nearest point is at that end (within :data:`CHANGE_M`);
- **circling**: otherwise — it moves while its distance stays within :data:`CHANGE_M` of
  where it started (an arc around the listener, or a sideways move of a few degrees).

A source heard in one frame, or without a position, has no motion class (None).
"""
from __future__ import annotations

import numpy as np

from ..core.geometry import sph_to_cart

MOTIONS = ("stationary", "approaching", "receding", "passing", "circling")
STILL_M = 0.1  # m: a source that never gets further than this from where it was heard first is still
STILL_DEG = 2.0  # degrees of azimuth: ... and whose direction does not change by more
CHANGE_M = 0.25  # m: a change of distance that counts as nearer or farther


def motion_class(azimuth, elevation, distance, active) -> str | None:
    """The motion class (:data:`MOTIONS`) of one source from its labels [F] (degrees,
    metres; NaN where positionless) and activity [F], or None."""
    az, el, d = (np.asarray(v, dtype=np.float64) for v in (azimuth, elevation, distance))
    heard = np.asarray(active, dtype=bool) & np.isfinite(az) & np.isfinite(el) & np.isfinite(d)
    if heard.sum() < 2:
        return None
    az, el, d = az[heard], el[heard], d[heard]
    xyz = sph_to_cart(az, el, d)
    span = np.degrees(np.ptp(np.unwrap(np.radians(az))))
    if np.max(np.linalg.norm(xyz - xyz[0], axis=-1)) < STILL_M and span < STILL_DEG:
        return "stationary"
    first, last, nearest = float(d[0]), float(d[-1]), float(np.min(d))
    if nearest < min(first, last) - CHANGE_M:
        return "passing"
    if last <= first - CHANGE_M and nearest >= last - CHANGE_M:
        return "approaching"
    if last >= first + CHANGE_M and nearest >= first - CHANGE_M:
        return "receding"
    return "circling"
