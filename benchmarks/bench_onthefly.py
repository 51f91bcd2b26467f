"""On-the-fly scenes for trainers against reading the same scenes from shards, same run.

    .venv/bin/python benchmarks/bench_onthefly.py [--scenes 32] [--preset demo]

Needs torch (``pip install -e '.[baseline]'``). Generates ``--scenes`` scenes of the
preset (10 s, 24 kHz, on the built-in demo corpus) into a temporary dataset, then feeds
the same scenes through ``tsel_data.tools.torch.Dataset`` + ``DataLoader`` (batch 8), once
rendered on the fly (``tsel_data.job.onthefly.SceneSource``) and once read from the shards
(the baseline), with 1 and 2 DataLoader workers. Prints scenes/s and the ratio
on-the-fly / shards. Each loader is iterated once to warm up (worker start-up, page
cache) before the timed pass.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

try:
    import torch
except ImportError:
    sys.exit("bench_onthefly needs torch: pip install -e '.[baseline]'")

from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.job.onthefly import SceneSource  # noqa: E402
from tsel_data.job.pipeline import generate  # noqa: E402
from tsel_data.tools.torch import Dataset, collate, worker_init_fn  # noqa: E402


def rate(dataset, workers: int) -> float:
    """Scenes per second through a DataLoader, after one warm-up pass."""
    loader = torch.utils.data.DataLoader(dataset, batch_size=8, num_workers=workers, collate_fn=collate,
                                         worker_init_fn=worker_init_fn, persistent_workers=True)
    for _ in loader:
        pass
    t0 = time.perf_counter()
    n = sum(len(b["scene_id"]) for b in loader)
    return n / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=32)
    ap.add_argument("--preset", default="demo")
    args = ap.parse_args()
    root = tempfile.mkdtemp(prefix="tsel-bench-otf-")
    try:
        corpus = os.path.join(root, "corpus")
        synth_corpus(corpus)
        cfg = load_config(preset=args.preset, corpus_dir=corpus, splits={"train": args.scenes, "val": 0, "test": 0})
        out = os.path.join(root, "out")
        generate(cfg, out, workers=2, progress=False)
        source = SceneSource(cfg, "train", home=out)
        print(f"{os.cpu_count()} cores; {args.scenes} scenes of preset {args.preset} "
              f"({cfg.audio.duration:g} s, {cfg.audio.fs} Hz, {cfg.scene.format})\n")
        print(f"{'DataLoader workers':>18} {'shards scenes/s':>16} {'on the fly scenes/s':>20} {'ratio':>7}")
        for workers in (1, 2):
            shards = rate(Dataset(out, "train"), workers)
            fly = rate(Dataset(source), workers)
            print(f"{workers:>18} {shards:16.1f} {fly:20.2f} {fly / shards:7.3f}", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
