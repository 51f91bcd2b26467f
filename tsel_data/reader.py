"""Reading datasets: the documented import path of :mod:`tsel_data.store.reader`."""
from .store.reader import Scene, SceneDataset, list_splits, load_manifest, open_dataset

__all__ = ["Scene", "SceneDataset", "list_splits", "load_manifest", "open_dataset"]
