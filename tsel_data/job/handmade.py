"""One scene by hand, from Python: "the target at 30°, 2 m, this clip; an interferer at
−60°, that clip; this room" — for figures, listening tests and unit tests of a model.

>>> from tsel_data.handmade import Event, build_scene
>>> recipe, scene = build_scene([Event("dog.wav", "a dog barks", azimuth=30, distance=2),
...                              Event("rain.wav", azimuth=-60, distance=3, tir_db=-6)],
...                             room=(6, 5, 3), rt60=0.4, receiver="foa", duration=4)

Positions are given as the labels state them: azimuth and elevation in degrees and
distance in metres in the array frame (docs/format.md: x front, y left, z up; azimuth
counter-clockwise from the front). The recipe is an ordinary one (every file it names an
absolute path), so the scene is what a dataset's scene would be: the same renderer,
labels, record and checks, and :func:`~tsel_data.job.stems.render_stems`,
:func:`~tsel_data.tools.inspect.inspect_scene` and :func:`write_scenes` (a dataset folder
every tool and reader opens) take it as they take a dataset's.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from ..choices import Role, Scenario
from ..config import Config, SplitConfig
from ..config.receiver import array_pose
from ..core.geometry import Room, array_to_room, sph_to_cart
from ..errors import ConfigError, GeometryError
from ..render.scenes import render_recipe
from ..scene.recipe import SceneRecipe, Source
from ..store.dataset import dataset_doc, shard_attrs
from ..store.layout import Layout
from ..store.scene import Scene
from ..store.writer import write_shard
from ..core.atomic import write_json
from .pipeline import check_ownership


@dataclass(frozen=True)
class Event:
    """One sound event of a hand-made scene (the first of a scene's events is the target).

    clip: an audio file (any format soundfile reads). caption: what the event is, one
    caption or several (the target's first is the scene's query; an interferer may have
    none). azimuth, elevation: degrees, distance: metres, in the array frame, where the
    event is for the whole scene; or ``path``: ``[(t s, azimuth, elevation, distance),
    ...]`` knots of a moving event, linearly interpolated in the room. start: seconds into
    the scene where the clip starts; offset: seconds into the clip. tir_db: an
    interferer's level against the target at the array (dB).
    """

    clip: str
    caption: str | Sequence[str] = ()
    azimuth: float = 0.0
    elevation: float = 0.0
    distance: float = 2.0
    path: Sequence[tuple[float, float, float, float]] = ()
    start: float = 0.0
    offset: float = 0.0
    tir_db: float = 0.0

    @property
    def captions(self) -> tuple[str, ...]:
        return (self.caption,) if isinstance(self.caption, str) else tuple(self.caption)


def scene_recipe(events: Sequence[Event], room: Sequence[float] = (6.0, 5.0, 3.0), rt60: float = 0.5,
                 receiver: str = "foa", position: Sequence[float] | None = None, yaw: float = 0.0,
                 duration: float = 10.0, fs: int = 24000, seed: int = 0, rir_method: str = "hybrid",
                 side: float = 0.1, hrtf: str | None = None, receivers: Sequence[str] = (),
                 label_hop: float = 0.1, target_level_dbfs: float = -25.0, wall_margin: float = 0.2,
                 scene_id: str = "handmade-000000", descriptors: bool = True) -> SceneRecipe:
    """The recipe of one scene: ``events`` (the first is the target) in a shoebox ``room``
    ((length, width, height) m, ``rt60`` s), heard by ``receiver`` (any receiver name,
    ``tsel presets``; ``hrtf``: a binaural receiver's SOFA file; ``side``: mic4's side,
    m) at ``position`` (room frame, m; default the room's middle at 1.5 m, or half its
    height when lower) turned by ``yaw`` degrees, and by ``receivers`` at the same place.
    ``seed`` draws what the simulator draws (the late tail's noise); ``descriptors``: the
    record gets each event's DRR, C50, T30 and motion class. Raises a one-line
    ConfigError or GeometryError for what cannot be built (a clip not there, an event
    outside the room or within ``wall_margin`` m of a wall, a target without caption).
    """
    if not events:
        raise ConfigError("a scene needs at least one event: its target (the first)")
    if not events[0].captions or not events[0].captions[0].strip():
        raise ConfigError("the target (the first event) needs a caption: it is the scene's query")
    dims = tuple(float(v) for v in room)
    if len(dims) != 3 or min(dims) <= 0:
        raise GeometryError(f"room {tuple(room)}: give (length, width, height) in metres, all above 0")
    centre = tuple(float(v) for v in position) if position is not None else (dims[0] / 2, dims[1] / 2,
                                                                              min(1.5, dims[2] / 2))
    cfg = Config()
    cfg = replace(cfg, scene=replace(cfg.scene, format=receiver, receivers=tuple(receivers)))
    if hrtf:
        cfg = replace(cfg, array=replace(cfg.array, hrtf=os.path.abspath(hrtf)))
    poses = [array_pose(cfg, centre, float(yaw), side, hrtf=os.path.abspath(hrtf) if hrtf else None, fmt=name)
             for name in (receiver, *receivers)]
    sources = tuple(_source(k, e, centre, float(yaw)) for k, e in enumerate(events))
    for k, (e, s) in enumerate(zip(events, sources)):
        for p in s.room_points():
            if any(v < wall_margin - 1e-9 or v > d - wall_margin + 1e-9 for v, d in zip(p, dims)):
                at = "a point of its path" if e.path else f"azimuth {e.azimuth:g}°, elevation {e.elevation:g}°, {e.distance:g} m"
                raise GeometryError(f"event {k} ({at} from the array at {list(centre)}) is at "
                                    f"{[round(v, 2) for v in p]}, outside the room {list(dims)} or within "
                                    f"{wall_margin:g} m of a wall; bring it closer, or move the array (position=)")
    recipe = SceneRecipe(scene_id=scene_id, split="handmade", index=0, seed=int(seed),
                         scenario=Scenario.TWO_DIRECTIONAL,  # every event directional, however many
                         query=sources[0].captions[0], array=poses[0], sources=sources, room=Room(dims, float(rt60)),
                         fs=int(fs), duration=float(duration), label_hop=float(label_hop), rir_method=rir_method,
                         target_level_dbfs=float(target_level_dbfs), receivers=tuple(poses[1:]),
                         descriptors=bool(descriptors))
    return recipe.validate(wall_margin)


def _source(k: int, e: Event, centre, yaw: float) -> Source:
    clip = os.path.abspath(os.path.expanduser(os.fspath(e.clip)))
    if not os.path.isfile(clip):
        raise ConfigError(f"event {k}: clip {e.clip} not found; give the path of an audio file")
    where = {}
    if e.path:
        knots = sorted((float(t), *_room_point(az, el, d, centre, yaw)) for t, az, el, d in e.path)
        where["path"] = tuple(tuple(round(v, 9) for v in knot) for knot in knots)
    else:
        where["position"] = _room_point(e.azimuth, e.elevation, e.distance, centre, yaw)
    return Source(role=Role.TARGET if k == 0 else Role.INTERFERER, clip_id=os.path.splitext(os.path.basename(clip))[0],
                  audio=clip, captions=e.captions, offset=float(e.offset), start=float(e.start),
                  tir_db=None if k == 0 else float(e.tir_db), **where)


def _room_point(az, el, dist, centre, yaw: float) -> tuple[float, float, float]:
    if not float(dist) > 0:
        raise GeometryError(f"distance {dist}: an event is more than 0 m from the array")
    p = array_to_room(sph_to_cart(float(az), float(el), float(dist)), np.asarray(centre), yaw)
    return tuple(round(float(v), 9) for v in p)


def build_scene(events: Sequence[Event], **room_and_receiver) -> tuple[SceneRecipe, Scene]:
    """:func:`scene_recipe` and its rendered :class:`~tsel_data.store.scene.Scene`
    (``audio`` [C, T], labels [S, F] per event, ``record``)."""
    recipe = scene_recipe(events, **room_and_receiver)
    return recipe, render_recipe(recipe)


def write_scenes(out_dir: str, built: Sequence[tuple[SceneRecipe, Scene]], split: str = "test",
                 force: bool = False) -> str:
    """Write hand-made scenes (``build_scene``'s pairs, one receiver set, rate and hop for
    all) as a dataset of one split, one shard: ``tsel inspect``, ``stats``, ``verify``,
    ``eval`` and :func:`~tsel_data.open_dataset` read it as any. ``out_dir`` must be new
    or empty, or a dataset this wrote (``force``: any folder). Returns ``out_dir``."""
    if not built:
        raise ConfigError("no scenes to write")
    first = built[0][0]
    for recipe, _ in built:
        if (recipe.fs, recipe.label_hop, recipe.array.format, [a.format for a in recipe.receivers]) != \
                (first.fs, first.label_hop, first.array.format, [a.format for a in first.receivers]):
            raise ConfigError(f"{recipe.scene_id}: every scene of a dataset has the same receivers, rate and label "
                              f"hop; this one differs from {first.scene_id}")
    layout = Layout(out_dir)
    check_ownership(layout, force)
    attrs = shard_attrs(first.fs, first.label_hop, first.array.format, "float32", list(first.array.channel_names()),
                        {a.format: list(a.channel_names()) for a in first.receivers})
    scenes = [_renamed(scene, f"{split}-{k:06d}", split, k) for k, (_, scene) in enumerate(built)]
    entry = write_shard(out_dir, split, 0, scenes, attrs)
    cfg = Config(name="handmade")
    # what the tools read of a dataset's config: its receivers, rate, length and hop
    cfg = replace(cfg, scene=replace(cfg.scene, format=first.array.format,
                                     receivers=tuple(a.format for a in first.receivers)),
                  audio=replace(cfg.audio, fs=first.fs, duration=max(r.duration for r, _ in built),
                                label_hop=first.label_hop, target_level_dbfs=first.target_level_dbfs),
                  splits={split: SplitConfig(count=len(built))})
    write_json(layout.dataset_file, dataset_doc(cfg.to_dict(), 0, attrs, {split: [entry]}))
    return out_dir


def _renamed(scene: Scene, scene_id: str, split: str, index: int) -> Scene:
    """The scene as the dataset's ``index``-th of ``split`` (its record says the same)."""
    record = None if scene.record is None else replace(scene.record, scene_id=scene_id, split=split, index=index)
    return replace(scene, scene_id=scene_id, split=split, index=index, record=record)
