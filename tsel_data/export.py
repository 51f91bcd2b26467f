"""Export a dataset in the DCASE 2024 Task 3 (STARSS23) layout, for SELD baselines.

Output::

    OUT/
      foa_dev/dev-{split}-tsel/fold{n}_{scene_id}.wav     (mic4 / tetra: mic_dev/)
      metadata_dev/dev-{split}-tsel/fold{n}_{scene_id}.csv
      queries.csv        fold,split,file,scene_id,query  (one row per scene)
      classes.json       {"0": "target", "1": "interferer"}, folds, format notes

Exporting some splits into an existing export of the same dataset adds them (their
files and query rows replace the earlier ones; the other splits' stay); an export of
another dataset, format or WAV subtype in ``OUT`` is refused.

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
import json
import io
import os

import numpy as np

from .atomic import write_json, write_text
from .audio import save_wav
from .choices import WavSubtype, values
from .errors import DatasetError, TselError
from .progress import bar
from .receivers import receiver
from .store.dataset import load_dataset_doc
from .store.reader import list_splits, open_dataset

CLASSES = {0: "target", 1: "interferer"}
QUERY_COLUMNS = ("fold", "split", "file", "scene_id", "query")
SUBTYPES = values(WavSubtype)


def dcase_rows(scene, frame_hop: float = 0.1) -> list[tuple[int, int, int, int, int, int]]:
    """DCASE label rows of one scene, sorted by frame then class then source.

    Our label frames must already be ``frame_hop`` long (the DCASE 100 ms resolution).
    """
    if abs(scene.label_hop - frame_hop) > 1e-9:
        raise DatasetError(f"{scene.scene_id}: label_hop is {scene.label_hop} s; DCASE export needs {frame_hop} s "
                           f"frames (set label_hop = {frame_hop} and regenerate)")
    rows = []
    per_class = {0: 0, 1: 0}
    for s in range(scene.n_sources):
        az = scene.azimuth[s]
        if not np.isfinite(az).any():
            continue  # additive / positionless source: nothing to localise
        cls = 0 if s == 0 else 1
        src_idx = per_class[cls]
        per_class[cls] += 1
        frames = np.flatnonzero(scene.active[s] & np.isfinite(az))
        az_i = _round_half_up(az[frames])
        az_i = np.where(az_i >= 180, az_i - 360, az_i)  # 179.6 rounds to 180 == -180
        el_i = _round_half_up(scene.elevation[s][frames])
        d_cm = _round_half_up(100.0 * scene.distance[s][frames])
        rows.extend(zip(frames.tolist(), [cls] * len(frames), [src_idx] * len(frames), az_i.tolist(),
                        el_i.tolist(), d_cm.tolist()))
    rows.sort()
    return rows


def _round_half_up(x) -> np.ndarray:
    return np.floor(np.asarray(x, dtype=np.float64) + 0.5).astype(np.int64)


def export_dcase(root: str, out: str, splits=None, subtype: str = "PCM_16", progress: bool | None = False) -> dict:
    """Write the DCASE layout of ``splits`` (default: all) under ``out``; returns a summary.

    subtype: WAV sample format (``PCM_16`` as STARSS23, which the baselines scale by
    1/32768; ``PCM_24``; ``FLOAT``). PCM needs every sample in [-1, 1). progress: a bar
    per split (None: when stderr is a terminal).
    """
    if subtype not in SUBTYPES:
        raise TselError(f"unknown WAV subtype {subtype!r}; choose one of {', '.join(SUBTYPES)}")
    all_splits = list_splits(root)
    splits = list(splits) if splits else all_splits
    for s in splits:
        if s not in all_splits:
            raise DatasetError(f"{root}: no split {s!r}; available splits: {', '.join(all_splits)}")
    if os.path.abspath(out) == os.path.abspath(root):
        raise TselError(f"--out {out} is the dataset itself; choose a new directory")
    fmt = load_dataset_doc(root).format
    folds, earlier = _earlier_export(out, root, fmt, subtype)
    summary = {"out": out, "splits": {}, "rows": 0}
    query_rows = [r for r in earlier if r[1] not in splits]  # the splits not exported now stay
    for split in splits:
        fold = all_splits.index(split) + 1
        if fold > 9:
            raise DatasetError(f"{root}: split {split!r} would be fold {fold}; DCASE names hold one digit (1-9)")
        with open_dataset(root, split) as ds:
            fmt, n_scenes = ds.format, len(ds)
            audio_dir = os.path.join(out, f"{receiver(fmt).export_folder}_dev", f"dev-{split}-tsel")
            meta_dir = os.path.join(out, "metadata_dev", f"dev-{split}-tsel")
            os.makedirs(audio_dir, exist_ok=True)
            os.makedirs(meta_dir, exist_ok=True)
            n_rows = 0
            written = set()
            b = bar(n_scenes, f"export {split}", "scene", progress)
            for scene in ds:
                name = f"fold{fold}_{scene.scene_id}"
                peak = float(np.max(np.abs(scene.audio))) if scene.audio.size else 0.0
                if subtype != "FLOAT" and peak >= 1.0:
                    raise DatasetError(f"{scene.scene_id}: peak {peak:.3f} would clip in {subtype}; "
                                       f"export with --subtype FLOAT")
                save_wav(os.path.join(audio_dir, name + ".wav"), scene.audio.T, scene.fs, subtype=subtype)
                rows = dcase_rows(scene)
                write_text(os.path.join(meta_dir, name + ".csv"), _csv(rows))
                n_rows += len(rows)
                query_rows.append((str(fold), split, name, scene.scene_id, scene.query))
                written.add(name)
                b.update()
            b.close()
            _remove_stale(fold, written, audio_dir, ".wav")
            _remove_stale(fold, written, meta_dir, ".csv")
        summary["splits"][split] = {"fold": fold, "scenes": n_scenes, "rows": n_rows, "audio_dir": audio_dir,
                                    "metadata_dir": meta_dir}
        summary["rows"] += n_rows
    query_rows.sort(key=lambda r: int(r[0]))  # fold order; scene order within a fold (a stable sort)
    write_text(os.path.join(out, "queries.csv"), _csv([QUERY_COLUMNS, *query_rows]))
    folds.update({s: v["fold"] for s, v in summary["splits"].items()})
    info = {"classes": {str(k): v for k, v in CLASSES.items()},
            "folds": dict(sorted(folds.items(), key=lambda kv: kv[1])),
            "format": fmt, "source": os.path.abspath(root),
            "csv_columns": ["frame", "class", "source", "azimuth_deg", "elevation_deg", "distance_cm"],
            "frame_hop_s": 0.1, "wav_subtype": subtype}
    write_json(os.path.join(out, "classes.json"), info)
    return summary


def _csv(rows) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def _earlier_export(out: str, root: str, fmt: str, subtype: str) -> tuple[dict, list]:
    """The folds and query rows an export already in ``out`` holds, so exporting one
    split adds to it instead of dropping the other splits' queries; a DatasetError when
    it is an export of another dataset, format or WAV subtype (merging would mix them)."""
    info_path = os.path.join(out, "classes.json")
    if not os.path.exists(info_path):
        return {}, []
    try:
        with open(info_path, encoding="utf-8") as f:
            info = json.load(f)
        with open(os.path.join(out, "queries.csv"), newline="", encoding="utf-8") as f:
            rows = [tuple(r) for r in csv.reader(f)]
    except (OSError, ValueError) as e:
        raise DatasetError(f"{out} holds an unreadable export ({e}); export into an empty --out") from None
    if not isinstance(info, dict) or not rows or tuple(rows[0]) != QUERY_COLUMNS:
        raise DatasetError(f"{out} holds files that are not a tsel export (classes.json, queries.csv); export into "
                           f"an empty --out")
    theirs = {"dataset": info.get("source"), "format": info.get("format"), "WAV subtype": info.get("wav_subtype")}
    mine = {"dataset": os.path.abspath(root), "format": fmt, "WAV subtype": subtype}
    differ = [f"{k} {theirs[k]} (now {mine[k]})" for k in mine if theirs[k] != mine[k]]
    if differ:
        raise DatasetError(f"{out} holds an export of another {', '.join(differ)}; adding this one would mix them: "
                           f"export into another --out")
    return dict(info.get("folds") or {}), rows[1:]


def _remove_stale(fold: int, written: set, folder: str, ext: str) -> None:
    """Remove a split's files an earlier export wrote that this one did not (the dataset
    has fewer scenes now): the export then holds exactly the dataset's scenes."""
    for name in os.listdir(folder):
        stem, e = os.path.splitext(name)
        if e == ext and stem.startswith(f"fold{fold}_") and stem not in written:
            os.remove(os.path.join(folder, name))


def read_dcase_csv(path: str) -> np.ndarray:
    """Read a DCASE label CSV -> int64 [N, 6] (frame, class, source, az, el, dist)."""
    rows = np.loadtxt(path, delimiter=",", dtype=np.int64, ndmin=2)
    return rows.reshape(-1, 6) if rows.size else np.zeros((0, 6), np.int64)
