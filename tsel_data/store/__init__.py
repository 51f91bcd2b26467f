"""The dataset format, in one package: it writes, reads and verifies what docs/format.md
promises, and nobody else spells a path or a record key.

Import order: ``layout`` (path names), ``records`` (the per-scene record), ``dataset``
(dataset.json, conventions, shard attributes), ``plans`` (plan files, shard tasks),
``sanity`` (the last look at a scene before it is written), then ``writer``, ``scene`` (what the reader returns), ``reader`` and ``check`` (``tsel check DIR``);
``outputs``: where the commands may write the files a user names, and over what.
"""
from .dataset import CONVENTIONS, FORMAT_VERSION, DatasetDoc, ShardEntry, load_dataset_doc, shard_attrs
from .layout import Layout, shard_names
from .reader import Scene, SceneDataset, list_splits, open_dataset
from .records import ArrayRecord, LevelsRecord, RoomRecord, SceneRecord, SourceRecord
from .writer import write_shard

__all__ = ["CONVENTIONS", "FORMAT_VERSION", "ArrayRecord", "DatasetDoc", "Layout", "LevelsRecord", "RoomRecord",
            "Scene", "SceneDataset", "SceneRecord", "ShardEntry", "SourceRecord", "list_splits",
           "load_dataset_doc", "open_dataset", "shard_attrs", "shard_names", "write_shard"]
