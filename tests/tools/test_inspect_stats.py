import dataclasses
import json

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner

from support.datasets import make_dataset
from tsel_data.cli.inspect import inspect_cmd
from tsel_data.cli.stats import stats_cmd
from tsel_data.errors import DatasetError, TselError
from tsel_data.core.geometry import array_to_room
from tsel_data.tools.inspect import find_scene, inspect_scene, source_tracks
from tsel_data.tools.stats import dataset_stats

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

    from tsel_data.tools.evaluate import PredictionError, evaluate

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


# --- looking and listening (issue 16) ---------------------------------------------------------------------------------


def test_frame_segments_show_sparse_activity_and_do_not_jump_at_the_wrap():
    from tsel_data.tools.inspect import frame_runs, frame_segments, wrap_breaks

    hop = 0.1
    active = np.zeros(20, bool)
    active[[3, 9, 10, 11]] = True  # a tick in one frame, then three frames
    x, y = frame_segments(np.full(20, 40.0), active, hop)
    assert frame_runs(active) == [(3, 1), (9, 3)]
    strokes = np.split(x, np.flatnonzero(np.isnan(x)))
    assert np.allclose(strokes[0], [0.3, 0.35, 0.4])  # the single frame is drawn its whole width
    assert np.allclose(strokes[1][~np.isnan(strokes[1])], [0.9, 0.95, 1.05, 1.15, 1.2])
    # a moving source crossing ±180°: no drawn step is longer than 180° (no vertical line)
    az = ((np.arange(20) * 25.0 + 180.0) % 360.0) - 180.0
    x, y = frame_segments(az, np.ones(20, bool), hop)
    ok = ~np.isnan(y[:-1]) & ~np.isnan(y[1:])
    assert np.all(np.abs(np.diff(y))[ok] <= 25.0 + 1e-9) and np.isnan(y).any()
    t, a = wrap_breaks(np.arange(20) * hop, az)
    ok = ~np.isnan(a[:-1]) & ~np.isnan(a[1:])
    assert np.all(np.abs(np.diff(a))[ok] <= 25.0 + 1e-9)


def test_summary_lists_every_caption(ds):
    root, _ = ds
    from tsel_data.tools.inspect import summary

    scene = find_scene(root, "train/0")
    object.__setattr__(scene.record.sources[0], "captions", [f"caption number {k}" for k in range(5)])
    text = summary(scene)
    assert all(f"caption: caption number {k}" in text for k in range(5))


# A record's noise as the renderer writes it (render/noise.py): every kind, sensor noise set in dBFS.
NOISE = ({"kind": "ambience", "snr_db": 12.5, "level_dbfs": -38.25, "file": "03_bahnhof/ambience_foa.wav",
          "offset": 48000},
         {"kind": "diffuse", "snr_db": 20.0, "level_dbfs": -45.5, "spectrum": "pink"},
         {"kind": "babble", "snr_db": 15.25, "level_dbfs": -41.0, "clips": [["audio/a.wav", 0.0], ["audio/b.wav", 1.5]],
          "directions": [[-87.639, 34.529], [24.115, -57.269]]},
         {"kind": "sensor", "snr_db": None, "level_dbfs": -60.0})


def with_noise(scene, noise=NOISE):
    from tsel_data.store.records import NoiseRecord

    scene.record = dataclasses.replace(scene.record, noise=tuple(NoiseRecord.from_json(n) for n in noise))
    return scene


def test_summary_shows_the_noise(ds):
    from tsel_data.tools.inspect import summary

    root, _ = ds
    text = summary(with_noise(find_scene(root, "train/0")))
    head, _, rest = text.partition("noise (unlabelled):\n")
    lines = dict((ln.split()[0], ln) for ln in rest.splitlines())
    assert list(lines) == ["ambience", "diffuse", "babble", "sensor"]
    assert "03_bahnhof/ambience_foa.wav from sample 48000" in lines["ambience"]
    assert "SNR 12.5 dB" in lines["ambience"] and "level -38.2 dBFS" in lines["ambience"]
    assert "pink spectrum" in lines["diffuse"] and "SNR 20.0 dB" in lines["diffuse"]
    assert "2 clips" in lines["babble"] and "from (az, el) deg (-87.6, 34.5) (24.1, -57.3)" in lines["babble"]
    assert "SNR 15.2 dB" in lines["babble"]
    assert "level -60.0 dBFS" in lines["sensor"] and "SNR" not in lines["sensor"]  # set in dBFS, no SNR
    assert "noise" not in summary(find_scene(root, "train/1"))  # a scene without noise says nothing of it


def test_summary_gives_a_moving_source_from_where_to_where(ds):
    from tsel_data.tools.inspect import summary

    root, _ = ds
    scene = find_scene(root, "train/1")  # its target turns 60 degrees
    scene.elevation[0] = np.linspace(10.0, 25.0, scene.n_frames)
    scene.distance[0] = np.linspace(1.8, 2.4, scene.n_frames)
    target, interferer = [ln for ln in summary(scene).splitlines() if ln.startswith(("  [0]", "  [1]"))]
    az = scene.azimuth[0]
    assert f"az {az[0]:7.1f} -> {az[-1]:.1f} deg  el  10.0 -> 25.0 deg  dist 1.80 -> 2.40 m" in target
    assert "el  -5.0 deg  dist 2.40 m" in interferer  # a static source: one value each


def test_stereo_preview_of_each_format():
    from tsel_data.core.geometry import foa_gains
    from tsel_data.receivers.stereo import stereo_preview

    sig = np.ones(8, np.float32)
    left_src = foa_gains(90.0, 0.0)[:, None] * sig  # a plane wave from the left
    front_src = foa_gains(0.0, 0.0)[:, None] * sig
    lr = stereo_preview(left_src, "foa")
    assert lr.shape == (2, 8) and np.allclose(lr[0], 1.0) and np.allclose(lr[1], 0.0)
    assert np.allclose(stereo_preview(front_src, "foa"), 0.5)  # in front: both ears alike
    mics = np.arange(4, dtype=np.float32)[:, None] * sig
    assert np.allclose(stereo_preview(mics, "mic4")[:, 0], [0, 3])  # front-left, front-right
    assert np.allclose(stereo_preview(mics, "tetra")[:, 0], [0, 1])
    assert stereo_preview(np.zeros((3, 4, 8)), "foa").shape == (3, 2, 8)


def test_inspect_writes_the_headphone_preview(ds, tmp_path):
    root, written = ds
    inspect_scene(root, "train/0", wav=str(tmp_path / "a.wav"))
    stereo, fs = sf.read(tmp_path / "a.stereo.wav", dtype="float32")
    w = written["train"][0]
    assert stereo.shape == (w.audio.shape[1], 2) and fs == 16000
    np.testing.assert_array_equal(stereo[:, 0], w.audio[0])  # mic4: the front pair
    np.testing.assert_array_equal(stereo[:, 1], w.audio[3])


def test_stats_motion_and_speed(ds, tmp_path):
    from tsel_data.tools.stats import angular_speed, plot_stats

    root, written = ds
    st = dataset_stats(str(root))
    tr = st["train"]
    # the fixture's moving target turns 60° over 20 frames of 0.1 s at 10° elevation
    speed = 60.0 / 19 / 0.1 * np.cos(np.radians(10.0))
    assert tr["moving_sources"]["speed_deg_s"]["n"] == 1
    assert tr["moving_sources"]["speed_deg_s"]["median"] == pytest.approx(speed, rel=1e-3)
    assert tr["moving_sources"]["scenes"] == {"static": 3, "target": 1}
    assert angular_speed([0, 90, 180], [0, 0, 0], 1.0) == pytest.approx(90.0)
    assert tr["target_elevation_deg"]["mean"] == pytest.approx(10.0)
    plot_stats(st, str(tmp_path / "s.png"))
    assert (tmp_path / "s.png").read_bytes()[:8] == PNG_MAGIC


def test_tools_read_the_finished_shards_of_a_dataset_still_being_made(ds, tmp_path, capsys):
    import shutil

    from tsel_data.cli import main
    from tsel_data.store.plans import plan_doc

    root, written = ds
    part = tmp_path / "part"
    shutil.copytree(root, part)
    os_remove = __import__("os").remove
    os_remove(part / "dataset.json")  # not finished: a plan, some shards
    os_remove(part / "train" / "shard-00000.h5")
    config = {"audio": {"fs": 16000, "duration": 2.0, "label_hop": 0.1}, "scene": {"format": "mic4"},
              "output": {"shard_size": 2}, "splits": {"train": {"count": 4}, "test": {"count": 2}}, "seed": 0}
    (part / "plan").mkdir()
    (part / "plan" / "config.json").write_text(json.dumps(plan_doc(config, {}, 0)))
    with pytest.raises(DatasetError, match="not a tsel-data dataset"):
        __import__("tsel_data").open_dataset(str(part), "train")  # trainers read finished datasets only
    scene = find_scene(str(part), "train/3")
    assert scene.scene_id == "train-000003" and scene.index == 3
    with pytest.raises(DatasetError, match=r"'train/1' is not rendered yet"):
        find_scene(str(part), "train/1")
    assert dataset_stats(str(part))["train"]["scenes"] == 2
    for args in (["inspect", part, "train/2"], ["stats", part], ["verify", part, "--quiet"]):
        with pytest.raises(SystemExit) as e:
            main([str(a) for a in args])
        out = capsys.readouterr()
        assert e.value.code == 0, out.err
        assert out.err.startswith(f"note: {part} is still being made (no dataset.json yet): 2 of 3 shards finished, "
                                  f"train 2 of 4, test 2 of 2 scenes; showing those")
