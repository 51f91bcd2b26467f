"""Why a row of the table is what it is: its test errors split by what the scenes hold.

    python -m tsel_baseline.diagnose baseline-out

For the synthetic demo corpus only (it needs ``corpus/clips.json``, which names each
clip's sound type and whether it is continuous or intermittent). For each measured row
it groups the per-scene errors that :func:`tsel_data.tools.evaluate.evaluate` returned (no
metric of its own: a group's MAE is the mean of its scenes' errors, as evaluate pools
clip units) by

- whether the target and the interferer are the *same sound type* (then no query can
  tell them apart: the scene is unanswerable), and
- the (target, interferer) temporal kinds: two continuous sounds overlap all the time,
  so only the spectrum (which GCC-PHAT whitens away) says which direction is which;
- the target's sound type (narrow-band sounds give a direction in few bands).

It also counts same-type scenes in every split of every dataset.
"""
from __future__ import annotations

import argparse
import json
import os
from collections import defaultdict

import numpy as np

import tsel_data
from tsel_data.store import list_splits


def clip_kinds(corpus: str) -> dict:
    """youtube_id -> (sound type, "continuous" | "intermittent") from the demo corpus."""
    with open(os.path.join(corpus, "clips.json"), encoding="utf-8") as f:
        return {c["youtube_id"]: (c["kind"], c["temporal"]) for c in json.load(f)["clips"]}


def scene_kinds(root: str, split: str, kinds: dict) -> dict:
    """scene_id -> [(type, temporal) per source], from the records (clip ids are youtube_id_start)."""
    out = {}
    for rec in tsel_data.open_dataset(root, split).records():
        out[rec["scene_id"]] = [kinds.get(s["clip_id"].rsplit("_", 1)[0], ("?", "?")) for s in rec["sources"]]
    return out


def same_type_share(root: str, kinds: dict) -> dict:
    """split -> (scenes whose first two sources share a sound type, scenes)."""
    out = {}
    for split in list_splits(root):
        sk = scene_kinds(root, split, kinds)
        out[split] = (sum(1 for v in sk.values() if len(v) > 1 and v[0][0] == v[1][0]), len(sk))
    return out


def breakdown(row: dict, root: str, kinds: dict) -> dict:
    """Group MAE of a row's per-scene errors: {group name: (scenes, MAE deg)}."""
    sk = scene_kinds(root, "test", kinds)
    groups = defaultdict(list)
    for s in row["per_scene"]:
        k = sk[s["scene_id"]]
        if len(k) < 2:
            continue
        groups["same type" if k[0][0] == k[1][0] else "different types"].append(s["error"])
        groups[f"target {k[0][1]}, interferer {k[1][1]}"].append(s["error"])
        groups[f"target type: {k[0][0]}"].append(s["error"])
    return {g: (len(v), float(np.mean(v))) for g, v in sorted(groups.items())}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m tsel_baseline.diagnose", description=__doc__.splitlines()[0])
    ap.add_argument("out", help="the experiment's --out folder")
    a = ap.parse_args(argv)
    kinds = clip_kinds(os.path.join(a.out, "corpus"))
    data = os.path.join(a.out, "data")
    for name in sorted(os.listdir(data)):
        shares = same_type_share(os.path.join(data, name), kinds)
        print(f"{name}: scenes whose target and interferer are the same sound type: "
              + ", ".join(f"{s} {n}/{t} ({100 * n / max(t, 1):.1f}%)" for s, (n, t) in shares.items()))
    rows_dir = os.path.join(a.out, "rows")
    for fn in sorted(os.listdir(rows_dir)):
        with open(os.path.join(rows_dir, fn), encoding="utf-8") as f:
            row = json.load(f)
        if row["output"] != "clip":
            continue
        print(f"\n{row['setting']}: test MAE {row['mae']:.2f}°")
        for g, (n, mae) in breakdown(row, os.path.join(data, row["dataset"]), kinds).items():
            print(f"  {g:<46}{n:>5} scenes  MAE {mae:6.2f}°")


if __name__ == "__main__":
    main()
