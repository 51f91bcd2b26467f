"""The plan is opened once and sealed: render and finalize read ``plan/config.json`` once
per job, refuse a plan edited after planning, and ``tsel check DIR`` notices a plan or a
``dataset.json`` edited after finalize. A plan alone is not held to the disk the audio
needs (the job-array flow plans on one machine and renders elsewhere)."""
import json
import os
import shutil

import pytest

from support.configs import DATASETS

import tsel_data.job.pipeline as pipeline
import tsel_data.job.shards as shards
from tsel_data.errors import DatasetError
from tsel_data.job.pipeline import generate, plan_dataset
from tsel_data.job.shards import finalize, open_plan, render_shards
from tsel_data.store import plans as store_plans
from tsel_data.store.check import check_dataset

SMALL = list(DATASETS["sealed"].overrides)
SPLITS = DATASETS["sealed"].splits


@pytest.fixture
def cfg(generated_dataset):
    return generated_dataset("sealed").cfg


@pytest.fixture
def made(generated_dataset):
    return generated_dataset("sealed").out


@pytest.fixture
def copy(made, tmp_path):
    out = str(tmp_path / "ds")
    shutil.copytree(made, out)
    return out


def _edit_line(path, n=0, old='"seed":'):
    """Change one recipe's seed digits without changing the file's size."""
    lines = open(path, encoding="utf-8").read().splitlines(keepends=True)
    i = lines[n].index(old) + len(old)
    digit = lines[n][i]
    lines[n] = lines[n][:i] + ("1" if digit != "1" else "2") + lines[n][i + 1:]
    open(path, "w", encoding="utf-8").writelines(lines)


def test_generate_reads_the_plan_document_once_for_render_and_finalize(cfg, tmp_path, monkeypatch):
    calls = []
    real = shards.read_plan_doc
    monkeypatch.setattr(shards, "read_plan_doc", lambda *a, **k: calls.append(a) or real(*a, **k))
    generate(cfg, str(tmp_path / "ds"), workers=1, progress=False)
    assert len(calls) == 1


def test_the_seal_holds_the_config_digest_and_each_plan_file(made):
    doc = json.load(open(os.path.join(made, "plan", "config.json")))
    seal = doc["seal"]
    assert seal["config_sha256"] == store_plans.config_digest(doc["config"])
    for split in ("train", "test"):
        data = open(os.path.join(made, "plan", f"{split}.jsonl"), "rb").read()
        assert seal["files"][split]["bytes"] == len(data)
    ds = json.load(open(os.path.join(made, "dataset.json")))
    assert ds["plan_seal"] == seal
    assert check_dataset(made).ok


def test_the_config_digest_ignores_roots_only(made):
    config = json.load(open(os.path.join(made, "plan", "config.json")))["config"]
    moved = {**config, "corpus": {**config["corpus"], "dir": "../elsewhere"}}
    assert store_plans.config_digest(moved) == store_plans.config_digest(config)
    reseeded = {**config, "seed": config["seed"] + 1}
    assert store_plans.config_digest(reseeded) != store_plans.config_digest(config)


def test_a_recipe_edited_after_planning_is_refused_by_render_and_finalize(copy):
    _edit_line(os.path.join(copy, "plan", "train.jsonl"))  # same size: only the hash sees it
    with pytest.raises(DatasetError, match=r"train.jsonl was edited after planning"):
        render_shards(copy, progress=False)
    with pytest.raises(DatasetError, match=r"train.jsonl was edited after planning"):
        finalize(copy)
    rep = check_dataset(copy)
    assert not rep.ok and any("train.jsonl was edited after planning" in str(e) for e in rep.errors)


def test_a_job_array_task_checks_sizes_of_its_splits_only(copy):
    path = os.path.join(copy, "plan", "test.jsonl")
    with open(path, "a", encoding="utf-8") as f:
        f.write("\n")
    render_shards(copy, shards=range(0, 2), progress=False)  # train shards: test.jsonl is not read
    with pytest.raises(DatasetError, match=r"test.jsonl was edited after planning"):
        render_shards(copy, shards=range(2, 3), progress=False)


def test_a_config_edited_in_the_plan_is_refused_when_opened(copy):
    path = os.path.join(copy, "plan", "config.json")
    doc = json.load(open(path))
    doc["config"]["seed"] += 1
    json.dump(doc, open(path, "w"))
    with pytest.raises(DatasetError, match=r"config.json: its config was edited after planning"):
        open_plan(copy)
    assert not check_dataset(copy).ok


def test_a_seed_edited_in_dataset_json_is_found_by_check(copy, tsel_cli):
    path = os.path.join(copy, "dataset.json")
    doc = json.load(open(path))
    doc["seed"] += 1
    json.dump(doc, open(path, "w"))
    rep = check_dataset(copy)
    assert not rep.ok and any("config or seed no longer matches" in str(e) for e in rep.errors)
    code, out, err = tsel_cli.run("check", copy)
    assert code == 2 and "config or seed no longer matches" in err


def test_a_dataset_moved_whole_still_verifies(made, tmp_path, demo_corpus):
    out = str(tmp_path / "moved" / "ds")
    shutil.copytree(made, out)  # new mtimes, new path: the seal holds sizes and hashes
    assert check_dataset(out).ok
    finalize(out, corpus_dir=demo_corpus)  # the corpus stayed: a relative root points elsewhere now


def test_plan_reports_the_size_and_leaves_the_disk_check_to_generate(cfg, tmp_path, monkeypatch, tsel_cli,
                                                                    demo_corpus):
    out = str(tmp_path / "jobs")
    monkeypatch.setattr(pipeline, "estimate_bytes", lambda cfg: 10 ** 15)
    plan_dataset(cfg, out, progress=False)  # planning writes only recipes: it does not ask for 1 PB
    with pytest.raises(DatasetError, match=r"the dataset needs about 1000000\.00 GB more"):
        generate(cfg, out, workers=1, progress=False, resume=True)
    train = os.path.join(out, "train")
    assert not os.path.isdir(train) or not any(n.startswith("shard-") for n in os.listdir(train))
    monkeypatch.undo()
    said = tsel_cli.ok("plan", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", str(tmp_path / "p2"),
                       "--split", "train=4", "--split", "val=0", "--split", "test=2",
                       *[a for o in SMALL for a in ("--set", o)])
    assert f"rendered, they take about {pipeline.estimate_bytes(cfg) / 1e9:.2f} GB" in said


def test_a_grow_stopped_between_plan_files_and_config_is_named_and_grow_again_mends_it(cfg, copy):
    from dataclasses import replace

    bigger = replace(cfg, splits={**cfg.splits, "train": replace(cfg.splits["train"], count=6)})
    plan_dataset(bigger, str(copy) + "-grown-ref", progress=False)  # what the grown plan files hold
    for split in ("train", "test"):  # the plan files written, plan/config.json not yet: the grow stopped there
        shutil.copyfile(os.path.join(str(copy) + "-grown-ref", "plan", f"{split}.jsonl"),
                        os.path.join(copy, "plan", f"{split}.jsonl"))
    with pytest.raises(DatasetError, match=r"or a --grow stopped before it finished.*--grow` again"):
        render_shards(copy, progress=False)
    generate(bigger, copy, workers=1, progress=False, grow=True)
    assert check_dataset(copy).ok
