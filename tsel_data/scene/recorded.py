"""The recipe of a scene cut from a real recording (docs/recorded.md): which recording,
which window of it, which of its sources is the target, and the query the labels made
true. Like a rendered scene's recipe it is plain data, one JSON line of the plan, and
names its files relative to the corpus folder: a recipe release of a recorded dataset
ships no audio and no labels, only where to find them in the user's own copy.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

KIND = "recorded"


@dataclass(frozen=True)
class SourceRef:
    """A source of the window (corpus/seld.py ``window_sources``): class index, the CSV's
    source column (an actor, or a track), and the ordinal among sources of that class and
    source column at once; its class name and caption wordings (the ontology's, kept here
    so the scene needs nothing but the recording and its labels)."""

    cls: int
    source: int
    ordinal: int
    name: str
    captions: tuple[str, ...]

    @property
    def key(self) -> tuple[int, int, int]:
        return (self.cls, self.source, self.ordinal)

    def to_dict(self) -> dict:
        return {"class": self.cls, "source": self.source, "ordinal": self.ordinal, "name": self.name,
                "captions": list(self.captions)}

    @classmethod
    def from_dict(cls, d: dict) -> "SourceRef":
        return cls(int(d["class"]), int(d["source"]), int(d["ordinal"]), str(d["name"]), tuple(d["captions"]))


@dataclass(frozen=True)
class RecordedRecipe:
    """One recorded scene. ``audio`` and ``metadata``: the recording and its label CSV,
    relative to the corpus folder; ``start``: its first label frame, ``frames`` how many
    (``label_hop`` s each); ``format``: the receiver the recording is; ``sources``: target
    first; the query as decided at planning (type, relation, evidence, every equally true
    wording); ``columns``: the CSV's columns when the config overrides the set's."""

    scene_id: str
    split: str
    index: int
    seed: int
    dataset: str
    audio: str
    metadata: str
    format: str
    start: int
    frames: int
    fs: int
    label_hop: float
    sources: tuple[SourceRef, ...]
    query: str
    query_type: str = "caption"
    query_relation: str | None = None
    query_evidence: dict | None = None
    query_alternatives: tuple[str, ...] = ()
    fold: int | None = None
    room: int | None = None
    columns: tuple[str, ...] = field(default=())

    kind = KIND

    @property
    def n_samples(self) -> int:
        return int(round(self.frames * self.label_hop * self.fs))

    @property
    def first_sample(self) -> int:
        return int(round(self.start * self.label_hop * self.fs))

    @property
    def duration(self) -> float:
        return self.frames * self.label_hop

    def input_files(self):
        """(root, name) of the files the scene reads: the recording and its labels."""
        return [("corpus", self.audio), ("corpus", self.metadata)]

    def to_dict(self) -> dict:
        d = {"kind": KIND, "scene_id": self.scene_id, "split": self.split, "index": self.index, "seed": self.seed,
             "dataset": self.dataset, "audio": self.audio, "metadata": self.metadata, "format": self.format,
             "start": self.start, "frames": self.frames, "fs": self.fs, "label_hop": self.label_hop,
             "sources": [s.to_dict() for s in self.sources], "query": self.query, "query_type": self.query_type,
             "query_relation": self.query_relation, "query_evidence": self.query_evidence,
             "query_alternatives": list(self.query_alternatives), "fold": self.fold, "room": self.room}
        if self.columns:
            d["columns"] = list(self.columns)
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), ensure_ascii=False, separators=(",", ":"))

    @classmethod
    def from_dict(cls, d: dict) -> "RecordedRecipe":
        return cls(scene_id=d["scene_id"], split=d["split"], index=int(d["index"]), seed=int(d["seed"]),
                   dataset=d["dataset"], audio=d["audio"], metadata=d["metadata"], format=d["format"],
                   start=int(d["start"]), frames=int(d["frames"]), fs=int(d["fs"]), label_hop=float(d["label_hop"]),
                   sources=tuple(SourceRef.from_dict(s) for s in d["sources"]), query=d["query"],
                   query_type=d.get("query_type") or "caption", query_relation=d.get("query_relation"),
                   query_evidence=d.get("query_evidence"),
                   query_alternatives=tuple(d.get("query_alternatives") or ()), fold=d.get("fold"),
                   room=d.get("room"), columns=tuple(d.get("columns") or ()))
