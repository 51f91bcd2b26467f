"""Read a generated dataset: ``open_dataset(DIR, split)`` for trainers and tools.

The reader opens nothing heavy up front: it reads ``dataset.json``, checks that the
split and its shard files exist, and opens each HDF5 shard on first access *in the
current process*. Pickling keeps only paths (``__getstate__`` drops the handles), and a
handle opened before a ``fork`` is never reused in the child (the owning pid is
checked), so a :class:`SceneDataset` is safe in PyTorch ``DataLoader`` workers.

Layout read here: docs/format.md (``{split}/shard-NNNNN.h5`` + ``.json``).
"""
from __future__ import annotations

import bisect
import json
import os
from dataclasses import dataclass
from typing import Iterator

import h5py
import numpy as np

from ..choices import AudioCoding
from ..core.files import check_input
from ..core.h5str import as_str, as_strs
from ..errors import DatasetError
from .codings import coding_of, decode
from .dataset import DatasetDoc, load_dataset_doc
from .layout import RECEIVERS_GROUP, Layout
from .plans import has_plan, unfinished_doc
from .records import LABEL_KEYS, SceneRecord
from .scene import Scene


@dataclass
class _ShardMeta:
    """What the reader keeps of an open shard: everything but the audio, and its handle."""

    labels: dict
    mics: np.ndarray
    queries: list
    ids: list
    audio: h5py.Dataset
    coding: str
    raw_chunks: bool
    fs: int
    label_hop: float
    format: str
    query_columns: dict | None = None  # QUERY_COLUMNS of shards with extended queries


def _raw_chunks(ds: h5py.Dataset) -> bool:
    """Whether scene i is exactly chunk (i, 0, 0), unfiltered, little-endian: as the
    writer makes float32 and int16 audio."""
    return (ds.ndim == 3 and ds.chunks == (1, *ds.shape[1:]) and ds.id.get_create_plist().get_nfilters() == 0
            and ds.dtype.byteorder in ("<", "=") and ds.dtype in (np.dtype("<f4"), np.dtype("<i2"))
            and np.little_endian)


class SceneDataset:
    """Random access over the scenes of one split (``len``, ``[i]``, iteration).

    ``ds[i]`` reads one scene (one HDF5 chunk of audio plus its labels);
    ``ds.by_id(scene_id)`` looks a scene up by id; ``ds.records()`` iterates the JSON
    records without touching audio. Negative indices count from the end.
    """

    def __init__(self, root: str, split: str, *, load_records: bool = True, unfinished: bool = False,
                 receiver: str | None = None):
        self.root = os.fspath(root)
        self.split = split
        self.load_records = load_records
        self.doc: DatasetDoc = dataset_doc(self.root, unfinished)
        if split not in self.doc.splits:
            have = ", ".join(sorted(self.doc.splits)) or "none"
            raise DatasetError(f"{self.root}: no split {split!r} in dataset.json; available splits: {have}")
        self.shards = list(self.doc.shards(split))
        missing = [s.file for s in self.shards if not os.path.exists(os.path.join(self.root, s.file))]
        if missing:
            raise DatasetError(
                f"{self.root}: split {split!r} is incomplete: {len(missing)} shard file(s) missing "
                f"(first: {missing[0]}); re-run `tsel generate` with the same --out to resume"
            )
        self._starts = list(np.cumsum([0] + [s.scenes for s in self.shards]))
        # each shard's first scene index in the split (not its position, while shards are missing)
        self._first = [int(self._starts[k]) if s.first is None else s.first for k, s in enumerate(self.shards)]
        self.fs = self.doc.fs
        self.label_hop = self.doc.label_hop
        self.format = self.doc.format
        self.channel_names = list(self.doc.channel_names)
        # a dataset heard by several receivers: whose audio ``audio`` is (default the first)
        self._group = ""
        if receiver is not None and receiver != self.doc.format:
            if receiver not in self.doc.receivers:
                have = ", ".join(self.doc.receiver_names())
                raise DatasetError(f"{self.root}: no receiver {receiver!r} in the dataset; it holds {have}")
            self.format, self.channel_names = receiver, list(self.doc.receivers[receiver])
            self._group = f"{RECEIVERS_GROUP}/{receiver}/"
        self._reset_handles()

    @property
    def seed(self) -> int:
        """The dataset seed."""
        return int(self.doc.raw.get("seed", 0))

    @property
    def caption_similarity(self) -> float:
        """The ambiguity guard the dataset was planned with (``scene.caption_similarity``)."""
        return float((self.doc.config.get("scene") or {}).get("caption_similarity", 0.5))

    @property
    def similarity(self) -> str:
        """The caption similarity the dataset was planned with (``scene.similarity``)."""
        return str((self.doc.config.get("scene") or {}).get("similarity", "words"))

    # --- process-local state --------------------------------------------------------
    def _reset_handles(self) -> None:
        self._pid = os.getpid()
        self._h5: dict[int, h5py.File] = {}
        self._json: dict[int, list] = {}  # per shard: the JSON records, parsed on access
        self._meta: dict[int, _ShardMeta] = {}
        self._ids: dict[str, int] | None = None

    def __getstate__(self):
        state = self.__dict__.copy()
        for k in ("_h5", "_json", "_meta", "_ids", "_pid"):
            state.pop(k, None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._reset_handles()

    def _file(self, k: int) -> h5py.File:
        if self._pid != os.getpid():
            # Inherited across fork: the parent's HDF5 handles must not be used here.
            self._reset_handles()
        f = self._h5.get(k)
        if f is None:
            f = self._h5[k] = open_shard(os.path.join(self.root, self.shards[k].file))
        return f

    def damaged(self, k: int, why: str, json_file: bool = False) -> DatasetError:
        """The one error of a shard whose files hold the wrong shape (every reader of a
        dataset meets a damaged shard here, and says it the same way)."""
        rel = self.shards[k].json if json_file else self.shards[k].file
        return DatasetError(f"{os.path.join(self.root, rel)}: damaged shard ({why}); `tsel check {self.root}` lists "
                            f"every damaged file: delete them, then run `tsel render {self.root}` and `tsel finalize "
                            f"{self.root}`")

    def finite(self, scene: Scene) -> Scene:
        """``scene`` (read with its audio) when every sample is finite, else the damaged-shard
        error naming its shard. Every reader that writes a scene's audio elsewhere or
        computes on it (exports, ``inspect``, ``verify``) asks: no NaN ever leaves a
        dataset. Not the reader's own path: it costs as much as reading the scene."""
        if scene.audio is not None and not np.isfinite(scene.audio).all():
            raise self.damaged(self.locate(scene.index)[0], f"scene {scene.scene_id}'s audio holds NaN or Inf samples")
        return scene

    def _records(self, k: int) -> list:
        recs = self._json.get(k)
        if recs is None:
            rel = self.shards[k].json
            recs = []
            if rel and self.load_records:
                path = os.path.join(self.root, rel)
                check_input(path, DatasetError, "a shard's JSON is a file: render the shard again")
                try:
                    with open(path, encoding="utf-8") as fh:
                        doc = json.load(fh)
                except FileNotFoundError:
                    raise DatasetError(f"{path}: shard labels missing; regenerate the dataset") from None
                except (json.JSONDecodeError, UnicodeDecodeError) as e:
                    raise DatasetError(f"{path}: not valid JSON ({e})") from None
                except (ValueError, RecursionError) as e:  # a number of 5,000 digits, lists nested 5,000 deep
                    raise self.damaged(k, f"unreadable JSON: {e}", json_file=True) from None
                recs = doc.get("scenes") if isinstance(doc, dict) else None
                if not isinstance(recs, list) or not all(isinstance(r, dict) for r in recs):
                    raise self.damaged(k, "its JSON is not {\"scenes\": [one object per scene]}", json_file=True)
            self._json[k] = recs
        return recs

    def _record(self, k: int, r: int) -> SceneRecord | None:
        recs = self._records(k)
        if r >= len(recs):
            return None
        if not isinstance(recs[r], SceneRecord):
            try:
                rec = SceneRecord.from_json(recs[r])  # parsed once, when first asked for
            except (ValueError, TypeError, KeyError, IndexError, AttributeError) as e:
                raise self.damaged(k, f"scene {r}'s record: {e}", json_file=True) from None
            if not rec.sources:
                raise self.damaged(k, f"scene {r}'s record lists no sources", json_file=True)
            recs[r] = rec
        return recs[r]

    def _shard(self, k: int) -> "_ShardMeta":
        """Everything of shard k but the audio, read once per process (labels are small)."""
        f = self._file(k)
        m = self._meta.get(k)
        if m is None:
            try:
                m = self._read_meta(f)
            except (KeyError, ValueError, TypeError, IndexError, AttributeError, OSError) as e:
                raise self.damaged(k, str(e).split(" (")[0] if isinstance(e, KeyError) else str(e)) from None
            self._check_pair(k, m.ids)
            self._meta[k] = m
        return m

    def _read_meta(self, f: h5py.File) -> "_ShardMeta":
        """A shard's metadata, its shapes checked: N scenes of S sources over F frames."""
        g = self._group
        need = [f"labels/{key}" for key in (*LABEL_KEYS, "active")] + [g + "mic_positions", "query", "scene_id",
                                                                        g + "audio"]
        absent = [name for name in need if name not in f]
        if absent:
            raise ValueError(f"no {', '.join(absent)}")
        labels = {key: f["labels"][key][()] for key in (*LABEL_KEYS, "active")}
        ids = list(f["scene_id"].asstr()[()])
        n = len(ids)
        shape = labels["azimuth"].shape
        if len(shape) != 3 or shape[0] != n or shape[1] < 1 or any(v.shape != shape for v in labels.values()):
            raise ValueError(f"labels of shapes {sorted({str(list(v.shape)) for v in labels.values()})} for {n} "
                             f"scenes; expected [scenes, sources, frames] each")
        mics, audio = f[g + "mic_positions"][()], f[g + "audio"]
        if mics.ndim != 3 or mics.shape[0] != n or mics.shape[2] != 3 or not audio.shape or audio.shape[0] != n:
            raise ValueError(f"mic_positions of shape {list(mics.shape)} and audio of shape {list(audio.shape)} "
                             f"for {n} scenes")
        queries = list(f["query"].asstr()[()])
        columns = None
        if "query_type" in f:
            columns = {**{c: list(f[c].asstr()[()]) for c in ("query_type", "query_relation", "pairing")},
                       "query_margin": f["query_margin"][()].astype(float).tolist()}
        if len(queries) != n or any(len(v) != n for v in (columns or {}).values()):
            raise ValueError(f"query columns of another length than its {n} scenes")
        return _ShardMeta(
            labels=labels, mics=mics.astype(np.float32), queries=queries, ids=ids, audio=audio,
            coding=coding_of(audio), raw_chunks=_raw_chunks(audio),
            fs=int(f.attrs.get("fs", self.fs)), label_hop=float(f.attrs.get("label_hop", self.label_hop)),
            format=self.format if g else as_str(f.attrs.get("format"), self.format), query_columns=columns)

    def _check_pair(self, k: int, ids: list[str]) -> None:
        """A shard's HDF5 and JSON files hold the same scenes, as many as dataset.json says
        (swapped or replaced files would pair one scene's audio with another's record)."""
        sh = self.shards[k]
        recs = self._records(k)
        json_ids = [r.scene_id if isinstance(r, SceneRecord) else r.get("scene_id") for r in recs]
        if len(ids) != sh.scenes or (self.load_records and json_ids != ids):
            raise DatasetError(f"{os.path.join(self.root, sh.file)} and {sh.json} do not hold the same scenes as "
                               f"dataset.json lists ({len(ids)} in the HDF5 file, {sh.scenes} listed); the shard's "
                               f"files were replaced or mixed up: `tsel check {self.root}` tells which, then render "
                               f"them again")

    def close(self) -> None:
        """Close every open shard of this process."""
        if self._pid == os.getpid():
            for f in self._h5.values():
                f.close()
        self._reset_handles()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # --- access ---------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self._starts[-1])

    def locate(self, i: int) -> tuple[int, int]:
        """Global index -> (shard number, row in shard)."""
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"scene index {i} out of range for split {self.split!r} with {n} scenes")
        k = bisect.bisect_right(self._starts, i) - 1
        return k, i - self._starts[k]

    def __getitem__(self, i: int) -> Scene:
        return self.get(int(i))

    def get(self, i: int, audio: bool = True) -> Scene:
        """Scene ``i``; ``audio=False`` skips the audio read (labels and metadata only)."""
        k, r = self.locate(i)
        i = self._first[k] + r
        m = self._shard(k)
        rec = self._record(k, r)
        # Shards pad S to their largest scene; trim to this scene's own sources.
        n_src = len(rec.sources) if rec is not None and rec.sources else m.labels["azimuth"].shape[1]
        if n_src > m.labels["azimuth"].shape[1]:
            raise self.damaged(k, f"scene {r}'s record lists {n_src} sources, its labels "
                                  f"{m.labels['azimuth'].shape[1]}")
        lab = m.labels
        qc, margin = m.query_columns, float("nan")
        if qc is not None:
            qtype, qrel, pairing = qc["query_type"][r], qc["query_relation"][r] or None, qc["pairing"][r]
            margin = qc["query_margin"][r]
        elif rec is not None:
            qtype, qrel, pairing = rec.query_type, rec.query_relation, rec.pairing
        else:
            qtype, qrel, pairing = "caption", None, "random"
        return Scene(
            scene_id=m.ids[r],
            split=self.split,
            index=i,
            query=m.queries[r],
            audio=self._audio(m, r) if audio else None,
            azimuth=lab["azimuth"][r, :n_src].astype(np.float32),
            elevation=lab["elevation"][r, :n_src].astype(np.float32),
            distance=lab["distance"][r, :n_src].astype(np.float32),
            active=lab["active"][r, :n_src].astype(bool),
            mic_positions=m.mics[r].copy(),
            fs=m.fs,
            label_hop=m.label_hop,
            format=m.format,
            record=rec,
            query_type=qtype,
            query_relation=qrel,
            pairing=pairing,
            query_margin=margin,
        )

    @staticmethod
    def _audio(m: "_ShardMeta", r: int, out: np.ndarray | None = None) -> np.ndarray:
        if m.coding == AudioCoding.FLAC:
            return decode(m.audio[r], m.coding, out)
        shape = m.audio.shape[1:]
        if out is None:
            out = np.empty(shape, dtype=np.float32)
        if m.raw_chunks:
            # One unfiltered chunk per scene: its bytes are the samples. Reading the chunk
            # skips HDF5's selection and conversion machinery (5x faster than audio[r]).
            if m.coding == AudioCoding.FLOAT32:
                m.audio.id.read_direct_chunk((r, 0, 0), out=out.reshape(-1).view(np.uint8))
                return out
            pcm = np.empty(shape, dtype=np.int16)
            m.audio.id.read_direct_chunk((r, 0, 0), out=pcm.reshape(-1).view(np.uint8))
            return decode(pcm, m.coding, out)
        if m.coding == AudioCoding.FLOAT32:
            m.audio.read_direct(out, np.s_[r])
            return out
        return decode(m.audio[r], m.coding, out)

    def read_audio(self, indices, out: np.ndarray | None = None) -> np.ndarray:
        """The audio of several scenes as float32 [B, C, T], into ``out`` when given (a
        buffer reused across batches saves allocating and zeroing 4 MB per scene)."""
        indices = list(indices)
        for b, i in enumerate(indices):
            k, r = self.locate(int(i))
            m = self._shard(k)
            if out is None:
                out = np.empty((len(indices), *self._audio_shape(m)), dtype=np.float32)
            self._audio(m, r, out[b])
        return out

    @property
    def audio_shape(self) -> tuple[int, int]:
        """(C, T) of every scene's audio in this split (opens the first shard)."""
        return self._audio_shape(self._shard(0))

    @staticmethod
    def _audio_shape(m: "_ShardMeta") -> tuple:
        if m.coding == AudioCoding.FLAC:
            return tuple(int(v) for v in m.audio.attrs["audio_shape"])
        return tuple(m.audio.shape[1:])

    def __iter__(self) -> Iterator[Scene]:
        for i in range(len(self)):
            yield self.get(i)

    def iter_labels(self) -> Iterator[Scene]:
        """Every scene without its audio (fast: labels and records only)."""
        for i in range(len(self)):
            yield self.get(i, audio=False)

    def records(self) -> Iterator[SceneRecord]:
        """The record of every scene, in order, without opening any HDF5 file (a generator)."""
        for k in range(len(self.shards)):
            for r in range(len(self._records(k))):
                yield self._record(k, r)

    def position_of(self, index: int) -> int:
        """The position (``ds[position]``) of the scene with index ``index`` in its split:
        the same number for a finished dataset; IndexError while its shard is missing."""
        for k, first in enumerate(self._first):
            if first <= index < first + self.shards[k].scenes:
                return int(self._starts[k]) + index - first
        raise IndexError(index)

    def scene_ids(self) -> list[str]:
        ids = self._id_index()
        return sorted(ids, key=ids.__getitem__)

    def index_of(self, scene_id: str) -> int:
        """Global index of ``scene_id`` in this split (DatasetError if absent)."""
        ids = self._id_index()
        if scene_id not in ids:
            raise DatasetError(f"{self.root}: no scene {scene_id!r} in split {self.split!r} ({len(self)} scenes)")
        return ids[scene_id]

    def by_id(self, scene_id: str, audio: bool = True) -> Scene:
        return self.get(self.index_of(scene_id), audio=audio)

    def __contains__(self, scene_id: str) -> bool:
        return scene_id in self._id_index()

    def _id_index(self) -> dict[str, int]:
        if self._pid != os.getpid():
            self._reset_handles()
        if self._ids is None:
            ids: dict[str, int] = {}
            for k in range(len(self.shards)):
                for r, sid in enumerate(self._shard(k).ids):
                    ids[sid] = self._starts[k] + r
            self._ids = ids
        return self._ids

    def __repr__(self) -> str:
        return f"SceneDataset({self.root!r}, split={self.split!r}, scenes={len(self)}, format={self.format!r})"


def open_shard(path: str) -> h5py.File:
    """An HDF5 shard opened for reading (DatasetError, one line, when it is damaged, or
    no regular file: a FIFO would keep HDF5 waiting for a writer)."""
    check_input(path, DatasetError, "a shard is a file: render it again")
    try:
        return h5py.File(path, "r")
    except OSError as e:
        raise DatasetError(f"{path}: cannot open shard ({e}); the file is damaged, regenerate it") from None


def shard_scene_ids(path: str) -> list[str]:
    """The scene ids an HDF5 shard holds, in order (without opening its audio)."""
    with open_shard(path) as h:
        return as_strs(h["scene_id"][()])


def load_manifest(root: str) -> dict:
    """The parsed ``ROOT/dataset.json`` as plain data (DatasetError if absent or bad);
    :func:`~tsel_data.store.dataset.load_dataset_doc` gives it typed."""
    return load_dataset_doc(root).raw


def list_splits(root: str, unfinished: bool = False) -> list[str]:
    """Split names of a dataset, in dataset.json order (``unfinished``: also of a
    dataset still being made, in plan order)."""
    return list(dataset_doc(root, unfinished).splits)


def dataset_doc(root: str, unfinished: bool = False) -> DatasetDoc:
    """``dataset.json`` parsed; with ``unfinished``, a dataset still being made (a plan,
    no ``dataset.json``) gives the doc of its finished shards (``doc.finished`` False)."""
    root = os.fspath(root)
    layout = Layout(root)
    if unfinished and not os.path.exists(layout.dataset_file) and has_plan(layout):
        return unfinished_doc(layout)
    return load_dataset_doc(root)


def open_dataset(root: str, split: str = "train", **kwargs) -> SceneDataset:
    """Open one split of a dataset folder for reading.

    Parameters
    ----------
    root : str
        The dataset folder (``tsel generate --out``).
    split : str
    load_records : bool, keyword
        Parse the JSON records (``Scene.record``); False leaves them None.
    unfinished : bool, keyword
        Also open a dataset still being made (no ``dataset.json`` yet): the scenes of
        the shards finished so far, in index order (``ds.doc.finished`` is False;
        ``Scene.index`` is the scene's index in the split, ``ds.position_of(index)``
        finds it). Trainers should read finished datasets only.
    receiver : str, keyword
        For a dataset heard by several receivers (``scene.receivers``): whose audio,
        channel names and ``mic_positions`` scenes carry (default the first,
        ``dataset.json``'s ``format``); labels are the same for all.

    Returns
    -------
    SceneDataset
        Lazy: only ``dataset.json`` is read now; safe to pass to DataLoader workers.

    Raises
    ------
    DatasetError
        No such folder, split, or missing shard files.
    """
    return SceneDataset(root, split, **kwargs)
