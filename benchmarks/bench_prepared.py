"""Real corpora at the cost of prepared ones: what ``corpus.prepare_on_check`` buys and costs.

    .venv/bin/python benchmarks/bench_prepared.py [--scenes 16] [--repeats 3]

The demo corpus rewritten as 44.1 kHz stereo 24-bit WAV (as real downloads come), in a
temporary folder. Measured in one run, one process:

1. **the full clip check** of every clip (``corpus.check = "full"``, nothing remembered)
   with ``corpus.prepare_on_check`` false and true: the second also writes each clip's
   prepared form from the same decode (and hashes the clip for its record);
2. **a scene** (``render_scene``, demo preset, 10 s, the clip cache emptied before each
   scene, as with a large corpus), interleaved ``--repeats`` times, median: from the
   24 kHz mono demo clips (the baseline), from the 44.1 kHz stereo clips decoded and
   resampled, and from the prepared forms the check wrote (each read back hashed and
   checked against its record).
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time

import numpy as np
import soundfile as sf

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

os.environ["TSEL_CACHE_DIR"] = "off"  # every clip check decodes

from tsel_data.corpus import audio  # noqa: E402
from tsel_data.plan.catalog import check_clips, read_split_clips, split_audio_dir  # noqa: E402
from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.plan.sampler import plan_scene, prepare_views  # noqa: E402
from tsel_data.corpus.prepared import CACHE_ENV  # noqa: E402
from tsel_data.render.mix import render_scene  # noqa: E402
from tsel_data.store.layout import Layout  # noqa: E402


def stereo_44k(src: str, dst: str) -> str:
    from scipy.signal import resample_poly

    shutil.copytree(src, dst)
    for f in os.listdir(os.path.join(src, "audio")):
        x, fs = sf.read(os.path.join(src, "audio", f), dtype="float32")
        x = x if x.ndim == 1 else x.mean(axis=1)
        g = np.gcd(44100, fs)
        y = resample_poly(x, 44100 // g, fs // g).astype(np.float32)
        sf.write(os.path.join(dst, "audio", f), np.stack([y, 0.8 * y], 1), 44100, subtype="PCM_24", format="WAV")
    return dst


def config(corpus, n, *more):
    return load_config(preset="demo", corpus_dir=corpus, splits={"train": n, "val": 0, "test": 0}, overrides=list(more))


def check_seconds(cfg, corpus) -> tuple[float, int]:
    clips = []
    for split in ("train", "val", "test"):
        clips += read_split_clips(cfg, split, corpus, split_audio_dir(cfg, split, corpus))
    t0, w0 = time.process_time(), time.perf_counter()
    verdicts = check_clips(clips, cfg, workers=1, progress=False)
    assert all(v.problem is None for v in verdicts), [v.problem for v in verdicts if v.problem][:2]
    return time.process_time() - t0, time.perf_counter() - w0, len(clips)


def scenes(cfg, root):
    _, views = prepare_views(cfg, Layout(os.path.join(root, "home")))
    n = cfg.splits["train"].count
    return [plan_scene(cfg, "train", i, views["train"]) for i in range(n)], views["train"].roots


def per_scene(recipes, roots) -> float:
    """CPU seconds per scene, each scene's clips read afresh."""
    render_scene(recipes[0], roots)  # warm-up: imports, FFT plans
    t0 = time.process_time()
    for r in recipes:
        audio._load_clip_cached.cache_clear()
        render_scene(r, roots)
    return (time.process_time() - t0) / len(recipes)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    root = tempfile.mkdtemp(prefix="tsel-bench-prepared-")
    empty, prepared = os.path.join(root, "no-clips"), os.path.join(root, "prepared-clips")
    os.makedirs(empty)
    try:
        mono = os.path.join(root, "mono")
        synth_corpus(mono)
        stereo = stereo_44k(mono, os.path.join(root, "stereo"))
        print(f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; demo corpus as 44.1 kHz stereo 24-bit WAV\n")

        os.environ[CACHE_ENV] = empty
        off, off_wall, n = check_seconds(config(stereo, 1, "corpus.prepare_on_check=false"), stereo)
        os.environ[CACHE_ENV] = prepared
        on, on_wall, _ = check_seconds(config(stereo, 1), stereo)
        made = sum(f.endswith(".npy") for _, _, fs in os.walk(prepared) for f in fs)
        print(f"full clip check of {n} clips, per clip: {1e3 * off / n:.1f} ms CPU, "
              f"{1e3 * off_wall / n:.1f} ms wall; with prepare_on_check {1e3 * on / n:.1f} ms CPU ({on / off:.2f}x), "
              f"{1e3 * on_wall / n:.1f} ms wall ({on_wall / off_wall:.2f}x, the prepared files synced to disk); "
              f"{made} prepared clips written\n")

        runs = {"24 kHz mono": (mono, empty), "44.1 kHz stereo": (stereo, empty),
                "44.1 kHz stereo, prepared by the check": (stereo, prepared)}
        plans = {name: scenes(config(folder, args.scenes, 'corpus.check="none"'), root) for name, (folder, _) in
                 runs.items()}
        times = {name: [] for name in runs}
        for _ in range(args.repeats):
            for name, (_, cache) in runs.items():  # interleaved: all see the same machine
                os.environ[CACHE_ENV] = cache
                times[name].append(per_scene(*plans[name]))
        base = statistics.median(times["24 kHz mono"])
        print(f"{'clips':>40} {'CPU ms/scene':>13} {'x 24 kHz mono':>14}   (median of {args.repeats} x "
              f"{args.scenes} scenes)")
        for name, t in times.items():
            med = statistics.median(t)
            print(f"{name:>40} {1e3 * med:13.1f} {med / base:14.2f}")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
