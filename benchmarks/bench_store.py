"""Storage and reading: codings, the reader against raw h5py, a worker's peak memory.

    .venv/bin/python benchmarks/bench_store.py [--scenes 32] [--rss-sizes 16,128,1024]

All on the built-in demo corpus, 10 s 24 kHz mic4 scenes, measured in one run:

1. **codings**: the same scenes generated with ``output.audio`` = float32, int16 and
   flac: bytes per scene and ratio to float32, SNR against float32, and scenes/s read
   through ``open_dataset`` (warm page cache) with the ratio to float32's.
2. **reader vs raw h5py**: float32 shards read one scene at a time with
   ``open_dataset(...)[i]`` against raw ``h5py`` ``audio[i]`` (the baseline), and in
   batches with ``read_audio(indices, out=buffer)`` against raw ``read_direct`` into one
   reused buffer.
3. **peak memory of a render worker** (``--rss-sizes``): one process renders and writes
   one shard of N scenes (``render_shard``, as a ``tsel render`` worker does); its peak
   resident set size (VmHWM of a fresh subprocess) per shard size.
4. **a DataLoader** (needs torch; ``--loader-repeats``): the float32 scenes through
   ``tsel_data.torch.Dataset`` and a DataLoader of batches of 8 with 0, 1 and 2 workers,
   item by item (PyTorch's default fetch and collate, as before ``__getitems__``) and in
   batches (``__getitems__``: one ``read_audio(out=)`` into a shared-memory tensor,
   handed on by ``collate`` without a copy). Scenes/s, median of interleaved passes, and the ratio to
   item by item without workers (the baseline); and the worst ratio of a DataLoader with
   workers to the same way without (the goal: never below 1).
5. **writing a scene's audio**: one shard of 16 scenes written through h5py
   (``audio[i] = x``, the baseline and the writer's way) and through
   ``write_direct_chunk`` (the same samples in another file layout, so not used:
   store/writer.py), CPU ms per scene, median of interleaved rounds.
6. **clips as they come**: the time to render a scene (``render_scene``, one process,
   the clip cache emptied before each scene, as with a large corpus) when the corpus is
   24 kHz mono WAV (the baseline), the same clips as 44.1 kHz stereo 24-bit WAV, and
   those after ``tsel corpus prepare``.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

import h5py  # noqa: E402

from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.job.pipeline import generate  # noqa: E402
from tsel_data.store.reader import open_dataset  # noqa: E402


def make(corpus, root, n, coding, shard_size=16):
    out = os.path.join(root, coding)
    cfg = load_config(preset="demo", corpus_dir=corpus, splits={"train": n, "val": 0, "test": 0},
                      overrides=[f'output.audio="{coding}"', f"output.shard_size={shard_size}"])
    generate(cfg, out, workers=2, progress=False)
    return out


def read_all(out, repeats=3) -> tuple[float, np.ndarray]:
    """Scenes/s through open_dataset, best of ``repeats`` warm passes; and the audio."""
    best, audio = 0.0, None
    with open_dataset(out, "train") as ds:
        audio = np.stack([ds[i].audio for i in range(len(ds))])  # warms the page cache
        for _ in range(repeats):
            t0 = time.perf_counter()
            for i in range(len(ds)):
                ds[i]
            best = max(best, len(ds) / (time.perf_counter() - t0))
    return best, audio


def shard_bytes(out) -> int:
    d = os.path.join(out, "train")
    return sum(os.path.getsize(os.path.join(d, f)) for f in os.listdir(d) if f.endswith(".h5"))


def raw_rates(out, repeats=3) -> tuple[float, float]:
    """Raw h5py scenes/s: audio[i] per scene, and read_direct into one reused buffer."""
    files = sorted(os.path.join(out, "train", f) for f in os.listdir(os.path.join(out, "train")) if f.endswith(".h5"))
    hs = [h5py.File(f, "r") for f in files]
    try:
        n = sum(h["audio"].shape[0] for h in hs)
        per, batched = 0.0, 0.0
        buf = np.empty(hs[0]["audio"].shape[1:], np.float32)
        for _ in range(repeats):
            t0 = time.perf_counter()
            for h in hs:
                a = h["audio"]
                for i in range(a.shape[0]):
                    a[i]
            per = max(per, n / (time.perf_counter() - t0))
            t0 = time.perf_counter()
            for h in hs:
                a = h["audio"]
                for i in range(a.shape[0]):
                    a.read_direct(buf, np.s_[i])
            batched = max(batched, n / (time.perf_counter() - t0))
        return per, batched
    finally:
        for h in hs:
            h.close()


def batched_rate(out, batch=8, repeats=3) -> float:
    with open_dataset(out, "train") as ds:
        n = len(ds)
        buf = np.empty((batch, *ds[0].audio.shape), np.float32)
        best = 0.0
        for _ in range(repeats):
            t0 = time.perf_counter()
            for start in range(0, n - batch + 1, batch):
                ds.read_audio(range(start, start + batch), out=buf)
            best = max(best, (n // batch) * batch / (time.perf_counter() - t0))
        return best


RSS_CHILD = r"""
import json, os, sys
sys.path.insert(0, {repo!r})
from tsel_data.runtime.pool import prepare_worker
from tsel_data.job.shards import open_plan, render_shard
prepare_worker()
out = {out!r}
plan = open_plan(out)
task = plan.tasks[0]
render_shard(out, task, plan.recipes([task])[0], plan.attrs, plan.roots)
# VmHWM, not ru_maxrss: the latter keeps the high-water mark of the parent's memory forked
# into this process before it exec'ed Python
peak = [l for l in open("/proc/self/status") if l.startswith("VmHWM:")][0].split()[1]
print(json.dumps(int(peak) * 1024))
"""


def peak_rss(corpus, root, size) -> float:
    """Peak RSS (bytes) of a fresh process rendering one shard of ``size`` scenes."""
    from tsel_data.job.pipeline import plan_dataset

    out = os.path.join(root, f"rss-{size}")
    cfg = load_config(preset="demo", corpus_dir=corpus, splits={"train": size, "val": 0, "test": 0},
                      overrides=[f"output.shard_size={size}"])
    plan_dataset(cfg, out, allow_reuse=True)  # a shard of this size, whatever the demo corpus's clip count
    code = RSS_CHILD.format(repo=os.path.join(os.path.dirname(__file__), ".."), out=out)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    shutil.rmtree(out)
    return float(json.loads(r.stdout.strip().splitlines()[-1]))


def scene_cost(corpus, root, n) -> dict:
    """Seconds per scene rendered from 24 kHz mono clips, 44.1 kHz stereo, and prepared."""
    from scipy.signal import resample_poly

    from tsel_data.corpus import audio
    from tsel_data.plan.catalog import build_catalog, prepare_corpus
    from tsel_data.plan.sampler import prepare_views, plan_scene
    from tsel_data.render.mix import render_scene
    from tsel_data.store.layout import Layout
    import soundfile as sf

    stereo = os.path.join(root, "stereo")
    shutil.copytree(corpus, stereo)
    for f in os.listdir(os.path.join(corpus, "audio")):
        x, fs = sf.read(os.path.join(corpus, "audio", f), dtype="float32")
        x = x if x.ndim == 1 else x.mean(axis=1)
        y = resample_poly(x, 44100 // np.gcd(44100, fs), fs // np.gcd(44100, fs)).astype(np.float32)
        sf.write(os.path.join(stereo, "audio", f), np.stack([y, 0.8 * y], 1), 44100, subtype="PCM_24", format="WAV")

    def per_scene(folder):
        cfg = load_config(preset="demo", corpus_dir=folder, splits={"train": n, "val": 0, "test": 0},
                          overrides=['corpus.check="none"'])
        _, views = prepare_views(cfg, Layout(os.path.join(root, "home")))
        recipes = [plan_scene(cfg, "train", i, views["train"]) for i in range(n)]
        roots = views["train"].roots  # recipes name clips relative to the corpus
        render_scene(recipes[0], roots)  # warm-up (imports, FFT plans)
        t0 = time.perf_counter()
        for r in recipes:
            audio._load_clip_cached.cache_clear()
            render_scene(r, roots)
        return (time.perf_counter() - t0) / n, cfg

    out = {"24 kHz mono": per_scene(corpus)[0]}
    out["44.1 kHz stereo"], cfg = per_scene(stereo)
    prepare_corpus(cfg, build_catalog(cfg, stereo).clips, workers=2)
    out["44.1 kHz stereo, prepared"] = per_scene(stereo)[0]
    return out


def loader_rates(out, repeats, touch: bool) -> dict | None:
    """{(way, workers): scenes/s} through tsel_data.torch.Dataset and a DataLoader."""
    try:
        import torch
    except ImportError:
        return None
    from tsel_data.tools.torch import Dataset, collate

    class ItemByItem(Dataset):
        __getitems__ = None  # PyTorch then fetches ds[i] one by one and stacks them

    loaders = {}
    for way, cls, coll in (("item by item", ItemByItem, None), ("batched", Dataset, collate)):
        for workers in (0, 1, 2):
            loaders[(way, workers)] = torch.utils.data.DataLoader(
                cls(out, "train"), batch_size=8, num_workers=workers, persistent_workers=workers > 0,
                collate_fn=coll)
    for dl in loaders.values():  # start the workers, warm the page cache
        for _ in dl:
            pass
    rates = {key: [] for key in loaders}
    for _ in range(repeats):
        for key, dl in loaders.items():  # interleaved: each sees the machine as the others do
            t0, n = time.perf_counter(), 0
            for b in dl:
                n += len(b["audio"])
                if touch:
                    float(b["audio"].sum())
            rates[key].append(n / (time.perf_counter() - t0))
    del loaders
    return {key: float(np.median(v)) for key, v in rates.items()}


def write_costs(rounds=5, n=16, shape=(4, 240000)) -> dict:
    """CPU ms per scene to write a shard's audio: h5py setitem against write_direct_chunk."""
    x = np.random.default_rng(0).standard_normal((n, *shape)).astype(np.float32)
    path = os.path.join(tempfile.mkdtemp(prefix="tsel-bench-write-"), "w.h5")
    out = {"h5py audio[i] = x": [], "write_direct_chunk": []}
    try:
        for _ in range(rounds):
            for way in out:
                t0 = time.process_time()
                with h5py.File(path, "w", track_order=False, libver=("earliest", "v110")) as h:
                    d = h.create_dataset("audio", (n, *shape), dtype="float32", chunks=(1, *shape), track_times=False)
                    for i in range(n):
                        if way == "write_direct_chunk":
                            d.id.write_direct_chunk((i, 0, 0), x[i])
                        else:
                            d[i] = x[i]
                out[way].append(1e3 * (time.process_time() - t0) / n)
                os.remove(path)
    finally:
        shutil.rmtree(os.path.dirname(path), ignore_errors=True)
    return {way: float(np.median(v)) for way, v in out.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=32)
    ap.add_argument("--rss-sizes", default="16,128,1024", help="Shard sizes for the memory test ('' skips it).")
    ap.add_argument("--loader-repeats", type=int, default=5)
    ap.add_argument("--sections", default="codings,reader,loader,write,clips,rss")
    args = ap.parse_args()
    sections = args.sections.split(",")
    root = tempfile.mkdtemp(prefix="tsel-bench-store-")
    os.environ["TSEL_CACHE_DIR"] = os.path.join(root, "cache")  # this run's clip checks: the user's cache stays
    try:
        corpus = os.path.join(root, "corpus")
        synth_corpus(corpus)
        print(f"{os.cpu_count()} cores; {args.scenes} demo scenes of 10 s, 24 kHz, 4 channels\n")
        codings = ("float32", "int16", "flac") if "codings" in sections else ("float32",)
        if "codings" in sections:
            print(f"{'coding':>8} {'MB/scene':>9} {'x float32':>10} {'SNR dB':>8} {'read scenes/s':>14} "
                  f"{'x float32':>10}")
        rows, ref = {}, None
        for coding in codings:
            out = make(corpus, root, args.scenes, coding)
            rate, audio = read_all(out)
            rows[coding] = (shard_bytes(out) / args.scenes, rate, audio, out)
        ref_bytes, ref_rate, ref, ref_out = rows["float32"]
        for coding, (b, rate, audio, _) in rows.items() if "codings" in sections else ():
            err = float(np.sum((audio - ref) ** 2))
            snr = 10 * np.log10(float(np.sum(ref ** 2)) / err) if err > 0 else float("inf")
            print(f"{coding:>8} {b / 1e6:9.2f} {b / ref_bytes:10.3f} {snr:8.1f} {rate:14.0f} {rate / ref_rate:10.2f}",
                  flush=True)

        if "reader" in sections:
            raw_per, raw_batched = raw_rates(ref_out)
            ours_batched = batched_rate(ref_out)
            print(f"\nreader vs raw h5py (float32, warm): per scene {ref_rate:.0f} vs {raw_per:.0f} scenes/s "
                  f"({ref_rate / raw_per:.2f}x); batched into a buffer {ours_batched:.0f} vs {raw_batched:.0f} "
                  f"scenes/s ({ours_batched / raw_batched:.2f}x)", flush=True)

        for touch in ((False, True) if "loader" in sections else ()):
            rates = loader_rates(ref_out, args.loader_repeats, touch)
            if not rates:
                print("\nDataLoader: skipped (no torch)")
                break
            base = rates[("item by item", 0)]
            print(f"\nDataLoader, batches of 8, the loop {'sums the audio' if touch else 'counts scenes'}: scenes/s "
                  f"(median of {args.loader_repeats}; load {os.getloadavg()[0]:.1f}); x item by item with 0 workers")
            for way in ("item by item", "batched"):
                print(f"  {way:>13}: " + "   ".join(f"{w} workers {rates[(way, w)]:5.0f} ({rates[(way, w)] / base:.2f}x)"
                                                   for w in (0, 1, 2)), flush=True)
            worst = min(rates[(way, w)] / rates[(way, 0)] for way in ("item by item", "batched") for w in (1, 2))
            print(f"  with workers against without (the same way): at worst {worst:.2f}x", flush=True)

        if "write" in sections:
            costs = write_costs()
            base = costs["h5py audio[i] = x"]
            print("\nwriting a scene's audio (4 x 240,000 float32), CPU ms per scene, median of 5")
            for way, t in costs.items():
                print(f"  {way:>20} {t:6.2f} ({t / base:.2f}x)", flush=True)

        if "clips" in sections:
            costs = scene_cost(corpus, root, min(args.scenes, 16))
            base = costs["24 kHz mono"]
            print(f"\n{'clips':>26} {'ms/scene':>9} {'x 24 kHz mono':>14}")
            for name, t in costs.items():
                print(f"{name:>26} {1e3 * t:9.1f} {t / base:14.2f}", flush=True)

        sizes = [int(x) for x in args.rss_sizes.split(",") if x] if "rss" in sections else []
        if sizes:
            print(f"\n{'shard size':>10} {'peak RSS of the render worker (MB)':>36}")
            for size in sizes:
                print(f"{size:>10} {peak_rss(corpus, root, size) / 1e6:36.0f}", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
