"""Recipe releases: `tsel export recipes` publishes a dataset without audio; `tsel generate
--from` rebuilds it from a copy of the corpus bit for bit, and from a corpus with a
changed and a missing clip says scene by scene what differs (and which clip) and what
could not be built; the missing-clip policy substitutes deterministically when asked;
`tsel check DIR --release REL` holds a dataset against a release."""
import json
import os
import shutil

import numpy as np
import pytest
import soundfile as sf

from tsel_data.cli import main
from tsel_data.config import load_config
from tsel_data.errors import TselError
from tsel_data.export import export
from tsel_data.job.pipeline import generate
from tsel_data.job.rebuild import rebuild
from tsel_data.store import open_dataset
from tsel_data.store.release import check_against_release, load_release


@pytest.fixture(scope="module")
def released(tmp_path_factory, demo_corpus):
    """A dataset made from a corpus folder of its own, and its recipe release."""
    base = tmp_path_factory.mktemp("release")
    corpus = str(base / "corpus")
    shutil.copytree(demo_corpus, corpus)
    cfg = load_config(preset="demo", corpus_dir=corpus, splits={"train": 4, "val": 0, "test": 2},
                      overrides=["audio.duration=2.0", "output.shard_size=2"])
    root = str(base / "ds")
    generate(cfg, root, workers=1, progress=False)
    rel = str(base / "rel")
    export("recipes", root, rel)
    return {"base": base, "corpus": corpus, "root": root, "rel": rel}


def copy_corpus(released, name: str) -> str:
    dst = str(released["base"] / name)
    shutil.copytree(released["corpus"], dst)
    return dst


def clip_uses(rel: str) -> dict:
    """{clip audio name: [scene ids using it]} from the release's checksums."""
    uses = {}
    r = load_release(rel)
    for split in r.splits:
        for sid, e in r.checksums(split).items():
            for c in e["clips"]:
                uses.setdefault(c, []).append(sid)
    return uses


def test_a_release_holds_recipes_and_checksums_and_no_audio(released):
    rel = released["rel"]
    files = [os.path.relpath(os.path.join(d, f), rel) for d, _, fs in os.walk(rel) for f in fs]
    assert not [f for f in files if f.endswith((".h5", ".wav", ".flac", ".tar"))]
    for f in ("release.json", "dataset.json", "plan/config.json", "plan/train.jsonl", "checksums/test.jsonl",
              "clips.jsonl", "README.md"):
        assert f in files, f
    r = load_release(rel)
    assert r.splits == ["train", "val", "test"] and len(r.checksums("train")) == 4 and not r.checksums("val")
    clips = r.clips()
    assert set(clips) == set(clip_uses(rel))  # every clip a recipe reads, and only those
    name = sorted(clips)[0]
    import hashlib

    with open(os.path.join(released["corpus"], name), "rb") as f:
        assert clips[name]["sha256"] == hashlib.sha256(f.read()).hexdigest()


def test_rebuilt_from_a_copied_corpus_is_bit_identical(released, capsys):
    corpus = copy_corpus(released, "copy")
    out = str(released["base"] / "rebuilt")
    main_args = ["generate", "--from", released["rel"], "--corpus-dir", corpus, "--out", out, "--quiet"]
    with pytest.raises(SystemExit) as ex:
        main(main_args)
    assert ex.value.code == 0
    printed = capsys.readouterr().out
    assert "train: 4 identical, 0 differs, 0 substituted, 0 not-buildable" in printed
    with open_dataset(released["root"], "train") as a, open_dataset(out, "train") as b:
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x.audio, y.audio)
            assert x.record.to_json() == y.record.to_json()
    rep = check_against_release(out, released["rel"])
    assert rep.ok and rep.facts["splits"]["test"] == {"scenes": 2, "identical": 2, "differs": 0, "absent": 0}


def test_a_changed_and_a_missing_clip_are_reported_scene_by_scene(released, capsys):
    corpus = copy_corpus(released, "damaged")
    uses = clip_uses(released["rel"])
    order = sorted(uses, key=lambda c: (len(uses[c]), c))
    gone = order[0]
    changed = next(c for c in order if not set(uses[c]) & set(uses[gone]))
    os.remove(os.path.join(corpus, gone))
    x, fs = sf.read(os.path.join(corpus, changed), dtype="float32")
    sf.write(os.path.join(corpus, changed), 0.5 * x, fs)
    out = str(released["base"] / "partly")
    rep = rebuild(released["rel"], out, corpus_dir=corpus, progress=False)
    status = {s["scene_id"]: s for s in rep["scenes"]}
    for sid in uses[gone]:
        assert status[sid]["status"] == "not-buildable" and gone in status[sid]["why"]
    for sid in uses[changed]:
        assert status[sid]["status"] == "differs" and "audio" in status[sid]["parts"]
        assert f"clip {changed} differs from the release's" in status[sid]["why"]
    others = set(status) - set(uses[gone]) - set(uses[changed])
    assert others and all(status[s]["status"] == "identical" for s in others)
    assert json.loads(open(os.path.join(out, "rebuild.json")).read())["scenes"] == rep["scenes"]
    with open_dataset(out, "train") as ds:  # the scenes left out are not in the dataset
        assert set(ds.scene_ids()) == {s for s in status if s.startswith("train") and s not in uses[gone]}
    check = check_against_release(out, released["rel"])
    assert not check.ok and len(check.errors) == len(uses[changed])
    assert sum("not in the dataset" in w for w in check.warnings) == len(uses[gone])
    with pytest.raises(SystemExit) as ex:
        main(["check", out, "--release", released["rel"]])
    assert ex.value.code == 2 and "differs from the release (audio" in capsys.readouterr().err


def test_missing_clips_are_substituted_deterministically_when_asked(released):
    corpus = copy_corpus(released, "holed")
    uses = clip_uses(released["rel"])
    gone = sorted(uses, key=lambda c: (len(uses[c]), c))[0]
    os.remove(os.path.join(corpus, gone))
    reports = [rebuild(released["rel"], str(released["base"] / f"subst{k}"), corpus_dir=corpus,
                       missing="substitute", progress=False) for k in range(2)]
    subst = [s for s in reports[0]["scenes"] if s["status"] == "substituted"]
    assert [s["scene_id"] for s in subst] == sorted(uses[gone])
    assert all("instead of" in s["why"] and gone not in s["clips"] for s in subst)
    assert reports[0]["scenes"] == reports[1]["scenes"]  # the same substitutes on every run
    with open_dataset(str(released["base"] / "subst0"), subst[0]["scene_id"].split("-")[0]) as ds:
        assert subst[0]["scene_id"] in ds
    assert check_against_release(str(released["base"] / "subst0"), released["rel"]).ok  # expected: warnings only


@pytest.mark.parametrize("argv,message", [
    (["--preset", "demo"], "--from takes its config and plan from the release"),
    ([], "give --corpus-dir with your copy"),
    (["--corpus-dir", "{corpus}", "--missing", "guess"], "Invalid value for '--missing'"),
])
def test_rebuild_mistakes_are_one_line(released, tmp_path, capsys, argv, message):
    argv = [a.replace("{corpus}", released["corpus"]) for a in argv]
    with pytest.raises(SystemExit) as ex:
        main(["generate", "--from", released["rel"], "--out", str(tmp_path / "o"), *argv])
    err = capsys.readouterr().err
    assert ex.value.code == 2 and err.count("\n") == 1 and message in err, err
    with pytest.raises(TselError, match="is not a recipe release"):
        rebuild(released["root"], str(tmp_path / "p"), corpus_dir=released["corpus"])
