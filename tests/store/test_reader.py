import multiprocessing as mp
import pickle

import numpy as np
import pytest

from support.datasets import make_dataset
from tsel_data.tools import labels as L
from tsel_data.errors import DatasetError
from tsel_data.store import list_splits, open_dataset


@pytest.fixture(scope="module")
def ds_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds")
    scenes = make_dataset(root, splits={"train": 5, "test": 2}, additive={"train-000003"}, moving={"train-000001"})
    return root, scenes


def test_round_trip_every_field(ds_dir):
    root, written = ds_dir
    ds = open_dataset(root, "train")
    assert len(ds) == 5 and len(ds.shards) == 3  # shard_size 2: 2 + 2 + 1
    for i, w in enumerate(written["train"]):
        s = ds[i]
        assert s.scene_id == w.scene_id and s.query == w.query and s.index == i
        assert s.audio.dtype == np.float32 and s.audio.shape == w.audio.shape
        np.testing.assert_array_equal(s.audio, w.audio)
        # Padding to the shard's widest scene is removed: S is the scene's own count.
        assert s.azimuth.shape == w.azimuth.shape
        np.testing.assert_array_equal(s.azimuth, w.azimuth)
        np.testing.assert_array_equal(s.active, w.active)
        np.testing.assert_allclose(s.mic_positions, w.mic_positions)
        assert s.record["scene_id"] == w.scene_id
        assert s.fs == 16000 and s.label_hop == 0.1 and s.format == "mic4"
    assert ds[1].target_moving and not ds[0].target_moving
    assert np.isnan(ds[3].azimuth[2]).all()  # additive source: no position


def test_negative_index_iteration_and_lookup(ds_dir):
    root, written = ds_dir
    ds = open_dataset(root, "train")
    assert ds[-1].scene_id == "train-000004"
    assert [s.scene_id for s in ds] == [w.scene_id for w in written["train"]]
    assert ds.by_id("train-000002").index == 2 and "train-000002" in ds and "test-000000" not in ds
    assert ds.get(0, audio=False).audio is None
    assert [r["scene_id"] for r in ds.records()] == ds.scene_ids()
    with pytest.raises(IndexError):
        ds[5]
    with pytest.raises(DatasetError, match="no scene"):
        ds.by_id("nope")


def test_errors_name_the_problem(tmp_path, ds_dir):
    root, _ = ds_dir
    with pytest.raises(DatasetError, match="dataset.json not found"):
        open_dataset(tmp_path, "train")
    with pytest.raises(DatasetError, match=r"available splits: test, train"):
        open_dataset(root, "val")
    assert list_splits(root) == ["train", "test"]


def test_missing_shard_is_reported(tmp_path):
    make_dataset(tmp_path, splits={"train": 2})
    (tmp_path / "train" / "shard-00000.h5").rename(tmp_path / "gone.h5")
    with pytest.raises(DatasetError, match="incomplete"):
        open_dataset(tmp_path, "train")


def _worker_read(ds, i, q):
    q.put(float(ds[i].audio.sum()))


def test_pickle_and_fork_safe(ds_dir):
    root, written = ds_dir
    ds = open_dataset(root, "train")
    _ = ds[0]  # opens a handle in the parent
    assert ds._h5
    clone = pickle.loads(pickle.dumps(ds))
    assert not clone._h5 and clone[2].scene_id == "train-000002"
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_worker_read, args=(ds, 1, q))
    p.start()
    got = q.get(timeout=20)
    p.join(timeout=20)
    assert p.exitcode == 0
    assert got == pytest.approx(float(written["train"][1].audio.sum()), rel=1e-6)
    # The parent's handle is untouched and still reads.
    assert ds[0].scene_id == "train-000000"


def test_torch_dataset_when_available(ds_dir):
    torch = pytest.importorskip("torch")
    from tsel_data.tools.torch import Dataset

    root, _ = ds_dir
    d = Dataset(root, "train")
    item = d[0]
    assert isinstance(item["audio"], torch.Tensor) and item["audio"].shape[0] == 4
    assert item["class_index"].shape == (20,)


def test_label_encodings():
    az = np.array([-180.0, -0.4, 0.5, 44.6, 179.6, -90.0])
    k = L.azimuth_to_class(az)
    assert k.tolist() == [180, 0, 1, 45, 180, 270]  # round(φ) mod 360, halves up
    np.testing.assert_allclose(L.class_to_azimuth(k), [-180, 0, 1, 45, -180, -90])

    g = L.gaussian_target(np.array([0.0, 179.0, np.nan]), sigma=5.0)
    assert g.shape == (3, 360)
    np.testing.assert_allclose(g[:2].sum(-1), 1.0, rtol=1e-6)
    assert g[2].sum() == 0  # no position: no target mass
    assert np.argmax(g[0]) == 0 and g[0, 5] == pytest.approx(g[0, 355])  # wraps around 0/360
    assert np.argmax(g[1]) == 179 and g[1, 181] == pytest.approx(g[1, 177])  # across ±180
    # One standard deviation away: exp(-1/2) of the peak.
    assert g[0, 5] / g[0, 0] == pytest.approx(np.exp(-0.5), rel=1e-6)
    assert L.decode_distribution(g[:2]).tolist() == [0.0, 179.0]

    v = L.accdoa(np.array([90.0, 0.0]), np.array([0.0, 90.0]), np.array([True, False]))
    np.testing.assert_allclose(v, [[0, 1, 0], [0, 0, 0]], atol=1e-7)
    az2, el2, act2 = L.decode_accdoa(L.accdoa(np.array([-135.0]), np.array([20.0]), np.array([True])))
    assert az2[0] == pytest.approx(-135.0) and el2[0] == pytest.approx(20.0) and act2[0]
