"""What ``corpus.fingerprint = "hash"`` costs on ``--resume``, against ``"stat"``.

    .venv/bin/python benchmarks/bench_fingerprint.py [--repeats 5] [--workers 2]

The demo corpus (``tsel corpus synth``: 15 sound types, 90 clips) and two datasets of the
``demo`` preset made from it, one per fingerprint. Then, interleaved ``--repeats``
times, a resume of each finished dataset (``render_shards`` on a complete folder: the
plan read, every shard's inputs stat-ed or hashed, each shard's fingerprint against its
seal; nothing rendered), wall and CPU seconds, median; and the ratio hash / stat. The
clips are in the page cache (read once by the renders): what a resume right after an
interruption costs. A cold cache adds reading the corpus from disk once.
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.job.pipeline import generate, render_shards  # noqa: E402


def corpus_bytes(folder: str) -> int:
    return sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(folder) for f in fs if f.endswith(".wav"))


def resume_once(out: str) -> tuple[float, float]:
    t0, c0 = time.perf_counter(), time.process_time()
    done = render_shards(out, progress=False)
    assert not any(done.values()), done  # a finished dataset: nothing to render
    return time.perf_counter() - t0, time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    root = tempfile.mkdtemp(prefix="tsel-bench-fingerprint-")
    try:
        corpus = os.path.join(root, "corpus")
        synth_corpus(corpus)
        outs, renders = {}, {}
        for mode in ("stat", "hash"):
            cfg = load_config(preset="demo", corpus_dir=corpus, overrides=[f'corpus.fingerprint="{mode}"'])
            outs[mode] = os.path.join(root, mode)
            t0 = time.perf_counter()
            generate(cfg, outs[mode], workers=args.workers, progress=False)
            renders[mode] = time.perf_counter() - t0
        scenes = sum(sp.count for sp in cfg.splits.values())
        print(f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; demo corpus: "
              f"{corpus_bytes(corpus) / 1e6:.1f} MB of WAV; demo preset: {scenes} scenes, "
              f"generate {renders['stat']:.1f} s (stat) / {renders['hash']:.1f} s (hash), {args.workers} workers\n")
        times = {m: [] for m in outs}
        for _ in range(args.repeats):
            for mode, out in outs.items():  # interleaved: both see the same machine
                times[mode].append(resume_once(out))
        med = {m: (statistics.median(w for w, _ in t), statistics.median(c for _, c in t)) for m, t in times.items()}
        print(f"{'fingerprint':>12} {'resume check s':>15} {'CPU s':>8}   (median of {args.repeats})")
        for mode, (wall, cpu) in med.items():
            print(f"{mode:>12} {wall:15.3f} {cpu:8.3f}")
        print(f"\nhash / stat: {med['hash'][0] / med['stat'][0]:.2f}x wall, {med['hash'][1] / med['stat'][1]:.2f}x CPU; "
              f"the hash resume check is {100 * med['hash'][0] / renders['hash']:.1f} % of the generate")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
