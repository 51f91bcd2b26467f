"""End to end: config -> plan -> shards -> dataset.json, through the library and the CLI."""
import json
import os

import h5py
import numpy as np
import pytest

from support.cli import tsel
from tsel_data.job.pipeline import finalize, generate
from tsel_data.core.digest import sha256_file


def _files(d):
    out = {}
    for root, _, files in os.walk(d):
        for f in files:
            p = os.path.join(root, f)
            rel = os.path.relpath(p, d)
            if rel.startswith("demo-corpus") or f.endswith(".seal.json"):  # seals record file times
                continue
            out[rel] = sha256_file(p)
    return out


@pytest.fixture
def dataset(generated_dataset):
    return generated_dataset("small")


def test_layout_and_counts(dataset):
    cfg, out = dataset
    doc = json.load(open(os.path.join(out, "dataset.json")))
    assert {k: v["scenes"] for k, v in doc["splits"].items()} == {"train": 6, "val": 2, "test": 3}
    assert [s["file"] for s in doc["splits"]["train"]["shards"]] == ["train/shard-00000.h5", "train/shard-00001.h5"]
    assert doc["fs"] == 24000 and doc["format"] == "mic4" and doc["label_hop"] == 0.1
    for split in doc["splits"].values():
        for sh in split["shards"]:
            assert sha256_file(os.path.join(out, sh["file"])) == sh["sha256"]
            with h5py.File(os.path.join(out, sh["file"])) as h:
                assert h["audio"].shape == (sh["scenes"], 4, 72000) and h["audio"].dtype == np.float32
                assert h["audio"].chunks == (1, 4, 72000)
                assert h["labels/azimuth"].shape == (sh["scenes"], 2, 30)
                assert h["labels/active"].dtype == bool
                assert h["mic_positions"].shape == (sh["scenes"], 4, 3)
                assert h.attrs["fs"] == 24000 and h.attrs["format"] == "mic4"
    plan_lines = open(os.path.join(out, "plan", "train.jsonl")).read().splitlines()
    assert len(plan_lines) == 6


def test_hdf5_and_json_agree(dataset):
    _, out = dataset
    doc = json.load(open(os.path.join(out, "dataset.json")))
    for split in doc["splits"].values():
        for sh in split["shards"]:
            js = json.load(open(os.path.join(out, sh["json"])))
            with h5py.File(os.path.join(out, sh["file"])) as h:
                ids = [x.decode() for x in h["scene_id"][()]]
                queries = [x.decode() for x in h["query"][()]]
                assert ids == [s["scene_id"] for s in js["scenes"]]
                assert queries == [s["query"] for s in js["scenes"]]
                for i, scene in enumerate(js["scenes"]):
                    assert scene["sources"][0]["role"] == "target"
                    assert scene["query"] in scene["sources"][0]["captions"]
                    for k, src in enumerate(scene["sources"]):
                        for key in ("azimuth", "elevation", "distance"):
                            j = np.array([np.nan if v is None else v for v in src[key]], dtype=np.float32)
                            np.testing.assert_allclose(h[f"labels/{key}"][i, k], j, atol=1e-3, equal_nan=True)
                        assert h["labels/active"][i, k].tolist() == src["active"]
                        if src["spatial"] == "additive":
                            assert all(v is None for v in src["azimuth"])
                    np.testing.assert_allclose(h["mic_positions"][i], scene["array"]["mic_positions"], atol=1e-6)
                    a = h["audio"][i]
                    assert np.all(np.isfinite(a)) and np.max(np.abs(a)) <= 0.99 + 1e-6


def test_levels_follow_the_recipe(dataset):
    _, out = dataset
    js = json.load(open(os.path.join(out, "train", "shard-00000.json")))
    for scene in js["scenes"]:
        t, i = scene["sources"]
        norm = scene["levels"]["normalisation_db"]
        assert t["level_dbfs"] == pytest.approx(scene["levels"]["target_level_dbfs"] + norm, abs=0.01)
        assert t["level_dbfs"] - i["level_dbfs"] == pytest.approx(i["tir_db"], abs=0.01)


@pytest.mark.slow
def test_workers_resume_and_reruns_give_identical_files(dataset, tmp_path):
    cfg, out = dataset
    ref = _files(out)
    two = str(tmp_path / "two")
    generate(cfg, two, workers=2, progress=False)
    assert _files(two) == ref
    # a killed run: one shard missing, a temporary file left behind, no dataset.json
    os.remove(os.path.join(two, "train", "shard-00001.h5"))
    os.remove(os.path.join(two, "dataset.json"))
    open(os.path.join(two, "train", "shard-00001.h5.tmp-4194305"), "wb").write(b"partial")
    with pytest.raises(Exception, match="not rendered"):
        finalize(two)
    generate(cfg, two, workers=1, resume=True, progress=False)
    assert not os.path.exists(os.path.join(two, "train", "shard-00001.h5.tmp-4194305"))  # leftovers cleaned
    assert _files(two) == ref


def test_refuses_to_overwrite_without_resume(dataset):
    cfg, out = dataset
    from tsel_data.errors import DatasetError

    with pytest.raises(DatasetError, match="--resume"):
        generate(cfg, out, progress=False)


def test_cli_generate_render_ranges_and_errors(demo_corpus, tmp_path):
    out = str(tmp_path / "cli")
    common = ["--preset", "demo", "--corpus-dir", demo_corpus, "--set", "audio.duration=2.0",
              "--split", "train=4", "--split", "val=2", "--split", "test=2", "--set", "output.shard_size=2"]
    r = tsel("plan", *common, "--out", out)
    assert r.returncode == 0, r.stderr
    assert "in 4 shards (0-3)" in r.stdout
    assert tsel("render", out, "--shards", "0-1", "--quiet").returncode == 0
    r = tsel("finalize", out)
    assert r.returncode == 2 and "not rendered" in r.stderr and "Traceback" not in r.stderr
    assert tsel("render", out, "--shards", "2-3", "--quiet").returncode == 0
    r = tsel("finalize", out)
    assert r.returncode == 0, r.stderr
    r = tsel("render", out, "--shards", "9-12")
    assert r.returncode == 2 and "outside the plan's 4 shards" in r.stderr


@pytest.mark.parametrize("args,message", [
    (["generate", "--preset", "nope", "--out", "x"], "unknown preset 'nope'"),
    (["generate", "--preset", "demo", "--out", "x", "--set", "room.rt7=1"], "did you mean room.rt60"),
    (["generate", "--preset", "paper-sim-2dir", "--out", "x"], "no corpus given"),
    (["generate", "--preset", "paper-sim-2dir", "--corpus-dir", "/nonexistent", "--out", "x"], "not found"),
    (["generate", "--out", "x"], "--preset NAME or --config"),
    (["render", "/nonexistent"], "has no plan"),
])
def test_cli_user_errors_exit_2_with_one_line(args, message, tmp_path):
    r = tsel(*args, cwd=str(tmp_path))
    assert r.returncode == 2
    assert message in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_missing_audio_is_reported(demo_corpus, tmp_path):
    import shutil

    corpus = tmp_path / "corpus"
    shutil.copytree(demo_corpus, corpus)
    victim = sorted(os.listdir(corpus / "audio"))[0]
    os.remove(corpus / "audio" / victim)
    args = ["generate", "--preset", "demo", "--corpus-dir", str(corpus), "--set", "audio.duration=2.0",
            "--split", "train=2", "--split", "val=1", "--split", "test=1", "--quiet"]
    r = tsel(*args, "--out", str(tmp_path / "a"), "--set", 'on_bad_clip="fail"')
    assert r.returncode == 2 and victim in r.stderr and "not found" in r.stderr
    r = tsel(*args, "--out", str(tmp_path / "b"))
    assert r.returncode == 0, r.stderr
    assert "0 bad clips skipped, 1 clips missing (see missing_clips.json)" in r.stdout
    assert not open(tmp_path / "b" / "bad_clips.jsonl").read()  # a partial download is not a list of bad clips
    missing = json.load(open(tmp_path / "b" / "missing_clips.json"))["splits"]
    (split, entry), = missing.items()
    assert entry["missing"] == 1 and victim.rsplit(".", 1)[0] in entry["clip_ids"][0]


def test_finalize_hashes_only_the_shards_that_changed_since_their_seal(generated_dataset, tmp_path, monkeypatch):
    """The writers hashed their shards as they sealed them: finalize (generate's, and
    `tsel finalize` alone) checks size and time against those seals and hashes only a
    file whose size or time moved (and accepts it when its bytes are the sealed ones)."""
    import tsel_data.store.integrity as integrity

    hashed = []
    real = integrity.sha256_file
    monkeypatch.setattr(integrity, "sha256_file", lambda p: hashed.append(os.path.basename(p)) or real(p))
    cfg = generated_dataset("small").cfg
    out = str(tmp_path / "ds")
    generate(cfg, out, workers=1, progress=False)
    assert not [h for h in hashed if h.startswith("shard-")]
    finalize(out)
    assert not [h for h in hashed if h.startswith("shard-")]
    touched = os.path.join(out, "train", "shard-00000.h5")
    st = os.stat(touched)
    os.utime(touched, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # copied without its time: same bytes
    finalize(out)
    assert hashed == ["shard-00000.h5"]
