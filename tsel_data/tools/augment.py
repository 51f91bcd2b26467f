"""Channel-swap augmentation with exact label transforms (``tsel_data.augment``).

A symmetry of a receiver is a rotation or reflection R of the array frame that maps the
receiver onto itself: every capsule onto a capsule (with its pattern and axis), or, for
first-order ambisonics, every channel's pickup onto a channel's, up to its sign. Then the
scene the receiver would record with every source at R·u instead of u is the recorded
scene with its channels permuted (and, for FOA, some negated), exactly: no resampling, no
interpolation, the room turned with the sources. Its labels are R applied to the labels.

The candidates are the 16 "audio channel swap" transforms of L. Mazzon, Y. Koizumi, M.
Yasuda, N. Harada ("First order ambisonics domain spatial augmentation for DNN-based
direction of arrival estimation", DCASE 2019): azimuth φ → ±φ + k·90°, elevation θ → ±θ.
Each receiver keeps those that are its symmetries, derived from its spec, not listed by
name (:func:`channel_swaps`):

- ``foa`` (ACN W, Y, Z, X, SN3D): all 16, each a permutation of Y and X with sign flips
  of Y, Z and X (W untouched);
- ``tetra`` (the DCASE MIC format): 8. The tetrahedron keeps the z axis under 8 of its 24
  symmetries (a capsule at elevation +35° must land on one, and every quarter turn moves
  the upper pair onto the lower one), so φ → φ ± 90° comes with θ → -θ and φ → φ + 180°
  without; the other 8 of the 16 move capsules where there are none;
- ``mic4``: the square's 8 (quarter turns and mirrors); θ → -θ changes none of its
  channels (a planar array cannot hear it), so it is not a transform of its own;
- any other receiver: those of the 16 that map its capsules onto themselves (``respeaker-4``
  8, ``respeaker-6`` and ``uma8`` 4, ``linear8`` and the ``stereo`` pair 2: the identity and
  one that swaps left and right); a receiver with no symmetry but the identity (``em32``, whose published
  capsule angles are not exactly symmetric; ``binaural``, a measured head) is refused in
  one line.

Transforms are drawn per (seed, epoch, scene index) (:func:`random_swap`), as the reader's
other per-item draws are, uniformly among the receiver's (the identity included). The
identity returns the audio as it is, bit for bit. The microphones as built
(``[hardware]``) are not symmetric: a swap moves each capsule's mismatch to another channel.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from ..choices import ReceiverModel
from ..core.geometry import sph_to_cart, wrap_azimuth
from ..errors import TselError
from ..receivers import ArrayPose, receiver
from ..store.records import LABEL_DECIMALS, label_list

TOLERANCE = 1e-6  # of the array's size: capsules this close are one place (float32 positions of a scene)
_AXIS_CHANNEL = {0: 3, 1: 1, 2: 2}  # FOA (ACN): x -> X (3), y -> Y (1), z -> Z (2)


@dataclass(frozen=True)
class ChannelSwap:
    """One symmetry: azimuth φ → ``mirror``·φ + ``turn`` (degrees), elevation θ →
    ``flip``·θ; the audio's new channel c is ``signs[c]`` times old channel ``order[c]``."""

    mirror: int
    turn: int
    flip: int
    order: tuple
    signs: tuple

    @property
    def name(self) -> str:
        """``az``, ``az+90``, ``-az+180 -el`` ...: what it does to the labels."""
        az = ("-az" if self.mirror < 0 else "az") + (f"{self.turn:+d}" if self.turn else "")
        return az + (" -el" if self.flip < 0 else "")

    @property
    def identity(self) -> bool:
        return self.mirror == 1 and self.turn == 0 and self.flip == 1

    @property
    def matrix(self) -> np.ndarray:
        """R [3, 3]: the array-frame direction u becomes R u."""
        return _rotation(self.mirror, self.turn, self.flip)

    def audio(self, audio: np.ndarray) -> np.ndarray:
        """The channels [C, T] permuted and signed (the identity: ``audio`` itself)."""
        if self.identity:
            return audio
        out = audio[list(self.order)]
        neg = [c for c, s in enumerate(self.signs) if s < 0]
        if neg:
            out[neg] = -out[neg]
        return out

    def labels(self, azimuth, elevation) -> tuple[np.ndarray, np.ndarray]:
        """Azimuth and elevation (degrees, any shape, NaN kept) as the transformed scene's."""
        az, el = np.asarray(azimuth), np.asarray(elevation)
        if self.identity:
            return az, el
        new_az = wrap_azimuth(self.mirror * az.astype(np.float64) + self.turn).astype(az.dtype)
        return new_az, (el if self.flip > 0 else -el)


def _rotation(mirror: int, turn: int, flip: int) -> np.ndarray:
    c, s = np.rint(np.cos(np.radians(turn))), np.rint(np.sin(np.radians(turn)))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.diag([1.0, float(mirror), float(flip)])


# the 16 candidates, the identity first and those that keep the elevation before those that flip it
CANDIDATES = tuple((m, t, f) for f in (1, -1) for m in (1, -1) for t in (0, 90, 180, -90))


def channel_swaps(fmt: str, mic_positions=None, patterns=None, orientations=None) -> tuple[ChannelSwap, ...]:
    """Every channel-swap symmetry of receiver ``fmt`` (the identity first).

    ``mic_positions`` [C, 3] (array frame): the scene's capsules (a custom array's, a
    mic4 of any side); default the receiver's own layout. ``patterns``, ``orientations``:
    a custom array's capsules' (the record's ``array``), when not all omni.

    Raises
    ------
    TselError
        One line, when the receiver has no symmetry but the identity.
    """
    spec = receiver(fmt)
    if spec.model == ReceiverModel.HRTF:
        raise TselError(f"channel swap: {spec.name} has no channel-swap symmetry: a measured head is not exactly "
                        f"symmetric, so swapping the ears would not be the scene mirrored")
    if mic_positions is None and not spec.configured:
        mic_positions = spec.positions(ArrayPose(spec.name, (0.0, 0.0, 0.0), 0.0, 0.1 if spec.size_key else None))
    if mic_positions is None:
        raise TselError(f"channel swap: a {spec.name} array's symmetries follow from its capsules: give "
                        f"mic_positions (the scene's)")
    key = (spec.name, _frozen(mic_positions), _frozen(patterns), _frozen(orientations))
    return _swaps(*key)


def _frozen(v):
    """A hashable copy of positions, patterns or orientations (for the cache)."""
    if v is None:
        return None
    if len(v) and isinstance(v[0], str):
        return tuple(v)
    return tuple(tuple(float(x) for x in row) for row in np.asarray(v, dtype=np.float64).reshape(len(v), -1))


@lru_cache(maxsize=64)
def _swaps(name: str, positions, patterns, orientations) -> tuple[ChannelSwap, ...]:
    spec = receiver(name)
    found: list[ChannelSwap] = []
    seen = set()
    for mirror, turn, flip in CANDIDATES:
        op = _channel_op(spec, _rotation(mirror, turn, flip), positions, patterns, orientations)
        if op is None:
            continue
        order, signs = op
        identity = (mirror, turn, flip) == (1, 0, 1)
        if (order, signs) in seen:
            continue  # the channels cannot tell it from one found already (e.g. θ → -θ to a planar array)
        seen.add((order, signs))
        if not identity and order == tuple(range(len(order))) and all(s > 0 for s in signs):
            continue
        found.append(ChannelSwap(mirror, turn, flip, order, signs))
    if len(found) < 2:
        raise TselError(f"channel swap: {name} has no channel-swap symmetry besides the identity (none of the 16 "
                        f"quarter turns and mirrors maps its capsules onto themselves); train without channel_swap")
    return tuple(found)


def _channel_op(spec, R: np.ndarray, positions, patterns, orientations):
    """(order, signs) with new channel c = signs[c] · old channel order[c] for the scene with
    every source at R u, or None when R is not a symmetry of the receiver."""
    if spec.model == ReceiverModel.AMBISONIC:
        return _ambisonic_op(R)
    if spec.model == ReceiverModel.MATRIX:
        base = _ambisonic_op(R) if receiver(spec.base).model == ReceiverModel.AMBISONIC else None
        return None if base is None else _mixed_op(np.asarray(spec.matrix, dtype=np.float64), base)
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    size = max(float(np.abs(pos).max()), 1e-9)
    # new channel c hears what the capsule at R^T p_c heard: find it
    moved = pos @ R  # rows: R^T p_c
    dist = np.linalg.norm(moved[:, None, :] - pos[None, :, :], axis=-1)
    order = np.argmin(dist, axis=1)
    if dist[np.arange(len(pos)), order].max() > TOLERANCE * size or len(set(order.tolist())) != len(pos):
        return None
    if patterns is not None and any(p != "omni" for p in patterns):
        axes = np.asarray(_axes(orientations), dtype=np.float64)
        if any(patterns[o] != patterns[c] for c, o in enumerate(order)) \
                or np.abs(axes @ R - axes[order]).max() > TOLERANCE:
            return None
    return tuple(int(o) for o in order), (1,) * len(pos)


def _axes(orientations) -> np.ndarray:
    az, el = np.asarray(orientations, dtype=np.float64).reshape(-1, 2).T
    return sph_to_cart(az, el, 1.0)


def _ambisonic_op(R: np.ndarray):
    """W stays; Y', Z', X' are the pickups of R u: row a of R picks one axis b with a sign."""
    order, signs = [0, 0, 0, 0], [1, 1, 1, 1]
    for a in range(3):
        b = int(np.argmax(np.abs(R[a])))
        order[_AXIS_CHANNEL[a]], signs[_AXIS_CHANNEL[a]] = _AXIS_CHANNEL[b], int(np.sign(R[a, b]))
    return tuple(order), tuple(signs)


def _mixed_op(M: np.ndarray, base):
    """Channels mixed from a base receiver (M [C, C_base]): the swap P of its channels with
    M · S = P · M (S the base's), or None when there is none."""
    S = np.zeros((M.shape[1], M.shape[1]))
    for c, (o, s) in enumerate(zip(*base)):
        S[c, o] = s
    P = np.round(M @ S @ np.linalg.pinv(M), 9)
    if not np.allclose(M @ S, P @ M, atol=1e-9) or not np.all(np.isin(np.abs(P), (0.0, 1.0))) \
            or not np.all(np.abs(P).sum(axis=1) == 1) or not np.all(np.abs(P).sum(axis=0) == 1):
        return None
    order = tuple(int(np.argmax(np.abs(row))) for row in P)
    return order, tuple(int(P[c, o]) for c, o in enumerate(order))


def scene_swaps(scene) -> tuple[ChannelSwap, ...]:
    """The symmetries of the receiver that recorded ``scene`` (its capsules as the scene has them)."""
    if scene.record is None and receiver(scene.format).configured:
        raise TselError(f"channel swap: {scene.scene_id}: a {scene.format} array's symmetries depend on its capsules' "
                        f"patterns, which are in the scene's record: read it with records (with_record=True)")
    arr = scene.record.receiver(scene.format) if scene.record is not None else None
    return channel_swaps(scene.format, scene.mic_positions, getattr(arr, "patterns", None),
                         getattr(arr, "orientations", None))


def swap_scene(scene, swap: ChannelSwap):
    """``scene`` as recorded with every source at R u: its channels swapped, its labels
    (and its record's) transformed; further receivers' audio is dropped (their symmetries
    are their own). ``Scene.channel_swap`` names the transform; the identity keeps the
    scene's arrays as they are."""
    if swap.identity:
        return replace(scene, channel_swap=swap.name)
    az, el = swap.labels(scene.azimuth, scene.elevation)
    record = scene.record
    if record is not None:
        sources = tuple(replace(src, azimuth=label_list(az[k], LABEL_DECIMALS["azimuth"]),
                                elevation=label_list(el[k], LABEL_DECIMALS["elevation"]))
                        for k, src in enumerate(record.sources))
        record = replace(record, sources=sources)
    return replace(scene, audio=swap.audio(scene.audio) if scene.audio is not None else None, azimuth=az,
                   elevation=el, record=record, receivers=None, channel_swap=swap.name)


def random_swap(scene, seed: int, epoch: int, index: int):
    """(the scene through one of its receiver's symmetries, that symmetry), drawn uniformly
    per (seed, epoch, index): the same item of the same epoch gets the same transform
    whatever the worker or the order items are read in."""
    swaps = scene_swaps(scene)
    swap = swaps[int(np.random.default_rng([seed, epoch, index, 2]).integers(len(swaps)))]
    return swap_scene(scene, swap), swap


__all__ = ["CANDIDATES", "ChannelSwap", "channel_swaps", "random_swap", "scene_swaps", "swap_scene"]
