"""The scene sampler: (config, split, index, clip catalog) -> SceneRecipe.

Every random choice of scene ``index`` in ``split`` comes from one generator seeded by
``(dataset seed, crc32(split), index)``, so a scene does not depend on any other scene,
on the order scenes are planned in, or on how many workers plan them.

This module samples only: which bank file a dataset uses and which rooms a split may
draw is decided in :mod:`tsel_data.banks.scenes`.
"""
from __future__ import annotations

import math
import os
import zlib
from dataclasses import dataclass
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from .banks.paths import sample_bank_path, sample_bank_point
from .banks.scenes import BUILTIN_DEMO_BANK, BankRequest, open_bank_cached, resolve_bank, split_rooms
from .captions import CaptionIndex, load_embeddings, max_similarity, tokens
from .catalog import BUILTIN_DEMO, MIN_CLIPS, CatalogScan, build_catalog, resolve_corpus_dir
from .choices import Motion, Pairing, QueryType, Relation, Role, Scenario, SimilarityMeasure, Spatial
from .clip import Clip
from .config import Config, rooms_without_bank
from .errors import GeometryError, TselError
from .geometry import ArrayPose, Room, frame_centres, interpolate_positions, wrap_azimuth
from .recipe import BankRef, BankWalk, QueryPlan, Roots, SceneRecipe, Source
from .store.layout import Layout

MAX_TRIES = 200


class CatalogView:
    """A split's clips with their caption tokens precomputed (shared by every scene), and
    the resolved path of the RIR bank when scenes use one."""

    def __init__(self, clips: list[Clip], bank_path: str | None = None, roots: Roots | None = None):
        if len(clips) < MIN_CLIPS:
            raise TselError(f"a split needs at least {MIN_CLIPS} usable clips to make scenes, it has {len(clips)}")
        self.clips = clips
        self.tokens = [tuple(tokens(c) for c in clip.captions) for clip in clips]
        # clips cut from the same recording (AudioCaps: same YouTube video) are one sound source
        self.source_key = [c.meta.get("youtube_id") or c.audio for c in clips]
        self.bank_path = bank_path
        # recipes name their files relative to these (absolute paths without them)
        self.roots = roots or Roots()
        self._indexes: dict = {}

    def caption_index(self, measure: str, embeddings: str = "") -> CaptionIndex:
        """The split's captions under ``measure``, built once per view (a few seconds for
        50k captions; :func:`prepare_views` builds the config's before workers start)."""
        key = (measure, embeddings)
        if key not in self._indexes:
            vectors = load_embeddings(embeddings) if measure == SimilarityMeasure.EMBEDDINGS else None
            self._indexes[key] = CaptionIndex([c.captions for c in self.clips], measure, vectors,
                                              where=f"corpus.caption_embeddings {embeddings}")
        return self._indexes[key]

    @property
    def source_ids(self) -> np.ndarray:
        """Each clip's sound source as an integer (clips of one recording share it)."""
        if "_source_ids" not in self.__dict__:
            ids: dict = {}
            self._source_ids = np.array([ids.setdefault(k, len(ids)) for k in self.source_key], dtype=np.int64)
        return self._source_ids


def prepare_views(cfg: Config, home: Layout, workers: int = 1,
                  progress: bool | None = None) -> tuple[CatalogScan, dict[str, CatalogView]]:
    """Everything planning needs besides the config: the checked catalog and, per split
    that makes scenes, its :class:`CatalogView` (clips, and the resolved bank).

    ``home`` is where built-in inputs are made once (``builtin:demo`` corpus,
    ``builtin:demo-bank``): the dataset folder for ``tsel generate``. ``progress``: bars
    while clips are checked (None: on a terminal). Raises the first problem of the
    corpus or the bank.
    """
    problem = rooms_without_bank(cfg)
    if problem:
        raise problem
    corpus_dir = resolve_corpus_dir(cfg, home.demo_corpus)
    catalog = build_catalog(cfg, corpus_dir, workers=workers, progress=progress)
    bank_path = resolve_bank(bank_request(cfg), home.demo_bank)
    roots = plan_roots(cfg, home)
    views = {split: CatalogView(clips, bank_path, roots) for split, clips in catalog.clips.items()}
    if extended_queries(cfg):
        for split in cfg.active_splits():
            if split in views:
                views[split].caption_index(cfg.scene.similarity, cfg.corpus.caption_embeddings)
    return catalog, views


def plan_roots(cfg: Config, home: Layout) -> Roots:
    """Where the files of ``cfg``'s recipes are on this machine: the corpus folder and the
    RIR bank (the built-in ones in ``home``, the dataset folder)."""
    corpus = home.demo_corpus if cfg.corpus.dir == BUILTIN_DEMO else cfg.corpus.dir
    bank = home.demo_bank if cfg.room.bank == BUILTIN_DEMO_BANK else cfg.room.bank
    return Roots(os.path.abspath(os.path.expanduser(corpus)) if corpus else "",
                 os.path.abspath(os.path.expanduser(bank)) if bank else "")


def bank_request(cfg: Config) -> BankRequest:
    """What the config asks of its RIR bank (plain values for :mod:`tsel_data.banks.scenes`)."""
    return BankRequest(cfg.room.bank, cfg.scene.format, cfg.audio.fs, cfg.rooms_by_split(), cfg.active_splits())


def scene_rng(seed: int, split: str, index: int, stream: int = 0) -> np.random.Generator:
    """The generator of every draw of scene ``index`` of ``split``.

    Streams 1 (query decisions: the query type, same-kind draws, the relation order and
    wording) and 2 (each source's start, ``scene.onset``) are independent generators of
    the same scene, so they never shift the draws of stream 0 (clips, levels, room,
    placement) that earlier releases made.
    """
    key = [seed, zlib.crc32(split.encode("utf-8")), index]
    return np.random.default_rng(key if stream == 0 else key + [stream])


def extended_queries(cfg: Config) -> bool:
    """Whether the config uses queries beyond today's (a caption, random pairing, word
    similarity): then recipes carry a QueryPlan and records the query fields."""
    sc = cfg.scene
    return (set(sc.query.options) != {QueryType.CAPTION} or sc.pairing != Pairing.RANDOM
            or sc.same_kind_distractors > 0 or sc.similarity != SimilarityMeasure.WORDS)


def plan_scene(cfg: Config, split: str, index: int, cat: CatalogView) -> SceneRecipe:
    """The recipe of scene ``index`` of ``split``.

    Draws, in order, from :func:`scene_rng`: scenario, interferer count, the target clip
    and the caption used as the query, interferers whose captions are not too similar
    to the query (``scene.caption_similarity``), TIRs, then the room, array and source
    placement (simulated rooms) or the bank room and each source's walk.

    With extended queries (:func:`extended_queries`; docs/queries.md) interferers are
    paired by ``scene.pairing`` and may be same-kind distractors, and the recipe gets a
    :class:`~tsel_data.recipe.QueryPlan` from which the renderer decides the query;
    the query's own draws and the sources' starts (``scene.onset``) come from separate
    streams of the same scene.

    Parameters
    ----------
    cfg : Config
        The dataset config.
    split : str
        Split name (seeds the scene's generator with ``index``).
    index : int
        Scene index within the split.
    cat : CatalogView
        The split's usable clips, and the resolved bank path for bank scenes.

    Returns
    -------
    SceneRecipe
        Validated (every point inside its room with the wall margins).

    Raises
    ------
    TselError, GeometryError
        No interferer or placement satisfies the constraints within the tries allowed.
    """
    rng = scene_rng(cfg.seed, split, index)
    sc = cfg.scene
    scenario = sc.scenario.sample(rng)
    n_int = int(sc.interferers.sample(rng))

    t = int(rng.integers(len(cat.clips)))
    q = int(rng.integers(len(cat.clips[t].captions)))
    query = cat.clips[t].captions[q]
    chosen = [t]
    pairs = None
    if extended_queries(cfg):
        pairs = _QueryDraws(cfg, split, index, cat, t, q)
        for k in range(n_int):
            chosen.append(pairs.pick(rng, chosen, same_kind=pairs.wants_same_kind(k, n_int)))
    else:
        for _ in range(n_int):
            chosen.append(_pick_interferer(rng, cat, chosen, cat.tokens[t][q], sc.caption_similarity, split, index))

    additive = Spatial.DIFFUSE if sc.additive == "diffuse" else Spatial.ADDITIVE
    spatial = [Spatial.DIRECTIONAL] + [
        additive if (scenario == Scenario.DIRECTIONAL_ADDITIVE and k == 0) else Spatial.DIRECTIONAL
        for k in range(n_int)]
    tir = [None] + [float(sc.tir_db.sample(rng)) for _ in range(n_int)]
    if pairs is not None:
        tir = pairs.separate_levels(tir)
    if cat.bank_path:
        room, array, places, bank = _place_bank(cfg, rng, spatial, split, index, cat.bank_path)
        bank = BankRef(cat.roots.relative_bank(bank.path), bank.room)
    else:
        (room, array, places), bank = _place(cfg, rng, spatial, split, index), None
    starts = _starts(cfg, split, index, len(chosen))
    sources = []
    for k, ci in enumerate(chosen):
        clip = cat.clips[ci]
        sources.append(Source(
            role=Role.TARGET if k == 0 else Role.INTERFERER, clip_id=clip.id, audio=cat.roots.relative_clip(clip.audio),
            captions=clip.captions, spatial=spatial[k], offset=clip.offset,
            tir_db=None if tir[k] is None else round(tir[k], 4), start=starts[k], **(places[k] or {}),
        ))
    a = cfg.audio
    recipe = SceneRecipe(
        scene_id=f"{split}-{index:06d}", split=split, index=index, seed=int(rng.integers(2**31 - 1)),
        scenario=scenario, query=query, array=array, sources=tuple(sources), room=room,
        fs=a.fs, duration=a.duration, label_hop=a.label_hop,
        rir_method="bank" if cat.bank_path else cfg.room.rir_method,
        target_level_dbfs=a.target_level_dbfs, activity_threshold_db=a.activity_threshold_db, bank=bank,
        query_plan=None if pairs is None else pairs.plan(chosen),
    )
    return recipe.validate(wall_margin=cfg.sources.wall_margin - 1e-6)


# Same-kind distractors get |TIR| >= margin_level + this, so the loudness relation holds
# on the rendered levels with room to spare (they follow the recipe's TIR to ~1e-6 dB).
LEVEL_SLACK_DB = 0.5


class _QueryDraws:
    """The query side of one scene (configs with extended queries): interferers paired
    by caption similarity, same-kind distractors, their levels, and the QueryPlan.

    Clips are drawn from the scene's main generator, as before; everything else about
    the query from its second stream (:func:`scene_rng` stream 1).
    """

    def __init__(self, cfg: Config, split: str, index: int, cat: CatalogView, t: int, q: int):
        self.cfg, self.sc, self.split, self.index, self.cat = cfg, cfg.scene, split, index, cat
        self.qrng = scene_rng(cfg.seed, split, index, stream=1)
        self.wanted = str(self.sc.query.sample(self.qrng))
        self.ix = cat.caption_index(self.sc.similarity, cfg.corpus.caption_embeddings)
        self.t, self.cap = t, self.ix.caption_id(t, q)
        self.pairings: list = [None]

    def wants_same_kind(self, k: int, n_int: int) -> bool:
        # a composite query needs a second source its caption fits: the last interferer
        # (directional unless it is a directional+additive scene's only one); any
        # interferer with probability scene.same_kind_distractors
        p = self.sc.same_kind_distractors
        drawn = bool(self.qrng.random() < p) if p > 0 else False
        return drawn or (self.wanted == QueryType.COMPOSITE and k == n_int - 1)

    def pick(self, rng, chosen: list[int], same_kind: bool) -> int:
        sc, ix, cat = self.sc, self.ix, self.cat
        taken = cat.source_ids[chosen]

        def allowed(clips):
            # a clip of a recording already in the scene (the chosen clips among them) is not another source
            return (cat.source_ids[clips][:, None] != taken[None, :]).all(axis=1)

        if same_kind:
            j = ix.sample(rng, self.cap, sc.same_kind_similarity, np.inf, allowed)
            if j is not None:
                self.pairings.append("same-kind")
                return j
        if sc.pairing != Pairing.RANDOM:
            lo, hi = ((sc.hard_similarity, sc.caption_similarity) if sc.pairing == Pairing.HARD
                      else (-np.inf, sc.easy_similarity))
            j = ix.sample(rng, self.cap, lo, hi, allowed)
            if j is not None:
                self.pairings.append(str(sc.pairing))
                return j
        # random pairing, and the fallback of a band the split cannot fill
        for _ in range(MAX_TRIES):
            j = int(rng.integers(len(cat.clips)))
            if j in chosen or cat.source_ids[j] in taken or ix.clip_sim(self.cap, j) > sc.caption_similarity:
                continue
            self.pairings.append(Pairing.RANDOM.value)
            return j
        raise TselError(
            f"scene {self.split}/{self.index}: no interferer found whose captions differ from the query "
            f"after {MAX_TRIES} tries; raise scene.caption_similarity (now {sc.caption_similarity}) or add clips")

    def separate_levels(self, tir: list) -> list:
        """Same-kind distractors all on one side of the target, by at least the level
        margin plus slack, so "the louder / quieter of the ..." is true when rendered."""
        same = [k for k, p in enumerate(self.pairings) if p == "same-kind"]
        if not same:
            return tir
        sign = 1.0 if tir[same[0]] >= 0 else -1.0
        least = self.sc.margin_level + LEVEL_SLACK_DB
        return [sign * max(abs(v), least) if k in same else v for k, v in enumerate(tir)]

    def plan(self, chosen: list[int]) -> QueryPlan:
        sc, ix, cat = self.sc, self.ix, self.cat
        matches = tuple(k for k, p in enumerate(self.pairings) if p == "same-kind")
        sims = [None] + [round(ix.clip_sim(self.cap, j), 4) for j in chosen[1:]]
        alternatives = ()
        if not matches:
            others = np.asarray(chosen[1:])
            alternatives = tuple(c for k, c in enumerate(cat.clips[self.t].captions)
                                 if ix.clip_sims(ix.caption_id(self.t, k), others).max() <= sc.caption_similarity)
        kinds = set(self.pairings[1:])
        pairing = "same-kind" if matches else (kinds.pop() if len(kinds) == 1 else "mixed")
        margins = {Relation.LOUDEST: sc.margin_level, Relation.QUIETEST: sc.margin_level,
                   Relation.NEAREST: sc.margin_distance, Relation.FARTHEST: sc.margin_distance,
                   Relation.STARTS_FIRST: sc.margin_onset, Relation.STARTS_LAST: sc.margin_onset,
                   Relation.MOVING: sc.margin_motion, Relation.HEARD_AT: sc.margin_solo}
        order = tuple(str(r) for r in self.qrng.permutation(list(sc.relations)))
        return QueryPlan(wanted=self.wanted, relations=order, matches=matches, alternatives=alternatives,
                         wording=int(self.qrng.integers(1 << 30)), pairing=pairing,
                         pairings=tuple(self.pairings), similarity=tuple(sims), measure=str(sc.similarity),
                         margins=tuple((str(k), float(v)) for k, v in margins.items()))


def _starts(cfg: Config, split: str, index: int, n: int) -> list[float]:
    """Each source's start in the scene (``scene.onset``), from the scene's third stream so
    that no other draw moves; all 0 (no draws) by default."""
    onset = cfg.scene.onset
    if onset.kind == "const" and float(onset.args[0]) == 0.0:
        return [0.0] * n
    rng = scene_rng(cfg.seed, split, index, stream=2)
    return [round(float(onset.sample(rng)), 4) for _ in range(n)]


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


@dataclass(frozen=True)
class _Want:
    """What a directional source must be, drawn once per scene and kept through every
    retry of the geometry: redrawing one of these alone when a layout does not fit would
    bias its distribution toward what fits (short distances, slow speeds)."""

    distance: float  # m from the array centre
    height: float  # m above the floor
    moving: bool
    kind: str = ""  # PathKind, for a moving source
    speed: float = 0.0  # °/s great-circle, for a moving source

    def describe(self) -> str:
        motion = f"a {self.kind} path at {self.speed:g}°/s (scene.speed), " if self.moving else ""
        return f"{motion}{self.distance:.2f} m from the array (sources.distance), {self.height:.2f} m high"


def _wants(cfg: Config, rng, spatial: list[str]) -> list[_Want | None]:
    out = []
    for sp in spatial:
        if sp != Spatial.DIRECTIONAL:
            out.append(None)
            continue
        d, h = float(cfg.sources.distance.sample(rng)), float(cfg.sources.height.sample(rng))
        mv = _moves(cfg, rng)
        kind = str(cfg.scene.path.sample(rng)) if mv else ""
        speed = float(cfg.scene.speed.sample(rng)) if mv else 0.0
        out.append(_Want(d, h, mv, kind, speed))
    return out


ROOM_TRIES, CENTRE_TRIES, AZIMUTH_TRIES = 10, 10, 50


def _place(cfg: Config, rng, spatial: list[str], split: str, index: int):
    """Room, array pose and each source's placement (Source fields; None for additive).

    Each directional source's distance, height, motion, path kind and speed are drawn
    first and kept; what is retried until the sources fit (inside the walls' margins,
    ``scene.min_separation`` apart) is the rest of the geometry: the source's azimuth and
    path (direction, time of closest approach), the array's place, and the room. So the
    configured distributions are what the dataset holds, and a setting the rooms cannot
    hold is an error that names it.
    """
    rc, ac = cfg.room, cfg.array
    fmt = cfg.scene.format
    wants = _wants(cfg, rng, spatial)
    for _ in range(ROOM_TRIES):
        dims = (float(rc.length.sample(rng)), float(rc.width.sample(rng)), float(rc.height.sample(rng)))
        room = Room(tuple(round(d, 4) for d in dims), round(float(rc.rt60.sample(rng)), 4))
        side = round(float(ac.side.sample(rng)), 5) if fmt == "mic4" else None
        yaw = round(float(ac.yaw.sample(rng)), 4)
        for _ in range(CENTRE_TRIES):
            centre = (
                float(rng.uniform(ac.wall_margin, room.dims[0] - ac.wall_margin)),
                float(rng.uniform(ac.wall_margin, room.dims[1] - ac.wall_margin)),
                float(min(ac.height.sample(rng), room.dims[2] - 0.1)),
            )
            centre = tuple(round(c, 5) for c in centre)
            places = _place_sources(cfg, rng, wants, room, centre, yaw)
            if places is not None:
                return room, ArrayPose(fmt, centre, yaw, side), places
    shown = "; ".join(f"source {k}: {w.describe()}" for k, w in enumerate(wants) if w is not None)
    raise GeometryError(
        f"scene {split}/{index}: could not place its sources ({shown}), {cfg.scene.min_separation}° apart "
        f"(scene.min_separation), in {ROOM_TRIES} rooms drawn from room.length/width/height; lower "
        f"scene.min_separation{_separation_hint(spatial)} or the settings named, lower the wall margins, or "
        f"enlarge the rooms"
    )


def _separation_hint(spatial: list[str]) -> str:
    """What scene.min_separation can be for these sources: k directional sources fit at
    most 360°/k apart, and placement draws azimuths at random, so it needs a margin."""
    k = sum(sp == Spatial.DIRECTIONAL for sp in spatial)
    return f" (at most {360 / k:g}° is possible for {k} directional sources, random placement needs less)" if k > 1 \
        else ""


def _moves(cfg: Config, rng) -> bool:
    m = cfg.scene.motion
    return m == Motion.MOVING or (m == Motion.MIXED and bool(rng.random() < cfg.scene.moving_fraction))


def _frame_centres(cfg: Config) -> np.ndarray:
    a = cfg.audio
    return frame_centres(int(round(a.duration / a.label_hop)), a.label_hop)


def _separated(az: np.ndarray, placed: list[np.ndarray], sc) -> bool:
    """Whether azimuth track ``az`` [F] keeps ``sc.min_separation`` from every placed track
    on at least ``sc.separated_frames`` of the label frames.

    Static sources are separated on every frame or none; a moving source may cross
    another one (at 40°/s a 10 s walk goes all the way round) for the rest.
    """
    for p in placed:
        d = np.abs(wrap_azimuth(az - p))
        if np.mean(d >= sc.min_separation) < sc.separated_frames - 1e-9:
            return False
    return True


def _place_sources(cfg, rng, wants: list, room: Room, centre, yaw):
    """Every source's place for this room and array position, or None when one does not
    fit (the caller then draws another position or room)."""
    m = cfg.sources.wall_margin
    dims = room.dims
    fc = _frame_centres(cfg)
    placed: list[np.ndarray] = []  # azimuth track of each directional source at the label frames
    out = []
    for w in wants:
        if w is None:
            out.append(None)
            continue
        dz = w.height - centre[2]
        if abs(dz) >= w.distance or not m <= w.height <= dims[2] - m:
            return None  # no azimuth helps: this array height (or room) cannot hold it
        r_h = math.sqrt(w.distance ** 2 - dz * dz)
        for _ in range(AZIMUTH_TRIES):
            az = float(rng.uniform(-180.0, 180.0))
            if w.moving:
                place = _moving_path(cfg, rng, room, centre, yaw, az, r_h, w, fc)
                if place is None:
                    continue
                track = place.pop("_track")
            else:
                # array frame -> room frame by hand: numpy per point is slower than the maths
                a = math.radians(az + yaw)
                p = (centre[0] + r_h * math.cos(a), centre[1] + r_h * math.sin(a), w.height)
                if not all(m <= p[k] <= dims[k] - m for k in range(3)):
                    continue
                place = {"position": tuple(round(v, 6) for v in p)}
                track = np.full(len(fc), az)
            if _separated(track, placed, cfg.scene):
                placed.append(track)
                out.append(place)
                break
        else:
            return None
    return out


# A moving source's RIRs are computed at least every 100 ms and every 4 degrees.
KNOT_HOP_S, KNOT_STEP_DEG = 0.1, 4.0


def _moving_path(cfg, rng, room: Room, centre, yaw, az0: float, r_h: float, want: "_Want", fc: np.ndarray):
    """A simulated moving source at constant height, or None if it leaves the room:
    ``{"path": ((t, x, y, z), ...) room frame, "_track": azimuth (array frame) at the label frames}``.

    ω = ``scene.speed`` is the angular speed seen from the array (great-circle °/s, as
    for bank walks). ``arc``: around the array at horizontal distance r_h (distance d),
    so the azimuth turns at ω·d/r_h. ``line``: a straight pass, perpendicular to azimuth
    az0 at horizontal distance r_h when closest (at a time drawn over the clip), at the
    speed v = ω·d that sweeps ω °/s there, the fastest it gets; the azimuth then turns at
    most ω·d/r_h. Knots every min(100 ms, 4° / that azimuth rate): a knot at least every
    100 ms and every 4° of azimuth.
    """
    kind, speed, d, h = want.kind, want.speed, want.distance, want.height
    direction = 1 if rng.random() < 0.5 else -1
    dur = cfg.audio.duration
    az_rate = speed * d / r_h  # °/s of azimuth: the arc's, and the line's at its closest
    hop = min(KNOT_HOP_S, KNOT_STEP_DEG / az_rate) if speed > 0 else dur
    t = np.arange(0.0, dur + hop - 1e-9, hop)
    if kind == "arc":  # PathKind.ARC
        a = np.radians(az0 + yaw + direction * az_rate * t)
        x, y = centre[0] + r_h * np.cos(a), centre[1] + r_h * np.sin(a)
        track = az0 + direction * az_rate * fc
    else:
        t_close = float(rng.uniform(0.0, dur))
        a0 = math.radians(az0 + yaw)
        v = math.radians(speed) * d
        s = direction * v * (t - t_close)  # signed distance along the line from the closest point
        x = centre[0] + r_h * math.cos(a0) - s * math.sin(a0)
        y = centre[1] + r_h * math.sin(a0) + s * math.cos(a0)
        track = az0 + direction * np.degrees(np.arctan2(v * (fc - t_close), r_h))
    m = cfg.sources.wall_margin
    if (x.min() < m or y.min() < m or x.max() > room.dims[0] - m or y.max() > room.dims[1] - m
            or not m <= h <= room.dims[2] - m):
        return None
    path = tuple((round(float(ti), 6), round(float(xi), 6), round(float(yi), 6), round(h, 6))
                 for ti, xi, yi in zip(t, x, y))
    return {"path": path, "_track": track}


# --- RIR-bank scenes ----------------------------------------------------------------------


def _place_bank(cfg: Config, rng, spatial: list[str], split: str, index: int, bank_path: str):
    """A bank room for the split, the bank's array, and each source's walk or point:
    (None, ArrayPose, [{"bank": BankWalk} or None per source], BankRef)."""
    bank = open_bank_cached(bank_path, cfg.scene.format)
    rooms = split_rooms(bank, cfg.rooms_by_split(), split)
    room_name = rooms[int(rng.integers(len(rooms)))]
    info = bank.room_info(room_name)
    side = (info.get("array") or {}).get("side") if bank.format == "mic4" else None
    array = ArrayPose(bank.format, (0.0, 0.0, 0.0), 0.0, side)
    fc = _frame_centres(cfg)
    placed: list[np.ndarray] = []
    out = []
    for sp in spatial:
        if sp != Spatial.DIRECTIONAL:
            out.append(None)
            continue
        mv = _moves(cfg, rng)
        speed = float(cfg.scene.speed.sample(rng)) if mv else 0.0  # kept through the retries (see _Want)
        for _ in range(MAX_TRIES // 4):
            if mv:
                tid, idx, times = sample_bank_path(bank, room_name, rng, cfg.audio.duration, speed,
                                                   knot_hop=KNOT_HOP_S)
            else:
                tid, i0 = sample_bank_point(bank, room_name, rng)
                idx, times = np.array([i0]), np.array([0.0])
            pos = bank.trajectory(room_name, tid).positions[idx]
            track = interpolate_positions(times, pos, fc)[:, 0]
            if _separated(track, placed, cfg.scene):
                placed.append(track)
                out.append({"bank": BankWalk(
                    room_name, tid, tuple(int(v) for v in idx), tuple(round(float(v), 6) for v in times),
                    tuple(tuple(round(float(v), 4) for v in p) for p in pos))})
                break
        else:
            raise GeometryError(f"scene {split}/{index}: could not place sources {cfg.scene.min_separation}° apart "
                                f"in bank room {room_name}; lower scene.min_separation{_separation_hint(spatial)}")
    return None, array, out, BankRef(bank_path, room_name)


_WORKER_STATE: dict = {}


def _init_planner(cfg, split, cat):
    _WORKER_STATE.update(cfg=cfg, split=split, cat=cat)


def _plan_chunk(bounds: tuple[int, int]) -> list[str]:
    st = _WORKER_STATE
    return [plan_scene(st["cfg"], st["split"], i, st["cat"]).to_json() for i in range(*bounds)]


def plan_split_json(cfg: Config, split: str, cat: CatalogView, workers: int = 1, chunk: int = 4000,
                    start: int = 0) -> list[str]:
    """JSON lines of a split's recipes, planned on ``workers`` processes.

    Scenes are independent, so the result is the same for any number of workers.

    Parameters
    ----------
    cfg : Config
    split : str
    cat : CatalogView
    workers : int
        Processes; 1 plans in this process.
    chunk : int
        Scenes per task.
    start : int
        The first scene to plan (a grown dataset plans only its new scenes).

    Returns
    -------
    list of str
        Scenes ``start`` .. ``splits[split].count - 1`` (``SceneRecipe.to_json``).
    """
    n = cfg.splits[split].count
    bounds = [(a, min(a + chunk, n)) for a in range(start, n, chunk)]
    if workers <= 1 or len(bounds) <= 1:
        _init_planner(cfg, split, cat)
        return [line for b in bounds for line in _plan_chunk(b)]
    with ProcessPoolExecutor(workers, initializer=_init_planner, initargs=(cfg, split, cat)) as ex:
        return [line for lines in ex.map(_plan_chunk, bounds) for line in lines]
