"""The image sources of a moving source, grouped by how their delays move.

Between two knots the moving renderer (:mod:`tsel_data.dsp.timevarying`) crossfades the
knots' RIRs after aligning them by one delay trajectory per channel, the warp. A
reflection whose delay changes by δ samples more than the warp between two knots is
crossfaded between two copies δ apart: a comb filter at the knot midpoints. With one
warp, the direct path's, a reflection of a line pass slides up to twice the knot's
travel against it (8 samples per 6 cm at 24 kHz); on an arc, whose direct path stands
still, a side wall's reflection moves as fast as the source.

So the image sources are split into groups, each with its own warp, clustered by the
sequence of their delay steps from knot to knot (k-means, energy-weighted, seeded
deterministically): the direct path's group (with the reflections that move like it)
warped by the direct path's own delay, exactly; each other group by the energy-weighted
mean of its members' delay trajectories. Every image then moves continuously with its group's delay, to within its
residual step (a fraction of a sample for most images, measured in
tests/acoustics/test_moving_reflections.py), and its gain is linear between knots. An image is
named by its key (:func:`tsel_data.acoustics.ism.image_positions`), so it stays in its
group whatever the source's position, as the crossfade needs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.geometry import SOUND_SPEED
from .ism import DIRECT_KEY, image_chunks, image_positions

GROUPS = 4  # warps per moving source: the direct path's and three more
MEMORY = 256 << 20  # bytes the grouped knot RIRs may take: fewer groups for large arrays
_ITERATIONS = 12


@dataclass(frozen=True)
class ImageGroups:
    """keys: int64 [N] sorted image keys; group: [N] each key's group (0: the direct
    path's); delays: float64 [K, G, C] samples, each group's warp per knot and channel;
    orders: int [N] each image's reflections; positions: float64 [N, K, 3] where each
    image is at each knot (room frame)."""

    keys: np.ndarray
    group: np.ndarray
    delays: np.ndarray
    orders: np.ndarray | None = None
    positions: np.ndarray | None = None

    @property
    def n_groups(self) -> int:
        return self.delays.shape[1]

    def of(self, keys: np.ndarray) -> np.ndarray:
        """The group of each of ``keys`` (an image the grouping did not see: the last)."""
        i = np.clip(np.searchsorted(self.keys, keys), 0, len(self.keys) - 1)
        return np.where(self.keys[i] == keys, self.group[i], self.n_groups - 1)


def n_groups(knots: int, channels: int, length: int) -> int:
    """How many groups a path's knot RIRs [knots, groups · channels, length] fit in MEMORY."""
    return int(np.clip(MEMORY // max(1, 4 * knots * channels * length), 1, GROUPS))


def image_groups(dims, points: np.ndarray, mics: np.ndarray, centre, fs: int, radius: float, beta: float,
                 groups: int = GROUPS) -> ImageGroups:
    """Group the images within ``radius`` of ``centre`` at any of the knots ``points``
    [K, 3] (room frame); ``mics`` [C, 3] the receiver's points, ``beta`` the reflection
    coefficient (for the energy weights)."""
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    centre = np.asarray(centre, dtype=np.float64)
    reach = float(np.linalg.norm(points - points[0], axis=1).max())
    found = [(o, k) for _, o, k in image_chunks(dims, points[0], centre, radius + reach, keys=True)]
    orders = np.concatenate([o for o, _ in found])
    keys = np.concatenate([k for _, k in found])
    pos = image_positions(dims, keys, points)  # [N, K, 3]
    dist = np.linalg.norm(pos - centre, axis=-1)
    near = dist.min(axis=1) <= radius
    keys, orders, pos, dist = keys[near], orders[near], pos[near], dist[near]
    sort = np.argsort(keys)
    keys, orders, pos, dist = keys[sort], orders[sort], pos[sort], dist[sort]

    direct = int(np.searchsorted(keys, DIRECT_KEY))
    weight = beta ** (2.0 * orders) / np.mean(dist, axis=1) ** 2  # each image's share of the energy
    G = max(1, min(int(groups), len(keys)))
    steps = np.diff(dist, axis=1) * (fs / SOUND_SPEED)
    label = _kmeans(steps, weight, G, direct)
    # channels at one point (coincident capsules, mixed channels) share its delays
    where, chan = np.unique(np.asarray(mics, dtype=np.float64), axis=0, return_inverse=True)
    delays = np.zeros((len(points), G, len(where)))
    for c, m in enumerate(where):
        d = np.linalg.norm(pos - m, axis=-1) * (fs / SOUND_SPEED)  # [N, K]
        for g in range(G):
            members = label == g
            if g == 0:  # the direct path's group moves exactly with it
                delays[:, g, c] = d[direct]
            elif members.any():
                delays[:, g, c] = weight[members] @ d[members] / weight[members].sum()
    return ImageGroups(keys, label, delays[:, :, np.ravel(chan)], orders, pos)


def _kmeans(x: np.ndarray, w: np.ndarray, k: int, pinned: int) -> np.ndarray:
    """Labels 0..k-1 of the rows of ``x`` [N, D] (weights ``w``): weighted Lloyd
    iterations from a farthest-first start, so always the same. Cluster 0 is the row
    ``pinned``'s (the direct path: reflections that move like it, the floor's and the
    ceiling's, share its exact warp), its centre held at that row."""
    cent = [x[pinned]]
    near = np.sum((x - cent[0]) ** 2, axis=1)
    for _ in range(1, k):
        cent.append(x[int(np.argmax(w * near))])
        near = np.minimum(near, np.sum((x - cent[-1]) ** 2, axis=1))
    cent = np.stack(cent)
    label = np.zeros(len(x), dtype=np.int64)
    for _ in range(_ITERATIONS if k > 1 else 0):
        d2 = np.sum(x**2, axis=1)[:, None] - 2.0 * x @ cent.T + np.sum(cent**2, axis=1)[None]
        label = np.argmin(d2, axis=1)
        label[pinned] = 0
        for j in range(1, k):
            sel = label == j
            if sel.any():
                cent[j] = w[sel] @ x[sel] / w[sel].sum()
    return label
