"""Every export format round-trips one dataset through the real package that reads it —
webdataset, datasets, pandas/pyarrow, lhotse — with every channel and the audio bit-equal
to the reader's, in each audio coding (float32, int16, flac), and labels and queries equal;
the streaming reader gives the reader's scenes, each exactly once per epoch whatever the
workers and ranks. Tests of a package that is not installed are skipped."""
import glob
import io
import json
import os
import tempfile

import numpy as np
import pytest
import soundfile as sf

from support.datasets import make_scene
from tsel_data.core.atomic import write_json
from tsel_data.export import export
from tsel_data.store import open_dataset
from tsel_data.store.dataset import dataset_doc, shard_attrs
from tsel_data.store.writer import write_shard
from tsel_data.tools.streaming import SceneStream

# datasets caches what it loads under HF_HOME: a folder of this run, never the network
if "HF_HOME" not in os.environ:  # tests/conftest.py sets it inside the run's folder
    os.environ["HF_HOME"] = tempfile.mkdtemp(prefix="tsel-test-hf-")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

TWO_SCENES = "1.1MB"  # 4 channels, 2 s at 16 kHz: 512 kB of float32 per scene


def write_dataset(root, coding="float32", fmt="mic4", splits=None, seed=3, moving=(), additive=()):
    """A small dataset through the real shard writer, in ``coding`` (datasetfixture's scenes)."""
    splits = splits or {"train": 3, "test": 2}
    rng = np.random.default_rng(seed)
    attrs = shard_attrs(16000, 0.1, fmt, coding)
    entries = {}
    for split, n in splits.items():
        scenes = [make_scene(split, i, fmt=fmt, rng=rng, moving=f"{split}-{i:06d}" in moving,
                             additive=f"{split}-{i:06d}" in additive) for i in range(n)]
        entries[split] = [write_shard(str(root), split, k, scenes[j:j + 2], attrs) for k, j in enumerate(range(0, n, 2))]
    config = {"audio": {"fs": 16000, "duration": 2.0, "label_hop": 0.1}, "splits": {s: {"count": n} for s, n in
                                                                                      splits.items()}}
    write_json(os.path.join(root, "dataset.json"), dataset_doc(config, seed, attrs, entries))
    return str(root)


@pytest.fixture(scope="module")
def datasets_(tmp_path_factory):
    """float32 mic4 (a moving target, an additive source), int16 em32 (32 channels), flac foa."""
    base = tmp_path_factory.mktemp("formats")
    return {"float32": write_dataset(base / "f32", moving={"train-000001"}, additive={"train-000002"}),
            "int16": write_dataset(base / "i16", "int16", "em32", {"train": 2, "test": 1}),
            "flac": write_dataset(base / "flac", "flac", "foa", {"train": 2, "test": 1})}


@pytest.fixture(scope="module")
def wds_out(datasets_, tmp_path_factory):
    out = {}
    for coding, root in datasets_.items():
        out[coding] = str(tmp_path_factory.mktemp(f"wds-{coding}"))
        export("webdataset", root, out[coding], shard_size=TWO_SCENES, card=False)
    return out


def reference(root, split):
    with open_dataset(root, split) as ds:
        return {s.scene_id: s for s in ds}


def assert_same_labels(a, b):
    assert (a.scene_id, a.query, a.query_type, a.query_relation, a.pairing) == \
        (b.scene_id, b.query, b.query_type, b.query_relation, b.pairing)
    for key in ("azimuth", "elevation", "distance", "active", "mic_positions"):
        x, y = getattr(a, key), getattr(b, key)
        assert x.dtype == y.dtype and x.shape == y.shape, key
        np.testing.assert_array_equal(x, y, err_msg=key)


@pytest.mark.parametrize("coding", ["float32", "int16", "flac"])
def test_streamed_scenes_are_the_readers(datasets_, wds_out, coding):
    for split in ("train", "test"):
        ref = reference(datasets_[coding], split)
        got = list(SceneStream(wds_out[coding], split))
        assert [s.scene_id for s in got] == list(ref)
        for s in got:
            r = ref[s.scene_id]
            assert s.audio.dtype == np.float32 and s.audio.shape == r.audio.shape
            np.testing.assert_array_equal(s.audio, r.audio)  # bit for bit, every channel
            assert_same_labels(s, r)
            assert s.record.to_json() == r.record.to_json() and s.index == r.index
    if coding == "int16":
        assert got[0].audio.shape[0] == 32


def test_label_text_is_the_text_json_gives():
    """Label arrays go into the sample JSON as json.dumps writes them (NaN as null), each
    distinct value formatted once: -0.0 is not 0.0, and repeats, NaN and infinities keep
    their places."""
    from tsel_data.formats.webdataset import _labels

    rng = np.random.default_rng(0)
    cases = [np.array([[0.0, -0.0, np.nan, 1.5, 0.0], [np.inf, -np.inf, 3e-40, 1e30, -0.0]], np.float32),
             np.repeat(rng.normal(size=(3, 1)), 50, axis=1).astype(np.float32), rng.normal(size=(2, 7)),
             np.zeros((0, 5), np.float32), np.zeros((3, 0), np.float32), np.float32([1, 2, 3])]
    for a in cases:
        assert _labels(a) == json.dumps(a.tolist()).replace("NaN", "null")


def test_tar_headers_read_as_tarfile_reads_them_and_damage_is_one_line(wds_out, tmp_path):
    import random
    import tarfile

    from tsel_data.errors import DatasetError
    from tsel_data.formats.webdataset import iter_members, tar_header

    headers = []
    for fmt in (tarfile.PAX_FORMAT, tarfile.USTAR_FORMAT, tarfile.GNU_FORMAT):
        for name in ("a.npy", "x" * 99, "d/" * 60 + "f.json", "é/ü.json", "dir/"):
            for size in (0, 1, 3840128, 8 ** 11 - 1, 8 ** 12):
                info = tarfile.TarInfo(name)
                info.size, info.type = size, tarfile.DIRTYPE if name.endswith("/") else tarfile.REGTYPE
                try:
                    buf = info.tobuf(fmt, "utf-8", "surrogateescape")
                except ValueError:  # too long or too large for the format
                    continue
                pos = 0
                while pos < len(buf):  # the format's own headers first (PAX records, GNU long names)
                    headers.append(buf[pos:pos + 512])
                    t = tarfile.TarInfo.frombuf(buf[pos:pos + 512], "utf-8", "surrogateescape")
                    pos += 512 + (-(-t.size // 512) * 512 if t.type in (tarfile.XHDTYPE, tarfile.GNUTYPE_LONGNAME)
                                  else 0)
    assert len(headers) > 60
    rng = random.Random(0)
    damaged = []
    for h in headers * 10:  # one byte changed anywhere: the checksum no longer holds
        k = rng.randrange(512)
        damaged.append(h[:k] + bytes([(h[k] + rng.randrange(1, 256)) % 256]) + h[k + 1:])
    for head in headers + damaged:
        try:
            t = tarfile.TarInfo.frombuf(head, "utf-8", "surrogateescape")
        except tarfile.HeaderError:
            with pytest.raises(ValueError):
                tar_header(head)
        else:
            assert tar_header(head) == (t.name, t.size, t.type)
    shard = tmp_path / "damaged.tar"
    data = bytearray(open(glob.glob(os.path.join(wds_out["float32"], "train", "*.tar"))[0], "rb").read())
    data[100] ^= 0xFF  # the first header's mode field: its checksum no longer holds
    shard.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match=r"damaged.tar: damaged tar header at byte 0 \(bad checksum\); export"):
        list(iter_members(str(shard)))


def test_tar_headers_written_are_the_ones_tarfile_writes():
    """A member's header is the bytes tarfile's PAX writer gives (mode 644, mtime 0), for
    names that fit a ustar block and names that need a PAX record, sizes up to 8 GiB and beyond."""
    import tarfile

    from tsel_data.formats.webdataset import header_block

    for name in ("a", "train-000001.audio.npy", "x" * 100, "x" * 101, "d/" * 60 + "f.json", "é.json",
                 "s\udc80.json", ""):
        for size in (0, 1, 511, 512, 3840128, 8 ** 11 - 1, 8 ** 11, 2 ** 40):
            info = tarfile.TarInfo(name)
            info.size, info.mode, info.mtime = size, 0o644, 0
            assert header_block(name, size) == info.tobuf(tarfile.PAX_FORMAT, "utf-8", "surrogateescape"), (name, size)


def test_a_damaged_shard_under_an_export_is_one_line_and_leaves_no_tar(tmp_path, monkeypatch):
    """A shard cut short is named in one line, whether HDF5 sees it on opening or the
    audio read (on the tar writer's own thread) meets the end of the file; no tar is left."""
    from tsel_data.errors import TselError
    from tsel_data.store import extents

    root = write_dataset(tmp_path / "ds", splits={"train": 4})
    shard = sorted(glob.glob(os.path.join(root, "train", "*.h5")))[-1]
    real = extents.os.preadv
    calls = {"n": 0}

    def cut_at_the_third_scene(fd, bufs, offset):
        calls["n"] += 1
        return 0 if calls["n"] >= 3 else real(fd, bufs, offset)

    monkeypatch.setattr(extents.os, "preadv", cut_at_the_third_scene)
    with pytest.raises(TselError, match=r"^/.*/shard-00001\.h5 ends inside a scene's audio \(byte [0-9]+\); the shard is "
                                         r"damaged: `tsel check` the dataset, render the shard again$"):
        export("webdataset", root, tmp_path / "wds", card=False)
    monkeypatch.undo()
    assert not glob.glob(str(tmp_path / "wds" / "train" / "*"))
    with open(shard, "r+b") as f:
        f.truncate(os.path.getsize(shard) - 300_000)
    with pytest.raises(TselError, match=r"shard-00001\.h5: cannot open shard .*the file is damaged, regenerate it$"):
        export("webdataset", root, tmp_path / "wds2", card=False)
    assert not glob.glob(str(tmp_path / "wds2" / "train" / "*"))


def test_shards_are_sized_by_bytes_and_indexed(wds_out):
    index = json.loads(open(os.path.join(wds_out["float32"], "index.json")).read())
    shards = index["splits"]["train"]["shards"]
    assert [s["scenes"] for s in shards] == [2, 1] and all(s["bytes"] <= 1_100_000 for s in shards)
    assert [os.path.getsize(os.path.join(wds_out["float32"], s["file"])) for s in shards] == [s["bytes"] for s in shards]
    assert index["audio_coding"] == "float32" and index["members"]["audio"] == "audio.npy"


def test_the_webdataset_package_reads_every_channel(datasets_, wds_out):
    wds = pytest.importorskip("webdataset")
    ref = reference(datasets_["int16"], "train")
    urls = sorted(glob.glob(os.path.join(wds_out["int16"], "train", "*.tar")))
    samples = list(wds.WebDataset(urls, shardshuffle=False).decode())
    assert [s["__key__"] for s in samples] == list(ref)
    for s in samples:
        r = ref[s["__key__"]]
        meta = s["json"]
        audio = s["audio.npy"].astype(np.float32) * np.float32(meta["audio_scale"])  # int16 as stored
        assert s["audio.npy"].dtype == np.int16 and audio.shape == (32, 32000)
        np.testing.assert_array_equal(audio, r.audio)
        assert meta["query"] == r.query and meta["channel_names"] == open_dataset(datasets_["int16"]).channel_names
        np.testing.assert_array_equal(np.array(meta["azimuth"], dtype=np.float32), r.azimuth)
        assert s["record.json"]["scene_id"] == r.scene_id


def test_datasets_loads_the_webdataset_export_with_every_channel(datasets_, wds_out):
    hfds = pytest.importorskip("datasets")
    ref = reference(datasets_["float32"], "train")
    ds = hfds.load_dataset(wds_out["float32"], split="train")  # the card is not needed: the tars say it all
    assert len(ds) == 3
    for row in ds.with_format("numpy"):
        r = ref[row["__key__"]]
        np.testing.assert_array_equal(np.asarray(row["audio.npy"], dtype=np.float32), r.audio)
        assert row["json"]["query"] == r.query


# the hf shards hold each scene twice, its audio file and its samples: 4 channels, 2 s at
# 16 kHz are 512 kB of each in float32
HF_TWO_SCENES = "2.1MB"


@pytest.fixture(scope="module")
def hf_out(datasets_, tmp_path_factory):
    pytest.importorskip("pyarrow")
    out = {}
    for coding in ("float32", "int16", "flac"):
        out[coding] = str(tmp_path_factory.mktemp(f"hf-{coding}"))
        export("hf", datasets_[coding], out[coding], shard_size=HF_TWO_SCENES)
    return out


@pytest.fixture
def no_torchcodec(monkeypatch):
    """datasets as it is on a machine without torchcodec, which datasets 4 and later decode
    Audio with: ``datasets.config.TORCHCODEC_AVAILABLE``, which it sets at import from
    whether torchcodec is installed, is False (this venv has none; one that has it is
    made to take the same path)."""
    hfds = pytest.importorskip("datasets")
    monkeypatch.setattr(hfds.config, "TORCHCODEC_AVAILABLE", False)
    return hfds


def stored(coding):
    """(numpy dtype of the samples column, what one stored unit is as a float sample)."""
    return (np.float32, 1.0) if coding == "float32" else (np.int16, 1 / 32768)


@pytest.mark.parametrize("coding", ["float32", "int16", "flac"])
def test_ds0_of_the_hf_layout_works_with_stock_datasets_and_holds_every_channel(datasets_, hf_out, coding,
                                                                                no_torchcodec):
    hfds = no_torchcodec
    pa = pytest.importorskip("pyarrow")
    from tsel_data.export.hf import DATA_COLUMNS

    ref = reference(datasets_[coding], "train")
    ds = hfds.load_dataset(hf_out[coding], split="train")  # the card's configs: default = the audio shards
    assert set(ds[0]) == {c for c, _ in DATA_COLUMNS}  # the user's first ds[0]: an ImportError before
    # an Audio column datasets decodes still fails here as that ds[0] did (the path without torchcodec);
    # the export's is not decoded
    with pytest.raises(ImportError, match="torchcodec"):
        ds.cast_column("audio", hfds.Audio())[0]
    assert ds.features["audio"] == hfds.Audio(decode=False)
    dtype, unit = stored(coding)
    channels, frames = next(iter(ref.values())).audio.shape
    assert ds.data.schema.field("samples").type == pa.list_(pa.list_(pa.from_numpy_dtype(dtype), frames), channels)
    shards = glob.glob(os.path.join(hf_out[coding], "data", "train", "*.parquet"))
    # at most 2.1 MB of audio file and samples a shard: float32 3 scenes in 2 + 1, int16 (32 channels, 4 MB a
    # scene) one a shard, flac (a smaller file and int16 samples) both in one
    assert len(ds) == len(ref) and len(shards) == {"float32": 2, "int16": 2, "flac": 1}[coding]
    for i in range(len(ds)):
        row = ds[i]  # a user's plain ds[i]: python values, nothing decoded
        r = ref[row["scene_id"]]
        assert set(row["audio"]) == {"bytes", "path"} and row["audio"]["path"] == \
            f"{r.scene_id}.{'flac' if coding == 'flac' else 'wav'}"
        samples = np.asarray(row["samples"], dtype=dtype)
        assert samples.shape == r.audio.shape == (channels, frames)
        np.testing.assert_array_equal(np.asarray(row["samples"], dtype=np.float32) * np.float32(unit), r.audio)
        # the audio file holds the same samples, every channel: as soundfile decodes it, and as stored
        audio, fs = sf.read(io.BytesIO(row["audio"]["bytes"]), dtype="float32", always_2d=True)
        assert fs == row["fs"] == r.fs
        np.testing.assert_array_equal(audio.T, np.asarray(row["samples"], dtype=np.float32) * np.float32(unit))
        units, _ = sf.read(io.BytesIO(row["audio"]["bytes"]), dtype=np.dtype(dtype).name, always_2d=True)
        np.testing.assert_array_equal(units.T, samples)
        # and the labels are the scene's (NaN where a source has no position)
        for key in ("azimuth", "elevation", "distance", "active", "mic_positions"):
            want = getattr(r, key)
            np.testing.assert_array_equal(np.array(row[key], dtype=want.dtype), want, err_msg=key)
        assert (row["query"], row["query_type"], row["query_relation"], row["pairing"]) == \
            (r.query, r.query_type, r.query_relation, r.pairing)
    # arrays straight from datasets' numpy format, a batch of scenes at once (it widens integers to int64)
    batch = ds.with_format("numpy")[:2]
    assert batch["samples"].shape == (2, channels, frames)
    assert (batch["samples"].dtype == np.float32) if coding == "float32" else (batch["samples"].dtype.kind == "i")
    np.testing.assert_array_equal(batch["samples"][1].astype(np.float32) * np.float32(unit),
                                  ref[batch["scene_id"][1]].audio)


@pytest.mark.parametrize("coding", ["float32", "int16", "flac"])
def test_the_hf_cards_loading_snippet_runs_with_stock_datasets(datasets_, hf_out, coding, no_torchcodec,
                                                                monkeypatch, capsys):
    """The card's Python, as it is, in the export's folder: it loads the first test scene and
    finds the audio file's samples equal to the samples column."""
    card = open(os.path.join(hf_out[coding], "README.md"), encoding="utf-8").read()
    section = card.split("## Load it", 1)[1].split("\n## ", 1)[0]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(hf_out[coding])
    exec(compile(code, "README.md", "exec"), {})
    first = next(iter(reference(datasets_[coding], "test").values()))
    shown = capsys.readouterr().out
    assert shown.startswith(f"{first.scene_id} {first.query!r} {first.audio.shape} {first.azimuth.shape}"), shown
    assert f"[{first.audio.shape[0]}, {first.audio.shape[1]}]" in section  # the shape it says is the scene's


def test_an_hf_export_of_the_layout_before_the_samples_is_not_added_to(datasets_, tmp_path):
    """Its shards have no samples column and a decoded Audio feature: a split exported
    now would not load beside them."""
    pytest.importorskip("pyarrow")
    from tsel_data.errors import DatasetError
    from tsel_data.export.base import MANIFEST_FILE

    out = tmp_path / "hf"
    export("hf", datasets_["flac"], str(out), splits=["train"], card=False)
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    del manifest["identity"]["hf layout"]  # as the exports before it wrote their manifest
    (out / MANIFEST_FILE).write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match=r"another hf layout None \(now 2\)"):
        export("hf", datasets_["flac"], str(out), splits=["test"], card=False)


def test_the_metadata_tables_follow_their_schema(datasets_, hf_out):
    pd = pytest.importorskip("pandas")
    hfds = pytest.importorskip("datasets")
    from tsel_data.export.hf import SCENE_COLUMNS, SOURCE_COLUMNS

    ref = reference(datasets_["float32"], "train")
    scenes = pd.read_parquet(os.path.join(hf_out["float32"], "metadata", "train", "scenes.parquet"))
    sources = pd.read_parquet(os.path.join(hf_out["float32"], "metadata", "train", "sources.parquet"))
    assert list(scenes.columns) == [c for c, _ in SCENE_COLUMNS] and list(sources.columns) == [c for c, _ in
                                                                                              SOURCE_COLUMNS]
    assert list(scenes.scene_id) == list(ref) and len(sources) == sum(s.n_sources for s in ref.values())
    for _, row in sources.iterrows():
        r = ref[row.scene_id]
        rec = r.record.sources[row.source]
        assert (row.role, row.clip_id, list(row.captions), row.spatial) == (rec.role, rec.clip_id, rec.captions,
                                                                            rec.spatial)
        np.testing.assert_array_equal(row.azimuth.astype(np.float32), r.azimuth[row.source])
    additive = sources[sources.spatial == "additive"]
    assert len(additive) == 1 and np.isnan(additive.iloc[0].azimuth).all()
    # the tables load through the card's configs, split by split, with the same types
    for config in ("scenes", "sources"):
        a = hfds.load_dataset(hf_out["float32"], config, split="train")
        b = hfds.load_dataset(hf_out["float32"], config, split="test")
        assert a.features == b.features


def test_lhotse_loads_the_manifests_and_the_audio_is_ours(datasets_, tmp_path):
    lhotse = pytest.importorskip("lhotse")
    for coding in ("float32", "int16"):
        out = tmp_path / coding
        export("lhotse", datasets_[coding], str(out), card=False)
        ref = reference(datasets_[coding], "train")
        cuts = lhotse.CutSet.from_file(out / "tsel_cuts_train.jsonl.gz").with_recording_path_prefix(str(out))
        recs = lhotse.RecordingSet.from_file(out / "tsel_recordings_train.jsonl.gz")
        sups = lhotse.SupervisionSet.from_file(out / "tsel_supervisions_train.jsonl.gz")
        assert len(recs) == len(ref) and len(sups) == sum(s.n_sources for s in ref.values())
        for cut in cuts:
            r = ref[cut.id]
            np.testing.assert_array_equal(cut.load_audio(), r.audio)  # every channel, bit for bit
            assert cut.recording.channel_ids == list(range(r.audio.shape[0]))
            target = cut.supervisions[0]
            assert target.text == r.query and target.custom["role"] == "target"
            az = np.array([np.nan if v is None else v for v in target.custom["azimuth"]], dtype=np.float32)
            np.testing.assert_array_equal(az, r.azimuth[0])
            assert cut.custom["query"] == r.query and cut.custom["record"]["scene_id"] == r.scene_id


def test_streaming_reads_each_scene_once_per_epoch_whatever_the_slots(datasets_, wds_out):
    ids = list(reference(datasets_["float32"], "train"))
    stream = SceneStream(wds_out["float32"], "train", shuffle=8, seed=4, with_record=False)
    assert len(stream) == 3
    orders = []
    for epoch in range(3):
        stream.set_epoch(epoch)
        orders.append([s.scene_id for s in stream])
        assert sorted(orders[-1]) == ids
        # 2 ranks x 2 workers > 2 shards: every slot reads every shard and keeps every 4th scene
        seen = [s.scene_id for rank in range(2) for w in range(2) for s in stream.iter(w, 2, rank, 2)]
        assert sorted(seen) == ids
        # 2 slots = 2 shards: a shard each
        assert sorted(s.scene_id for w in range(2) for s in stream.iter(w, 2)) == ids
    assert len({tuple(o) for o in orders}) > 1  # epochs shuffle differently
    again = SceneStream(wds_out["float32"], "train", shuffle=8, seed=4, with_record=False)
    again.set_epoch(2)
    assert [s.scene_id for s in again] == orders[2]  # the same order for the same seed and epoch
    files = sorted(glob.glob(os.path.join(wds_out["float32"], "train", "*.tar")))
    assert [s.scene_id for s in SceneStream(files)] == ids  # tar files instead of the folder


def test_torch_streaming_dataset_and_default_collate(datasets_, wds_out):
    torch = pytest.importorskip("torch")
    from tsel_data.tools.torch import Dataset, StreamingDataset

    ids = list(reference(datasets_["float32"], "test"))
    # the map-style dataset's items batch with PyTorch's default collate (a caption query's relation is "")
    batch = next(iter(torch.utils.data.DataLoader(Dataset(datasets_["float32"], "test"), batch_size=2)))
    assert batch["audio"].shape == (2, 4, 32000) and batch["query_relation"] == ["", ""]
    assert batch["scene_id"] == ids
    stream = StreamingDataset(wds_out["float32"], "train", shuffle=4, seed=1)
    loader = torch.utils.data.DataLoader(stream, batch_size=1, num_workers=2)
    got = [b["scene_id"][0] for b in loader]
    assert sorted(got) == list(reference(datasets_["float32"], "train"))
    item = next(iter(StreamingDataset(wds_out["flac"], "test")))
    ref = reference(datasets_["flac"], "test")[item["scene_id"]]
    assert torch.equal(item["audio"], torch.from_numpy(ref.audio)) and item["gaussian"].shape == (20, 360)
