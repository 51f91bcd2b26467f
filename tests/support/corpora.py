"""Tiny AudioCaps-format corpora, built in a test's folder: eight clips of decaying
noise bursts, never silent, one defect at a time where a test adds one."""
from __future__ import annotations

import csv
import os

import numpy as np
import soundfile as sf

FS = 24000
CAPTIONS = {
    "dogA": "a dog barks twice",
    "rainB": "rain falls on a metal roof",
    "carC": "an engine idles then revs",
    "bellD": "church bells ring slowly",
    "birdE": "small birds chirp in trees",
    "doorF": "wooden door creaks open",
    "waterG": "water pours into sink",
    "crowdH": "people chatter in hall",
}
SPLITS = {"train": ["dogA", "rainB", "carC", "bellD"], "val": ["birdE", "doorF"], "test": ["waterG", "crowdH"]}


def tone(seed: int, seconds: float = 1.5, channels: int = 1) -> np.ndarray:
    """A decaying noise burst train: [T] or [T, channels] float32, never silent."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    env = np.exp(-((np.arange(n) / FS) % 0.5) * 8.0)
    x = (0.3 * env * rng.standard_normal(n)).astype(np.float32)
    return x if channels == 1 else np.repeat(x[:, None], channels, axis=1)


def make_corpus(root, splits=SPLITS) -> str:
    """AudioCaps-format corpus: audio/{id}.wav + {split}.csv (header, one row per clip)."""
    root = str(root)
    os.makedirs(os.path.join(root, "audio"), exist_ok=True)
    k = 0
    for split, ids in splits.items():
        with open(os.path.join(root, f"{split}.csv"), "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["audiocap_id", "youtube_id", "start_time", "caption"])
            for cid in ids:
                k += 1
                w.writerow([str(100 + k), cid, "0", CAPTIONS[cid]])
                sf.write(os.path.join(root, "audio", f"{cid}.wav"), tone(k), FS)
    return root
