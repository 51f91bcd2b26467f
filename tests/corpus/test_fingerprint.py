"""corpus.fingerprint: what a shard's seal records of the clips it read, and so what
`--resume` notices (docs/reliability.md): "stat" (size and mtime), "hash" (size and sha256)."""
import json
import os
import shutil

import pytest
import soundfile as sf

from tsel_data.config import load_config
from tsel_data.job.pipeline import generate, render_shards
from tsel_data.core.digest import sha256_file
from tsel_data.store.integrity import input_stats


def _dataset(tmp_path, demo_corpus, mode):
    corpus = shutil.copytree(demo_corpus, str(tmp_path / "corpus"))
    cfg = load_config(preset="demo", corpus_dir=corpus, splits={"train": 2, "val": 0, "test": 0},
                      overrides=["audio.duration=1.0", "output.shard_size=1", f'corpus.fingerprint="{mode}"'])
    out = str(tmp_path / "out")
    generate(cfg, out, workers=1, progress=False)
    with open(os.path.join(out, "plan", "train.jsonl"), encoding="utf-8") as f:
        clip = os.path.join(corpus, json.loads(f.readline())["sources"][0]["audio"])  # read by shard 0
    return out, clip


def _rewrite_keeping_size_and_mtime(path):
    st = os.stat(path)
    x, fs = sf.read(path, dtype="float32")
    sf.write(path, x[::-1].copy(), fs, subtype=sf.info(path).subtype)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert (os.path.getsize(path), os.stat(path).st_mtime_ns) == (st.st_size, st.st_mtime_ns)


@pytest.mark.parametrize("mode,again", [("stat", 0), ("hash", 1)])
def test_a_clip_rewritten_with_its_size_and_mtime_is_caught_by_hash_only(tmp_path, demo_corpus, mode, again):
    out, clip = _dataset(tmp_path, demo_corpus, mode)
    shard = os.path.join(out, "train", "shard-00000.h5")
    before = sha256_file(shard)
    _rewrite_keeping_size_and_mtime(clip)
    assert render_shards(out, progress=False) == {"train": again, "val": 0, "test": 0}
    # "stat" keeps a shard of the old clip (the documented limit); "hash" renders it from the new one
    assert (sha256_file(shard) != before) == bool(again)


@pytest.mark.parametrize("mode,again", [("stat", 1), ("hash", 0)])
def test_a_clip_only_touched_is_rendered_again_by_stat_only(tmp_path, demo_corpus, mode, again):
    out, clip = _dataset(tmp_path, demo_corpus, mode)
    os.utime(clip, ns=(os.stat(clip).st_atime_ns, os.stat(clip).st_mtime_ns + 10**9))
    assert render_shards(out, progress=False) == {"train": again, "val": 0, "test": 0}


def test_a_hash_fingerprint_reads_each_file_once_per_check(tmp_path, monkeypatch):
    from tsel_data.store import integrity

    p = tmp_path / "a.wav"
    p.write_bytes(b"x" * 100)
    reads = []
    real = integrity.sha256_file
    monkeypatch.setattr(integrity, "sha256_file", lambda path: reads.append(path) or real(path))
    hashes = {}
    first = input_stats([("a.wav", str(p))], content=True, hashes=hashes)
    assert input_stats([("a.wav", str(p))], content=True, hashes=hashes) == first
    assert first == [("a.wav", 100, real(str(p)))] and len(reads) == 1
    assert input_stats([("gone.wav", str(tmp_path / "gone.wav"))], content=True) == [("gone.wav", -1, 0)]
