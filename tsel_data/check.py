"""Validation before and after the heavy work: ``tsel check CONFIG`` and ``tsel check DIR``.

:func:`check_config` runs every check a dataset job can fail on, without rendering:
the config's ranges and geometry (including the *smallest* room a range can draw),
the RIR bank (when ``room.bank`` is set), the output folder, every manifest, every clip
(``corpus.check`` level, ``on_bad_clip`` policy), duplicate clip ids, and finally the
whole plan is sampled in memory (planning is cheap: ~0.2 ms per scene), so a scene
that cannot be placed is found here and not after hours of rendering.

:func:`check_dataset` verifies a written dataset: every shard listed in
``dataset.json`` is present with the recorded sha256, each HDF5 file and its JSON twin
hold the same scenes, queries and labels, and the counts agree with the plan.

Both return a :class:`CheckReport`; nothing here raises for a user mistake (problems
are collected, so a user sees all of them at once). ``report.raise_for_errors()``
turns the first problem into its :class:`~tsel_data.errors.TselError`.
"""
from __future__ import annotations

import glob
import json
import math
import os
import shutil
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .config import Config, validate_config
from .errors import ConfigError, DatasetError, GeometryError, ManifestError, TselError

MAX_NUMBER = 1e9  # check_raw_config: larger config numbers are typos (seeds excepted)
# JSON labels are rounded to 3 decimals (distance 4): HDF5 and JSON agree within this
LABEL_ATOL = 2e-3


@dataclass
class CheckReport:
    """What a check found.

    target: what was checked (config name or dataset folder). errors: problems that
    stop a run, as TselError instances (one-line messages). warnings: one-line strings
    for things that work but deserve a look. bad_clips: {"split", "clip_id", "origin",
    "problem"} for every clip the bad-clip policy applies to. facts: plain numbers
    (clips, scenes, shards, bytes) for the summary.
    """

    target: str
    errors: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    bad_clips: list = field(default_factory=list)
    facts: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.errors

    def error(self, e: TselError | str, cls=TselError) -> None:
        self.errors.append(e if isinstance(e, TselError) else cls(e))

    def messages(self) -> list[str]:
        return [str(e) for e in self.errors]

    def raise_for_errors(self) -> None:
        """Raise the first problem (its own TselError subclass), noting how many more there are."""
        if not self.errors:
            return
        first = self.errors[0]
        if len(self.errors) == 1:
            raise first
        raise type(first)(f"{first} (and {len(self.errors) - 1} more problem(s); run `tsel check` to list them)")

    def to_dict(self) -> dict:
        return {"target": self.target, "ok": self.ok, "errors": self.messages(), "warnings": list(self.warnings),
                "bad_clips": list(self.bad_clips), "facts": self.facts}

    def summary_lines(self) -> list[str]:
        """Human summary (what was checked, counts); problems are in errors/warnings."""
        f = self.facts
        out = [f"{self.target}: {'OK' if self.ok else f'{len(self.errors)} problem(s)'}"]
        for split, s in f.get("splits", {}).items():
            parts = []
            if "clips" in s:
                parts.append(f"{s['clips']} clips")
            if s.get("bad"):
                parts.append(f"{s['bad']} bad ({s.get('policy', 'skip')})")
            if "planned" in s:
                parts.append(f"{s['planned']} scenes planned")
            if "scenes" in s and "planned" not in s:
                parts.append(f"{s['scenes']} scenes")
            if "shards" in s:
                parts.append(f"{s['shards']} shards")
            out.append(f"  {split}: " + ", ".join(parts))
        if "estimated_bytes" in f:
            free = f.get("free_bytes")
            out.append(f"  output about {f['estimated_bytes'] / 1e9:.2f} GB"
                       + (f" ({free / 1e9:.1f} GB free)" if free is not None else ""))
        if "bytes" in f:
            out.append(f"  {f['bytes'] / 1e6:.1f} MB checked")
        return out


# --- config ---------------------------------------------------------------------------------


def check_config(cfg: Config, out_dir: str | None = None, workers: int = 1, plan: bool = True) -> CheckReport:
    """Validate a config and everything it reads, before any rendering.

    cfg: a loaded Config. out_dir: the output folder a run would use (checked for
    writability, an existing plan, free space); None to skip. workers: processes for
    clip checks and planning. plan: also sample every scene in memory.
    """
    rep = CheckReport(f"config {cfg.name}")
    try:
        validate_config(cfg, smallest_room=False)  # geometry_problems below reports every one
    except TselError as e:
        rep.error(e)
        return rep  # later checks assume a sane config
    for e in geometry_problems(cfg):
        rep.error(e)
    if cfg.room.bank:
        for e in bank_problems(cfg):
            rep.error(e)
    else:
        for name, sp in cfg.splits.items():
            if sp.rooms:
                rep.error(ConfigError(f"splits.{name}.rooms is set but room.bank is empty; set room.bank to an "
                                      f"RIR bank or remove the rooms"))
    if out_dir:
        _check_out_dir(cfg, out_dir, rep)
    with tempfile.TemporaryDirectory(prefix="tsel-check-") as scratch:
        catalogs = _check_corpus(cfg, out_dir, scratch, workers, rep)
        if plan and catalogs and not rep.errors:
            _check_plan(cfg, catalogs, workers, rep, out_dir, scratch)
    return rep


def geometry_problems(cfg: Config) -> list[TselError]:
    """Layouts no scene drawn from the config's ranges could realise, judged on the
    *smallest* room the ranges allow (config.validate_config judges the largest).

    Checks: the array (its radius plus ``array.wall_margin``) fits the smallest floor;
    sources fit between their wall margins in it; the minimum source distance is
    reachable in it (diagonal of the floor area left by the margins, with the largest
    height difference); heights fit under the lowest ceiling. Returns GeometryErrors.
    """
    if cfg.room.bank:
        return []
    r, arr, src = cfg.room, cfg.array, cfg.sources
    bounds = {k: getattr(r, k).bounds for k in ("length", "width", "height")}
    if any(b is None for b in bounds.values()) or arr.height.bounds is None or src.height.bounds is None \
            or src.distance.bounds is None:
        return []  # validate_config reports non-numeric ranges
    out: list[TselError] = []
    lmin, wmin, hmin = bounds["length"][0], bounds["width"][0], bounds["height"][0]
    floor = min(lmin, wmin)
    side = arr.side.bounds[1] if cfg.scene.format == "mic4" and arr.side.bounds else 0.0
    radius = {"mic4": side / math.sqrt(2.0), "tetra": 0.042, "foa": 0.0}.get(cfg.scene.format, 0.0)
    need = 2 * (arr.wall_margin + radius)
    if floor < need:
        key = "room.length" if lmin <= wmin else "room.width"
        out.append(GeometryError(
            f"{key} minimum {floor} m is smaller than the array plus its margins ({need:.2f} m = 2 x "
            f"(array.wall_margin {arr.wall_margin} + array radius {radius:.3f})); raise the minimum to at least "
            f"{need:.2f} m or lower array.wall_margin"))
    if floor <= 2 * src.wall_margin:
        out.append(GeometryError(
            f"the smallest room ({floor} m) leaves no floor between the sources' wall margins "
            f"(2 x sources.wall_margin = {2 * src.wall_margin} m); raise the room minimum or lower sources.wall_margin"))
    if arr.height.bounds[0] >= hmin:
        out.append(GeometryError(
            f"array.height minimum {arr.height.bounds[0]} m does not fit under the lowest ceiling (room.height minimum "
            f"{hmin} m); lower array.height or raise room.height"))
    top = hmin - src.wall_margin
    if src.height.bounds[0] > top:
        out.append(GeometryError(
            f"sources.height minimum {src.height.bounds[0]} m is above the highest source position in the lowest room "
            f"({hmin} m - sources.wall_margin {src.wall_margin} m = {top:.2f} m); lower sources.height or raise "
            f"room.height"))
    if not out:
        reach_xy = math.hypot(max(lmin - arr.wall_margin - src.wall_margin, 0.0),
                              max(wmin - arr.wall_margin - src.wall_margin, 0.0))
        dz = max(abs(src.height.bounds[1] - arr.height.bounds[0]), abs(arr.height.bounds[1] - src.height.bounds[0]))
        reach = math.hypot(reach_xy, min(dz, hmin))
        dmin = src.distance.bounds[0]
        if dmin > reach:
            out.append(GeometryError(
                f"sources.distance minimum {dmin} m cannot fit in the smallest room ({lmin} x {wmin} x {hmin} m; at "
                f"most {reach:.2f} m from the array given the wall margins); lower sources.distance or raise the room "
                f"minimum"))
    return out


def bank_problems(cfg: Config) -> list[TselError]:
    """Problems with ``room.bank``: missing or unreadable bank, array format or sample
    rate differing from the config, split rooms the bank lacks, rooms without
    trajectories, missing or non-finite positions, mic4 rooms without the array's side
    length. Returns TselErrors (BankError)."""
    try:
        from .banks import BankError, open_bank
    except ImportError:  # pragma: no cover - banks ship with the package
        return [ConfigError("room.bank is set but this installation has no RIR bank support")]
    out: list[TselError] = []
    fmt = cfg.scene.format
    if cfg.room.bank.startswith("builtin:"):
        return []  # built by the run itself to match the config (plan.resolve_bank)
    try:
        path = os.path.abspath(os.path.expanduser(cfg.room.bank))
        # a folder (TAU-SRIR DB, SpatialScaper's SOFA files) may hold several formats: take the config's
        bank = open_bank(path, format=fmt if os.path.isdir(path) else None)
    except TselError as e:
        return [e]
    except OSError as e:
        return [BankError(f"RIR bank {cfg.room.bank}: cannot read it ({e.strerror or e}); check the path")]
    with bank:
        if bank.format != fmt:
            out.append(BankError(f"{bank.source}: the bank holds {bank.format} RIRs but scene.format = {fmt!r}; "
                                 f"set scene.format = \"{bank.format}\" or use a {fmt} bank"))
        try:
            bank.require_fs(cfg.audio.fs)
        except TselError as e:
            out.append(e)
        if not bank.rooms:
            out.append(BankError(f"{bank.source}: the bank holds no rooms; rebuild or re-import it"))
            return out
        used: dict[str, str] = {}
        for split, sp in cfg.splits.items():
            if not sp.count:
                continue  # a split made from another bank (or later) may name rooms this one lacks
            for key in sp.rooms:
                try:
                    room = bank.resolve_room(key)
                except TselError as e:
                    out.append(BankError(f"splits.{split}.rooms: {e}"))
                    continue
                if room in used and used[room] != split:
                    out.append(BankError(
                        f"splits.{split}.rooms: room {room} is also used by split {used[room]}; a room in two splits "
                        f"leaks its acoustics into evaluation; give each split its own rooms"))
                used.setdefault(room, split)
        unlisted = [s for s, sp in cfg.splits.items() if sp.count and not sp.rooms]
        if unlisted:
            from .plan import split_rooms

            try:  # the rooms no split names, shared by every split without rooms
                for room in split_rooms(cfg, unlisted[0], bank):
                    used.setdefault(room, unlisted[0])
            except ConfigError as e:
                out.append(e)
        for room in used:
            e = _room_positions_problem(bank, room)
            if e:
                out.append(e)
    return out


def _room_positions_problem(bank, room: str):
    from .banks import BankError

    try:
        trajs = bank.trajectories(room)
    except TselError as e:
        return e
    if not trajs or sum(len(t) for t in trajs) == 0:
        return BankError(f"{bank.source}: room {room} has no RIR positions (no trajectories); re-import the room or "
                         f"remove it from the split's rooms")
    if bank.format == "mic4":
        side = (bank.room_info(room).get("array") or {}).get("side")
        if not isinstance(side, (int, float)) or not side > 0:
            # a square array's mic positions (labels' mic_positions) need its side length
            return BankError(f"{bank.source}: room {room} is a mic4 room without the array's side length (room info "
                             f"array.side); rebuild it with `tsel bank build` or add the side to its info")
    for t in trajs:
        p = np.asarray(t.positions, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
            return BankError(f"{bank.source}: room {room} trajectory {t.id}: positions missing (shape {p.shape}, "
                             f"expected [N, 3] azimuth, elevation, distance); re-import the bank")
        bad = ~np.all(np.isfinite(p), axis=1) | (p[:, 2] <= 0)
        if bad.any():
            return BankError(f"{bank.source}: room {room} trajectory {t.id}: {int(bad.sum())} of {len(p)} positions "
                             f"missing or invalid (first at index {int(np.argmax(bad))}: {p[np.argmax(bad)].tolist()}); "
                             f"re-import the bank or drop the room")
    return None


def _check_out_dir(cfg: Config, out_dir: str, rep: CheckReport) -> None:
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
    stored = os.path.join(out_dir, "plan", "config.json")
    if os.path.isfile(stored):
        try:
            with open(stored, encoding="utf-8") as f:
                old = json.load(f).get("config")
        except (OSError, ValueError):
            old = None
        if old != cfg.to_dict():
            rep.error(DatasetError(f"{out_dir} was planned with a different config ({stored}); choose another --out, "
                                   f"or use the same config to --resume"))
        elif os.path.isfile(os.path.join(out_dir, "dataset.json")):
            rep.warnings.append(f"{out_dir} already holds this finished dataset; `tsel check {out_dir}` verifies it")
        else:
            rep.warnings.append(f"{out_dir} holds an unfinished run of this config; `tsel generate ... --resume` "
                                f"continues it")
    from .geometry import CHANNEL_NAMES

    a = cfg.audio
    n_scenes = sum(sp.count for sp in cfg.splits.values())
    frames = int(round(a.duration / a.label_hop))
    n_src = (cfg.scene.interferers.bounds or (1, 1))[1] + 1
    per_scene = len(CHANNEL_NAMES[cfg.scene.format]) * int(round(a.duration * a.fs)) * 4 + n_src * frames * 13 + 2000
    need = n_scenes * per_scene
    free = shutil.disk_usage(base).free
    rep.facts.update(estimated_bytes=need, free_bytes=free)
    if need > free:
        rep.warnings.append(f"the dataset needs about {need / 1e9:.1f} GB but {base} has {free / 1e9:.1f} GB free; "
                            f"free space or choose another --out (an interrupted run resumes with --resume)")


def _check_corpus(cfg: Config, out_dir, scratch: str, workers: int, rep: CheckReport) -> dict:
    """Read every split's manifest and check its clips; returns {split: good clips}."""
    from .catalog import BUILTIN_DEMO, check_clips, duplicate_clips, read_split_clips, resolve_corpus_dir

    active = {s: sp for s, sp in cfg.splits.items() if sp.count > 0}
    rep.facts["splits"] = {s: {"scenes": sp.count} for s, sp in cfg.splits.items()}
    if not active:
        rep.warnings.append("no split has scenes to make; set splits.NAME.count or pass --split NAME=COUNT")
        return {}
    corpus_home = scratch
    if cfg.corpus.dir == BUILTIN_DEMO and out_dir and os.path.isfile(os.path.join(out_dir, "demo-corpus", "test.csv")):
        corpus_home = out_dir
    try:
        corpus_dir = resolve_corpus_dir(cfg, corpus_home)
    except TselError as e:
        rep.error(e)
        return {}
    rep.facts["corpus_dir"] = corpus_dir if cfg.corpus.dir != BUILTIN_DEMO else BUILTIN_DEMO
    good: dict = {}
    seen: dict = {}
    for split in active:
        facts = rep.facts["splits"][split]
        try:
            clips = read_split_clips(cfg, split, corpus_dir)
        except TselError as e:
            rep.error(e)
            continue
        except OSError as e:
            rep.error(ManifestError(f"splits.{split}.manifest: cannot read it ({e.strerror or e}: {e.filename}); "
                                    f"check the file"))
            continue
        for msg in duplicate_clips(clips, split, seen):
            rep.error(ManifestError(msg))
        checks = check_clips(clips, cfg, workers)
        ok = []
        for clip, chk in zip(clips, checks):
            if chk.problem is None:
                ok.append(clip)
                continue
            bad = {"split": split, "clip_id": clip.id, "origin": clip.origin, "problem": chk.problem}
            rep.bad_clips.append(bad)
            if cfg.on_bad_clip == "fail":
                rep.error(_bad_clip_error(bad))
            else:
                rep.warnings.append(f"{clip.origin}: clip {clip.id}: {chk.problem} (skipped: on_bad_clip = \"skip\")")
        facts.update(clips=len(clips), bad=len(clips) - len(ok), policy=cfg.on_bad_clip)
        if len(ok) < 2:
            rep.error(TselError(f"split {split}: only {len(ok)} usable clips in {cfg.splits[split].manifest}; a scene "
                                f"needs two; add clips or fix the bad ones"))
            continue
        good[split] = ok
    return good


def _bad_clip_error(b: dict):
    from .errors import AudioError

    return AudioError(f"{b['origin']}: clip {b['clip_id']}: {b['problem']}; fix or remove it, or set "
                      f"on_bad_clip = \"skip\"")


def _check_plan(cfg: Config, catalogs: dict, workers: int, rep: CheckReport, out_dir, scratch: str) -> None:
    """Sample every scene in memory (what `tsel plan` would write), collecting failures."""
    from .plan import CatalogView, plan_split_json, resolve_bank

    bank_path = None
    if cfg.room.bank:
        home = out_dir if out_dir and os.path.exists(os.path.join(out_dir, "demo-bank.h5")) else scratch
        try:
            bank_path = resolve_bank(cfg, home)
        except TselError as e:
            rep.error(e)
            return
    for split, clips in catalogs.items():
        try:
            lines = plan_split_json(cfg, split, CatalogView(clips, bank_path), workers)
        except TselError as e:
            rep.error(e)
            continue
        rep.facts["splits"][split]["planned"] = len(lines)


# --- dataset ------------------------------------------------------------------------------


def check_dataset(out_dir: str, workers: int = 1, audio: bool = True) -> CheckReport:
    """Verify a written dataset folder against its ``dataset.json``.

    Every listed shard must exist with the recorded sha256 (HDF5 and JSON); each
    HDF5 must hold the datasets and shapes of docs/format.md and agree scene by scene
    with its JSON (ids, queries, per-frame labels, activity, mic positions); counts must
    match the plan and the config; ``audio=True`` also checks every sample is finite.
    An unfinished run (plan but no ``dataset.json``) is reported with its progress.
    """
    rep = CheckReport(f"dataset {out_dir}")
    if not os.path.isdir(out_dir):
        rep.error(DatasetError(f"{out_dir}: no such folder; give the --out folder of `tsel generate`"))
        return rep
    doc_path = os.path.join(out_dir, "dataset.json")
    if not os.path.isfile(doc_path):
        _report_unfinished(out_dir, rep)
        return rep
    try:
        with open(doc_path, encoding="utf-8") as f:
            doc = json.load(f)
        splits = doc["splits"]
        config = doc["config"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        rep.error(DatasetError(f"{doc_path}: unreadable or incomplete ({e}); rerun `tsel finalize {out_dir}`"))
        return rep
    expect = {"fs": doc.get("fs"), "format": doc.get("format"), "channels": len(doc.get("channel_names") or []),
              "samples": int(round(config["audio"]["duration"] * config["audio"]["fs"])),
              "frames": int(round(config["audio"]["duration"] / config["audio"]["label_hop"])), "audio": audio}
    jobs = []
    rep.facts["splits"] = {}
    total_bytes = 0
    for split, s in splits.items():
        shards = s.get("shards", [])
        n = sum(sh.get("scenes", 0) for sh in shards)
        rep.facts["splits"][split] = {"scenes": s.get("scenes", 0), "shards": len(shards)}
        want = config.get("splits", {}).get(split, {}).get("count")
        if n != s.get("scenes"):
            rep.error(DatasetError(f"{doc_path}: split {split} lists {s.get('scenes')} scenes but its shards hold {n}; "
                                   f"rerun `tsel finalize {out_dir}`"))
        if want is not None and n != want:
            rep.error(DatasetError(f"{doc_path}: split {split} holds {n} scenes but the config asks for {want}; the "
                                   f"dataset is incomplete: rerun `tsel generate ... --resume`"))
        plan_ids = _plan_ids(out_dir, split)
        if plan_ids is not None and len(plan_ids) != n:
            rep.error(DatasetError(f"{split}: the plan (plan/{split}.jsonl) has {len(plan_ids)} scenes, the shards "
                                   f"{n}; rerun `tsel render {out_dir}` and `tsel finalize {out_dir}`"))
        start = 0
        for sh in shards:
            k = sh.get("scenes", 0)
            ids = plan_ids[start:start + k] if plan_ids is not None and len(plan_ids) == n else None
            jobs.append((out_dir, sh, ids, expect))
            start += k
            for key in ("file", "json"):
                p = os.path.join(out_dir, sh.get(key, ""))
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
    listed = {os.path.normpath(sh.get(key, "")) for s in splits.values() for sh in s.get("shards", [])
              for key in ("file", "json")}
    for split in splits:
        for p in sorted(glob.glob(os.path.join(out_dir, glob.escape(split), "*"))):
            rel = os.path.relpath(p, out_dir)
            if ".tmp-" in os.path.basename(p):
                rep.warnings.append(f"{rel}: leftover temporary file of an interrupted write; safe to delete")
            elif rel not in listed and p.endswith((".h5", ".json")):
                rep.warnings.append(f"{rel}: not listed in dataset.json; delete it or rerun `tsel finalize {out_dir}`")
    rep.facts["bytes"] = total_bytes
    return rep


def _report_unfinished(out_dir: str, rep: CheckReport) -> None:
    from .generate import load_plan, shard_complete, shard_tasks

    if not os.path.isfile(os.path.join(out_dir, "plan", "config.json")):
        rep.error(DatasetError(f"{out_dir}: not a dataset (no dataset.json and no plan); give the --out folder of "
                               f"`tsel generate`, or check a config with `tsel check --preset/--config`"))
        return
    try:
        cfg, plans = load_plan(out_dir)
    except (TselError, OSError, ValueError) as e:
        rep.error(DatasetError(f"{out_dir}: the plan is unreadable ({e}); plan again into a new --out"))
        return
    tasks = shard_tasks(cfg, plans)
    done = sum(shard_complete(out_dir, t) for t in tasks)
    rep.facts["splits"] = {s: {"scenes": len(p)} for s, p in plans.items()}
    rep.error(DatasetError(f"{out_dir}: unfinished dataset (no dataset.json): {done} of {len(tasks)} shards rendered; "
                           f"continue with `tsel generate ... --resume` or `tsel render {out_dir}` then "
                           f"`tsel finalize {out_dir}`"))


def _plan_ids(out_dir: str, split: str) -> list[str] | None:
    path = os.path.join(out_dir, "plan", f"{split}.jsonl")
    if not os.path.isfile(path):
        return None
    ids = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.strip():
                ids.append(json.loads(line)["scene_id"])
    return ids


def _check_shard(job) -> list[str]:
    """Problems of one shard (empty list when it is sound)."""
    import h5py

    from .store.writer import sha256_file

    out_dir, entry, plan_ids, expect = job
    h5_rel, js_rel = entry.get("file", "?"), entry.get("json", "?")
    h5_path, js_path = os.path.join(out_dir, h5_rel), os.path.join(out_dir, js_rel)
    fix = f"delete it and rerun `tsel render {out_dir}` and `tsel finalize {out_dir}`"
    problems = []
    for rel, path, key in ((h5_rel, h5_path, "sha256"), (js_rel, js_path, "json_sha256")):
        if not os.path.isfile(path):
            problems.append(f"{rel}: listed in dataset.json but missing; rerun `tsel render {out_dir}` and "
                            f"`tsel finalize {out_dir}`")
        elif entry.get(key) and sha256_file(path) != entry[key]:
            problems.append(f"{rel}: sha256 differs from dataset.json (the file changed or is corrupt); {fix}")
    if problems:
        return problems
    try:
        with open(js_path, encoding="utf-8") as f:
            js = json.load(f)["scenes"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        return [f"{js_rel}: unreadable shard JSON ({e}); {fix}"]
    try:
        with h5py.File(h5_path, "r") as h:
            return _compare_shard(h, js, entry, plan_ids, expect, h5_rel, fix)
    except (OSError, KeyError) as e:
        return [f"{h5_rel}: unreadable or incomplete HDF5 ({e}); {fix}"]


def _compare_shard(h, js: list, entry: dict, plan_ids, expect: dict, rel: str, fix: str) -> list[str]:
    n = entry.get("scenes")
    a = h["audio"]
    if a.ndim != 3 or a.shape[0] != n or a.shape[1] != expect["channels"] or a.shape[2] != expect["samples"]:
        return [f"{rel}: audio has shape {a.shape}, expected ({n}, {expect['channels']}, {expect['samples']}); {fix}"]
    if h.attrs.get("fs") != expect["fs"] or _s(h.attrs.get("format")) != expect["format"]:
        return [f"{rel}: fs/format attributes ({h.attrs.get('fs')}, {_s(h.attrs.get('format'))}) differ from "
                f"dataset.json ({expect['fs']}, {expect['format']}); {fix}"]
    ids = [_s(x) for x in h["scene_id"][()]]
    if len(js) != n or [s.get("scene_id") for s in js] != ids:
        return [f"{rel}: HDF5 scene ids differ from its JSON's ({len(ids)} vs {len(js)} scenes); {fix}"]
    if plan_ids is not None and ids != list(plan_ids):
        return [f"{rel}: holds scenes {ids[0]}..{ids[-1]} but the plan puts {plan_ids[0]}..{plan_ids[-1]} here; {fix}"]
    queries = [_s(x) for x in h["query"][()]]
    labels = {k: h[f"labels/{k}"][()] for k in ("azimuth", "elevation", "distance")}
    active = h["labels/active"][()]
    mics = h["mic_positions"][()]
    if labels["azimuth"].shape[2] != expect["frames"]:
        return [f"{rel}: labels have {labels['azimuth'].shape[2]} frames, expected {expect['frames']}; {fix}"]
    for i, scene in enumerate(js):
        sid = ids[i]
        if queries[i] != scene.get("query"):
            return [f"{rel}: scene {sid}: query differs between HDF5 and JSON; {fix}"]
        srcs = scene.get("sources", [])
        if len(srcs) > labels["azimuth"].shape[1]:
            return [f"{rel}: scene {sid}: JSON has {len(srcs)} sources, HDF5 room for {labels['azimuth'].shape[1]}; {fix}"]
        for k in range(labels["azimuth"].shape[1]):
            for key, arr in labels.items():
                got = arr[i, k]
                want = (np.array([np.nan if v is None else v for v in srcs[k][key]], dtype=np.float64)
                        if k < len(srcs) else np.full(got.shape, np.nan))
                if want.shape != got.shape or not np.allclose(got, want, atol=LABEL_ATOL, equal_nan=True):
                    return [f"{rel}: scene {sid} source {k}: {key} labels differ between HDF5 and JSON; {fix}"]
            want_act = srcs[k]["active"] if k < len(srcs) else [False] * active.shape[2]
            if active[i, k].tolist() != list(want_act):
                return [f"{rel}: scene {sid} source {k}: activity differs between HDF5 and JSON; {fix}"]
        jm = scene.get("array", {}).get("mic_positions")
        if jm is not None and not np.allclose(mics[i], np.asarray(jm, dtype=np.float64), atol=1e-5):
            return [f"{rel}: scene {sid}: mic positions differ between HDF5 and JSON; {fix}"]
        if expect["audio"]:
            x = a[i]
            if not np.all(np.isfinite(x)):
                return [f"{rel}: scene {sid}: audio holds NaN or Inf samples; {fix}"]
    return []


def _s(x) -> str:
    if isinstance(x, bytes):
        return x.decode("utf-8")
    if isinstance(x, np.ndarray) and x.shape == ():
        return _s(x.item())
    return x if x is None else str(x)


# --- raw config structure (wired in front of config.parse_config) ----------------------------


def check_raw_config(raw, where: str = "config") -> None:
    """Reject raw config data (TOML tables, ``--set`` values, dataset.json's config) whose
    *shape* the typed parser does not expect, with a one-line ConfigError naming the key:
    a config or ``splits`` that is not a table, keys with control characters (they would
    break the one-line messages), and numbers
    that are not finite (TOML allows ``inf`` and ``nan``) or larger than MAX_NUMBER
    (the seed excepted), which would overflow ratios such as duration / label_hop.
    Type and range checks of single fields stay in config.py.
    """
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: a config must be a table of sections, got {type(raw).__name__}")
    splits = raw.get("splits")
    if splits is not None and not isinstance(splits, dict):
        raise ConfigError(f"{where}: splits must be a table of [splits.NAME] with manifest and count, "
                          f"got {splits!r}")
    _finite(raw, where, "")


def _finite(x, where: str, key: str) -> None:
    if isinstance(x, dict):
        for k, v in x.items():
            if not isinstance(k, str) or any(ord(c) < 32 or ord(c) == 127 for c in k):
                shown = f"{key}.{k!r}" if key else repr(k)
                raise ConfigError(f"{where}: config key {shown} is not a plain name (control characters or not a "
                                  f"string); keys are names such as room.rt60")
            _finite(v, where, f"{key}.{k}" if key else str(k))
    elif isinstance(x, (list, tuple)):
        for v in x:
            _finite(v, where, key)
    elif isinstance(x, bool):
        return
    elif isinstance(x, (int, float)):
        key = key.encode("unicode_escape").decode("ascii")  # odd keys stay on one line
        try:
            ok = math.isfinite(float(x))
        except OverflowError:
            ok = False
        if not ok:
            raise ConfigError(f"{where}: {key or 'config'} = {x!r} is not a finite number; write a number "
                              f"within float range")
        if key != "seed" and abs(x) > MAX_NUMBER:
            # no physical quantity, count or rate here comes near; ratios of such numbers overflow
            raise ConfigError(f"{where}: {key} = {x!r} is out of range (|x| > {MAX_NUMBER:g}); check the value")
