"""Where a receiver stands in a room, how it is turned, and what it is (:class:`ArrayPose`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..choices import Baffle, ReceiverModel
from ..core.geometry import Vec3
from ..core.jsonable import JsonFields, key, rows, unset
from .registry import receiver


def _floats(v):
    return None if v is None else tuple(tuple(float(x) for x in row) for row in v)


@dataclass(frozen=True)
class ArrayPose(JsonFields):
    """A receiver in a room: which one, where and how it is turned.

    format: the receiver's name (``scene.format``; :mod:`tsel_data.receivers.builtin`).
    centre: room frame (m). yaw: degrees, the direction of the array's +x axis in the
    room frame. side: mic4 side length (m). The rest only for receivers that need them
    (None otherwise, and then absent from recipes, so older recipes keep their bytes):
    capsules: a custom array's capsule positions ((x, y, z), ...) m, array frame;
    patterns: its capsules' first-order patterns (``omni``, ``cardioid``, ...; None: all
    omni); orientations: their axes ((azimuth °, elevation °), ...), array frame;
    baffle: a sphere array's ``rigid`` or ``open`` baffle (None: open, as recipes made
    before baffles were modelled); hrtf: a binaural receiver's SOFA file (as the plan
    names it; Roots say where it is); interpolation: its HRTF lookup (``nearest`` or
    ``interpolated``).
    """

    format: str
    centre: Vec3 = key(encode=list, decode=tuple)
    yaw: float = key()
    side: float | None = None
    capsules: tuple | None = key(None, omit=unset("capsules"), encode=rows, decode=lambda v: _floats(v))
    patterns: tuple | None = key(None, omit=unset("patterns"), encode=list,
                                 decode=lambda v: None if v is None else tuple(v))
    orientations: tuple | None = key(None, omit=unset("orientations"), encode=rows, decode=lambda v: _floats(v))
    baffle: str | None = key(None, omit=unset("baffle"))
    hrtf: str | None = key(None, omit=unset("hrtf"))
    interpolation: str | None = key(None, omit=unset("interpolation"))

    @property
    def spec(self):
        """This receiver's :class:`~tsel_data.receivers.spec.ReceiverSpec`."""
        return receiver(self.format)

    def mics(self) -> np.ndarray:
        """Channel positions [C, 3] in the array frame (metres); coincident channels at the centre."""
        return self.spec.positions(self)

    @property
    def n_channels(self) -> int:
        return len(self.spec.channels(self))

    def channel_names(self) -> tuple:
        return self.spec.channels(self)

    @property
    def free_field_omnis(self) -> bool:
        """Whether every channel is an omnidirectional capsule in the free field (spaced
        omnis, or a sphere array without its baffle): what pyroomacoustics can render."""
        spec = self.spec
        if spec.model == ReceiverModel.SPHERE:
            return self.baffle in (None, Baffle.OPEN)
        return spec.model == ReceiverModel.SPACED and all(p == "omni" for p in self.patterns or ())

    def radius(self) -> float:
        """Distance (m) of the farthest capsule (or the sphere's or head's surface) from the centre."""
        return array_radius(self)

    def room_mic_points(self) -> list[Vec3]:
        """Capsule positions in the room frame, in plain Python (validation runs once per
        planned scene, where numpy's per-call cost dominates). Coincident receivers: the centre."""
        c, s = math.cos(math.radians(self.yaw)), math.sin(math.radians(self.yaw))
        spec = self.spec
        if spec.coincident:
            local = [(0.0, 0.0, 0.0)]
        elif spec.size_key == "side":
            r = self.side / math.sqrt(2.0)
            local = [(r * math.cos(math.radians(45 + 90 * k)), r * math.sin(math.radians(45 + 90 * k)), 0.0)
                     for k in range(4)]
        else:
            local = self.mics().tolist()
        x0, y0, z0 = self.centre
        return [(x0 + c * x - s * y, y0 + s * x + c * y, z0 + z) for x, y, z in local]

    # --- recipes --------------------------------------------------------------------




def array_radius(pose) -> float:
    """Distance (m) of the farthest capsule from the array centre, or the sphere's or the
    head's radius when larger: what must fit between the array centre and the walls."""
    spec = pose.spec
    if spec.size_key == "side":  # a mic4 square: side/√2, in plain Python (rules call it per range)
        return float(pose.side) / math.sqrt(2.0)
    pos = spec.positions(pose)
    reach = float(np.max(np.linalg.norm(pos, axis=1))) if len(pos) else 0.0
    return max(reach, spec.radius)


def mic_positions(fmt: str, side: float | None = None) -> np.ndarray:
    """Channel positions [C, 3] (array frame) of a receiver that needs nothing but its
    name and, for mic4, its side (m)."""
    return ArrayPose(fmt, (0.0, 0.0, 0.0), 0.0, side).mics()
