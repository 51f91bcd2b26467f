"""pyroomacoustics' default path, as a user would write it.

Absorption and maximum image order from ``pra.inverse_sabine(rt60, dims)``, specular
walls, ``room.compute_rir()``. Omni capsules only (mic4, and tetra as free-field omnis);
FOA needs the project's own simulator. This is the reference the fast simulator is
benchmarked against (benchmarks/bench_simulated.py).
"""
from __future__ import annotations

import numpy as np
import pyroomacoustics as pra

from ..geometry import SOUND_SPEED, array_to_room
from .base import RirSet

# pyroomacoustics centres its fractional-delay filter, which delays every RIR by half
# the filter length; we remove it so sample 0 is the emission time.
_PRA_LATENCY = (pra.constants.get("frac_delay_length") - 1) // 2


def pyroom_rirs(room, array, points: np.ndarray, fs: int, seed: int = 0, max_order: int | None = None) -> RirSet:
    if array.format == "foa":
        raise ValueError("the pyroomacoustics method renders omni capsules only; use rir_method 'ism' or 'hybrid' for FOA")
    pra.constants.set("c", SOUND_SPEED)  # pyroomacoustics' own default, stated
    # pyroomacoustics draws from numpy's global generator (random ISM, ray tracing):
    # seed it per task so forked workers do not share a stream, and give the caller's
    # state back afterwards
    state = np.random.get_state()
    np.random.seed(seed % 2**32)
    try:
        return _pyroom_rirs(room, array, points, fs, max_order)
    finally:
        np.random.set_state(state)


def _pyroom_rirs(room, array, points: np.ndarray, fs: int, max_order: int | None) -> RirSet:
    e_abs, order = pra.inverse_sabine(room.rt60, list(room.dims))
    r = pra.ShoeBox(
        list(room.dims), fs=fs, materials=pra.Material(e_abs), max_order=order if max_order is None else max_order
    )
    mics = array_to_room(array.mics(), array.centre, array.yaw)
    r.add_microphone_array(mics.T)
    for p in points:
        r.add_source(list(p))
    r.compute_rir()
    n_ch, n_src = len(mics), len(points)
    length = max(len(r.rir[m][s]) for m in range(n_ch) for s in range(n_src)) - _PRA_LATENCY
    out = np.zeros((n_src, n_ch, length), dtype=np.float32)
    for m in range(n_ch):
        for s in range(n_src):
            h = r.rir[m][s][_PRA_LATENCY:]
            out[s, m, : len(h)] = h
    return RirSet(out, None)
