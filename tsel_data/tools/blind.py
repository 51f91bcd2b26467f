"""What a test split rewards without listening: the scores of blind answers beside a
model's (docs/commands/eval.md, "Blind scores").

Real recordings carry priors a model can exploit without hearing the scene: a class that
is always in front, an actor who never moves. Each blind answer is a prediction file's
worth of azimuths made from the training split's labels and the test scene's query and
record only, scored with the same metric as a model:

- ``train mean``: the circular mean direction of the training split's targets, for every scene;
- ``train mean per query``: the training split's mean direction of the targets with the
  same query text (the train mean for a text it never asked);
- ``train mean per class``: the same per target class (recorded datasets: the class the
  labels name);
- ``an interferer``: the direction of the scene's first directional interferer (what a
  model that localises a sound, but not the one asked for, would say).

A test split whose best blind answer scores within :data:`CLOSE_DEG` of the model's MAE is
flagged: its number says little about listening.
"""
from __future__ import annotations

import numpy as np

from ..core.geometry import circular_mean
from ..store.reader import list_splits, open_dataset

CLOSE_DEG = 5.0  # a blind answer this close to the model's MAE flags the split


def _target_direction(scene) -> float | None:
    az, use = scene.azimuth[0].astype(np.float64), np.asarray(scene.active[0], bool)
    use = use & np.isfinite(az) if (use & np.isfinite(az)).any() else np.isfinite(az)
    return circular_mean(az[use]) if use.any() else None


def _class_of(scene):
    rec = scene.record
    if rec is not None and rec.recording is not None and rec.recording.class_indices:
        return rec.recording.class_indices[0]
    return None


def _interferer_direction(scene) -> float | None:
    for s in range(1, scene.n_sources):
        az, use = scene.azimuth[s].astype(np.float64), np.asarray(scene.active[s], bool)
        ok = np.isfinite(az) & use if (np.isfinite(az) & use).any() else np.isfinite(az)
        if ok.any():
            return circular_mean(az[ok])
    return None


def blind_predictions(root: str, split: str, train: str = "train") -> dict[str, dict[str, float]]:
    """{answer name: {scene_id: azimuth}} for the scenes of ``split`` from the labels of
    ``train``; {} when the dataset has no such training split (or ``split`` is it)."""
    if split == train or train not in list_splits(root):
        return {}
    with open_dataset(root, train) as ds:
        seen = [(s.query, _class_of(s), _target_direction(s)) for s in ds.iter_labels()]
    seen = [x for x in seen if x[2] is not None]
    if not seen:
        return {}
    overall = circular_mean([d for _, _, d in seen])

    def means(key: int) -> dict:
        groups: dict = {}
        for item in seen:
            if item[key] is not None:
                groups.setdefault(item[key], []).append(item[2])
        return {k: circular_mean(v) for k, v in groups.items()}

    by_query, by_class = means(0), means(1)
    out: dict[str, dict[str, float]] = {"train mean": {}, "train mean per query": {}}
    has_classes = bool(by_class)
    if has_classes:
        out["train mean per class"] = {}
    out["an interferer"] = {}
    with open_dataset(root, split) as ds:
        for s in ds.iter_labels():
            out["train mean"][s.scene_id] = overall
            out["train mean per query"][s.scene_id] = by_query.get(s.query, overall)
            if has_classes:
                out["train mean per class"][s.scene_id] = by_class.get(_class_of(s), overall)
            other = _interferer_direction(s)
            out["an interferer"][s.scene_id] = overall if other is None else other
    return out
