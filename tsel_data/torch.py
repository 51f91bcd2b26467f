"""PyTorch ``Dataset`` over a split: a generated dataset, or scenes rendered on the fly
(only importable when torch is installed).

torch is not a dependency of tsel-data: ``pip install 'tsel-data[baseline]'`` or your
own torch. Each item is a dict: ``audio`` float32 [C, T], ``azimuth``/``elevation``/
``distance`` float32 [S, F], ``active`` bool [S, F], ``class_index`` int64 [F] (target,
-1 where it has no position), ``gaussian`` float32 [F, 360] (target, σ = ``sigma``),
``accdoa`` float32 [S, F, 3], ``mic_positions`` float32 [C, 3], plus ``query``,
``query_type``, ``query_relation`` (None for a caption), ``pairing`` (docs/queries.md),
``scene_id`` and (``with_record=True``) ``record``.

HDF5 files and clips are opened lazily in each worker (see :mod:`tsel_data.store.reader`
and :mod:`tsel_data.onthefly`), so ``DataLoader(..., num_workers=N)`` works with fork and
spawn alike. Scenes of one split share C, T and F but not S: batch with :func:`collate`
when splits mix scenarios with different source counts, or when items hold records.
"""
from __future__ import annotations

import os

try:
    import torch
except ImportError as e:  # pragma: no cover - exercised only without torch
    raise ImportError("tsel_data.torch needs PyTorch, which tsel-data does not install: "
                      "pip install 'tsel-data[baseline]' (or torch)") from e

import numpy as np

from .executors import prepare_worker
from .labels import scene_targets
from .store.reader import open_dataset

QUERIES = ("dataset", "any")


class Dataset(torch.utils.data.Dataset):
    """Map-style dataset over one split.

    Parameters
    ----------
    scenes : str or scene sequence
        A dataset folder (read with ``open_dataset(scenes, split)``), or any sequence of
        scenes with ``len`` and ``[i]``: an opened split, or a
        :class:`~tsel_data.onthefly.SceneSource` rendering scenes on the fly.
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

    ``set_epoch(e)`` before each epoch draws epoch *e*'s scenes from an on-the-fly source
    (and its captions with ``query="any"``); an index may also be a pair ``(epoch, i)``,
    which works with persistent workers too.
    """

    def __init__(self, scenes, split: str = "train", sigma: float = 5.0, transform=None, query: str = "dataset",
                 with_record: bool = False):
        if query not in QUERIES:
            raise ValueError(f"query must be one of {QUERIES}, got {query!r}")
        self.scenes = open_dataset(scenes, split) if isinstance(scenes, (str, os.PathLike)) else scenes
        self.sigma, self.transform, self.query, self.with_record = sigma, transform, query, with_record
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)
        if hasattr(self.scenes, "set_epoch"):
            self.scenes.set_epoch(epoch)

    def __len__(self) -> int:
        return len(self.scenes)

    def __getitem__(self, key) -> dict:
        epoch, i = key if isinstance(key, tuple) else (self.epoch, key)
        i = int(i)
        if epoch != getattr(self.scenes, "epoch", epoch):
            s = self.scenes.get(i, epoch=epoch)
        else:
            s = self.scenes[i]
        enc = scene_targets(s, self.sigma)
        item = {
            "audio": torch.from_numpy(s.audio),
            "azimuth": torch.from_numpy(s.azimuth),
            "elevation": torch.from_numpy(s.elevation),
            "distance": torch.from_numpy(s.distance),
            "active": torch.from_numpy(s.active),
            "class_index": torch.from_numpy(enc["class_index"]),
            "gaussian": torch.from_numpy(enc["gaussian"]),
            "accdoa": torch.from_numpy(enc["accdoa"]),
            "mic_positions": torch.from_numpy(s.mic_positions),
            "query": self._query(s, epoch, i),
            "query_type": s.query_type,
            "query_relation": s.query_relation,
            "pairing": s.pairing,
            "scene_id": s.scene_id,
        }
        if self.with_record:
            item["record"] = s.record
        return self.transform(item) if self.transform else item

    def _query(self, scene, epoch: int, i: int) -> str:
        if self.query == "dataset" or scene.record is None:
            return scene.query
        pool = scene.record.query_pool(getattr(self.scenes, "caption_similarity", 0.5))
        rng = np.random.default_rng([getattr(self.scenes, "seed", 0), epoch, i, 1])
        return pool[int(rng.integers(len(pool)))]


def collate(items: list[dict]) -> dict:
    """Batch items whose source count S differs (pad with NaN / False / zeros); values
    that are not tensors (query, scene_id, record) become lists."""
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
        out[key] = torch.stack(vals)
    return out


pad_sources = collate  # the name of earlier releases


def worker_init_fn(_worker_id: int) -> None:
    """DataLoader workers that render on the fly: one thread each, freed memory kept for
    the next scene (as ``tsel generate``'s workers)."""
    prepare_worker()
    torch.set_num_threads(1)


__all__ = ["Dataset", "collate", "pad_sources", "worker_init_fn"]
