"""What a job-array task pays before it renders: reading its shards' recipes of a large plan.

    .venv/bin/python benchmarks/bench_jobarray.py --corpus-dir ../shared/audiocaps [--scenes 100000]

Plans ``--scenes`` train scenes of ``paper-sim-2dir`` from the manifests alone
(``corpus.check = "none"``: no audio needed) into a temporary folder, then measures, each
in a fresh process (wall time from the start of the measured call, peak RSS as VmHWM):

- baseline: every recipe of every split (``Plan.recipes`` of all shards: what each task read before);
- a task: the plan's config and the recipes of one shard range (``tsel render --shards
  A-B`` does this), for a range at the start, the middle and the end of the plan.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, REPO)

CHILD = r"""
import json, sys, time
sys.path.insert(0, {repo!r})
from tsel_data.job.shards import open_plan
out, which = {out!r}, {which!r}
t0 = time.perf_counter()
plan = open_plan(out)
if which == "whole":
    n = sum(len(r) for r in plan.recipes(plan.tasks))
else:
    k = {{"start": 0, "middle": len(plan.tasks) // 2, "end": len(plan.tasks) - 1}}[which]
    n = sum(len(r) for r in plan.recipes(plan.tasks[k:k + 1]))
dt = time.perf_counter() - t0
peak = [l for l in open("/proc/self/status") if l.startswith("VmHWM:")][0].split()[1]
print(json.dumps({{"seconds": dt, "rss": int(peak) * 1024, "recipes": n}}))
"""


def measure(out: str, which: str) -> dict:
    code = CHILD.format(repo=REPO, out=out, which=which)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(r.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus-dir", required=True)
    ap.add_argument("--scenes", type=int, default=100_000)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    from tsel_data.config import load_config
    from tsel_data.job.pipeline import plan_dataset

    root = tempfile.mkdtemp(prefix="tsel-bench-jobs-")
    try:
        out = os.path.join(root, "ds")
        cfg = load_config(preset="paper-sim-2dir", corpus_dir=args.corpus_dir, overrides=['corpus.check="none"'],
                          splits={"train": args.scenes, "val": 0, "test": 0})
        t0 = time.perf_counter()
        plan_dataset(cfg, out, workers=args.workers, progress=False)
        size = os.path.getsize(os.path.join(out, "plan", "train.jsonl"))
        print(f"plan: {args.scenes} scenes, {size / 1e6:.0f} MB of recipes, {time.perf_counter() - t0:.0f} s to plan")
        print(f"{'what':<34}{'recipes':>9}{'s':>8}{'MB':>8}{'time ratio':>12}")
        base = measure(out, "whole")
        print(f"{'baseline: every recipe':<34}{base['recipes']:>9}{base['seconds']:>8.2f}"
              f"{base['rss'] / 2**20:>8.0f}{1.0:>12.3f}")
        for which in ("start", "middle", "end"):
            m = measure(out, which)
            print(f"{'task: one shard, ' + which + ' of the plan':<34}{m['recipes']:>9}{m['seconds']:>8.2f}"
                  f"{m['rss'] / 2**20:>8.0f}{m['seconds'] / base['seconds']:>12.3f}")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
