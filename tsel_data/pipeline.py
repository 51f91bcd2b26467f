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

from .catalog import write_bad_clips, write_missing_clips
from .config import Config, Difference, config_differences, parse_config
from .errors import DatasetError, TselError
from .executors import Runner
from .h5str import as_strs
from .plan import plan_split_json, prepare_views
from .recipe import SceneRecipe
from .render import render_scene
from .store.dataset import dataset_doc, shard_attrs
from .store.layout import Layout
from .store.plans import (ShardTask, has_plan, plan_doc, read_plan_doc, read_plan_lines, read_split_plan,
                          shard_complete, shard_tasks, stored_config)
from .store.writer import shard_entry, write_error, write_json, write_lines, write_shard


# --- plan ----------------------------------------------------------------------------------


def planned_with(layout: Layout, cfg: Config) -> str:
    """Whether ``layout`` holds a plan of ``cfg``: ``"none"`` (no plan), ``"same"``, or
    ``"different"`` (another config, or an unreadable one)."""
    if not has_plan(layout):
        return "none"
    try:
        return "different" if plan_differences(layout, cfg) else "same"
    except TselError:
        return "different"


def plan_differences(layout: Layout, cfg: Config) -> list[Difference]:
    """The keys where ``cfg`` differs from the config ``layout``'s plan was made with
    (DatasetError when the stored config is unreadable)."""
    stored = stored_config(layout)
    if stored is None:
        raise DatasetError(f"{layout.config_file} is damaged or holds no config; plan again into a new --out")
    return config_differences(stored, cfg, where=layout.config_file)


def growth(diffs: list[Difference]) -> dict[str, tuple[int, int]] | None:
    """{split: (planned, asked)} when every difference is a larger ``splits.NAME.count``
    of a split the plan has (what ``--grow`` adds scenes for), else None."""
    out = {}
    for d in diffs:
        parts = d.key.split(".")
        if len(parts) != 3 or parts[0] != "splits" or parts[2] != "count" or not isinstance(d.before, int) \
                or not isinstance(d.after, int) or d.after < d.before:
            return None
        out[parts[1]] = (d.before, d.after)
    return out or None


def _refuse(out_dir: str, layout: Layout, diffs: list[Difference], grow: bool) -> DatasetError:
    """The one-line refusal to continue a plan of another config, naming the keys."""
    shown = "; ".join(str(d) for d in diffs[:4]) + (f"; and {len(diffs) - 4} more" if len(diffs) > 4 else "")
    counts_only = all(d.key.startswith("splits.") and d.key.endswith(".count") for d in diffs)
    if counts_only and growth(diffs):
        fix = "to add the scenes to this dataset pass --grow (the planned scenes stay as they are)"
    elif counts_only:
        fix = "a dataset does not shrink: ask for at least the planned counts, or choose another --out"
    else:
        fix = (f"--resume needs the config the plan was made with ({layout.config_file}); use it, or choose "
               f"another --out" + (" (--grow changes only splits.NAME.count)" if grow else ""))
    return DatasetError(f"{out_dir} was planned with a different config: {shown}; {fix}")


def plan_dataset(cfg: Config, out_dir: str, workers: int = 1, resume: bool = False, grow: bool = False,
                 progress: bool | None = None, report=None) -> dict:
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
    grow : bool
        Accept an existing plan whose config asks fewer scenes of some splits, and add
        the scenes: the planned ones keep their recipes (and rendered shards their
        bytes), so the grown dataset is the one a fresh run with the new counts makes.
    progress : bool or None
        Bars while clips are checked (None: on a terminal).
    report : callable, optional
        Called with one-line notes for the user: per split, how many of the listed
        clips are present; clips reused by many scenes.

    Returns
    -------
    dict
        {split: scenes planned}.

    Raises
    ------
    DatasetError
        ``out_dir`` holds a plan (without ``resume``/``grow``) or a plan of another
        config (naming the keys that differ).
    TselError
        Any problem of the corpus or the bank (the first; ``tsel check`` lists all).
    """
    layout = Layout(out_dir)
    state = planned_with(layout, cfg)
    if state != "none":
        if not resume and not grow:
            raise DatasetError(f"{out_dir} already holds a dataset plan; pass --resume to continue it "
                               f"or choose another --out")
        diffs = plan_differences(layout, cfg)
        if not diffs:
            return {s: sp.count for s, sp in cfg.splits.items()}
        grown = growth(diffs) if grow else None
        if grown is None:
            raise _refuse(out_dir, layout, diffs, grow)
        return _grow(cfg, layout, grown, workers, progress, report)
    try:
        os.makedirs(layout.plan_dir, exist_ok=True)
    except OSError as e:
        raise write_error(out_dir, e, out_dir) from None
    catalog, views = _catalog(cfg, layout, workers, progress, report)
    plans = {split: plan_split_json(cfg, split, views[split], workers) if sp.count else []
             for split, sp in cfg.splits.items()}
    _write_plan(cfg, layout, catalog, plans)
    return {split: len(lines) for split, lines in plans.items()}


def _catalog(cfg: Config, layout: Layout, workers: int, progress, report):
    """The checked catalog and planning views, with the notes the user should see first."""
    catalog, views = prepare_views(cfg, layout, workers, progress)
    if report:
        for line in catalog.presence_lines() + [f"warning: {w}" for w in catalog.warnings]:
            report(line)
    return catalog, views


def _write_plan(cfg: Config, layout: Layout, catalog, plans: dict[str, list[str]]) -> None:
    """bad_clips.jsonl, missing_clips.json (when files are missing), the plan files, and
    plan/config.json last: its presence means the plan is complete."""
    write_bad_clips(layout.bad_clips_file, catalog.bad)
    missing = {s: len(c) for s, c in catalog.missing.items() if c}
    if missing:
        write_missing_clips(layout.missing_clips_file, catalog)
    for split, lines in plans.items():
        write_lines(layout.plan_file(split), lines)
    doc = plan_doc(cfg.to_dict(), {s: len(c) for s, c in catalog.clips.items()}, len(catalog.bad), missing)
    write_json(layout.config_file, doc)


def _grow(cfg: Config, layout: Layout, grown: dict[str, tuple[int, int]], workers: int, progress, report) -> dict:
    """Add scenes to a planned (perhaps finished) dataset: plan every split again with
    the same catalog, require the planned scenes to come out the same (else the corpus or
    bank changed and the grown dataset would mix two), mark the dataset unfinished
    (dataset.json removed), remove each grown split's last shard if it was partial (it
    is rendered again, fuller), then write the longer plan."""
    catalog, views = _catalog(cfg, layout, workers, progress, report)
    plans = {}
    for split, sp in cfg.splits.items():
        before = read_plan_lines(layout, split)
        if split not in grown:
            plans[split] = before
            continue
        planned = grown[split][0]
        lines = plan_split_json(cfg, split, views[split], workers) if sp.count else []
        changed = next((i for i in range(planned) if i >= len(before) or lines[i] != before[i]), None)
        if changed is not None:
            raise DatasetError(f"{layout.root}: scene {split}-{changed:06d} would now be planned differently (the "
                               f"corpus, its clip checks or the RIR bank changed since the plan); growing would mix "
                               f"two corpora: generate the larger dataset into a new --out")
        plans[split] = lines
    stale = [layout.dataset_file]
    size = cfg.output.shard_size
    for split, (planned, _) in grown.items():
        if planned % size:  # a partial last shard: rendered again with the new scenes
            stale += reversed(layout.shard_files(split, planned // size))  # HDF5 first: then it is incomplete
    for path in stale:
        try:
            os.remove(path)
        except FileNotFoundError:
            pass
        except OSError as e:
            raise write_error(os.path.relpath(path, layout.root), e, layout.root) from None
    _write_plan(cfg, layout, catalog, plans)
    return {split: len(lines) for split, lines in plans.items()}


def load_plan(out_dir: str) -> tuple[Config, dict[str, list[SceneRecipe]]]:
    """The stored config and every split's recipes.

    Returns
    -------
    (Config, dict)
        The config ``plan/config.json`` holds, and {split: [SceneRecipe]} in plan order.
    """
    layout = Layout(out_dir)
    cfg = parse_config(read_plan_doc(layout)["config"], where=layout.config_file)
    plans = {s: read_split_plan(layout, s) for s in cfg.splits}
    for s, recipes in plans.items():
        if len(recipes) != cfg.splits[s].count:
            # plan files are written before plan/config.json: a grow interrupted in between
            raise DatasetError(f"{layout.plan_file(s)} holds {len(recipes)} scenes but {layout.config_file} asks "
                               f"{cfg.splits[s].count}; the plan was interrupted: run the same `tsel generate "
                               f"... --grow` again")
    return cfg, plans


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
             executor: str = "local", scheduler: str | None = None, grow: bool = False, report=None) -> dict:
    """Plan, render and finalize a dataset (the three stages above, in one call).

    Parameters are those of :func:`plan_dataset` and :func:`render_shards`.

    Returns
    -------
    dict
        ``out``, ``splits`` ({split: scenes}), ``rendered_now`` ({split: scenes rendered by
        this call}), ``bad_clips`` (count), ``missing_clips`` (clips whose audio file is
        absent), ``plan_seconds``, ``render_seconds``, ``bytes`` (on disk).
    """
    t0 = time.perf_counter()
    # clip-check bars only on a terminal: a log file would get thousands of bar updates
    plan_dataset(cfg, out_dir, workers=workers, resume=resume, grow=grow, progress=None if progress else False,
                 report=report)
    t1 = time.perf_counter()
    rendered = render_shards(out_dir, workers=workers, progress=progress, executor=executor, scheduler=scheduler)
    t2 = time.perf_counter()
    doc = finalize(out_dir)
    layout = Layout(out_dir)
    plan = read_plan_doc(layout)
    return {"out": out_dir, "splits": {s: v["scenes"] for s, v in doc["splits"].items()},
            "rendered_now": rendered, "bad_clips": plan.get("bad_clips", 0),
            "missing_clips": sum((plan.get("missing_clips") or {}).values()), "plan_seconds": t1 - t0,
            "render_seconds": t2 - t1, "bytes": _dir_size(out_dir)}


def _dir_size(d: str) -> int:
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(d) for f in fs)
