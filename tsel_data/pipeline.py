"""The dataset job: plan -> render shards -> finalize.

Three stages a scheduler can run separately (``tsel plan``, ``tsel render --shards``,
``tsel finalize``) or together (``tsel generate``):

- :func:`plan_dataset` checks the corpus and writes ``plan/{split}.jsonl`` and
  ``plan/config.json`` (nothing heavy has run yet; every error a user can make is
  caught here);
- :func:`render_shards` renders shards (each a pure function of its recipes) on a
  process pool or a Dask cluster, skipping shards already complete, so an interrupted
  run resumes;
- :func:`finalize` checks every shard against the plan and writes ``dataset.json`` last.

Where each file goes is :class:`~tsel_data.store.layout.Layout`'s business.
"""
from __future__ import annotations

import os
import time

import h5py
from tqdm import tqdm

from .catalog import write_bad_clips
from .config import Config, parse_config
from .errors import DatasetError
from .executors import Runner
from .h5str import as_strs
from .plan import plan_split_json, prepare_views
from .recipe import SceneRecipe
from .render import render_scene
from .store.dataset import dataset_doc, shard_attrs
from .store.layout import Layout
from .store.plans import (ShardTask, has_plan, plan_doc, read_plan_doc, read_split_plan, shard_complete, shard_tasks,
                          stored_config)
from .store.writer import shard_entry, write_error, write_json, write_lines, write_shard


# --- plan ----------------------------------------------------------------------------------


def planned_with(layout: Layout, cfg: Config) -> str:
    """Whether ``layout`` holds a plan of ``cfg``: ``"none"`` (no plan), ``"same"``, or
    ``"different"`` (another config, or an unreadable one)."""
    if not has_plan(layout):
        return "none"
    return "same" if stored_config(layout) == cfg.to_dict() else "different"


def plan_dataset(cfg: Config, out_dir: str, workers: int = 1, resume: bool = False) -> dict:
    """Check the corpus and write the plan into ``out_dir``.

    Parameters
    ----------
    cfg : Config
    out_dir : str
        The dataset folder (created).
    workers : int
        Processes for clip checks and planning.
    resume : bool
        Accept an existing plan of the same config (and plan nothing).

    Returns
    -------
    dict
        {split: scenes planned}.

    Raises
    ------
    DatasetError
        ``out_dir`` holds a plan (without ``resume``) or a plan of another config.
    TselError
        Any problem of the corpus or the bank (the first; ``tsel check`` lists all).
    """
    layout = Layout(out_dir)
    state = planned_with(layout, cfg)
    if state != "none":
        if not resume:
            raise DatasetError(f"{out_dir} already holds a dataset plan; pass --resume to continue it "
                               f"or choose another --out")
        if state == "different":
            raise DatasetError(f"{out_dir} was planned with a different config; --resume needs the same "
                               f"config, seed and splits (compare with {layout.config_file})")
        return {s: sp.count for s, sp in cfg.splits.items()}
    try:
        os.makedirs(layout.plan_dir, exist_ok=True)
    except OSError as e:
        raise write_error(out_dir, e, out_dir) from None
    catalog, views = prepare_views(cfg, layout, workers)
    write_bad_clips(layout.bad_clips_file, catalog.bad)
    counts = {}
    for split, sp in cfg.splits.items():
        lines = plan_split_json(cfg, split, views[split], workers) if sp.count else []
        write_lines(layout.plan_file(split), lines)
        counts[split] = len(lines)
    doc = plan_doc(cfg.to_dict(), {s: len(c) for s, c in catalog.clips.items()}, len(catalog.bad))
    write_json(layout.config_file, doc)  # last: its presence means the plan is complete
    return counts


def load_plan(out_dir: str) -> tuple[Config, dict[str, list[SceneRecipe]]]:
    """The stored config and every split's recipes.

    Returns
    -------
    (Config, dict)
        The config ``plan/config.json`` holds, and {split: [SceneRecipe]} in plan order.
    """
    layout = Layout(out_dir)
    cfg = parse_config(read_plan_doc(layout)["config"], where=layout.config_file)
    return cfg, {s: read_split_plan(layout, s) for s in cfg.splits}


def plan_shard_tasks(cfg: Config, plans: dict[str, list]) -> list[ShardTask]:
    """Every shard of a loaded plan."""
    return shard_tasks({s: len(r) for s, r in plans.items()}, cfg.output.shard_size)


# --- render ----------------------------------------------------------------------------------


def render_shard(out_dir: str, task: ShardTask, recipes: list[SceneRecipe], attrs: dict) -> int:
    """Render one shard's recipes and write the shard; returns its scene count."""
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
    """Render the plan's shards; complete shards are skipped.

    Parameters
    ----------
    out_dir : str
        A planned dataset folder.
    shards : range, optional
        Indices into the plan's global shard list (split by split, in order); all if None.
    workers : int
        Processes (or Dask workers for ``dask-local``).
    progress : bool
        A progress bar per split.
    executor : str
        ``local`` | ``dask`` | ``dask-local`` (executors.py).
    scheduler : str, optional
        The Dask scheduler's address for ``dask``.

    Returns
    -------
    dict
        {split: scenes rendered now}.
    """
    out_dir = os.path.abspath(out_dir)  # dask workers may run elsewhere on a shared filesystem
    layout = Layout(out_dir)
    cfg, plans = load_plan(out_dir)
    tasks = plan_shard_tasks(cfg, plans)
    if shards is not None:
        if shards.stop > len(tasks):
            raise DatasetError(f"shard range {shards.start}-{shards.stop - 1} is outside the plan's "
                               f"{len(tasks)} shards (0-{len(tasks) - 1})")
        tasks = [tasks[i] for i in shards]
    todo = [t for t in tasks if not shard_complete(layout, t)]
    attrs = shard_attrs(cfg.audio.fs, cfg.audio.label_hop, cfg.scene.format)
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
    return tqdm(total=total, initial=initial, desc=f"{split:>5}", unit="scene", disable=not progress,
                dynamic_ncols=True, mininterval=1.0)


# --- finalize ----------------------------------------------------------------------------------


def finalize(out_dir: str) -> dict:
    """Check every shard against the plan and write ``dataset.json`` (atomically, last).

    Returns
    -------
    dict
        The ``dataset.json`` document.

    Raises
    ------
    DatasetError
        A shard is missing or holds other scenes than the plan puts there.
    """
    layout = Layout(out_dir)
    cfg, plans = load_plan(out_dir)
    entries: dict[str, list] = {split: [] for split in plans}  # config order
    missing = []
    for task in plan_shard_tasks(cfg, plans):
        h5_rel = task.files[0]
        if not shard_complete(layout, task):
            missing.append(h5_rel)
            continue
        want = [r.scene_id for r in plans[task.split][task.start:task.stop]]
        with h5py.File(layout.path(h5_rel), "r") as h:
            got = as_strs(h["scene_id"][()])
        if got != want:
            raise DatasetError(f"{h5_rel} does not hold the planned scenes {want[0]}..{want[-1]}; "
                               f"delete it and run `tsel render` again")
        entries[task.split].append(shard_entry(out_dir, task.split, task.shard, len(want)))
    if missing:
        raise DatasetError(f"{len(missing)} shard(s) not rendered yet, e.g. {missing[0]}; "
                           f"run `tsel render {out_dir}` (or `tsel generate ... --resume`) first")
    doc = dataset_doc(cfg.to_dict(), cfg.seed, shard_attrs(cfg.audio.fs, cfg.audio.label_hop, cfg.scene.format),
                      entries)
    write_json(layout.dataset_file, doc)
    return doc


def generate(cfg: Config, out_dir: str, workers: int = 1, resume: bool = False, progress: bool = True,
             executor: str = "local", scheduler: str | None = None) -> dict:
    """Plan, render and finalize a dataset (the three stages above, in one call).

    Parameters are those of :func:`plan_dataset` and :func:`render_shards`.

    Returns
    -------
    dict
        ``out``, ``splits`` ({split: scenes}), ``rendered_now`` ({split: scenes rendered by
        this call}), ``bad_clips`` (count), ``plan_seconds``, ``render_seconds``, ``bytes``
        (on disk).
    """
    t0 = time.perf_counter()
    plan_dataset(cfg, out_dir, workers=workers, resume=resume)
    t1 = time.perf_counter()
    rendered = render_shards(out_dir, workers=workers, progress=progress, executor=executor, scheduler=scheduler)
    t2 = time.perf_counter()
    doc = finalize(out_dir)
    bad = 0
    bad_path = Layout(out_dir).bad_clips_file
    if os.path.exists(bad_path):
        with open(bad_path, encoding="utf-8") as f:
            bad = sum(1 for _ in f)
    return {"out": out_dir, "splits": {s: v["scenes"] for s, v in doc["splits"].items()},
            "rendered_now": rendered, "bad_clips": bad, "plan_seconds": t1 - t0, "render_seconds": t2 - t1,
            "bytes": _dir_size(out_dir)}


def _dir_size(d: str) -> int:
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(d) for f in fs)
