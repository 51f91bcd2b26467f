"""tsel-data: datasets for text-queried target sound event localization.

>>> import tsel_data
>>> ds = tsel_data.open_dataset("demo-out", "train")
>>> scene = ds[0]; scene.audio.shape, scene.query

The package's folders are the pipeline's stages and its support; their layers and what
each may import: docs/design.md.
"""
import importlib
import importlib.abc
import importlib.util
import sys

from .core.version import __version__

__all__ = ["open_dataset", "__version__"]

# The short import paths a trainer's code uses (README, docs/reader.md), kept as they
# were before the modules moved into stage folders: `import tsel_data.torch` is the
# module `tsel_data.tools.torch` itself, not a copy.
PUBLIC_MODULES = {
    "torch": "tools.torch",
    "streaming": "tools.streaming",
    "evaluate": "tools.evaluate",
    "labels": "tools.labels",
    "onthefly": "job.onthefly",
    "features": "dsp.features",
    "handmade": "job.handmade",
    "augment": "tools.augment",
}


class _PublicPaths(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``tsel_data.<short>`` for the names of PUBLIC_MODULES and hands back the
    module where it lives (imported on first use, so `import tsel_data` stays cheap)."""

    def find_spec(self, fullname, path=None, target=None):
        head, _, short = fullname.partition(".")
        if head == __name__ and short in PUBLIC_MODULES:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        return importlib.import_module(f"{__name__}.{PUBLIC_MODULES[spec.name.partition('.')[2]]}")

    def exec_module(self, module):
        pass  # already executed under its own name


if not any(isinstance(f, _PublicPaths) for f in sys.meta_path):
    sys.meta_path.append(_PublicPaths())


def __getattr__(name):
    # lazy: `import tsel_data` stays cheap (no h5py) for the CLI and workers
    if name == "open_dataset":
        from .store.reader import open_dataset

        return open_dataset
    raise AttributeError(f"module 'tsel_data' has no attribute {name!r}")
