"""Real corpora: what checking and preparing clips costs, where preparing pays, and a first build.

    .venv/bin/python benchmarks/bench_prepared.py [--sections breakeven,first,paper] [--scenes 400]
        [--manifests /work/shared/audiocaps] [--repeats 3]

Clips as real downloads come: 10 s, 44.1 kHz, stereo, 24-bit WAV (the demo corpus
resampled, in a temporary folder). Every ratio is against a baseline measured in the same run.

breakeven: per clip, the full clip check (``corpus.check = "full"``, nothing remembered)
   without and with writing the prepared form from its decode (CPU); per scene
   (``render_scene``, demo preset, the clip cache emptied before each), the clips decoded
   and resampled against read from their prepared forms; interleaved ``--repeats`` times,
   medians. Preparing pays above (prepare's extra cost) / (what a scene's read of a clip
   saves) uses per clip.
first: a first build of a small plan over a large manifest: the AudioCaps manifests
   (``--manifests``: 51,308 clips; never copied into the repository), each clip's audio a
   hard link to one of 64 stand-in files, ``paper-sim-2dir`` with ``--scenes`` train
   scenes (an eighth of that for val and test), 2 workers, nothing remembered: ``tsel
   generate`` with ``corpus.check = "drawn"`` (headers before planning, the clips the plan
   draws decoded, those used twice prepared): the whole build against its render stage.
paper: the paper's 9,030 scenes (7,224 / 903 / 903) projected on 2 cores from costs
   measured here: the header check of every manifest clip, planning, the full check of
   the clips the plan draws (counted on the real plan, planned from the manifests), the
   prepared forms of the clips it uses twice, and the render of each scene (its clips
   decoded, or read prepared); against the same with every clip checked and prepared up
   front (``corpus.check = "full"``, the default before).
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from collections import Counter

import numpy as np
import soundfile as sf

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus import audio  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.corpus.prepared import CACHE_ENV  # noqa: E402
from tsel_data.plan.catalog import check_clips, read_split_clips  # noqa: E402
from tsel_data.plan.sampler import plan_scene, plan_split_json, prepare_views  # noqa: E402
from tsel_data.render.mix import render_scene  # noqa: E402
from tsel_data.runtime.pool import prepare_worker  # noqa: E402
from tsel_data.store.layout import Layout  # noqa: E402

STAND_INS = 64


def stereo_44k(src: str, dst: str) -> str:
    """The demo corpus with every clip as 10 s of 44.1 kHz stereo 24-bit WAV."""
    from scipy.signal import resample_poly

    shutil.copytree(src, dst)
    for f in os.listdir(os.path.join(src, "audio")):
        x, fs = sf.read(os.path.join(src, "audio", f), dtype="float32")
        x = x if x.ndim == 1 else x.mean(axis=1)
        g = np.gcd(44100, fs)
        y = resample_poly(x, 44100 // g, fs // g).astype(np.float32)
        y = np.resize(y, 441000)  # 10 s, as AudioCaps clips
        sf.write(os.path.join(dst, "audio", f), np.stack([y, 0.8 * y], 1), 44100, subtype="PCM_24", format="WAV")
    return dst


def demo_config(corpus, n, *more):
    return load_config(preset="demo", corpus_dir=corpus, splits={"train": n, "val": 0, "test": 0},
                       overrides=["audio.duration=10.0", *more])


def _cache(root: str, name: str) -> None:
    """A fresh, empty per-user cache (clip checks and prepared clips) for what follows."""
    os.environ["TSEL_CACHE_DIR"] = os.path.join(root, f"cache-{name}")
    os.environ.pop(CACHE_ENV, None)


def breakeven(root: str, stereo: str, scenes: int, repeats: int) -> dict:
    """Per clip: the full check with and without preparing; per scene: decoded against prepared."""
    cfg = demo_config(stereo, scenes)
    clips = read_split_clips(cfg, "train", stereo)
    costs = {"check": [], "check+prepare": []}
    for r in range(repeats):
        for name, prep in (("check", False), ("check+prepare", True)):
            _cache(root, f"be-{name}-{r}")
            t0 = time.process_time()
            verdicts = check_clips(clips, cfg, level="full", prepare=[prep] * len(clips))
            costs[name].append((time.process_time() - t0) / len(clips))
            assert all(v.problem is None for v in verdicts)
    plan_cfg = demo_config(stereo, scenes, 'corpus.check="none"')
    _, views = prepare_views(plan_cfg, Layout(os.path.join(root, "home")))
    recipes = [plan_scene(plan_cfg, "train", i, views["train"]) for i in range(scenes)]
    roots = views["train"].roots
    uses = sum(len(r.sources) for r in recipes) / scenes
    prepared_cache = os.path.join(root, f"cache-be-check+prepare-{repeats - 1}")
    runs = {"decoded": os.path.join(root, "cache-none"), "prepared": prepared_cache}
    render_scene(recipes[0], roots)  # warm-up: imports, FFT plans
    per_scene = {name: [] for name in runs}
    for _ in range(repeats):
        for name, cache in runs.items():  # interleaved: both see the machine alike
            os.environ["TSEL_CACHE_DIR"] = cache
            t0 = time.process_time()
            for rec in recipes:
                audio._load_clip_cached.cache_clear()
                render_scene(rec, roots)
            per_scene[name].append((time.process_time() - t0) / scenes)
    check, prep = statistics.median(costs["check"]), statistics.median(costs["check+prepare"])
    dec, red = statistics.median(per_scene["decoded"]), statistics.median(per_scene["prepared"])
    saving = (dec - red) / uses
    print(f"breakeven: {len(clips)} clips, 10 s 44.1 kHz stereo 24-bit; {scenes} demo scenes; CPU, median of {repeats}"
          f" (load {os.getloadavg()[0]:.1f})")
    print(f"  full check per clip {1e3 * check:6.1f} ms; with its prepared form {1e3 * prep:6.1f} ms "
          f"({prep / check:.2f}x): preparing adds {1e3 * (prep - check):.1f} ms once")
    print(f"  a scene, clips decoded {1e3 * dec:6.1f} ms; read prepared {1e3 * red:6.1f} ms ({red / dec:.2f}x): "
          f"each use of a prepared clip saves {1e3 * saving:.1f} ms")
    print(f"  preparing pays above {(prep - check) / saving:.2f} uses per clip", flush=True)
    return {"check": check, "prepare": prep - check, "decoded": dec, "prepared": red, "uses": uses}


def standin_corpus(root: str, stereo: str, manifests: str) -> str:
    """The AudioCaps manifests, each clip's audio a hard link to one of STAND_INS files."""
    corpus = os.path.join(root, "audiocaps")
    os.makedirs(os.path.join(corpus, "audio"))
    sources = sorted(os.path.join(stereo, "audio", f) for f in os.listdir(os.path.join(stereo, "audio")))[:STAND_INS]
    n = 0
    for split in ("train", "val", "test"):
        src = os.path.join(manifests, f"{split}.csv")
        shutil.copyfile(src, os.path.join(corpus, f"{split}.csv"))
        with open(src, encoding="utf-8") as f:
            for row in csv.DictReader(f):
                dst = os.path.join(corpus, "audio", f"{row['youtube_id']}.wav")
                if not os.path.exists(dst):
                    os.link(sources[n % len(sources)], dst)
                    n += 1
    return corpus


def paper_config(corpus, scenes: dict, *more):
    return load_config(preset="paper-sim-2dir", corpus_dir=corpus, splits=scenes, overrides=list(more))


def first_build(root: str, corpus: str, scenes: int) -> dict:
    from tsel_data.job.pipeline import generate

    _cache(root, "first")
    splits = {"train": scenes, "val": max(2, scenes // 8), "test": max(2, scenes // 8)}
    cfg = paper_config(corpus, splits)
    notes = []
    t0 = time.perf_counter()
    res = generate(cfg, os.path.join(root, "first"), workers=2, progress=False, report=notes.append)
    total = time.perf_counter() - t0
    plan, render = res["plan_seconds"], res["render_seconds"]
    line = next((x for x in notes if x.startswith("checked in full")), "")
    print(f"first: a first build of {sum(splits.values())} paper-sim-2dir scenes over 51,308 AudioCaps clips "
          f"(stand-ins), 2 workers, nothing remembered (load {os.getloadavg()[0]:.1f})")
    print(f"  {line}")
    print(f"  whole build {total:6.1f} s (check and plan {plan:5.1f} s); its render stage {render:6.1f} s; "
          f"ratio {total / render:.2f}", flush=True)
    shutil.rmtree(os.path.join(root, "first"))
    return {"total": total, "render": render, "scenes": sum(splits.values())}


def paper(root: str, corpus: str, be: dict) -> None:
    """The paper's 9,030 scenes projected on 2 cores from unit costs measured here."""
    prepare_worker()
    splits = {"train": 7224, "val": 903, "test": 903}
    # the plan the paper size draws (from the manifests: planning needs no audio)
    _cache(root, "paper-plan")
    cfg = paper_config(corpus, splits, 'corpus.check="none"')
    t0 = time.process_time()
    _, views = prepare_views(cfg, Layout(os.path.join(root, "home")))
    read_s = time.process_time() - t0
    uses, lines = Counter(), {}
    t0 = time.process_time()
    for split in splits:
        lines[split] = plan_split_json(cfg, split, views[split])
        uses.update((split, s["clip_id"]) for line in lines[split] for s in json.loads(line)["sources"])
    plan_s = time.process_time() - t0
    listed = sum(len(v.clips) for v in views.values())
    drawn, reused = len(uses), sum(1 for n in uses.values() if n >= 2)
    reused_uses = sum(n for n in uses.values() if n >= 2)
    # the header check of every clip, nothing remembered
    _cache(root, "paper-header")
    clips = [c for v in views.values() for c in v.clips]
    t0 = time.process_time()
    check_clips(clips, cfg, level="header")
    header_s = time.process_time() - t0
    # a paper scene's render from decoded and from prepared clips
    recipes = [plan_scene(cfg, "train", i, views["train"]) for i in range(12)]
    roots = views["train"].roots
    _cache(root, "paper-render")
    render_scene(recipes[0], roots)
    per = {}
    for name, prep in (("decoded", False), ("prepared", True)):
        if prep:
            for r in recipes:
                for s in r.sources:
                    audio.prepare_clip(os.path.join(corpus, s.audio), cfg.audio.fs, cfg.audio.duration, s.offset)
        t0 = time.process_time()
        for r in recipes:
            audio._load_clip_cached.cache_clear()
            render_scene(r, roots)
        per[name] = (time.process_time() - t0) / len(recipes)
    sources = 2
    scenes = sum(splits.values())
    decoded_uses = scenes * sources - reused_uses
    clip_read = (per["decoded"] - per["prepared"]) / sources  # what decoding a clip adds to a scene
    render_cpu = scenes * per["prepared"] + decoded_uses * clip_read
    now_cpu = header_s + plan_s + drawn * be["check"] + reused * be["prepare"] + render_cpu
    before_cpu = listed * (be["check"] + be["prepare"]) + plan_s + scenes * per["prepared"]
    serial = read_s  # manifests read once, in one process
    print(f"paper: 9,030 paper-sim-2dir scenes over {listed:,} clips; the plan draws {drawn:,} clips, {reused:,} of "
          f"them twice or more ({reused_uses:,} of {scenes * sources:,} uses); CPU measured here")
    print(f"  header check of every clip {header_s:5.1f} s; planning {plan_s:5.1f} s; a scene's render "
          f"{1e3 * per['decoded']:.1f} ms decoded, {1e3 * per['prepared']:.1f} ms prepared")
    for name, cpu in (("now (drawn)", now_cpu), ("before (full, every clip prepared)", before_cpu)):
        wall = serial + cpu / 2
        print(f"  {name:36s} {cpu / 60:6.1f} min of CPU, on 2 cores {wall / 60:5.1f} min "
              f"({wall / (render_cpu / 2):.2f}x its render)")
    print(flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sections", default="breakeven,first,paper")
    ap.add_argument("--scenes", type=int, default=400, help="first: train scenes")
    ap.add_argument("--be-scenes", type=int, default=16, help="breakeven: scenes")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--manifests", default="/work/shared/audiocaps", help="AudioCaps train/val/test.csv")
    args = ap.parse_args()
    sections = args.sections.split(",")
    root = tempfile.mkdtemp(prefix="tsel-bench-prepared-")
    try:
        mono = os.path.join(root, "mono")
        synth_corpus(mono)
        stereo = stereo_44k(mono, os.path.join(root, "stereo"))
        print(f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}\n")
        be = breakeven(root, stereo, args.be_scenes, args.repeats) if "breakeven" in sections or "paper" in sections \
            else None
        if "first" in sections or "paper" in sections:
            corpus = standin_corpus(root, stereo, args.manifests)
            if "first" in sections:
                first_build(root, corpus, args.scenes)
            if "paper" in sections:
                paper(root, corpus, be)
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
