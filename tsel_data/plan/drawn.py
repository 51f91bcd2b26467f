"""Clips checked in full where a plan draws them (``corpus.check = "drawn"``, the default).

Decoding every clip of a manifest before planning (``full``) costs what rendering a
small dataset costs, and more: 51,308 AudioCaps clips for a dataset that draws a few
thousand. Here every clip's header is checked before planning (the catalog:
plan/catalog.py), the splits are planned, and only the clips the plans draw (targets,
interferers, noise clips) are decoded and checked (:func:`~tsel_data.corpus.audio.check_clip`,
verdicts remembered as a full check's). A bad one is excluded from the split's draws
(:meth:`~tsel_data.plan.sampler.CatalogView.exclude`: a draw that lands on it is drawn
again) and the scenes that drew it are planned again, until every clip the plans draw
is good.

The dataset does not depend on which clips were checked first, nor on what the clip
check remembers: a draw that never lands on a bad clip is the draw without exclusions,
so the plan is the one with every bad clip of the corpus excluded, found or not. When
every clip is good it is the plan of a ``full`` check, bit for bit. A bad clip a plan
draws is handled as before: listed in ``bad_clips.jsonl`` and never used
(``on_bad_clip = "skip"``), or the run stops before rendering (``"fail"``).

Prepared clips (corpus/prepared.py) are made from the same decode for the clips the
plans use at least twice (``corpus.prepare_on_check``): making one costs more than
decoding the clip once more at render time, less than twice
(``benchmarks/bench_prepared.py``).
"""
from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field

from ..config import Config
from ..core.progress import bar
from .catalog import BadClip, CatalogScan, check_clips
from .sampler import CatalogView, plan_scene, plan_split_json

PREPARE_USES = 2  # a clip is prepared from its check's decode when the plans use it this often


@dataclass
class DrawnChecks:
    """What checking the drawn clips found: ``bad`` (every bad clip the plans drew, in the
    order found), ``checked`` (clips decoded or remembered), ``prepared`` (clips kept
    prepared), ``rounds`` (plans made: 1 when no drawn clip was bad)."""

    bad: list[BadClip] = field(default_factory=list)
    checked: int = 0
    prepared: int = 0
    rounds: int = 1

    def line(self) -> str:
        """One line for the user."""
        bad = f", {len(self.bad):,} bad" if self.bad else ""
        kept = f", {self.prepared:,} kept prepared (used twice or more)" if self.prepared else ""
        return f"checked in full: the {self.checked:,} clips the plan draws{bad}{kept}"


def plan_drawn(cfg: Config, views: dict[str, CatalogView], workers: int = 1, progress: bool | None = None,
               prepare: bool = True, stop_at_bad: bool = False) -> tuple[dict[str, list[str]], DrawnChecks]:
    """Plan every split of ``views`` and check in full the clips the plans draw; plan the
    scenes that drew a bad clip again, until none does (the module docstring).

    Parameters
    ----------
    cfg : Config
    views : dict
        {split: CatalogView} of the splits that make scenes (their clips header-checked);
        the bad clips found are excluded from them.
    workers : int
        Processes for planning and decoding.
    progress : bool or None
        Bars while scenes are planned and clips checked (None: on a terminal).
    prepare : bool
        Write prepared forms (with ``corpus.prepare_on_check``) for clips used twice or more.
    stop_at_bad : bool
        Return at the first round that finds bad clips (``on_bad_clip = "fail"``: the run
        stops before rendering anyway).

    Returns
    -------
    (plans, DrawnChecks)
        {split: recipe JSON lines} for every split of ``cfg`` (empty for splits without
        scenes), and what the checks found.
    """
    plans = {split: plan_split_json(cfg, split, views[split], workers, progress=progress)
             if split in views and sp.count else [] for split, sp in cfg.splits.items()}
    found = DrawnChecks()
    verdicts: dict[tuple, bool] = {}  # (split, clip index) -> good
    while True:
        drawn = {split: _drawn_clips(plans[split], views[split]) for split in views}
        uses = Counter((split, i) for split in drawn for scene in drawn[split] for i in scene)
        todo = sorted({key for key in uses if key not in verdicts})
        new_bad = _check(cfg, views, todo, uses, workers, progress, prepare and cfg.corpus.prepare_on_check,
                         verdicts, found)
        if not new_bad or stop_at_bad:
            break
        found.rounds += 1
        for split in views:
            mine = {i for s, i in new_bad if s == split}
            if not mine:
                continue
            views[split].exclude(mine)
            for index, scene in enumerate(drawn[split]):
                if mine.intersection(scene):
                    plans[split][index] = plan_scene(cfg, split, index, views[split]).to_json()
    found.checked = len(verdicts)
    return plans, found


def _check(cfg: Config, views, todo: list[tuple], uses: Counter, workers: int, progress, prepare: bool,
           verdicts: dict, found: DrawnChecks) -> list[tuple]:
    """Check ``todo`` ((split, clip index) pairs) in full; record verdicts and bad clips;
    returns the bad pairs."""
    clips = [views[split].clips[i] for split, i in todo]
    wanted = [prepare and uses[key] >= PREPARE_USES for key in todo]
    with bar(None, "check drawn clips", "clip", progress if todo else False) as b:
        checks = check_clips(clips, cfg, workers, progress=False, level="full", prepare=wanted)
        b.update(len(checks))
    bad = []
    for key, clip, chk in zip(todo, clips, checks):
        problem = chk.problem or chk.prepared  # a prepared form render would refuse stops it as a bad clip would
        verdicts[key] = problem is None
        found.prepared += int(chk.kept)
        if problem is not None:
            found.bad.append(BadClip(key[0], clip.id, clip.origin, problem))
            bad.append(key)
    return bad


def _drawn_clips(lines: list[str], view: CatalogView) -> list[set[int]]:
    """Per recipe, the indices (into ``view.clips``) of the clips it reads: its sources'
    clips and its noises' (babble, diffuse from a clip)."""
    by_id = view.__dict__.get("_by_id")
    if by_id is None:
        by_id = view._by_id = {c.id: i for i, c in enumerate(view.clips)}
        view._by_file = {}
        for i, c in enumerate(view.clips):
            view._by_file.setdefault((view.roots.relative_clip(c.audio), float(c.offset)), []).append(i)
    out = []
    for line in lines:
        rec = json.loads(line)
        used = {by_id[s["clip_id"]] for s in rec["sources"] if s.get("clip_id") in by_id}
        for item in rec.get("noise") or ():
            for path, offset in item.get("clips") or ():
                used.update(view._by_file.get((path, float(offset)), ()))
        out.append(used)
    return out


def exclude_every_bad_clip(cfg: Config, view: CatalogView, workers: int = 1) -> int:
    """Check every clip of ``view`` in full and exclude the bad ones (returns how many):
    scenes drawn on demand (job/onthefly.py) are then the scenes a ``drawn`` plan reaches
    (the plan with every bad clip excluded), whichever scenes are asked for."""
    checks = check_clips(view.clips, cfg, workers, progress=False, level="full", prepare=[False] * len(view.clips))
    bad = [i for i, chk in enumerate(checks) if (chk.problem or chk.prepared) is not None]
    view.exclude(bad)
    return len(bad)


def scan_with_drawn(scan: CatalogScan, found: DrawnChecks) -> None:
    """Add what the drawn checks found to the catalog scan: its bad clips and per split counts."""
    scan.bad.extend(found.bad)
    for b in found.bad:
        scan.counts[b.split]["bad"] = scan.counts[b.split].get("bad", 0) + 1
