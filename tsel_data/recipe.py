"""Scene recipes: plain, frozen data that fully determine one scene.

``render(recipe)`` depends on nothing but the recipe and the files it names, so a
dataset can be planned once, inspected before any audio exists, and rendered in any
order on any number of workers. Recipes round-trip through JSON (``to_dict`` /
``from_dict``); the plan stage writes one per line to ``plan/{split}.jsonl``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, fields

import numpy as np

from .errors import GeometryError
from .geometry import FORMATS, mic_positions, room_to_array

Vec3 = tuple[float, float, float]

SCENARIOS = ("two-directional", "directional+additive")


@dataclass(frozen=True)
class Room:
    """A shoebox room: ``dims`` (Lx, Ly, Lz) in metres and the requested RT60 in seconds."""

    dims: Vec3
    rt60: float


@dataclass(frozen=True)
class ArrayPose:
    """Where the array is and how it is turned.

    format: ``mic4`` | ``foa`` | ``tetra``. centre: room frame (m). yaw: degrees, the
    direction of the array's +x axis in the room frame. side: mic4 side length (m).
    """

    format: str
    centre: Vec3
    yaw: float
    side: float | None = None

    def mics(self) -> np.ndarray:
        """Channel positions [C, 3] in the array frame (metres)."""
        return mic_positions(self.format, self.side)


@dataclass(frozen=True)
class Source:
    """One sound event of a scene.

    role: ``target`` or ``interferer``. spatial: ``directional`` (rendered through the
    room) or ``additive`` (added to every channel unspatialised; no position).
    position: room frame (m) for a static directional source. path: for a moving
    source, knots ``(t, x, y, z)`` in the room frame, linearly interpolated in time.
    bank: for bank-rendered sources, a reference into an RIR bank (see banks docs).
    tir_db: target-to-interferer ratio at the array for interferers (dB), None for
    the target. seed: the stochastic parts of this source's rendering.
    """

    role: str
    clip_id: str
    audio: str
    captions: tuple[str, ...]
    spatial: str = "directional"
    offset: float = 0.0
    position: Vec3 | None = None
    path: tuple[tuple[float, float, float, float], ...] | None = None
    bank: dict | None = None
    tir_db: float | None = None

    @property
    def moving(self) -> bool:
        return bool(self.path) or bool(self.bank and len(self.bank.get("indices", ())) > 1)


@dataclass(frozen=True)
class SceneRecipe:
    """Everything needed to render one scene (target is ``sources[0]``)."""

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
    extra: dict = field(default_factory=dict)

    @property
    def target(self) -> Source:
        return self.sources[0]

    @property
    def n_samples(self) -> int:
        return int(round(self.duration * self.fs))

    @property
    def n_frames(self) -> int:
        return int(round(self.duration / self.label_hop))

    # --- serialisation -------------------------------------------------------------
    def to_dict(self) -> dict:
        # hand-written rather than dataclasses.asdict: planning 100k scenes is dominated
        # by serialisation otherwise
        a = self.array
        return {
            "scene_id": self.scene_id, "split": self.split, "index": self.index, "seed": self.seed,
            "scenario": self.scenario, "query": self.query,
            "array": {"format": a.format, "centre": list(a.centre), "yaw": a.yaw, "side": a.side},
            "sources": [_source_dict(s) for s in self.sources],
            "room": None if self.room is None else {"dims": list(self.room.dims), "rt60": self.room.rt60},
            "fs": self.fs, "duration": self.duration, "label_hop": self.label_hop, "rir_method": self.rir_method,
            "target_level_dbfs": self.target_level_dbfs, "activity_threshold_db": self.activity_threshold_db,
            "extra": _plain(self.extra),
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), ensure_ascii=False, separators=(",", ":"))

    @classmethod
    def from_dict(cls, d: dict) -> "SceneRecipe":
        d = dict(d)
        d["array"] = ArrayPose(**{**d["array"], "centre": tuple(d["array"]["centre"])})
        d["room"] = None if d.get("room") is None else Room(tuple(d["room"]["dims"]), d["room"]["rt60"])
        d["sources"] = tuple(_source_from_dict(s) for s in d["sources"])
        known = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in known})

    @classmethod
    def from_json(cls, line: str) -> "SceneRecipe":
        return cls.from_dict(json.loads(line))

    # --- validation ------------------------------------------------------------------
    def validate(self, wall_margin: float = 0.0) -> "SceneRecipe":
        """Raise GeometryError unless the scene can be realised; returns self."""
        if self.scenario not in SCENARIOS:
            raise GeometryError(f"{self.scene_id}: unknown scenario {self.scenario!r}; expected one of {SCENARIOS}")
        if self.array.format not in FORMATS:
            raise GeometryError(f"{self.scene_id}: unknown array format {self.array.format!r}")
        if not self.sources or self.sources[0].role != "target" or self.sources[0].spatial != "directional":
            raise GeometryError(f"{self.scene_id}: source 0 must be the directional target")
        if any(s.role != "interferer" for s in self.sources[1:]):
            raise GeometryError(f"{self.scene_id}: only source 0 may be the target")
        if self.room is not None:
            dims = self.room.dims
            _inside(_mic_room_positions(self.array), dims, 0.0, f"{self.scene_id}: array")
            for i, s in enumerate(self.sources):
                pts = source_points(s)
                if s.spatial == "directional" and s.bank is None and pts is None:
                    raise GeometryError(f"{self.scene_id}: source {i} is directional but has no position")
                if pts is not None:
                    _inside(pts, dims, wall_margin, f"{self.scene_id}: source {i}")
        return self


def source_points(s: Source):
    """Every room-frame point a source occupies (a sequence of (x, y, z)), or None."""
    if s.path:
        return [k[1:] for k in s.path]
    if s.position is not None:
        return [s.position]
    return None


def _mic_room_positions(a: ArrayPose):
    """Mic positions in the room frame, in plain Python (validation runs per planned scene)."""
    import math

    c, s = math.cos(math.radians(a.yaw)), math.sin(math.radians(a.yaw))
    if a.format == "mic4":
        r = a.side / math.sqrt(2.0)
        local = [(r * math.cos(math.radians(45 + 90 * k)), r * math.sin(math.radians(45 + 90 * k)), 0.0) for k in range(4)]
    elif a.format == "tetra":
        from .geometry import tetra_positions

        local = tetra_positions().tolist()
    else:
        local = [(0.0, 0.0, 0.0)]
    return [(a.centre[0] + c * x - s * y, a.centre[1] + s * x + c * y, a.centre[2] + z) for x, y, z in local]


def source_position_at(s: Source, t) -> np.ndarray:
    """Room-frame position(s) [..., 3] of a simulated source at time(s) t (seconds)."""
    t = np.asarray(t, dtype=np.float64)
    if s.path:
        knots = np.asarray(s.path, dtype=np.float64)
        return np.stack([np.interp(t, knots[:, 0], knots[:, k]) for k in (1, 2, 3)], axis=-1)
    return np.broadcast_to(np.asarray(s.position, dtype=np.float64), t.shape + (3,)).copy()


def array_frame_position_at(recipe: SceneRecipe, s: Source, t) -> np.ndarray:
    """Array-frame position(s) [..., 3] of a room-simulated source at time(s) t."""
    return room_to_array(source_position_at(s, t), recipe.array.centre, recipe.array.yaw)


def _inside(pts, dims, margin: float, what: str) -> None:
    for p in pts:
        if any(p[k] < margin - 1e-9 or p[k] > dims[k] - margin + 1e-9 for k in range(3)):
            raise GeometryError(
                f"{what} at {[round(float(v), 3) for v in p]} is outside room {[round(float(d), 3) for d in dims]} "
                f"with a {margin} m wall margin"
            )


def _source_from_dict(d: dict) -> Source:
    d = dict(d)
    d["captions"] = tuple(d["captions"])
    if d.get("position") is not None:
        d["position"] = tuple(d["position"])
    if d.get("path"):
        d["path"] = tuple(tuple(k) for k in d["path"])
    return Source(**d)


def _source_dict(s: Source) -> dict:
    return {
        "role": s.role, "clip_id": s.clip_id, "audio": s.audio, "captions": list(s.captions),
        "spatial": s.spatial, "offset": s.offset, "position": None if s.position is None else list(s.position),
        "path": None if not s.path else [list(k) for k in s.path], "bank": _plain(s.bank), "tir_db": s.tir_db,
    }


def _plain(x):
    """Tuples -> lists, numpy scalars -> Python, for JSON."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def read_plan(path) -> list[SceneRecipe]:
    with open(path, encoding="utf-8") as f:
        return [SceneRecipe.from_json(line) for line in f if line.strip()]
