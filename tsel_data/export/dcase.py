"""The DCASE 2024 Task 3 (STARSS23) layout, for SELD baselines.

Output::

    OUT/
      foa_dev/dev-{split}-tsel/fold{n}_{scene_id}.wav     (mic arrays: mic_dev/, the receiver's export_folder)
      metadata_dev/dev-{split}-tsel/fold{n}_{scene_id}.csv
      queries.csv        fold,split,file,scene_id,query  (one row per scene)
      classes.json       {"0": "target", "1": "interferer"}, folds, format notes

Label CSV rows (no header, as STARSS23): ``frame,class,source,azimuth,elevation,distance``
— frame index of 100 ms frames, class index, source index (counted per class, as in
STARSS23), azimuth and elevation in integer degrees (array frame, azimuth counter-
clockwise from the front, [-180, 180)), distance in integer centimetres (DCASE 2024).
Only frames where a source is active are written; sources without a position (the
additive one) are not written. Classes: the query's target is class 0, every other
directional source is class 1 — TSEL has no fixed sound classes, the query picks one.

File names start with ``fold{n}_`` because the DCASE baselines read the fold from the
5th character of the name: fold n is the n-th split of dataset.json (1-based).
"""
from __future__ import annotations

import csv
import io
import os

import numpy as np

from ..choices import WavSubtype, values
from ..corpus.audio import save_wav
from ..errors import DatasetError
from ..core.files import check_input
from ..receivers import receiver
from ..formats.dcase import FRAME_HOP, dcase_rows
from .base import SplitResult, Writer, WriterOption, run_export

CLASSES = {0: "target", 1: "interferer"}
QUERY_COLUMNS = ("fold", "split", "file", "scene_id", "query")
SUBTYPES = values(WavSubtype)
QUERIES_FILE = "queries.csv"
CLASSES_FILE = "classes.json"


class DcaseWriter(Writer):
    name = "dcase"
    summary = "DCASE 2024 Task 3 layout: WAV per scene, frame/class/source/azimuth/elevation/distance CSVs, queries."
    options = (WriterOption("subtype", "WAV sample format (the DCASE baselines expect 16-bit).", "PCM_16",
                            choices=SUBTYPES),)

    def __init__(self, **options):
        super().__init__(**options)
        self.queries: dict[str, list] = {}

    def identity(self, doc) -> dict:
        return {**super().identity(doc), "WAV subtype": self.opts["subtype"]}

    def check(self, job) -> None:
        if abs(job.doc.label_hop - FRAME_HOP) > 1e-9:
            raise DatasetError(f"{job.root}: label_hop is {job.doc.label_hop} s; DCASE export needs {FRAME_HOP} s "
                               f"frames (set label_hop = {FRAME_HOP} and regenerate)")
        for split in job.splits:
            if job.fold(split) > 9:
                raise DatasetError(f"{job.root}: split {split!r} would be fold {job.fold(split)}; DCASE names hold "
                                   f"one digit (1-9)")
        for rel in (QUERIES_FILE, CLASSES_FILE):  # written last: refused before the audio, not after
            job.check_free(rel)

    def write_split(self, job, split: str) -> SplitResult:
        subtype, fold = self.opts["subtype"], job.fold(split)
        audio_dir = f"{receiver(job.doc.format).export_folder}_dev/dev-{split}-tsel"
        meta_dir = f"metadata_dev/dev-{split}-tsel"
        files, queries, n_rows = [], [], 0
        with job.open(split) as ds:
            b = job.bar(len(ds), f"export {split}")
            for scene in job.scenes(ds):
                name = f"fold{fold}_{scene.scene_id}"
                peak = float(np.max(np.abs(scene.audio))) if scene.audio.size else 0.0
                if subtype != "FLOAT" and peak >= 1.0:
                    raise DatasetError(f"{scene.scene_id}: peak {peak:.3f} would clip in {subtype}; "
                                       f"export with --subtype FLOAT")
                wav = f"{audio_dir}/{name}.wav"
                save_wav(job.path(wav), scene.audio.T, scene.fs, subtype=subtype)
                rows = dcase_rows(scene)
                files += [wav, job.write_text(f"{meta_dir}/{name}.csv", _csv(rows))]
                n_rows += len(rows)
                queries.append((str(fold), split, name, scene.scene_id, scene.query))
                b.update()
            b.close()
            n_scenes = len(ds)
        self.queries[split] = queries
        return SplitResult(files, {"fold": fold, "scenes": n_scenes, "rows": n_rows, "audio_dir": audio_dir,
                                   "metadata_dir": meta_dir})

    def finish(self, job) -> list:
        earlier = _read_queries(job.out) if job.owns(QUERIES_FILE) else []  # another's file is not read (--force)
        rows = [r for r in earlier if r[1] not in self.queries and r[1] in job.summaries]
        for split in job.exported_splits():
            rows += self.queries.get(split, [])
        rows.sort(key=lambda r: int(r[0]))  # fold order; scene order within a fold (a stable sort)
        files = [job.write_text(QUERIES_FILE, _csv([QUERY_COLUMNS, *rows]))]
        info = {"classes": {str(k): v for k, v in CLASSES.items()},
                "folds": {s: job.fold(s) for s in job.exported_splits()}, "format": job.doc.format,
                "csv_columns": ["frame", "class", "source", "azimuth_deg", "elevation_deg", "distance_cm"],
                "frame_hop_s": FRAME_HOP, "wav_subtype": self.opts["subtype"]}
        files.append(job.write_json(CLASSES_FILE, info))
        return files + super().finish(job)

    def lines(self, result) -> list:
        out = [f"{split}: fold {v['fold']}, {v['scenes']} scenes, {v['rows']} label rows -> "
               f"{os.path.join(result.out, v['audio_dir'])}" for split, v in result.splits.items()]
        return out + [f"queries: {result.out}/{QUERIES_FILE}; classes: 0 = target, 1 = interferer "
                      f"({result.out}/{CLASSES_FILE})"]


def _read_queries(out: str) -> list:
    """The query rows of the export already in ``out`` (ours: the manifest says so)."""
    path = os.path.join(out, QUERIES_FILE)
    check_input(path, DatasetError, "export into a new --out")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = [tuple(r) for r in csv.reader(f)]
    except (OSError, UnicodeDecodeError) as e:
        raise DatasetError(f"{path} is unreadable ({e}); export into a new --out, or pass --force") from None
    if not rows or rows[0] != QUERY_COLUMNS:
        raise DatasetError(f"{path} is not the queries file of a DCASE export; export into a new --out, or pass "
                           f"--force")
    return rows[1:]


def _csv(rows) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def export_dcase(root: str, out: str, splits=None, subtype: str = "PCM_16", progress: bool | None = False,
                 force: bool = False, **options) -> dict:
    """Write the DCASE layout of ``splits`` (default: all) under ``out``; returns a summary
    ({"out", "splits": {split: {"fold", "scenes", "rows", "audio_dir", "metadata_dir"}}, "rows"}).

    subtype: WAV sample format (``PCM_16`` as STARSS23, which the baselines scale by
    1/32768; ``PCM_24``; ``FLOAT``). PCM needs every sample in [-1, 1). progress: a bar
    per split (None: when stderr is a terminal). force: write over an export of something
    else, or files no export wrote (docs/commands/export.md).
    """
    result = run_export(DcaseWriter(subtype=subtype, **options), root, out, splits, force, progress)
    summary = {"out": out, "splits": {}, "rows": 0}
    for split, v in result.splits.items():
        summary["splits"][split] = {**v, "audio_dir": os.path.join(out, v["audio_dir"]),
                                    "metadata_dir": os.path.join(out, v["metadata_dir"])}
        summary["rows"] += v["rows"]
    return summary
