"""Scenes rendered on the fly are the scenes of the generated dataset, bit for bit;
epochs draw other scenes deterministically; sources work in fork and spawn workers."""
import multiprocessing as mp
from dataclasses import replace

import pytest

from support.datasets import assert_same_scene

from tsel_data.config import load_config
from tsel_data.errors import ConfigError
from tsel_data.job.onthefly import SceneSource, epoch_seed, scene_source
from tsel_data.job.pipeline import generate
from tsel_data.plan.sampler import plan_scene
from tsel_data.store.reader import open_dataset


@pytest.fixture
def generated(generated_dataset):
    return generated_dataset("onthefly")


def test_on_the_fly_scenes_equal_the_generated_dataset(generated):
    cfg, out = generated
    for split in ("train", "test"):
        source = SceneSource(cfg, split, home=out)
        with open_dataset(out, split) as ds:
            assert len(source) == len(ds)
            for i in range(len(ds)):
                assert_same_scene(source[i], ds[i])


@pytest.mark.slow
def test_on_the_fly_bank_scenes_with_moving_sources_equal_the_generated_dataset(tmp_path, demo_corpus):
    out = str(tmp_path / "out")
    cfg = load_config(preset="demo-moving", corpus_dir=demo_corpus, splits={"train": 4, "val": 0, "test": 0},
                      overrides=["audio.duration=2.0", "scene.moving_fraction=1.0"])
    generate(cfg, out, workers=1, progress=False)
    source = SceneSource(cfg, "train", home=out)
    with open_dataset(out, "train") as ds:
        assert any(s.target_moving for s in ds)
        for i in range(len(ds)):
            assert_same_scene(source[i], ds[i])


def test_epochs_draw_other_scenes_deterministically(generated):
    cfg, out = generated
    a = SceneSource(cfg, "train", home=out)
    b = SceneSource(cfg, "train", home=out, epoch=2)
    assert a.recipe(0) != a.recipe(0, epoch=1) != a.recipe(0, epoch=2)
    assert b.recipe(0) == a.recipe(0, epoch=2)  # the same epoch, whichever source draws it
    # epoch e is the dataset of seed epoch_seed(seed, e): reproducible offline with --seed
    assert a.recipe(3, epoch=1) == plan_scene(replace(cfg, seed=epoch_seed(cfg.seed, 1)), "train", 3, a.view)
    assert epoch_seed(cfg.seed, 0) == cfg.seed and len({epoch_seed(0, e) for e in range(50)}) == 50
    a.set_epoch(1)
    assert a[0].query == a.get(0, epoch=1).query and a.epoch == 1
    with pytest.raises(IndexError):
        a[6]
    assert a[-1].scene_id == "train-000005"


def _render(args):
    source, i = args
    return source[i]


@pytest.mark.parametrize("method", ["fork", "spawn"])
def test_sources_render_the_same_in_worker_processes(generated, method):
    cfg, out = generated
    source = SceneSource(cfg, "test", home=out)
    here = [source[i] for i in range(len(source))]
    with mp.get_context(method).Pool(2) as pool:
        there = pool.map(_render, [(source, i) for i in range(len(source))])
    for a, b in zip(here, there):
        assert_same_scene(a, b)


def test_scene_source_from_a_preset_and_bad_splits(generated, demo_corpus, tmp_path):
    cfg, out = generated
    s = scene_source(preset="demo", split="test", home=out, corpus_dir=demo_corpus, splits={"train": 6, "val": 0, "test": 2},
                     overrides=["audio.duration=2.0", "output.shard_size=4"])
    assert len(s) == 2 and s.recipe(1) == SceneSource(cfg, "test", home=out).recipe(1)
    with pytest.raises(ConfigError, match="split 'val' makes no scenes.*train, test"):
        SceneSource(cfg, "val", home=out)
