"""A moving source rendered the slow, plain way, to check the fast one against.

The physics of a moving source (dsp/timevarying.py): a sound emitted at sample n goes
through the RIR of where the source is at n. :func:`dense_image` samples that RIR every
``step`` seconds of the path (0.5 ms: a source at 2 m/s moves 1 mm, its reflections'
delays a few hundredths of a sample) and weights the input by hat functions between
those knots, each knot's piece convolved directly — no warps, no groups, no partitions.
Only the image-source part (the shoebox simulator's, up to its transition): the late
tail of a moving source is one static convolution in both (render.path_image).
"""
from __future__ import annotations

import numpy as np

from ..core.geometry import SOUND_SPEED
from .shoebox import FADE, TRANSITION, shoebox_rirs

BATCH = 256  # knots simulated at a time: memory stays ~ BATCH · C · L floats


def image_part_timing(points: np.ndarray, centre, rt60: float) -> tuple[float, float]:
    """(transition, length) in s that shoebox_rirs gives the knots ``points`` together,
    so that knots simulated in batches get the same image-source part."""
    d = float(np.linalg.norm(np.asarray(points) - np.asarray(centre), axis=1).max()) / SOUND_SPEED
    return max(TRANSITION, d + 0.020), d + rt60 + 0.005


def dense_image(room, array, position, x: np.ndarray, fs: int, step: float = 5e-4,
                timing: tuple[float, float] | None = None) -> np.ndarray:
    """The image-source part of a moving source's image, float64 [C, len(x)].

    position: t [K] (s) -> room-frame points [K, 3], the path. x: the dry signal.
    timing: (transition, length) of the image part, by default :func:`image_part_timing`
    over the path at the knots.
    """
    T = len(x)
    times = np.arange(-step, T / fs + 2 * step, step)
    points = position(times)
    if timing is None:
        timing = image_part_timing(points, array.centre, room.rt60)
    assert timing[0] - FADE / 2 < timing[1], "the path's RIRs end before the transition"
    p = times * fs
    n = np.arange(T)
    y = None
    for b0 in range(0, len(times), BATCH):
        ks = range(b0, min(b0 + BATCH, len(times)))
        h = shoebox_rirs(room, array, points[ks.start:ks.stop], fs, one_source=True, tail_apart=True,
                         transition=timing[0], length=timing[1]).rirs
        if y is None:
            y = np.zeros((h.shape[1], T + h.shape[2]))
        for j, k in enumerate(ks):
            left = p[k - 1] if k else p[k] - 1.0
            right = p[k + 1] if k + 1 < len(p) else p[k] + 1.0
            a, b = max(0, int(np.floor(left)) + 1), min(T, int(np.ceil(right)))
            if a >= b:
                continue
            m = n[a:b]
            w = np.where(m <= p[k], (m - left) / (p[k] - left), (right - m) / (right - p[k]))
            seg = x[a:b] * np.clip(w, 0.0, 1.0)
            for c in range(h.shape[1]):
                y[c, a:b + h.shape[2] - 1] += np.convolve(seg, h[j, c])
    return y[:, :T]
