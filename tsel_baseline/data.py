"""From scenes to training examples.

Three layers, each usable alone:

1. :class:`SceneFeatures` — a torch ``Dataset`` over *any* scene source (an object with
   ``__len__`` and ``__getitem__`` returning :class:`tsel_data.store.Scene`: an offline
   ``tsel_data.open_dataset(...)`` split today, an on-the-fly renderer later). Each item
   is one scene's features and labels as numpy arrays. Picklable, so feature
   extraction runs in ``DataLoader`` workers.
2. :class:`FeatureTable` — the same items for a whole split, computed once
   (:func:`precompute`) and kept as stacked arrays (saved as ``.npz``). Indexing it
   gives exactly what :class:`SceneFeatures` gives, so everything downstream takes
   either.
3. :class:`Examples` — (scene, source, caption) triples turned into model inputs:
   features (optionally rotated, :mod:`tsel_baseline.augment`), the caption's text
   vector, and the chosen source's azimuth per frame.

Why a source other than the target: a training scene's record carries the captions
*and* the position of every source, so a two-directional scene is two examples, one
per source, with the same audio and different answers. Nothing teaches a model that the
words matter more directly; a model trained only on source 0 can lean on cues such as
"the louder one" instead.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

import numpy as np
import torch

from tsel_data.tools.torch import worker_init_fn

from .augment import apply, is_mic4_square, random_transform
from .features import FeatureConfig, scene_features



def scene_captions(scene) -> list[list[str]]:
    """Captions of every source of a scene (source 0 first), from its JSON record."""
    sources = (scene.record or {}).get("sources") or []
    caps = [list(s.get("captions") or []) for s in sources]
    if not caps:
        caps = [[scene.query]]  # no record: only the query is known
    return caps


class SceneFeatures(torch.utils.data.Dataset):
    """Features and labels of each scene of a scene source, computed when read.

    Item: ``{"features": {name: float32 array}, "azimuth": float32 [S, F],
    "active": bool [S, F], "scene_id": str, "query": str, "captions": [[str]] per source,
    "format": str, "mic4": bool}``.
    """

    def __init__(self, scenes, config: FeatureConfig = FeatureConfig()):
        self.scenes = scenes
        self.config = config

    def __len__(self) -> int:
        return len(self.scenes)

    def labels(self, i: int) -> dict:
        """``azimuth`` [S, F], ``captions``, ``query`` of scene i (no audio read where the source allows)."""
        get = getattr(self.scenes, "get", None)
        s = get(int(i), audio=False) if get else self.scenes[int(i)]
        return {"azimuth": np.asarray(s.azimuth, np.float32), "captions": scene_captions(s), "query": s.query,
                "scene_id": s.scene_id}

    def __getitem__(self, i: int) -> dict:
        s = self.scenes[int(i)]
        return {
            "features": scene_features(s, self.config),
            "azimuth": np.asarray(s.azimuth, dtype=np.float32),
            "active": np.asarray(s.active, dtype=bool),
            "scene_id": s.scene_id,
            "query": s.query,
            "captions": scene_captions(s),
            "format": s.format,
            "mic4": is_mic4_square(s.mic_positions),
        }


def _identity(x):
    return x


@dataclass
class FeatureTable:
    """A split's :class:`SceneFeatures` items, stacked: ``features[name]`` [N, ...],
    ``azimuth``/``active`` [N, S, F] (S padded with NaN / False), per-scene lists."""

    features: dict
    azimuth: np.ndarray
    active: np.ndarray
    scene_ids: list
    queries: list
    captions: list
    format: str
    mic4: np.ndarray
    config: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.scene_ids)

    def labels(self, i: int) -> dict:
        n_src = len(self.captions[i])
        return {"azimuth": self.azimuth[i, :n_src], "captions": self.captions[i], "query": self.queries[i],
                "scene_id": self.scene_ids[i]}

    def __getitem__(self, i: int) -> dict:
        n_src = len(self.captions[i])
        return {
            "features": {k: v[i] for k, v in self.features.items()},
            "azimuth": self.azimuth[i, :n_src],
            "active": self.active[i, :n_src],
            "scene_id": self.scene_ids[i],
            "query": self.queries[i],
            "captions": self.captions[i],
            "format": self.format,
            "mic4": bool(self.mic4[i]),
        }

    def save(self, path: str) -> None:
        """One ``.npz`` (arrays) with the per-scene lists as JSON inside it."""
        meta = {"scene_ids": self.scene_ids, "queries": self.queries, "captions": self.captions,
                "format": self.format, "config": self.config}
        tmp = path + ".part.npz"
        np.savez(tmp, azimuth=self.azimuth, active=self.active, mic4=self.mic4,
                 meta=np.array(json.dumps(meta)), **{f"feat_{k}": v for k, v in self.features.items()})
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: str) -> "FeatureTable":
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            feats = {k[5:]: z[k] for k in z.files if k.startswith("feat_")}
            return cls(features=feats, azimuth=z["azimuth"], active=z["active"], mic4=z["mic4"],
                       scene_ids=meta["scene_ids"], queries=meta["queries"], captions=meta["captions"],
                       format=meta["format"], config=meta["config"])


def precompute(scenes, config: FeatureConfig = FeatureConfig(), workers: int = 0, cache: str | None = None,
               log=print) -> FeatureTable:
    """Features of every scene of a source, once (``workers`` DataLoader processes).

    ``cache``: an ``.npz`` path; read if it exists and was made with the same config,
    else written after computing.
    """
    if cache and os.path.exists(cache):
        table = FeatureTable.load(cache)
        if table.config == config.to_dict() and len(table) == len(scenes):
            return table
    # worker_init_fn: one BLAS thread per worker (two workers with two spinning OpenBLAS
    # threads each ran 3x slower on 2 cores than with one)
    loader = torch.utils.data.DataLoader(SceneFeatures(scenes, config), batch_size=None, shuffle=False,
                                         num_workers=workers, collate_fn=_identity,
                                         worker_init_fn=worker_init_fn if workers else None,
                                         persistent_workers=False, prefetch_factor=8 if workers else None)
    items = []
    for n, it in enumerate(loader):
        items.append(it)
        if log and (n + 1) % 500 == 0:
            log(f"  features: {n + 1}/{len(scenes)} scenes")
    if not items:
        raise ValueError("no scenes to compute features of")
    n_src = max(it["azimuth"].shape[0] for it in items)

    def pad(a, fill):
        return np.concatenate([a, np.full((n_src - a.shape[0], *a.shape[1:]), fill, a.dtype)]) if a.shape[0] < n_src else a

    table = FeatureTable(
        features={k: np.stack([it["features"][k] for it in items]) for k in items[0]["features"]},
        azimuth=np.stack([pad(it["azimuth"], np.nan) for it in items]),
        active=np.stack([pad(it["active"], False) for it in items]),
        scene_ids=[it["scene_id"] for it in items], queries=[it["query"] for it in items],
        captions=[it["captions"] for it in items], format=items[0]["format"],
        mic4=np.array([it["mic4"] for it in items]), config=config.to_dict(),
    )
    if cache:
        table.save(cache)
    return table


def clip_azimuth(az: np.ndarray, active: np.ndarray) -> float:
    """One azimuth for a static source: circular mean (deg) over its active frames (all if none)."""
    use = active & np.isfinite(az)
    if not use.any():
        use = np.isfinite(az)
    a = np.radians(az[use].astype(np.float64))
    return float(np.degrees(np.arctan2(np.sin(a).mean(), np.cos(a).mean())))


def example_list(source, all_sources: bool, queries: list[str] | None = None) -> list[tuple[int, int, str]]:
    """(scene index, source index, caption) triples.

    ``all_sources=False``: one per scene, the scene's query for source 0 (or
    ``queries[i]`` when given: the shuffled-query control). ``True``: every caption of
    every source with a position (additive sources have none).
    """
    out = []
    for i in range(len(source)):
        lab = source.labels(i)
        if not all_sources:
            out.append((i, 0, queries[i] if queries is not None else lab["query"]))
            continue
        for k, caps in enumerate(lab["captions"]):
            if k < lab["azimuth"].shape[0] and np.isfinite(lab["azimuth"][k]).any():
                out.extend((i, k, c) for c in caps)
    return out


class Examples(torch.utils.data.Dataset):
    """Model inputs for (scene, source, caption) triples of a feature source.

    source:    a :class:`FeatureTable` or :class:`SceneFeatures`.
    examples:  triples from :func:`example_list`.
    text:      callable list[str] -> float32 [N, D] (cached by caption here).
    augment:   rotate/mirror each example at random (a new draw every epoch; see
               :meth:`set_epoch`); seed: where the draws come from.
    Item: ``{"feat_<name>": float32, "text": [D], "azimuth": [F] (deg, NaN where the
    source has no position), "active": bool [F], "clip_azimuth": float, "index": int}``.
    """

    def __init__(self, source, examples, text, augment: bool = False, seed: int = 0):
        self.source = source
        self.examples = list(examples)
        caps = sorted({c for _, _, c in self.examples})
        vecs = text(caps)
        self._text = {c: vecs[n] for n, c in enumerate(caps)}
        self.augment = augment
        self.seed = seed
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def __len__(self) -> int:
        return len(self.examples)

    def __getitem__(self, n: int) -> dict:
        i, k, caption = self.examples[n]
        item = self.source[i]
        feats, az, active = item["features"], item["azimuth"][k], item["active"][k]
        if self.augment:
            spatial = next(k for k in ("gcc", "xspec", "iv") if k in feats)
            if spatial == "iv" or item["mic4"]:
                t = random_transform(np.random.default_rng([self.seed, self.epoch, n]), spatial)
                feats, az = apply(feats, t), t.azimuth(az)
        out = {f"feat_{name}": np.ascontiguousarray(v, dtype=np.float32) for name, v in feats.items()}
        out.update(text=self._text[caption], azimuth=np.asarray(az, np.float32), active=np.asarray(active, bool),
                   clip_azimuth=np.float32(clip_azimuth(az, active)), index=n)
        return out
