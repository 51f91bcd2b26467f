"""The store: audio codings round-trip and read back as float32; the reader returns what
plain h5py reads; the writer streams (one scene's audio in memory) and leaves nothing on
failure."""
import io
import os
import shutil

import h5py
import numpy as np
import pytest
import soundfile as sf

from support.datasets import make_scene
from tsel_data.errors import DatasetError
from tsel_data.store.codings import INT16_SCALE, decode, encode, to_int16
from tsel_data.store.dataset import shard_attrs
from tsel_data.store.reader import open_dataset
from tsel_data.store.check import check_dataset
from tsel_data.store.writer import ShardWriter


def test_int16_and_flac_codings_round_trip():
    rng = np.random.default_rng(0)
    x = np.clip(0.3 * rng.standard_normal((4, 4800)), -0.99, 0.99).astype(np.float32)
    q = decode(encode(x, "int16", 24000), "int16")
    assert q.dtype == np.float32 and np.max(np.abs(q - x)) <= 0.5 / INT16_SCALE + 1e-9
    f = decode(encode(x, "flac", 24000), "flac")
    np.testing.assert_array_equal(f, q)  # lossless over int16
    assert to_int16(np.array([1.5, -1.5], np.float32)).tolist() == [32767, -32768]  # saturates, never wraps
    tone = (0.5 * np.sin(2 * np.pi * 440 * np.arange(4800) / 24000)).astype(np.float32)[None].repeat(4, 0)
    flac = encode(tone, "flac", 24000)
    assert flac.dtype == np.uint8 and flac.nbytes < 0.5 * encode(tone, "int16", 24000).nbytes


@pytest.fixture(params=["int16", "flac"])
def coded(request, generated_dataset):
    coding = request.param
    return coding, {c: generated_dataset(f"coded-{c}").out for c in ("float32", coding)}


def test_every_coding_reads_back_as_float32_and_verifies(coded):
    coding, out = coded
    assert check_dataset(out[coding]).ok
    with open_dataset(out["float32"], "train") as ref, open_dataset(out[coding], "train") as ds:
        assert ds.doc.raw["audio_coding"] == coding
        for i in range(len(ds)):
            a, b = ref[i].audio, ds[i].audio
            assert b.dtype == np.float32 and b.shape == a.shape
            np.testing.assert_allclose(b, a, atol=0.5 / INT16_SCALE + 1e-7)
            np.testing.assert_array_equal(ds[i].azimuth, ref[i].azimuth)
        buf = np.zeros((2, *ds[0].audio.shape), np.float32)
        np.testing.assert_array_equal(ds.read_audio([2, 0], out=buf), np.stack([ds[2].audio, ds[0].audio]))


def test_plain_h5py_decodes_every_coding_as_docs_format_says(coded):
    """The recipes of docs/format.md, "Audio codings"."""
    coding, out = coded
    with h5py.File(os.path.join(out[coding], "train", "shard-00000.h5")) as h:
        a = h["audio"]
        if coding == "int16":
            x = a[1].astype(np.float32) * a.attrs["audio_scale"]
        else:
            pcm, fs = sf.read(io.BytesIO(a[1].tobytes()), dtype="int16")
            x = pcm.T.astype(np.float32) * a.attrs["audio_scale"]
    with open_dataset(out[coding], "train") as ds:
        np.testing.assert_array_equal(x, ds[1].audio)


def test_the_writer_streams_and_leaves_nothing_when_a_scene_fails(tmp_path):
    rng = np.random.default_rng(1)
    scenes = [make_scene("train", i, rng=rng) for i in range(3)]
    attrs = shard_attrs(16000, 0.1, "mic4")
    with pytest.raises(RuntimeError, match="render failed"):
        with ShardWriter(str(tmp_path), "train", 0, 3, attrs) as w:
            w.add(scenes[0])
            assert w.kept[0].audio is None  # the audio went to the file, not to memory
            raise RuntimeError("render failed")
    assert os.listdir(tmp_path / "train") == []
    with ShardWriter(str(tmp_path), "train", 0, 3, attrs, fingerprint="f") as w:
        for s in scenes:
            w.add(s)
    assert sorted(os.listdir(tmp_path / "train")) == ["shard-00000.h5", "shard-00000.json", "shard-00000.seal.json"]
    with pytest.raises(ValueError, match="1 scenes written, 3 expected"):
        with ShardWriter(str(tmp_path), "train", 1, 3, attrs) as w:
            w.add(scenes[0])  # too few scenes: nothing under a final name
    assert not os.path.exists(tmp_path / "train" / "shard-00001.h5")


def test_a_shard_with_a_wrong_coding_is_refused(coded, tmp_path):
    coding, out = coded
    import json
    copy = shutil.copytree(out[coding], str(tmp_path / "ds"))
    p = os.path.join(copy, "dataset.json")
    doc = json.load(open(p))
    doc["audio_coding"] = "float32"
    json.dump(doc, open(p, "w"))
    msgs = check_dataset(copy).messages()
    assert any(f"audio coded as {coding}" in m for m in msgs)
    with pytest.raises(DatasetError):
        open_dataset(out[coding], "nope")


def test_plan_ranges_are_read_across_block_boundaries(tmp_path):
    from tsel_data.store.layout import Layout
    from tsel_data.store.plans import read_plan_range

    layout = Layout(str(tmp_path))
    os.makedirs(layout.plan_dir)
    lines = [f'{{"scene_id": "train-{i:06d}", "pad": "{"x" * (i % 7)}"}}' for i in range(50)]
    with open(layout.plan_file("train"), "w", encoding="utf-8") as f:
        f.write("\n".join(lines))  # no newline after the last line
    for block in (1, 5, 17, 64, 1 << 20):
        for start, stop in ((0, 50), (0, 1), (13, 29), (49, 50), (40, 60), (50, 51)):
            assert read_plan_range(layout, "train", start, stop, block=block) == lines[start:stop], (block, start, stop)


def test_a_job_array_task_reads_only_its_shards_recipes(tmp_path, small_config):
    from tsel_data.errors import DatasetError
    from tsel_data.job.pipeline import plan_dataset, render_shards
    from tsel_data.store.layout import Layout

    cfg = small_config("output.shard_size=2", "audio.duration=1.0", splits={"train": 6, "val": 0, "test": 0})
    out = str(tmp_path / "ds")
    plan_dataset(cfg, out)
    path = Layout(out).plan_file("train")
    lines = open(path, encoding="utf-8").read().splitlines()
    lines[5] = "{damaged".ljust(len(lines[5]))  # scene 5, in shard 2; the same size: a task checks only sizes
    open(path, "w", encoding="utf-8").write("\n".join(lines) + "\n")
    assert render_shards(out, shards=range(0, 2), progress=False) == {"train": 4, "val": 0, "test": 0}
    with pytest.raises(DatasetError, match=r"train.jsonl:6: damaged scene recipe"):
        render_shards(out, shards=range(2, 3), progress=False)
