"""The scene sampler: (config, split, index, clip catalog) -> SceneRecipe.

Every random choice of scene ``index`` in ``split`` comes from one generator seeded by
``(dataset seed, crc32(split), index)``, so a scene does not depend on any other scene,
on the order scenes are planned in, or on how many workers plan them.
"""
from __future__ import annotations

import math
import zlib

import numpy as np

from .captions import max_similarity, tokens
from .clip import Clip
from .config import Config
from .errors import GeometryError, TselError
from .recipe import ArrayPose, Room, SceneRecipe, Source

MAX_TRIES = 200


class CatalogView:
    """A split's clips with their caption tokens precomputed (shared by every scene)."""

    def __init__(self, clips: list[Clip]):
        if len(clips) < 2:
            raise TselError(f"a split needs at least 2 usable clips to make scenes, it has {len(clips)}")
        self.clips = clips
        self.tokens = [tuple(tokens(c) for c in clip.captions) for clip in clips]
        # clips cut from the same recording (AudioCaps: same YouTube video) are one sound source
        self.source_key = [c.meta.get("youtube_id") or c.audio for c in clips]


def scene_rng(seed: int, split: str, index: int) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(split.encode("utf-8")), index])


def plan_split(cfg: Config, split: str, catalog: CatalogView, start: int = 0, stop: int | None = None) -> list[SceneRecipe]:
    stop = cfg.splits[split].count if stop is None else stop
    return [plan_scene(cfg, split, i, catalog) for i in range(start, stop)]


def plan_scene(cfg: Config, split: str, index: int, cat: CatalogView) -> SceneRecipe:
    rng = scene_rng(cfg.seed, split, index)
    sc = cfg.scene
    scenario = sc.scenario.sample(rng)
    n_int = int(sc.interferers.sample(rng))

    t = int(rng.integers(len(cat.clips)))
    q = int(rng.integers(len(cat.clips[t].captions)))
    query = cat.clips[t].captions[q]
    chosen = [t]
    for _ in range(n_int):
        chosen.append(_pick_interferer(rng, cat, chosen, cat.tokens[t][q], sc.caption_similarity, split, index))

    spatial = ["directional"] + ["additive" if (scenario == "directional+additive" and k == 0) else "directional"
                                 for k in range(n_int)]
    tir = [None] + [float(sc.tir_db.sample(rng)) for _ in range(n_int)]
    room, array, positions = _place(cfg, rng, spatial, split, index)
    sources = []
    for k, ci in enumerate(chosen):
        clip = cat.clips[ci]
        sources.append(Source(
            role="target" if k == 0 else "interferer", clip_id=clip.id, audio=clip.audio,
            captions=clip.captions, spatial=spatial[k], offset=clip.offset,
            position=None if positions[k] is None else tuple(round(float(v), 6) for v in positions[k]),
            tir_db=None if tir[k] is None else round(tir[k], 4),
        ))
    a = cfg.audio
    recipe = SceneRecipe(
        scene_id=f"{split}-{index:06d}", split=split, index=index, seed=int(rng.integers(2**31 - 1)),
        scenario=scenario, query=query, array=array, sources=tuple(sources), room=room,
        fs=a.fs, duration=a.duration, label_hop=a.label_hop, rir_method=cfg.room.rir_method,
        target_level_dbfs=a.target_level_dbfs, activity_threshold_db=a.activity_threshold_db,
    )
    return recipe.validate(wall_margin=cfg.sources.wall_margin - 1e-6)


def _pick_interferer(rng, cat: CatalogView, chosen: list[int], query_tokens, max_sim: float, split, index) -> int:
    taken = {cat.source_key[i] for i in chosen}
    for _ in range(MAX_TRIES):
        j = int(rng.integers(len(cat.clips)))
        if j in chosen or cat.source_key[j] in taken:
            continue
        if max_similarity(query_tokens, cat.tokens[j]) > max_sim:
            continue
        return j
    raise TselError(
        f"scene {split}/{index}: no interferer found whose captions differ from the query "
        f"after {MAX_TRIES} tries; raise scene.caption_similarity (now {max_sim}) or add clips"
    )


def _place(cfg: Config, rng, spatial: list[str], split: str, index: int):
    """Room, array pose and room-frame positions (None for additive sources)."""
    rc, ac, srcc = cfg.room, cfg.array, cfg.sources
    fmt = cfg.scene.format
    dims = (float(rc.length.sample(rng)), float(rc.width.sample(rng)), float(rc.height.sample(rng)))
    room = Room(tuple(round(d, 4) for d in dims), round(float(rc.rt60.sample(rng)), 4))
    side = round(float(ac.side.sample(rng)), 5) if fmt == "mic4" else None
    yaw = round(float(ac.yaw.sample(rng)), 4)
    for _ in range(MAX_TRIES // 10):
        centre = (
            float(rng.uniform(ac.wall_margin, room.dims[0] - ac.wall_margin)),
            float(rng.uniform(ac.wall_margin, room.dims[1] - ac.wall_margin)),
            float(min(ac.height.sample(rng), room.dims[2] - 0.1)),
        )
        centre = tuple(round(c, 5) for c in centre)
        positions = _place_sources(cfg, rng, spatial, room, centre, yaw)
        if positions is not None:
            return room, ArrayPose(fmt, centre, yaw, side), positions
    raise GeometryError(
        f"scene {split}/{index}: could not place {len(spatial)} sources {srcc.distance.to_json()} m from the "
        f"array, {cfg.scene.min_separation}° apart, in a {room.dims} m room; widen sources.distance, "
        f"lower scene.min_separation or the wall margins"
    )


def _place_sources(cfg, rng, spatial, room: Room, centre, yaw):
    srcc, m = cfg.sources, cfg.sources.wall_margin
    dims = room.dims
    placed_az: list[float] = []
    out = []
    for sp in spatial:
        if sp == "additive":
            out.append(None)
            continue
        for _ in range(MAX_TRIES // 4):
            d = float(srcc.distance.sample(rng))
            h = float(srcc.height.sample(rng))
            dz = h - centre[2]
            if abs(dz) >= d:
                continue
            az = float(rng.uniform(-180.0, 180.0))
            if any(_sep(az, p) < cfg.scene.min_separation for p in placed_az):
                continue
            # array frame -> room frame by hand: numpy per point is slower than the maths
            r_h = math.sqrt(d * d - dz * dz)
            a = math.radians(az + yaw)
            p = (centre[0] + r_h * math.cos(a), centre[1] + r_h * math.sin(a), h)
            if all(m <= p[k] <= dims[k] - m for k in range(3)):
                placed_az.append(az)
                out.append(p)
                break
        else:
            return None
    return out


def _sep(a: float, b: float) -> float:
    d = (a - b) % 360.0
    return min(d, 360.0 - d)


_WORKER_STATE: dict = {}


def _init_planner(cfg, split, cat):
    _WORKER_STATE.update(cfg=cfg, split=split, cat=cat)


def _plan_chunk(bounds: tuple[int, int]) -> list[str]:
    st = _WORKER_STATE
    return [plan_scene(st["cfg"], st["split"], i, st["cat"]).to_json() for i in range(*bounds)]


def plan_split_json(cfg: Config, split: str, cat: CatalogView, workers: int = 1, chunk: int = 4000) -> list[str]:
    """JSON lines of a split's recipes, planned on ``workers`` processes.

    Scenes are independent, so the result is the same for any number of workers.
    """
    n = cfg.splits[split].count
    bounds = [(a, min(a + chunk, n)) for a in range(0, n, chunk)]
    if workers <= 1 or len(bounds) <= 1:
        _init_planner(cfg, split, cat)
        return [line for b in bounds for line in _plan_chunk(b)]
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(workers, initializer=_init_planner, initargs=(cfg, split, cat)) as ex:
        return [line for lines in ex.map(_plan_chunk, bounds) for line in lines]
