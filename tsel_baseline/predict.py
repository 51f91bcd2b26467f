"""Predictions in the ``tsel eval`` format, scored only by :func:`tsel_data.tools.evaluate.evaluate`.

One JSON line per scene: ``{"scene_id", "azimuth": float}`` from a clip-level model or
``{"scene_id", "azimuth": [F floats]}`` from a frame-level one (docs/reader.md).
"""
from __future__ import annotations

import numpy as np
import torch

from tsel_data.tools.evaluate import evaluate, write_predictions

from .data import Examples, example_list
from .model import TselNet, decode
from .train import batch_features


def predict(model: TselNet, source, text, queries: list[str] | None = None, batch_size: int = 64) -> list[dict]:
    """Predict every scene of ``source`` (FeatureTable or SceneFeatures).

    queries: one caption per scene to ask instead of the scene's own query (the
    shuffled-query control); default: each scene's query.
    """
    examples = example_list(source, all_sources=False, queries=queries)
    data = Examples(source, examples, text, augment=False)
    loader = torch.utils.data.DataLoader(data, batch_size=batch_size, shuffle=False)
    model.eval()
    rows = []
    with torch.no_grad():
        for batch in loader:
            az = decode(model(batch_features(batch, model.cfg.inputs), batch["text"]))
            for n, a in zip(batch["index"].tolist(), az):
                sid = source.labels(examples[n][0])["scene_id"]
                rows.append({"scene_id": sid, "azimuth": round(float(a), 3) if np.ndim(a) == 0
                             else [round(float(v), 3) for v in a]})
    return rows


def score(rows: list[dict], root: str, split: str, path: str):
    """Write ``rows`` to ``path`` (JSONL) and score it with tsel_data.tools.evaluate.evaluate."""
    write_predictions(path, rows)
    return evaluate(root, split, path)


def shuffled_queries(queries: list[str], seed: int) -> list[str]:
    """The queries permuted so that no scene keeps its own (a random derangement)."""
    rng = np.random.default_rng(seed)
    n = len(queries)
    if n < 2:
        raise ValueError("shuffling queries needs at least 2 scenes")
    while True:
        perm = rng.permutation(n)
        if not (perm == np.arange(n)).any():
            return [queries[j] for j in perm]
