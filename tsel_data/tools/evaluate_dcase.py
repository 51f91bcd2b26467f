"""``tsel eval --dcase``: the DCASE 2024 SELD metrics (:mod:`tsel_data.tools.seld`) of a folder
of DCASE output CSVs against a split's labels as ``tsel export dcase`` writes them.

Apart from :mod:`tsel_data.tools.evaluate` because it reads the export's label rows, and the
export package (its dataset card) reads evaluate's SNR groups.
"""
from __future__ import annotations

import os

import numpy as np

from ..core.files import check_input
from ..errors import DatasetError, PredictionError
from ..formats.dcase import FRAME_HOP, dcase_rows
from ..store.reader import open_dataset
from .seld import SeldAccumulator, SeldScores, frames_of

CLASSES = (0, 1)  # a tsel export's: 0 the query's target, 1 the other directional sources (export/dcase.py)


def row_problem(row: list, classes=CLASSES) -> str | None:
    """What makes a prediction row no row of this dataset's, or None: a frame or source
    that is not a whole number from 0, a class the dataset does not have, angles out of
    range, a negative distance (DCASE output CSVs hold no such rows; a scorer would drop
    or misread them and report a wrong score)."""
    frame, cls, source, az, el = row[:5]
    if frame < 0 or not float(frame).is_integer():
        return f"frame {frame:g} is not a frame number (a whole number from 0)"
    if cls not in classes:
        return (f"class {cls:g} is not a class of the dataset: its classes are 0 (the query's target) and 1 (the "
                f"other sources)")
    if source < 0 or not float(source).is_integer():
        return f"source {source:g} is not a source index (a whole number from 0)"
    if not -360 <= az <= 360 or not -90 <= el <= 90:
        return f"azimuth {az:g}° or elevation {el:g}° is not an angle in degrees (azimuth ±180, elevation ±90)"
    if len(row) > 5 and row[5] < 0:
        return f"distance {row[5]:g} cm is negative"
    return None


def read_dcase_predictions(pred_dir: str) -> dict[str, list]:
    """{scene_id: rows} from a folder of DCASE output CSVs, one per scene, named as the
    DCASE export names them (``fold{n}_{scene_id}.csv``, or ``{scene_id}.csv``); rows
    ``frame,class,source,azimuth,elevation[,distance_cm]`` (no header), each checked
    (:func:`row_problem`)."""
    fix = "give the folder of DCASE prediction CSVs (one per scene)"
    check_input(pred_dir, PredictionError, fix, folder=True)
    if not os.path.isdir(pred_dir):
        raise PredictionError(f"{pred_dir}: not a folder; {fix}")
    out: dict[str, list] = {}
    for name in sorted(os.listdir(pred_dir)):
        if not name.endswith(".csv"):
            continue
        stem = name[:-4]
        sid = stem.split("_", 1)[1] if stem.startswith("fold") and "_" in stem else stem
        path = os.path.join(pred_dir, name)
        check_input(path, PredictionError, "a prediction is a CSV file")  # a FIFO would block, /dev/zero never end
        rows = []
        with open(path, encoding="utf-8", errors="replace") as f:
            for n, line in enumerate(f, 1):
                if not line.strip():
                    continue
                try:
                    row = [float(v) for v in line.split(",")]
                except ValueError:
                    row = []
                if len(row) not in (5, 6) or not all(np.isfinite(row)):
                    raise PredictionError(f"{path}:{n}: a row is frame,class,source,azimuth,elevation[,distance_cm] "
                                          f"(numbers), got {line.strip()[:80]!r}")
                problem = row_problem(row)
                if problem:
                    raise PredictionError(f"{path}:{n}: {problem}; a row is frame,class,source,azimuth,elevation"
                                          f"[,distance_cm] as `tsel export dcase` writes them")
                rows.append(row)
        if sid in out:
            raise PredictionError(f"{pred_dir}: scene {sid!r} has two prediction files; keep one")
        out[sid] = rows
    return out


def evaluate_dcase(root: str, split: str, pred_dir: str) -> SeldScores:
    """The DCASE 2024 SELD metrics (tsel_data/tools/seld.py) of the DCASE output CSVs in
    ``pred_dir`` against the split's labels as ``tsel export dcase`` writes them."""
    preds = read_dcase_predictions(pred_dir)
    acc = SeldAccumulator(classes=CLASSES)
    with open_dataset(root, split) as ds:
        ids = set(ds.scene_ids())
        unknown = sorted(set(preds) - ids)
        if unknown:
            raise PredictionError(f"{pred_dir}: {len(unknown):,} file(s) name no scene of split {split!r}, e.g. "
                                  f"{unknown[0]!r}; predict the scenes of `--split {split}`")
        missing = sorted(ids - set(preds))
        if missing:
            raise PredictionError(f"{pred_dir}: {len(missing):,} of {len(ids):,} scenes of split {split!r} have no "
                                  f"prediction file, e.g. {missing[0] + '.csv'!r}; write one per scene (empty: nothing "
                                  f"detected)")
        if abs(ds.label_hop - FRAME_HOP) > 1e-9:
            raise DatasetError(f"{root}: label_hop is {ds.label_hop} s; the DCASE metrics need {FRAME_HOP} s frames")
        for scene in ds.iter_labels():
            n = scene.azimuth.shape[1]
            for ref, pred in zip(frames_of(dcase_rows(scene), n), frames_of(preds[scene.scene_id], n)):
                acc.add_frame(ref, pred)
    return acc.scores()
