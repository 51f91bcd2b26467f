"""What every RIR method returns."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class RirSet:
    """rirs: float32 [S, C, L] (point, channel, sample). rt60_measured: T30 (s) of the
    omni/W response of the first point, or None when it was not measured. tail: None, or
    (knots of one moving source, asked for apart) the late part all points share, float32
    [C, L_tail] with L_tail >= L: point s's whole RIR is rirs[s] (zero-padded) + tail.
    delays: None, or (images in G groups, shoebox.py) float64 [S, G, C] samples: each
    group's delay trajectory; rirs is then [S, G·C, L], group-major. highpass: None, or
    the second-order sections of the DC blocker the image parts in ``rirs`` still need,
    applied once to what is rendered from them (shoebox.py ``image_highpass=False``)."""

    rirs: np.ndarray
    rt60_measured: float | None = None
    tail: np.ndarray | None = None
    delays: np.ndarray | None = None
    highpass: np.ndarray | None = None
