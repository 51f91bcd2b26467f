"""Shard files: HDF5 for trainers, JSON for people and other tools (docs/format.md)."""
from .writer import FORMAT_VERSION, RenderedScene, write_shard, shard_names

__all__ = ["FORMAT_VERSION", "RenderedScene", "write_shard", "shard_names"]
