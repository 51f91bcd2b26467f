"""End-to-end scaling: scenes/hour/core per format, storage per 1,000 scenes, 1 -> 2 workers;
what a scene costs beyond its render; finalize at 1,000 hours.

    .venv/bin/python benchmarks/bench_scaling.py [--scenes 32] [--workers 2] [--sections scaling,overhead,finalize]

scaling: the real job (`tsel_data.job.pipeline.generate`: plan, render, shards on disk,
   dataset.json) on the built-in demo corpus, 10 s 24 kHz 2-source scenes, for each
   setting below, once with 1 worker (the baseline, measured in the same run) and once
   with N. One row per setting; docs/scaling.md quotes its output.
overhead: end to end against render, per scene, one process (CPU seconds, the demo
   preset, 10 s scenes, shards of 16): the baseline renders the plan's recipes and keeps
   nothing (``render_recipe``); end to end renders the same plan into shards on disk
   (HDF5 + JSON, sealed) and finalizes (``render_shards`` + ``finalize``). Interleaved
   ``--repeats`` times; the median of each and of the paired ratios.
finalize: ``finalize`` of a finished dataset of ``--finalize-scenes`` short scenes (in
   shards of 128; what finalize does per shard does not depend on the audio's length),
   in a fresh process, and the sha256 rate of one process over shard files; projected to
   1,000 hours of 10 s scenes (360,000 scenes, 1.39 TB of float32 audio) against the
   render of those scenes on a 64-core node (the overhead section's render per scene).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
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


def overhead(corpus, root, scenes, repeats) -> float:
    """End to end (render, shards, seal, finalize) against render alone, CPU per scene;
    returns the render's CPU seconds per scene (the median)."""
    from tsel_data.job.shards import finalize, open_plan, render_shards
    from tsel_data.render.scenes import render_recipe
    from tsel_data.runtime.pool import prepare_worker

    prepare_worker()  # as a render worker: one BLAS thread, freed memory kept (both sides alike)

    cfg = load_config(preset="demo", corpus_dir=corpus, overrides=["output.shard_size=16"],
                      splits={"train": scenes, "val": 0, "test": 0})
    proto = os.path.join(root, "proto")
    plan_dataset(cfg, proto, workers=1)
    plan = open_plan(proto)
    recipes = [r for rs in plan.recipes(plan.tasks) for r in rs]
    for r in recipes[:2]:  # warm-up: imports, FFT plans, the clip cache
        render_recipe(r, plan.roots)
    alone, whole = [], []
    for k in range(repeats):
        t0 = time.process_time()
        for r in recipes:
            render_recipe(r, plan.roots)
        alone.append((time.process_time() - t0) / scenes)
        out = os.path.join(root, f"e2e-{k}")
        shutil.copytree(proto, out)
        t0 = time.process_time()
        render_shards(out, workers=1, progress=False)
        finalize(out)
        whole.append((time.process_time() - t0) / scenes)
        shutil.rmtree(out)
    ratios = [w / a for w, a in zip(whole, alone)]
    print(f"overhead: {scenes} demo scenes of 10 s, one process, CPU ms per scene, median of {repeats} "
          f"(load {os.getloadavg()[0]:.1f})")
    print(f"  render alone (baseline) {1e3 * statistics.median(alone):7.1f}")
    print(f"  end to end              {1e3 * statistics.median(whole):7.1f}   ratio {statistics.median(ratios):.2f} "
          f"(paired: {min(ratios):.2f}-{max(ratios):.2f})", flush=True)
    return statistics.median(alone)


FINALIZE_CHILD = r"""
import json, sys, time
sys.path.insert(0, {repo!r})
t0 = time.process_time(); w0 = time.perf_counter()
from tsel_data.job.shards import finalize
finalize({out!r})
print(json.dumps({{"cpu": time.process_time() - t0, "wall": time.perf_counter() - w0}}))
"""

HOURS_1000 = 360_000  # 10 s scenes
BYTES_PER_SCENE = 4 * 24000 * 10 * 4  # mic4 float32


def finalize_projection(corpus, root, scenes, workers, render_per_scene) -> None:
    """finalize's cost per scene, projected to 1,000 hours against the render on 64 cores."""
    out = os.path.join(root, "finalize")
    cfg = load_config(preset="demo", corpus_dir=corpus, overrides=["output.shard_size=128", "audio.duration=0.5"],
                      splits={"train": scenes, "val": 0, "test": 0})
    generate(cfg, out, workers=workers, progress=False, allow_reuse=True)
    code = FINALIZE_CHILD.format(repo=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."), out=out)
    runs = [json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                      check=True).stdout.strip().splitlines()[-1]) for _ in range(3)]
    per_scene = statistics.median(r["wall"] for r in runs) / scenes
    shard = max((os.path.join(out, "train", f) for f in os.listdir(os.path.join(out, "train")) if f.endswith(".h5")),
                key=os.path.getsize)
    data = open(shard, "rb").read()
    t0 = time.perf_counter()
    for _ in range(8):
        hashlib.sha256(data).digest()
    rate = 8 * len(data) / (time.perf_counter() - t0)
    shutil.rmtree(out)
    render = HOURS_1000 * render_per_scene / 64
    tail = HOURS_1000 * per_scene
    rehash = HOURS_1000 * BYTES_PER_SCENE / rate
    print(f"finalize: {scenes} scenes in shards of 128, {1e3 * per_scene:.3f} ms per scene (wall, median of 3 "
          f"fresh processes); sha256 {rate / 1e9:.2f} GB/s in one process")
    print(f"  1,000 hours (360,000 scenes of 10 s, {HOURS_1000 * BYTES_PER_SCENE / 1e12:.2f} TB): render on 64 cores "
          f"{render / 60:.1f} min (the overhead section's {1e3 * render_per_scene:.1f} ms per scene); finalize, serial, "
          f"{tail / 60:.1f} min ({tail / render:.2f}x the render); a serial re-hash of every shard would be "
          f"{rehash / 60:.1f} min ({rehash / render:.2f}x)", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=32)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3, help="overhead: interleaved repeats")
    ap.add_argument("--finalize-scenes", type=int, default=4096)
    ap.add_argument("--sections", default="scaling,overhead,finalize")
    args = ap.parse_args()
    root = tempfile.mkdtemp(prefix="tsel-bench-")
    os.environ["TSEL_CACHE_DIR"] = os.path.join(root, "cache")  # clip checks of this run only: the user's stay
    corpus = os.path.join(root, "corpus")
    synth_corpus(corpus)
    bank = None
    try:
        sections = args.sections.split(",")
        render_per_scene = None
        if "overhead" in sections or "finalize" in sections:
            render_per_scene = overhead(corpus, root, args.scenes, args.repeats)
        if "finalize" in sections:
            finalize_projection(corpus, root, args.finalize_scenes, args.workers, render_per_scene)
        if "scaling" not in sections:
            return
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
