import csv
import json

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner

from support.datasets import make_dataset
from tsel_data.cli.export import export_cmd
from tsel_data.errors import DatasetError, TselError
from tsel_data.export import export_dcase
from tsel_data.formats.dcase import dcase_rows, read_dcase_csv
from tsel_data.store import Scene, open_dataset


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds")
    make_dataset(root, splits={"train": 3, "test": 2}, moving={"train-000001"}, additive={"train-000002"})
    out = tmp_path_factory.mktemp("dcase")
    summary = export_dcase(str(root), str(out), subtype="FLOAT")
    return root, out, summary


def test_csv_matches_labels(exported):
    root, out, summary = exported
    for split, fold in (("train", 1), ("test", 2)):
        assert summary["splits"][split]["fold"] == fold
        for s in open_dataset(root, split):
            rows = read_dcase_csv(out / "metadata_dev" / f"dev-{split}-tsel" / f"fold{fold}_{s.scene_id}.csv")
            directional = [k for k in range(s.n_sources) if np.isfinite(s.azimuth[k]).any()]
            # Only active frames, only sources with a position.
            assert len(rows) == sum(int(s.active[k].sum()) for k in directional)
            for k in directional:
                cls, src = (0, 0) if k == 0 else (1, k - 1)
                mine = rows[(rows[:, 1] == cls) & (rows[:, 2] == src)]
                np.testing.assert_array_equal(mine[:, 0], np.flatnonzero(s.active[k]))
                on = s.active[k]
                assert np.all(np.abs(mine[:, 3] - s.azimuth[k][on]) <= 0.5 + 1e-4)
                assert np.all(np.abs(mine[:, 4] - s.elevation[k][on]) <= 0.5 + 1e-4)
                assert np.all(np.abs(mine[:, 5] - 100 * s.distance[k][on]) <= 0.5 + 1e-3)  # centimetres
            assert (np.diff(rows[:, 0]) >= 0).all()  # sorted by frame


def test_wav_and_queries(exported):
    root, out, _ = exported
    s = open_dataset(root, "train")[1]
    audio, fs = sf.read(out / "mic_dev" / "dev-train-tsel" / "fold1_train-000001.wav", dtype="float32")
    assert fs == s.fs
    np.testing.assert_array_equal(audio.T, s.audio)
    with open(out / "queries.csv", newline="") as f:
        q = list(csv.DictReader(f))
    assert [r["scene_id"] for r in q] == [f"train-{i:06d}" for i in range(3)] + ["test-000000", "test-000001"]
    assert q[1]["query"] == s.query and q[1]["file"] == "fold1_train-000001" and q[1]["file"][4] == "1"
    info = json.loads((out / "classes.json").read_text())
    assert info["classes"] == {"0": "target", "1": "interferer"} and info["folds"] == {"train": 1, "test": 2}


def _scene(az, el, dist, active, hop=0.1):
    az, el, dist = (np.asarray(x, np.float32) for x in (az, el, dist))
    return Scene("x", "test", 0, "q", None, az, el, dist, np.asarray(active, bool), np.zeros((4, 3), np.float32),
                 24000, hop, "mic4")


def test_rows_round_and_wrap():
    s = _scene([[179.6, -0.5, 10.4], [np.nan] * 3, [45.0, 45.0, 45.0]], [[0.4, 0.5, -0.5], [np.nan] * 3, [1, 1, 1]],
               [[1.234, 2.0, 0.9999], [np.nan] * 3, [3, 3, 3]], [[1, 1, 1], [1, 1, 1], [0, 1, 0]])
    rows = dcase_rows(s)
    # 179.6 rounds to 180, which is -180 in [-180, 180); source 1 (additive) is skipped;
    # source 2 is the first interferer: class 1, source index 0.
    assert rows == [(0, 0, 0, -180, 0, 123), (1, 0, 0, 0, 1, 200), (1, 1, 0, 45, 1, 300), (2, 0, 0, 10, 0, 100)]
    with pytest.raises(DatasetError, match="label_hop"):
        dcase_rows(_scene([[0.0]], [[0.0]], [[1.0]], [[1]], hop=0.05))


def test_pcm_and_cli(exported, tmp_path):
    root, _, _ = exported
    res = CliRunner().invoke(export_cmd, ["dcase", str(root), "--out", str(tmp_path / "o"), "--split", "test",
                                          "--quiet"])
    assert res.exit_code == 0, res.output
    assert "test: fold 2, 2 scenes" in res.output
    info = sf.info(tmp_path / "o" / "mic_dev" / "dev-test-tsel" / "fold2_test-000000.wav")
    assert info.subtype == "PCM_16" and info.channels == 4
    res = CliRunner().invoke(export_cmd, ["dcase", str(root), "--out", str(tmp_path / "o2"), "--split", "val"])
    assert isinstance(res.exception, TselError) and "available splits: train, test" in str(res.exception)


def test_exporting_a_split_into_an_export_merges_it(tmp_path):
    root = tmp_path / "ds"
    make_dataset(root, splits={"train": 3, "val": 1, "test": 2})
    out = tmp_path / "dcase"
    export_dcase(str(root), str(out), splits=["train"], subtype="FLOAT")
    export_dcase(str(root), str(out), splits=["test"], subtype="FLOAT")
    export_dcase(str(root), str(out), splits=["train"], subtype="FLOAT")  # again: replaces, no duplicates
    with open(out / "queries.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["fold", "split", "file", "scene_id", "query"]
    assert [(r[0], r[3]) for r in rows[1:]] == [("1", "train-000000"), ("1", "train-000001"), ("1", "train-000002"),
                                                ("3", "test-000000"), ("3", "test-000001")]
    assert json.loads((out / "classes.json").read_text())["folds"] == {"train": 1, "test": 3}
    # a dataset that shrank leaves no stale files behind
    make_dataset(root, splits={"train": 1, "val": 1, "test": 2})
    export_dcase(str(root), str(out), splits=["train"], subtype="FLOAT")
    assert sorted(p.name for p in (out / "mic_dev" / "dev-train-tsel").iterdir()) == ["fold1_train-000000.wav"]
    assert sorted(p.name for p in (out / "metadata_dev" / "dev-train-tsel").iterdir()) == ["fold1_train-000000.csv"]


def test_exporting_into_an_export_of_something_else_is_refused(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    make_dataset(a, splits={"train": 2, "test": 1})
    make_dataset(b, splits={"train": 2, "test": 1}, fmt="foa")
    out = tmp_path / "dcase"
    export_dcase(str(a), str(out), splits=["train"], subtype="FLOAT")
    with pytest.raises(DatasetError) as e:
        export_dcase(str(b), str(out), splits=["test"], subtype="FLOAT")
    assert str(e.value) == (f"{out} holds an export of another dataset {a} (now {b}), format mic4 (now foa); adding "
                            f"this one would mix them: export into another --out, or pass --force to replace it")
    with pytest.raises(DatasetError, match=r"another WAV subtype FLOAT \(now PCM_16\)"):
        export_dcase(str(a), str(out), splits=["test"], subtype="PCM_16")
    from tsel_data.cli import main

    with pytest.raises(SystemExit) as ex:
        main(["export", "dcase", str(b), "--out", str(out)])
    err = capsys.readouterr().err
    assert ex.value.code == 2 and err.count("\n") == 1 and err.startswith(f"error: {out} holds an export of another")
