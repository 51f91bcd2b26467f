"""The PyTorch adapter over on-the-fly scenes: DataLoader workers (fork and spawn, any
count) give the same scenes as the main process; epochs draw new ones; ``query="any"``
only gives unambiguous captions. Skipped without torch."""
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from tsel_data.corpus.captions import answerable_queries  # noqa: E402
from tsel_data.config import load_config  # noqa: E402
from tsel_data.core.jsonable import jsonable  # noqa: E402
from tsel_data.job.onthefly import SceneSource  # noqa: E402
from tsel_data.tools.torch import Dataset, collate, worker_init_fn  # noqa: E402


@pytest.fixture(scope="module")
def source(tmp_path_factory, demo_corpus):
    cfg = load_config(preset="demo", corpus_dir=demo_corpus, splits={"train": 6, "val": 0, "test": 0},
                      overrides=["audio.duration=1.0", 'scene.scenario="two-directional"'])
    return SceneSource(cfg, "train", home=str(tmp_path_factory.mktemp("home")))


def _batches(ds, workers, method=None, epoch=0):
    ds.set_epoch(epoch)
    loader = torch.utils.data.DataLoader(ds, batch_size=2, num_workers=workers, collate_fn=collate,
                                         multiprocessing_context=method if workers else None,
                                         worker_init_fn=worker_init_fn if workers else None)
    return [b for b in loader]


@pytest.mark.parametrize("workers,method", [(2, "fork"), (2, "spawn"), (1, "spawn")])
def test_workers_give_the_main_process_scenes(source, workers, method):
    ds = Dataset(source, with_record=True)
    main = _batches(ds, 0)
    other = _batches(ds, workers, method)
    for a, b in zip(main, other):
        assert a["scene_id"] == b["scene_id"] and a["query"] == b["query"]
        assert torch.equal(a["audio"], b["audio"]) and torch.equal(a["gaussian"], b["gaussian"])
        assert [json.dumps(jsonable(r)) for r in a["record"]] == [json.dumps(jsonable(r)) for r in b["record"]]


def test_epochs_draw_new_scenes_the_same_for_any_worker_count(source):
    ds = Dataset(source)
    e0, e1 = _batches(ds, 0, epoch=0), _batches(ds, 0, epoch=1)
    assert not torch.equal(e0[0]["audio"], e1[0]["audio"])
    e1_workers = _batches(ds, 2, "fork", epoch=1)
    assert all(torch.equal(a["audio"], b["audio"]) for a, b in zip(e1, e1_workers))
    # an (epoch, index) key reads any epoch, whatever the current one
    ds.set_epoch(0)
    assert torch.equal(ds[(1, 0)]["audio"], e1[0]["audio"][0])


def test_any_query_is_one_of_the_targets_unambiguous_captions(source):
    ds = Dataset(source, query="any", with_record=True)
    seen = set()
    for epoch in range(4):
        ds.set_epoch(epoch)
        for i in range(len(ds)):
            item = ds[i]
            rec = item["record"]
            pool = answerable_queries(rec.sources[0].captions, [s.captions for s in rec.sources[1:]],
                                      source.caption_similarity)
            assert item["query"] in (pool or [rec.query])
            seen.add(item["query"])
    assert len(seen) > len(ds)  # captions vary across epochs and scenes


def test_item_shapes_and_targets(source):
    item = Dataset(source)[0]
    assert item["audio"].shape == (4, 24000) and item["audio"].dtype == torch.float32
    assert item["gaussian"].shape == (10, 360)
    k = item["class_index"].numpy()
    az = item["azimuth"][0].numpy()
    np.testing.assert_array_equal(k, np.floor(az + 0.5).astype(int) % 360)


@pytest.mark.parametrize("workers", [0, 2])
def test_a_batch_from_shards_is_its_items_read_in_one_pass(generated_dataset, workers):
    """``__getitems__`` reads a batch's audio into one tensor (shared memory in a worker),
    and collate hands that tensor on as it is: the same batches as item by item."""
    _, out = generated_dataset("small")

    class ItemByItem(Dataset):
        __getitems__ = None  # the DataLoader then asks ds[i] for each index

    def batches(ds, n):
        loader = torch.utils.data.DataLoader(ds, batch_size=n, num_workers=workers, collate_fn=collate)
        return list(loader)

    for got, want in zip(batches(Dataset(out, "train"), 4), batches(ItemByItem(out, "train"), 4)):
        assert got.keys() == want.keys() and got["scene_id"] == want["scene_id"]
        for key, value in want.items():
            if isinstance(value, torch.Tensor):
                assert torch.equal(got[key].nan_to_num(7.0), value.nan_to_num(7.0)), key
    items = Dataset(out, "train").__getitems__([3, 0, 5])
    batch = collate(items)
    assert batch["audio"].data_ptr() == items[0]["audio"].data_ptr()  # no copy
    assert all(torch.equal(batch["audio"][b], Dataset(out, "train")[i]["audio"]) for b, i in enumerate([3, 0, 5]))
