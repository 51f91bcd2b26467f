"""A dataset folder's plan: ``plan/config.json``, ``plan/{split}.jsonl``, and which
shards it asks for.

Shard *k* of a split holds that split's scenes ``k·shard_size … (k+1)·shard_size − 1``.
These functions read plain data; parsing the stored config into a ``Config`` is the
pipeline's job (the store does not depend on the config layer).
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass

from ..core.digest import sha256_file
from ..core.files import check_input
from ..core.version import __version__
from ..errors import DatasetError
from ..receivers import canonical, receiver
from ..scene.recipe import SceneRecipe, read_plan
from .dataset import DatasetDoc, ShardEntry
from .layout import CONFIG_FILE, Layout, shard_names


@dataclass(frozen=True)
class ShardTask:
    """Shard ``shard`` of ``split``: the split's scenes ``start`` .. ``stop - 1``."""

    split: str
    shard: int
    start: int
    stop: int

    @property
    def files(self) -> tuple[str, str]:
        """(HDF5, JSON) paths relative to the dataset folder."""
        return shard_names(self.split, self.shard)


def shard_tasks(counts: dict[str, int], shard_size: int) -> list[ShardTask]:
    """Every shard of a plan with ``counts`` scenes per split, split by split in order."""
    tasks = []
    for split, n in counts.items():
        for k, start in enumerate(range(0, n, shard_size)):
            tasks.append(ShardTask(split, k, start, min(start + shard_size, n)))
    return tasks


def shard_sealed(layout: Layout, task: ShardTask) -> bool:
    """The shard was written to the end (its files and its seal, written last, exist). Whether it is
    the shard the plan asks for is :func:`~tsel_data.store.integrity.shard_state`'s question."""
    return all(os.path.isfile(p) for p in (*layout.shard_files(task.split, task.shard),
                                           layout.seal_file(task.split, task.shard)))


def plan_doc(config: dict, clips: dict[str, int], bad_clips: int, missing_clips: dict[str, int] | None = None,
             plans: dict[str, list[str]] | None = None) -> dict:
    """The document of ``plan/config.json``: tool, version, the resolved config as plain
    data, usable clips per split, the number of bad clips and, when audio files are
    missing, how many per split; and the plan's seal (:func:`plan_seal`) of the recipe
    lines ``plans`` ({split: lines}) written beside it."""
    doc = {"tool": "tsel-data", "version": __version__, "config": config, "clips": clips, "bad_clips": bad_clips}
    if missing_clips:
        doc["missing_clips"] = missing_clips
    if plans is not None:
        doc["seal"] = plan_seal(config, plans)
    return doc


def plan_seal(config: dict, plans: dict[str, list[str]]) -> dict:
    """What the plan was when it was written: the digest of its config (roots left out: a
    dataset and its inputs may move) and the size and sha256 of each plan file."""
    files = {}
    for split, lines in plans.items():
        data = "".join(line + "\n" for line in lines).encode("utf-8")
        files[split] = {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    return {"config_sha256": config_digest(config), "files": files}


def config_digest(config: dict) -> str:
    """sha256 of a config (plain data) without its roots (:data:`ROOT_KEYS`)."""
    rootless = _map_roots(config, lambda v: "")
    return hashlib.sha256(json.dumps(rootless, sort_keys=True, separators=(",", ":")).encode("utf-8")).hexdigest()


def seal_problem(layout: Layout, doc: dict, splits=None, deep: bool = True, edited: str = "") -> str:
    """What no longer matches the plan's seal in ``plan/config.json`` (``doc``): its
    config, or a plan file (of ``splits``, default all; ``deep``: by sha256, else by size
    only, for a job-array task that reads a few lines of a large plan). "" when all
    match, or for a plan written before plans were sealed. ``edited``: when the plan
    files were last written on purpose ("after the release was made"; default: after
    planning, or by a --grow that stopped)."""
    seal = doc.get("seal")
    if not isinstance(seal, dict):
        return ""
    if seal.get("config_sha256") != config_digest(doc["config"]):
        return (f"{layout.config_file}: its config was edited {edited or 'after planning'} (it no longer matches its "
                f"seal)")
    files = seal.get("files") if isinstance(seal.get("files"), dict) else {}
    for split in files if splits is None else splits:
        want, path = files.get(split) if isinstance(files.get(split), dict) else {}, layout.plan_file(split)
        try:
            check_input(path, DatasetError)
            size = os.path.getsize(path)
            if size != want.get("bytes") or (deep and sha256_file(path) != want.get("sha256")):
                # a --grow writes the plan files first and plan/config.json (the seal) last
                return (f"{path} was edited {edited} (it no longer matches the seal in {CONFIG_FILE})" if edited else
                        f"{path} was edited after planning, or a --grow stopped before it finished (it no longer "
                        f"matches the seal in {CONFIG_FILE})")
        except OSError as e:
            return f"{path}: cannot read ({e.strerror or e})"
        except DatasetError as e:
            return str(e)
    return ""


# config keys that name files outside the dataset (the roots of its relative paths)
ROOT_KEYS = ("corpus.dir", "room.bank", "corpus.caption_embeddings", "array.hrtf")


def _map_roots(config: dict, fn) -> dict:
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in config.items()}
    for key in ROOT_KEYS:
        sec, name = key.split(".")
        value = (out.get(sec) or {}).get(name)
        if isinstance(value, str) and value and not value.startswith("builtin:"):
            out[sec][name] = fn(value)
    return out


def portable_roots(config: dict, root: str) -> dict:
    """``config`` (plain data) with its roots (:data:`ROOT_KEYS`) relative to the dataset
    folder ``root``, as files store them: a dataset moved together with its corpus needs
    nothing, and no absolute path of the machine it was made on is written."""
    # real paths: a dataset reached through a symlink resolves its roots from where it
    # really is, however it is named later
    base = os.path.realpath(root)
    return _map_roots(config, lambda v: os.path.relpath(os.path.realpath(os.path.expanduser(v)), base)
                      .replace(os.sep, "/"))


def local_roots(config: dict, root: str) -> dict:
    """The inverse of :func:`portable_roots`: roots as paths on this machine."""
    base = os.path.realpath(root)
    return _map_roots(config, lambda v: os.path.normpath(os.path.join(base, os.path.expanduser(v))))


def has_plan(layout: Layout) -> bool:
    return os.path.isfile(layout.config_file)


PLAN_AGAIN = ("run `tsel plan` or `tsel generate` first", "plan again into a new --out")


def read_plan_doc(layout: Layout, remedy: tuple[str, str] = PLAN_AGAIN) -> dict:
    """``plan/config.json`` (written last by the plan stage): tool, version, the resolved
    ``config`` as plain data, clip counts. ``remedy``: what the error line advises when
    the file is missing, and when it is damaged (a recipe release says "export it again")."""
    path = layout.config_file
    check_input(path, DatasetError, remedy[1])
    if not os.path.isfile(path):
        raise DatasetError(f"{layout.root} has no plan ({CONFIG_FILE} missing); {remedy[0]}")
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (ValueError, RecursionError) as e:  # not JSON, not UTF-8, nested thousands deep
        raise DatasetError(f"{path} is damaged ({e}); {remedy[1]}") from None
    except OSError as e:
        raise DatasetError(f"{path}: cannot read ({e.strerror or e}); {remedy[1]}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("config"), dict):
        raise DatasetError(f"{path} holds no config; {remedy[1]}")
    return doc


def stored_config(layout: Layout) -> dict | None:
    """The config a folder was planned with (plain data, roots as paths here), as it was
    asked: a recorded plan's split counts are the caps asked (``recorded.asked``), not the
    scenes planned. None when the folder holds no readable plan."""
    try:
        doc = read_plan_doc(layout) if has_plan(layout) else None
    except DatasetError:
        return None
    if doc is None:
        return None
    config = local_roots(doc["config"], layout.root)
    for split, summary in (doc.get("recorded") or {}).items():
        if isinstance(summary, dict) and split in (config.get("splits") or {}) and "asked" in summary:
            config["splits"][split] = {**config["splits"][split], "count": summary["asked"]}
    return config


def read_split_plan(layout: Layout, split: str) -> list[SceneRecipe]:
    """Every recipe of a split's plan file."""
    return read_plan(layout.plan_file(split))


def read_plan_lines(layout: Layout, split: str) -> list[str]:
    """The recipe lines of a split's plan file as written (none when there is no file)."""
    path = layout.plan_file(split)
    check_input(path, DatasetError, "plan again into a new --out")
    if not os.path.isfile(path):
        return []
    with open(path, encoding="utf-8") as f:
        return [line.rstrip("\n") for line in f if line.strip()]


def read_plan_range(layout: Layout, split: str, start: int, stop: int, block: int = 1 << 22) -> list[str]:
    """Lines ``start`` .. ``stop - 1`` of a split's plan file (fewer when the file is
    shorter), read in blocks: a job-array task of a 100k-scene plan reads what it needs,
    without holding or parsing the rest."""
    out: list[str] = []
    line, tail = 0, b""
    check_input(layout.plan_file(split), DatasetError, "plan again into a new --out")
    try:
        f = open(layout.plan_file(split), "rb")
    except OSError as e:
        raise DatasetError(f"{layout.plan_file(split)}: cannot read the plan ({e.strerror or e}); plan again into "
                           f"a new --out") from None
    with f:
        while line < stop:
            data = f.read(block)
            if not data:
                break
            data = tail + data
            cut = data.rfind(b"\n") + 1
            whole, tail = data[:cut], data[cut:]
            n = whole.count(b"\n")
            if line + n <= start:  # nothing wanted in this block: count its lines only
                line += n
                continue
            for raw in whole.split(b"\n")[:-1]:
                if start <= line < stop:
                    out.append(raw.decode("utf-8"))
                line += 1
        if tail.strip() and start <= line < stop:  # a last line without its newline
            out.append(tail.decode("utf-8"))
    return out


def plan_ids(layout: Layout, split: str) -> list[str] | None:
    """The scene ids of a split's plan file, in order (None when there is no such file)."""
    path = layout.plan_file(split)
    check_input(path, DatasetError, "plan again into a new --out")
    if not os.path.isfile(path):
        return None
    ids = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for n, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                ids.append(str(json.loads(line)["scene_id"]))
            except (ValueError, KeyError, TypeError):
                raise DatasetError(f"{path}:{n}: a damaged plan line (not a scene recipe); the plan was edited or "
                                   f"cut short: plan again into a new --out") from None
    return ids


def unfinished_doc(layout: Layout) -> DatasetDoc:
    """A :class:`~tsel_data.store.dataset.DatasetDoc` of the shards finished so far, for
    a dataset still being made (a plan, no ``dataset.json``): every shard whose two files
    exist under their final names (the writer renames them last), with the index of its
    first scene, so tools can read them while the rest renders."""
    doc = read_plan_doc(layout)
    cfg = doc["config"]
    try:
        size = int(cfg["output"]["shard_size"])
        counts = {s: int(v.get("count", 0)) for s, v in cfg["splits"].items() if v.get("count")}
        fs, hop, fmt = int(cfg["audio"]["fs"]), float(cfg["audio"]["label_hop"]), str(cfg["scene"]["format"])
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise DatasetError(f"{layout.config_file} is incomplete ({type(e).__name__}: {e}); plan again into a new "
                           f"--out") from None
    tasks = shard_tasks(counts, size)
    splits: dict[str, list[ShardEntry]] = {s: [] for s in counts}
    for t in tasks:
        if shard_sealed(layout, t):
            h5, js = t.files
            splits[t.split].append(ShardEntry(h5, js, t.stop - t.start, first=t.start))
    return DatasetDoc(path=layout.config_file, fs=fs, label_hop=hop, format=fmt,
                      channel_names=_channel_names(cfg, fmt), config=cfg, splits=splits,
                      counts={s: sum(e.scenes for e in v) for s, v in splits.items()},
                      receivers={r: list(receiver(r).channels(n=len((cfg.get("array") or {}).get("capsules") or ())))
                                 for r in (cfg.get("scene") or {}).get("receivers") or () if canonical(r)},
                      raw={"seed": cfg.get("seed", 0), "config": cfg}, finished=False, planned=counts,
                      shards_planned=len(tasks))


def _channel_names(cfg: dict, fmt: str) -> list:
    """The receiver's channel names from a plan's config (a custom array's follow its capsules)."""
    if canonical(fmt) is None:
        return []
    caps = (cfg.get("array") or {}).get("capsules") or ()
    return list(receiver(fmt).channels(n=len(caps)))
