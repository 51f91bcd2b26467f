"""Reflections that move: accuracy and cost of simulated moving sources, now against before.

    .venv/bin/python benchmarks/bench_moving_reflections.py [--sources 8] [--rounds 3]

accuracy: the image-source part of the paths of tests/acoustics/test_moving_reflections.py (1.2 s
   of pink noise, 24 kHz) against the dense physical reference (acoustics/reference.py:
   RIRs every 0.5 ms), waveform SNR in dB: before (one warp, the direct path's; knots
   every 100 ms / 4°, and on lines every 3 cm) and now (image groups each aligned by its
   own delay, acoustics/image_paths.py; knots by placement.knot_hop).
cost: ms per 10 s moving source as render.path_image does it (simulate the knots, the
   image part through the moving renderer, the shared tail convolved once), line passes
   and arcs at 10 and 40 °/s planned in the demo preset's rooms (mic4), before and now
   interleaved source by source (the machine may be shared; pairs cancel its drift):
   medians and the median of the paired ratios.
scenes: whole moving scenes end to end, `tsel generate` of --scenes 10 s scenes (demo
   preset, every source moving on arcs and lines at 10/20/40 °/s, one worker) with this
   checkout and with --against REV (default the commit before image groups) in a git
   worktree, interleaved --rounds times: CPU seconds of each run and the median ratio.
ratio: a simulated moving scene against a static one (the baseline), both rendered here
   (``render_scene``, one process set up as a render worker): --scenes demo scenes of
   10 s with two directional sources, static, and the same plan's scenes with every
   source moving on arcs and lines at 10/20/40 °/s; interleaved --rounds times, CPU ms
   per scene, medians and the median of the paired ratios.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests", "acoustics"))

from tsel_data.acoustics import simulate_rirs  # noqa: E402
from tsel_data.acoustics.image_paths import GROUPS  # noqa: E402
from tsel_data.acoustics.reference import dense_image, image_part_timing  # noqa: E402
from tsel_data.acoustics.shoebox import shoebox_rirs  # noqa: E402
from tsel_data.choices import PathKind  # noqa: E402
from tsel_data.core.geometry import Room  # noqa: E402
from tsel_data.plan.placement import KNOT_HOP_S, KNOT_STEP_DEG, knot_hop  # noqa: E402
from tsel_data.receivers import ArrayPose  # noqa: E402
from tsel_data.render.mix import moving_image_part  # noqa: E402
from tsel_data.dsp.timevarying import render_static  # noqa: E402

FS = 24000


def before_hop(kind, speed, distance, r_h):
    """The knots before image groups: 100 ms / 4°, and on lines every 3 cm."""
    hop = min(KNOT_HOP_S, KNOT_STEP_DEG / (speed * distance / r_h))
    return hop if kind == PathKind.ARC else min(hop, 0.03 / (math.radians(speed) * distance))


def accuracy():
    import test_moving_reflections as t

    rng = np.random.default_rng(7)
    n = int(t.DUR * FS)
    w = np.fft.rfft(rng.standard_normal(n))
    x = np.fft.irfft(w / np.sqrt(np.maximum(np.fft.rfftfreq(n, 1 / FS), 20.0)), n)
    x = (x / x.std()).astype(np.float32)
    print("accuracy: image-source part against RIRs every 0.5 ms (waveform SNR, dB)")
    for case, ((dims, rt60), (fmt, centre, side), kind, speed, r, path) in t.CASES.items():
        room, array = Room(dims, rt60), ArrayPose(fmt, centre, 0.0, side)
        pos = path(centre)
        out = {}
        for name, hop_of, groups in (("before", before_hop, 1), ("now", knot_hop, GROUPS)):
            hop = hop_of(kind, speed, r, r)
            knots = np.arange(0.0, t.DUR + hop, hop)
            timing = image_part_timing(pos(knots), centre, rt60)
            if "ref" not in out:
                out["ref"] = dense_image(room, array, pos, x, FS, timing=timing)
            rs = shoebox_rirs(room, array, pos(knots), FS, one_source=True, tail_apart=True, groups=groups,
                              transition=timing[0], length=timing[1], image_highpass=name == "before")
            y = moving_image_part(x, rs, knots, FS)[:, :n]
            ref = out["ref"]
            out[name] = 10 * np.log10(np.sum(ref**2) / np.sum((ref - y) ** 2))
        print(f"  {case:28s} before {out['before']:5.1f}   now {out['now']:5.1f}")


def _paths(n, seed=0):
    """(room, array, kind, speed, distance, position(t)) of n 10 s moving sources in demo-like rooms."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        kind = (PathKind.LINE, PathKind.ARC)[i % 2]
        speed = (10.0, 40.0)[(i // 2) % 2]
        dims = (float(rng.uniform(5, 15)), float(rng.uniform(5, 15)), float(rng.uniform(2.5, 4.0)))
        room = Room(dims, float(rng.uniform(0.5, 1.0)))
        d = float(rng.uniform(1.5, 2.5))
        c = (dims[0] / 2, dims[1] / 2 - 1.0, 1.2)
        array = ArrayPose("mic4", c, 0.0, 0.12)
        if kind == PathKind.LINE:
            v = math.radians(speed) * d
            reach = dims[0] / 2 - 0.6

            def pos(t, c=c, v=v, d=d, reach=reach):
                s = np.clip(v * (np.asarray(t) - 5.0), -reach, reach)
                return np.stack([c[0] + s, np.full_like(s, c[1] + d), np.full_like(s, 1.5)], -1)
        else:
            def pos(t, c=c, d=min(d, dims[1] / 2 - 0.6), speed=speed):
                a = np.radians(speed * np.asarray(t))
                return np.stack([c[0] + d * np.cos(a), c[1] + 1.0 + d * np.sin(a), np.full_like(a, 1.5)], -1)
        out.append((room, array, kind, speed, d, pos))
    return out


def _path_image(room, array, knots, pos, x, groups):
    rs = simulate_rirs(room, array, pos(knots), FS, one_source=True, tail_apart=True, groups=groups,
                       image_highpass=groups == 1)
    image = moving_image_part(x, rs, knots, FS)[:, :len(x)]
    if rs.tail is not None:
        image = image + render_static(x, rs.tail)[:, :len(x)]
    return image


def cost(n_sources, rounds):
    x = np.random.default_rng(1).standard_normal(10 * FS).astype(np.float32)
    paths = _paths(n_sources)
    rows = {}
    for _ in range(rounds):
        for room, array, kind, speed, d, pos in paths:
            key = f"{kind} {speed:g}°/s"
            for name, hop_of, groups in (("before", before_hop, 1), ("now", knot_hop, GROUPS)):
                hop = hop_of(kind, speed, d, d)
                knots = np.arange(0.0, 10.0 + hop, hop)
                t0 = time.process_time()
                _path_image(room, array, knots, pos, x, groups)
                rows.setdefault(key, {}).setdefault(name, []).append(1000 * (time.process_time() - t0))
    print("cost: ms of CPU per 10 s mic4 source (simulate + render), median; paired ratio now / before")
    for key, r in rows.items():
        b, n = np.asarray(r["before"]), np.asarray(r["now"])
        print(f"  {key:14s} before {np.median(b):6.0f}   now {np.median(n):6.0f}   ratio {np.median(n / b):.2f}")
    b = np.concatenate([r["before"] for r in rows.values()])
    n = np.concatenate([r["now"] for r in rows.values()])
    print(f"  all            before {np.median(b):6.0f}   now {np.median(n):6.0f}   ratio {np.median(n / b):.2f}")


def scenes(n, rounds, against):
    import resource
    import shutil
    import subprocess
    import tempfile

    here = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
    tmp = tempfile.mkdtemp(prefix="bench-moving-")
    other = os.path.join(tmp, "against")
    subprocess.run(["git", "-C", here, "worktree", "add", "--detach", other, against], check=True,
                   capture_output=True)
    try:
        corpus = os.path.join(tmp, "corpus")
        subprocess.run([sys.executable, "-m", "tsel_data.cli", "corpus", "synth", "--out", corpus], cwd=here,
                       check=True, capture_output=True)
        args = ["generate", "--preset", "demo", "--corpus-dir", corpus, "--split", f"train={n}", "--split", "val=0",
                "--split", "test=0", "--set", 'scene.motion="moving"', "--set", 'scene.path=["choose", ["arc", "line"]]',
                "--workers", "1", "--quiet"]
        cpu = {"now": [], "before": []}
        for r in range(rounds):
            for name, tree in (("before", other), ("now", here)):
                out = os.path.join(tmp, f"{name}-{r}")
                t0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                subprocess.run([sys.executable, "-m", "tsel_data.cli", *args, "--out", out], cwd=tree, check=True,
                               env={**os.environ, "PYTHONPATH": tree})
                t1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu[name].append(t1.ru_utime + t1.ru_stime - t0.ru_utime - t0.ru_stime)
                shutil.rmtree(out)
        b, w = np.asarray(cpu["before"]), np.asarray(cpu["now"])
        print(f"scenes: {n} moving 10 s demo scenes, CPU s per run: before ({against}) {np.median(b):.1f}   "
              f"now {np.median(w):.1f}   ratio {np.median(w / b):.2f}")
    finally:
        subprocess.run(["git", "-C", here, "worktree", "remove", "--force", other], capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)


def ratio(n, rounds):
    """A moving scene's render against a static one's (the module docstring)."""
    import shutil
    import tempfile

    from tsel_data.config import load_config
    from tsel_data.corpus.demo import synth_corpus
    from tsel_data.plan.sampler import plan_scene, prepare_views
    from tsel_data.render.mix import render_scene
    from tsel_data.runtime.pool import prepare_worker
    from tsel_data.store.layout import Layout

    prepare_worker()
    tmp = tempfile.mkdtemp(prefix="bench-moving-ratio-")
    os.environ["TSEL_CACHE_DIR"] = os.path.join(tmp, "cache")
    try:
        corpus = os.path.join(tmp, "corpus")
        synth_corpus(corpus)
        plans = {}
        for name, more in (("static", []), ("moving", ['scene.motion="moving"', 'scene.path=["choose", ["arc", "line"]]'])):
            cfg = load_config(preset="demo", corpus_dir=corpus, splits={"train": n, "val": 0, "test": 0},
                              overrides=['scene.scenario="two-directional"', *more])
            _, views = prepare_views(cfg, Layout(os.path.join(tmp, "home")))
            plans[name] = ([plan_scene(cfg, "train", i, views["train"]) for i in range(n)], views["train"].roots)
        for recipes, roots in plans.values():  # warm-up: imports, FFT plans, the clip cache
            render_scene(recipes[0], roots)
        cpu = {name: [] for name in plans}
        for _ in range(rounds):
            for name, (recipes, roots) in plans.items():
                t0 = time.process_time()
                for r in recipes:
                    render_scene(r, roots)
                cpu[name].append(1e3 * (time.process_time() - t0) / n)
        st, mv = np.asarray(cpu["static"]), np.asarray(cpu["moving"])
        print(f"ratio: {n} demo scenes of 10 s, 2 directional sources, CPU ms per scene, median of {rounds} "
              f"(load {os.getloadavg()[0]:.1f}): static {np.median(st):.1f}   moving {np.median(mv):.1f}   "
              f"ratio {np.median(mv / st):.2f} (paired {np.min(mv / st):.2f}-{np.max(mv / st):.2f})")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sources", type=int, default=8, help="cost: 10 s sources (lines and arcs, 10 and 40 °/s)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--scenes", type=int, default=12, help="scenes: 10 s scenes per run")
    ap.add_argument("--against", default="64636ea", help="scenes: the commit to compare with")
    ap.add_argument("--sections", default="accuracy,cost,scenes,ratio")
    args = ap.parse_args()
    if "ratio" in args.sections:
        ratio(args.scenes, args.rounds)
    if "accuracy" in args.sections:
        accuracy()
    if "cost" in args.sections:
        cost(args.sources, args.rounds)
    if "scenes" in args.sections:
        scenes(args.scenes, args.rounds, args.against)


if __name__ == "__main__":
    main()
