"""PyTorch ``Dataset`` over one split (only importable when torch is installed).

torch is not a dependency of tsel-data; install it yourself. Each item is a dict of
tensors: ``audio`` float32 [C, T], ``azimuth``/``elevation``/``distance`` float32
[S, F], ``active`` bool [S, F], ``class_index`` int64 [F] (target, -1 where it has no
position), ``gaussian`` float32 [F, 360] (target, σ = ``sigma``), ``accdoa`` float32
[S, F, 3], ``mic_positions`` float32 [C, 3], plus ``query`` and ``scene_id`` strings.

HDF5 files are opened lazily in each worker (see :mod:`tsel_data.reader`), so
``DataLoader(..., num_workers=N)`` works with fork and spawn alike. Scenes of one split
share C, T and F but not S: batch with ``pad_sources`` as ``collate_fn`` when splits
mix scenarios with different source counts.
"""
from __future__ import annotations

try:
    import torch
except ImportError as e:  # pragma: no cover - exercised only without torch
    raise ImportError("tsel_data.torch needs PyTorch, which tsel-data does not install: pip install torch") from e


from .labels import scene_targets
from .store.reader import open_dataset


class Dataset(torch.utils.data.Dataset):
    """``Dataset(root, split, sigma=5.0, transform=None)``; ``transform(item) -> item``."""

    def __init__(self, root, split: str = "train", sigma: float = 5.0, transform=None):
        self.scenes = open_dataset(root, split)
        self.sigma = sigma
        self.transform = transform

    def __len__(self) -> int:
        return len(self.scenes)

    def __getitem__(self, i: int) -> dict:
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
            "query": s.query,
            "scene_id": s.scene_id,
        }
        return self.transform(item) if self.transform else item


def pad_sources(items: list[dict]) -> dict:
    """Collate items whose source count S differs: pad with NaN / False / zeros."""
    n_src = max(it["azimuth"].shape[0] for it in items)
    out = {}
    for key in items[0]:
        vals = [it[key] for it in items]
        if isinstance(vals[0], str):
            out[key] = vals
            continue
        if key in ("azimuth", "elevation", "distance", "active", "accdoa"):
            fill = False if key == "active" else (0.0 if key == "accdoa" else float("nan"))
            vals = [torch.cat([v, torch.full((n_src - v.shape[0], *v.shape[1:]), fill, dtype=v.dtype)]) for v in vals]
        out[key] = torch.stack(vals)
    return out


__all__ = ["Dataset", "pad_sources"]
