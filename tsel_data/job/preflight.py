"""``tsel check CONFIG``: every check a dataset job can fail on, before any rendering.

The config's fields and geometry (in the largest *and* the smallest room the ranges
allow), the RIR bank (when ``room.bank`` is set), the output folder, every manifest,
every clip (``corpus.check`` level, ``on_bad_clip`` policy; at ``full``, each clip's
prepared form too: its record, its bytes and its samples), duplicate clip ids, and
finally the whole plan sampled in memory (planning is cheap: ~0.2 ms per scene), so a
scene that cannot be placed is found here and not after hours of rendering.

Each check is the one the job itself runs (config rules, :func:`~tsel_data.plan.catalog.scan_catalog`,
:mod:`tsel_data.banks.scenes`, the planner), in its collecting form: the report lists
every problem at once. Nothing is written, except a demo corpus or bank synthesised
into a scratch folder.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import replace

from ..banks.scenes import bank_problems
from ..choices import CheckLevel
from ..config import Config, config_problems, geometry_problems, rooms_without_bank
from ..config.receiver import array_poses, hrtf_problem
from ..core.report import CheckReport
from ..errors import DatasetError, TselError
from ..plan.catalog import BUILTIN_DEMO, resolve_corpus_dir, reuse_stop, scan_catalog
from ..plan.drawn import plan_drawn
from ..plan.recorded import plan_recorded, recorded_corpus
from ..plan.sampler import ambience_problems, bank_request, catalog_views, plan_split_json
from ..store.layout import Layout
from .pipeline import check_ownership, estimate_bytes, plan_differences, planned_with

def check_config(cfg: Config, out_dir: str | None = None, workers: int = 1, plan: bool = True) -> CheckReport:
    """Validate a config and everything it reads, before any rendering.

    Parameters
    ----------
    cfg : Config
        Loaded with ``load_config(..., validate=False)``, so every problem is reported here.
    out_dir : str, optional
        The output folder a run would use (checked for writability, an existing plan,
        free space).
    workers : int
        Processes for clip checks and planning.
    plan : bool
        Also sample every scene in memory. Without it, ``corpus.check = "drawn"`` checks
        every clip in full: no plan says which it draws.

    Returns
    -------
    CheckReport
        Every problem (``errors``), what deserves a look (``warnings``), bad clips, facts.
    """
    rep = CheckReport(f"config {cfg.name}")
    for e in config_problems(cfg, geometry=False):
        rep.error(e)
    if rep.errors:
        return rep  # later checks assume sane fields
    if cfg.recorded.on:
        return _check_recorded(cfg, out_dir, rep, plan)
    for e in geometry_problems(cfg):
        rep.error(e)
    rep.facts["receivers"] = [{"name": p.format, "channels": p.n_channels} for p in array_poses(cfg, side=0.1)]
    for problem in (rooms_without_bank(cfg), hrtf_problem(cfg)):
        if problem:
            rep.error(problem)
    for e in bank_problems(bank_request(cfg)):
        rep.error(e)
    for e in ambience_problems(cfg):
        rep.error(e)
    if out_dir:
        _check_out_dir(cfg, out_dir, rep)
    if not plan and cfg.corpus.check == CheckLevel.DRAWN:
        # no plan says which clips it would draw: any may be, so each is checked as drawn ones are
        cfg = replace(cfg, corpus=replace(cfg.corpus, check=CheckLevel.FULL))
    with tempfile.TemporaryDirectory(prefix="tsel-check-") as scratch:
        catalogs = _check_corpus(cfg, out_dir, Layout(scratch), workers, rep)
        if plan and catalogs and not rep.errors:
            _check_plan(cfg, catalogs, workers, rep, out_dir, Layout(scratch))
    return rep


def _check_recorded(cfg: Config, out_dir, rep: CheckReport, plan: bool) -> CheckReport:
    """A recorded dataset's checks (docs/recorded.md): the output folder, the layout, every
    recording and label file of the splits, and the plan made in memory: how many targets
    each split keeps, and how many it skips and why."""
    rep.facts["receivers"] = [{"name": p.format, "channels": p.n_channels} for p in array_poses(cfg, side=0.1)]
    rep.facts["splits"] = {s: {"scenes": sp.count} for s, sp in cfg.splits.items()}
    if out_dir:
        _check_out_dir(cfg, out_dir, rep, space=False)  # the space needed is known once planned
    with tempfile.TemporaryDirectory(prefix="tsel-check-") as scratch:
        home = Layout(out_dir) if out_dir and os.path.isdir(Layout(out_dir).demo_recordings) else Layout(scratch)
        try:
            plans, summary = plan_recorded(cfg, recorded_corpus(cfg, home))
        except TselError as e:
            rep.error(e)
            return rep
    for split, s in summary.items():
        rep.facts["splits"][split].update(planned=s["kept"], windows=s["windows"], recordings=s["recordings"],
                                          skipped=s["skipped"])
        for why, n in s["skipped"].items():
            rep.warnings.append(f"split {split}: {n:,} of {s['candidates']:,} targets skipped: {why}")
    if out_dir:
        counted = replace(cfg, splits={k: replace(sp, count=len(plans.get(k, []))) for k, sp in cfg.splits.items()})
        _check_space(counted, out_dir, rep, planned_with(Layout(out_dir), cfg))
    return rep


def _check_out_dir(cfg: Config, out_dir: str, rep: CheckReport, space: bool = True) -> None:
    base = os.path.abspath(out_dir)
    while not os.path.exists(base):
        base = os.path.dirname(base)
    if not os.path.isdir(base):
        rep.error(DatasetError(f"output {out_dir}: {base} is a file, not a folder; choose another --out"))
        return
    try:
        fd, probe = tempfile.mkstemp(prefix=".tsel-check-", dir=base)
        os.close(fd)
        os.remove(probe)
    except OSError as e:
        rep.error(DatasetError(f"output {out_dir} is not writable ({base}: {e.strerror or e}); fix its permissions "
                               f"or choose another --out"))
        return
    layout = Layout(out_dir)
    try:
        check_ownership(layout)
    except TselError as e:
        rep.error(e)
        return
    state = planned_with(layout, cfg)
    if state == "different":
        try:
            keys = "; ".join(str(d) for d in plan_differences(layout, cfg)[:4])
        except TselError:
            keys = "its config is unreadable"
        rep.error(DatasetError(f"{out_dir} was planned with a different config ({layout.config_file}: {keys}); "
                               f"choose another --out, use the same config to --resume, or --grow if only "
                               f"splits.NAME.count grew"))
    elif state == "same" and os.path.isfile(layout.dataset_file):
        rep.warnings.append(f"{out_dir} already holds this finished dataset; `tsel check {out_dir}` verifies it")
    elif state == "same":
        rep.warnings.append(f"{out_dir} holds an unfinished run of this config; `tsel generate ... --resume` "
                            f"continues it")
    if space:
        _check_space(cfg, out_dir, rep, state)


def _check_space(cfg: Config, out_dir: str, rep: CheckReport, state: str) -> None:
    base = os.path.abspath(out_dir)
    while not os.path.exists(base):
        base = os.path.dirname(base)
    need = estimate_bytes(cfg)
    free = shutil.disk_usage(base).free
    rep.facts.update(estimated_bytes=need, free_bytes=free)
    if need > free and state != "same":
        rep.error(DatasetError(f"the dataset needs about {need / 1e9:.1f} GB but {base} has {free / 1e9:.1f} GB free; "
                               f"free space, choose another --out, or make fewer scenes"))


def _check_corpus(cfg: Config, out_dir, scratch: Layout, workers: int, rep: CheckReport) -> dict:
    """Read every split's manifest and check its clips; returns {split: good clips}."""
    rep.facts["splits"] = {s: {"scenes": sp.count} for s, sp in cfg.splits.items()}
    if not cfg.active_splits():
        rep.warnings.append("no split has scenes to make; set splits.NAME.count or pass --split NAME=COUNT")
        return {}
    # a demo corpus already synthesised into --out is used as it is; else one in scratch
    home = Layout(out_dir) if cfg.corpus.dir == BUILTIN_DEMO and out_dir and os.path.isfile(
        os.path.join(Layout(out_dir).demo_corpus, "test.csv")) else scratch
    try:
        corpus_dir = resolve_corpus_dir(cfg, home.demo_corpus)
    except TselError as e:
        rep.error(e)
        return {}
    rep.facts["corpus_dir"] = corpus_dir if cfg.corpus.dir != BUILTIN_DEMO else BUILTIN_DEMO
    # a check writes nothing: prepared clips are checked here (hashed), never made
    looking = replace(cfg, corpus=replace(cfg.corpus, prepare_on_check=False))
    scan = scan_catalog(looking, corpus_dir, workers, progress=None)  # bars only on a terminal
    for e in scan.problems:
        rep.error(e)
    _report_bad(cfg, scan.bad, rep)
    for split, clips in scan.missing.items():
        if clips and cfg.on_bad_clip == "skip":
            # a partial download is normal: one line per split, not one per absent file
            rep.warnings.append(f"split {split}: {len(clips):,} of {scan.counts[split]['clips']:,} audio files are "
                                f"missing from {' or '.join(scan.audio_dirs[split])} (first: {os.path.basename(clips[0].audio)}, "
                                f"{clips[0].origin}); those clips are skipped and listed in OUT/missing_clips.json"
                                + (f"; {scan.hints[split]}" if split in scan.hints else ""))
    rep.warnings += scan.warnings
    stop = reuse_stop(cfg, scan)
    if stop:
        rep.warnings.append(f"`tsel generate` will stop before rendering: {stop}")
    for split, c in scan.counts.items():
        rep.facts["splits"][split].update(clips=c["clips"], missing=c["missing"], bad=c["bad"],
                                          policy=cfg.on_bad_clip, band_limited=sum(scan.rates[split].values()),
                                          left_out=scan.left_out[split],
                                          band_limited_rates=scan.rates.get(split, {}))
    rep.facts["fs"] = cfg.audio.fs
    return scan.clips


def _report_bad(cfg: Config, bad: list, rep: CheckReport, errors: bool = False) -> None:
    """Bad clips in the report: listed, and a warning each under ``on_bad_clip = "skip"``
    (under ``"fail"`` they are errors: the scan's problems, or here with ``errors``)."""
    for b in bad:
        rep.bad_clips.append(b.to_json())
        if cfg.on_bad_clip == "fail" and errors:
            rep.error(b.error())
        elif cfg.on_bad_clip == "skip":
            rep.warnings.append(f"{b.origin}: clip {b.clip_id}: {b.problem} (skipped: on_bad_clip = \"skip\")")


def _check_plan(cfg: Config, catalogs: dict, workers: int, rep: CheckReport, out_dir, scratch: Layout) -> None:
    """Sample every scene in memory (what `tsel plan` would write), collecting failures;
    the views are made as `tsel generate` makes them (plan.sampler.catalog_views)."""
    home = Layout(out_dir) if out_dir and os.path.exists(Layout(out_dir).demo_bank) else scratch
    for split, clips in catalogs.items():
        try:
            view = catalog_views(cfg, {split: clips}, home)[split]
            if cfg.corpus.check == "drawn":  # the clips the plan draws, checked as the job checks them
                plans, found = plan_drawn(cfg, {split: view}, workers, progress=None, prepare=False)
                lines = plans[split]
                _report_bad(cfg, found.bad, rep, errors=True)
                rep.facts["splits"][split]["bad"] = rep.facts["splits"][split].get("bad", 0) + len(found.bad)
                rep.facts["splits"][split]["checked_in_full"] = found.checked
            else:
                lines = plan_split_json(cfg, split, view, workers, progress=None)  # a bar only on a terminal
        except TselError as e:
            rep.error(e)
            continue
        rep.facts["splits"][split]["planned"] = len(lines)
