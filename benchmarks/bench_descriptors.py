"""Benchmark: what measuring the acoustic descriptors (output.descriptors) adds to a scene.

Run by hand (``.venv/bin/python benchmarks/bench_descriptors.py [--scenes N]``); prints
numbers, writes only to a temporary directory.

Scenes of the ``demo`` preset (10 s, mic4, two or three sources, RT60 0.2-1.0 s) and of
``demo-moving`` (FOA, moving sources from the demo bank), planned once; each scene's
recipe is rendered with ``descriptors`` on and off, interleaved (the clip cache warm), and
the ratio of the two times is taken per scene: its median, and the milliseconds the
descriptors add per directional source.
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "PRA_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.plan.sampler import plan_scene, prepare_views  # noqa: E402
from tsel_data.render.scenes import render_recipe  # noqa: E402
from tsel_data.scene.recipe import plan_roots  # noqa: E402
from tsel_data.store.layout import Layout  # noqa: E402


def timed(recipe, roots) -> float:
    t = time.perf_counter()
    render_recipe(recipe, roots)
    return time.perf_counter() - t


def measure(preset: str, n: int, home: Layout) -> None:
    cfg = load_config(preset=preset, splits={"train": 0, "val": 0, "test": n})
    _, views = prepare_views(cfg, home, progress=False)
    roots = plan_roots(cfg, home)
    ratios, added = [], []
    for i in range(n):
        on = plan_scene(cfg, "test", i, views["test"])
        off = replace(on, descriptors=False)
        render_recipe(on, roots)  # warm: clips decoded, RIR code paths loaded
        t_on, t_off = [], []
        for _ in range(3):
            t_off.append(timed(off, roots))
            t_on.append(timed(on, roots))
        a, b = min(t_on), min(t_off)
        ratios.append(a / b)
        added.append((a - b) / sum(s.spatial == "directional" for s in on.sources))
    print(f"{preset:12s} {n} scenes: render with descriptors / without, median {np.median(ratios):.3f} "
          f"(range {min(ratios):.3f}-{max(ratios):.3f}); {1000 * np.median(added):.2f} ms per directional source")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", type=int, default=12)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        home = Layout(tmp)
        for preset in ("demo", "demo-moving"):
            measure(preset, args.scenes, home)


if __name__ == "__main__":
    main()
