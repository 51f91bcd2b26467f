"""Planning speed per pairing mode on real manifests (docs/queries.md quotes its output).

    .venv/bin/python benchmarks/bench_planning.py --corpus-dir ../shared/audiocaps [--scenes 100000] [--workers 1]

Plans ``--scenes`` train scenes of ``paper-sim-2dir`` from the manifests alone
(``corpus.check = "none"``: no audio needed) for each setting below, and prints the time
to read the manifests and build the caption index, and the time to plan (recipes as
JSON lines, as ``tsel plan`` writes them), with the share of interferers each pairing
produced (a band the split cannot fill falls back to random pairing).
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.plan.sampler import plan_split_json, prepare_views  # noqa: E402
from tsel_data.store.layout import Layout  # noqa: E402

SETTINGS = {
    "random, lexicon (default)": [],
    "random, words": ['scene.similarity="words"'],
    "random, tfidf": ['scene.similarity="tfidf"'],
    "hard, tfidf": ['scene.similarity="tfidf"', 'scene.pairing="hard"'],
    "easy, tfidf": ['scene.similarity="tfidf"', 'scene.pairing="easy"'],
    "hard + same-kind 0.2, tfidf": ['scene.similarity="tfidf"', 'scene.pairing="hard"',
                                    "scene.same_kind_distractors=0.2",
                                    'scene.query=["choose", ["caption", "relational"]]'],
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus-dir", required=True)
    ap.add_argument("--scenes", type=int, default=100_000)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--only", help="run only settings whose name contains this")
    args = ap.parse_args()
    print(f"{'setting':<30}{'index (s)':>10}{'plan (s)':>10}{'ms/scene':>10}  interferers drawn")
    for name, over in SETTINGS.items():
        if args.only and args.only not in name:
            continue
        cfg = load_config(preset="paper-sim-2dir", corpus_dir=args.corpus_dir,
                          overrides=['corpus.check="none"', *over], splits={"train": args.scenes, "val": 0, "test": 0})
        t0 = time.perf_counter()
        _, views = prepare_views(cfg, Layout(tempfile.mkdtemp(prefix="tsel-bench-")), args.workers)
        t1 = time.perf_counter()
        lines = plan_split_json(cfg, "train", views["train"], args.workers)
        t2 = time.perf_counter()
        kinds = collections.Counter()
        for line in lines:
            qp = json.loads(line).get("query_plan")
            kinds.update(qp["pairings"][1:] if qp else ["random"])
        total = sum(kinds.values())
        mix = ", ".join(f"{k} {100 * v / total:.1f}%" for k, v in kinds.most_common())
        print(f"{name:<30}{t1 - t0:>10.1f}{t2 - t1:>10.1f}{1e3 * (t2 - t1) / len(lines):>10.2f}  {mix}", flush=True)


if __name__ == "__main__":
    main()
