"""How a receiver's channels hear image sources and a diffuse field: one class per capsule
model (receivers/spec.py), chosen by :func:`capsule_model` from the receiver's spec.

A model turns image sources (room-frame positions, amplitudes before spreading) into
impulses on its channels, renders them to signals, and draws diffuse noise with the
receiver's diffuse-field statistics for the late tail. The simulators call nothing else,
so a receiver of an existing model needs no code here.

- :class:`Spaced`: capsules at their own positions; each image reaches capsule c after
  r_c / c with amplitude g_c / (4π r_c), g_c = α_c + (1 - α_c) u_c·o_c the capsule's
  first-order pattern towards the image (1 for omnis).
- :class:`Ambisonic`: W, Y, Z, X (ACN/SN3D) at the centre, gains 1, u_y, u_z, u_x.
- :class:`Mixed`: another model's channels mixed by a matrix (DCASE stereo from FOA).
"""
from __future__ import annotations

import numpy as np

from ..choices import ReceiverModel
from ..geometry import SOUND_SPEED, array_to_room, foa_gains_of
from ..receivers import ArrayPose
from .ism import add_impulses, grid_to_signal, new_grid
from .late import diffuse_filters as _diffuse_filters_omni, diffuse_noise


def fade_out(t: np.ndarray, fade) -> np.ndarray | float:
    """Power-complementary cross-fade: images get cos, the tail sin, of π/2 · ρ(t)."""
    if fade is None:
        return 1.0
    t_mix, width = fade
    rho = np.clip((t - (t_mix - width / 2)) / width, 0.0, 1.0)
    return np.cos(0.5 * np.pi * rho)


class Spaced:
    """Free-field capsules at the array's channel positions, omni or first order."""

    coincident = False

    def __init__(self, array, fs: int):
        self.fs = fs
        caps = array.spec.capsules(array)
        self.centre = np.asarray(array.centre, dtype=np.float64)
        self.mics = array_to_room(caps.positions, self.centre, array.yaw)  # [C, 3], room frame
        self.n_channels = len(self.mics)
        self.omni = caps.omni
        self.alpha = caps.alpha
        # capsule axes in the room frame (rotation only)
        self.axes = array_to_room(caps.orientation, (0.0, 0.0, 0.0), array.yaw)
        self.points = self.mics  # where the receiver is (checks, the image radius)
        self.reference = self.mics[0]  # the ISM fit's receiver (ism method)

    def new_grid(self, n: int):
        return new_grid(self.n_channels, n)

    def add(self, grid, pos: np.ndarray, amp: np.ndarray, fade) -> None:
        c = SOUND_SPEED
        for ch, m in enumerate(self.mics):
            r = np.linalg.norm(pos - m, axis=1)
            t = r / c
            w = amp / (4 * np.pi * r)
            if not self.omni and self.alpha[ch] != 1.0:
                u = (pos - m) / r[:, None]  # towards the image: where the wave comes from
                w = w * (self.alpha[ch] + (1.0 - self.alpha[ch]) * (u @ self.axes[ch]))
            add_impulses(grid, ch, t * self.fs, w * fade_out(t, fade))

    def render(self, grid) -> np.ndarray:
        return grid_to_signal(grid)

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        """[n_sets, C, n] noise with the receiver's diffuse-field statistics (omni variance 1)."""
        if not self.omni:
            raise NotImplementedError("diffuse tails of directional capsules")
        return diffuse_noise(rng, n_sets, n, self.fs, positions=self.mics)

    def diffuse_filters(self, rng, array) -> np.ndarray:
        return _diffuse_filters_omni(self.fs, rng, positions=array.mics())


class Ambisonic:
    """First-order ambisonics (ACN/SN3D) at the array centre."""

    coincident = True
    n_channels = 4

    def __init__(self, array, fs: int):
        self.fs = fs
        self.centre = np.asarray(array.centre, dtype=np.float64)
        self.yaw = array.yaw
        self.points = self.centre[None, :]
        self.reference = self.centre

    def new_grid(self, n: int):
        return new_grid(4, n)

    def add(self, grid, pos: np.ndarray, amp: np.ndarray, fade) -> None:
        """Gains 1, u_y, u_z, u_x of the unit direction u in the array frame
        (geometry.foa_gains_of, the convention of docs/format.md)."""
        v = pos - self.centre
        r = np.linalg.norm(v, axis=1)
        c, s = np.cos(np.radians(self.yaw)), np.sin(np.radians(self.yaw))
        ux = (c * v[:, 0] + s * v[:, 1]) / r  # Rz(-yaw) v
        uy = (-s * v[:, 0] + c * v[:, 1]) / r
        uz = v[:, 2] / r
        gains = foa_gains_of(np.stack([ux, uy, uz], axis=-1))  # [N, 4]
        t = r / SOUND_SPEED
        w = amp / (4 * np.pi * r) * fade_out(t, fade)
        for ch in range(4):
            add_impulses(grid, ch, t * self.fs, w if ch == 0 else w * gains[:, ch])

    def render(self, grid) -> np.ndarray:
        return grid_to_signal(grid)

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        return diffuse_noise(rng, n_sets, n, self.fs, foa=True)

    def diffuse_filters(self, rng, array) -> np.ndarray:
        return _diffuse_filters_omni(self.fs, rng, foa=True)


class Mixed:
    """Channels mixed from a base receiver's by ``matrix`` [C, C_base] (the spec's
    ``base`` and ``matrix``): whatever the base hears, mixed."""

    def __init__(self, array, fs: int):
        spec = array.spec
        base = ArrayPose(spec.base, array.centre, array.yaw)
        self.base = capsule_model(base, fs)
        self.matrix = np.asarray(spec.matrix, dtype=np.float64)
        self.n_channels = len(self.matrix)
        self.coincident = self.base.coincident
        self.points, self.reference = self.base.points, self.base.reference
        self.fs = fs

    def new_grid(self, n: int):
        return self.base.new_grid(n)

    def add(self, grid, pos, amp, fade) -> None:
        self.base.add(grid, pos, amp, fade)

    def render(self, grid) -> np.ndarray:
        return self.matrix @ self.base.render(grid)

    def diffuse_noise(self, rng, n_sets: int, n: int) -> np.ndarray:
        return np.einsum("cb,sbn->scn", self.matrix, self.base.diffuse_noise(rng, n_sets, n))

    def diffuse_filters(self, rng, array) -> np.ndarray:
        base = ArrayPose(array.spec.base, array.centre, array.yaw)
        return (self.matrix @ self.base.diffuse_filters(rng, base)).astype(np.float32)


MODELS = {
    ReceiverModel.SPACED: Spaced,
    ReceiverModel.AMBISONIC: Ambisonic,
    ReceiverModel.MATRIX: Mixed,
}


def capsule_model(array, fs: int):
    """The capsule model of ``array`` (an ArrayPose) at ``fs`` Hz."""
    spec = array.spec
    model = spec.model
    if model == ReceiverModel.SPHERE:
        # an open sphere is free-field omnis at the capsule positions; recipes without a
        # baffle predate the rigid model
        if array.baffle in (None, "open"):
            return Spaced(array, fs)
        raise NotImplementedError("rigid spheres")
    cls = MODELS.get(model)
    if cls is None:
        raise NotImplementedError(f"capsule model {model!r}")
    return cls(array, fs)
