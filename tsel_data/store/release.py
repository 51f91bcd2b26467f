"""Recipe releases: a dataset published as its plan and per-scene checksums, no audio
(docs/format.md, "Recipe releases"). ``tsel export recipes`` writes one; ``tsel generate
--from`` rebuilds the dataset from it; ``tsel check DIR --release REL`` holds a dataset
against it. This module is the format: its paths, the checksums, reading and comparing.

    REL/
      release.json            what the release is: splits, their files, the inputs, the checksum definitions
      dataset.json            the dataset's, as it was
      plan/config.json        the plan's config (roots as the dataset stored them)
      plan/{split}.jsonl      one recipe per line
      checksums/{split}.jsonl one line per scene: scene_id, index, audio, labels, record (sha256), clips
      clips.jsonl             one line per clip the plan reads: audio (relative to the corpus), clip_id,
                              sha256, bytes, captions, splits, scenes
      README.md               the dataset card

A rebuilt dataset says how it went in ``rebuild.json`` (:data:`REBUILD_FILE`).
"""
from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass, field

import numpy as np

from ..core.files import check_input, name_problem
from ..core.jsonable import JsonFields, key
from ..core.report import CheckReport
from ..core.version import __version__
from ..errors import DatasetError
from ..scene.recipe import recipe_from_line
from ..choices import SPLIT_NAME
from .layout import CONFIG_FILE, DATASET_FILE, PLAN_DIR, Layout
from .plans import read_plan_doc, read_plan_lines, seal_problem
from .reader import list_splits, open_dataset

RELEASE_FILE = "release.json"
CLIPS_FILE = "clips.jsonl"
CHECKSUM_DIR = "checksums"
REBUILD_FILE = "rebuild.json"
RELEASE_KIND = "tsel-data recipe release"
RELEASE_VERSION = 1
PARTS = ("audio", "labels", "record")
DIGESTS = {
    "audio": "sha256 of 'C,T' then the float32 [C, T] samples the reader returns, little-endian, C order",
    "labels": "sha256 of the query (UTF-8), a NUL byte, then azimuth, elevation, distance (float32, NaN as the "
              "quiet NaN 0x7fc00000), active (uint8), each [S, F], and mic_positions float32 [C, 3]",
    "record": "sha256 of the scene's JSON record with sorted keys, no spaces, UTF-8",
}
CANONICAL_NAN = np.float32(np.nan)


def checksums_file(split: str) -> str:
    return f"{CHECKSUM_DIR}/{split}.jsonl"


def plan_file(split: str) -> str:
    return f"{PLAN_DIR}/{split}.jsonl"


def _sha(*chunks) -> str:
    h = hashlib.sha256()
    for c in chunks:
        h.update(c)
    return h.hexdigest()


def _f32(a) -> bytes:
    a = np.asarray(a, dtype="<f4")
    return np.where(np.isnan(a), CANONICAL_NAN, a).astype("<f4").tobytes()


def scene_digest(scene) -> dict:
    """{"audio", "labels", "record"}: sha256 of a scene's parts (:data:`DIGESTS`)."""
    audio = np.ascontiguousarray(scene.audio, dtype="<f4")
    labels = _sha(scene.query.encode("utf-8"), b"\0", _f32(scene.azimuth), _f32(scene.elevation),
                  _f32(scene.distance), np.asarray(scene.active, dtype=np.uint8).tobytes(), _f32(scene.mic_positions))
    record = "" if scene.record is None else _sha(json.dumps(scene.record.to_json(), sort_keys=True,
                                                             separators=(",", ":"), ensure_ascii=False).encode())
    return {"audio": _sha(f"{audio.shape[0]},{audio.shape[1]}".encode(), audio.tobytes()), "labels": labels,
            "record": record}


def differing_parts(want: dict, got: dict) -> list[str]:
    """The parts (:data:`PARTS`) whose checksums differ."""
    return [p for p in PARTS if want.get(p) != got.get(p)]


@dataclass(frozen=True)
class ClipEntry(JsonFields):
    """One line of ``clips.jsonl``: a file the plan reads, relative to the corpus."""

    audio: str
    clip_id: str
    sha256: str
    bytes: int
    captions: list = key(default_factory=list)
    splits: list = key(default_factory=list)
    scenes: int = 0


@dataclass(frozen=True)
class ChecksumEntry(JsonFields):
    """One line of ``checksums/{split}.jsonl``: a scene's checksums (:data:`DIGESTS`) and
    the files it reads."""

    scene_id: str
    index: int
    audio: str
    labels: str
    record: str
    clips: list = key(default_factory=list)


_HEX64 = re.compile(r"[0-9a-f]{64}")


@dataclass(frozen=True)
class Release:
    """A recipe release folder, read and checked whole (:func:`load_release`): ``doc``
    (release.json), ``plan_doc`` (plan/config.json), and each split's recipe lines,
    checksums and the clips they read."""

    root: str
    doc: dict
    plan_doc: dict
    lines: dict = field(default_factory=dict)  # split -> [recipe line]
    sums: dict = field(default_factory=dict)  # split -> {scene_id: checksum row}
    clip_rows: dict = field(default_factory=dict)  # audio name -> clip row

    @property
    def splits(self) -> list[str]:
        return list(self.doc["splits"])

    def path(self, rel: str) -> str:
        return os.path.join(self.root, rel)

    def recipe_lines(self, split: str) -> list[str]:
        return list(self.lines[split])

    def checksums(self, split: str) -> dict:
        """{scene_id: {"index", "audio", "labels", "record", "clips"}} in plan order."""
        return dict(self.sums[split])

    def clips(self) -> dict:
        """{audio name: {"clip_id", "sha256", "bytes", "captions", "splits", "scenes"}}."""
        return dict(self.clip_rows)


def _damaged(path: str, why: str) -> DatasetError:
    return DatasetError(f"{path}: {why}; the release was edited or damaged: download or export it again")


def _jsonl(path: str, entry) -> list:
    """The lines of a release's JSONL file, each checked as an ``entry`` (its keys, their
    JSON types) before anything reads it."""
    check_input(path, DatasetError, "the release is damaged: download or export it again")
    out = []
    n = 0
    try:
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                if line.strip():
                    row = json.loads(line)
                    entry.from_json(row)
                    out.append(row)
    except OSError as e:
        raise DatasetError(f"{path}: cannot read ({e.strerror or e}); the release is incomplete") from None
    except (ValueError, TypeError, RecursionError) as e:
        raise _damaged(f"{path}:{n}", f"damaged line ({e})") from None
    return out


def load_release(root: str) -> Release:
    """Read a release folder and check it whole before anything is done with it
    (DatasetError in one line): release.json's kind, version and splits; the plan's seal
    (a recipe or the config edited since the release was made is named as such); every
    recipe line, checksum row and clip row, their keys and types; names that stay inside
    the corpus; every scene with its checksums, every file a recipe reads listed."""
    root = os.fspath(root)
    path = os.path.join(root, RELEASE_FILE)
    check_input(root, DatasetError, "a release is the folder `tsel export recipes` wrote", folder=True)
    check_input(path, DatasetError, "the release is damaged: download or export it again")
    if not os.path.isfile(path):
        raise DatasetError(f"{path} not found: {root} is not a recipe release (`tsel export recipes DIR --out "
                           f"{root}` makes one)")
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, ValueError, RecursionError) as e:
        raise DatasetError(f"{root}: the release is damaged or incomplete ({e}); export it again") from None
    if not isinstance(doc, dict) or not str(doc.get("kind", "")).startswith(RELEASE_KIND):
        raise DatasetError(f"{path} is not a tsel-data recipe release")
    version = doc.get("release_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise _damaged(path, f"release_version is {version!r}, not a whole number")
    if version > RELEASE_VERSION or doc["kind"] != RELEASE_KIND:
        what = f"release version {version}" if version > RELEASE_VERSION else f"a {doc['kind']!r}"
        raise DatasetError(f"{path} is {what} (made by tsel-data {doc.get('version', '?')}), which this tsel-data "
                           f"({__version__}, release version {RELEASE_VERSION}) does not read; update tsel-data: pip "
                           f"install -U tsel-data")
    splits = doc.get("splits")
    if not isinstance(splits, dict) or not splits:
        raise _damaged(path, "it lists no splits")
    for split in splits:
        if not SPLIT_NAME.fullmatch(split):
            raise _damaged(path, f"split {split!r} is not a plain name")
    layout = Layout(root)
    again = "the release is incomplete or damaged: export it again"
    plan_doc = read_plan_doc(layout, remedy=(again, again))
    problem = seal_problem(layout, plan_doc, splits=list(splits), edited="after the release was made")
    if problem:
        raise DatasetError(f"{problem}; the release was edited: its recipes are not the ones its checksums hold, "
                           f"download or export it again")
    lines, sums = {}, {}
    for split in splits:
        lines[split] = read_plan_lines(layout, split)
        ids = []
        for n, line in enumerate(lines[split], 1):
            ids.append(recipe_from_line(layout.plan_file(split), n, line).scene_id)
        rows = _jsonl(os.path.join(root, checksums_file(split)), ChecksumEntry)
        sums[split] = {r["scene_id"]: r for r in rows}
        bad = next((r for r in rows if not all(_HEX64.fullmatch(r[p]) or (p == "record" and not r[p])
                                               for p in PARTS)), None)
        if bad is not None:
            raise _damaged(os.path.join(root, checksums_file(split)), f"scene {bad['scene_id']}: a checksum is not "
                                                                      f"64 hex digits")
        if list(sums[split]) != ids:
            lost = next((i for i in ids if i not in sums[split]), None) or next(i for i in sums[split] if i not in ids)
            raise _damaged(os.path.join(root, checksums_file(split)),
                           f"its scenes are not those of {plan_file(split)} ({len(rows)} checksum rows, {len(ids)} "
                           f"recipes; e.g. {lost})")
    clip_rows = {}
    for row in _jsonl(os.path.join(root, CLIPS_FILE), ClipEntry):
        why = name_problem(row["audio"])
        if why or not _HEX64.fullmatch(row["sha256"]) or row["bytes"] < 0:
            raise _damaged(os.path.join(root, CLIPS_FILE), f"clip {row['audio']!r}: " + (
                f"the name {why}" if why else "its sha256 or size is not one"))
        clip_rows[row["audio"]] = row
    for split in splits:
        for r in sums[split].values():
            unlisted = [c for c in r["clips"] if c not in clip_rows]
            if unlisted:
                raise _damaged(os.path.join(root, CLIPS_FILE), f"it does not list {unlisted[0]}, which scene "
                                                               f"{r['scene_id']} reads")
    return Release(root, doc, plan_doc, lines, sums, clip_rows)


def read_rebuild_report(root: str) -> dict | None:
    """``rebuild.json`` of a dataset rebuilt from a release (None when absent)."""
    try:
        with open(os.path.join(root, REBUILD_FILE), encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def check_against_release(root: str, release_dir: str) -> CheckReport:
    """Hold the dataset ``root`` against a release, scene by scene: each scene's audio,
    labels and record against the release's checksums. A scene that differs, or that
    the dataset lacks without its rebuild report saying why, is an error; a scene left
    out or substituted by the rebuild (a clip was missing) is a warning."""
    rep = CheckReport(f"dataset {root} against release {release_dir}")
    try:
        rel = load_release(release_dir)
        have = list_splits(root)
    except DatasetError as e:
        rep.error(e)
        return rep
    known = {s["scene_id"]: s for s in (read_rebuild_report(root) or {}).get("scenes", [])}
    rep.facts["splits"] = {}
    for split in rel.splits:
        want = rel.checksums(split)
        counts = {"identical": 0, "differs": 0, "absent": 0}
        got = {}
        if split in have:
            with open_dataset(root, split) as ds:
                for scene in ds:
                    got[scene.scene_id] = scene_digest(scene)
        for sid, digest in want.items():
            note = known.get(sid, {})
            if sid not in got:
                counts["absent"] += 1
                if note.get("status") == "not-buildable":
                    rep.warnings.append(f"{sid}: not in the dataset ({note.get('why', 'a clip is missing')})")
                else:
                    rep.error(f"{sid}: in the release but not in {root}", DatasetError)
                continue
            parts = differing_parts(digest, got[sid])
            if not parts:
                counts["identical"] += 1
            elif note.get("status") == "substituted":
                counts["differs"] += 1
                rep.warnings.append(f"{sid}: differs ({', '.join(parts)}) as expected: {note.get('why', '')}")
            else:
                counts["differs"] += 1
                rep.error(f"{sid}: differs from the release ({', '.join(parts)})"
                          + (f": {note['why']}" if note.get("why") else ""), DatasetError)
        extra = sorted(set(got) - set(want))
        if extra:
            rep.error(f"{split}: {len(extra)} scene(s) not in the release, e.g. {extra[0]}", DatasetError)
        rep.facts["splits"][split] = {"scenes": len(want), **counts}
    return rep


def release_summary_lines(rep: CheckReport) -> list[str]:
    """The per-split counts of :func:`check_against_release`."""
    out = [f"{rep.target}: {'OK' if rep.ok else f'{len(rep.errors)} problem(s)'}"]
    for split, s in rep.facts.get("splits", {}).items():
        out.append(f"  {split}: {s['identical']} of {s['scenes']} scenes bit-identical, {s['differs']} differ, "
                   f"{s['absent']} absent")
    return out


# files a release copies from the dataset as they are
COPIED = (DATASET_FILE, CONFIG_FILE)
