"""What a receiver is: one :class:`ReceiverSpec` per array, declared once.

A receiver is whatever hears a scene: a microphone array, an ambisonic microphone, a
stereo pair, two ears. Every stage reads its spec and none compares format names: the
planner its size parameter and wall margin, the simulators its capsule model, the mixer
its level and additive channels, the tools its localizer, headphone preview and export
folder, ``dataset.json`` its convention text.

Capsule models (``model``, :class:`~tsel_data.choices.ReceiverModel`), each implemented
once in ``acoustics/capsules.py``:

- ``spaced``: capsules at their own positions in the free field, each omnidirectional or
  first order: a plane wave from the unit direction u reaches capsule c with gain
  ``α_c + (1 - α_c) u·o_c`` (o_c its orientation; α = 1 omni, 1/2 cardioid, (√3 - 1)/2
  supercardioid, 1/4 hypercardioid, 0 figure-8).
- ``ambisonic``: first-order ambisonics, ACN/SN3D (W, Y, Z, X), coincident.
- ``sphere``: capsules on a sphere of ``radius``, with a rigid baffle (the pressure of
  the wave scattered by the sphere, acoustics/sphere.py) or open (free-field omnis).
- ``hrtf``: two ears, each image source through the head-related impulse response of
  its direction (a SOFA file, acoustics/hrtf.py).
- ``matrix``: channels mixed from another receiver's (``base``, ``matrix``): DCASE 2025's
  stereo from FOA.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..choices import Localizer, ReceiverModel

# First-order patterns: gain α + (1 - α) cos Θ for a wave from Θ off the capsule's axis.
PATTERN_ALPHA = {
    "omni": 1.0,
    "subcardioid": 0.75,
    "cardioid": 0.5,
    "supercardioid": (math.sqrt(3.0) - 1.0) / 2.0,  # the largest front-to-back energy ratio
    "hypercardioid": 0.25,  # the highest directivity index of first order
    "figure8": 0.0,
}

MAX_CHANNELS = 64


@dataclass(frozen=True)
class Capsules:
    """A receiver as the simulators see it (array frame): ``positions`` [C, 3] m,
    ``alpha`` [C] first-order pattern coefficients (1 = omni), ``orientation`` [C, 3]
    unit vectors (each capsule's axis; unused for omnis)."""

    positions: np.ndarray
    alpha: np.ndarray
    orientation: np.ndarray

    @property
    def omni(self) -> bool:
        return bool(np.all(self.alpha == 1.0))


@dataclass(frozen=True)
class ReceiverSpec:
    """One receiver, declared once (:mod:`tsel_data.receivers.builtin`).

    name: the ``scene.format`` value. summary: one line (``tsel presets``, docs).
    model: how a wave reaches its channels (module docstring). layout: the array pose ->
    capsule positions [C, 3] (m, array frame), a function because some arrays are drawn
    per scene (mic4's side) or come from the config (custom). channel_names: fixed names,
    or empty for ``mic0 … micC-1``. patterns: the pose -> (α [C], orientation [C, 3]);
    None: every capsule omni. size_key: the ``array.*`` key that sizes the array per
    scene (``side``), or empty. radius: the sphere's (``sphere``) or head's (``hrtf``)
    radius in m, for wall margins and scattering. baffle: the default of a sphere's
    ``array.baffle`` (``rigid`` or ``open``). stereo: the headphone preview, a pair of
    channel indices (left, right), ``"sides"`` (the
    outermost capsules along y) or a decode matrix [2][C]. level_channels: the
    channels whose mean energy is a source's level (a source's "omni energy"; all when
    empty). additive: per-channel gains of an unspatialised (additive) source (all 1
    when empty). convention: the text ``dataset.json`` carries. aliases: other names
    (banks, SOFA files). base, matrix: the ``matrix`` model's receiver and [C][C_base]
    mixing. localizer: how ``tsel verify`` hears it (``srp``: SRP-PHAT over capsule
    pairs; ``intensity``: the FOA intensity vector; empty: not judged, ``unjudged``
    says why). export_folder: the DCASE layout's audio folder prefix. recorded: a format
    real SELD recordings are distributed in, read from ``{export_folder}_dev/`` of a
    recorded dataset (docs/recorded.md). source: where the
    geometry comes from (docs). ambiguity: what the receiver cannot tell apart (docs;
    ``lateral``: it hears only the angle from the median plane, asin(sin φ cos θ), so
    verify judges that). configured: its capsules come from the config (``array.capsules``: custom).
    """

    name: str
    summary: str
    model: str
    layout: Callable
    channel_names: tuple = ()
    patterns: Callable | None = None
    size_key: str = ""
    radius: float = 0.0
    baffle: str = ""
    stereo: tuple = (0, 1)
    level_channels: tuple = ()
    additive: tuple = ()
    convention: str = ""
    aliases: tuple = ()
    base: str = ""
    matrix: tuple = ()
    localizer: str = Localizer.SRP
    unjudged: str = ""
    export_folder: str = "mic"
    recorded: bool = False
    source: str = ""
    ambiguity: str = ""
    configured: bool = False

    @property
    def bankable(self) -> bool:
        """Whether an RIR bank can be simulated for it: one fixed array (a custom array is
        configured per dataset; ears are heard through an HRTF file)."""
        return not self.configured and self.model != ReceiverModel.HRTF

    @property
    def bank_format(self) -> str:
        """The format of the RIR banks this receiver renders from (a mixed receiver's base)."""
        return self.base or self.name

    @property
    def ambisonic(self) -> bool:
        """Whether its channels are first-order ambisonics (a direction reads off their
        intensity vector)."""
        return self.localizer == Localizer.INTENSITY

    @property
    def coincident(self) -> bool:
        """Channels at one point (FOA and what is mixed from it): no spacing to check."""
        return self.model in (ReceiverModel.AMBISONIC, ReceiverModel.MATRIX)

    def positions(self, pose) -> np.ndarray:
        """Capsule positions [C, 3] (m, array frame) of this receiver at ``pose``."""
        return self.layout(pose)

    def channels(self, pose=None, n: int | None = None) -> tuple:
        """Channel names: the fixed ones, else ``mic0 …`` for the pose's (or ``n``) capsules."""
        if self.channel_names:
            return self.channel_names
        count = n if n is not None else len(self.positions(pose))
        return tuple(f"mic{k}" for k in range(count))

    def capsules(self, pose) -> Capsules:
        pos = self.positions(pose)
        if self.patterns is None:
            return Capsules(pos, np.ones(len(pos)), np.zeros((len(pos), 3)))
        alpha, orient = self.patterns(pose)
        return Capsules(pos, np.asarray(alpha, dtype=np.float64), np.asarray(orient, dtype=np.float64))

    def stereo_pair(self, positions=None) -> tuple[int, int] | None:
        """The headphone preview's (left, right) channels, or None when it is a decode
        matrix (:meth:`stereo_matrix`). ``"sides"``: the most +y and the most -y capsule
        of ``positions`` [C, 3] (a spaced pair, heard as a time difference)."""
        s = self.stereo
        if s == "sides":
            pos = np.asarray(positions, dtype=np.float64)
            return int(np.argmax(pos[:, 1])), int(np.argmin(pos[:, 1]))
        if len(s) == 2 and all(isinstance(v, int) for v in s):
            return int(s[0]), int(s[1])
        return None

    def stereo_matrix(self) -> np.ndarray | None:
        """The headphone preview as a decode matrix [2, C], or None for a channel pair."""
        return None if self.stereo == "sides" or self.stereo_pair() is not None else np.asarray(self.stereo)

    def level_slice(self):
        """Index of the level channels (a slice when they are consecutive, for speed)."""
        lc = self.level_channels
        if not lc:
            return slice(None)
        if list(lc) == list(range(lc[0], lc[-1] + 1)):
            return slice(lc[0], lc[-1] + 1)
        return list(lc)

    def mixed(self, base_signals: np.ndarray) -> np.ndarray:
        """Signals [..., C_base, T] of the base receiver as this one's [..., C, T] (the
        ``matrix`` model; others get them back as they are)."""
        if not self.matrix:
            return base_signals
        m = np.asarray(self.matrix, dtype=np.float32)
        return np.einsum("cb,...bt->...ct", m, np.asarray(base_signals, dtype=np.float32))

    def additive_gains(self, n_channels: int) -> np.ndarray:
        return np.ones(n_channels) if not self.additive else np.asarray(self.additive, dtype=np.float64)
