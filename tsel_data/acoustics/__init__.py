"""Room impulse responses behind one interface.

``simulate_rirs(room, array, points, fs, method, seed)`` returns the RIRs from each
room-frame point to each channel of the array, as a :class:`RirSet`. Sample 0 of every
RIR is the emission time, so the direct path of a source at distance r arrives at
r / c · fs samples (no filter latency left in).

Methods: ``pyroomacoustics`` (the library's default path, as users write it: absorption
and max order from ``inverse_sabine``, ``compute_rir``), and the project's own
``ism`` / ``hybrid`` (see shoebox.py, docs/acoustics.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SOUND_SPEED = 343.0
RIR_METHODS = ("hybrid", "ism", "pyroomacoustics")


@dataclass
class RirSet:
    """rirs: float32 [S, C, L] (point, channel, sample). rt60_measured: T30 (s) of the
    omni/W response of the first point, or None when it was not measured."""

    rirs: np.ndarray
    rt60_measured: float | None = None


def simulate_rirs(room, array, points, fs: int, method: str = "hybrid", seed: int = 0,
                  one_source: bool = False) -> RirSet:
    """RIRs [S, C, L] from room-frame ``points`` [S, 3] to ``array``'s channels.

    one_source: the points are the knots of one moving source (the stochastic late tail
    is then one realisation shared by all knots).
    """
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    if method == "pyroomacoustics":
        from .pyroom import pyroom_rirs

        return pyroom_rirs(room, array, points, fs, seed=seed)
    if method in ("ism", "hybrid"):
        from .shoebox import shoebox_rirs

        return shoebox_rirs(room, array, points, fs, method=method, seed=seed, one_source=one_source)
    raise ValueError(f"unknown RIR method {method!r}; expected one of {RIR_METHODS}")
