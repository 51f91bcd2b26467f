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
from tsel_data.core.version import RENDERER, __version__
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
    return _release(base, corpus, {"train": 4, "val": 0, "test": 2}, ["audio.duration=2.0", "output.shard_size=2"])


def _release(base, corpus: str, splits: dict, overrides: list) -> dict:
    """A dataset of the demo preset made from ``corpus`` in ``base/ds``, and its release ``base/rel``."""
    root, rel = str(base / "ds"), str(base / "rel")
    generate(load_config(preset="demo", corpus_dir=corpus, splits=splits, overrides=overrides), root, workers=1,
             progress=False)
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
    assert r.doc["renderer"] == RENDERER and r.doc["version"] == __version__
    with open(os.path.join(rel, "dataset.json"), encoding="utf-8") as f:
        assert json.load(f)["renderer"] == RENDERER
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


def test_a_release_of_another_renderer_rebuilds_naming_the_version_that_matches_it(released, capsys):
    """A release made by tsel-data 0.1.9 (renderer 1: its release.json names none), one of
    whose scenes that renderer made otherwise: the rebuild still renders every scene,
    reports that one as differing because of the renderer, and names 0.1.9 as the version
    that rebuilds the release bit for bit."""
    rel = str(released["base"] / "rel-renderer-1")
    shutil.copytree(released["rel"], rel)
    with open(os.path.join(rel, "release.json"), encoding="utf-8") as f:
        doc = json.load(f)
    del doc["renderer"]
    doc["version"] = "0.1.9"
    with open(os.path.join(rel, "release.json"), "w", encoding="utf-8") as f:
        json.dump(doc, f)
    path = os.path.join(rel, "checksums", "train.jsonl")
    with open(path, encoding="utf-8") as f:
        lines = [json.loads(line) for line in f]
    other = lines[1]["scene_id"]
    lines[1]["audio"] = "0" * 64  # what renderer 1 made of it
    with open(path, "w", encoding="utf-8") as f:
        f.writelines(json.dumps(e) + "\n" for e in lines)
    out = str(released["base"] / "rebuilt-renderer-1")
    with pytest.raises(SystemExit) as ex:
        main(["generate", "--from", rel, "--corpus-dir", copy_corpus(released, "copy-renderer"), "--out", out,
              "--quiet"])
    assert ex.value.code == 0
    printed = capsys.readouterr().out
    assert f"rendered by renderer 1 (tsel-data 0.1.9); this tsel-data ({__version__}) renders with renderer {RENDERER}" \
        in printed and "tsel-data 0.1.9 rebuilds the release bit for bit" in printed
    assert "train: 3 identical, 1 differs, 0 substituted, 0 not-buildable" in printed
    with open(os.path.join(out, "rebuild.json"), encoding="utf-8") as f:
        rep = json.load(f)
    assert rep["renderer"] == {"release": 1, "this": RENDERER} and "0.1.9" in rep["note"]
    status = {s["scene_id"]: s for s in rep["scenes"]}
    assert status[other]["status"] == "differs" and status[other]["parts"] == ["audio"]
    assert "no clip differs: the renderer does" in status[other]["why"] and "tsel-data 0.1.9" in status[other]["why"]
    with open(os.path.join(out, "dataset.json"), encoding="utf-8") as f:
        assert json.load(f)["renderer"] == RENDERER  # the rebuild is this renderer's
    # the same renderer: no note
    rep = rebuild(released["rel"], str(released["base"] / "rebuilt-same"), corpus_dir=released["corpus"],
                  progress=False)
    assert rep["note"] is None and rep["renderer"] == {"release": RENDERER, "this": RENDERER}


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


# --- releases rebuild from any copy (issue 41) ------------------------------------------------

def _ids(corpus: str) -> dict[str, list[str]]:
    """{split: youtube ids} of the demo corpus' manifests."""
    import csv

    out = {}
    for split in ("train", "val", "test"):
        with open(os.path.join(corpus, f"{split}.csv"), newline="", encoding="utf-8") as f:
            out[split] = list(dict.fromkeys(r["youtube_id"] for r in csv.DictReader(f)))
    return out


def _lay_out(src: str, dst: str, where, per_split: bool = False) -> str:
    """A copy of the corpus ``src`` (its audio in ``audio/``, or ``audio/{split}/`` when
    ``per_split``) at ``dst``: the manifests, and each split's clip at ``where(split,
    id)`` (relative to ``dst``; None: left out)."""
    os.makedirs(dst)
    for split, ids in _ids(src).items():
        shutil.copy(os.path.join(src, f"{split}.csv"), dst)
        for cid in ids:
            rel = where(split, cid)
            if rel:
                os.makedirs(os.path.dirname(os.path.join(dst, rel)), exist_ok=True)
                shutil.copy(os.path.join(src, "audio", *([split] if per_split else []), f"{cid}.wav"),
                            os.path.join(dst, rel))
    return dst


@pytest.fixture(scope="module")
def released_per_split(tmp_path_factory, demo_corpus):
    """A dataset made from a corpus whose audio is in a folder per split (audio/{split}/),
    and its recipe release: the layout of the issue's report."""
    base = tmp_path_factory.mktemp("release-per-split")
    corpus = _lay_out(demo_corpus, str(base / "corpus"), lambda split, cid: f"audio/{split}/{cid}.wav")
    return _release(base, corpus, {"train": 3, "val": 0, "test": 2}, ["audio.duration=1.0", "output.shard_size=3"])


SPLIT_WORDS = {"train": "training", "test": "evaluation"}
LAYOUTS = {
    "flat": lambda split, cid: f"{cid}.wav",
    "flat-in-audio": lambda split, cid: f"audio/{cid}.wav",
    "Y-prefixed": lambda split, cid: f"audio/Y{cid}.wav",
    "other-split-folders": lambda split, cid: f"downloads/{SPLIT_WORDS.get(split, split)}/{cid}.wav",
}


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_a_release_rebuilds_bit_for_bit_from_a_copy_laid_out_otherwise(released_per_split, layout, capsys):
    rel, base = released_per_split["rel"], released_per_split["base"]
    copy = _lay_out_from(released_per_split["corpus"], str(base / f"copy-{layout}"), LAYOUTS[layout])
    out = str(base / f"rebuilt-{layout}")
    code = _main(["generate", "--from", rel, "--corpus-dir", copy, "--out", out, "--quiet", "--workers", "1"])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "train: 3 identical, 0 differs, 0 substituted, 0 not-buildable" in printed.out, printed.out
    assert "test: 2 identical" in printed.out and "0 missing" in printed.out, printed.out
    rep = json.loads(open(os.path.join(out, "rebuild.json")).read())
    assert rep["clips"]["found elsewhere"] == len(rep["found"]) > 0 and rep["clips"]["missing"] == 0
    name, where = next(iter(rep["found"].items()))
    assert os.path.isfile(os.path.join(copy, where)) and name.startswith("audio/")
    assert check_against_release(out, rel).ok
    with open_dataset(released_per_split["root"], "test") as a, open_dataset(out, "test") as b:
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x.audio, y.audio)
            assert x.record.to_json() == y.record.to_json()  # the release's names, not the copy's


def test_a_copy_missing_every_clip_builds_nothing_and_says_so(released_per_split, capsys):
    base = released_per_split["base"]
    copy = _lay_out_from(released_per_split["corpus"], str(base / "copy-empty"), lambda split, cid: None)
    out = str(base / "rebuilt-empty")
    code = _main(["generate", "--from", released_per_split["rel"], "--corpus-dir", copy, "--out", out, "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "0 of the release's 5 scenes can be built, fewer than --min-scenes 1" in err and "is missing" in err, err
    assert not os.path.exists(os.path.join(out, "dataset.json"))
    rep = json.loads(open(os.path.join(out, "rebuild.json")).read())
    assert rep["clips"]["missing"] == len(load_release(released_per_split["rel"]).clips()) and rep["stopped"]


def test_a_rebuild_that_would_make_fewer_scenes_than_asked_stops_before_rendering(released_per_split, capsys):
    rel, base = released_per_split["rel"], released_per_split["base"]
    uses = clip_uses(rel)
    gone = sorted(uses, key=lambda c: (-len(uses[c]), c))[0]  # the most used clip
    copy = _lay_out_from(released_per_split["corpus"], str(base / "copy-holed"),
                         lambda split, cid: None if gone.endswith(f"/{cid}.wav") else f"{cid}.wav")
    out = str(base / "rebuilt-holed")
    code = _main(["generate", "--from", rel, "--corpus-dir", copy, "--out", out, "--quiet", "--min-scenes", "100%"])
    err = capsys.readouterr().err
    assert code == 2 and f"{5 - len(uses[gone])} of the release's 5 scenes can be built" in err, err
    assert not os.path.exists(os.path.join(out, "dataset.json"))
    code = _main(["generate", "--from", rel, "--corpus-dir", copy, "--out", out, "--quiet", "--workers", "1",
                  "--min-scenes", str(5 - len(uses[gone]))])  # tolerated: the same folder, resumed
    assert code == 0, capsys.readouterr().err
    with open_dataset(out, "test") as ds:
        assert len(ds) == 2 - sum(s.startswith("test") for s in uses[gone])


def _lay_out_from(corpus: str, dst: str, where) -> str:
    return _lay_out(corpus, dst, where, per_split=True)


def _main(argv) -> int:
    with pytest.raises(SystemExit) as ex:
        main(argv)
    return ex.value.code
