"""What the microphones as built ([hardware]) cost a render: the same scenes with and without.

    .venv/bin/python benchmarks/bench_hardware.py [--scenes 12] [--profile mems] [--format mic4]

Scenes of the demo preset (10 s, the demo corpus synthesised in a temporary folder), with
``hardware.profile`` set; each is rendered as planned and with its hardware taken out of
the recipe (ideal capsules), interleaved scene by scene (the machine may be shared; pairs
cancel its drift). Prints the medians and the median of the paired ratios, and the
layer's own seconds (``with - without``) per scene.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.corpus.demo import synth_corpus  # noqa: E402
from tsel_data.job.onthefly import SceneSource  # noqa: E402
from tsel_data.render.mix import render_scene  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=12)
    ap.add_argument("--profile", default="mems")
    ap.add_argument("--format", default="mic4")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        synth_corpus(os.path.join(tmp, "demo"), seed=0)
        cfg = load_config(preset="demo", corpus_dir=os.path.join(tmp, "demo"), splits={"train": a.scenes},
                          overrides=[f'hardware.profile="{a.profile}"', f'scene.format="{a.format}"'])
        source = SceneSource(cfg, "train", home=tmp)
        roots = source.view.roots
        render_scene(source.recipe(0), roots)  # warm: clips, kernels, caches
        built, ideal = [], []
        for i in range(a.scenes):
            recipe = source.recipe(i)
            for r, out in ((recipe, built), (replace(recipe, hardware=()), ideal)):
                t = time.perf_counter()
                render_scene(r, roots)
                out.append(time.perf_counter() - t)
    built, ideal = np.array(built), np.array(ideal)
    print(f"{a.format}, hardware.profile={a.profile}, {a.scenes} scenes of 10 s: with {np.median(built):.3f} s, "
          f"without {np.median(ideal):.3f} s per scene, ratio {np.median(built / ideal):.2f} (median of pairs); "
          f"the layer {np.median(built - ideal) * 1000:.0f} ms per scene")


if __name__ == "__main__":
    main()
