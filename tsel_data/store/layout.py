"""Every path name of a dataset folder (docs/format.md, "Layout"), in one place.

    OUT/dataset.json            written last: its presence means the dataset is complete
    OUT/plan/config.json        the resolved config the plan was made with
    OUT/plan/{split}.jsonl      one scene recipe per line
    OUT/bad_clips.jsonl         clips skipped by the bad-clip policy
    OUT/missing_clips.json      clips whose audio file is absent (a partial download), per split
    OUT/{split}/shard-NNNNN.h5  audio and labels; .json: the same scenes' records;
                                .seal.json: what the shard was made from, and its checksums
    OUT/.tsel.lock              the dataset's lock; its presence marks the folder as ours
    OUT/demo-corpus/, OUT/demo-bank.h5   built-in demo inputs, built on first use

An export folder is marked by its manifest, ``.tsel-export.json`` (export/base.py), and
locked by ``.tsel-export.lock`` while an export writes into it (store/lock.py).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass

DATASET_FILE = "dataset.json"
PLAN_DIR = "plan"
CONFIG_FILE = f"{PLAN_DIR}/config.json"
BAD_CLIPS_FILE = "bad_clips.jsonl"
MISSING_CLIPS_FILE = "missing_clips.json"
DEMO_CORPUS_DIR = "demo-corpus"
DEMO_RECORDINGS_DIR = "demo-recordings"  # builtin:demo-recorded: the STARSS23 stand-in
DEMO_BANK_FILE = "demo-bank.h5"
LOCK_FILE = ".tsel.lock"
SEAL_SUFFIX = ".seal.json"
EXPORT_MANIFEST_FILE = ".tsel-export.json"
EXPORT_LOCK_FILE = ".tsel-export.lock"  # one export at a time into a folder (store/lock.py)
TOOL = "tsel-data"  # the "tool" of every JSON document that marks a folder as ours
NOISE_GROUP = "noise"  # HDF5 group of a shard's unlabelled noise: noise/KIND/{snr_db, level_dbfs}
DESCRIPTORS_GROUP = "descriptors"  # HDF5 group of the sources' acoustic descriptors (output.descriptors)
RECEIVERS_GROUP = "receivers"  # HDF5 group of a shard's further receivers: receivers/NAME/{audio, mic_positions}
HARDWARE_GROUP = "hardware"  # HDF5 group of the microphones as built ([hardware]): hardware/{gain_db, ...}


def shard_names(split: str, shard: int) -> tuple[str, str]:
    """Relative paths of shard ``shard`` of ``split``: (HDF5, JSON)."""
    stem = f"{split}/shard-{shard:05d}"
    return f"{stem}.h5", f"{stem}.json"


@dataclass(frozen=True)
class Layout:
    """The files of the dataset folder ``root``; properties are full paths."""

    root: str

    def path(self, rel: str) -> str:
        """A path relative to the dataset folder, made full."""
        return os.path.join(self.root, rel)

    @property
    def dataset_file(self) -> str:
        return self.path(DATASET_FILE)

    @property
    def plan_dir(self) -> str:
        return self.path(PLAN_DIR)

    @property
    def config_file(self) -> str:
        return self.path(CONFIG_FILE)

    def plan_file(self, split: str) -> str:
        return os.path.join(self.plan_dir, f"{split}.jsonl")

    @property
    def bad_clips_file(self) -> str:
        return self.path(BAD_CLIPS_FILE)

    @property
    def missing_clips_file(self) -> str:
        return self.path(MISSING_CLIPS_FILE)

    @property
    def demo_corpus(self) -> str:
        return self.path(DEMO_CORPUS_DIR)

    @property
    def demo_recordings(self) -> str:
        return self.path(DEMO_RECORDINGS_DIR)

    @property
    def demo_bank(self) -> str:
        return self.path(DEMO_BANK_FILE)

    def split_dir(self, split: str) -> str:
        return self.path(split)

    def shard_files(self, split: str, shard: int) -> tuple[str, str]:
        """Full paths of a shard's (HDF5, JSON) files."""
        h5, js = shard_names(split, shard)
        return self.path(h5), self.path(js)

    def seal_file(self, split: str, shard: int) -> str:
        """Full path of a shard's seal (store/integrity.py)."""
        return self.path(f"{split}/shard-{shard:05d}{SEAL_SUFFIX}")

    @property
    def lock_file(self) -> str:
        return self.path(LOCK_FILE)

    def is_ours(self) -> bool:
        """Whether the folder holds a tsel-data dataset (finished, planned, or started);
        another tool's ``dataset.json`` or ``plan/config.json`` does not make it one."""
        return os.path.exists(self.lock_file) or any(_is_tsel_doc(p) for p in (self.config_file, self.dataset_file))


def _is_tsel_doc(path: str) -> bool:
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and doc.get("tool") == TOOL
