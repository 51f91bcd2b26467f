"""How often the nearer source is the louder one, under each level model (docs/queries.md).

Run by hand (``.venv/bin/python benchmarks/measure_level_models.py``); prints numbers.

Renders N scenes of the demo corpus (two directional sources, the ``realistic-sim`` rooms)
with ``scene.levels = "tir"`` (the paper's: interferers ``tir_db`` ~ U[-5, 5] dB below the
target whatever the distance) and ``"distance"`` (levels at 1 m ~ U[-5, 5] dB, the level at
the array from the room; and once with every source as loud at 1 m), and counts how often
the source nearer the array is the louder one in the rendered mixture: how often a
"nearest" / "farthest" answer is also the "loudest" / "quietest" one.
"""
from __future__ import annotations

import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.plan.sampler import plan_roots, plan_scene, prepare_views  # noqa: E402
from tsel_data.render.mix import render_scene  # noqa: E402
from tsel_data.store.layout import Layout  # noqa: E402


def agreement(model: str, n: int, home: str, extra=()) -> float:
    cfg = load_config(preset="realistic-sim", corpus_dir="builtin:demo", splits={"train": n, "val": 0, "test": 0},
                      overrides=[f'scene.levels="{model}"', "audio.duration=4.0", *extra])
    _, views = prepare_views(cfg, Layout(home))
    roots = plan_roots(cfg, Layout(home))
    agree = 0
    for i in range(n):
        r = render_scene(plan_scene(cfg, "train", i, views["train"]), roots)
        (a, b) = r.record.sources[:2]
        nearer_is_louder = (np.nanmean(r.distance[0]) < np.nanmean(r.distance[1])) == (a.level_dbfs > b.level_dbfs)
        agree += nearer_is_louder
    return agree / n


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 60
    home = tempfile.mkdtemp(prefix="tsel-levels-")
    print(f"{n} two-source scenes (realistic-sim rooms): the nearer source is the louder one in")
    for model, extra, note in (("tir", (), ""), ("distance", (), " (levels at 1 m U[-5, 5] dB)"),
                               ("distance", ("sources.power=0.0",), " (every source as loud at 1 m)")):
        print(f"  scene.levels = {model!r:<11} {100 * agreement(model, n, home, extra):.0f} % of them{note}")


if __name__ == "__main__":
    main()
