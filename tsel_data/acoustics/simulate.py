"""One entry point for every RIR method."""
from __future__ import annotations

import numpy as np

from ..choices import RirMethod, values
from .base import RirSet

RIR_METHODS = values(RirMethod)


def simulate_rirs(room, array, points, fs: int, method: str = "hybrid", seed: int = 0,
                  one_source: bool = False, tail_apart: bool = False, groups: int = 1,
                  image_highpass: bool = True) -> RirSet:
    """RIRs from room-frame points to an array's channels.

    Parameters
    ----------
    room : Room
        Shoebox dims (m) and requested RT60 (s).
    array : ArrayPose
    points : array_like, [S, 3]
        Source positions, room frame, metres.
    fs : int
        Hz.
    method : str
        One of :data:`RIR_METHODS`.
    seed : int
        The stochastic parts (late tail, pyroomacoustics' global state).
    one_source : bool
        The points are the knots of one moving source (one late-tail realisation shared
        by all knots).
    tail_apart : bool
        With ``one_source``: return that shared late tail in ``RirSet.tail`` and only the
        early parts in ``rirs`` (methods without a shared tail return whole RIRs and no
        tail). A moving source's tail does not move with it, so the renderer convolves it
        once (render.spatial_images).
    groups : int
        With ``tail_apart``: the image sources in up to this many groups that move alike,
        each with its delay trajectory (``RirSet.delays``; shoebox methods only).
    image_highpass : bool
        False (with ``tail_apart``, shoebox methods): the image parts without their DC
        blocker, for the caller to apply once (``RirSet.highpass``).

    Returns
    -------
    RirSet
        ``rirs`` float32 [S, C, L], sample 0 = emission time; ``rt60_measured`` (s) or None;
        ``tail`` (see ``tail_apart``) or None.
    """
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    # each method is imported when used: pyroomacoustics takes seconds to import, and a
    # process usually needs one method
    if method == RirMethod.PYROOMACOUSTICS:
        from .pyroom import pyroom_rirs

        return pyroom_rirs(room, array, points, fs, seed=seed)
    if method in (RirMethod.ISM, RirMethod.HYBRID):
        from .shoebox import shoebox_rirs

        return shoebox_rirs(room, array, points, fs, method=method, seed=seed, one_source=one_source,
                            tail_apart=tail_apart, groups=groups, image_highpass=image_highpass)
    raise ValueError(f"unknown RIR method {method!r}; expected one of {RIR_METHODS}")
