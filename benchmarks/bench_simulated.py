"""Benchmark: simulated-room scenes, the project's simulator against pyroomacoustics' default path.

Run by hand (``make bench`` or ``.venv/bin/python benchmarks/bench_simulated.py``); it
prints numbers and writes nothing outside a temporary directory.

Scenes: static, 2 directional sources, 10 s at 24 kHz. Rooms sampled with a seeded
Generator:
  paper      every side U[5, 15] m, RT60 U[0.5, 1.0] s
  realistic  floor U[5, 15] m, height U[2.5, 4] m, RT60 U[0.5, 1.0] s
Array: mic4 side U[0.10, 0.13] m (or FOA) at height U[1.0, 1.2] m, 1 m from the walls,
random yaw; sources 1-3 m from the array, 0.5 m from every wall.

Measured, each configuration in its own worker process (one thread each):
  * scenes/s per core end to end: recipe -> dry clips from disk -> RIRs -> FFT
    convolution -> levels, labels -> HDF5 + JSON shard on disk (tsel_data.render.mix,
    tsel_data.store.writer);
  * the same for pyroomacoustics' default path (pra.inverse_sabine absorption and max
    order, ShoeBox, room.simulate(return_premix=True)) on the same recipes, written the
    same way; and the ratio;
  * peak RSS of each worker;
  * T30 / requested RT60 of the first RIR (omni / W, Schroeder -5..-35 dB) over more
    rooms: min, median, max, share within ±10 %;
  * 2 worker processes against 1 on the same scenes;
  * a scene against its own convolution (``--sections ratio``): CPU time of a whole
    ``render_scene`` (clips from the cache, RIRs, convolution, levels, labels, record;
    no shard writing) over the CPU time of the static convolutions inside it
    (timevarying.render_static as render/mix.py calls it), hybrid, mic4, median of
    ``--repeats``. Once with the render workers' memory settings
    (executors.prepare_worker: freed memory kept for reuse) and once with glibc's
    defaults, where every large buffer comes fresh from the kernel (page faults), as in
    a process that does not set them up (issue 25's audit measured this way).
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS", "PRA_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import multiprocessing as mp  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import soundfile as sf  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from tsel_data.acoustics import simulate_rirs  # noqa: E402
from tsel_data.acoustics.metrics import t30  # noqa: E402
from tsel_data.core.geometry import Room, array_to_room  # noqa: E402
from tsel_data.receivers import ArrayPose  # noqa: E402
from tsel_data.scene.recipe import SceneRecipe, Source  # noqa: E402

FS = 24000
DURATION = 10.0
N_CLIPS = 96  # more than the loader's cache, so clips really come from disk
SHARD = 10  # scenes per shard


# --- scenes --------------------------------------------------------------------------------
def sample_room(rng: np.random.Generator, family: str) -> Room:
    if family == "paper":
        dims = rng.uniform(5.0, 15.0, 3)
    else:
        dims = np.r_[rng.uniform(5.0, 15.0, 2), rng.uniform(2.5, 4.0)]
    return Room(tuple(float(d) for d in np.round(dims, 3)), float(round(rng.uniform(0.5, 1.0), 3)))


def sample_scene(rng, index: int, family: str, fmt: str, method: str, clip_dir: str) -> SceneRecipe:
    room = sample_room(rng, family)
    dims = np.asarray(room.dims)
    centre = np.r_[rng.uniform(1.0, dims[:2] - 1.0), rng.uniform(1.0, 1.2)]
    array = ArrayPose(fmt, tuple(np.round(centre, 3)), float(round(rng.uniform(-180, 180), 2)),
                      float(round(rng.uniform(0.10, 0.13), 4)) if fmt == "mic4" else None)
    positions = []
    while len(positions) < 2:
        d, az, el = rng.uniform(1.0, 3.0), rng.uniform(-np.pi, np.pi), rng.uniform(-0.6, 0.6)
        p = centre + d * np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
        if np.all(p >= 0.5) and np.all(p <= dims - 0.5):
            positions.append(tuple(float(v) for v in np.round(p, 3)))
    clips = rng.choice(N_CLIPS, 2, replace=False)
    sources = tuple(
        Source(role="target" if k == 0 else "interferer", clip_id=f"c{c}", audio=os.path.join(clip_dir, f"c{c}.wav"),
               captions=("noise",), position=positions[k], tir_db=None if k == 0 else float(rng.uniform(-5, 5)))
        for k, c in enumerate(clips)
    )
    return SceneRecipe(scene_id=f"{family}-{fmt}-{index:05d}", split="bench", index=index, seed=int(rng.integers(2**31)),
                       scenario="two-directional", query="noise", array=array, sources=sources, room=room, fs=FS,
                       duration=DURATION, rir_method=method)


def scenes(n: int, family: str, fmt: str, method: str, clip_dir: str, seed: int = 0) -> list[SceneRecipe]:
    # same seed for every method: the baseline sees exactly the same recipes
    rng = np.random.default_rng([seed, {"paper": 0, "realistic": 1}[family], {"mic4": 0, "foa": 1}[fmt]])
    return [sample_scene(rng, i, family, fmt, method, clip_dir) for i in range(n)]


def make_clips(clip_dir: str) -> None:
    rng = np.random.default_rng(1)
    n = int(DURATION * FS)
    t = np.arange(n) / FS
    for c in range(N_CLIPS):
        # noise bursts with a slow on/off envelope, so the activity labels have something to do
        env = (np.sin(2 * np.pi * rng.uniform(0.1, 0.5) * t + rng.uniform(0, 6)) > -0.3).astype(np.float32)
        sf.write(os.path.join(clip_dir, f"c{c}.wav"), 0.1 * rng.standard_normal(n).astype(np.float32) * env, FS,
                 subtype="FLOAT")


# --- rendering -----------------------------------------------------------------------------
def render_ours(recipe: SceneRecipe):
    from tsel_data.render.mix import render_scene

    return render_scene(recipe)


def render_pra_default(recipe: SceneRecipe):
    """pyroomacoustics as a user writes it: inverse_sabine, ShoeBox, room.simulate()."""
    import pyroomacoustics as pra

    from tsel_data.corpus.audio import active_rms, frame_activity, load_clip_cached
    from tsel_data.render.mix import source_labels
    from tsel_data.store.scene import Scene

    np.random.seed(recipe.seed % 2**32)  # pra's generator is numpy's global one
    dims = list(recipe.room.dims)
    e_abs, order = pra.inverse_sabine(recipe.room.rt60, dims)
    room = pra.ShoeBox(dims, fs=FS, materials=pra.Material(e_abs), max_order=order)
    room.add_microphone_array(array_to_room(recipe.array.mics(), recipe.array.centre, recipe.array.yaw).T)
    dry = []
    for s in recipe.sources:
        x = load_clip_cached(s.audio, FS, DURATION, s.offset)
        dry.append(x)
        room.add_source(list(s.position), signal=x)
    n = recipe.n_samples
    images = room.simulate(return_premix=True)[..., :n].astype(np.float32)  # [S, C, T]
    active = np.stack([frame_activity(x, FS, recipe.label_hop, recipe.n_frames, recipe.activity_threshold_db) for x in dry])
    levels = np.array([active_rms(images[k], active[k], FS, recipe.label_hop) for k in range(len(images))])
    want = 10 ** (recipe.target_level_dbfs / 20) * np.array([1.0] + [10 ** (-s.tir_db / 20) for s in recipe.sources[1:]])
    mix = np.tensordot((want / levels).astype(np.float32), images, axes=1)
    mix *= np.float32(min(1.0, 0.99 / float(np.abs(mix).max())))
    labels = [source_labels(recipe, k) for k in range(len(recipe.sources))]
    az, el, dist = (np.stack([lab[i] for lab in labels]) for i in range(3))
    return Scene(recipe.scene_id, recipe.split, recipe.index, recipe.query, mix, az, el, dist, active,
                 recipe.array.mics().astype(np.float32), recipe.fs, recipe.label_hop, recipe.array.format)


def run_scenes(args) -> dict:
    """Render and write ``recipes`` in this process; returns timing and peak RSS."""
    recipes, renderer, out_dir = args
    from tsel_data.store.writer import write_shard

    render = {"ours": render_ours, "pra": render_pra_default}[renderer]
    # warm-up outside the timer: imports, FFT plans (a long-running worker pays these once)
    import pyroomacoustics  # noqa: F401

    import tsel_data.render.mix  # noqa: F401
    if renderer == "ours":
        render(recipes[0])
    attrs = {"fs": FS, "label_hop": 0.1, "format": recipes[0].array.format,
             "channel_names": list(recipes[0].array.channel_names())}
    t0 = time.perf_counter()
    buf = []
    for r in recipes:
        buf.append(render(r))
        if len(buf) == SHARD or r is recipes[-1]:
            write_shard(out_dir, f"{renderer}-{recipes[0].scene_id}", r.index // SHARD, buf, attrs)
            buf = []
    elapsed = time.perf_counter() - t0
    rir_ms = float("nan")
    if renderer == "ours":  # the simulator's share of the time: RIRs alone, same recipes
        t1 = time.perf_counter()
        for r in recipes:
            simulate_rirs(r.room, r.array, np.array([s.position for s in r.sources]), FS, r.rir_method, r.seed)
        rir_ms = (time.perf_counter() - t1) / len(recipes) * 1000
    return {"n": len(recipes), "seconds": elapsed, "rir_ms": rir_ms,
            "rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def in_worker(fn, args, processes: int = 1):
    """Run ``fn`` on each of ``args`` in a fresh pool (fresh processes: clean peak RSS), each
    process set up as the toolkit's render workers are (executors.prepare_worker)."""
    from tsel_data.runtime.pool import prepare_worker

    ctx = mp.get_context("fork")
    with ctx.Pool(processes, initializer=prepare_worker, maxtasksperchild=1) as pool:
        return pool.map(fn, args)


# --- T30 ----------------------------------------------------------------------------------
def scene_vs_convolution(args) -> dict:
    """CPU ms per scene of ``render_scene`` on ``recipes`` and of the convolutions inside
    it, in this process (one worker of :func:`in_worker` or :func:`in_plain_worker`)."""
    recipes = args
    import tsel_data.render.mix as render

    spent = [0.0]
    convolve_static = render.render_static

    def timed(*a, **k):
        t = time.process_time()
        y = convolve_static(*a, **k)
        spent[0] += time.process_time() - t
        return y

    render.render_static = timed
    for r in recipes:  # warm-up: the clip cache, FFT plans, freed memory to reuse
        render.render_scene(r)
    spent[0] = 0.0
    t0 = time.process_time()
    for r in recipes:
        render.render_scene(r)
    total = time.process_time() - t0
    return {"scene_ms": total / len(recipes) * 1000, "conv_ms": spent[0] / len(recipes) * 1000}


def _one_thread() -> None:
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def in_plain_worker(fn, args):
    """As :func:`in_worker`, one thread, but glibc's default memory settings."""
    ctx = mp.get_context("fork")
    with ctx.Pool(1, initializer=_one_thread, maxtasksperchild=1) as pool:
        return pool.map(fn, args)


def ratio_table(opts, clip_dir: str) -> None:
    print("\n== a scene against its own convolution (CPU ms per scene, hybrid, mic4) ==")
    print(f"{'rooms':10s} {'memory':26s} {'scene':>7s} {'convolution':>12s} {'ratio':>6s}  (each repeat's ratio)")
    for family in ("paper", "realistic"):
        recs = scenes(opts.scenes, family, "mic4", "hybrid", clip_dir, seed=opts.seed + 2)
        runs = {"render workers' (reuse)": [], "glibc defaults": []}
        for _ in range(opts.repeats):  # interleaved: both settings see the same load
            runs["render workers' (reuse)"] += in_worker(scene_vs_convolution, [recs])
            runs["glibc defaults"] += in_plain_worker(scene_vs_convolution, [recs])
        for memory, res in runs.items():
            ratios = [r["scene_ms"] / r["conv_ms"] for r in res]
            print(f"{family:10s} {memory:26s} {np.median([r['scene_ms'] for r in res]):7.1f} "
                  f"{np.median([r['conv_ms'] for r in res]):12.1f} {np.median(ratios):5.2f}x  "
                  f"({', '.join(f'{x:.2f}' for x in ratios)})")


def t30_ratios(args) -> list[float]:
    family, method, n, seed = args
    rng = np.random.default_rng([seed, 7, {"paper": 0, "realistic": 1}[family]])
    out = []
    for i in range(n):
        r = sample_scene(rng, i, family, "mic4", method, "")
        pts = np.array([s.position for s in r.sources])
        rs = simulate_rirs(r.room, r.array, pts, FS, method=method, seed=r.seed)
        measured = rs.rt60_measured if rs.rt60_measured is not None else t30(rs.rirs[0, 0], FS)
        out.append(measured / r.room.rt60)
    return out


def summarise(ratios) -> str:
    a = np.asarray(ratios)
    return (f"n={len(a):3d}  min {a.min():.3f}  median {np.median(a):.3f}  max {a.max():.3f}  "
            f"within ±10%: {np.mean(np.abs(a - 1) <= 0.10) * 100:5.1f}%")


def speed_table(opts, clip_dir: str, out_dir: str) -> None:
    print("\n== end to end (recipe -> shard on disk), per core ==")
    print("(other processes share the cores: the load average before each row is shown)")
    print(f"{'rooms':10s} {'format':6s} {'method':16s} {'scenes':>6s} {'s/scene':>8s} {'scenes/s':>9s} "
          f"{'RIRs ms':>8s} {'peak RSS':>9s} {'load':>5s}  vs pyroomacoustics")
    for family in ("paper", "realistic"):
        base = None
        rows = [("mic4", "pyroomacoustics", opts.pra_scenes), ("mic4", "hybrid", opts.scenes),
                ("mic4", "ism", opts.ism_scenes), ("foa", "hybrid", opts.scenes), ("foa", "ism", opts.ism_scenes)]
        for fmt, method, n in rows:
            if n <= 0:
                continue
            renderer = "pra" if method == "pyroomacoustics" else "ours"
            recs = scenes(n, family, fmt, method, clip_dir, seed=opts.seed)
            load = os.getloadavg()[0]
            (res,) = in_worker(run_scenes, [(recs, renderer, out_dir)])
            per = res["seconds"] / res["n"]
            if method == "pyroomacoustics":
                base = per
                note = "(default path: inverse_sabine + room.simulate)"
            else:
                note = f"{base / per:6.1f}x" if (base and fmt == "mic4") else ""
            print(f"{family:10s} {fmt:6s} {method:16s} {res['n']:6d} {per:8.3f} {1 / per:9.2f} "
                  f"{res['rir_ms']:8.1f} {res['rss_mib']:6.0f}MiB {load:5.2f}  {note}")


def worker_scaling(opts, clip_dir: str, out_dir: str) -> None:
    print("\n== 2 workers vs 1 (hybrid, mic4, paper rooms) ==")
    n2 = max(2 * opts.scenes, 20)
    recs = scenes(n2, "paper", "mic4", "hybrid", clip_dir, seed=opts.seed + 1)
    half = n2 // 2
    targets = [("shards on disk", out_dir)]
    if os.path.isdir("/dev/shm"):
        # the same in memory: separates the CPU scaling from the disk's write bandwidth
        targets.append(("shards in /dev/shm", tempfile.mkdtemp(prefix="tsel-bench-", dir="/dev/shm")))
    for label, target in targets:
        # interleaved repeats, best of each: other jobs on a shared machine only ever slow
        # a run down, so the fastest repeat is the closest to the machine's own speed
        one, two, loads = [], [], []
        for _ in range(opts.repeats):
            loads.append(os.getloadavg()[0])
            (r1,) = in_worker(run_scenes, [(recs, "ours", target)], processes=1)
            r2 = in_worker(run_scenes, [(recs[:half], "ours", target), (recs[half:], "ours", target)], processes=2)
            one.append(n2 / r1["seconds"])
            two.append(n2 / max(r["seconds"] for r in r2))
        print(f"{label:20s} {n2} scenes, best of {opts.repeats}: 1 worker {max(one):6.2f} scenes/s, 2 workers "
              f"{max(two):6.2f} scenes/s: speed-up {max(two) / max(one):.2f}x   "
              f"(all ratios {', '.join(f'{b / a:.2f}' for a, b in zip(one, two))}; load {min(loads):.1f}-{max(loads):.1f})")
        if target != out_dir:
            shutil.rmtree(target, ignore_errors=True)


def t30_table(opts) -> None:
    print("\n== T30 / requested RT60 (first RIR, omni; Schroeder -5..-35 dB) ==")
    for family in ("paper", "realistic"):
        for method, n in (("hybrid", opts.t30_rooms), ("ism", opts.t30_rooms_slow),
                          ("pyroomacoustics", opts.t30_rooms_slow)):
            if n <= 0:
                continue
            chunks = [(family, method, n // 2, opts.seed), (family, method, n - n // 2, opts.seed + 1000)]
            ratios = sum(in_worker(t30_ratios, chunks, processes=2), [])
            print(f"{family:10s} {method:16s} {summarise(ratios)}")


# --- main ------------------------------------------------------------------------------------
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=int, default=30, help="timed scenes per configuration, our methods")
    ap.add_argument("--pra-scenes", type=int, default=8, help="timed scenes per room family, pyroomacoustics")
    ap.add_argument("--ism-scenes", type=int, default=8, help="timed scenes per room family, rir_method=ism")
    ap.add_argument("--t30-rooms", type=int, default=100, help="rooms per family for the hybrid T30 distribution")
    ap.add_argument("--t30-rooms-slow", type=int, default=40, help="rooms per family for ism / pyroomacoustics T30")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=3, help="repeats of the 2-vs-1 worker comparison and of the ratio")
    ap.add_argument("--sections", default="speed,workers,t30,ratio",
                    help="comma-separated subset of speed,workers,t30,ratio")
    opts = ap.parse_args()

    print(f"bench_simulated: {DURATION:.0f} s scenes at {FS} Hz, 2 static sources, 1 thread per worker, "
          f"{os.cpu_count()} cores")
    with tempfile.TemporaryDirectory(prefix="tsel-bench-") as tmp:
        clip_dir = os.path.join(tmp, "clips")
        os.makedirs(clip_dir)
        make_clips(clip_dir)
        out_dir = os.path.join(tmp, "out")

        # warm-up (imports, FFT plans) so the first configuration is not penalised
        in_worker(run_scenes, [(scenes(1, "paper", "mic4", "hybrid", clip_dir, seed=99), "ours", out_dir)])

        sections = set(opts.sections.split(","))
        if "speed" in sections:
            speed_table(opts, clip_dir, out_dir)
        if "workers" in sections:
            worker_scaling(opts, clip_dir, out_dir)
        if "t30" in sections:
            t30_table(opts)
        if "ratio" in sections:
            ratio_table(opts, clip_dir)


if __name__ == "__main__":
    main()
