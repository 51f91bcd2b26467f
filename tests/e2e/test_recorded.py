"""Real recordings as text-queried test sets (docs/recorded.md), from outside: a dataset in
STARSS23's exact layout (synthetic plane waves with known events: corpus/demo/recordings.py)
becomes TSEL scenes whose labels are its metadata frame by frame, whose FOA audio points
where the labels say, whose every query has one answer; skipped targets are counted;
releases rebuild bit for bit; bad input is one line; every tool reads the result."""
from __future__ import annotations

import csv
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from support.cli import InProcessCli
from tsel_data.corpus.demo.recordings import RECORDINGS
from tsel_data.core.geometry import azimuth_difference
from tsel_data.plan.recorded import SKIP_NO_RELATION, recorded_truth
from tsel_data.corpus.seld import Source
from tsel_data.scene.queries import check, margins
from tsel_data.store.reader import open_dataset

FS = 24000


@pytest.fixture
def made(generated_dataset):
    return generated_dataset("recorded")


def _rows(root: str, metadata: str) -> list[list[int]]:
    with open(os.path.join(root, metadata), newline="") as f:
        return [[int(v) for v in r] for r in csv.reader(f) if r]


def test_labels_are_the_metadata_frame_by_frame(made):
    cfg, out = made
    for split in ("train", "test"):
        with open_dataset(out, split) as ds:
            for scene in ds.iter_labels():
                r = scene.record.recording
                rows = _rows(cfg.corpus.dir, r.metadata)
                for k in range(scene.n_sources):
                    cls, actor = r.class_indices[k], r.actors[k]
                    mine = {(row[0] - r.start_frame): row for row in rows
                            if row[1] == cls and row[2] == actor and r.start_frame <= row[0] < r.start_frame + r.frames}
                    if r.events[k] == 0 and sum(1 for row in rows if row[1] == cls and row[2] == actor
                                                and row[0] == r.start_frame) <= 1:
                        active = np.flatnonzero(scene.active[k])
                        assert sorted(active.tolist()) == sorted(f for f in mine if _alone(rows, row_key(mine[f])))
                    for f in np.flatnonzero(scene.active[k]):
                        row = _nearest(rows, r.start_frame + f, cls, actor, scene.azimuth[k, f])
                        want_az = row[3] - 360 if row[3] >= 180 else row[3]
                        assert scene.azimuth[k, f] == want_az and scene.elevation[k, f] == row[4]
                        if len(row) == 6:
                            assert scene.distance[k, f] == pytest.approx(row[5] / 100.0)
                        else:
                            assert np.isnan(scene.distance[k, f])
                    assert np.isnan(scene.azimuth[k][~scene.active[k]]).all()


def row_key(row):
    return (row[0], row[1], row[2])


def _alone(rows, key) -> bool:
    return sum(1 for r in rows if (r[0], r[1], r[2]) == key) == 1


def _nearest(rows, frame, cls, actor, az):
    """The row of (frame, class, actor) nearest in azimuth to ``az`` (two sources of one
    class and actor at once are told apart by direction)."""
    mine = [r for r in rows if r[0] == frame and r[1] == cls and r[2] == actor]
    assert mine, (frame, cls, actor)
    return min(mine, key=lambda r: abs(float(azimuth_difference(r[3], az))))


def test_the_foa_audio_points_where_the_labels_say_when_the_target_sounds_alone(made):
    _, out = made
    checked = 0
    for split in ("train", "test"):
        with open_dataset(out, split) as ds:
            for scene in ds:
                alone = scene.active[0] & ~scene.active[1:].any(axis=0)
                hop = int(scene.label_hop * scene.fs)
                for f in np.flatnonzero(alone):
                    w, y, _, x = scene.audio[:, f * hop:(f + 1) * hop].astype(np.float64)
                    az = np.degrees(np.arctan2(np.mean(w * y), np.mean(w * x)))  # the active intensity's azimuth
                    assert abs(float(azimuth_difference(az, scene.azimuth[0, f]))) < 2.0, (scene.scene_id, f)
                    checked += 1
    assert checked > 200


def test_every_query_has_one_answer(made):
    cfg, out = made
    m = margins(cfg.scene)
    kinds = set()
    for split in ("train", "test"):
        with open_dataset(out, split) as ds:
            for scene in ds.iter_labels():
                rec = scene.record
                classes = rec.recording.class_indices
                same = [k for k in range(1, len(classes)) if classes[k] == classes[0]]
                kinds.add(scene.query_type)
                if scene.query_type == "caption":
                    assert not same and scene.query in rec.sources[0].captions
                    assert all(scene.query not in s.captions for s in rec.sources[1:])
                    continue
                assert scene.query_type == "composite" and same, scene.scene_id
                truth = recorded_truth([Source((0, 0, 0), scene.azimuth[k].astype(float),
                                               scene.elevation[k].astype(float), scene.distance[k].astype(float),
                                               scene.active[k]) for k in range(scene.n_sources)])
                ev = check(scene.query_relation, truth, same, m[scene.query_relation])
                assert ev is not None and ev["value"] == rec.query_evidence["value"], scene.scene_id
                # ... and for no other source of its class: none is heard in the window the query
                # names, none starts before (after) it, none is as near (far)
                for k in same:
                    if scene.query_relation == "heard_at":
                        t, half = ev["time"], m["heard_at"] / 2
                        frames = [f for f in range(scene.n_frames) if t - half < (f + 1) * scene.label_hop
                                  and f * scene.label_hop < t + half]
                        assert not scene.active[k][frames].any(), scene.scene_id
                        continue
                    order = [k] + [j for j in [0] + same if j != k]
                    other = recorded_truth([Source((0, 0, 0), scene.azimuth[j].astype(float),
                                                   scene.elevation[j].astype(float),
                                                   scene.distance[j].astype(float), scene.active[j]) for j in order])
                    assert check(scene.query_relation, other, list(range(1, len(order))),
                                 m[scene.query_relation]) is None, scene.scene_id
    assert kinds == {"caption", "composite"}


def test_targets_no_relation_tells_apart_are_skipped_and_counted(made, tsel_cli):
    _, out = made
    doc = json.load(open(os.path.join(out, "dataset.json")))
    test = doc["recorded"]["test"]
    # fold4_room4: two men starting and stopping together, in two windows: four targets
    assert test["skipped"] == {SKIP_NO_RELATION: 4}
    assert test["kept"] == doc["splits"]["test"]["scenes"] == test["candidates"] - 4
    assert doc["recorded"]["train"]["too_short"] == 1  # the knock of 0.6 s
    text = tsel_cli.ok("stats", out)
    assert f"skipped 4: {SKIP_NO_RELATION}" in text and "recorded: " in text and "target classes: " in text


def test_six_column_files_give_distances_and_five_column_files_none(made):
    _, out = made
    with open_dataset(out, "train") as ds:  # fold 3: six columns
        assert all(np.isfinite(s.distance[0][s.active[0]]).all() for s in ds.iter_labels())
    with open_dataset(out, "test") as ds:  # fold 4: five
        assert all(np.isnan(s.distance).all() for s in ds.iter_labels())


def test_a_release_rebuilds_bit_for_bit_and_names_what_changed(made, tmp_path, tsel_cli):
    cfg, out = made
    rel = tmp_path / "release"
    tsel_cli.ok("export", "recipes", out, "--out", rel)
    assert not list(rel.rglob("*.wav")) and not list(rel.rglob("*.h5"))
    copy = tmp_path / "my-starss"
    shutil.copytree(cfg.corpus.dir, copy)
    tsel_cli.ok("generate", "--from", rel, "--corpus-dir", copy, "--out", tmp_path / "again", "--quiet")
    report = json.load(open(tmp_path / "again" / "rebuild.json"))
    assert {s: v["identical"] for s, v in report["splits"].items()} == {
        s: v["scenes"] for s, v in json.load(open(os.path.join(out, "dataset.json")))["splits"].items()}
    # a recording changed (one sample) and one gone: per scene, as with clips
    changed = copy / "foa_dev" / "dev-train-sony" / "fold3_room1_mix001.wav"
    x, fs = sf.read(changed, dtype="int16")
    x[FS * 12, 0] += 7
    sf.write(changed, x, fs, subtype="PCM_16")
    os.remove(copy / "foa_dev" / "dev-test-sony" / "fold4_room3_mix003.wav")
    tsel_cli.ok("generate", "--from", rel, "--corpus-dir", copy, "--out", tmp_path / "third", "--quiet")
    scenes = json.load(open(tmp_path / "third" / "rebuild.json"))["scenes"]
    by = {}
    for s in scenes:
        by.setdefault(s["status"], []).append(s)
    assert by["not-buildable"] and all("fold4_room3_mix003" in s["why"] for s in by["not-buildable"])
    assert by["differs"] and all("fold3_room1_mix001.wav differs" in s["why"] for s in by["differs"])
    assert all("fold3_room1_mix001" not in " ".join(s["clips"]) for s in by["identical"])


def _tiny_starss(root, seconds: float = 12.0, rate: int = FS, channels: int = 4, rows=None) -> str:
    """One STARSS23-layout recording of ``seconds`` s with its labels (a woman at 30 deg)."""
    wav = root / "foa_dev" / "dev-test-sony" / "fold4_room1_mix001.wav"
    meta = root / "metadata_dev" / "dev-test-sony" / "fold4_room1_mix001.csv"
    wav.parent.mkdir(parents=True)
    meta.parent.mkdir(parents=True)
    sf.write(wav, 0.01 * np.random.default_rng(0).standard_normal((int(seconds * rate), channels)), rate)
    rows = rows if rows is not None else [f"{f},0,1,30,0" for f in range(0, 100)]
    meta.write_text("\n".join(rows) + "\n")
    return str(root)


@pytest.mark.parametrize("case,needles", [
    ("wav without csv", ["fold4_room1_mix001.wav has no label file"]),
    ("csv without wav", ["fold4_room1_mix002.csv has no recording", "a download cut short"]),
    ("row of four", ["fold4_room1_mix001.csv:3: a row of 4 fields", "5 or 6 whole numbers"]),
    ("not a number", ["fold4_room1_mix001.csv:3: azimuth '3O' is not a whole number"]),
    ("class outside", ["fold4_room1_mix001.csv:3: class 20 is not in the ontology"]),
    ("azimuth outside", ["fold4_room1_mix001.csv:3: azimuth 200 is outside [-180, 180]"]),
    ("wrong rate", ["is 16000 Hz but the scenes are audio.fs = 24000 Hz"]),
    ("wrong channels", ["has 2 channels; scene.format = \"foa\" has 4"]),
    ("no samples", ["holds no samples"]),
    ("window longer", ["the window (audio.duration = 10 s) is longer than the recording (6 s)"]),
    ("labels past the end", ["labels 19.9 s but", "is 12 s long: the recording is cut short"]),
    ("eval only", ["an evaluation set without labels cannot be a test set"]),
    ("hop not whole", ["recorded.hop 0.15 s is not a whole number of label frames"]),
    ("not a recorded format", ["recorded datasets are distributed as foa (foa_dev/), tetra (mic_dev/), stereo "
                               "(stereo_dev/); 'mic4' is not one"]),
    ("min_active longer", ["recorded.min_active 20 s is longer than the window"]),
    ("rendered-only key", ["scene.query shapes rendered scenes"]),
    ("no decidable relation", ["none of ['loudest'] can be decided on a recording"]),
    ("splits share", ["splits train and test both take foa_dev/dev-test-sony/fold4_room1_mix001.wav"]),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, case, needles):
    rows = [f"{f},0,1,30,0" for f in range(100)]
    kw, sets, splits = {}, [], ["--split", "train=0"]
    if case == "row of four":
        rows[2] = "2,0,1,30"
    elif case == "not a number":
        rows[2] = "2,0,1,3O,0"
    elif case == "class outside":
        rows[2] = "2,20,1,30,0"
    elif case == "azimuth outside":
        rows[2] = "2,0,1,200,0"
    elif case == "wrong rate":
        kw["rate"] = 16000
    elif case == "wrong channels":
        kw["channels"] = 2
    elif case == "no samples":
        kw["seconds"] = 0.0
    elif case == "window longer":
        kw["seconds"] = 6.0
    elif case == "labels past the end":
        rows += [f"{f},0,1,30,0" for f in range(100, 200)]
    sets = {"hop not whole": ["recorded.hop=0.15"], "not a recorded format": ['scene.format="mic4"'],
            "min_active longer": ["recorded.min_active=20"], "rendered-only key": ['scene.query="relational"'],
            "no decidable relation": ['scene.relations=["loudest"]'],
            "splits share": ["splits.train.folds=[4]"]}.get(case, [])
    if case == "splits share":
        splits = ["--split", "train=5"]
    root = _tiny_starss(tmp_path / "starss", rows=rows, **kw)
    meta_dir = os.path.join(root, "metadata_dev", "dev-test-sony")
    if case == "wav without csv":
        os.remove(os.path.join(meta_dir, "fold4_room1_mix001.csv"))
    if case == "csv without wav":
        shutil.copy(os.path.join(meta_dir, "fold4_room1_mix001.csv"), os.path.join(meta_dir, "fold4_room1_mix002.csv"))
    if case == "eval only":
        os.rename(os.path.join(root, "foa_dev"), os.path.join(root, "foa_eval"))
        shutil.rmtree(os.path.join(root, "metadata_dev"))
    cli = InProcessCli(capsys)
    args = ["--preset", "starss23", "--corpus-dir", root, *splits, *[a for s in sets for a in ("--set", s)]]
    for cmd in (["generate", "--out", tmp_path / "out", "--quiet"], ["check"]):
        line = cli.refused(*cmd, *args)
        for n in needles:
            assert n in line, line
    assert not os.path.exists(tmp_path / "out" / "dataset.json")


def test_a_count_caps_a_split_and_grows_keeping_its_scenes(demo_recordings, tmp_path, tsel_cli):
    args = ["--preset", "starss23", "--corpus-dir", demo_recordings, "--split", "train=0", "--out", tmp_path / "ds",
            "--quiet"]
    tsel_cli.ok("generate", *args, "--split", "test=3")
    first = open(tmp_path / "ds" / "plan" / "test.jsonl").read().splitlines()
    assert len(first) == 3
    tsel_cli.ok("generate", *args, "--split", "test=5", "--grow")
    grown = open(tmp_path / "ds" / "plan" / "test.jsonl").read().splitlines()
    assert len(grown) == 5 and grown[:3] == first
    # a cap above what the recordings hold keeps every target; --resume with it plans nothing new
    tsel_cli.ok("generate", *args, "--split", "test=1000", "--grow")
    assert len(open(tmp_path / "ds" / "plan" / "test.jsonl").read().splitlines()) == 7
    tsel_cli.ok("generate", *args, "--split", "test=1000", "--resume")


def test_the_mic_format_reads_mic_dev_with_its_capsules(demo_recordings, tmp_path, tsel_cli):
    tsel_cli.ok("generate", "--preset", "starss23", "--corpus-dir", demo_recordings, "--set", 'scene.format="tetra"',
                "--split", "train=0", "--split", "test=2", "--out", tmp_path / "mic", "--quiet")
    with open_dataset(str(tmp_path / "mic"), "test") as ds:
        s = ds[0]
        r = s.record.recording
        assert r.audio.startswith("mic_dev/") and s.format == "tetra" and list(ds.channel_names) == ["M1", "M2", "M3", "M4"]
        assert np.abs(np.linalg.norm(s.mic_positions, axis=1) - 0.042).max() < 1e-6
        x, _ = sf.read(os.path.join(demo_recordings, r.audio), dtype="float32", start=r.start_frame * 2400,
                       frames=r.frames * 2400)
        np.testing.assert_array_equal(s.audio, x.T)  # the recording's samples as they are


def test_recordings_of_your_own_with_your_ontology(tmp_path, demo_recordings, tsel_cli):
    own = tmp_path / "own"
    own.mkdir()
    for name in ("fold4_room3_mix003", "fold4_room4_mix004"):
        shutil.copy(os.path.join(demo_recordings, "foa_dev", "dev-test-sony", name + ".wav"), own / f"{name}.wav")
        shutil.copy(os.path.join(demo_recordings, "metadata_dev", "dev-test-sony", name + ".csv"), own / f"{name}.csv")
    onto = tmp_path / "classes.csv"
    onto.write_text("index,name,captions\n" + "\n".join(f"{k},thing {k},A thing number {k} hums" for k in range(13)))
    out = tmp_path / "ds"
    tsel_cli.ok("generate", "--preset", "starss23", "--corpus-dir", own, "--set", 'recorded.dataset="custom"',
                "--set", f'recorded.ontology="{onto}"', "--set", "splits.test.folds=[]", "--split", "train=0",
                "--out", out, "--quiet")
    with open_dataset(str(out), "test") as ds:
        queries = {s.query for s in ds.iter_labels()}
        assert any(q.startswith("A thing number") for q in queries)
        assert all("thing" in q.lower() for q in queries)
    line = tsel_cli.refused("check", "--preset", "starss23", "--corpus-dir", own, "--set", 'recorded.dataset="custom"')
    assert "recorded.dataset = \"custom\" needs your classes: recorded.ontology = FILE" in line


def test_every_tool_reads_a_recorded_dataset(made, tmp_path, tsel_cli):
    cfg, out = made
    text = tsel_cli.ok("inspect", out, "test/0", "--png", tmp_path / "s.png", "--wav", tmp_path / "s.wav")
    assert "recorded: starss23 foa_dev/" in text and "classes: [0] " in text and (tmp_path / "s.png").exists()
    code, text, err = tsel_cli.run("verify", out)
    assert code == 0 and "this reports how often they do, it does not judge the dataset" in text
    for fmt in ("webdataset", "hf", "dcase"):
        tsel_cli.ok("export", fmt, out, "--out", tmp_path / fmt)
    from tsel_data.streaming import SceneStream

    with open_dataset(out, "test") as ds:
        streamed = {s.scene_id: s for s in SceneStream(str(tmp_path / "webdataset"), "test")}
        for s in ds:
            np.testing.assert_array_equal(streamed[s.scene_id].audio, s.audio)
            assert streamed[s.scene_id].record.recording == s.record.recording
    # eval: predictions, with the blind answers beside them and a flag when one comes close
    pred = tmp_path / "pred.jsonl"
    with open_dataset(out, "test") as ds, open(pred, "w") as f:
        for s in ds.iter_labels():
            f.write(json.dumps({"scene_id": s.scene_id, "azimuth": float(s.azimuth[0][s.active[0]][0])}) + "\n")
    text = tsel_cli.ok("eval", out, "--pred", pred)
    assert "blind=train mean per class" in text and "blind=an interferer" in text and "warning:" not in text
    with open_dataset(out, "test") as ds, open(pred, "w") as f:
        for s in ds.iter_labels():
            f.write(json.dumps({"scene_id": s.scene_id, "azimuth": 0.0}) + "\n")
    text = tsel_cli.ok("eval", out, "--pred", pred)
    assert "warning: split test: answering blind (" in text and "rewards what a model can learn" in text


def test_the_stand_in_holds_what_the_docs_say():
    events = [e for *_, evs in RECORDINGS for e in evs]
    assert any(e.az[0] != e.az[1] for e in events)  # moving events
    assert any(e.off - e.on < 10 for e in events)  # shorter than min_active


def test_the_torch_dataset_serves_recorded_scenes(made):
    pytest.importorskip("torch")
    from tsel_data.torch import Dataset

    _, out = made
    ds = Dataset(out, "test")
    item = ds[0]
    assert tuple(item["audio"].shape) == (4, 240000) and item["pairing"] == "recorded"
    active = item["active"][0].numpy()
    assert np.isfinite(item["azimuth"][0].numpy()[active]).all()
    assert np.isnan(item["azimuth"][0].numpy()[~active]).all()


def test_the_dcase2025_stereo_set_reads_azimuth_and_distance_and_verifies(demo_recordings, tmp_path, tsel_cli):
    """The stereo set's layout (stereo_dev/, rows frame,class,source,azimuth,distance,onscreen),
    made here from the stand-in's FOA (L = W + Y, R = W - Y; azimuth folded to the front as
    the set's are): elevation is not labelled, and verify judges the lateral angle."""
    from tsel_data.tools.verify import fold_front_back

    root = tmp_path / "stereo-set"
    for folder in ("dev-train-sony", "dev-test-sony"):
        (root / "stereo_dev" / folder).mkdir(parents=True)
        (root / "metadata_dev" / folder).mkdir(parents=True)
        for wav in Path(demo_recordings, "foa_dev", folder).iterdir():
            x, fs = sf.read(wav, dtype="float32")
            sf.write(root / "stereo_dev" / folder / wav.name, np.stack([x[:, 0] + x[:, 1], x[:, 0] - x[:, 1]], 1), fs)
            rows = _rows(demo_recordings, f"metadata_dev/{folder}/{wav.stem}.csv")
            with open(root / "metadata_dev" / folder / f"{wav.stem}.csv", "w") as f:
                for r in rows:
                    f.write(f"{r[0]},{r[1]},{r[2]},{int(round(float(fold_front_back(r[3]))))},150,1\n")
    out = tmp_path / "ds"
    tsel_cli.ok("generate", "--preset", "dcase2025-stereo", "--corpus-dir", root, "--out", out, "--quiet")
    with open_dataset(str(out), "test") as ds:
        s = ds[0]
        assert s.format == "stereo" and s.audio.shape == (2, 5 * FS) and s.n_frames == 50
        assert np.isnan(s.elevation).all() and np.nanmax(s.distance) == pytest.approx(1.5)
    code, text, _ = tsel_cli.run("verify", out, "--json")
    rates = [v["rate"] for v in json.loads(text)["splits"].values() if v["tested"]]
    assert code == 0 and rates and all(r > 0.5 for r in rates)


def test_a_rebuild_says_which_scenes_labels_that_changed_can_no_longer_make(made, tmp_path, tsel_cli):
    cfg, out = made
    rel = tmp_path / "release"
    tsel_cli.ok("export", "recipes", out, "--out", rel, "--split", "test")
    copy = tmp_path / "copy"
    shutil.copytree(cfg.corpus.dir, copy)
    meta = copy / "metadata_dev" / "dev-test-sony" / "fold4_room3_mix003.csv"
    meta.write_text("".join(line for line in meta.read_text().splitlines(keepends=True)
                            if line.split(",")[1] != "10"))  # the running tap is no longer labelled
    tsel_cli.ok("generate", "--from", rel, "--corpus-dir", copy, "--out", tmp_path / "again", "--quiet")
    scenes = json.load(open(tmp_path / "again" / "rebuild.json"))["scenes"]
    gone = [s for s in scenes if s["status"] == "not-buildable"]
    assert gone and all("no longer labels source (10, 0, 0)" in s["why"] for s in gone)
    assert {s["status"] for s in scenes} - {"not-buildable"} <= {"identical", "differs"}
