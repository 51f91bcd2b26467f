"""The dataset job: plan -> render shards -> finalize.

Three stages a scheduler can run separately (``tsel plan``, ``tsel render --shards``,
``tsel finalize``) or together (``tsel generate``):

- ``plan_dataset`` checks the corpus and writes ``plan/{split}.jsonl`` and
  ``plan/config.json`` (nothing heavy has run yet; every error a user can make is
  caught here);
- ``render_shards`` renders shards (each a pure function of its recipes) on a process
  pool, skipping shards already complete, so an interrupted run resumes;
- ``finalize`` checks every shard against the plan and writes ``dataset.json`` last.
"""
from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass

from . import __version__
from .catalog import build_catalog, write_bad_clips
from .config import Config, parse_config
from .errors import DatasetError
from .executors import Runner
from .plan import CatalogView, plan_split_json, resolve_bank
from .recipe import SceneRecipe, read_plan
from .store.writer import FORMAT_VERSION, atomic_write, remove_stale_tmp, shard_entry, shard_names, write_error, write_shard

PLAN_DIR = "plan"
CONFIG_FILE = "plan/config.json"

CONVENTIONS = {
    "array_frame": "right-handed, origin at the array centre, x front, y left, z up",
    "azimuth": "degrees, counter-clockwise from +x seen from above, [-180, 180)",
    "elevation": "degrees above the horizontal plane, [-90, 90]",
    "distance": "metres from the array centre",
    "label_frames": "frame k covers [k*hop, (k+1)*hop); position at the frame centre",
    "foa": "ACN (W, Y, Z, X), SN3D",
    "mic4": "mic k at azimuth 45 + 90k degrees, radius side/sqrt(2): front-left, back-left, back-right, front-right",
    "sources": "source 0 is the target; NaN positions for absent or non-directional sources",
}


@dataclass(frozen=True)
class ShardTask:
    split: str
    shard: int
    start: int
    stop: int


# --- plan ----------------------------------------------------------------------------------


def plan_dataset(cfg: Config, out_dir: str, workers: int = 1, resume: bool = False) -> dict:
    """Check the corpus, write the plan. Returns {split: scene count}."""
    stored = os.path.join(out_dir, CONFIG_FILE)
    if os.path.exists(stored):
        if not resume:
            raise DatasetError(f"{out_dir} already holds a dataset plan; pass --resume to continue it "
                               f"or choose another --out")
        old = load_config_json(out_dir)
        if old["config"] != cfg.to_dict():
            raise DatasetError(f"{out_dir} was planned with a different config; --resume needs the same "
                               f"config, seed and splits (compare with {stored})")
        return {s: sp.count for s, sp in cfg.splits.items()}
    try:
        os.makedirs(os.path.join(out_dir, PLAN_DIR), exist_ok=True)
    except OSError as e:
        raise write_error(out_dir, e, out_dir) from None
    catalog = build_catalog(cfg, out_dir, workers=workers)
    bank_path = resolve_bank(cfg, out_dir)
    write_bad_clips(os.path.join(out_dir, "bad_clips.jsonl"), catalog.bad)
    counts = {}
    for split, sp in cfg.splits.items():
        lines = plan_split_json(cfg, split, CatalogView(catalog.clips[split], bank_path), workers) if sp.count else []
        _write_lines(os.path.join(out_dir, PLAN_DIR, f"{split}.jsonl"), lines)
        counts[split] = len(lines)
    doc = {"tool": "tsel-data", "version": __version__, "config": cfg.to_dict(),
           "clips": {s: len(c) for s, c in catalog.clips.items()}, "bad_clips": len(catalog.bad)}
    _write_json(stored, doc)  # last: its presence means the plan is complete
    return counts


def load_config_json(out_dir: str) -> dict:
    path = os.path.join(out_dir, CONFIG_FILE)
    if not os.path.isfile(path):
        raise DatasetError(f"{out_dir} has no plan ({CONFIG_FILE} missing); run `tsel plan` or `tsel generate` first")
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DatasetError(f"{path} is damaged ({e}); plan again into a new --out") from None


def load_plan(out_dir: str) -> tuple[Config, dict[str, list[SceneRecipe]]]:
    doc = load_config_json(out_dir)
    cfg = parse_config(doc["config"], where=os.path.join(out_dir, CONFIG_FILE))
    plans = {s: read_plan(os.path.join(out_dir, PLAN_DIR, f"{s}.jsonl")) for s in cfg.splits}
    return cfg, plans


def shard_tasks(cfg: Config, plans: dict[str, list]) -> list[ShardTask]:
    size = cfg.output.shard_size
    tasks = []
    for split, recipes in plans.items():
        for k, start in enumerate(range(0, len(recipes), size)):
            tasks.append(ShardTask(split, k, start, min(start + size, len(recipes))))
    return tasks


# --- render ----------------------------------------------------------------------------------


def shard_attrs(cfg: Config) -> dict:
    from .geometry import CHANNEL_NAMES

    return {"fs": cfg.audio.fs, "label_hop": cfg.audio.label_hop, "format": cfg.scene.format,
            "channel_names": list(CHANNEL_NAMES[cfg.scene.format]), "format_version": FORMAT_VERSION}


def shard_complete(out_dir: str, task: ShardTask) -> bool:
    h5, js = shard_names(task.split, task.shard)
    return os.path.isfile(os.path.join(out_dir, h5)) and os.path.isfile(os.path.join(out_dir, js))


def render_shard(out_dir: str, task: ShardTask, recipes: list[SceneRecipe], attrs: dict) -> int:
    from .render import render_scene

    scenes = [render_scene(r) for r in recipes]
    # write_shard's entry (with checksums) is not needed here: finalize makes it, also for
    # shards other processes wrote
    write_shard(out_dir, task.split, task.shard, scenes, attrs, checksums=False)
    return len(scenes)


def _render_task(args) -> tuple[ShardTask, int]:
    out_dir, task, recipes, attrs = args
    return task, render_shard(out_dir, task, recipes, attrs)


def render_shards(out_dir: str, shards: range | None = None, workers: int = 1, progress: bool = True,
                  executor: str = "local", scheduler: str | None = None) -> dict:
    """Render the plan's shards (all, or the indices in ``shards`` of the global shard list).

    Complete shards are skipped. ``executor``: local | dask | dask-local (executors.py).
    Returns {split: scenes rendered now}.
    """
    out_dir = os.path.abspath(out_dir)  # dask workers may run elsewhere on a shared filesystem
    cfg, plans = load_plan(out_dir)
    tasks = shard_tasks(cfg, plans)
    if shards is not None:
        if shards.stop > len(tasks):
            raise DatasetError(f"shard range {shards.start}-{shards.stop - 1} is outside the plan's "
                               f"{len(tasks)} shards (0-{len(tasks) - 1})")
        tasks = [tasks[i] for i in shards]
    todo = [t for t in tasks if not shard_complete(out_dir, t)]
    attrs = shard_attrs(cfg)
    done: dict[str, int] = {s: 0 for s in plans}
    with Runner(executor, workers if len(todo) > 1 else 1, scheduler) as runner:
        # split by split, so each split gets its own progress bar and rate
        for split in plans:
            jobs = [(out_dir, t, plans[t.split][t.start:t.stop], attrs) for t in todo if t.split == split]
            total = sum(t.stop - t.start for t in tasks if t.split == split)
            if not total:
                continue
            bar = _bar(split, total, total - sum(j[1].stop - j[1].start for j in jobs), progress)
            for t, n in runner.map_unordered(_render_task, jobs):
                done[t.split] += n
                bar.update(n)
            bar.close()
    return done


def _bar(split: str, total: int, initial: int, progress: bool):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=f"{split:>5}", unit="scene", disable=not progress,
                dynamic_ncols=True, mininterval=1.0)


# --- finalize ----------------------------------------------------------------------------------


def finalize(out_dir: str) -> dict:
    """Check every shard against the plan and write ``dataset.json`` (atomically, last)."""
    import h5py

    cfg, plans = load_plan(out_dir)
    splits: dict[str, dict] = {split: {"scenes": 0, "shards": []} for split in plans}  # config order
    missing = []
    for task in shard_tasks(cfg, plans):
        h5_rel = shard_names(task.split, task.shard)[0]
        h5_path = os.path.join(out_dir, h5_rel)
        if not shard_complete(out_dir, task):
            missing.append(h5_rel)
            continue
        want = [r.scene_id for r in plans[task.split][task.start:task.stop]]
        with h5py.File(h5_path, "r") as h:
            got = [s.decode() if isinstance(s, bytes) else s for s in h["scene_id"][()]]
        if got != want:
            raise DatasetError(f"{h5_rel} does not hold the planned scenes {want[0]}..{want[-1]}; "
                               f"delete it and run `tsel render` again")
        splits[task.split]["scenes"] += len(want)
        splits[task.split]["shards"].append(shard_entry(out_dir, task.split, task.shard, len(want)))
    if missing:
        raise DatasetError(f"{len(missing)} shard(s) not rendered yet, e.g. {missing[0]}; "
                           f"run `tsel render {out_dir}` (or `tsel generate ... --resume`) first")
    doc = {"tool": "tsel-data", "version": __version__, "format_version": FORMAT_VERSION,
           "conventions": CONVENTIONS, "config": cfg.to_dict(), "seed": cfg.seed, **shard_attrs(cfg),
           "splits": splits}
    _write_json(os.path.join(out_dir, "dataset.json"), doc)
    return doc


def generate(cfg: Config, out_dir: str, workers: int = 1, resume: bool = False, progress: bool = True,
             executor: str = "local", scheduler: str | None = None) -> dict:
    """Plan, render and finalize a dataset. Returns a summary dict."""
    t0 = time.perf_counter()
    plan_dataset(cfg, out_dir, workers=workers, resume=resume)
    t1 = time.perf_counter()
    rendered = render_shards(out_dir, workers=workers, progress=progress, executor=executor, scheduler=scheduler)
    t2 = time.perf_counter()
    doc = finalize(out_dir)
    bad = 0
    bad_path = os.path.join(out_dir, "bad_clips.jsonl")
    if os.path.exists(bad_path):
        with open(bad_path, encoding="utf-8") as f:
            bad = sum(1 for _ in f)
    return {"out": out_dir, "splits": {s: v["scenes"] for s, v in doc["splits"].items()},
            "rendered_now": rendered, "bad_clips": bad, "plan_seconds": t1 - t0, "render_seconds": t2 - t1,
            "bytes": _dir_size(out_dir)}


def _dir_size(d: str) -> int:
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(d) for f in fs)


def _write_lines(path: str, lines: list[str]) -> None:
    _write_text(path, "".join(line + "\n" for line in lines))


def _write_json(path: str, doc: dict) -> None:
    _write_text(path, json.dumps(doc, ensure_ascii=False, indent=1) + "\n")


def _write_text(path: str, text: str) -> None:
    """Atomic write (store.writer.atomic_write); a failed write is one clear line."""
    remove_stale_tmp(path)
    try:
        atomic_write(path, text.encode("utf-8"))
    except OSError as e:
        raise write_error(os.path.basename(path), e, os.path.dirname(path)) from None
