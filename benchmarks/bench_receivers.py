"""Benchmark: scenes heard by several receivers in one pass, against each receiver alone.

Run by hand (``.venv/bin/python benchmarks/bench_receivers.py``); prints numbers, writes
only to a temporary directory.

The corpus is the demo corpus as a download would be: 44.1 kHz stereo WAV (like
AudioCaps' files), so every scene decodes and resamples its clips. Scenes: 10 s, the
``demo`` preset's rooms, two directional sources, heard by RECEIVERS (the first is
``scene.format``, the rest ``scene.receivers``). Two measures, each in one run:

* ``scene``: ``render_scene`` (clips, RIRs, convolution, levels, labels, record) of each
  scene in one pass, and of the same scene once per receiver alone, interleaved, each
  decoding its clips as a job of its own would (the clip cache emptied before each);
  seconds per scene and the ratio (one pass / the sum of the singles), median over scenes;
* ``job``: ``tsel generate`` of N scenes with all receivers, against one ``tsel generate``
  per receiver (each checks the corpus, plans, renders and writes its own dataset);
  wall seconds and their ratio.
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "PRA_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402
import soundfile as sf  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from tsel_data.corpus.audio import _load_clip_cached  # noqa: E402
from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.plan.sampler import plan_scene, prepare_views  # noqa: E402
from tsel_data.render.mix import render_scene  # noqa: E402
from tsel_data.store.layout import Layout  # noqa: E402

TSEL = os.path.join(os.path.dirname(sys.executable), "tsel")


def stereo_corpus(root: str) -> str:
    """The demo corpus, its clips as 44.1 kHz stereo 24-bit WAV."""
    from scipy.signal import resample_poly

    src, out = os.path.join(root, "demo"), os.path.join(root, "stereo")
    synth_corpus(src, seed=0)
    shutil.copytree(src, out)
    for f in os.listdir(os.path.join(src, "audio")):
        x, fs = sf.read(os.path.join(src, "audio", f), dtype="float32")
        x = x if x.ndim == 1 else x.mean(axis=1)
        y = resample_poly(x, 44100 // np.gcd(44100, fs), fs // np.gcd(44100, fs)).astype(np.float32)
        sf.write(os.path.join(out, "audio", f), np.stack([y, 0.8 * y], 1), 44100, subtype="PCM_24", format="WAV")
    return out


def overrides(names: list[str]) -> list[str]:
    return [f'scene.format="{names[0]}"', f"scene.receivers={json.dumps(names[1:])}",
            'scene.scenario="two-directional"', 'corpus.check="header"']


def scene_cost(corpus: str, home: str, names: list[str], n: int) -> None:
    cfg = load_config(preset="demo", corpus_dir=corpus, splits={"train": n, "val": 0, "test": 0},
                      overrides=overrides(names))
    _, views = prepare_views(cfg, Layout(home))
    roots = views["train"].roots
    recipes = [plan_scene(cfg, "train", i, views["train"]) for i in range(n)]
    for pose in (recipes[0].array, *recipes[0].receivers):  # warm: imports, FFT plans, the sphere's tables
        render_scene(replace(recipes[0], array=pose, receivers=()), roots)
    one, alone = [], []
    for r in recipes:
        _load_clip_cached.cache_clear()
        t = time.perf_counter()
        render_scene(r, roots)
        one.append(time.perf_counter() - t)
        t = time.perf_counter()
        for pose in (r.array, *r.receivers):
            _load_clip_cached.cache_clear()
            render_scene(replace(r, array=pose, receivers=()), roots)
        alone.append(time.perf_counter() - t)
    one, alone = np.array(one), np.array(alone)
    print(f"scene: {n} scenes of {cfg.audio.duration:g} s, receivers {', '.join(names)}")
    print(f"  one pass            {np.median(one):.3f} s/scene")
    print(f"  each alone, summed  {np.median(alone):.3f} s/scene")
    print(f"  ratio (one pass / each alone): median {np.median(one / alone):.2f}, "
          f"range {np.min(one / alone):.2f}-{np.max(one / alone):.2f}")


def generate(corpus: str, out: str, names: list[str], n: int) -> float:
    cmd = [TSEL, "generate", "--preset", "demo", "--corpus-dir", corpus, "--out", out, "--workers", "1",
           "--split", f"train={n}", "--split", "val=0", "--split", "test=0"]
    for o in overrides(names):
        cmd += ["--set", o]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def job_cost(corpus: str, root: str, names: list[str], n: int) -> None:
    together = generate(corpus, os.path.join(root, "all"), names, n)
    apart = sum(generate(corpus, os.path.join(root, name), [name], n) for name in names)
    print(f"job: tsel generate of {n} scenes")
    print(f"  one dataset heard by all    {together:.1f} s")
    print(f"  one dataset per receiver    {apart:.1f} s (summed)")
    print(f"  ratio: {together / apart:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=int, default=6)
    ap.add_argument("--job-scenes", type=int, default=24)
    ap.add_argument("--receivers", default="mic4,foa,tetra,uma8", help="comma-separated, the first is scene.format")
    ap.add_argument("--sections", default="scene,job")
    args = ap.parse_args()
    names = args.receivers.split(",")
    root = tempfile.mkdtemp(prefix="tsel-bench-receivers-")
    try:
        corpus = stereo_corpus(root)
        if "scene" in args.sections:
            scene_cost(corpus, os.path.join(root, "home"), names, args.scenes)
        if "job" in args.sections:
            job_cost(corpus, root, names, args.job_scenes)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
