"""``tsel check DIR``: verify a written dataset against its ``dataset.json`` and plan.

Every listed shard must exist with the recorded sha256 (HDF5 and JSON); each HDF5 must
hold the datasets and shapes of docs/format.md and agree scene by scene with its JSON
(ids, queries, per-frame labels, activity, mic positions); counts must match the plan
and the config; ``audio=True`` also checks every sample is finite. An unfinished run
(plan but no ``dataset.json``) is reported with its progress. Problems are collected
in a :class:`~tsel_data.core.report.CheckReport`, never raised.
"""
from __future__ import annotations

import glob
import json
import os
from concurrent.futures import ProcessPoolExecutor

import h5py
import numpy as np

from ..core.digest import sha256_file
from ..core.files import path_problem
from ..core.h5str import as_str, as_strs
from ..core.report import CheckReport
from ..errors import DatasetError, TselError
from .codings import coding_of, decode
from .dataset import load_dataset_doc
from .layout import SEAL_SUFFIX, Layout
from .plans import config_digest, has_plan, plan_ids, read_plan_doc, seal_problem, shard_sealed, shard_tasks
from .records import LABEL_ATOL, LABEL_KEYS, SourceRecord


def check_dataset(out_dir: str, workers: int = 1, audio: bool = True) -> CheckReport:
    """Verify a dataset folder.

    Parameters
    ----------
    out_dir : str
    workers : int
        Processes checking shards in parallel.
    audio : bool
        Also check that every audio sample is finite.

    Returns
    -------
    CheckReport
    """
    rep = CheckReport(f"dataset {out_dir}")
    if not os.path.isdir(out_dir):
        why = f" {path_problem(out_dir, folder=True)}" if os.path.lexists(out_dir) else ": no such folder"
        rep.error(DatasetError(f"{out_dir}{why}; give the --out folder of `tsel generate`"))
        return rep
    layout = Layout(out_dir)
    if not os.path.isfile(layout.dataset_file):
        _report_unfinished(layout, rep)
        return rep
    try:
        doc = load_dataset_doc(out_dir)
        audio_cfg = doc.config["audio"]
        expect = {"fs": doc.fs, "format": doc.format, "channels": len(doc.channel_names),
                  "coding": str(doc.raw.get("audio_coding", "float32")),
                  "samples": int(round(audio_cfg["duration"] * audio_cfg["fs"])),
                  "frames": int(round(audio_cfg["duration"] / audio_cfg["label_hop"])), "audio": audio}
    except TselError as e:
        rep.error(e)
        return rep
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as e:
        rep.error(DatasetError(f"{layout.dataset_file}: its config is incomplete ({type(e).__name__}: {e}); "
                               f"rerun `tsel finalize {out_dir}`"))
        return rep
    for problem in _seal_problems(layout, doc.raw):
        rep.error(DatasetError(problem))
    config_splits = doc.config.get("splits") or {}
    jobs = []
    rep.facts["splits"] = {}
    total_bytes = 0
    for split, shards in doc.splits.items():
        n = sum(sh.scenes for sh in shards)
        listed = doc.counts[split]
        rep.facts["splits"][split] = {"scenes": listed, "shards": len(shards)}
        want = (config_splits.get(split) or {}).get("count")
        if n != listed:
            rep.error(DatasetError(f"{layout.dataset_file}: split {split} lists {listed} scenes but its shards hold "
                                   f"{n}; rerun `tsel finalize {out_dir}`"))
        if want is not None and n != want:
            rep.error(DatasetError(f"{layout.dataset_file}: split {split} holds {n} scenes but the config asks for "
                                   f"{want}; the dataset is incomplete: rerun `tsel generate ... --resume`"))
        try:
            ids = plan_ids(layout, split)
        except DatasetError as e:
            rep.error(e)
            ids = None
        if ids is not None and len(ids) != n:
            rep.error(DatasetError(f"{split}: the plan (plan/{split}.jsonl) has {len(ids)} scenes, the shards "
                                   f"{n}; rerun `tsel render {out_dir}` and `tsel finalize {out_dir}`"))
        start = 0
        for sh in shards:
            part = ids[start:start + sh.scenes] if ids is not None and len(ids) == n else None
            jobs.append((out_dir, sh, part, expect))
            start += sh.scenes
            for rel in (sh.file, sh.json):
                p = layout.path(rel)
                if os.path.isfile(p):
                    total_bytes += os.path.getsize(p)
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(min(workers, len(jobs))) as ex:
            results = list(ex.map(_check_shard, jobs))
    else:
        results = [_check_shard(j) for j in jobs]
    for problems in results:
        for p in problems:
            rep.error(DatasetError(p))
    listed_files = {os.path.normpath(rel) for shards in doc.splits.values() for sh in shards
                    for rel in (sh.file, sh.json)}
    for split in doc.splits:
        for p in sorted(glob.glob(os.path.join(glob.escape(layout.split_dir(split)), "*"))):
            rel = os.path.relpath(p, out_dir)
            if ".tmp-" in os.path.basename(p):
                rep.warnings.append(f"{rel}: leftover temporary file of an interrupted write; safe to delete")
            elif rel not in listed_files and p.endswith((".h5", ".json")) and not p.endswith(SEAL_SUFFIX):
                rep.warnings.append(f"{rel}: not listed in dataset.json; delete it or rerun `tsel finalize {out_dir}`")
    rep.facts["bytes"] = total_bytes
    return rep


def _seal_problems(layout: Layout, raw: dict) -> list[str]:
    """Whether ``dataset.json`` and the plan are still what finalize sealed: its config
    and seed, the plan's config and every plan file. A dataset finalized before plans
    were sealed has nothing to compare."""
    seal = raw.get("plan_seal")
    if not isinstance(seal, dict):
        return []
    fix = "the dataset was edited after it was made: make it again, or put the files back as they were"
    problems = []
    config = raw.get("config") or {}
    if config_digest(config) != seal.get("config_sha256") or raw.get("seed") != config.get("seed"):
        problems.append(f"{layout.dataset_file}: its config or seed no longer matches the plan it was made from; "
                        f"{fix}")
    try:
        plan = read_plan_doc(layout)
    except TselError as e:
        return problems + [str(e)]
    if plan.get("seal") != seal:
        problems.append(f"{layout.config_file}: another plan than the one {layout.dataset_file} was made from; {fix}")
    else:
        problem = seal_problem(layout, plan)
        if problem:
            problems.append(f"{problem}; {fix}")
    return problems


def _report_unfinished(layout: Layout, rep: CheckReport) -> None:
    out_dir = layout.root
    if not has_plan(layout):
        rep.error(DatasetError(f"{out_dir}: not a dataset (no dataset.json and no plan); give the --out folder of "
                               f"`tsel generate`, or check a config with `tsel check --preset/--config`"))
        return
    try:
        config = read_plan_doc(layout)["config"]
        counts = {s: len(plan_ids(layout, s) or []) for s in config["splits"]}
        tasks = shard_tasks(counts, int(config["output"]["shard_size"]))
    except (TselError, OSError, ValueError, KeyError, TypeError) as e:
        rep.error(DatasetError(f"{out_dir}: the plan is unreadable ({e}); plan again into a new --out"))
        return
    done = sum(shard_sealed(layout, t) for t in tasks)
    rep.facts["splits"] = {s: {"scenes": n} for s, n in counts.items()}
    rep.error(DatasetError(f"{out_dir}: unfinished dataset (no dataset.json): {done} of {len(tasks)} shards rendered; "
                           f"continue with `tsel generate ... --resume` or `tsel render {out_dir}` then "
                           f"`tsel finalize {out_dir}`"))


def _check_shard(job) -> list[str]:
    """Problems of one shard (empty list when it is sound)."""
    out_dir, entry, ids_planned, expect = job
    h5_path, js_path = os.path.join(out_dir, entry.file), os.path.join(out_dir, entry.json)
    fix = f"delete it and rerun `tsel render {out_dir}` and `tsel finalize {out_dir}`"
    problems = []
    for rel, path, digest in ((entry.file, h5_path, entry.sha256), (entry.json, js_path, entry.json_sha256)):
        special = path_problem(path)
        if special and special != "does not exist":  # a FIFO would keep the hash waiting
            problems.append(f"{rel} {special}; {fix}")
        elif not os.path.isfile(path):
            problems.append(f"{rel}: listed in dataset.json but missing; rerun `tsel render {out_dir}` and "
                            f"`tsel finalize {out_dir}`")
        elif digest and sha256_file(path) != digest:
            problems.append(f"{rel}: sha256 differs from dataset.json (the file changed or is corrupt); {fix}")
    if problems:
        return problems
    try:
        with open(js_path, encoding="utf-8") as f:
            js = json.load(f)["scenes"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        return [f"{entry.json}: unreadable shard JSON ({e}); {fix}"]
    try:
        with h5py.File(h5_path, "r") as h:
            return _compare_shard(h, js, entry, ids_planned, expect, fix)
    except (OSError, KeyError) as e:
        return [f"{entry.file}: unreadable or incomplete HDF5 ({e}); {fix}"]


def _compare_shard(h, js: list, entry, ids_planned, expect: dict, fix: str) -> list[str]:
    rel, n = entry.file, entry.scenes
    a = h["audio"]
    coding = coding_of(a)
    if coding != expect["coding"]:
        return [f"{rel}: audio coded as {coding}, dataset.json says {expect['coding']}; {fix}"]
    shape = (a.shape[0], *(int(v) for v in a.attrs["audio_shape"])) if coding == "flac" else a.shape
    if len(shape) != 3 or shape[0] != n or shape[1] != expect["channels"] or shape[2] != expect["samples"]:
        return [f"{rel}: audio has shape {shape}, expected ({n}, {expect['channels']}, {expect['samples']}); {fix}"]
    fmt = as_str(h.attrs.get("format"), None)
    if h.attrs.get("fs") != expect["fs"] or fmt != expect["format"]:
        return [f"{rel}: fs/format attributes ({h.attrs.get('fs')}, {fmt}) differ from "
                f"dataset.json ({expect['fs']}, {expect['format']}); {fix}"]
    ids = as_strs(h["scene_id"][()])
    if len(js) != n or [s.get("scene_id") for s in js] != ids:
        return [f"{rel}: HDF5 scene ids differ from its JSON's ({len(ids)} vs {len(js)} scenes); {fix}"]
    if ids_planned is not None and ids != list(ids_planned):
        return [f"{rel}: holds scenes {ids[0]}..{ids[-1]} but the plan puts {ids_planned[0]}..{ids_planned[-1]} "
                f"here; {fix}"]
    queries = as_strs(h["query"][()])
    labels = {k: h[f"labels/{k}"][()] for k in LABEL_KEYS}
    active = h["labels/active"][()]
    mics = h["mic_positions"][()]
    if labels["azimuth"].shape[2] != expect["frames"]:
        return [f"{rel}: labels have {labels['azimuth'].shape[2]} frames, expected {expect['frames']}; {fix}"]
    for i, scene in enumerate(js):
        sid = ids[i]
        if queries[i] != scene.get("query"):
            return [f"{rel}: scene {sid}: query differs between HDF5 and JSON; {fix}"]
        srcs = [SourceRecord.from_json(s, k) for k, s in enumerate(scene.get("sources", []))]
        if len(srcs) > labels["azimuth"].shape[1]:
            return [f"{rel}: scene {sid}: JSON has {len(srcs)} sources, HDF5 room for {labels['azimuth'].shape[1]}; {fix}"]
        for k in range(labels["azimuth"].shape[1]):
            for key, arr in labels.items():
                got = arr[i, k]
                want = srcs[k].labels(key) if k < len(srcs) else np.full(got.shape, np.nan)
                if want.shape != got.shape or not np.allclose(got, want, atol=LABEL_ATOL, equal_nan=True):
                    return [f"{rel}: scene {sid} source {k}: {key} labels differ between HDF5 and JSON; {fix}"]
            want_act = srcs[k].active if k < len(srcs) else [False] * active.shape[2]
            if active[i, k].tolist() != list(want_act):
                return [f"{rel}: scene {sid} source {k}: activity differs between HDF5 and JSON; {fix}"]
        jm = (scene.get("array") or {}).get("mic_positions")
        if jm is not None and not np.allclose(mics[i], np.asarray(jm, dtype=np.float64), atol=1e-5):
            return [f"{rel}: scene {sid}: mic positions differ between HDF5 and JSON; {fix}"]
        if expect["audio"]:
            try:
                x = decode(a[i], coding)
            except (RuntimeError, ValueError, OSError) as e:  # a damaged FLAC row
                return [f"{rel}: scene {sid}: audio does not decode ({e}); {fix}"]
            if x.shape != (expect["channels"], expect["samples"]) or not np.all(np.isfinite(x)):
                return [f"{rel}: scene {sid}: audio holds NaN or Inf samples, or decodes to shape {x.shape}; {fix}"]
    return []
