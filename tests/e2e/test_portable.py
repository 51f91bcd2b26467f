"""Datasets that travel: no path of the machine that made them in any file, and a moved
dataset (with or without its corpus) that every read-only tool and --resume accept."""
from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from support.cli import cli
from tsel_data.job.pipeline import finalize, render_shards

SETS = ["audio.duration=1.0", "audio.fs=8000", "output.shard_size=2", 'room.rt60=["uniform", 0.2, 0.3]']
SPLITS = ["--split", "train=4", "--split", "val=0", "--split", "test=2"]


def generate_args(corpus, out, *extra):
    return ["generate", "--preset", "demo", "--corpus-dir", corpus, "--out", out, *SPLITS,
            *sum((["--set", s] for s in SETS), []), "--quiet", "--workers", "1", *extra]


def shard_digests(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("shard-*")) if not p.name.endswith(".seal.json")}


def files_naming(root: Path, needle: str) -> list[str]:
    raw = needle.encode("utf-8")
    return [str(p.relative_to(root)) for p in sorted(root.rglob("*")) if p.is_file() and raw in p.read_bytes()]


@pytest.fixture(scope="module")
def corpus_copy(demo_corpus, tmp_path_factory):
    base = tmp_path_factory.mktemp("machine-a")
    corpus = base / "corpora" / "demo"
    shutil.copytree(demo_corpus, corpus)
    return base, corpus


def test_no_file_names_a_folder_of_the_machine_that_made_it(capsys, demo_corpus, tmp_path):
    corpus = tmp_path / "corpora" / "demo"
    shutil.copytree(demo_corpus, corpus)
    audio = sorted((corpus / "audio").iterdir())
    audio[0].unlink()  # a partial download: listed in missing_clips.json
    audio[1].write_bytes(b"not audio at all")  # a bad clip: listed in bad_clips.jsonl
    out = tmp_path / "somewhere" / "ds"
    code, _, err = cli(capsys, *generate_args(corpus, out))
    assert code == 0, err
    assert (out / "missing_clips.json").is_file() and (out / "bad_clips.jsonl").read_text().strip()
    assert files_naming(out, str(tmp_path)) == []
    # the roots are kept relative to the dataset, in the run's config only
    plan = json.loads((out / "plan" / "config.json").read_text())
    assert plan["config"]["corpus"]["dir"] == os.path.relpath(corpus, out)
    rec = json.loads((out / "test" / "shard-00000.json").read_text())["scenes"][0]
    assert all(not os.path.isabs(s["audio"]) and (corpus / s["audio"]).is_file() for s in rec["sources"])


def test_shards_are_the_same_bytes_wherever_the_dataset_and_the_corpus_are(capsys, corpus_copy, demo_corpus,
                                                                           tmp_path):
    _, corpus = corpus_copy
    a, b = tmp_path / "a", tmp_path / "deeper" / "path" / "b"
    assert cli(capsys, *generate_args(corpus, a))[0] == 0
    assert cli(capsys, *generate_args(demo_corpus, b))[0] == 0
    assert shard_digests(a) == shard_digests(b) and len(shard_digests(a)) == 6


def test_a_moved_dataset_and_corpus_are_read_resumed_and_finished_there(capsys, corpus_copy, tmp_path):
    _, corpus = corpus_copy
    old = tmp_path / "old"
    shutil.copytree(corpus, old / "corpus")  # copy2 keeps modification times, as mv and rsync -a do
    assert cli(capsys, *generate_args(old / "corpus", old / "ds"))[0] == 0
    reference = shard_digests(old / "ds")
    (old / "ds" / "dataset.json").unlink()  # half made: shards 1 and 2 of train to do
    for name in ("shard-00001.h5", "shard-00001.json", "shard-00001.seal.json"):
        (old / "ds" / "train" / name).unlink()
    new = tmp_path / "new" / "place"
    new.parent.mkdir()
    os.rename(old, new)

    # moved together: the plan's roots are relative to the dataset, so nothing to say
    render_shards(str(new / "ds"), progress=False)
    finalize(str(new / "ds"))
    assert shard_digests(new / "ds") == reference

    # the corpus moved on alone: a resume that names it continues (the shards are not stale)
    os.rename(new / "corpus", tmp_path / "corpus-elsewhere")
    stamp = (new / "ds" / "train" / "shard-00000.h5").stat().st_mtime_ns
    (new / "ds" / "dataset.json").unlink()
    code, out, err = cli(capsys, *generate_args(tmp_path / "corpus-elsewhere", new / "ds", "--resume"))
    assert code == 0, err
    assert (new / "ds" / "train" / "shard-00000.h5").stat().st_mtime_ns == stamp  # nothing rendered again
    plan = json.loads((new / "ds" / "plan" / "config.json").read_text())
    assert plan["config"]["corpus"]["dir"] == "../../../corpus-elsewhere"  # where it is now, relative
    # a resume that changes anything but where the inputs are still names the keys
    code, _, err = cli(capsys, *generate_args(tmp_path / "corpus-elsewhere", new / "ds", "--resume", "--seed", "3"))
    assert code == 2 and "seed (planned 0, now 3)" in err and "corpus.dir" not in err

    # the corpus gone: every read-only tool still works there
    shutil.rmtree(tmp_path / "corpus-elsewhere")
    ds = new / "ds"
    assert cli(capsys, "check", ds)[0] == 0
    assert cli(capsys, "stats", ds)[0] == 0
    code, out, err = cli(capsys, "inspect", ds, "test/1", "--wav", tmp_path / "x.wav")
    assert code == 0 and "note: no stems" in err and (tmp_path / "x.wav").is_file()
    assert cli(capsys, "export", "dcase", ds, "--out", tmp_path / "dcase")[0] == 0
    assert cli(capsys, "verify", ds)[0] == 0


def _seals(ds: Path) -> dict[str, int]:
    return {str(p.relative_to(ds)): p.stat().st_mtime_ns for p in sorted(ds.rglob("*.seal.json"))}


def test_inputs_not_where_the_plan_says_are_named_and_nothing_is_touched(capsys, corpus_copy, tmp_path):
    _, corpus = corpus_copy
    mine = tmp_path / "corpus"
    shutil.copytree(corpus, mine)
    ds = tmp_path / "ds"
    assert cli(capsys, *generate_args(mine, ds))[0] == 0
    before = _seals(ds)
    # a resume that does not say where the corpus is keeps the plan's root: nothing to render
    resume = [a for a in generate_args(mine, ds, "--resume") if a not in ("--corpus-dir", mine)]
    code, _, err = cli(capsys, *resume)
    assert code == 0, err
    assert _seals(ds) == before
    assert json.loads((ds / "plan" / "config.json").read_text())["config"]["corpus"]["dir"] == "../corpus"
    # the corpus gone: render, finalize and a resume say so in one line and change nothing
    os.rename(mine, tmp_path / "elsewhere")
    for args in (["render", ds, "--quiet"], ["finalize", ds], resume):
        code, _, err = cli(capsys, *args)
        lines = [line for line in err.splitlines() if line.strip()]
        assert code == 2 and len(lines) == 1 and "--corpus-dir" in lines[0] and "not in the corpus" in lines[0], err
        assert _seals(ds) == before
    # a resume naming a corpus that is not there either is refused before anything is stored
    code, _, err = cli(capsys, *generate_args(tmp_path / "nowhere", ds, "--resume"))
    assert code == 2 and "corpus.dir" in err and "not found" in err
    assert json.loads((ds / "plan" / "config.json").read_text())["config"]["corpus"]["dir"] == "../corpus"
    assert cli(capsys, "render", ds, "--corpus-dir", tmp_path / "elsewhere", "--quiet")[0] == 0
    assert _seals(ds) == before  # found: every shard verifies, none is rendered again


def test_a_dataset_made_through_a_symlink_is_read_through_its_real_path(capsys, corpus_copy, tmp_path):
    _, corpus = corpus_copy
    (tmp_path / "real" / "deep").mkdir(parents=True)
    os.symlink(tmp_path / "real" / "deep", tmp_path / "link")
    assert cli(capsys, *generate_args(corpus, tmp_path / "link" / "ds"))[0] == 0
    real = tmp_path / "real" / "deep" / "ds"
    before = _seals(real)
    assert cli(capsys, "finalize", real)[0] == 0 and cli(capsys, "render", real, "--quiet")[0] == 0
    assert _seals(real) == before
