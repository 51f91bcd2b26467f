"""pyroomacoustics' default path, as a user would write it.

Absorption and maximum image order from ``pra.inverse_sabine(rt60, dims)``, specular
walls, ``room.compute_rir()``. Omni capsules only (mic4, and tetra as free-field omnis);
FOA needs the project's own simulator. This is the reference the fast simulator is
benchmarked against (benchmarks/bench_simulated.py).

Put on the project's conventions (acoustics/simulate.py): sample 0 is the emission time
(pyroomacoustics' fractional-delay latency is removed) and the direct path of a point r
metres away has amplitude 1 / (4π r). pyroomacoustics 0.10 computes image amplitudes as
``damping / distance`` (1 / r, 22 dB above 1 / (4π r)); older versions used 1 / (4π r).
Which one the installed version does is measured once (:func:`pyroom_scale`), not assumed.

``inverse_sabine`` cannot make a room decay faster than Sabine's formula with fully
absorbing walls: it needs RT60 ≥ 24 ln(10) V / (c S) (V volume, S surface, c = 343 m/s;
0.16 s · V/S in metres). Below that it raises a bare ``ValueError``; here that is a
:class:`~tsel_data.errors.GeometryError` naming the room and the limit
(:func:`sabine_min_rt60`).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pyroomacoustics as pra

from ..core.geometry import SOUND_SPEED, array_to_room
from ..errors import GeometryError
from .base import RirSet
from .metrics import sabine_min_rt60

# pyroomacoustics centres its fractional-delay filter, which delays every RIR by half
# the filter length; we remove it so sample 0 is the emission time.
_PRA_LATENCY = (pra.constants.get("frac_delay_length") - 1) // 2


@lru_cache(maxsize=8)
def pyroom_scale(fs: int) -> float:
    """Factor that puts the installed pyroomacoustics' RIRs on the 1 / (4π r) convention:
    1 / (4π) when its direct path is 1 / r (0.10), 1 when it is already 1 / (4π r).

    Measured, not assumed: the free-field RIR (max_order = 0) of a point whose delay is a
    whole number of samples is one sample of the direct path's amplitude.
    """
    pra.constants.set("c", SOUND_SPEED)
    n = 48
    r = n * SOUND_SPEED / fs
    room = pra.ShoeBox([4.0, 4.0, 4.0], fs=fs, max_order=0)
    room.add_microphone(np.array([1.0, 2.0, 2.0]))
    room.add_source([1.0 + r, 2.0, 2.0])
    room.compute_rir()
    amp = float(np.max(np.abs(np.asarray(room.rir[0][0])[_PRA_LATENCY + n - 2 : _PRA_LATENCY + n + 3])))
    ratio = amp * 4 * np.pi * r  # 1 for the 1 / (4π r) convention, 4π for 1 / r
    for convention in (1.0, 4 * np.pi):
        if abs(ratio / convention - 1.0) < 0.05:
            return 1.0 / convention
    raise RuntimeError(f"pyroomacoustics {pra.__version__}: a direct path at {r:.3f} m has amplitude {amp:.4g}, "
                       f"neither 1/r nor 1/(4 pi r); the pyroomacoustics RIR method does not know its scale")


def pyroom_rirs(room, array, points: np.ndarray, fs: int, seed: int = 0, max_order: int | None = None) -> RirSet:
    if not array.free_field_omnis:
        raise ValueError(f"the pyroomacoustics method renders free-field omni capsules only, not {array.format}; "
                         f"use rir_method 'ism' or 'hybrid'")
    pra.constants.set("c", SOUND_SPEED)  # pyroomacoustics' own default, stated
    limit = sabine_min_rt60(room.dims)
    if room.rt60 < limit:
        raise GeometryError(
            f"room {[round(float(v), 3) for v in room.dims]} m with RT60 {room.rt60:g} s: the pyroomacoustics method "
            f"(inverse_sabine) cannot decay faster than {limit:.3f} s in it, Sabine's RT60 with fully absorbing walls "
            f"(24 ln10 V / (c S)); use rir_method \"hybrid\" or \"ism\", a longer room.rt60 or smaller rooms")
    scale = pyroom_scale(int(fs))
    # pyroomacoustics draws from numpy's global generator (random ISM, ray tracing):
    # seed it per task so forked workers do not share a stream, and give the caller's
    # state back afterwards
    state = np.random.get_state()
    np.random.seed(seed % 2**32)
    try:
        out = _pyroom_rirs(room, array, points, fs, max_order)
    finally:
        np.random.set_state(state)
    out.rirs *= np.float32(scale)
    return out


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
