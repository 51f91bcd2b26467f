"""One entry point for every RIR method."""
from __future__ import annotations

import numpy as np

from ..choices import RirMethod, values
from .base import RirSet

RIR_METHODS = values(RirMethod)


def simulate_rirs(room, array, points, fs: int, method: str = "hybrid", seed: int = 0,
                  one_source: bool = False) -> RirSet:
    """RIRs [S, C, L] from room-frame ``points`` [S, 3] (m) to ``array``'s channels.

    room: :class:`~tsel_data.geometry.Room`. array: :class:`~tsel_data.geometry.ArrayPose`.
    fs: Hz. method: one of :data:`RIR_METHODS`. seed: the stochastic parts (late tail).
    one_source: the points are the knots of one moving source (the stochastic late tail
    is then one realisation shared by all knots).
    """
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    # each method is imported when used: pyroomacoustics and scipy.signal are slow to
    # import, and a process usually needs one method
    if method == RirMethod.PYROOMACOUSTICS:
        from .pyroom import pyroom_rirs

        return pyroom_rirs(room, array, points, fs, seed=seed)
    if method in (RirMethod.ISM, RirMethod.HYBRID):
        from .shoebox import shoebox_rirs

        return shoebox_rirs(room, array, points, fs, method=method, seed=seed, one_source=one_source)
    raise ValueError(f"unknown RIR method {method!r}; expected one of {RIR_METHODS}")
