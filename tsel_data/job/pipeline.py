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

The plan stage and the whole job live here; reading a plan back, rendering its shards and
finalizing, in :mod:`tsel_data.job.shards` (re-exported: ``tsel_data.job.pipeline.render_shards``).
Where each file goes is :class:`~tsel_data.store.layout.Layout`'s business.
"""
from __future__ import annotations

import os
import shutil
import time

from ..config import Config, Difference, config_differences
from ..config.receiver import array_poses
from ..core.atomic import write_error, write_json, write_lines
from ..errors import ConfigError, DatasetError, TselError
from ..plan.catalog import prepared_line, reuse_stop, write_bad_clips, write_missing_clips
from ..plan.drawn import plan_drawn, scan_with_drawn
from ..plan.recorded import plan_recorded, recorded_corpus
from ..plan.sampler import plan_split_json, prepare_views
from ..scene.recipe import plan_roots
from ..store.layout import Layout
from ..store.lock import DatasetLock
from ..store.plans import ROOT_KEYS, has_plan, plan_doc, portable_roots, read_plan_doc, read_plan_lines, stored_config
from .shards import finalize, open_plan, render_shards


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


def plan_differences(layout: Layout, cfg: Config, roots: bool = False) -> list[Difference]:
    """The keys where ``cfg`` differs from the config ``layout``'s plan was made with
    (DatasetError when the stored config is unreadable). The roots (where the corpus and
    the bank are: :data:`~tsel_data.store.plans.ROOT_KEYS`) are not the plan's business:
    a dataset may move, and its inputs too; they are compared only with ``roots``."""
    stored = stored_config(layout)
    if stored is None:
        raise DatasetError(f"{layout.config_file} is damaged or holds no config; plan again into a new --out")
    diffs = config_differences(stored, cfg, where=layout.config_file)
    return [d for d in diffs if (d.key in ROOT_KEYS) == roots]


def _move_roots(layout: Layout, cfg: Config) -> None:
    """Store where ``cfg`` says the inputs are now, when that is a place that exists (a
    resume after the corpus or the bank moved). The plan's root stays when ``cfg`` gives
    none, a built-in default, or a place that is gone while the plan's still resolves (the
    dataset moved together with its inputs, resumed with the original command line)."""
    moved = []
    for d in plan_differences(layout, cfg, roots=True):
        new, old = str(d.after or ""), str(d.before or "")
        if not new or (new.startswith("builtin:") and not old.startswith("builtin:")):
            continue
        if os.path.exists(os.path.expanduser(new)) or new.startswith("builtin:"):
            moved.append(d)
        elif old.startswith("builtin:") or not os.path.exists(old):
            raise ConfigError(f"{d.key} {new} not found, and the plan's {old} is not there either; give where it is "
                              f"now")
    if not moved:
        return
    doc = read_plan_doc(layout)
    config = dict(doc["config"])
    given = portable_roots(cfg.to_dict(), layout.root)
    for d in moved:
        sec, name = d.key.split(".")
        config[sec] = {**config.get(sec, {}), name: given[sec][name]}
    write_json(layout.config_file, {**doc, "config": config})


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
        fix = ("a dataset does not shrink once shards are rendered: ask for at least the planned counts, or choose "
               "another --out")
    else:
        fix = (f"--resume needs the config the plan was made with ({layout.config_file}); use it, or choose "
               f"another --out" + (" (--grow changes only splits.NAME.count)" if grow else ""))
    return DatasetError(f"{out_dir} was planned with a different config: {shown}; {fix}")


def plan_dataset(cfg: Config, out_dir: str, workers: int = 1, resume: bool = False, grow: bool = False,
                 force: bool = False, progress: bool | None = None, report=None, allow_reuse: bool = False) -> dict:
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
        Bars while manifests are read, clips checked and scenes planned (None: on a terminal).
    report : callable, optional
        Called with one-line notes for the user: per split, how many of the listed
        clips are present; clips reused by many scenes.
    force : bool
        Write into a folder that holds files but no tsel-data dataset (files of the same
        names are replaced); without it such a folder is refused.
    allow_reuse : bool
        Plan even when a split would use each clip in more than ``corpus.max_reuse``
        scenes (:func:`~tsel_data.plan.catalog.reuse_stop`); without it that is refused.

    A plan whose shards are not rendered yet is planned again when only the split
    counts changed (smaller too: nothing is lost); once a shard is rendered, counts may
    only grow (``grow``).

    Returns
    -------
    dict
        {split: scenes planned}.

    Raises
    ------
    DatasetError
        ``out_dir`` holds a plan (without ``resume``/``grow``), a plan of another config
        (naming the keys that differ), files that are not a dataset (without ``force``),
        or another process is writing it.
    ConfigError
        A split would reuse its clips beyond ``corpus.max_reuse`` (without ``allow_reuse``).
    TselError
        Any problem of the corpus or the bank (the first; ``tsel check`` lists all).
    """
    layout = _claim(out_dir, force)
    with DatasetLock(layout, exclusive=True, what="plan it"):
        return _plan_locked(cfg, layout, workers, resume, grow, progress, report, allow_reuse)


# Disk per scene beyond the float32 audio: the HDF5 labels (3 float32 + 1 bool per source
# and frame = 13 bytes), and the JSON record (about 20 bytes per source and frame: three
# rounded numbers and a bool) plus about 2 kB of metadata.
LABEL_BYTES_PER_SOURCE_FRAME = 13 + 20
OVERHEAD_BYTES_PER_SCENE = 2000


def estimate_bytes(cfg: Config) -> int:
    """About how many bytes the dataset's shards take (the most sources a scene can have)."""
    a = cfg.audio
    n_scenes = sum(sp.count for sp in cfg.splits.values())
    frames = int(round(a.duration / a.label_hop))
    # a recorded window holds as many sources as were annotated: STARSS23 has up to 6 at once
    n_src = 8 if cfg.recorded.on else int((cfg.scene.interferers.bounds or (1, 1))[1]) + 1
    per_scene = (sum(p.n_channels for p in array_poses(cfg, side=0.1)) * int(round(a.duration * a.fs)) * 4
                 + n_src * frames * LABEL_BYTES_PER_SOURCE_FRAME + OVERHEAD_BYTES_PER_SCENE)
    return n_scenes * per_scene


def check_space(cfg: Config, layout: Layout) -> None:
    """Refuse, before any audio is written, a dataset whose shards still to render the
    disk cannot hold (shards written so far count as written). A plan alone needs little:
    the job-array flow plans on one machine and renders elsewhere, where each shard's
    writer checks the space it needs."""
    written = sum(os.path.getsize(os.path.join(d, n)) for d in map(layout.split_dir, cfg.splits)
                  if os.path.isdir(d) for n in os.listdir(d) if n.startswith("shard-"))
    need, free = max(0, estimate_bytes(cfg) - written), shutil.disk_usage(layout.root).free
    if need > free:
        raise DatasetError(f"the dataset needs about {need / 1e9:.2f} GB more but {layout.root} has "
                           f"{free / 1e9:.2f} GB free; free space, choose another --out, or make fewer scenes")


def _claim(out_dir: str, force: bool) -> Layout:
    """The dataset folder, created, once it is known to be ours (or ``force``)."""
    layout = Layout(out_dir)
    check_ownership(layout, force)
    try:
        os.makedirs(layout.plan_dir, exist_ok=True)
    except OSError as e:
        raise write_error(out_dir, e, out_dir) from None
    return layout


def check_ownership(layout: Layout, force: bool = False) -> None:
    """Refuse a folder that holds files but no tsel-data dataset, unless ``force``: we
    write only into our own datasets (or new or empty folders)."""
    root = layout.root
    if os.path.isfile(root):
        raise DatasetError(f"--out {root} is a file; choose a folder")
    if force or not os.path.isdir(root) or layout.is_ours() or not os.listdir(root):
        return
    shown = ", ".join(sorted(os.listdir(root))[:3])
    raise DatasetError(f"{root} already holds files that are not a tsel-data dataset ({shown}, ...); choose a new or "
                       f"empty --out, or pass --force to write into it anyway (files of the same names are replaced)")


def _plan_locked(cfg: Config, layout: Layout, workers: int, resume: bool, grow: bool, progress, report,
                 allow_reuse: bool = False) -> dict:
    out_dir = layout.root
    state = planned_with(layout, cfg)
    if state != "none":
        diffs = plan_differences(layout, cfg) if state == "different" else []
        # nothing rendered: new counts lose nothing (a --grow keeps its own path, which
        # also refuses a corpus that changed since)
        if diffs and _counts_only(diffs) and not (grow and growth(diffs)) and not _rendered_any(layout):
            _forget_plan(layout, diffs, report)
        elif not resume and not grow:
            if diffs:
                raise _refuse(out_dir, layout, diffs, grow)
            raise DatasetError(f"{out_dir} already holds a dataset plan; pass --resume to continue it "
                               f"or choose another --out")
        elif not diffs:
            _move_roots(layout, cfg)
            return {s: sp.count for s, sp in cfg.splits.items()}
        else:
            grown = growth(diffs) if grow else None
            if grown is None:
                raise _refuse(out_dir, layout, diffs, grow)
            if cfg.recorded.on:
                return _plan_recorded(cfg, layout, report, grown)
            return _grow(cfg, layout, grown, workers, progress, report, allow_reuse)
    if cfg.recorded.on:
        return _plan_recorded(cfg, layout, report)
    catalog, views = _catalog(cfg, layout, workers, progress, report, allow_reuse)
    plans = _plans(cfg, catalog, views, workers, progress, report)
    _write_plan(cfg, layout, catalog, plans)
    return {split: len(lines) for split, lines in plans.items()}


def _plans(cfg: Config, catalog, views, workers: int, progress, report) -> dict[str, list[str]]:
    """The recipe lines of every split in ``views`` (others: none); with ``corpus.check = "drawn"``, the clips they draw
    checked in full and the scenes that drew a bad one planned again (plan/drawn.py): the
    bad clips go to the catalog (``bad_clips.jsonl``), or stop the run under
    ``on_bad_clip = "fail"``."""
    if cfg.corpus.check != "drawn":
        return {split: plan_split_json(cfg, split, views[split], workers, progress=progress)
                if split in views and sp.count else [] for split, sp in cfg.splits.items()}
    fail = cfg.on_bad_clip == "fail"
    plans, found = plan_drawn(cfg, views, workers, progress, stop_at_bad=fail)
    scan_with_drawn(catalog, found)
    if fail and found.bad:
        first, more = found.bad[0].error(), len(found.bad) - 1
        raise type(first)(f"{first}" + (f" (and {more} more problem(s); run `tsel check` to list them)" if more else ""))
    if report:
        report(found.line())
        if found.prepared:
            report(prepared_line())
    return plans


def _catalog(cfg: Config, layout: Layout, workers: int, progress, report, allow_reuse: bool = False):
    """The checked catalog and planning views, with the notes the user should see first;
    a ConfigError when the counts would reuse the clips beyond ``corpus.max_reuse``."""
    catalog, views = prepare_views(cfg, layout, workers, progress)
    if report:
        for line in catalog.presence_lines() + [f"warning: {w}" for w in catalog.warnings]:
            report(line)
    stop = None if allow_reuse else reuse_stop(cfg, catalog)
    if stop:
        raise ConfigError(stop)
    return catalog, views


def _counts_only(diffs: list[Difference]) -> bool:
    return all(d.key.startswith("splits.") and d.key.endswith(".count") for d in diffs)


def _rendered_any(layout: Layout) -> bool:
    """Whether any file of any shard (or of one being written) is there: what a new plan
    would lose."""
    for split in _planned_splits(layout):
        d = layout.split_dir(split)
        if os.path.isdir(d) and any(n.startswith("shard-") for n in os.listdir(d)):
            return True
    return False


def _forget_plan(layout: Layout, diffs: list[Difference], report) -> None:
    """Remove a plan nothing was rendered from (plan/config.json first: without it there
    is no plan), so the new counts are planned afresh."""
    if report:
        report(f"planning {layout.root} again: nothing was rendered yet ("
               + "; ".join(str(d) for d in diffs[:4]) + ")")
    names = [layout.config_file] + [layout.plan_file(s) for s in sorted(_planned_splits(layout))]
    _remove(layout, names + [layout.bad_clips_file, layout.missing_clips_file])


def _remove(layout: Layout, paths: list[str]) -> None:
    """Remove files of the dataset in this order; one that is already gone is fine."""
    for path in paths:
        try:
            os.remove(path)
        except FileNotFoundError:
            pass
        except OSError as e:
            raise write_error(os.path.relpath(path, layout.root), e, layout.root) from None


def _planned_splits(layout: Layout) -> list[str]:
    return [n[:-len(".jsonl")] for n in os.listdir(layout.plan_dir) if n.endswith(".jsonl")]


def _write_plan(cfg: Config, layout: Layout, catalog, plans: dict[str, list[str]]) -> None:
    """bad_clips.jsonl, missing_clips.json (when files are missing), the plan files, and
    plan/config.json last: its presence means the plan is complete."""
    corpus = plan_roots(cfg, layout).corpus
    write_bad_clips(layout.bad_clips_file, catalog.bad, corpus)
    missing = {s: len(c) for s, c in catalog.missing.items() if c}
    if missing:
        write_missing_clips(layout.missing_clips_file, catalog, corpus)
    for split, lines in plans.items():
        write_lines(layout.plan_file(split), lines)
    doc = plan_doc(portable_roots(cfg.to_dict(), layout.root), {s: len(c) for s, c in catalog.clips.items()},
                   len(catalog.bad), missing, plans)
    write_json(layout.config_file, doc)


def _plan_recorded(cfg: Config, layout: Layout, report, grown: dict | None = None) -> dict:
    """Plan a recorded dataset (:mod:`tsel_data.plan.recorded`), or grow one: the scenes
    already planned must come out the same (else the recordings or their labels changed).
    The stored config counts the scenes planned (a count asks for at most so many); the
    counts asked and what was kept or skipped, and why, are the plan's ``recorded``."""
    plans, summary = plan_recorded(cfg, recorded_corpus(cfg, layout), report)
    for split in grown or ():
        before = read_plan_lines(layout, split)
        if plans.get(split, [])[:len(before)] != before:
            raise DatasetError(f"{layout.root}: the scenes of {split} would now be planned differently (the "
                               f"recordings or their labels changed since the plan); growing would mix two: generate "
                               f"the larger dataset into a new --out")
    if grown:
        _remove(layout, [layout.dataset_file])
        for split, (planned, _) in grown.items():
            if planned % cfg.output.shard_size:
                last = planned // cfg.output.shard_size
                _remove(layout, [*reversed(layout.shard_files(split, last)), layout.seal_file(split, last)])
    plans = {split: plans.get(split, []) for split in cfg.splits}
    config = cfg.to_dict()
    for split, lines in plans.items():
        config["splits"][split]["count"] = len(lines)
    for split, lines in plans.items():
        write_lines(layout.plan_file(split), lines)
    doc = plan_doc(portable_roots(config, layout.root), {}, 0, None, plans)
    doc["recorded"] = summary
    write_json(layout.config_file, doc)
    return {split: len(lines) for split, lines in plans.items()}


def _grow(cfg: Config, layout: Layout, grown: dict[str, tuple[int, int]], workers: int, progress, report,
          allow_reuse: bool = False) -> dict:
    """Add scenes to a planned (perhaps finished) dataset: plan every split again with
    the same catalog, require the planned scenes to come out the same (else the corpus or
    bank changed and the grown dataset would mix two), mark the dataset unfinished
    (dataset.json removed), remove each grown split's last shard if it was partial (it
    is rendered again, fuller), then write the longer plan."""
    catalog, views = _catalog(cfg, layout, workers, progress, report, allow_reuse)
    fresh = _plans(cfg, catalog, {s: v for s, v in views.items() if s in grown}, workers, progress, report)
    plans = {}
    for split, sp in cfg.splits.items():
        before = read_plan_lines(layout, split)
        if split not in grown:
            plans[split] = before
            continue
        planned = grown[split][0]
        lines = fresh[split]
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
            last = planned // size
            # HDF5 first (then it is incomplete), its seal last (else render calls it one of another plan)
            stale += [*reversed(layout.shard_files(split, last)), layout.seal_file(split, last)]
            if report and os.path.exists(layout.shard_files(split, last)[0]):
                report(f"{split}: rendering {os.path.basename(layout.shard_files(split, last)[0])} again, the "
                       f"last shard: it held {planned % size} of {size} scenes, and --grow fills it")
    _remove(layout, stale)
    _write_plan(cfg, layout, catalog, plans)
    return {split: len(lines) for split, lines in plans.items()}


def generate(cfg: Config, out_dir: str, workers: int = 1, resume: bool = False, progress: bool = True,
             executor: str = "local", scheduler: str | None = None, grow: bool = False, force: bool = False,
             report=None, allow_reuse: bool = False) -> dict:
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
    layout = _claim(out_dir, force)
    # one lock from planning to finalizing: a second run cannot slip in between the stages
    with DatasetLock(layout, exclusive=True, what="generate it"):
        # clip-check bars only on a terminal: a log file would get thousands of bar updates
        _plan_locked(cfg, layout, workers, resume, grow, None if progress else False, report, allow_reuse)
        plan = open_plan(out_dir)  # as stored: the stages render what the plan files say
        check_space(plan.cfg, layout)  # after planning: what is wrong with the inputs is said first
        t1 = time.perf_counter()
        rendered = render_shards(plan, workers=workers, progress=progress, executor=executor, scheduler=scheduler)
        t2 = time.perf_counter()
        doc = finalize(plan)
    return {"out": out_dir, "splits": {s: v["scenes"] for s, v in doc["splits"].items()},
            "rendered_now": rendered, "bad_clips": plan.doc.get("bad_clips", 0),
            "missing_clips": sum((plan.doc.get("missing_clips") or {}).values()), "plan_seconds": t1 - t0,
            "render_seconds": t2 - t1, "bytes": _dir_size(out_dir)}


def _dir_size(d: str) -> int:
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(d) for f in fs)
