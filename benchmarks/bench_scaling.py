"""End-to-end scaling: scenes/hour/core per format, storage per 1,000 scenes, 1 -> 2 workers.

    .venv/bin/python benchmarks/bench_scaling.py [--scenes 32] [--workers 2]

Runs the real job (`tsel_data.job.pipeline.generate`: plan, render, shards on disk,
dataset.json) on the built-in demo corpus, 10 s 24 kHz 2-source scenes, for each setting
below, once with 1 worker (the baseline, measured in the same run) and once with N.
Prints one row per setting; docs/scaling.md quotes its output.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.job.pipeline import generate, plan_dataset  # noqa: E402

SETTINGS = {
    "mic4, paper rooms (hybrid)": ("paper-sim-2dir", []),
    "mic4, realistic rooms (hybrid)": ("realistic-sim", []),
    "foa, paper rooms (hybrid)": ("paper-sim-2dir", ['scene.format="foa"']),
    "foa bank, static+moving": ("demo-moving", []),
}


def run(preset, overrides, corpus, scenes, workers, root, bank):
    if bank:
        overrides = overrides + [f'room.bank="{bank}"']
    cfg = load_config(preset=preset, corpus_dir=corpus, overrides=overrides + ["output.shard_size=8"],
                      splits={"train": scenes, "val": 0, "test": 0})
    out = tempfile.mkdtemp(dir=root)
    plan_dataset(cfg, out, workers=1)  # planning is not what we measure here
    t0 = time.perf_counter()
    generate(cfg, out, workers=workers, resume=True, progress=False)
    dt = time.perf_counter() - t0
    size = sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(os.path.join(out, "train")) for f in fs)
    shutil.rmtree(out)
    return dt, size


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=32)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    root = tempfile.mkdtemp(prefix="tsel-bench-")
    corpus = os.path.join(root, "corpus")
    synth_corpus(corpus)
    bank = None
    try:
        from tsel_data.banks.scenes import resolve_bank
        from tsel_data.plan.sampler import bank_request
        from tsel_data.store.layout import Layout

        # builds the demo bank once
        bank = resolve_bank(bank_request(load_config(preset="demo-moving", corpus_dir=corpus)), Layout(root).demo_bank)
        print(f"{os.cpu_count()} cores; {args.scenes} scenes of 10 s per run; 1 vs {args.workers} workers\n")
        print(f"{'setting':34} {'1 worker s/scene':>17} {'scenes/h/core':>14} {'MB/1000 scenes':>15} "
              f"{f'{args.workers} workers':>10} {'speed-up':>9}")
        for name, (preset, ov) in SETTINGS.items():
            b = bank if preset == "demo-moving" else None
            t1, size = run(preset, ov, corpus, args.scenes, 1, root, b)
            tn, _ = run(preset, ov, corpus, args.scenes, args.workers, root, b)
            print(f"{name:34} {t1 / args.scenes:17.3f} {3600 * args.scenes / t1:14.0f} "
                  f"{size / args.scenes * 1000 / 1e6:15.0f} {tn:9.1f}s {t1 / tn:8.2f}x", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
