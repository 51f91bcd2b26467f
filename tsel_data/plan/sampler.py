"""The scene sampler: (config, split, index, clip catalog) -> SceneRecipe.

Every random choice of scene ``index`` in ``split`` comes from one generator seeded by
``(dataset seed, crc32(split), index)``, so a scene does not depend on any other scene,
on the order scenes are planned in, or on how many workers plan them.

This module samples only: which bank file a dataset uses and which rooms a split may
draw is decided in :mod:`tsel_data.banks.scenes`.
"""
from __future__ import annotations

import os
import zlib

import numpy as np

from ..banks.scenes import BankRequest, open_bank_cached, resolve_bank, split_rooms
from ..choices import Additive, LevelModel, Pairing, QueryType, Role, Scenario, SimilarityMeasure, Spatial
from ..config import Config, rooms_without_bank
from ..config.receiver import array_pose, hrtf_problem
from ..core.progress import bar
from ..corpus.ambience import check_sounds, find_ambience
from ..corpus.captions import CaptionIndex, caption_sets, load_embeddings, max_similarity, same_kind, sound_events
from ..corpus.clip import Clip
from ..errors import TselError
from ..receivers import receiver
from ..runtime.pool import ordered_pool
from ..render.hardware import draw_hardware
from ..render.noise import draw_noise
from ..scene.queries import margins as relation_margins
from ..scene.recipe import BUILTIN_DEMO_BANK, BankRef, QueryPlan, Roots, SceneRecipe, Source, plan_roots
from ..store.layout import Layout
from .catalog import MIN_CLIPS, CatalogScan, build_catalog, resolve_corpus_dir
from .placement import MAX_TRIES, place, place_bank



class CatalogView:
    """A split's clips with their caption sets and indexes made once (shared by every
    scene), and the resolved path of the RIR bank when scenes use one."""

    def __init__(self, clips: list[Clip], bank_path: str | None = None, roots: Roots | None = None,
                 ambience=None):
        if len(clips) < MIN_CLIPS:
            raise TselError(f"a split needs at least {MIN_CLIPS} usable clips to make scenes, it has {len(clips)}")
        self.clips = clips
        # clips cut from the same recording (AudioCaps: same YouTube video) are one sound source
        self.source_key = [c.meta.get("youtube_id") or c.audio for c in clips]
        self.bank_path = bank_path
        # recipes name their files relative to these (absolute paths without them)
        self.roots = roots or Roots()
        self.ambience = ambience  # the AmbienceSet of noise.ambience, or None
        # clips a full check found bad since (corpus.check = "drawn", plan/drawn.py): a draw
        # that lands on one is drawn again, so indices stay and scenes that never drew one
        # keep every draw
        self.excluded: frozenset[int] = frozenset()
        self._indexes: dict = {}

    def exclude(self, indices) -> None:
        """Leave the clips ``indices`` out of every draw from now on (:attr:`excluded`)."""
        self.excluded = self.excluded | {int(i) for i in indices}
        self.__dict__.pop("_excluded_mask", None)

    def excluded_mask(self, clips: np.ndarray) -> np.ndarray:
        """Which of the clip indices ``clips`` are excluded (bool, their shape)."""
        if not self.excluded:
            return np.zeros(np.shape(clips), dtype=bool)
        if "_excluded_mask" not in self.__dict__:
            mask = np.zeros(len(self.clips), dtype=bool)
            mask[list(self.excluded)] = True
            self._excluded_mask = mask
        return self._excluded_mask[clips]

    def draw(self, rng: np.random.Generator) -> int:
        """A clip index uniformly over the split's clips, drawn again while it is excluded."""
        while True:
            j = int(rng.integers(len(self.clips)))
            if j not in self.excluded:
                return j

    def caption_index(self, measure: str, embeddings: str = "") -> CaptionIndex:
        """The split's captions under ``measure``, built once per view (a few seconds for
        50k captions; :func:`prepare_views` builds the config's before workers start)."""
        key = (measure, embeddings)
        if key not in self._indexes:
            vectors = load_embeddings(embeddings) if measure == SimilarityMeasure.EMBEDDINGS else None
            self._indexes[key] = CaptionIndex([c.captions for c in self.clips], measure, vectors,
                                              where=f"corpus.caption_embeddings {embeddings}")
        return self._indexes[key]

    def caption_sets(self, measure: str) -> list[tuple]:
        """Each clip's captions as the sets ``measure`` compares (``words``, ``lexicon``), made once."""
        key = ("sets", measure)
        if key not in self._indexes:
            self._indexes[key] = [tuple(caption_sets(c, measure) for c in clip.captions) for clip in self.clips]
        return self._indexes[key]

    def sound_events(self) -> list[frozenset]:
        """Each clip's sound events, its captions together (corpus.captions.sound_events), made once."""
        key = ("events",)
        if key not in self._indexes:
            self._indexes[key] = [sound_events(c.captions) for c in self.clips]
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
    for problem in (rooms_without_bank(cfg), hrtf_problem(cfg)):
        if problem:
            raise problem
    corpus_dir = resolve_corpus_dir(cfg, home.demo_corpus)
    catalog = build_catalog(cfg, corpus_dir, workers=workers, progress=progress)
    return catalog, catalog_views(cfg, catalog.clips, home)


def catalog_views(cfg: Config, clips: dict, home: Layout) -> dict[str, CatalogView]:
    """Per split of ``clips`` ({split: [Clip]}), the :class:`CatalogView` its scenes are
    planned from: the resolved bank, the roots, the ambience, the caption index. The one
    way a view is made, for ``tsel generate`` and ``tsel check`` alike."""
    bank_path = resolve_bank(bank_request(cfg), home.demo_bank) if cfg.room.bank else None
    roots = plan_roots(cfg, home)
    ambience = find_config_ambience(cfg)
    views = {split: CatalogView(split_clips, bank_path, roots, ambience) for split, split_clips in clips.items()}
    if extended_queries(cfg):  # built once here, not in every planning process
        for split in cfg.active_splits():
            if split in views:
                views[split].caption_index(cfg.scene.similarity, cfg.corpus.caption_embeddings)
                if same_kind_possible(cfg):
                    views[split].sound_events()
    return views


def ambience_problems(cfg: Config) -> list[TselError]:
    """What keeps ``noise.ambience`` from serving the config: the folder, its recordings'
    channels, rate and length (tsel_data.corpus.ambience), and with a bank, a recording for every
    bank room the active splits use."""
    try:
        amb = find_config_ambience(cfg)
        if amb is None or not cfg.room.bank or cfg.room.bank == BUILTIN_DEMO_BANK:
            return []
        path = os.path.abspath(os.path.expanduser(cfg.room.bank))
        bank = open_bank_cached(path, receiver(cfg.scene.format).bank_format if os.path.isdir(path) else None)
        for split in cfg.active_splits():
            for room in split_rooms(bank, cfg.rooms_by_split(), split):
                amb.for_room(room, np.random.default_rng(0))
    except TselError as e:
        return [e]
    return []


def find_config_ambience(cfg: Config):
    """The ambience recordings ``noise.ambience`` names (tsel_data.corpus.ambience), checked against
    the receiver's channels and the scenes' rate, or None without ambience."""
    if not cfg.noise.ambience:
        return None
    pose = array_pose(cfg)
    found = find_ambience(os.path.abspath(os.path.expanduser(cfg.noise.ambience)), pose.n_channels, cfg.audio.fs,
                          pose.format, scene_samples=int(round(cfg.audio.duration * cfg.audio.fs)))
    for rec in found.recordings:
        check_sounds(rec.path, cfg.audio.fs)
    return found


def bank_request(cfg: Config) -> BankRequest:
    """What the config asks of its RIR bank (plain values for :mod:`tsel_data.banks.scenes`)."""
    # a mixed receiver (stereo from FOA) renders from banks of its base format
    return BankRequest(cfg.room.bank, receiver(cfg.scene.format).bank_format, cfg.audio.fs, cfg.rooms_by_split(),
                       cfg.active_splits())


def scene_rng(seed: int, split: str, index: int, stream: int = 0) -> np.random.Generator:
    """The generator of every draw of scene ``index`` of ``split``.

    Streams 1 (query decisions: the query type, same-kind draws, the relation order and
    wording), 2 (each source's start, ``scene.onset``), 3 (``[noise]``), 4 (source powers)
    and 5 (``[hardware]``: each receiver's capsules and clocks) are independent generators
    of the same scene, so they never shift the draws of stream 0 (clips, levels, room,
    placement) that earlier releases made.
    """
    key = [seed, zlib.crc32(split.encode("utf-8")), index]
    return np.random.default_rng(key if stream == 0 else key + [stream])


def extended_queries(cfg: Config) -> bool:
    """Whether the config uses queries beyond a caption with random pairing under a set
    measure (``lexicon``, ``words``, ``none``): then recipes carry a QueryPlan and records
    the query fields."""
    sc = cfg.scene
    return (set(sc.query.options) != {QueryType.CAPTION} or sc.pairing != Pairing.RANDOM
            or sc.same_kind_distractors > 0 or sc.similarity not in SET_MEASURES)


def same_kind_possible(cfg: Config) -> bool:
    """Whether scenes may draw same-kind distractors (composite queries, or a probability of them)."""
    return cfg.scene.same_kind_distractors > 0 or QueryType.COMPOSITE in cfg.scene.query.options


SET_MEASURES = (SimilarityMeasure.LEXICON, SimilarityMeasure.WORDS, SimilarityMeasure.NONE)


def plan_scene(cfg: Config, split: str, index: int, cat: CatalogView) -> SceneRecipe:
    """The recipe of scene ``index`` of ``split``.

    Draws, in order, from :func:`scene_rng`: scenario, interferer count, the target clip
    and the caption used as the query, interferers whose captions are not too similar
    to the query (``scene.caption_similarity``), TIRs, then the room, array and source
    placement (simulated rooms) or the bank room and each source's walk.

    With extended queries (:func:`extended_queries`; docs/queries.md) interferers are
    paired by ``scene.pairing`` and may be same-kind distractors, and the recipe gets a
    :class:`~tsel_data.scene.recipe.QueryPlan` from which the renderer decides the query;
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

    t = cat.draw(rng)
    q = int(rng.integers(len(cat.clips[t].captions)))
    query = cat.clips[t].captions[q]
    chosen = [t]
    pairs = None
    if extended_queries(cfg):
        pairs = _QueryDraws(cfg, split, index, cat, t, q)
        for k in range(n_int):
            chosen.append(pairs.pick(rng, chosen, kind=pairs.wants_same_kind(k, n_int)))
    else:
        for _ in range(n_int):
            chosen.append(_pick_interferer(rng, cat, chosen, (t, q), sc, split, index))

    additive = Spatial.DIFFUSE if sc.additive == Additive.DIFFUSE else Spatial.ADDITIVE
    spatial = [Spatial.DIRECTIONAL] + [
        additive if (scenario == Scenario.DIRECTIONAL_ADDITIVE and k == 0) else Spatial.DIRECTIONAL
        for k in range(n_int)]
    tir = [None] + [float(sc.tir_db.sample(rng)) for _ in range(n_int)]
    if pairs is not None:
        tir = pairs.separate_levels(tir)
    if cat.bank_path:
        room, array, places, bank = place_bank(cfg, rng, spatial, split, index, cat.bank_path)
        bank = BankRef(cat.roots.relative_bank(bank.path), bank.room)
    else:
        (room, array, places), bank = place(cfg, rng, spatial, split, index), None
    starts = _starts(cfg, split, index, len(chosen))
    powers = _powers(cfg, split, index, spatial)
    sources = []
    for k, ci in enumerate(chosen):
        clip = cat.clips[ci]
        kept_tir = tir[k] if powers[k] is None else None  # a source with a power has no TIR: distance sets it
        sources.append(Source(
            role=Role.TARGET if k == 0 else Role.INTERFERER, clip_id=clip.id, audio=cat.roots.relative_clip(clip.audio),
            captions=clip.captions, spatial=spatial[k], offset=clip.offset,
            tir_db=None if kept_tir is None else round(kept_tir, 4), start=starts[k], power_db=powers[k],
            **(places[k] or {}),
        ))
    a = cfg.audio
    recipe = SceneRecipe(
        scene_id=f"{split}-{index:06d}", split=split, index=index, seed=int(rng.integers(2**31 - 1)),
        scenario=scenario, query=query, array=array[0], receivers=tuple(array[1:]), sources=tuple(sources), room=room,
        fs=a.fs, duration=a.duration, label_hop=a.label_hop,
        rir_method="bank" if cat.bank_path else cfg.room.rir_method,
        target_level_dbfs=a.target_level_dbfs, activity_threshold_db=a.activity_threshold_db, bank=bank,
        query_plan=None if pairs is None else pairs.plan(chosen),
        noise=_noise_items(cfg, split, index, cat, chosen, bank.room if bank else None),
        hardware=draw_hardware(cfg, scene_rng(cfg.seed, split, index, 5), array),
        descriptors=cfg.output.descriptors,
    )
    return recipe.validate(wall_margin=cfg.sources.wall_margin - 1e-6)


def _powers(cfg: Config, split: str, index: int, spatial: list) -> list:
    """Each source's level at 1 m (dB) when levels follow distance (``scene.levels``), from
    the scene's stream 4; None for positionless sources and under the TIR model."""
    if cfg.scene.levels != LevelModel.DISTANCE:
        return [None] * len(spatial)
    rng = scene_rng(cfg.seed, split, index, 4)
    return [round(float(cfg.sources.power.sample(rng)), 3) if sp == Spatial.DIRECTIONAL else None for sp in spatial]


def _noise_items(cfg: Config, split: str, index: int, cat: CatalogView, chosen: list, bank_room) -> tuple:
    """The scene's noises (``[noise]``), drawn from its stream 3 (render/noise.py
    ``NOISE_KINDS``: the ambience recording of its room and where in it, the diffuse
    field's spectrum, the babble's clips and directions, the sensor noise's level; each
    with an SNR and a seed of its own)."""
    return draw_noise(cfg, scene_rng(cfg.seed, split, index, 3), index, cat, chosen, bank_room)


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
        self.t, self.q, self.cap = t, q, self.ix.caption_id(t, q)
        self.pairings: list = [None]

    def wants_same_kind(self, k: int, n_int: int) -> bool:
        # a composite query needs a second source its caption fits: the last interferer
        # (directional unless it is a directional+additive scene's only one); any
        # interferer with probability scene.same_kind_distractors
        p = self.sc.same_kind_distractors
        drawn = bool(self.qrng.random() < p) if p > 0 else False
        return drawn or (self.wanted == QueryType.COMPOSITE and k == n_int - 1)

    def pick(self, rng, chosen: list[int], kind: bool) -> int:
        sc, ix, cat = self.sc, self.ix, self.cat
        taken = cat.source_ids[chosen]

        def allowed(clips):
            # a clip of a recording already in the scene (the chosen clips among them) is not another source
            return (cat.source_ids[clips][:, None] != taken[None, :]).all(axis=1)

        excluded = cat.excluded_mask if cat.excluded else None
        if kind:
            # of the target's kind: the band of similarity to the query caption, and the
            # sound events the caption names, no more than the target's (corpus.captions.same_kind)
            events = cat.sound_events()
            query, target = sound_events(cat.clips[self.t].captions[self.q]), events[self.t]

            def of_kind(clips):
                ok = allowed(clips)
                return ok & np.array([same_kind(query, target, events[j]) for j in clips], dtype=bool)

            j = ix.sample(rng, self.cap, sc.same_kind_similarity, np.inf, of_kind, excluded=excluded)
            if j is not None:
                self.pairings.append("same-kind")
                return j
        if sc.pairing != Pairing.RANDOM:
            lo, hi = ((sc.hard_similarity, sc.caption_similarity) if sc.pairing == Pairing.HARD
                      else (-np.inf, sc.easy_similarity))
            j = ix.sample(rng, self.cap, lo, hi, allowed, excluded=excluded)
            if j is not None:
                self.pairings.append(str(sc.pairing))
                return j
        # random pairing, and the fallback of a band the split cannot fill
        for _ in range(MAX_TRIES):
            j = int(rng.integers(len(cat.clips)))
            if j in chosen or j in cat.excluded or cat.source_ids[j] in taken or \
                    ix.clip_sim(self.cap, j) > sc.caption_similarity:
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
        margins = relation_margins(sc)
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


def _pick_interferer(rng, cat: CatalogView, chosen: list[int], query: tuple[int, int], sc, split, index) -> int:
    """Any clip of another recording whose captions are at most ``sc.caption_similarity``
    similar to caption ``query`` = (clip, caption) under ``sc.similarity`` (``none``: any).
    ``lexicon`` holds them to every caption of the target clip: a clip captioned five times
    (AudioCaps val/test, Clotho) is one sound described five ways, and an interferer that
    shares a sound with any of them shares it with the target (on the AudioCaps test split
    1.00 % of scenes ambiguous against the query alone, 0.44 % so)."""
    taken = {cat.source_key[i] for i in chosen}
    measure, max_sim = str(sc.similarity), sc.caption_similarity
    sets = cat.caption_sets(measure) if measure != SimilarityMeasure.NONE else None
    if sets is not None:
        target = sets[query[0]] if measure == SimilarityMeasure.LEXICON else (sets[query[0]][query[1]],)
    for _ in range(MAX_TRIES):
        j = int(rng.integers(len(cat.clips)))
        if j in chosen or j in cat.excluded or cat.source_key[j] in taken:
            continue
        if sets is not None and any(max_similarity(q, sets[j], measure) > max_sim for q in target):
            continue
        return j
    raise TselError(
        f"scene {split}/{index}: no interferer found whose captions differ from the query "
        f"after {MAX_TRIES} tries; raise scene.caption_similarity (now {max_sim}) or add clips"
    )


_WORKER_STATE: dict = {}


def _init_planner(cfg, split, cat):
    _WORKER_STATE.update(cfg=cfg, split=split, cat=cat)


def _plan_chunk(bounds: tuple[int, int]) -> list[str]:
    st = _WORKER_STATE
    return [plan_scene(st["cfg"], st["split"], i, st["cat"]).to_json() for i in range(*bounds)]


def plan_split_json(cfg: Config, split: str, cat: CatalogView, workers: int = 1, chunk: int = 4000,
                    start: int = 0, progress: bool | None = False) -> list[str]:
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
    progress : bool or None
        A bar counting the scenes (None: when stderr is a terminal).

    Returns
    -------
    list of str
        Scenes ``start`` .. ``splits[split].count - 1`` (``SceneRecipe.to_json``).
    """
    n = cfg.splits[split].count
    bounds = [(a, min(a + chunk, n)) for a in range(start, n, chunk)]
    with bar(n - start, f"plan {split}", "scene", progress if n > start else False) as b:
        if workers <= 1 or len(bounds) <= 1:
            _init_planner(cfg, split, cat)
            out = []
            for i in range(start, n):  # scenes are independent: one at a time counts the same
                out += _plan_chunk((i, i + 1))
                b.update()
            return out
        out = []
        for lines in _pooled(workers, cfg, split, cat, bounds):
            out += lines
            b.update(len(lines))
        return out


def _pooled(workers: int, cfg: Config, split: str, cat: CatalogView, bounds):
    """The chunks' lines in order, planned on a pool of ``workers`` processes."""
    with ordered_pool(workers, _init_planner, (cfg, split, cat)) as ex:
        yield from ex.map(_plan_chunk, bounds)
