"""Rebuild a dataset from a recipe release (``tsel generate --from REL --corpus-dir MY_COPY
--out DIR``) and say, scene by scene, how close it came.

The release's recipes are rendered from the user's copy of the corpus; each scene then
gets one status, held against the release's checksums (store/release.py):

- ``identical``: audio, labels and record are the release's, bit for bit;
- ``differs``: they are not; ``why`` names the scene's clips whose bytes differ from the
  release's (or says none does: the renderer or its libraries differ; a release rendered
  by another renderer than this tsel-data's, core/version.py, is named in ``renderer``
  and ``note``, with the tsel-data version that rebuilds it bit for bit);
- ``not-buildable``: a clip is missing (or no longer readable), and the policy is
  ``skip``: the scene is left out of the dataset;
- ``substituted``: a clip was missing and the policy is ``substitute``: a clip of the
  same split drawn per (scene, source) from those present and unchanged plays in its
  place (a substituted target's query becomes the substitute's first caption); the
  substitution is in ``why``.

The dataset is an ordinary one (plan, shards, ``dataset.json``: every tool reads it);
``rebuild.json`` holds the report. Running the same command again resumes it.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, field

from ..banks.scenes import resolve_bank
from ..choices import MissingClipPolicy, values
from ..config import parse_config
from ..core.atomic import write_json, write_lines
from ..core.version import RENDERER, __version__, is_newer, renderer_of
from ..corpus.audio import check_clip
from ..errors import ConfigError, DatasetError, TselError
from ..plan.catalog import BUILTIN_DEMO, resolve_corpus_dir
from ..plan.sampler import bank_request
from ..plan.recorded import recorded_corpus
from ..render.recorded import recorded_problem
from ..scene.recipe import BUILTIN_DEMO_RECORDED, RECORDED, Roots, SceneRecipe, corpus_files, recipe_from_dict
from ..store.layout import Layout
from ..store.lock import DatasetLock
from ..store.plans import has_plan, local_roots, plan_seal, read_plan_doc
from ..store.reader import open_dataset
from ..store.release import REBUILD_FILE, Release, differing_parts, load_release, scene_digest
from .pipeline import check_ownership, finalize, render_shards
from .relocate import VIEW, locate_clips, write_view

POLICIES = values(MissingClipPolicy)
STATUSES = ("identical", "differs", "substituted", "not-buildable")


@dataclass
class SceneOutcome:
    """How one scene of the release came out (see the module docstring)."""

    scene_id: str
    split: str
    status: str
    why: str = ""
    parts: list = field(default_factory=list)
    clips: list = field(default_factory=list)


@dataclass
class ClipState:
    """A clip of the release in the user's copy: ``missing`` (with the reason) or ``changed``."""

    missing: dict = field(default_factory=dict)
    changed: set = field(default_factory=set)


def rebuild(release_dir: str, out_dir: str, corpus_dir: str | None = None, bank: str | None = None,
            missing: str = "skip", workers: int = 1, progress: bool = True, force: bool = False,
            executor: str = "local", scheduler: str | None = None, min_scenes: int | str = 1) -> dict:
    """Render the release ``release_dir`` into ``out_dir`` from the corpus at
    ``corpus_dir`` (and the RIR bank at ``bank``); returns the report written to
    ``out_dir/rebuild.json``: ``splits`` ({split: {status: count}}), ``clips`` (how many
    were found at their names, elsewhere in the copy, differing, missing), ``found``
    ({release name: where it is in the copy} for the clips found elsewhere) and ``scenes``
    (every :class:`SceneOutcome`, in plan order).

    The clips are found wherever the copy holds them (:mod:`tsel_data.job.relocate`).
    ``min_scenes``: the fewest scenes the rebuild must make, a count or a share of the
    release's (``"95%"``); when fewer can be built, it stops before rendering, with the
    report (``stopped``) and no ``dataset.json``.

    Raises a TselError (one line) for a folder that is not a release, a corpus or bank
    not given or not there, an unknown ``missing`` policy, an ``out_dir`` that holds
    anything but this rebuild (without ``force``), fewer buildable scenes than ``min_scenes``.
    """
    if missing not in POLICIES:
        raise TselError(f"--missing {missing!r}: choose one of {', '.join(POLICIES)}")
    rel = load_release(release_dir)
    total = sum(len(rel.recipe_lines(s)) for s in rel.splits)
    need = required_scenes(min_scenes, total)
    layout = Layout(out_dir)
    check_ownership(layout, force)
    os.makedirs(layout.plan_dir, exist_ok=True)
    with DatasetLock(layout, exclusive=True, what="rebuild it"):
        config = _config_here(rel, layout, corpus_dir, bank)
        try:
            cfg = parse_config(local_roots(config, layout.root), where=rel.path("plan/config.json"), stored=True)
        except ConfigError as e:
            if not is_newer(rel.doc.get("version")):
                raise
            raise DatasetError(f"{release_dir} was made by tsel-data {rel.doc.get('version')}, newer than this one "
                               f"({__version__}), and its config is not one this version reads ({e}); update "
                               f"tsel-data: pip install -U tsel-data") from None
        corpus = recorded_corpus(cfg, layout) if cfg.recorded.on else resolve_corpus_dir(cfg, layout.demo_corpus)
        if cfg.room.bank:
            resolve_bank(bank_request(cfg), layout.demo_bank)  # builds the built-in one, checks any other
        found = locate_clips(rel.clips(), corpus, cfg, progress, skip=layout.root)
        clips = _clip_states(rel, found, cfg)
        if any(f.path and f.how != "name" for f in found.values()):  # read through links named as the release's
            corpus = layout.path(VIEW)
            write_view(corpus, found)
            config["corpus"]["dir"] = VIEW
        plans, outcomes = _plan(rel, clips, missing, Roots(corpus=corpus))
        report = _report(rel, release_dir, out_dir, missing, found, corpus_dir or corpus, outcomes)
        built = sum(len(lines) for lines in plans.values())
        if built < need:
            gone = len(clips.missing)
            why = next(iter(clips.missing.values()), "")
            report["stopped"] = (f"{built:,} of the release's {total:,} scenes can be built, fewer than "
                                 f"--min-scenes {min_scenes}" + (f" ({gone:,} clips missing or bad; the first: {why})"
                                                                  if why else ""))
            write_json(os.path.join(out_dir, REBUILD_FILE), report)
            raise DatasetError(f"{report['stopped']}; nothing rendered, what was found where: "
                               f"{os.path.join(out_dir, REBUILD_FILE)}; pass --corpus-dir with the copy that holds "
                               f"the clips" + ("" if missing == "substitute" else ", or --missing substitute"))
        _write_plan(rel, layout, config, plans)
        render_shards(out_dir, workers=workers, progress=progress, executor=executor, scheduler=scheduler)
        finalize(out_dir)
        _compare(rel, out_dir, outcomes, clips)
    report = _report(rel, release_dir, out_dir, missing, found, corpus_dir or corpus, outcomes)
    write_json(os.path.join(out_dir, REBUILD_FILE), report)
    return report


def required_scenes(spec: int | str, total: int) -> int:
    """The fewest scenes a rebuild must make: ``spec`` a count (``30``) or a share of the
    release's ``total`` (``"95%"``), never more than the release holds."""
    text = str(spec).strip()
    try:
        n = math.ceil(float(text[:-1]) * total / 100 - 1e-9) if text.endswith("%") else int(text)
    except (ValueError, OverflowError):  # not a number, nan%, inf%
        n = -1
    if n < 0 or (text.endswith("%") and float(text[:-1]) > 100):
        raise TselError(f"--min-scenes {spec}: give a count of scenes (e.g. 30) or a share of the release's "
                        f"(e.g. 95%)")
    return min(n, total)


def _report(rel: Release, release_dir: str, out_dir: str, missing: str, found: dict, copy: str,
            outcomes: list) -> dict:
    """rebuild.json: per split, how many scenes came out how; the clips found, where."""
    moved = {name: os.path.relpath(f.path, copy).replace(os.sep, "/") for name, f in sorted(found.items())
             if f.path and f.how != "name"}
    return {"tool": "tsel-data", "version": __version__,
            "release": os.path.relpath(os.path.realpath(release_dir), os.path.realpath(out_dir)).replace(os.sep, "/"),
            "release_version": rel.doc.get("version"), "missing": missing,
            "renderer": {"release": renderer_of(rel.doc), "this": RENDERER}, "note": renderer_note(rel),
            "splits": {s: {k: sum(o.split == s and o.status == k for o in outcomes) for k in STATUSES}
                       for s in rel.splits},
            "clips": {"at their names": sum(bool(f.path) and f.how == "name" for f in found.values()),
                      "found elsewhere": len(moved),
                      "differing": sum(bool(f.path) and not f.same for f in found.values()),
                      "missing": sum(f.path is None for f in found.values())},
            "found": moved,
            "scenes": [asdict(o) for o in outcomes]}


def renderer_note(rel: Release) -> str | None:
    """One line when the release was rendered by another renderer than this tsel-data's
    (None when by the same): scenes whose bytes changed between them will differ, and the
    version that made the release rebuilds it bit for bit."""
    theirs, made = renderer_of(rel.doc), rel.doc.get("version") or "unknown"
    if theirs == RENDERER:
        return None
    return (f"the release was rendered by renderer {theirs} (tsel-data {made}); this tsel-data ({__version__}) "
            f"renders with renderer {RENDERER}, so scenes whose bytes changed between them are reported as differing; "
            f"tsel-data {made} rebuilds the release bit for bit (pip install 'tsel-data=={made}')")


def _config_here(rel: Release, layout: Layout, corpus_dir: str | None, bank: str | None) -> dict:
    """The release's config with its roots where they are here (as plan/config.json
    stores them: relative to the new dataset), or a one-line error naming the flag."""
    config = json.loads(json.dumps(rel.plan_doc["config"]))
    corpus = (config.get("corpus") or {}).get("dir", "")
    if corpus_dir:
        config["corpus"]["dir"] = os.path.abspath(os.path.expanduser(corpus_dir))
    elif corpus not in (BUILTIN_DEMO, BUILTIN_DEMO_RECORDED):
        raise TselError(f"the release's clips come from a corpus of your own ({corpus or 'unnamed'}, as the "
                        f"dataset's maker had it): give --corpus-dir with your copy")
    room = config.get("room") or {}
    if bank:
        room["bank"] = os.path.abspath(os.path.expanduser(bank))
    elif room.get("bank") and not str(room["bank"]).startswith("builtin:"):
        raise TselError(f"the release renders through the RIR bank {room['bank']}: give --bank with your copy")
    config["room"] = room
    for sec, key in (("corpus", "dir"), ("room", "bank")):  # relative to the new dataset, as plans store roots
        value = config[sec].get(key)
        if value and os.path.isabs(value):
            config[sec][key] = os.path.relpath(os.path.realpath(value), os.path.realpath(layout.root)) \
                .replace(os.sep, "/")
    return config


def _clip_states(rel: Release, found: dict, cfg) -> ClipState:
    """Which of the release's clips are missing from (or unreadable in) the copy, and
    which differ from the release's bytes (``found``: :func:`~tsel_data.job.relocate.locate_clips`)."""
    state = ClipState()
    c = cfg.corpus
    for name, entry in rel.clips().items():
        f = found[name]
        if f.path is None:
            where = "at that name" if cfg.recorded.on else "at that name, through its manifests and by file name"
            state.missing[name] = (f"{'file' if cfg.recorded.on else 'clip'} {entry['clip_id']} ({name}) is missing "
                                   f"from the copy (looked for {where})")
            continue
        if f.same:
            continue
        state.changed.add(name)
        if cfg.recorded.on:  # a recording or its labels: the scenes' checksums tell what changed
            continue
        check = check_clip(entry["clip_id"], f.path, "full", c.min_duration, c.max_channels)
        if check.problem:
            state.missing[name] = f"clip {entry['clip_id']} changed and is a bad clip now: {check.problem}"
    return state


def _plan(rel: Release, clips: ClipState, policy: str, roots: Roots) -> tuple[dict, list]:
    """{split: recipe lines to render} and the outcomes known before rendering (a recorded
    scene whose recording or labels changed so that it cannot be cut: not buildable)."""
    entries = rel.clips()
    plans, outcomes = {}, []
    for split in rel.splits:
        pool = sorted(n for n, e in entries.items() if split in e.get("splits", ()) and n not in clips.missing
                      and n not in clips.changed and e.get("captions"))  # a clip heard only as noise has no caption
        lines = []
        for line in rel.recipe_lines(split):
            d = json.loads(line)
            names = [name for name, _, _ in corpus_files(d)]
            gone = [n for n in names if n in clips.missing]
            problem = None
            if not gone and d.get("kind") == RECORDED and any(n in clips.changed for n in names):
                problem = recorded_problem(recipe_from_dict(d), roots)
            if problem:
                outcomes.append(SceneOutcome(d["scene_id"], split, "not-buildable", problem, clips=names))
                continue
            if not gone:
                lines.append(line)
                outcomes.append(SceneOutcome(d["scene_id"], split, "", clips=names))
                continue
            why = "; ".join(clips.missing[n] for n in gone)
            # a recording, or a clip the scene's noise plays, has no stand-in
            if policy == MissingClipPolicy.SKIP or d.get("kind") == RECORDED or \
                    not {s["audio"] for s in d["sources"]}.issuperset(gone):
                outcomes.append(SceneOutcome(d["scene_id"], split, "not-buildable", why, clips=names))
                continue
            done = _substitute(d, gone, pool, entries)
            if done is None:
                outcomes.append(SceneOutcome(d["scene_id"], split, "not-buildable",
                                             why + "; no clip of the split is left to stand in", clips=names))
                continue
            lines.append(SceneRecipe.from_dict(d).to_json())
            outcomes.append(SceneOutcome(d["scene_id"], split, "substituted", why + "; " + done,
                                         clips=[s["audio"] for s in d["sources"]]))
        plans[split] = lines
    return plans, outcomes


def _substitute(d: dict, gone: list, pool: list, entries: dict) -> str | None:
    """Put a clip of ``pool`` in place of each missing one of recipe ``d`` (in place);
    the choice hashes (scene id, source, clip), so it is the same on every machine.
    Returns what was done, or None when the pool has no clip the scene does not use."""
    done = []
    for k, s in enumerate(d["sources"]):
        if s["audio"] not in gone:
            continue
        used = {x["audio"] for x in d["sources"]}
        free = [n for n in pool if n not in used]
        if not free:
            return None
        key = hashlib.sha256(f"{d['scene_id']}/{k}/{s['audio']}".encode()).digest()
        name = free[int.from_bytes(key[:8], "big") % len(free)]
        new = entries[name]
        done.append(f"source {k} plays {new['clip_id']} instead of {s['clip_id']}")
        s.update(audio=name, clip_id=new["clip_id"], captions=list(new["captions"]), offset=0.0)
        if k == 0:
            d["query"] = new["captions"][0]
            if d.get("query_plan"):  # the relations stand; the captions are the substitute's
                d["query_plan"].update(alternatives=list(new["captions"]), matches=[])
    return ", ".join(done)


def _write_plan(rel: Release, layout: Layout, config: dict, plans: dict) -> None:
    """The plan of the scenes to render, as the plan stage writes it (config last). A
    folder that already holds this plan (an interrupted rebuild) is resumed as it is."""
    counts = {s: len(lines) for s, lines in plans.items()}
    config = {**config, "splits": {s: {**v, "count": counts.get(s, 0)} for s, v in config["splits"].items()}}
    # sealed anew: the config (counts) and the plan files (scenes left out or substituted)
    # are this rebuild's, not the release's
    doc = {**rel.plan_doc, "config": config,
           "seal": plan_seal(config, {s: plans.get(s, []) for s in config["splits"]})}
    if has_plan(layout):
        if read_plan_doc(layout) == json.loads(json.dumps(doc)):
            return
        raise DatasetError(f"{layout.root} holds another dataset plan; rebuild into a new --out")
    for split in config["splits"]:  # a split the release does not hold is planned empty
        write_lines(layout.plan_file(split), plans.get(split, []))
    write_json(layout.config_file, doc)


def _compare(rel: Release, out_dir: str, outcomes: list, clips: ClipState) -> None:
    """Each rendered scene's checksums against the release's: its status and why."""
    by_id = {o.scene_id: o for o in outcomes}
    for split in rel.splits:
        want = rel.checksums(split)
        with open_dataset(out_dir, split) as ds:
            for scene in ds:
                o = by_id[scene.scene_id]
                o.parts = differing_parts(want[scene.scene_id], scene_digest(scene))
                if o.status == "substituted":
                    continue
                if not o.parts:
                    o.status = "identical"
                    continue
                o.status = "differs"
                changed = [n for n in o.clips if n in clips.changed]
                # an edited recipe was refused on load by the plan's seal; a release without one cannot tell
                edited = "" if isinstance(rel.plan_doc.get("seal"), dict) else \
                    "its recipe was edited (the release has no plan seal to tell), or "
                theirs = renderer_of(rel.doc)
                o.why = ("; ".join(f"clip {n} differs from the release's (sha256)" for n in changed) if changed else
                         f"no clip differs: {edited}the renderer does (release rendered by renderer {theirs}, this is "
                         f"renderer {RENDERER}: tsel-data {rel.doc.get('version')} rebuilds it bit for bit)"
                         if theirs != RENDERER else
                         f"no clip differs: {edited}the renderer or its libraries do (release made by tsel-data "
                         f"{rel.doc.get('version')}, this is {__version__})")
