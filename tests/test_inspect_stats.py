import json

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner

from datasetfixture import make_dataset
from tsel_data.cli.inspect import inspect_cmd
from tsel_data.cli.stats import stats_cmd
from tsel_data.errors import DatasetError, TselError
from tsel_data.geometry import array_to_room
from tsel_data.inspect import find_scene, inspect_scene, source_tracks
from tsel_data.stats import dataset_stats

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds")
    written = make_dataset(root, splits={"train": 4, "test": 2}, moving={"train-000001"},
                           additive={"train-000002"})
    return root, written


def test_find_scene_by_id_and_index(ds):
    root, _ = ds
    assert find_scene(root, "test-000001").split == "test"
    assert find_scene(root, "train/-1").scene_id == "train-000003"
    with pytest.raises(DatasetError, match="no scene 'test-000009'"):
        find_scene(root, "test-000009")
    with pytest.raises(DatasetError, match="has 2 scenes"):
        find_scene(root, "test/5")
    with pytest.raises(TselError, match="integer index"):
        find_scene(root, "test/x")


def test_inspect_outputs(ds, tmp_path):
    root, written = ds
    scene, text = inspect_scene(root, "train-000002", png=str(tmp_path / "a.png"), wav=str(tmp_path / "a.wav"))
    w = written["train"][2]
    assert w.query in text and "additive" in text and "no position" in text and "RT60 0.60 s" in text
    assert (tmp_path / "a.png").read_bytes()[:8] == PNG_MAGIC
    audio, fs = sf.read(tmp_path / "a.wav", dtype="float32")
    assert fs == 16000
    np.testing.assert_array_equal(audio.T, w.audio)


def test_tracks_are_the_room_positions(ds):
    root, written = ds
    s = find_scene(root, "train/0")
    tracks, centre, yaw = source_tracks(s)
    # Labels (array frame) mapped back into the room land on the recorded room positions.
    for k, src in enumerate(s.record["sources"]):
        np.testing.assert_allclose(tracks[k][0], src["position"], atol=1e-3)
    np.testing.assert_allclose(centre, s.record["array"]["centre"])
    moving = find_scene(root, "train/1")
    tr = source_tracks(moving)[0][0]
    assert np.linalg.norm(tr[-1] - tr[0]) > 0.5  # the moving target's track really moves
    assert np.allclose(np.linalg.norm(tr - array_to_room(np.zeros(3), *source_tracks(moving)[1:]), axis=1), 1.8,
                       atol=1e-3)


def test_stats_values(ds, tmp_path):
    root, written = ds
    st = dataset_stats(str(root))
    tr = st["train"]
    assert tr["scenes"] == 4 and st["test"]["scenes"] == 2
    assert sum(tr["target_azimuth_hist"]["counts"]) == 4
    assert tr["moving_fraction"] == 0.25
    clip_ids = [src["clip_id"] for w in written["train"] for src in w.record["sources"]]
    assert tr["clips"]["uses"] == len(clip_ids) and tr["clips"]["used"] == len(set(clip_ids))
    assert tr["clips"]["reused"] == sum(clip_ids.count(c) > 1 for c in set(clip_ids))
    assert tr["separation_deg"]["min"] >= 70.0 - 1e-3  # the fixture keeps interferers 70..290 deg away
    assert tr["room_m"]["volume_m3"]["mean"] == pytest.approx(90.0)
    assert tr["rt60_s"]["measured_minus_requested"]["mean"] == pytest.approx(-0.05)
    assert tr["query_words"]["min"] >= 8
    assert tr["scenarios"] == {"two-directional": 3, "directional+additive": 1}


def test_clis(ds, tmp_path):
    root, _ = ds
    res = CliRunner().invoke(inspect_cmd, [str(root), "test/0", "--png", str(tmp_path / "i.png")])
    assert res.exit_code == 0, res.output
    assert "scene test-000000" in res.output and (tmp_path / "i.png").exists()
    res = CliRunner().invoke(stats_cmd, [str(root), "--png", str(tmp_path / "s.png")])
    assert res.exit_code == 0, res.output
    assert "split train: 4 scenes" in res.output and (tmp_path / "s.png").read_bytes()[:8] == PNG_MAGIC
    res = CliRunner().invoke(stats_cmd, [str(root), "--split", "test", "--json"])
    assert json.loads(res.output)["test"]["scenes"] == 2
    res = CliRunner().invoke(stats_cmd, [str(tmp_path / "nothing")])
    assert isinstance(res.exception, DatasetError)


def test_tools_close_their_files_even_when_they_fail(ds):
    """An error's traceback keeps the failing call's frame (and its open dataset) alive as
    long as the caller holds it, e.g. a notebook's last exception: the files must be closed
    by then, not when the traceback goes."""
    import h5py

    from tsel_data.evaluate import PredictionError, evaluate

    root, _ = ds

    def open_files():
        return h5py.h5f.get_obj_count(h5py.h5f.OBJ_ALL, h5py.h5f.OBJ_FILE)

    before = open_files()
    with pytest.raises(PredictionError) as bad_predictions:
        evaluate(root, "test", {})
    with pytest.raises(DatasetError) as bad_index:
        find_scene(root, "test/99")
    assert bad_predictions.tb is not None and bad_index.tb is not None  # both frames still alive
    assert open_files() == before
