"""Microphones as built (``[hardware]``): how the planner draws each receiver's capsules
and clocks for a scene (:func:`draw_hardware`), beside what the renderer does with them
(dsp/hardware.py; render/mix.py applies it to each receiver's mixture).

Draws come from the scene's own generator (the planner's stream 5 of the scene), receiver
by receiver in the recipe's order, and for each: every capsule's gain, then delay,
high-pass corner, tilt and self-noise, then every device's clock offset and drift after the
first, then the self-noise's seed. A receiver gets its own draw, so several receivers in
one scene are as many separate sets of microphones.
"""
from __future__ import annotations

import os
from functools import lru_cache

from ..scene.hardware import Hardware, read_response

# recipes round what is drawn, as they round positions and levels
DECIMALS = {"gain_db": 4, "delay_us": 4, "highpass_hz": 3, "tilt_db": 4, "self_noise_dba": 3,
            "clock_offset_us": 4, "clock_ppm": 4}


def draw_hardware(cfg, rng, poses) -> tuple:
    """One :class:`~tsel_data.scene.hardware.Hardware` per receiver of ``poses`` (the
    recipe's ``array`` then ``receivers``), drawn from ``rng``; () when ``[hardware]`` is off."""
    hw = cfg.hardware
    if not hw.on:
        return ()
    response = _response(hw.response) if hw.response else None
    return tuple(_draw_one(hw, rng, pose.n_channels, response) for pose in poses)


@lru_cache(maxsize=4)
def _response(path: str) -> tuple:
    return read_response(path)  # once per process: every scene of a plan holds the same table


def _draw_one(hw, rng, C: int, response) -> Hardware:
    def per(name: str, n: int) -> tuple:
        d = getattr(hw, name)
        return tuple(round(float(d.sample(rng)), DECIMALS[name]) for _ in range(n))

    drawn = {name: per(name, C) for name in ("gain_db", "delay_us", "highpass_hz", "tilt_db")}
    noise = per("self_noise_dba", C) if hw.self_noise_dba.bounds != (0.0, 0.0) else None
    devices = tuple(int(d) for d in hw.devices) if hw.devices else None
    clocks = {}
    n_dev = (max(devices) + 1) if devices else 1
    if n_dev > 1:
        clocks = {name: (0.0, *per(name, n_dev - 1)) for name in ("clock_offset_us", "clock_ppm")}
    return Hardware(profile=str(hw.profile), seed=int(rng.integers(2**31 - 1)), highpass_order=int(hw.highpass_order),
                    self_noise_dba=noise, sensitivity_dbfs=float(hw.sensitivity_dbfs), devices=devices,
                    response_file=os.path.basename(hw.response) if hw.response else None, response=response,
                    **drawn, **clocks)
