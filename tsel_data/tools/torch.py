"""PyTorch ``Dataset`` over a split: a generated dataset, or scenes rendered on the fly
(only importable when torch is installed).

torch is not a dependency of tsel-data: ``pip install 'tsel-data[baseline]'`` or your
own torch. Each item is a dict: ``audio`` float32 [C, T], ``azimuth``/``elevation``/
``distance`` float32 [S, F], ``active`` bool [S, F], ``class_index`` int64 [F] (target,
-1 where it has no position), ``gaussian`` float32 [F, 360] (target, σ = ``sigma``),
``accdoa`` float32 [S, F, 3], ``mic_positions`` float32 [C, 3], plus ``query``,
``query_type``, ``query_relation`` (``""`` for a caption, so PyTorch's default collate
takes every item), ``pairing`` (docs/queries.md), ``scene_id`` and
(``with_record=True``) ``record``.

HDF5 files and clips are opened lazily in each worker (see :mod:`tsel_data.store.reader`
and :mod:`tsel_data.job.onthefly`), so ``DataLoader(..., num_workers=N)`` works with fork and
spawn alike. Scenes of one split share C, T and F but not S: batch with :func:`collate`
when splits mix scenarios with different source counts, or when items hold records.

:class:`StreamingDataset` streams a WebDataset export (``tsel export webdataset``) instead:
an ``IterableDataset`` with a shuffle buffer, split between workers and ranks, epoch by
epoch (:mod:`tsel_data.tools.streaming`).
"""
from __future__ import annotations

import os

try:
    import torch
except ImportError as e:  # pragma: no cover - exercised only without torch
    raise ImportError("tsel_data.tools.torch needs PyTorch, which tsel-data does not install: "
                      "pip install 'tsel-data[baseline]' (or torch)") from e

import numpy as np

from ..runtime.pool import prepare_worker
from ..receivers import receiver
from ..store.reader import open_dataset
from .augment import channel_swaps, random_swap
from .labels import scene_targets
from .streaming import SceneStream

QUERIES = ("dataset", "any")


class Dataset(torch.utils.data.Dataset):
    """Map-style dataset over one split.

    Parameters
    ----------
    scenes : str or scene sequence
        A dataset folder (read with ``open_dataset(scenes, split)``), or any sequence of
        scenes with ``len`` and ``[i]``: an opened split, or a
        :class:`~tsel_data.job.onthefly.SceneSource` rendering scenes on the fly.
    split : str
        The split, when ``scenes`` is a folder.
    sigma : float
        Width of the Gaussian azimuth target, degrees.
    transform : callable, optional
        ``transform(item) -> item``.
    query : str
        ``"dataset"``: the scene's query as planned; ``"any"``: drawn per (seed, epoch,
        index) among the scene's queries that are as true and unambiguous as its own:
        for a caption, the target's captions that pass the dataset's ambiguity guard
        against every other source's captions; for a relational or composite query, the
        other wordings of the same relation (never a caption, which a same-kind
        distractor may make ambiguous). Records of extended queries list these
        (``query_alternatives``, decided with the dataset's own caption similarity).
    with_record : bool
        Add the scene's :class:`~tsel_data.store.records.SceneRecord` (batch with
        :func:`collate`).
    channel_swap : bool
        Channel-swap augmentation (:mod:`tsel_data.augment`): each item goes through one of
        its receiver's symmetries, drawn per (seed, epoch, index), its channels permuted and
        its labels transformed exactly; the item's ``channel_swap`` names it (``"az"``: as
        recorded). A receiver without symmetries is refused here, in one line.

    ``set_epoch(e)`` before each epoch draws epoch *e*'s scenes from an on-the-fly source
    (and its captions with ``query="any"``, its channel swaps); an index may also be a pair
    ``(epoch, i)``, which works with persistent workers too.
    """

    def __init__(self, scenes, split: str = "train", sigma: float = 5.0, transform=None, query: str = "dataset",
                 with_record: bool = False, channel_swap: bool = False):
        if query not in QUERIES:
            raise ValueError(f"query must be one of {QUERIES}, got {query!r}")
        self.scenes = open_dataset(scenes, split) if isinstance(scenes, (str, os.PathLike)) else scenes
        self.sigma, self.transform, self.query, self.with_record = sigma, transform, query, with_record
        self.channel_swap = channel_swap
        fmt = getattr(self.scenes, "format", None)
        if channel_swap and fmt and not receiver(fmt).configured:
            channel_swaps(fmt)  # one line now, not in a worker, when the receiver has none
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)
        if hasattr(self.scenes, "set_epoch"):
            self.scenes.set_epoch(epoch)

    def __len__(self) -> int:
        return len(self.scenes)

    def __getitem__(self, key) -> dict:
        epoch, i = self._key(key)
        s = self._scene(epoch, i, audio=True)
        if self.channel_swap:
            s = random_swap(s, getattr(self.scenes, "seed", 0), epoch, i)[0]
        item = scene_item(s, self.sigma, self._query(s, epoch, i), self.with_record)
        return self.transform(item) if self.transform else item

    def __getitems__(self, keys) -> list[dict]:
        """The items of ``keys`` (what a DataLoader asks for one batch), their audio read
        in one pass into one [B, C, T] tensor (``read_audio(out=)``), each item's a view
        of it: in a DataLoader worker the tensor is in shared memory, so the batch crosses
        to the trainer without a copy, and :func:`collate` returns it as it is (PyTorch's
        default collate copies it once more)."""
        if self.channel_swap:  # each scene through its own drawn symmetry: item by item
            return [self[k] for k in keys]
        keys = [self._key(k) for k in keys]
        read = getattr(self.scenes, "read_audio", None)
        scenes = [self._scene(e, i, audio=read is None) for e, i in keys]
        shape = tuple(self.scenes.audio_shape) if read is not None else scenes[0].audio.shape
        audio = _batch_tensor((len(keys), *shape))
        if read is not None:
            read([i for _, i in keys], out=audio.numpy())
        else:
            for b, s in enumerate(scenes):
                audio[b] = torch.from_numpy(s.audio)
        items = []
        for b, ((e, i), s) in enumerate(zip(keys, scenes)):
            item = scene_item(s, self.sigma, self._query(s, e, i), self.with_record, audio=audio[b])
            items.append(self.transform(item) if self.transform else item)
        return items

    def _key(self, key) -> tuple[int, int]:
        epoch, i = key if isinstance(key, tuple) else (self.epoch, key)
        return epoch, int(i)

    def _scene(self, epoch: int, i: int, audio: bool):
        if epoch != getattr(self.scenes, "epoch", epoch):
            return self.scenes.get(i, epoch=epoch)
        if not audio:
            return self.scenes.get(i, audio=False)
        return self.scenes[i]

    def _query(self, scene, epoch: int, i: int) -> str:
        return pick_query(scene, self.query, getattr(self.scenes, "seed", 0), epoch, i,
                          getattr(self.scenes, "caption_similarity", 0.5))


def pick_query(scene, how: str, seed: int, epoch: int, i: int, caption_similarity: float = 0.5) -> str:
    """The query an item carries: the scene's (``how="dataset"``), or one of its equally
    true queries drawn per (seed, epoch, index) (``"any"``; see :class:`Dataset`)."""
    if how == "dataset" or scene.record is None:
        return scene.query
    pool = scene.record.query_pool(caption_similarity)
    rng = np.random.default_rng([seed, epoch, i, 1])
    return pool[int(rng.integers(len(pool)))]


def _batch_tensor(shape: tuple) -> "torch.Tensor":
    """An uninitialised float32 tensor; in a DataLoader worker, in shared memory (as
    PyTorch's default collate makes its batches there), so sending it costs no copy."""
    if torch.utils.data.get_worker_info() is None:
        return torch.empty(shape, dtype=torch.float32)
    n = int(np.prod(shape))
    storage = torch.empty(0, dtype=torch.float32)._typed_storage()._new_shared(n)
    return torch.empty(0, dtype=torch.float32).new(storage).resize_(shape)


def scene_item(s, sigma: float, query: str, with_record: bool = False, audio=None) -> dict:
    """A scene as a dict of tensors and strings (the module docstring lists the keys);
    ``audio``: the tensor to give as its audio (default the scene's own)."""
    enc = scene_targets(s, sigma)
    item = {
        "audio": torch.from_numpy(s.audio) if audio is None else audio,
        "azimuth": torch.from_numpy(s.azimuth),
        "elevation": torch.from_numpy(s.elevation),
        "distance": torch.from_numpy(s.distance),
        "active": torch.from_numpy(s.active),
        "class_index": torch.from_numpy(enc["class_index"]),
        "gaussian": torch.from_numpy(enc["gaussian"]),
        "accdoa": torch.from_numpy(enc["accdoa"]),
        "mic_positions": torch.from_numpy(s.mic_positions),
        "query": query,
        "query_type": s.query_type,
        "query_relation": s.query_relation or "",  # default_collate takes strings, not None
        "pairing": s.pairing,
        "scene_id": s.scene_id,
    }
    if with_record:
        item["record"] = s.record
    if s.channel_swap is not None:
        item["channel_swap"] = s.channel_swap
    return item


class StreamingDataset(torch.utils.data.IterableDataset):
    """The scenes of a WebDataset export as an ``IterableDataset``: items as
    :class:`Dataset`'s, read sequentially from tar shards.

    Parameters
    ----------
    source : str or list of str
        The export folder (``tsel export webdataset --out``), or tar files.
    split : str
    shuffle : int
        Scenes in each worker's shuffle buffer (0: the shards' order).
    seed : int
        Seeds the shard order, the buffers and ``query="any"``.
    rank, world_size : int, optional
        This process among distributed ranks (default: ``torch.distributed``'s when it is
        initialized, else 0 of 1). Each rank reads its own shards (or, with fewer shards
        than ranks times workers, every ``R·W``-th scene): give every rank as many shards
        (``--shard-size``) so they see as many scenes.
    sigma, transform, query, with_record, channel_swap
        As :class:`Dataset` (the swaps drawn per (seed, epoch, scene index)).

    ``set_epoch(e)`` before each epoch draws epoch *e*'s shard order and buffer (with
    ``persistent_workers=True`` the workers keep the epoch they started with).
    """

    def __init__(self, source, split: str = "train", shuffle: int = 0, seed: int = 0, sigma: float = 5.0,
                 transform=None, query: str = "dataset", with_record: bool = False, rank: int | None = None,
                 world_size: int | None = None, channel_swap: bool = False):
        if query not in QUERIES:
            raise ValueError(f"query must be one of {QUERIES}, got {query!r}")
        self.stream = SceneStream(source, split, shuffle=shuffle, seed=seed, with_record=with_record or query == "any",
                                  channel_swap=channel_swap)
        self.sigma, self.transform, self.query, self.with_record = sigma, transform, query, with_record
        self.rank, self.world_size = rank, world_size

    def set_epoch(self, epoch: int) -> None:
        self.stream.set_epoch(epoch)

    def __len__(self) -> int:
        return len(self.stream)

    def _place(self) -> tuple[int, int, int, int]:
        info = torch.utils.data.get_worker_info()
        worker, workers = (info.id, info.num_workers) if info is not None else (0, 1)
        rank, world = self.rank, self.world_size
        if rank is None or world is None:
            dist = torch.distributed
            on = dist.is_available() and dist.is_initialized()
            rank = (dist.get_rank() if on else 0) if rank is None else rank
            world = (dist.get_world_size() if on else 1) if world is None else world
        return worker, workers, rank, world

    def __iter__(self):
        worker, workers, rank, world = self._place()
        epoch = self.stream.epoch
        for s in self.stream.iter(worker, workers, rank, world):
            q = pick_query(s, self.query, self.stream.seed, epoch, s.index)
            item = scene_item(s, self.sigma, q, self.with_record)
            yield self.transform(item) if self.transform else item


def collate(items: list[dict]) -> dict:
    """Batch items whose source count S differs (pad with NaN / False / zeros); values
    that are not tensors (query, scene_id, record) become lists. Tensors that are already
    the rows of one batch tensor, in order (the audio :meth:`Dataset.__getitems__` reads),
    are that tensor, not a copy."""
    n_src = max(it["azimuth"].shape[0] for it in items)
    out = {}
    for key in items[0]:
        vals = [it[key] for it in items]
        if not isinstance(vals[0], torch.Tensor):
            out[key] = vals
            continue
        if key in ("azimuth", "elevation", "distance", "active", "accdoa"):
            fill = False if key == "active" else (0.0 if key == "accdoa" else float("nan"))
            vals = [torch.cat([v, torch.full((n_src - v.shape[0], *v.shape[1:]), fill, dtype=v.dtype)]) for v in vals]
        out[key] = _rows_of_one(vals)
        if out[key] is None:
            out[key] = torch.stack(vals)
    return out


def _rows_of_one(vals: list) -> "torch.Tensor | None":
    """The tensor whose rows ``vals`` are, when they are the consecutive rows of one
    contiguous tensor filling its storage (else None)."""
    first = vals[0]
    storage, n = first.untyped_storage(), first.numel()
    if not first.is_contiguous() or storage.nbytes() != len(vals) * n * first.element_size():
        return None
    for b, v in enumerate(vals):
        if (v.untyped_storage().data_ptr() != storage.data_ptr() or v.storage_offset() != b * n
                or v.shape != first.shape or v.dtype != first.dtype or not v.is_contiguous()):
            return None
    return torch.empty(0, dtype=first.dtype).set_(storage, 0, (len(vals), *first.shape))


pad_sources = collate  # the name of earlier releases


def worker_init_fn(_worker_id: int) -> None:
    """DataLoader workers that render on the fly: one thread each, freed memory kept for
    the next scene (as ``tsel generate``'s workers)."""
    prepare_worker()
    torch.set_num_threads(1)


__all__ = ["Dataset", "StreamingDataset", "collate", "pad_sources", "pick_query", "scene_item", "worker_init_fn"]
