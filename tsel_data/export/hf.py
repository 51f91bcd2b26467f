"""The Hugging Face layout: Parquet shards of audio and labels, Parquet metadata tables,
and a card whose YAML header names the three configs, so ``datasets.load_dataset(OUT)``
reads it from a local folder or from the Hub, and ``ds[0]`` works with stock
``datasets`` (no audio codec needed).

Output::

    OUT/
      README.md                          the card; configs: default (data/), scenes, sources
      data/{split}/{k:05d}.parquet       one row per scene: ids, query, audio (file and samples), labels
      metadata/{split}/scenes.parquet    one row per scene: the record (room, array, levels, query fields)
      metadata/{split}/sources.parquet   one row per source of every scene: clip, captions, labels, levels

Every scene's audio is there twice, both exact and with every channel:

- ``samples``: the samples as the dataset stores them, float32 [C][T] (int16 for int16
  and flac datasets: ``sample / 32768``), Arrow fixed-size lists any Parquet reader
  reads; ``datasets`` gives a nested list, or an array [C, T] with
  ``ds.with_format("numpy")``. ``fs`` beside it.
- ``audio``: the Hub's Audio column (a struct of ``bytes`` and ``path``): one WAV file
  per scene (32-bit float for float32 datasets, 16-bit for int16) or its FLAC file (flac
  datasets). Its feature in the Parquet metadata is ``Audio(decode=False)`` (datasets 4
  and later decode Audio with torchcodec, one more install; datasets 3 down-mixes it to
  mono), so ``row["audio"]`` is the file, which
  ``soundfile.read(io.BytesIO(row["audio"]["bytes"]))`` (or :func:`audio_of`) reads whole.

Every column and its type: :data:`DATA_COLUMNS` (:func:`data_columns` gives the
samples' shape), :data:`SCENE_COLUMNS`, :data:`SOURCE_COLUMNS` (docs/format.md, "Hugging
Face layout"; docs/commands/export.md). Needs pandas and pyarrow (``pip install
'tsel-data[export]'``).
"""
from __future__ import annotations

import io
import json

import numpy as np
import soundfile as sf

from ..choices import AudioCoding
from ..errors import TselError
from .base import Shards, SplitResult, Writer, WriterOption, parse_size
from ..formats.coding import file_audio, stored_samples

DEFAULT_SHARD_SIZE = "500MB"
LAYOUT = 2  # the writer's identity: 2 has the samples column and the undecoded Audio feature
ROW_GROUP_BYTES = 64_000_000  # the Hub's viewer reads a row group at a time

# (column, type) where type is a short name :func:`_arrow_type` turns into pyarrow's:
# ``[]`` a list, ``[N]`` a list of exactly N (the first the outermost, as in ``x[C][T]``)
SAMPLES = "samples[C][T]"  # float32 or int16, C and T of the dataset: :func:`data_columns`
DATA_COLUMNS = (
    ("scene_id", "string"), ("split", "string"), ("index", "int64"), ("query", "string"), ("query_type", "string"),
    ("query_relation", "string"), ("pairing", "string"), ("audio", "audio"), ("samples", SAMPLES),
    ("fs", "int64"), ("azimuth", "float32[][]"), ("elevation", "float32[][]"), ("distance", "float32[][]"),
    ("active", "bool[][]"), ("mic_positions", "float32[][]"),
)
SCENE_COLUMNS = (
    ("scene_id", "string"), ("split", "string"), ("index", "int64"), ("seed", "int64"), ("scenario", "string"),
    ("motion", "string"), ("rir_method", "string"), ("query", "string"), ("query_type", "string"),
    ("query_relation", "string"), ("query_wanted", "string"), ("pairing", "string"),
    ("query_alternatives", "string[]"), ("query_evidence", "string"), ("n_sources", "int64"),
    ("room_dims", "float64[]"), ("room_rt60", "float64"), ("room_rt60_measured", "float64"), ("room_name", "string"),
    ("room_bank", "string"), ("array_format", "string"), ("array_centre", "float64[]"), ("array_yaw", "float64"),
    ("array_side", "float64"), ("mic_positions", "float64[][]"), ("target_level_dbfs", "float64"),
    ("peak", "float64"), ("normalisation_db", "float64"), ("audio_file", "string"), ("audio_row", "int64"),
)
SOURCE_COLUMNS = (
    ("scene_id", "string"), ("source", "int64"), ("role", "string"), ("clip_id", "string"), ("clip_audio", "string"),
    ("captions", "string[]"), ("spatial", "string"), ("moving", "bool"), ("position", "float64[]"),
    ("path", "float64[][]"), ("bank", "string"), ("tir_db", "float64"), ("gain_db", "float64"),
    ("level_dbfs", "float64"), ("pairing", "string"), ("caption_similarity", "float64"), ("azimuth", "float32[]"),
    ("elevation", "float32[]"), ("distance", "float32[]"), ("active", "bool[]"),
)
# the Hub's feature for the audio column, not decoded: datasets 4 and later decode Audio
# with torchcodec (an ImportError on the first ``ds[0]`` without it), datasets 3 to mono
# by default; every other column's type follows from Parquet
HF_FEATURES = {"audio": {"_type": "Audio", "decode": False}}


def _pyarrow():
    try:
        import pyarrow as pa  # optional: only this export writes Parquet
        import pyarrow.parquet as pq
    except ImportError:
        raise TselError("the hf export writes Parquet with pyarrow, which is not installed: pip install "
                        "'tsel-data[export]'") from None
    return pa, pq


def _arrow_type(pa, name: str):
    if name == "audio":
        return pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    if name.endswith("]"):  # the outermost list is the first bracket: strip the first
        base, dims = name.split("[", 1)
        inner, size = base + dims[dims.index("]") + 1:], dims[:dims.index("]")]
        return pa.list_(_arrow_type(pa, inner), int(size)) if size else pa.list_(_arrow_type(pa, inner))
    return {"string": pa.string(), "int64": pa.int64(), "int16": pa.int16(), "float64": pa.float64(),
            "float32": pa.float32(), "bool": pa.bool_()}[name]


def samples_dtype(coding: str) -> str:
    """The samples' type: float32, or int16 for the 16-bit codings (int16 and flac)."""
    return "float32" if coding == AudioCoding.FLOAT32 else "int16"


def data_columns(coding: str, shape: tuple) -> tuple:
    """:data:`DATA_COLUMNS` with the samples' type and shape: ``float32[C][T]`` or ``int16[C][T]``."""
    channels, frames = shape
    return tuple((n, f"{samples_dtype(coding)}[{channels}][{frames}]" if t == SAMPLES else t) for n, t in DATA_COLUMNS)


def schema(columns, hf_features: dict | None = None):
    """The pyarrow schema of a table (with the Hub's features in its metadata)."""
    pa, _ = _pyarrow()
    meta = {b"huggingface": json.dumps({"info": {"features": hf_features}}).encode()} if hf_features else None
    return pa.schema([(n, _arrow_type(pa, t)) for n, t in columns], metadata=meta)


def data_row(scene, coding: str) -> dict:
    """One row of an audio shard (``samples``: the array, [C, T], as the dataset stores it)."""
    ext, data = file_audio(scene.audio, coding, scene.fs)
    return {"scene_id": scene.scene_id, "split": scene.split, "index": int(scene.index), "query": scene.query,
            "query_type": scene.query_type, "query_relation": scene.query_relation, "pairing": scene.pairing,
            "audio": {"bytes": data, "path": f"{scene.scene_id}.{ext}"},
            "samples": np.ascontiguousarray(stored_samples(scene.audio, coding)), "fs": int(scene.fs),
            "azimuth": scene.azimuth.tolist(),
            "elevation": scene.elevation.tolist(), "distance": scene.distance.tolist(),
            "active": scene.active.tolist(), "mic_positions": scene.mic_positions.tolist()}


def _json_text(v) -> str | None:
    return None if v is None else json.dumps(v, ensure_ascii=False)


def scene_row(scene, audio_file: str, audio_row: int) -> dict:
    """One row of ``scenes.parquet``: the record, flattened."""
    r = scene.record
    return {"scene_id": scene.scene_id, "split": scene.split, "index": int(scene.index), "seed": r.seed,
            "scenario": r.scenario, "motion": r.motion, "rir_method": r.rir_method, "query": scene.query,
            "query_type": scene.query_type, "query_relation": scene.query_relation, "query_wanted": r.query_wanted,
            "pairing": scene.pairing, "query_alternatives": r.query_alternatives,
            "query_evidence": _json_text(r.query_evidence), "n_sources": scene.n_sources, "room_dims": r.room.dims,
            "room_rt60": r.room.rt60, "room_rt60_measured": r.room.rt60_measured, "room_name": r.room.name,
            "room_bank": r.room.bank, "array_format": r.array.format, "array_centre": r.array.centre,
            "array_yaw": r.array.yaw, "array_side": r.array.side, "mic_positions": scene.mic_positions.tolist(),
            "target_level_dbfs": r.levels.target_level_dbfs, "peak": r.levels.peak,
            "normalisation_db": r.levels.normalisation_db, "audio_file": audio_file, "audio_row": audio_row}


def source_rows(scene) -> list[dict]:
    """The rows of ``sources.parquet`` of one scene (labels from the HDF5 arrays: exact)."""
    rows = []
    for k, s in enumerate(scene.record.sources):
        rows.append({"scene_id": scene.scene_id, "source": k, "role": s.role, "clip_id": s.clip_id,
                     "clip_audio": s.audio, "captions": list(s.captions), "spatial": s.spatial, "moving": s.moving,
                     "position": s.position, "path": s.path,
                     "bank": None if s.bank is None else _json_text(s.bank.to_dict()), "tir_db": s.tir_db,
                     "gain_db": s.gain_db, "level_dbfs": s.level_dbfs, "pairing": s.pairing,
                     "caption_similarity": s.caption_similarity, "azimuth": scene.azimuth[k].tolist(),
                     "elevation": scene.elevation[k].tolist(), "distance": scene.distance[k].tolist(),
                     "active": scene.active[k].tolist()})
    return rows


def data_table(rows: list[dict], data_schema):
    """An audio shard's rows as a table: the samples viewing their arrays (no copy, no
    Python lists), the other columns from the rows."""
    pa, _ = _pyarrow()
    i = data_schema.get_field_index("samples")
    field = data_schema.field(i)
    rest = pa.Table.from_pylist([{k: v for k, v in r.items() if k != "samples"} for r in rows],
                                schema=data_schema.remove(i))
    samples = pa.chunked_array([pa.FixedSizeListArray.from_arrays(pa.FixedSizeListArray.from_arrays(
        pa.array(r["samples"].reshape(-1)), type=field.type.value_type), type=field.type) for r in rows],
        type=field.type)
    return rest.add_column(i, field, samples)


def _leaves(name: str, typ) -> list:
    """The Parquet column paths of an Arrow field (``samples.list.element.list.element``)."""
    import pyarrow as pa

    if pa.types.is_list(typ) or pa.types.is_fixed_size_list(typ):
        return _leaves(f"{name}.list.element", typ.value_type)
    if pa.types.is_struct(typ):
        return [leaf for f in typ for leaf in _leaves(f"{name}.{f.name}", f.type)]
    return [name]


def shard_options(data_schema) -> dict:
    """How an audio shard is written: zstd, the samples without a dictionary, float32
    ones byte-stream-split (each byte of a sample with its like), int16 ones
    delta-coded; on the demo, 18 % and 27 % under their raw size. Both are standard
    Parquet encodings that pyarrow (so datasets and pandas) has long read."""
    import pyarrow as pa

    field = data_schema.field("samples")
    leaf = _leaves("samples", field.type)[0]
    floats = pa.types.is_floating(field.type.value_type.value_type)
    return {"compression": "zstd",
            "use_dictionary": [p for f in data_schema for p in _leaves(f.name, f.type) if p != leaf],
            "column_encoding": {leaf: "BYTE_STREAM_SPLIT" if floats else "DELTA_BINARY_PACKED"}}


def write_table(path: str, rows: list[dict], columns) -> None:
    """A metadata table: built with pandas, written by pyarrow with the explicit schema
    (so every split's table has the same types, whatever its values)."""
    import pandas as pd  # about 0.5 s to import: only the hf export pays it

    pa, pq = _pyarrow()
    frame = pd.DataFrame(rows, columns=[n for n, _ in columns])
    pq.write_table(pa.Table.from_pandas(frame, schema=schema(columns), preserve_index=False), path)


class HuggingFaceWriter(Writer):
    name = "hf"
    summary = "Hugging Face layout: Parquet audio shards (all channels), scenes and sources tables, the card."
    options = (WriterOption("shard_size", "Most bytes of audio per Parquet audio shard, the file and the samples "
                            "counted uncompressed (e.g. 500MB).", DEFAULT_SHARD_SIZE, parse=parse_size, bound="shard_bytes"),)

    def identity(self, doc) -> dict:
        # "hf layout" 2: the samples column and the undecoded Audio feature (1: neither,
        # the manifests before them say nothing): shards of the two do not mix
        return {**super().identity(doc), "audio coding": str(doc.raw.get("audio_coding", "float32")),
                "hf layout": LAYOUT}

    def check(self, job) -> None:
        _pyarrow()  # before anything is written
        self._coding = str(job.doc.raw.get("audio_coding", "float32"))
        self._shape = None  # (C, T) of the first scene: the samples column's, in every split

    def _schema_for(self, scene, shape: tuple):
        """The audio shards' schema, fixed by the first scene; another shape is refused."""
        if self._shape is None:
            self._shape = shape
            self._schema = schema(data_columns(self._coding, shape), HF_FEATURES)
        elif shape != self._shape:
            raise TselError(f"{scene.scene_id}: audio of {shape[0]} channels x {shape[1]} samples where the "
                            f"export's first scene has {self._shape[0]} x {self._shape[1]}; the hf export's "
                            f"samples column holds one shape")
        return self._schema

    def write_split(self, job, split: str) -> SplitResult:
        _, pq = _pyarrow()
        data_schema = None  # from the first scene (its shape)
        max_bytes = self.opts["shard_size"]
        files, scenes, sources, group = [], [], [], []
        shard_bytes = group_bytes = row = 0

        def flush(writer):
            if group:
                writer.write_table(data_table(group, data_schema))
                group.clear()

        def open_shard(tmp):
            return _ParquetShard(pq.ParquetWriter(tmp, data_schema, **shard_options(data_schema)), flush)

        with job.open(split) as ds, Shards(job, open_shard) as out:
            b = job.bar(len(ds), f"export {split}")
            for scene in job.scenes(ds):
                item = data_row(scene, self._coding)
                data_schema = self._schema_for(scene, item["samples"].shape)
                size = len(item["audio"]["bytes"]) + item["samples"].nbytes
                if out.current is None or shard_bytes + size > max_bytes:
                    files.append(f"data/{split}/{len(files):05d}.parquet")
                    out.next(files[-1])
                    shard_bytes = group_bytes = row = 0
                group.append(item)
                scenes.append(scene_row(scene, files[-1], row))
                sources.extend(source_rows(scene))
                shard_bytes, group_bytes, row = shard_bytes + size, group_bytes + size, row + 1
                if group_bytes >= ROW_GROUP_BYTES:
                    flush(out.current.writer)
                    group_bytes = 0
                b.update()
            b.close()
        for name, rows, columns in (("scenes", scenes, SCENE_COLUMNS), ("sources", sources, SOURCE_COLUMNS)):
            rel = f"metadata/{split}/{name}.parquet"
            with job.output(rel) as tmp:
                write_table(tmp, rows, columns)
            files.append(rel)
        return SplitResult(files, {"scenes": len(scenes), "sources": len(sources),
                                   "shards": sum(f.startswith("data/") for f in files)})

    def card_yaml(self, job) -> dict:
        splits = job.exported_splits()
        return {"configs": [
            {"config_name": "default", "default": True,
             "data_files": [{"split": s, "path": f"data/{s}/*.parquet"} for s in splits]},
            {"config_name": "scenes", "data_files": [{"split": s, "path": f"metadata/{s}/scenes.parquet"}
                                                     for s in splits]},
            {"config_name": "sources", "data_files": [{"split": s, "path": f"metadata/{s}/sources.parquet"}
                                                      for s in splits]}]}

    def lines(self, result) -> list:
        out = [f"{split}: {v['scenes']} scenes in {v['shards']} Parquet shard(s), {v['sources']} sources -> "
               f"{result.out}/data/{split}/" for split, v in result.splits.items()]
        return out + [f"metadata: {result.out}/metadata/; card: {result.out}/README.md (load_dataset({result.out!r}))"]


class _ParquetShard:
    """An audio shard being written: the rows not yet written go in as its last row group."""

    def __init__(self, writer, flush):
        self.writer, self._flush = writer, flush

    def close(self) -> None:
        self._flush(self.writer)
        self.writer.close()


def audio_of(row_audio: dict) -> np.ndarray:
    """float32 [C, T] of an ``audio`` value ({"bytes", "path"}): every channel, exact."""
    samples, _ = sf.read(io.BytesIO(row_audio["bytes"]), dtype="float32", always_2d=True)
    return samples.T
