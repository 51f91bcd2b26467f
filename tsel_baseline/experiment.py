"""The baseline experiment, one command: make the data, train, predict, score, print one table.

    python -m tsel_baseline.experiment --out baseline-out

With ``--recorded-test DIR`` (a recorded dataset, docs/recorded.md, e.g. STARSS23's
``tsel generate --preset starss23``), the model of the moving row (FOA, frame-level, trained
only on simulated scenes) also predicts that dataset's test split: the row "real rooms".

Steps (each skipped when its output is already there, so a re-run only redoes what is
missing): a synthetic captioned corpus (``tsel corpus synth``), three datasets made with
``tsel generate`` from the paper's presets (scaled down, see ``DATASETS``), features once
per split, one model per table row, predictions as JSONL scored by
:func:`tsel_data.tools.evaluate.evaluate`. Results: ``OUT/results.json`` and ``OUT/table.md``.
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
import multiprocessing  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402
import torch  # noqa: E402

import tsel_data  # noqa: E402

from .data import FeatureTable, precompute  # noqa: E402
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
    "1dir+1add": DatasetSpec("paper-sim-1dir-1add", {"train": 600, "val": 60, "test": 200}),
    "2dir": DatasetSpec("paper-sim-2dir", {"train": 1200, "val": 120, "test": 240}),
    # the 2dir scenes with a room that is not silent: pink diffuse noise at the DCASE
    # generator's 6-30 dB SNR against the target, and the microphones' own noise
    "2dir-noisy": DatasetSpec("paper-sim-2dir", {"train": 1200, "val": 120, "test": 240},
                              ['noise.diffuse="pink"', 'noise.diffuse_snr=["uniform", 6.0, 30.0]',
                               'noise.sensor="dbfs"', 'noise.sensor_level=["uniform", -90.0, -75.0]']),
    # every source moves (the preset's default mixes static and moving ones)
    "moving": DatasetSpec("demo-moving", {"train": 600, "val": 60, "test": 160},
                          ['scene.motion="moving"', "output.shard_size=128"]),
    # the same bank, rooms and counts with every source still: what motion itself costs
    "static-bank": DatasetSpec("demo-moving", {"train": 600, "val": 60, "test": 160},
                               ['scene.motion="static"', "output.shard_size=128"]),
}


@dataclass
class Setting:
    """One row of the table: which dataset, which model and features, which head, shuffled queries or not."""

    label: str
    dataset: str
    inputs: tuple
    output: str = "clip"
    epochs: int = 30
    fusion: str = "select"
    control_of: str | None = None  # label of the trained row whose model this control reuses
    extra: bool = False  # run only when its dataset is named with --only (not in `make baseline`)

    @property
    def tag(self) -> str:
        return f"{self.dataset}-{self.fusion}-{'-'.join(self.inputs)}" + ("-shuffled" if self.control_of else "")


# The rows `make baseline` reports: SelectNet (tsel_baseline.model), whose text picks the
# frames and bands to localise before anything is pooled. The cross-spectrum per band
# (xspec) replaces GCC-PHAT on mic4: GCC-PHAT sums all bands, so with two sources it shows
# two delays and nothing says which belongs to which sound.
SETTINGS = [
    Setting("1 dir + 1 add, xspec + log-mel + text (SelectNet)", "1dir+1add", ("xspec", "mel"), epochs=12),
    Setting("2 dir, xspec + text (SelectNet, no log-mel)", "2dir", ("xspec",), epochs=12),
    Setting("2 dir, xspec + log-mel + text (SelectNet)", "2dir", ("xspec", "mel"), epochs=12),
    Setting("2 dir, same model, queries shuffled across test scenes (control)", "2dir", ("xspec", "mel"),
            control_of="2 dir, xspec + log-mel + text (SelectNet)"),
    Setting("2 dir, noisy (pink diffuse noise at 6-30 dB SNR + sensor noise), xspec + log-mel + text (SelectNet)",
            "2dir-noisy", ("xspec", "mel"), epochs=12),
    Setting("2 dir, moving (demo-moving bank, FOA, frame-level), intensity vectors + log-mel + text (SelectNet)",
            "moving", ("iv", "mel"), output="frame", epochs=12),
    # a check of the moving row, `--only static-bank`: same model, bank and rooms, sources
    # still. tsel eval scores a static target once per scene (the circular mean of the
    # frame predictions over its active frames), so its unit differs from the moving row's.
    Setting("2 dir, static (demo-moving bank, FOA, frame-level model), intensity vectors + log-mel + text "
            "(SelectNet)", "static-bank", ("iv", "mel"), output="frame", epochs=12, extra=True),
]

# The paper's model (TselNet: clip-level concatenation of audio and text embeddings) on
# the paper's features; `--model paper`. Kept to show what the selection model changes.
PAPER_SETTINGS = [
    Setting("1 dir + 1 add, GCC-PHAT + text (paper's concat model)", "1dir+1add", ("gcc",), epochs=30,
            fusion="concat"),
    Setting("2 dir, GCC-PHAT + text (paper's concat model)", "2dir", ("gcc",), epochs=24, fusion="concat"),
    Setting("2 dir, GCC-PHAT + log-mel + text (paper's concat model)", "2dir", ("gcc", "mel"), epochs=24,
            fusion="concat"),
    Setting("2 dir, paper's concat model, queries shuffled across test scenes (control)", "2dir", ("gcc", "mel"),
            fusion="concat", control_of="2 dir, GCC-PHAT + log-mel + text (paper's concat model)"),
    Setting("2 dir, moving (demo-moving bank, FOA, frame-level), intensity vectors + log-mel + text "
            "(paper's model, frame head)", "moving", ("iv", "mel"), output="frame", epochs=20, fusion="concat"),
]

MODELS = {"select": SETTINGS, "paper": PAPER_SETTINGS}


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


def feature_config(settings: list[Setting], dataset: str) -> FeatureConfig:
    """The features every row on ``dataset`` reads, computed together from one STFT."""
    spatial = sorted({n for s in settings if s.dataset == dataset for n in s.inputs if n != "mel"})
    return FeatureConfig(spatial="+".join(spatial) if spatial else "auto")


def train_row(job: dict) -> list[dict]:
    """Train one row's model, predict and score its test split, and the controls that reuse
    the model. Runs in its own process when rows train side by side (``jobs`` > 1)."""
    set_threads(job["threads"])
    setting, out, name = job["setting"], job["out"], job["setting"].dataset
    tag = setting.tag
    log = job.get("log") or (lambda msg: print(f"[{tag}] {msg}", flush=True))
    t = time.time()
    tables = {split: FeatureTable.load(path) for split, path in job["tables"].items()}
    root = job["root"]
    text = text_for(tables["train"], job["text"], job["text_npz"])

    def validate(m):
        preds = predict(m, tables["val"], text)
        return score(preds, root, "val", os.path.join(out, "predictions", f"{tag}-val.jsonl")).overall["mae"]

    recorded = job.get("recorded")  # a recorded test set this row's model also predicts

    log(f"== {setting.label}")
    model, history = fit(ModelConfig(inputs=setting.inputs, output=setting.output, fusion=setting.fusion,
                                     pool_frames=2 if setting.fusion == "concat" and setting.output == "clip" else 1),
                         TrainConfig(epochs=setting.epochs, seed=job["seed"], all_sources=True, augment=True,
                                     threads=job["threads"]),
                         tables["train"], text, validate=validate, log=log)
    torch.save({"model_config": model.cfg.to_dict(), "state_dict": model.state_dict(),
                "text": text.encoder.state()}, os.path.join(out, "models", f"{tag}.pt"))
    rows = []
    for s in [setting, *job["controls"]]:
        queries = shuffled_queries(tables["test"].queries, job["seed"]) if s.control_of else None
        path = os.path.join(out, "predictions", f"{s.tag}-test.jsonl")
        result = score(predict(model, tables["test"], text, queries=queries), root, "test", path)
        row = {"setting": s.label, "dataset": name, "model": s.fusion, "inputs": list(s.inputs), "output": s.output,
               "text": job["text"], "mae": result.overall["mae"], "acc10": result.overall["acc10"],
               "acc5": result.overall["acc5"], "acc20": result.overall["acc20"], "units": result.overall["units"],
               "predictions": path, "seconds": time.time() - t, "history": [] if s.control_of else history,
               "per_scene": result.per_scene}
        with open(os.path.join(out, "rows", f"{s.tag}.json"), "w") as f:
            json.dump(row, f, indent=1)
        log(f"   {s.label}: test MAE {row['mae']:.2f}°, acc@10 {100 * row['acc10']:.1f}%  ({row['seconds']:.0f} s)")
        rows.append(row)
    if recorded:
        rows.append(recorded_row(model, text, setting, recorded, out, job["text"], log))
    return rows


def recorded_label(root: str) -> str:
    return f"real rooms: the moving row's model (trained on simulated FOA scenes only) on {os.path.basename(root)}"


def recorded_row(model, text, setting: Setting, recorded: dict, out: str, text_name: str, log) -> dict:
    """Predict and score a recorded dataset's test split with a model trained on rendered
    scenes; the row keeps the blind answers' scores beside it (tsel_data.tools.blind)."""
    table = FeatureTable.load(recorded["table"])
    path = os.path.join(out, "predictions", f"recorded-{setting.tag}-test.jsonl")
    result = score(predict(model, table, text), recorded["root"], recorded["split"], path)
    label = recorded_label(recorded["root"])
    row = {"setting": label, "dataset": "recorded", "model": setting.fusion, "inputs": list(setting.inputs),
           "output": setting.output, "text": text_name, "mae": result.overall["mae"],
           "acc10": result.overall["acc10"], "acc5": result.overall["acc5"], "acc20": result.overall["acc20"],
           "units": result.overall["units"], "predictions": path, "recorded": recorded["root"],
           "blind": {k: v["mae"] for k, v in result.blind.items()}, "blind_flag": result.blind_flag,
           "per_scene": result.per_scene}
    with open(os.path.join(out, "rows", f"recorded-{setting.tag}.json"), "w") as f:
        json.dump(row, f, indent=1)
    log(f"   {label}: test MAE {row['mae']:.2f}°, acc@10 {100 * row['acc10']:.1f}%"
        + (f"; {result.blind_flag}" if result.blind_flag else ""))
    return row


def run(out: str, text_name: str = "bow", text_npz: str | None = None, workers: int = 2, seed: int = 0,
        only: list[str] | None = None, model: str = "select", jobs: int = 2, log=None,
        recorded_test: str | None = None, recorded_split: str = "test") -> list[dict]:
    log = log or (lambda msg: print(msg, flush=True))
    t_start = time.time()
    cores = set_threads(0)
    jobs = max(1, min(jobs, cores))
    log(f"tsel-baseline experiment in {out} ({cores} cores, {workers} workers, {jobs} models trained at once)")
    for d in ("predictions", "features", "rows", "models"):
        os.makedirs(os.path.join(out, d), exist_ok=True)
    all_settings = MODELS[model]
    settings = [s for s in all_settings if (s.dataset in only if only else not s.extra)]
    needed = sorted({s.dataset for s in settings}, key=list(DATASETS).index)
    timings = {}

    t = time.time()
    corpus = make_corpus(out)
    roots = {name: make_dataset(out, name, DATASETS[name], corpus, workers) for name in needed}
    timings["data"] = time.time() - t
    log(f"datasets ready ({timings['data']:.0f} s)")

    t = time.time()
    paths = {}
    for name in needed:
        fcfg = feature_config(settings, name)
        for split in ("train", "val", "test"):
            path = os.path.join(out, "features", f"{name}-{fcfg.spatial}-{split}.npz")
            precompute(tsel_data.open_dataset(roots[name], split), fcfg, workers=workers, cache=path, log=log)
            paths[name, split] = path
    recorded = None
    if recorded_test:
        if "moving" not in needed:
            raise SystemExit("--recorded-test scores the moving row's model (FOA): run it with that row")
        fcfg = feature_config(settings, "moving")
        path = os.path.join(out, "features", f"recorded-{os.path.basename(os.path.normpath(recorded_test))}-"
                                             f"{fcfg.spatial}-{recorded_split}.npz")
        precompute(tsel_data.open_dataset(recorded_test, recorded_split), fcfg, workers=workers, cache=path, log=log)
        recorded = {"root": recorded_test, "split": recorded_split, "table": path}
    timings["features"] = time.time() - t
    log(f"features ready ({timings['features']:.0f} s)")

    # Rows train side by side, one process and one thread each: these small models use a
    # second thread poorly (measured: 2 threads no faster than 1 on 2 cores), a second
    # process well. Longest first, so the lanes end together.
    t = time.time()
    trained = [s for s in settings if not s.control_of]
    trained.sort(key=lambda s: -s.epochs * DATASETS[s.dataset].splits["train"] * (3 if s.output == "frame" else 1))
    todo = [{"setting": s, "controls": [c for c in settings if c.control_of == s.label], "out": out,
             "root": roots[s.dataset], "tables": {sp: paths[s.dataset, sp] for sp in ("train", "val", "test")},
             "text": text_name, "text_npz": text_npz, "seed": seed, "threads": max(1, cores // jobs),
             "recorded": recorded if s.dataset == "moving" and s.output == "frame" else None}
            for s in trained]
    if jobs == 1:
        rows = [r for job in todo for r in train_row(dict(job, log=log))]
    else:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            rows = [r for rs in pool.map(train_row, todo) for r in rs]
    timings["training"] = time.time() - t
    timings["total"] = time.time() - t_start
    # the table shows every row of this model measured in OUT so far (a run with --only adds its own)
    done = {}
    for fn in sorted(os.listdir(os.path.join(out, "rows"))):
        with open(os.path.join(out, "rows", fn)) as f:
            r = json.load(f)
        done[r["setting"]] = r
    shown = [done[s.label] for s in all_settings if s.label in done]
    shown += [r for label, r in done.items() if r.get("dataset") == "recorded"]
    table = format_table(shown)
    log("\n" + table + f"\n\nwall time {timings['total'] / 60:.1f} min (data {timings['data']:.0f} s, "
        f"features {timings['features']:.0f} s, training {timings['training']:.0f} s)")
    suffix = ("" if model == "select" else f"-{model}") + ("" if not only else "-" + "-".join(only))
    with open(os.path.join(out, f"table{suffix}.md"), "w") as f:
        f.write(table + "\n")
    with open(os.path.join(out, f"results{suffix}.json"), "w") as f:
        json.dump({"rows": rows, "model": model, "only": only, "timings": timings, "text": text_name, "seed": seed,
                   "datasets": {k: vars(v) for k, v in DATASETS.items()}, "corpus_clips": CORPUS_CLIPS,
                   "features": {name: feature_config(settings, name).to_dict() for name in needed}}, f, indent=1)
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
    ap.add_argument("--model", default="select", choices=list(MODELS),
                    help="select: SelectNet (the table of docs/baseline.md); paper: the paper's concat model")
    ap.add_argument("--jobs", type=int, default=2, help="models trained at once (one process each)")
    ap.add_argument("--recorded-test", metavar="DIR",
                    help="a recorded FOA dataset (docs/recorded.md): the moving row's model also predicts its test "
                         "split (the row \"real rooms\")")
    ap.add_argument("--recorded-split", default="test", help="the split of --recorded-test to score")
    a = ap.parse_args(argv)
    if a.recorded_test and not os.path.isfile(os.path.join(a.recorded_test, "dataset.json")):
        ap.error(f"--recorded-test {a.recorded_test}: not a finished tsel-data dataset (tsel generate --preset "
                 f"starss23 --corpus-dir YOUR_STARSS23 --out DIR makes one)")
    run(a.out, a.text, a.text_npz, a.workers, a.seed, a.only, a.model, a.jobs, recorded_test=a.recorded_test,
        recorded_split=a.recorded_split)


if __name__ == "__main__":
    main()
