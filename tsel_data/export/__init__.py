"""Exports of a finished dataset for other tools: one writer interface, one module per
format, a name -> writer table (as lhotse's ``resolve_writer``).

    from tsel_data.export import export
    export("webdataset", "/data/tsel", "/data/tsel-wds", shard_size="500MB")

Import order inside the package (each module imports only those above it; none imports
this one)::

    card        the dataset card (README.md with the Hub's YAML header)
    base        Writer, WriterOption, ExportJob, run_export: walking splits, claiming
                --out, per-split replace, the export's manifest
    dcase       the DCASE 2024 Task 3 layout
    webdataset  WebDataset tar shards
    hf          the Hugging Face layout: Parquet audio shards and metadata tables
    lhotse      lhotse manifests (recordings, supervisions, cuts) and the audio files
    recipes     recipe releases: the plan and per-scene checksums, no audio
    cardonly    the card alone, for any dataset
    spatial     what the spatial-language exports read from a scene (facts, names, truth)
    captions    spatial captions in a named vocabulary (JSONL)
    qa          spatial question-answer pairs in a named schema (JSONL)

What a format's files hold, and their readers, live in ``tsel_data.formats`` (the tools
read them back without importing the writers).

A new format is one module with a :class:`~tsel_data.export.base.Writer` subclass and one
line in :data:`WRITERS`; ``tsel export NAME`` and its options follow from the writer.
"""
from __future__ import annotations

from ..errors import TselError
from .base import ExportResult, Writer, WriterOption, run_export
from .captions import CaptionsWriter
from .cardonly import CardWriter
from .dcase import DcaseWriter, export_dcase
from .hf import HuggingFaceWriter
from .lhotse import LhotseWriter
from .qa import QaWriter
from .recipes import RecipesWriter
from .webdataset import WebDatasetWriter

WRITERS: dict[str, type[Writer]] = {w.name: w for w in (DcaseWriter, WebDatasetWriter, HuggingFaceWriter,
                                                        LhotseWriter, RecipesWriter, CaptionsWriter, QaWriter,
                                                        CardWriter)}


def resolve_writer(name: str) -> type[Writer]:
    """The writer class of an export format (TselError naming the formats there are)."""
    try:
        return WRITERS[name]
    except KeyError:
        raise TselError(f"no export format {name!r}; choose one of {', '.join(WRITERS)}") from None


def export(name: str, root: str, out: str, splits=None, force: bool = False, progress: bool | None = False,
           **options) -> ExportResult:
    """Export the dataset ``root`` into ``out`` in format ``name`` (:data:`WRITERS`);
    ``options`` are the writer's (``tsel export NAME --help`` lists them)."""
    return run_export(resolve_writer(name)(**options), root, out, splits, force, progress)


__all__ = ["WRITERS", "ExportResult", "Writer", "WriterOption", "export", "export_dcase", "resolve_writer",
           "run_export"]
