"""Scene recipes: plain, frozen data that fully determine one scene.

``render_scene(recipe)`` depends on nothing but the recipe and the files it names, so
a dataset can be planned once, inspected before any audio exists, and rendered in any
order on any number of workers. Recipes round-trip through JSON (``to_dict`` /
``from_dict``); the plan stage writes one per line to ``plan/{split}.jsonl``.

The files a recipe names are relative to two roots (:class:`Roots`): clips to the corpus
folder, the RIR bank to the bank given by ``room.bank``. So a plan, and every record
rendered from it, holds no path of the machine it was made on; the renderer is given the
roots of the machine it runs on.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, replace

import numpy as np

from ..choices import Role, Scenario, Spatial, values
from ..core.files import check_input
from ..core.geometry import Room, interpolate_positions, room_to_array
from ..core.jsonable import JsonFields, key, rows, unset
from ..errors import DatasetError, GeometryError
from ..receivers import RECEIVERS, ArrayPose
from .hardware import Hardware
from .recorded import KIND as RECORDED, RecordedRecipe

SCENARIOS = values(Scenario)


@dataclass(frozen=True)
class BankWalk:
    """Where a bank-rendered source is: knots along one trajectory of an RIR bank room.

    room: room name. trajectory: trajectory id in that room. indices: bank positions
    used as knots, in walk order (one index: a static source). times: seconds at which
    each knot applies fully (``render_moving``'s knot times). positions: each knot's
    (azimuth °, elevation °, distance m) in the array frame, as the bank states them.
    """

    room: str
    trajectory: str | int
    indices: tuple[int, ...]
    times: tuple[float, ...]
    positions: tuple[tuple[float, float, float], ...]

    @property
    def moving(self) -> bool:
        return len(self.indices) > 1

    def positions_at(self, t) -> np.ndarray:
        """(az, el, dist) [len(t), 3] at times ``t``: the knots blended with the renderer's
        crossfade weights, so labels follow the rendered walk."""
        return interpolate_positions(self.times, self.positions, t)

    def to_dict(self) -> dict:
        return {"room": self.room, "trajectory": self.trajectory, "indices": list(self.indices),
                "times": list(self.times), "positions": [list(p) for p in self.positions]}

    @classmethod
    def from_dict(cls, d: dict) -> "BankWalk":
        return cls(d["room"], d["trajectory"], tuple(int(i) for i in d["indices"]), tuple(d["times"]),
                   tuple(tuple(p) for p in d["positions"]))


@dataclass(frozen=True)
class BankRef:
    """The RIR bank a scene is rendered from: ``path`` (the bank's name; :class:`Roots` says where it is)
    and the bank ``room`` every source of the scene uses."""

    path: str
    room: str


@dataclass(frozen=True)
class Source(JsonFields):
    """One sound event of a scene.

    role: ``target`` or ``interferer``. spatial: ``directional`` (rendered through the
    room), ``additive`` (added to every channel unspatialised; no position) or
    ``diffuse`` (heard as a diffuse field at the array; no position).
    position: room frame (m) for a static simulated source. path: for a moving simulated
    source, knots ``(t s, x, y, z m)`` in the room frame, linearly interpolated in time.
    bank: for bank-rendered sources, where in the bank (:class:`BankWalk`).
    tir_db: target-to-interferer ratio at the array for interferers (dB), None for the
    target. offset: seconds into the audio file where the clip starts. start: seconds
    into the scene where the clip starts (silence before it; ``scene.onset``). power_db:
    with ``scene.levels = "distance"``, its level at 1 m (dB, relative; None otherwise).
    """

    role: str
    clip_id: str
    audio: str
    captions: tuple[str, ...] = key(encode=list, decode=tuple)
    spatial: str = Spatial.DIRECTIONAL
    offset: float = 0.0
    position: tuple[float, float, float] | None = key(None, encode=lambda v: None if v is None else list(v),
                                                      decode=lambda v: None if v is None else tuple(v))
    path: tuple[tuple[float, float, float, float], ...] | None = key(
        None, encode=lambda v: rows(v) if v else None, decode=lambda v: tuple(tuple(k) for k in v) if v else v)
    bank: BankWalk | None = key(None, encode=lambda b: None if b is None else b.to_dict(),
                                decode=lambda v: None if v is None else BankWalk.from_dict(v))
    tir_db: float | None = None
    start: float = key(0.0, omit=lambda s: not s.start)  # absent when 0: recipes without scene.onset keep their bytes
    power_db: float | None = key(None, omit=unset("power_db"))  # levels that follow distance only

    @property
    def moving(self) -> bool:
        return bool(self.path) or bool(self.bank and self.bank.moving)

    def room_points(self):
        """Every room-frame point the source occupies (a sequence of (x, y, z)), or None."""
        if self.path:
            return [k[1:] for k in self.path]
        if self.position is not None:
            return [self.position]
        return None

    def position_at(self, t) -> np.ndarray:
        """Room-frame position(s) [..., 3] of a simulated source at time(s) t (seconds)."""
        t = np.asarray(t, dtype=np.float64)
        if self.path:
            knots = np.asarray(self.path, dtype=np.float64)
            return np.stack([np.interp(t, knots[:, 0], knots[:, k]) for k in (1, 2, 3)], axis=-1)
        return np.broadcast_to(np.asarray(self.position, dtype=np.float64), t.shape + (3,)).copy()


@dataclass(frozen=True)
class NoiseItem(JsonFields):
    """One part of what a scene hears besides its sources (``[noise]``; never labelled).

    kind: ``ambience`` (a recording: ``file`` named relative to ``noise.ambience``, from
    ``offset`` samples), ``diffuse`` (simulated, ``spectrum`` white / pink / brown, or the
    long-term spectrum of the clip ``clips[0]``), ``babble`` (``clips``, each (audio path
    relative to the corpus, offset s), a plane wave from ``directions[k]`` (azimuth °,
    elevation °, array frame)) or ``sensor`` (independent per channel). snr_db: against
    the target's omni energy (None for ``sensor`` at ``level_dbfs``). seed: its random
    draws at render time.
    """

    kind: str
    seed: int = key(decode=int)
    snr_db: float | None = key(None, omit=unset("snr_db"))
    level_dbfs: float | None = key(None, omit=unset("level_dbfs"))
    spectrum: str | None = key(None, omit=unset("spectrum"))
    file: str | None = key(None, omit=unset("file"))
    offset: int | None = key(None, omit=unset("offset"))
    clips: tuple = key((), omit=lambda n: not n.clips, encode=rows, decode=lambda v: tuple(tuple(c) for c in v or ()))
    directions: tuple = key((), omit=lambda n: not n.directions, encode=rows,
                            decode=lambda v: tuple(tuple(c) for c in v or ()))


@dataclass(frozen=True)
class QueryPlan:
    """What the renderer needs to decide a scene's query on the rendered truth
    (docs/queries.md). Only recipes planned with non-default query settings carry one.

    wanted: the query type drawn (``caption``, ``relational``, ``composite``).
    relations: the relations to try, in the order drawn for this scene.
    matches: sources besides the target that the query caption also describes (the
    same-kind distractors); a composite query's relation is decided among these.
    alternatives: the target's captions that describe it and no other source (empty
    when a same-kind distractor is present: then no bare caption is unambiguous).
    wording: picks the template of a relation's wordings. pairing: the scene's pairing
    (``random``, ``hard``, ``easy``, ``same-kind`` or ``mixed``). pairings, similarity:
    per source (None for the target): how it was paired, and the similarity of its
    captions to the query caption under ``measure``. margins: relation name -> the
    margin it must hold with (dB, m, s, deg; ``heard_at``: the solo window, s).
    """

    wanted: str
    relations: tuple[str, ...]
    matches: tuple[int, ...]
    alternatives: tuple[str, ...]
    wording: int
    pairing: str
    pairings: tuple[str | None, ...]
    similarity: tuple[float | None, ...]
    measure: str
    margins: tuple[tuple[str, float], ...]

    def margin(self, relation: str) -> float:
        return dict(self.margins)[relation]

    def to_dict(self) -> dict:
        return {"wanted": self.wanted, "relations": list(self.relations), "matches": list(self.matches),
                "alternatives": list(self.alternatives), "wording": self.wording, "pairing": self.pairing,
                "pairings": list(self.pairings), "similarity": list(self.similarity), "measure": self.measure,
                "margins": dict(self.margins)}

    @classmethod
    def from_dict(cls, d: dict) -> "QueryPlan":
        return cls(d["wanted"], tuple(d["relations"]), tuple(int(k) for k in d["matches"]), tuple(d["alternatives"]),
                   int(d["wording"]), d["pairing"], tuple(d["pairings"]), tuple(d["similarity"]), d["measure"],
                   tuple((k, float(v)) for k, v in d["margins"].items()))


@dataclass(frozen=True)
class SceneRecipe:
    """Everything needed to render one scene (the target is ``sources[0]``).

    fs: Hz. duration, label_hop: s. rir_method: the simulator, or ``"bank"``.
    target_level_dbfs: active-frame RMS of the target's image at the array.
    activity_threshold_db: a frame is active within this of the clip's loudest frame.
    room: the simulated shoebox (None for bank scenes). bank: the bank and room of a
    bank scene (None for simulated scenes). query: the target's caption drawn as the
    query; with a ``query_plan`` the renderer decides the scene's query from it and the
    rendered truth (a relation, or this caption). receivers: further receivers heard in
    the same pass, at the array's centre and yaw (``scene.receivers``). noise: what else
    it hears, unlabelled (:class:`NoiseItem`, ``[noise]``). hardware: each receiver's
    microphones as built (``[hardware]``; :class:`~tsel_data.scene.hardware.Hardware`), in
    the order ``array``, ``receivers``; empty: ideal capsules. descriptors: the record gets
    each source's acoustic descriptors and motion class, and the room's size
    (``output.descriptors``).
    """

    scene_id: str
    split: str
    index: int
    seed: int
    scenario: str
    query: str
    array: ArrayPose
    sources: tuple[Source, ...]
    room: Room | None = None
    fs: int = 24000
    duration: float = 10.0
    label_hop: float = 0.1
    rir_method: str = "hybrid"
    target_level_dbfs: float = -25.0
    activity_threshold_db: float = -30.0
    bank: BankRef | None = None
    query_plan: QueryPlan | None = None
    receivers: tuple[ArrayPose, ...] = ()
    noise: tuple[NoiseItem, ...] = ()
    hardware: tuple[Hardware, ...] = ()
    descriptors: bool = False

    kind = "rendered"  # a plan line's kind (a recorded scene's recipe says "recorded")

    @property
    def target(self) -> Source:
        return self.sources[0]

    @property
    def n_samples(self) -> int:
        return int(round(self.duration * self.fs))

    @property
    def n_frames(self) -> int:
        return int(round(self.duration / self.label_hop))

    @property
    def moving(self) -> bool:
        return any(s.moving for s in self.sources)

    def input_files(self):
        """(root, name) of every file the scene reads: clips (corpus), ambience
        recordings, the RIR bank, an HRTF (:meth:`Roots.path` resolves each)."""
        out = [("corpus", s.audio) for s in self.sources] + [("corpus", c[0]) for n in self.noise for c in n.clips]
        out += [("ambience", n.file) for n in self.noise if n.file]
        out += [("bank", self.bank.path)] if self.bank else []
        out += [("hrtf", a.hrtf) for a in (self.array, *self.receivers) if a.hrtf]
        return out

    # --- serialisation -------------------------------------------------------------
    def to_dict(self) -> dict:
        # hand-written rather than dataclasses.asdict: planning 100k scenes is dominated
        # by serialisation otherwise. The bank reference is stored as "extra" (format 1).
        d = {
            "scene_id": self.scene_id, "split": self.split, "index": self.index, "seed": self.seed,
            "scenario": self.scenario, "query": self.query,
            "array": self.array.to_dict(),
            "sources": [s.to_dict() for s in self.sources],
            "room": None if self.room is None else {"dims": list(self.room.dims), "rt60": self.room.rt60},
            "fs": self.fs, "duration": self.duration, "label_hop": self.label_hop, "rir_method": self.rir_method,
            "target_level_dbfs": self.target_level_dbfs, "activity_threshold_db": self.activity_threshold_db,
            "extra": {} if self.bank is None else {"bank": self.bank.path, "bank_room": self.bank.room},
        }
        if self.query_plan is not None:  # absent in recipes of default query settings: their bytes stay
            d["query_plan"] = self.query_plan.to_dict()
        if self.receivers:  # further receivers at the array's place (scene.receivers)
            d["receivers"] = [a.to_dict() for a in self.receivers]
        if self.noise:
            d["noise"] = [n.to_dict() for n in self.noise]
        if self.hardware:  # [hardware]: absent otherwise, so recipes without it keep their bytes
            d["hardware"] = [h.to_dict() for h in self.hardware]
        if self.descriptors:  # absent otherwise: recipes made before it keep their bytes
            d["descriptors"] = True
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), ensure_ascii=False, separators=(",", ":"))

    @classmethod
    def from_dict(cls, d: dict) -> "SceneRecipe":
        d = dict(d)
        extra = d.pop("extra", None) or {}
        d["array"] = ArrayPose.from_dict(d["array"])
        d["room"] = None if d.get("room") is None else Room(tuple(d["room"]["dims"]), d["room"]["rt60"])
        d["sources"] = tuple(Source.from_dict(s) for s in d["sources"])
        d["bank"] = BankRef(extra["bank"], extra["bank_room"]) if extra.get("bank") else None
        qp = d.pop("query_plan", None)
        d["query_plan"] = None if qp is None else QueryPlan.from_dict(qp)
        d["receivers"] = tuple(ArrayPose.from_dict(a) for a in d.get("receivers") or ())
        d["noise"] = tuple(NoiseItem.from_dict(n) for n in d.get("noise") or ())
        d["hardware"] = tuple(Hardware.from_dict(h) for h in d.get("hardware") or ())
        return cls(**d)

    @classmethod
    def from_json(cls, line: str) -> "SceneRecipe":
        return cls.from_dict(json.loads(line))

    # --- validation ------------------------------------------------------------------
    def validate(self, wall_margin: float = 0.0) -> "SceneRecipe":
        """Raise GeometryError unless the scene can be realised; returns self."""
        if self.scenario not in SCENARIOS:
            raise GeometryError(f"{self.scene_id}: unknown scenario {self.scenario!r}; expected one of {SCENARIOS}")
        if self.array.format not in RECEIVERS:
            raise GeometryError(f"{self.scene_id}: unknown array format {self.array.format!r}")
        if not self.sources or self.sources[0].role != Role.TARGET or self.sources[0].spatial != Spatial.DIRECTIONAL:
            raise GeometryError(f"{self.scene_id}: source 0 must be the directional target")
        if any(s.role != Role.INTERFERER for s in self.sources[1:]):
            raise GeometryError(f"{self.scene_id}: only source 0 may be the target")
        if self.room is not None:
            dims = self.room.dims
            for a in (self.array, *self.receivers):
                _inside(a.room_mic_points(), dims, 0.0, f"{self.scene_id}: array {a.format}")
            for i, s in enumerate(self.sources):
                pts = s.room_points()
                if s.spatial == Spatial.DIRECTIONAL and s.bank is None and pts is None:
                    raise GeometryError(f"{self.scene_id}: source {i} is directional but has no position")
                if pts is not None:
                    _inside(pts, dims, wall_margin, f"{self.scene_id}: source {i}")
        return self


# roots a config may name instead of a path: the inputs tsel-data makes itself
BUILTIN_DEMO = "builtin:demo"
BUILTIN_DEMO_BANK = "builtin:demo-bank"
BUILTIN_DEMO_RECORDED = "builtin:demo-recorded"  # the STARSS23 stand-in (corpus/demo/recordings.py)


@dataclass(frozen=True)
class Roots:
    """Where a recipe's relative paths point on this machine: ``corpus`` (the corpus
    folder: clip paths are relative to it), ``bank`` (the bank file or folder; a config
    has one bank, so a recipe's bank name just names it) and ``hrtf`` (a binaural
    receiver's SOFA file, named by the recipe the same way). Empty roots leave paths
    as they are (recipes made with absolute paths)."""

    corpus: str = ""
    bank: str = ""
    hrtf: str = ""
    ambience: str = ""

    def relative_clip(self, path: str) -> str:
        """A clip's path as a plan stores it: relative to the corpus, with ``/``."""
        if not self.corpus:
            return path
        return os.path.relpath(path, self.corpus).replace(os.sep, "/")

    def relative_bank(self, path: str) -> str:
        return os.path.basename(os.path.normpath(path)) if self.bank else path

    def clip(self, rel: str) -> str:
        return os.path.normpath(os.path.join(self.corpus, rel)) if self.corpus else rel

    def bank_file(self, rel: str) -> str:
        return self.bank or rel

    def hrtf_file(self, rel: str) -> str:
        return self.hrtf or rel

    def ambience_file(self, rel: str) -> str:
        """An ambience recording, named relative to the ambience folder."""
        return os.path.normpath(os.path.join(self.ambience, rel)) if self.ambience else rel

    def resolve(self, recipe: "SceneRecipe") -> "SceneRecipe":
        """The recipe with the files it names as paths on this machine."""
        if not self.corpus and not self.bank and not self.hrtf and not self.ambience:
            return recipe
        sources = tuple(replace(s, audio=self.clip(s.audio)) for s in recipe.sources)
        bank = None if recipe.bank is None else replace(recipe.bank, path=self.bank_file(recipe.bank.path))
        here = [a if not a.hrtf else replace(a, hrtf=self.hrtf_file(a.hrtf)) for a in (recipe.array, *recipe.receivers)]
        noise = tuple(replace(n, file=None if n.file is None else self.ambience_file(n.file),
                              clips=tuple((self.clip(c[0]), *c[1:]) for c in n.clips)) for n in recipe.noise)
        return replace(recipe, sources=sources, bank=bank, array=here[0], receivers=tuple(here[1:]), noise=noise)

    def path(self, root: str, name: str) -> str:
        """A file a recipe names (``root``: ``corpus``, ``ambience``, ``bank``, ``hrtf``) as
        a path on this machine."""
        return {"corpus": self.clip, "ambience": self.ambience_file, "bank": self.bank_file,
                "hrtf": self.hrtf_file}[root](name)

    def inputs(self, recipes) -> list[tuple[str, str]]:
        """[(name as the plan says it, path here)] of every file ``recipes`` read, sorted."""
        return sorted({(name, self.path(root, name)) for r in recipes for root, name in r.input_files()})


def plan_roots(cfg, home) -> Roots:
    """Where the files of ``cfg``'s recipes are on this machine: the corpus folder, the
    RIR bank (the built-in ones in ``home``, the dataset folder's
    :class:`~tsel_data.store.layout.Layout`), a binaural receiver's HRTF and the ambience
    folder. ``cfg``: a :class:`~tsel_data.config.Config` (read, not imported: the render
    job needs the roots, not the config layer's sampler)."""
    corpus = {BUILTIN_DEMO: home.demo_corpus, BUILTIN_DEMO_RECORDED: home.demo_recordings}.get(cfg.corpus.dir,
                                                                                           cfg.corpus.dir)
    bank = home.demo_bank if cfg.room.bank == BUILTIN_DEMO_BANK else cfg.room.bank
    return Roots(*(os.path.abspath(os.path.expanduser(p)) if p else ""
                   for p in (corpus, bank, cfg.array.hrtf, cfg.noise.ambience)))


def array_frame_position_at(recipe: SceneRecipe, s: Source, t) -> np.ndarray:
    """Array-frame position(s) [..., 3] of a room-simulated source at time(s) t."""
    return room_to_array(s.position_at(t), recipe.array.centre, recipe.array.yaw)


def _inside(pts, dims, margin: float, what: str) -> None:
    for p in pts:
        if any(p[k] < margin - 1e-9 or p[k] > dims[k] - margin + 1e-9 for k in range(3)):
            raise GeometryError(
                f"{what} at {[round(float(v), 3) for v in p]} is outside room {[round(float(d), 3) for d in dims]} "
                f"with a {margin} m wall margin"
            )


def read_plan(path) -> list[SceneRecipe]:
    """Every recipe of a ``plan/{split}.jsonl`` file, in order (DatasetError naming the
    line when one is damaged)."""
    out = []
    check_input(path, DatasetError, "plan again into a new --out")
    try:
        with open(path, "rb") as f:
            for n, raw in enumerate(f, 1):
                if not raw.strip():
                    continue
                out.append(recipe_from_line(path, n, raw))
    except OSError as e:
        raise DatasetError(f"{path}: cannot read the plan ({e.strerror or e}); plan again into a new --out") from None
    return out


def corpus_files(d: dict) -> list[tuple[str, str, list]]:
    """(file relative to the corpus, its id, its captions) of what a plan line (as plain
    data) reads from the corpus, in source order: a rendered scene's clips (its sources',
    then the clips its noise plays: babble talkers, a diffuse bed's spectrum, named by
    their file and without captions), or a recorded scene's recording and its label file
    (a recipe release lists and checks these)."""
    if d.get("kind") == RECORDED:
        stem = os.path.splitext(os.path.basename(d["audio"]))[0]
        return [(d["audio"], stem, []), (d["metadata"], f"{stem} labels", [])]
    sources = [(s["audio"], s["clip_id"], s["captions"]) for s in d["sources"]]
    mine = {name for name, _, _ in sources}
    noise = [c[0] for n in d.get("noise", ()) for c in n.get("clips", ()) if c[0] not in mine]
    return sources + [(name, os.path.splitext(os.path.basename(name))[0], []) for name in dict.fromkeys(noise)]


def recipe_from_dict(d: dict):
    """A plan line's recipe: a rendered scene's :class:`SceneRecipe`, or a recorded
    scene's (``"kind": "recorded"``, :class:`~tsel_data.scene.recorded.RecordedRecipe`)."""
    return RecordedRecipe.from_dict(d) if d.get("kind") == RECORDED else SceneRecipe.from_dict(d)


def recipe_from_line(path, n: int, raw: bytes | str) -> SceneRecipe:
    """The recipe on line ``n`` (1-based) of plan file ``path`` (DatasetError naming the
    line when it is damaged)."""
    try:
        return recipe_from_dict(json.loads(raw.decode("utf-8") if isinstance(raw, bytes) else raw))
    except (ValueError, KeyError, TypeError, IndexError, AttributeError, RecursionError) as e:
        raise DatasetError(f"{path}:{n}: damaged scene recipe ({type(e).__name__}: {str(e)[:80]}); plan again "
                           f"into a new --out") from None
