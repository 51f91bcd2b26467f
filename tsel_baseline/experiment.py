"""The baseline experiment, one command: make the data, train, predict, score, print one table.

    python -m tsel_baseline.experiment --out baseline-out

Steps (each skipped when its output is already there, so a re-run only redoes what is
missing): a synthetic captioned corpus (``tsel corpus synth``), three datasets made with
``tsel generate`` from the paper's presets (scaled down, see ``DATASETS``), features once
per split, one model per table row, predictions as JSONL scored by
:func:`tsel_data.evaluate.evaluate`. Results: ``OUT/results.json`` and ``OUT/table.md``.
"""
from __future__ import annotations

import os

# Passive OpenMP waiting: on a machine where other processes also run, torch's
# spinning threads otherwise slow training down ~10x (measured on 2 cores).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402
import torch  # noqa: E402

import tsel_data  # noqa: E402

from .data import precompute  # noqa: E402
from .features import FeatureConfig  # noqa: E402
from .model import ModelConfig  # noqa: E402
from .predict import predict, score, shuffled_queries  # noqa: E402
from .text import make_text_encoder  # noqa: E402
from .train import TrainConfig, fit, set_threads  # noqa: E402

CORPUS_CLIPS = (20, 3, 4)  # clips per sound type in train, val, test (15 types)


@dataclass
class DatasetSpec:
    """A dataset of the experiment: a preset, scene counts per split, extra --set overrides."""

    preset: str
    splits: dict
    sets: list = field(default_factory=list)


DATASETS = {
    "1dir+1add": DatasetSpec("paper-sim-1dir-1add", {"train": 800, "val": 100, "test": 300}),
    "2dir": DatasetSpec("paper-sim-2dir", {"train": 1600, "val": 160, "test": 320}),
    # every source moves (the preset's default mixes static and moving ones)
    "moving": DatasetSpec("demo-moving", {"train": 800, "val": 80, "test": 160},
                          ['scene.motion="moving"', "output.shard_size=128"]),
}


@dataclass
class Setting:
    """One row of the table: which dataset, which features, which head, shuffled queries or not."""

    label: str
    dataset: str
    inputs: tuple
    output: str = "clip"
    epochs: int = 30
    control_of: str | None = None  # label of the trained row whose model this control reuses


SETTINGS = [
    Setting("1 dir + 1 add, GCC-PHAT + text", "1dir+1add", ("gcc",), epochs=30),
    Setting("2 dir, GCC-PHAT + text", "2dir", ("gcc",), epochs=24),
    Setting("2 dir, GCC-PHAT + log-mel + text", "2dir", ("gcc", "mel"), epochs=24),
    Setting("2 dir, same model, queries shuffled across test scenes (control)", "2dir", ("gcc", "mel"),
            control_of="2 dir, GCC-PHAT + log-mel + text"),
    Setting("2 dir, moving (demo-moving bank, frame-level)", "moving", ("iv", "mel"), output="frame", epochs=20),
]


def tsel(*args: str) -> None:
    """Run the tsel CLI of this Python (the public way to make data)."""
    cmd = [sys.executable, "-m", "tsel_data.cli", *args]
    r = subprocess.run(cmd)
    if r.returncode:
        raise SystemExit(f"failed ({r.returncode}): {' '.join(cmd)}")


def make_corpus(out: str, clips=CORPUS_CLIPS) -> str:
    path = os.path.join(out, "corpus")
    if not os.path.exists(os.path.join(path, "clips.json")):
        tsel("corpus", "synth", "--out", path, "--clips-per-type", ",".join(map(str, clips)))
    return path


def make_dataset(out: str, name: str, spec: DatasetSpec, corpus: str, workers: int) -> str:
    root = os.path.join(out, "data", name)
    if not os.path.exists(os.path.join(root, "dataset.json")):
        args = ["generate", "--preset", spec.preset, "--out", root, "--corpus-dir", corpus,
                "--workers", str(workers), "--quiet"]
        for split, n in spec.splits.items():
            args += ["--split", f"{split}={n}"]
        for s in spec.sets:
            args += ["--set", s]
        if os.path.exists(root):
            args.append("--resume")
        tsel(*args)
    return root


class CachedText:
    """A fitted text encoder with a per-caption cache: callable list[str] -> [N, D]."""

    def __init__(self, encoder):
        self.encoder = encoder
        self.cache: dict[str, np.ndarray] = {}

    def __call__(self, captions):
        missing = sorted({c for c in captions if c not in self.cache})
        if missing:
            self.cache.update(zip(missing, self.encoder.encode(missing)))
        return np.stack([self.cache[c] for c in captions])


def text_for(train_source, name: str, npz: str | None = None) -> CachedText:
    """A text encoder fitted on the training split's captions (every source's).

    train_source: a FeatureTable or SceneFeatures of the training split (only its labels are read).
    """
    enc = make_text_encoder(name, npz)
    enc.fit([c for i in range(len(train_source)) for cs in train_source.labels(i)["captions"] for c in cs])
    return CachedText(enc)


def run(out: str, text_name: str = "bow", text_npz: str | None = None, workers: int = 2, seed: int = 0,
        only: list[str] | None = None, log=None) -> list[dict]:
    log = log or (lambda msg: print(msg, flush=True))
    t_start = time.time()
    threads = set_threads(0)
    log(f"tsel-baseline experiment in {out} ({threads} torch threads, {workers} workers)")
    os.makedirs(os.path.join(out, "predictions"), exist_ok=True)
    os.makedirs(os.path.join(out, "features"), exist_ok=True)
    os.makedirs(os.path.join(out, "rows"), exist_ok=True)
    settings = [s for s in SETTINGS if not only or s.dataset in only]
    needed = sorted({s.dataset for s in settings}, key=list(DATASETS).index)
    timings = {}

    t = time.time()
    corpus = make_corpus(out)
    roots = {name: make_dataset(out, name, DATASETS[name], corpus, workers) for name in needed}
    timings["data"] = time.time() - t
    log(f"datasets ready ({timings['data']:.0f} s)")

    t = time.time()
    fcfg = FeatureConfig()
    tables = {(name, split): precompute(tsel_data.open_dataset(roots[name], split), fcfg, workers=workers,
                                        cache=os.path.join(out, "features", f"{name}-{split}.npz"), log=log)
              for name in needed for split in ("train", "val", "test")}
    timings["features"] = time.time() - t
    log(f"features ready ({timings['features']:.0f} s)")

    rows, models, texts = [], {}, {}
    for s in settings:
        t = time.time()
        name = s.dataset
        if name not in texts:
            texts[name] = text_for(tables[name, "train"], text_name, text_npz)
        text = texts[name]
        tag = s.label.split(",")[0].replace(" ", "") + "-" + "-".join(s.inputs) + ("-shuffled" if s.control_of else "")
        test = tables[name, "test"]
        queries = None
        if s.control_of:
            model = models[s.control_of]
            queries = shuffled_queries(test.queries, seed)
            history = []
        else:
            log(f"== {s.label}")

            def validate(m, _name=name, _tag=tag):
                preds = predict(m, tables[_name, "val"], text)
                return score(preds, roots[_name], "val", os.path.join(out, "predictions", f"{_tag}-val.jsonl")).overall["mae"]

            model, history = fit(ModelConfig(inputs=s.inputs, output=s.output,
                                             pool_frames=2 if s.output == "clip" else 1),
                                 TrainConfig(epochs=s.epochs, seed=seed, all_sources=True, augment=True),
                                 tables[name, "train"], text, validate=validate, log=log)
            models[s.label] = model
            os.makedirs(os.path.join(out, "models"), exist_ok=True)
            torch.save({"model_config": model.cfg.to_dict(), "state_dict": model.state_dict(),
                        "text": text.encoder.state()}, os.path.join(out, "models", f"{tag}.pt"))
        path = os.path.join(out, "predictions", f"{tag}-test.jsonl")
        result = score(predict(model, test, text, queries=queries), roots[name], "test", path)
        row = {"setting": s.label, "dataset": name, "inputs": list(s.inputs), "output": s.output,
               "text": text_name, "mae": result.overall["mae"], "acc10": result.overall["acc10"],
               "acc5": result.overall["acc5"], "acc20": result.overall["acc20"], "units": result.overall["units"],
               "predictions": path, "seconds": time.time() - t, "history": history,
               "per_scene": result.per_scene}
        rows.append(row)
        with open(os.path.join(out, "rows", f"{tag}.json"), "w") as f:
            json.dump(row, f, indent=1)
        log(f"   test MAE {row['mae']:.2f}°, acc@10 {100 * row['acc10']:.1f}%  ({row['seconds']:.0f} s)")
    timings["total"] = time.time() - t_start
    # the table shows every row measured in OUT so far (a run with --only adds its own)
    done = {}
    for fn in sorted(os.listdir(os.path.join(out, "rows"))):
        with open(os.path.join(out, "rows", fn)) as f:
            r = json.load(f)
        done[r["setting"]] = r
    table = format_table([done[s.label] for s in SETTINGS if s.label in done])
    log("\n" + table + f"\n\nwall time {timings['total'] / 60:.1f} min "
        f"(data {timings['data']:.0f} s, features {timings['features']:.0f} s)")
    with open(os.path.join(out, "table.md"), "w") as f:
        f.write(table + "\n")
    with open(os.path.join(out, "results.json" if not only else f"results-{'-'.join(only)}.json"), "w") as f:
        json.dump({"rows": rows, "only": only, "timings": timings, "text": text_name, "seed": seed,
                   "datasets": {k: vars(v) for k, v in DATASETS.items()}, "corpus_clips": CORPUS_CLIPS,
                   "features": fcfg.to_dict()}, f, indent=1)
    return rows


def format_table(rows: list[dict]) -> str:
    lines = ["| setting | MAE (°) | acc@10 |", "|---|---|---|"]
    lines += [f"| {r['setting']} | {r['mae']:.2f} | {100 * r['acc10']:.1f}% |" for r in rows]
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m tsel_baseline.experiment", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="baseline-out", help="working folder (data, features, predictions, results)")
    ap.add_argument("--text", default="bow", choices=("bow", "minilm", "precomputed"), help="text encoder")
    ap.add_argument("--text-npz", help="caption vectors for --text precomputed")
    ap.add_argument("--workers", type=int, default=2, help="processes for rendering and features")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", action="append", choices=list(DATASETS), help="run only the rows of this dataset")
    a = ap.parse_args(argv)
    run(a.out, a.text, a.text_npz, a.workers, a.seed, a.only)


if __name__ == "__main__":
    main()
