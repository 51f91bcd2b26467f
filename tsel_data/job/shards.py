"""Reading a plan back, rendering its shards, finalizing the dataset.

The second and third stages of :mod:`tsel_data.job.pipeline`. :func:`open_plan` reads a
folder's plan once into a :class:`Plan` that goes from stage to stage;
:func:`render_shards` renders its shards (all, or a job-array task's range, reading only
their recipes), skipping those whose seal verifies; :func:`finalize` checks every shard
against the plan and writes ``dataset.json`` last. Both refuse a plan edited since it was
planned (the seal in ``plan/config.json``).
"""
from __future__ import annotations

import os
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

from tqdm import tqdm

from ..config import Config, parse_config
from ..config.receiver import array_poses
from ..core.atomic import write_json
from ..errors import AudioError, BankError, DatasetError
from ..render.scenes import render_recipe
from ..runtime.runner import Runner
from ..scene.recipe import Roots, SceneRecipe, plan_roots, recipe_from_line
from ..store.dataset import ShardEntry, dataset_doc, shard_attrs
from ..store.integrity import input_stats, missing_inputs, read_seal, shard_fingerprint, shard_state
from ..store.layout import Layout
from ..store.lock import DatasetLock
from ..store.plans import (ShardTask, local_roots, portable_roots, read_plan_doc, read_plan_range, seal_problem,
                           shard_tasks)
from ..store.reader import shard_scene_ids
from ..store.writer import ShardWriter


@dataclass
class Plan:
    """A dataset's plan, opened once (:func:`open_plan`) and handed from stage to stage:
    the folder, the config ``plan/config.json`` holds (roots as paths here), where the
    inputs are, every shard of the plan, the shard attributes, and the stored plan
    document. Recipes are read when asked for (:meth:`recipes`), once per split range."""

    layout: Layout
    cfg: Config
    roots: Roots
    tasks: list[ShardTask]
    attrs: dict
    doc: dict
    _parts: dict[str, "PlanPart"] = field(default_factory=dict, repr=False)
    _hashed: set = field(default_factory=set, repr=False)  # splits whose plan file matched its seal by sha256

    @property
    def out_dir(self) -> str:
        return self.layout.root

    def recipes(self, tasks: list[ShardTask]) -> list[list[SceneRecipe]]:
        """Each task's recipes, read from the plan files the first time a range is asked for."""
        splits = {t.split for t in tasks if not self._has(t)}
        if splits:  # the asked tasks of those splits, read as one range each
            for split, part in load_plan_part(self.layout, self.cfg, [t for t in tasks if t.split in splits]).items():
                if part.recipes:
                    self._parts[split] = part
        return [self._parts[t.split][t.start:t.stop] for t in tasks]

    def _has(self, t: ShardTask) -> bool:
        part = self._parts.get(t.split)
        return part is not None and part.offset <= t.start and t.stop <= part.offset + len(part.recipes)


def open_plan(out_dir: str, corpus_dir: str | None = None, bank: str | None = None) -> Plan:
    """Open a dataset folder's plan (``plan/config.json`` read and parsed once).

    Parameters
    ----------
    out_dir : str
    corpus_dir, bank : str, optional
        Where the corpus and the RIR bank are now, when not where the plan says (a
        dataset or its inputs moved; a job array on another machine).

    Raises
    ------
    DatasetError
        No plan, a damaged one, or a config edited since it was planned (its seal).
    """
    layout = Layout(os.path.abspath(out_dir))  # dask workers may run elsewhere on a shared filesystem
    doc = read_plan_doc(layout)
    problem = seal_problem(layout, doc, splits=())
    if problem:
        raise DatasetError(f"{problem}; plan again into a new --out")
    raw = local_roots(doc["config"], layout.root)
    if corpus_dir:
        raw["corpus"] = {**raw.get("corpus", {}), "dir": os.path.abspath(os.path.expanduser(corpus_dir))}
    if bank:
        raw["room"] = {**raw.get("room", {}), "bank": os.path.abspath(os.path.expanduser(bank))}
    cfg = parse_config(raw, where=layout.config_file, stored=True)
    return Plan(layout, cfg, plan_roots(cfg, layout), plan_shard_tasks(cfg), dataset_attrs(cfg), doc)


def _opened(plan: Plan | str, corpus_dir: str | None, bank: str | None) -> Plan:
    if isinstance(plan, Plan):
        return plan
    return open_plan(plan, corpus_dir, bank)


def _check_count(layout: Layout, cfg: Config, split: str, have: int) -> None:
    """Plan files are written before plan/config.json: a grow interrupted in between leaves
    them with another count than the config's."""
    if have != cfg.splits[split].count:
        raise DatasetError(f"{layout.plan_file(split)} holds {have} scenes but {layout.config_file} asks "
                           f"{cfg.splits[split].count}; the plan was interrupted: run the same `tsel generate ... "
                           f"--grow` again")


def _check_seal(plan: Plan, splits, deep: bool) -> None:
    """Refuse plan files edited since they were planned: their recipes would be rendered
    under the seal of the plan that was checked. A split hashed once for this plan (the
    render stage of ``generate``) is not hashed again (its finalize)."""
    splits = [s for s in splits if s not in plan._hashed]
    problem = seal_problem(plan.layout, plan.doc, splits=splits, deep=deep)
    if problem:
        raise DatasetError(f"{problem}; run the same `tsel generate ... --grow` again if one stopped, else plan "
                           f"again into a new --out or put the plan back as it was")
    if deep:
        plan._hashed.update(splits)


def plan_shard_tasks(cfg: Config) -> list[ShardTask]:
    """Every shard of a plan (the scene counts are the config's)."""
    return shard_tasks({s: sp.count for s, sp in cfg.splits.items()}, cfg.output.shard_size)


class PlanPart:
    """The recipes of scenes ``offset`` .. ``offset + len(recipes) - 1`` of a split;
    sliced with the split's own scene indices."""

    def __init__(self, offset: int = 0, recipes: list | None = None):
        self.offset, self.recipes = offset, recipes or []

    def __getitem__(self, s: slice) -> list[SceneRecipe]:
        return self.recipes[s.start - self.offset:s.stop - self.offset]


def load_plan_part(layout: Layout, cfg: Config, tasks: list[ShardTask]) -> dict[str, PlanPart]:
    """{split: PlanPart} holding the recipes of ``tasks`` only (every split of the plan is
    a key): what a job-array task reads of a large plan."""
    parts = {}
    for split in cfg.splits:
        mine = [t for t in tasks if t.split == split]
        if not mine:
            parts[split] = PlanPart()
            continue
        start, stop = min(t.start for t in mine), max(t.stop for t in mine)
        lines = read_plan_range(layout, split, start, stop)
        if len(lines) != stop - start:  # the file ends early: it holds start + len(lines) scenes
            _check_count(layout, cfg, split, start + len(lines))
        path = layout.plan_file(split)
        parts[split] = PlanPart(start, [recipe_from_line(path, start + k + 1, line) for k, line in enumerate(lines)])
    return parts


def inputs_here(out_dir: str, shard_recipes: list, roots: Roots, verb: str, content: bool = False) -> list[list]:
    """:func:`~tsel_data.store.integrity.input_stats` of each shard's inputs (read once,
    for its fingerprint; ``content``: hashed, each file once). Refuses, in one line and
    before any shard is touched, when files
    are not where the roots say: a moved or unmounted corpus or bank is not a changed one,
    and taking it for one would render every finished shard again (or strip their seals)."""
    hashes: dict = {}
    stats = [input_stats(roots.inputs(recipes), content, hashes) for recipes in shard_recipes]
    missing = sorted({name for st in stats for name in missing_inputs(st)})
    if not missing:
        return stats
    kind = {name: root for recipes in shard_recipes for r in recipes for root, name in r.input_files()}
    if kind.get(missing[0]) == "bank":
        where, flag = f"the RIR bank is not at {roots.bank_file(missing[0])}", "--bank"
    elif kind.get(missing[0]) == "hrtf":
        where, flag = f"the HRTF is not at {roots.hrtf_file(missing[0])}", "--set array.hrtf=PATH"
    else:
        where = f"{len(missing)} clip(s) are not in the corpus at {roots.corpus}, e.g. {missing[0]}"
        flag = "--corpus-dir"
    raise DatasetError(f"{where}; if it moved, pass {flag} with where it is now (to `tsel {verb}` or `tsel generate "
                       f"... --resume`); nothing was changed")


def expected_fingerprint(recipes: list[SceneRecipe], roots: Roots, stats: list | None = None,
                         content: bool = False) -> str:
    """The fingerprint a shard of these recipes must carry, with its inputs (clips, RIR
    bank) as they are now (``stats``, when :func:`inputs_here` has read them already;
    ``content``: ``corpus.fingerprint = "hash"``)."""
    if stats is None:
        stats = input_stats(roots.inputs(recipes), content)
    return shard_fingerprint([r.to_json() for r in recipes], stats)


def render_shard(out_dir: str, task: ShardTask, recipes: list[SceneRecipe], attrs: dict, roots: Roots,
                 content: bool = False) -> int:
    """Render one shard's recipes and write the shard, sealed with what it was made from
    (``content``: its inputs hashed); returns its scene count."""
    # before reading anything: a clip changed meanwhile is stale
    fingerprint = expected_fingerprint(recipes, roots, content=content)
    with ShardWriter(out_dir, task.split, task.shard, len(recipes), attrs, fingerprint) as w:
        for r in recipes:  # one scene's audio in memory at a time
            w.add(render_recipe(r, roots))
    return len(recipes)


def _render_task(args) -> tuple[ShardTask, int, str]:
    """One shard; a bad input met only now (a clip or an RIR the checks let through) is
    reported, not raised, so the other shards go on."""
    out_dir, task, recipes, attrs, roots, content = args
    try:
        return task, render_shard(out_dir, task, recipes, attrs, roots, content), ""
    except (AudioError, BankError) as e:  # clips named as the plan names them, relative to the corpus
        return task, 0, str(e).replace(os.path.join(roots.corpus, ""), "") if roots.corpus else str(e)


def render_shards(plan: Plan | str, shards: range | None = None, workers: int = 1, progress: bool = True,
                  executor: str = "local", scheduler: str | None = None, corpus_dir: str | None = None,
                  bank: str | None = None) -> dict:
    """Render the plan's shards; complete shards are skipped.

    A shard counts as complete only when its seal matches the plan and its files
    (store/integrity.py): shards of another plan, made from clips that changed since, or
    damaged, are rendered again (and said so on stderr).

    Parameters
    ----------
    plan : Plan or str
        An opened plan (:func:`open_plan`), or a planned dataset folder.
    shards : range, optional
        Indices into the plan's global shard list (split by split, in order); all if None.
    workers : int
        Processes (or Dask workers for ``dask-local``).
    progress : bool
        A progress bar per split.
    executor : str
        ``local`` | ``dask`` | ``dask-local`` (runtime/runner.py).
    scheduler : str, optional
        The Dask scheduler's address for ``dask``.
    corpus_dir, bank : str, optional
        Where the corpus and the bank are, when not where the plan says (:func:`open_plan`;
        only with a folder).

    Returns
    -------
    dict
        {split: scenes rendered now}.

    Raises
    ------
    DatasetError
        Shards that could not be rendered (bad clips or RIRs found only now: the first is
        named; the others were rendered), a plan edited since it was planned, too little
        disk for the shards to render, or another process is planning the folder.
    """
    plan = _opened(plan, corpus_dir, bank)  # a plan is written last by its planner: complete, or absent
    layout = plan.layout
    with DatasetLock(layout, exclusive=False, what="render it"):
        tasks = plan.tasks
        if shards is not None:
            if shards.stop > len(tasks):
                raise DatasetError(f"shard range {shards.start}-{shards.stop - 1} is outside the plan's "
                                   f"{len(tasks)} shards (0-{len(tasks) - 1})")
            tasks = [tasks[i] for i in shards]
        # a job-array task reads a few lines of a large plan: it checks sizes, the whole job hashes
        _check_seal(plan, sorted({t.split for t in tasks}), deep=shards is None)
        recipes = plan.recipes(tasks)  # only the recipes of these shards
        todo, redo = [], []
        content = plan.cfg.corpus.fingerprint == "hash"
        for t, rs, stats in zip(tasks, recipes, inputs_here(plan.out_dir, recipes, plan.roots, "render", content)):
            state, why = shard_state(layout, t.split, t.shard, expected_fingerprint(rs, plan.roots, stats))
            if state != "complete":
                todo.append((t, rs))
                if state in ("stale", "damaged"):
                    redo.append(f"{t.files[0]} ({why})")
        if redo:
            print(f"rendering {len(redo)} shard(s) again that do not verify, e.g. {redo[0]}", file=sys.stderr)
        return _render_todo(plan, tasks, todo, workers, progress, executor, scheduler)


def _render_todo(plan: Plan, tasks, todo, workers, progress, executor, scheduler) -> dict:
    done: dict[str, int] = {s: 0 for s in plan.cfg.splits}
    failed: list[str] = []
    with Runner(executor, workers if len(todo) > 1 else 1, scheduler) as runner:
        # split by split, so each split gets its own progress bar and rate
        for split in plan.cfg.splits:
            jobs = [(plan.out_dir, t, rs, plan.attrs, plan.roots, plan.cfg.corpus.fingerprint == "hash")
                    for t, rs in todo if t.split == split]
            total = sum(t.stop - t.start for t in tasks if t.split == split)
            if not total:
                continue
            # closed however the loop ends: a stopped run leaves its bar where it was, drawn once
            with _bar(split, total, total - sum(j[1].stop - j[1].start for j in jobs), progress) as bar:
                for t, n, problem in runner.map_unordered(_render_task, jobs):
                    done[t.split] += n
                    bar.update(n)
                    if problem:
                        failed.append(f"{t.files[0]}: {problem}")
    if failed:
        raise DatasetError(f"{len(failed)} shard(s) could not be rendered (the others were), e.g. {failed[0]}; fix the "
                           f"input and rerun with --resume (shards that read a changed clip are rendered again)")
    return done


def _bar(split: str, total: int, initial: int, progress: bool):
    return tqdm(total=total, initial=initial, desc=f"{split:>5}", unit="scene", disable=not progress,
                dynamic_ncols=True, mininterval=1.0)


# --- finalize ----------------------------------------------------------------------------------


def finalize(plan: Plan | str, corpus_dir: str | None = None, bank: str | None = None) -> dict:
    """Check every shard against the plan and write ``dataset.json`` (atomically, last).

    ``plan``: an opened plan (:func:`open_plan`) or a planned dataset folder;
    ``corpus_dir``, ``bank``: where the inputs are, when not where the plan says.

    Returns
    -------
    dict
        The ``dataset.json`` document (it carries the plan's seal, so ``tsel check``
        notices a plan or config edited afterwards).

    Raises
    ------
    DatasetError
        A shard is missing, does not verify (another plan, changed inputs, damaged
        files), or holds other scenes than the plan puts there; the plan was edited.
    """
    plan = _opened(plan, corpus_dir, bank)
    layout, out_dir = plan.layout, plan.out_dir
    _check_seal(plan, list(plan.cfg.splits), deep=True)
    shard_recipes = plan.recipes(plan.tasks)
    for split, sp in plan.cfg.splits.items():  # a plan file longer than the config's count
        if read_plan_range(layout, split, sp.count, sp.count + 1):
            _check_count(layout, plan.cfg, split, sp.count + 1)
    stats = inputs_here(out_dir, shard_recipes, plan.roots, "finalize", plan.cfg.corpus.fingerprint == "hash")
    with DatasetLock(layout, exclusive=True, what="finalize it"):
        entries: dict[str, list] = {split: [] for split in plan.cfg.splits}  # config order
        missing, bad = [], []
        prints = [expected_fingerprint(recipes, plan.roots, st) for recipes, st in zip(shard_recipes, stats)]
        states = shard_states(layout, plan.tasks, prints)
        for task, recipes, (state, why) in zip(plan.tasks, shard_recipes, states):
            if state == "missing":
                missing.append(task.files[0])
                continue
            if state != "complete":
                bad.append(f"{task.files[0]}: {why}")
                continue
            want = [r.scene_id for r in recipes]
            if shard_scene_ids(layout.path(task.files[0])) != want:  # a sealed shard of this plan holds its
                # scenes; this guards the seal itself
                bad.append(f"{task.files[0]}: holds scenes other than the planned {want[0]}..{want[-1]}")
                continue
            seal = read_seal(layout, task.split, task.shard)
            entries[task.split].append(ShardEntry(*task.files, len(want), seal.h5.sha256, seal.json.sha256))
        if bad:
            raise DatasetError(f"{len(bad)} shard(s) do not verify, e.g. {bad[0]}; run `tsel render {out_dir}` (or "
                               f"`tsel generate ... --resume`) to render them again")
        if missing:
            raise DatasetError(f"{len(missing)} shard(s) not rendered yet, e.g. {missing[0]}; "
                               f"run `tsel render {out_dir}` (or `tsel generate ... --resume`) first")
        doc = dataset_doc(portable_roots(plan.cfg.to_dict(), out_dir), plan.cfg.seed, plan.attrs, entries)
        if "seal" in plan.doc:
            doc["plan_seal"] = plan.doc["seal"]
        if "recorded" in plan.doc:  # what the windows held: kept, skipped and why (docs/recorded.md)
            doc["recorded"] = plan.doc["recorded"]
        write_json(layout.dataset_file, doc)
        return doc


def shard_states(layout: Layout, tasks: list[ShardTask], prints: list[str]) -> list[tuple[str, str]]:
    """:func:`~tsel_data.store.integrity.shard_state` of every shard: a shard whose files
    keep the size and modification time of its seal is taken as sealed (its writer hashed
    it as it sealed it), so only changed files are hashed, on threads (hashlib and file
    reads release the GIL): a finalize of 1,000 hours of shards is no serial re-hash."""
    def one(job):
        task, fingerprint = job
        return shard_state(layout, task.split, task.shard, fingerprint)

    if len(tasks) < 2:
        return [one(j) for j in zip(tasks, prints)]
    with ThreadPoolExecutor(max_workers=min(len(tasks), os.cpu_count() or 1)) as pool:
        return list(pool.map(one, zip(tasks, prints)))


def dataset_attrs(cfg: Config) -> dict:
    """The shard attributes of ``cfg``'s datasets (store.dataset.shard_attrs)."""
    poses = array_poses(cfg, side=0.1)
    return shard_attrs(cfg.audio.fs, cfg.audio.label_hop, cfg.scene.format, cfg.output.audio,
                       poses[0].channel_names(), {p.format: list(p.channel_names()) for p in poses[1:]})
