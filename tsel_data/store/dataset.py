"""``dataset.json``: what a finished dataset holds (docs/format.md, "dataset.json").

:func:`dataset_doc` builds the document ``finalize`` writes; :func:`load_dataset_doc`
reads it back as a :class:`DatasetDoc`; :func:`shard_attrs` are the attributes every
shard carries. :data:`CONVENTIONS` is the conventions block, in words.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace

from ..choices import SPLIT_NAME
from ..core.files import check_input, name_problem
from ..core.version import RENDERER, __version__
from ..errors import DatasetError
from ..receivers import RECEIVERS, receiver
from .layout import DATASET_FILE

FORMAT_VERSION = 1

CONVENTIONS = {
    "array_frame": "right-handed, origin at the array centre, x front, y left, z up",
    "azimuth": "degrees, counter-clockwise from +x seen from above, [-180, 180)",
    "elevation": "degrees above the horizontal plane, [-90, 90]",
    "distance": "metres from the array centre",
    "label_frames": "frame k covers [k*hop, (k+1)*hop); position at the frame centre",
    "foa": RECEIVERS["foa"].convention,
    "mic4": RECEIVERS["mic4"].convention,
    "sources": "source 0 is the target; NaN positions for absent or non-directional sources",
}


def conventions(fmt: str, others=()) -> dict:
    """The conventions block of a dataset of receiver ``fmt`` (and the ``others`` heard in
    the same pass): the shared ones, and each receiver's own (mic4 and foa datasets keep
    format 1's block)."""
    names = [n for n in (fmt, *others) if n not in CONVENTIONS]
    if not names:
        return CONVENTIONS
    return {**{k: v for k, v in CONVENTIONS.items() if k != "sources"},
            **{receiver(n).name: receiver(n).convention for n in names}, "sources": CONVENTIONS["sources"]}


def shard_attrs(fs: int, label_hop: float, fmt: str, coding: str = "float32", channels=None,
                receivers: dict | None = None) -> dict:
    """The attributes of every shard (HDF5 attrs, JSON header) and of ``dataset.json``;
    ``audio_coding`` only when it is not float32 (format version 1's only coding).
    channels: the receiver's channel names (default: its fixed ones; a custom array's
    follow its capsules). receivers: further receivers heard in the same pass, name ->
    channel names (``receivers``, only when there are some)."""
    names = list(channels) if channels is not None else list(receiver(fmt).channels())
    attrs = {"fs": fs, "label_hop": label_hop, "format": fmt, "channel_names": names,
             "format_version": FORMAT_VERSION}
    if receivers:
        attrs["receivers"] = {k: list(v) for k, v in receivers.items()}
    if coding != "float32":
        attrs["audio_coding"] = str(coding)
    return attrs


@dataclass(frozen=True)
class ShardEntry:
    """One shard in ``dataset.json``: its files (relative to the dataset folder), scene
    count and checksums."""

    file: str
    json: str
    scenes: int
    sha256: str = ""
    json_sha256: str = ""
    first: int | None = None  # index of its first scene (None: after the shards before it)

    def to_json(self) -> dict:
        return {"file": self.file, "json": self.json, "scenes": self.scenes, "sha256": self.sha256,
                "json_sha256": self.json_sha256}


@dataclass(frozen=True)
class DatasetDoc:
    """A parsed ``dataset.json``. ``splits``: {name: [ShardEntry]} in file order;
    ``counts``: {name: scenes the split lists}; ``raw``: the whole document.
    ``finished``: False for the finished shards of a dataset still being made
    (:func:`~tsel_data.store.plans.unfinished_doc`); ``planned``: {name: scenes the
    plan asks}, ``shards_planned``: shards the plan asks in all (then)."""

    path: str
    fs: int
    label_hop: float
    format: str
    channel_names: list
    config: dict
    splits: dict
    counts: dict
    raw: dict = field(default_factory=dict, repr=False)
    finished: bool = True
    planned: dict = field(default_factory=dict)
    shards_planned: int = 0
    receivers: dict = field(default_factory=dict)  # further receivers of one pass: name -> channel names

    def receiver_names(self) -> list[str]:
        """Every receiver whose audio the dataset holds: ``format`` first."""
        return [self.format, *self.receivers]

    def heard_by(self, name: str | None) -> "DatasetDoc":
        """This document as seen by receiver ``name`` of a several-receiver dataset: its
        ``format`` and ``channel_names`` are that receiver's, the others in ``receivers``
        (``name`` None or ``format``: this one)."""
        if name is None or name == self.format:
            return self
        if name not in self.receivers:
            raise DatasetError(f"{self.path}: no receiver {name!r} in the dataset; it holds "
                               f"{', '.join(self.receiver_names())}")
        others = {self.format: list(self.channel_names), **{k: v for k, v in self.receivers.items() if k != name}}
        return replace(self, format=name, channel_names=list(self.receivers[name]), receivers=others)

    def shards(self, split: str) -> list[ShardEntry]:
        return self.splits[split]

    def unfinished_note(self, root: str) -> str | None:
        """One line for tools that read a dataset still being made (None when finished)."""
        if self.finished:
            return None
        done = sum(len(v) for v in self.splits.values())
        return (f"{root} is still being made (no dataset.json yet): {done} of {self.shards_planned} shards "
                f"finished, " + ", ".join(f"{s} {self.counts[s]} of {n}" for s, n in self.planned.items())
                + " scenes; showing those")


def dataset_doc(config: dict, seed: int, attrs: dict, splits: dict[str, list[ShardEntry]]) -> dict:
    """The document ``finalize`` writes: tool, version, renderer, format version, conventions,
    the resolved config, seed, shard attributes, and per split its scene count and shards."""
    return {"tool": "tsel-data", "version": __version__, "renderer": RENDERER, "format_version": FORMAT_VERSION,
            "conventions": conventions(attrs["format"], attrs.get("receivers") or ()), "config": config, "seed": seed, **attrs,
            "splits": {s: {"scenes": sum(e.scenes for e in entries), "shards": [e.to_json() for e in entries]}
                       for s, entries in splits.items()}}


def _typed(value, kind: type, where: str, path: str, root: str):
    """``value`` if it is a ``kind`` (an int for float; never a bool), else the DatasetError
    of a hand-edited or damaged document: a scene count of "12" is not read as 12."""
    ok = isinstance(value, (int, float) if kind is float else kind) and not isinstance(value, bool)
    if not ok or (kind is int and value < 0):
        what = "missing" if value is None else f"{value!r}, not {'a count' if kind is int else kind.__name__}"
        raise DatasetError(f"{path}: incomplete or damaged ({where} is {what}); the file was edited or cut short: "
                           f"rerun `tsel finalize {root}`")
    return value


def load_dataset_doc(root: str) -> DatasetDoc:
    """Parse ``ROOT/dataset.json`` (DatasetError with a clear message if absent or bad)."""
    root = os.fspath(root)
    path = os.path.join(root, DATASET_FILE)
    check_input(root, DatasetError, "give the --out folder of `tsel generate`", folder=True)
    if not os.path.isdir(root):
        raise DatasetError(f"{root}: no such dataset directory")
    if not os.path.exists(path):
        raise DatasetError(f"{path} not found: {root} is not a tsel-data dataset (or generation has not finished)")
    check_input(path, DatasetError, f"rerun `tsel finalize {root}`")
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path}: not valid JSON ({e})") from None
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not UTF-8 text; rerun `tsel finalize {root}`") from None
    except (RecursionError, ValueError) as e:  # lists nested thousands deep, a number of 5,000 digits
        raise DatasetError(f"{path}: damaged ({e}); rerun `tsel finalize {root}`") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("splits"), dict):
        raise DatasetError(f"{path}: no 'splits' entry; is this a tsel-data dataset.json?")
    try:
        splits, counts = {}, {}
        for name, s in doc["splits"].items():
            if not SPLIT_NAME.fullmatch(name):  # a split names folders of the dataset and of its exports
                raise DatasetError(f"{path}: split {name!r} is not a plain name (letters, digits, _ or -); the file "
                                   f"was edited: rerun `tsel finalize {root}`")
            shards = s.get("shards") or []
            for k, e in enumerate(shards):
                where = f"splits.{name}.shards[{k}]"
                for key, kind in (("file", str), ("json", str), ("scenes", int), ("sha256", str), ("json_sha256", str)):
                    if key in e or key in ("file", "json", "scenes"):
                        _typed(e.get(key), kind, f"{where}.{key}", path, root)
                for key in ("file", "json"):  # a name read from the file stays inside the dataset
                    why = name_problem(e[key])
                    if why:
                        raise DatasetError(f"{path}: {where}.{key} {e[key]!r} {why}; the file was edited: rerun "
                                           f"`tsel finalize {root}`")
            splits[name] = [ShardEntry(e["file"], e["json"], e["scenes"], e.get("sha256", ""),
                                       e.get("json_sha256", "")) for e in shards]
            counts[name] = _typed(s.get("scenes", 0), int, f"splits.{name}.scenes", path, root)
        _typed(doc.get("fs", 24000), int, "fs", path, root)
        _typed(doc.get("label_hop", 0.1), float, "label_hop", path, root)
        return DatasetDoc(path=path, fs=int(doc.get("fs", 24000)), label_hop=float(doc.get("label_hop", 0.1)),
                          format=str(doc.get("format", "")), channel_names=list(doc.get("channel_names") or []),
                          config=doc.get("config") if isinstance(doc.get("config"), dict) else {},
                          splits=splits, counts=counts, raw=doc,
                          receivers={str(k): list(v) for k, v in (doc.get("receivers") or {}).items()})
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise DatasetError(f"{path}: incomplete or damaged ({type(e).__name__}: {e}); rerun "
                           f"`tsel finalize {root}`") from None
