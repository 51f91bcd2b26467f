"""corpus.check = "drawn" (the default): headers checked before planning, the clips a plan
draws checked in full, scenes that drew a bad clip planned again (plan/drawn.py). The plan
is the full check's when every clip is good; with bad clips it does not depend on which
were checked first; a bad clip a plan draws is skipped and listed, or stops the run."""
import json
import os
import shutil
from collections import Counter

import numpy as np
import pytest
import soundfile as sf

from support.cli import completed
from support.corpora import CAPTIONS, FS, make_corpus, tone
from tsel_data.config import load_config
from tsel_data.corpus import audio
from tsel_data.job.pipeline import generate, plan_dataset
from tsel_data.plan.catalog import check_clips
from tsel_data.plan.sampler import prepare_views, plan_split_json
from tsel_data.store.layout import Layout

PHRASES = ["a dog barks twice", "rain falls on a metal roof", "an engine idles then revs", "church bells ring slowly",
           "small birds chirp in trees", "wooden door creaks open", "water pours into sink", "people chatter in hall",
           "wind howls past windows", "a clock ticks steadily", "telephone rings repeatedly", "car horn honks loudly",
           "snare drum rolls fast", "glass shatters on tiles", "footsteps crunch gravel", "freight train rumbles by"]
GOOD = {f"clip{k:02d}": p for k, p in enumerate(PHRASES)}
BAD = {"clip03": "silent", "clip07": "nan", "clip11": "silent", "clip14": "nan"}  # header-good, bad once decoded


@pytest.fixture(scope="module")
def bad_corpus(tmp_path_factory):
    """16 train clips, four of them bad in a way only decoding shows."""
    CAPTIONS.update(GOOD)
    corpus = make_corpus(tmp_path_factory.mktemp("drawn") / "corpus", {"train": list(GOOD)})
    for cid, defect in BAD.items():
        p = os.path.join(corpus, "audio", f"{cid}.wav")
        if defect == "silent":
            sf.write(p, np.zeros(FS * 2, np.float32), FS)
        else:
            x = tone(3, 2.0)
            x[500] = np.nan
            sf.write(p, x, FS, subtype="FLOAT")
    return corpus


def _cfg(corpus, *more, scenes=12):
    return load_config(preset="demo", corpus_dir=str(corpus), splits={"train": scenes, "val": 0, "test": 0},
                       overrides=["audio.duration=1.0", "output.shard_size=4", *more])


def _plan(cfg, out):
    plan_dataset(cfg, str(out), allow_reuse=True)
    with open(os.path.join(out, "plan", "train.jsonl"), encoding="utf-8") as f:
        return f.read().splitlines()


def _clips_of(lines):
    return [{s["clip_id"] for s in json.loads(line)["sources"]} for line in lines]


def test_with_every_clip_good_the_plan_is_the_full_checks(demo_corpus, tmp_path, monkeypatch):
    monkeypatch.setenv("TSEL_CACHE_DIR", str(tmp_path / "cache"))
    for kind in ("noise.babble=2", 'scene.pairing="hard"'):  # noise clips and caption-paired interferers draw too
        drawn = _plan(load_config(preset="demo", corpus_dir=demo_corpus, overrides=["audio.duration=1.0", kind],
                                  splits={"train": 20, "val": 2, "test": 2}), tmp_path / f"drawn-{kind}")
        full = _plan(load_config(preset="demo", corpus_dir=demo_corpus, splits={"train": 20, "val": 2, "test": 2},
                                 overrides=["audio.duration=1.0", kind, 'corpus.check="full"']), tmp_path / f"full-{kind}")
        assert drawn == full


def test_a_bad_clip_a_plan_draws_is_left_out_whatever_was_checked_first(bad_corpus, tmp_path, monkeypatch):
    """The plan is the one with every bad clip excluded (found or not), with an empty clip
    check cache and with one that already knows every verdict; its bad clips are listed."""
    monkeypatch.setenv("TSEL_CACHE_DIR", str(tmp_path / "empty-cache"))
    cfg = _cfg(bad_corpus)
    first = _plan(cfg, tmp_path / "a")
    listed = [json.loads(line) for line in open(tmp_path / "a" / "bad_clips.jsonl", encoding="utf-8")]
    assert listed and {b["clip_id"] for b in listed} <= {f"{c}_0" for c in BAD}  # only truly bad clips
    assert all(b["origin"].startswith("train.csv:") for b in listed)
    used = set().union(*_clips_of(first))
    assert not used & {f"{c}_0" for c in BAD}  # no scene uses a bad clip
    doc = json.load(open(tmp_path / "a" / "plan" / "config.json"))
    assert doc["bad_clips"] == len(listed)

    # what the plan must be: every bad clip of the corpus excluded, by rejection
    _, views = prepare_views(cfg, Layout(str(tmp_path / "home")))
    view = views["train"]
    verdicts = check_clips(view.clips, cfg, level="full", prepare=[False] * len(view.clips))
    view.exclude([i for i, v in enumerate(verdicts) if v.problem])
    assert len(view.excluded) == len(BAD)
    assert plan_split_json(cfg, "train", view) == first

    # a cache that knows every verdict (the full check above) gives the same plan
    assert _plan(cfg, tmp_path / "b") == first


def test_scenes_that_never_drew_a_bad_clip_keep_their_recipes(bad_corpus, tmp_path, monkeypatch):
    monkeypatch.setenv("TSEL_CACHE_DIR", str(tmp_path / "cache"))
    cfg = _cfg(bad_corpus)
    _, views = prepare_views(cfg, Layout(str(tmp_path / "home")))
    unchecked = plan_split_json(cfg, "train", views["train"])  # as if every clip were good
    checked = _plan(cfg, tmp_path / "a")
    bad = {f"{c}_0" for c in BAD}
    redrawn = [i for i, clips in enumerate(_clips_of(unchecked)) if clips & bad]
    assert redrawn  # the plan drew a bad clip: the test means something
    for i, (a, b) in enumerate(zip(unchecked, checked)):
        assert (a == b) == (i not in redrawn), i


def test_a_bad_clip_a_plan_draws_stops_the_run_under_fail(bad_corpus, tmp_path):
    args = ["--preset", "demo", "--corpus-dir", str(bad_corpus), "--split", "train=12", "--split", "val=0",
            "--split", "test=0", "--set", "audio.duration=1.0", "--set", 'on_bad_clip="fail"']
    gen, chk = completed("generate", *args, "--out", str(tmp_path / "out"), "--quiet"), completed("check", *args)
    for r in (gen, chk):
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
        assert errors and any(c in errors[0] for c in BAD) and 'on_bad_clip = "skip"' in errors[0], r.stderr
    assert not (tmp_path / "out" / "plan" / "config.json").exists()
    assert not [f for _, _, fs in os.walk(tmp_path / "out") for f in fs if f.endswith(".h5")]


def test_tsel_check_lists_the_bad_clips_the_plan_draws(bad_corpus, tmp_path):
    r = completed("check", "--preset", "demo", "--corpus-dir", str(bad_corpus), "--split", "train=12", "--split",
                  "val=0", "--split", "test=0", "--set", "audio.duration=1.0")
    assert r.returncode == 0, r.stderr
    skipped = [w for w in r.stderr.splitlines() if 'skipped: on_bad_clip = "skip"' in w]
    assert skipped and all(any(c in w for c in BAD) for w in skipped)


def test_only_clips_used_twice_are_prepared_and_the_shards_are_the_same(tmp_path, monkeypatch, demo_corpus):
    """44.1 kHz stereo clips: the drawn check prepares those the plan uses twice or more,
    from its own decode; the shards are those of a run that prepares nothing."""
    corpus = str(tmp_path / "corpus")
    shutil.copytree(demo_corpus, corpus)
    for name in os.listdir(os.path.join(corpus, "audio")):
        p = os.path.join(corpus, "audio", name)
        x, fs = sf.read(p, dtype="float32", always_2d=True)
        sf.write(p, np.repeat(x[:, :1], 2, axis=1) * np.float32(0.8), fs, subtype="PCM_24")  # stereo: prepared
    monkeypatch.setenv("TSEL_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("TSEL_CLIP_CACHE", raising=False)
    cfg = _cfg(corpus, scenes=40)
    generate(cfg, str(tmp_path / "a"), progress=False, allow_reuse=True)
    lines = open(tmp_path / "a" / "plan" / "train.jsonl", encoding="utf-8").read().splitlines()
    uses = Counter((s["audio"], s["offset"]) for line in lines for s in json.loads(line)["sources"])
    state = {key: audio.prepared_state(os.path.join(corpus, key[0]), cfg.audio.fs, cfg.audio.duration, key[1])
             for key in uses}
    assert any(n >= 2 for n in uses.values()) and any(n == 1 for n in uses.values())
    assert {key for key, s in state.items() if s == "ok"} == {key for key, n in uses.items() if n >= 2}
    generate(_cfg(corpus, "corpus.prepare_on_check=false", scenes=40), str(tmp_path / "b"), progress=False,
             allow_reuse=True)
    shards = sorted(f for f in os.listdir(tmp_path / "a" / "train") if f.endswith((".h5", ".json")) and "seal" not in f)
    for f in shards:
        assert open(tmp_path / "a" / "train" / f, "rb").read() == open(tmp_path / "b" / "train" / f, "rb").read(), f
