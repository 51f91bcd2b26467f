"""tsel-data: datasets for text-queried target sound event localization.

>>> import tsel_data
>>> ds = tsel_data.open_dataset("demo-out", "train")
>>> scene = ds[0]; scene.audio.shape, scene.query

The package's layers and what each may import: docs/design.md.
"""
from .version import __version__

__all__ = ["open_dataset", "__version__"]


def __getattr__(name):
    # lazy: `import tsel_data` stays cheap (no h5py) for the CLI and workers
    if name == "open_dataset":
        from .store.reader import open_dataset

        return open_dataset
    raise AttributeError(f"module 'tsel_data' has no attribute {name!r}")
