"""Sampling static points and moving-source walks along bank trajectories.

A moving source walks along one bank trajectory at a constant angular speed v (°/s),
measured as the great-circle angle between consecutive bank positions, starting at a
random point in a random direction. The walk is rendered from the bank RIRs it passes
("knots"), each applied at the instant the walk passes its position; between knots the
renderer crossfades linearly (timevarying.render_moving) and labels interpolate the
knot positions with the same weights (:func:`bank_path_positions`), so the labelled
trajectory is exactly the rendered one.

Knots are every ``stride``-th RIR along the path, ``stride = max(1, floor(v·knot_hop/Δ))``
with Δ the median spacing, so there is a knot at least every ``knot_hop`` seconds (the
DCASE generator's 100 ms) or at every RIR passed, whichever is sparser-but-not-coarser.
Closed loops (full circles) wrap around. On an open path too short for the walk, the
source turns back at the ends (a ping-pong walk) rather than changing speed.
"""
from __future__ import annotations

import numpy as np

from ..core.geometry import interpolate_positions, sph_to_cart
from ..errors import BankError


def angular_steps(positions) -> np.ndarray:
    """Great-circle angle (deg) from position i to i+1, the last one back to position 0. [N]"""
    u = sph_to_cart(np.asarray(positions)[:, 0], np.asarray(positions)[:, 1], 1.0)
    v = np.roll(u, -1, axis=0)
    cross = np.linalg.norm(np.cross(u, v), axis=1)
    return np.degrees(np.arctan2(cross, np.sum(u * v, axis=1)))


class _Walk:
    """Arc length along a trajectory, unrolled over the integers (wrap or reflect)."""

    def __init__(self, positions, closed: bool):
        steps = angular_steps(positions)
        self.n = len(positions)
        self.c = np.concatenate([[0.0], np.cumsum(steps[:-1])])
        self.closed = closed
        self.length = float(self.c[-1])
        self.period = self.length + float(steps[-1]) if closed else 2.0 * self.length
        self.median_step = float(np.median(steps[:-1])) if self.n > 1 else 0.0

    def arc(self, u):
        u = np.asarray(u, dtype=np.int64)
        if self.closed:
            k, f = np.divmod(u, self.n)
            return self.c[f] + k * self.period
        m = 2 * (self.n - 1)
        k, f = np.divmod(u, m)
        a = np.where(f <= self.n - 1, self.c[np.minimum(f, self.n - 1)], self.period - self.c[np.clip(m - f, 0, self.n - 1)])
        return a + k * self.period

    def index(self, u):
        u = np.asarray(u, dtype=np.int64)
        if self.closed:
            return np.mod(u, self.n)
        m = 2 * (self.n - 1)
        f = np.mod(u, m)
        return np.where(f <= self.n - 1, f, m - f)

    def locate(self, s: float) -> int:
        """Largest u with arc(u) <= s."""
        k = int(np.floor(s / self.period))
        r = s - k * self.period
        if self.closed:
            return k * self.n + int(np.searchsorted(self.c, r, "right") - 1)
        m = 2 * (self.n - 1)
        if r <= self.length:
            return k * m + int(np.searchsorted(self.c, r, "right") - 1)
        j = int(np.searchsorted(self.c, self.period - r, "left"))
        return k * m + (m - j)


def sample_bank_path(bank, room: str, rng: np.random.Generator, duration: float, speed_deg_s,
                     knot_hop: float | None = 0.1, trajectory=None, direction: int | None = None):
    """A moving-source walk: ``(traj_id, indices int64 [K], times float64 [K])``.

    rng: numpy Generator. duration: seconds the walk must cover. speed_deg_s: angular
    speed in °/s, or a sequence to choose from uniformly (DCASE: 10, 20, 40).
    knot_hop: longest time between knots (s); None uses every RIR passed.
    trajectory: a trajectory id to walk on (default: one at random).
    direction: +1 (along the stored order) or -1 (default: random).

    ``bank.read(room, traj_id, indices)`` gives the knot RIRs; ``times`` the seconds at
    which each applies fully (``times[0] <= 0``, ``times[-1] >= duration``), ready for
    ``render_moving``. Speed 0 gives a static point (one index, times ``[0.0]``).
    """
    speed = float(rng.choice(np.asarray(speed_deg_s, dtype=np.float64))) if np.ndim(speed_deg_s) else float(speed_deg_s)
    if speed < 0:
        raise ValueError(f"speed must be >= 0 deg/s, got {speed}")
    trajs = [t for t in bank.trajectories(room) if len(t) >= 2]
    if trajectory is not None:
        traj = bank.trajectory(room, trajectory)
    elif trajs:
        traj = trajs[int(rng.integers(len(trajs)))]
    else:
        traj_id, idx = sample_bank_point(bank, room, rng)
        return traj_id, np.array([idx], dtype=np.int64), np.array([0.0])
    d = int(direction) if direction is not None else (1 if rng.random() < 0.5 else -1)
    if speed == 0 or duration <= 0 or len(traj) < 2:
        return traj.id, np.array([int(rng.integers(len(traj)))], dtype=np.int64), np.array([0.0])

    w = _Walk(traj.positions, traj.closed)
    if w.length <= 0:
        raise ValueError(f"trajectory {room}/{traj.id} has all its positions at one direction")
    span = speed * duration
    if w.closed:
        s0 = float(rng.uniform(0.0, w.period))
    elif span <= w.length:
        lo = 0.0 if d > 0 else span
        s0 = float(rng.uniform(lo, lo + w.length - span))
    else:
        s0 = float(rng.uniform(0.0, w.length))
    stride = 1 if not knot_hop else max(1, int(np.floor(speed * knot_hop / max(w.median_step, 1e-9) + 1e-9)))
    s_end = s0 + d * span

    u0 = w.locate(s0)
    if d < 0 and w.arc(u0) < s0:
        u0 += 1
    n = int(np.ceil(abs(w.locate(s_end) - u0) / stride)) + 3
    while True:
        u = u0 + d * stride * np.arange(n)
        a = w.arc(u)
        past = np.nonzero((a - s_end) * d >= 0)[0]
        if past.size:
            u, a = u[: past[0] + 1], a[: past[0] + 1]
            break
        n *= 2
    times = (a - s0) / (d * speed)
    keep = np.concatenate([[True], np.diff(times) > 1e-9])  # drop repeated positions
    return traj.id, w.index(u[keep]).astype(np.int64), times[keep]


def sample_bank_point(bank, room: str, rng: np.random.Generator):
    """A static source: ``(traj_id, index)``, uniform over all RIRs of the room."""
    trajs = bank.trajectories(room)
    sizes = np.array([len(t) for t in trajs], dtype=np.int64)
    if sizes.sum() == 0:
        raise BankError(f"{bank.source}: room {room!r} holds no RIRs")
    k = int(rng.integers(sizes.sum()))
    i = int(np.searchsorted(np.cumsum(sizes), k, "right"))
    return trajs[i].id, int(k - (np.cumsum(sizes)[i] - sizes[i]))


def bank_path_positions(trajectory, indices, times, t) -> np.ndarray:
    """Positions (az, el, dist) [len(t), 3] of a walk at times ``t`` (e.g. label-frame centres).

    Interpolates the knot positions with the renderer's weights (linear in time,
    azimuth unwrapped), so labels follow exactly what ``render_moving`` rendered.
    """
    return interpolate_positions(times, np.asarray(trajectory.positions)[np.asarray(indices)], t)
