"""Prepared clips (tsel corpus prepare): scenes are bit for bit the same, and made without
decoding or resampling any clip again."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf

from tsel_data import audio
from tsel_data.config import load_config
from tsel_data.pipeline import generate
from tsel_data.store.integrity import sha256_file


def _stereo_44k_corpus(src, dst):
    """The demo corpus as 44.1 kHz stereo FLAC files, as real downloads come."""
    from scipy.signal import resample_poly

    shutil.copytree(src, dst)
    for f in os.listdir(os.path.join(src, "audio")):
        x, fs = sf.read(os.path.join(src, "audio", f), dtype="float32")
        x = x if x.ndim == 1 else x.mean(axis=1)
        if fs != 24000:
            continue  # keep the demo's few clips at other rates as they are
        y = resample_poly(x, 441, 240).astype(np.float32)
        sf.write(os.path.join(dst, "audio", f), np.stack([y, 0.8 * y], 1), 44100, subtype="PCM_24", format="WAV")
    return dst


def _shards(d):
    return {f: sha256_file(os.path.join(d, "train", f)) for f in sorted(os.listdir(os.path.join(d, "train")))
            if not f.endswith(".seal.json")}


def test_prepared_clips_give_the_same_scenes_without_decoding(tmp_path, demo_corpus, monkeypatch):
    corpus = _stereo_44k_corpus(demo_corpus, str(tmp_path / "corpus"))
    args = dict(preset="demo", corpus_dir=corpus, splits={"train": 3, "val": 0, "test": 0},
                overrides=["audio.duration=2.0", "output.shard_size=3"])
    generate(load_config(**args), str(tmp_path / "a"), workers=1, progress=False)
    r = subprocess.run([sys.executable, "-m", "tsel_data.cli", "corpus", "prepare", "--preset", "demo",
                        "--corpus-dir", corpus, "--split", "train=3", "--split", "val=0", "--split", "test=0",
                        "--set", "audio.duration=2.0", "--quiet", "--workers", "1"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "prepared 60 clips" in r.stdout
    assert os.listdir(os.path.join(corpus, "audio", ".tsel-clips"))
    audio._load_clip_cached.cache_clear()

    def no_decoding(*a, **k):
        raise AssertionError("a prepared clip was decoded again")
    monkeypatch.setattr(audio, "load_clip", no_decoding)
    generate(load_config(**args), str(tmp_path / "b"), workers=1, progress=False)
    assert _shards(str(tmp_path / "a")) == _shards(str(tmp_path / "b"))


def test_a_changed_clip_is_not_served_from_its_old_preparation(tmp_path):
    p = str(tmp_path / "c.wav")
    sf.write(p, 0.1 * np.ones(24000, np.float32), 24000)
    assert audio.prepare_clip(p, 24000, 1.0, 0.0) and not audio.prepare_clip(p, 24000, 1.0, 0.0)
    sf.write(p, 0.2 * np.ones(24000, np.float32), 24000, subtype="FLOAT")
    audio._load_clip_cached.cache_clear()
    np.testing.assert_allclose(audio.load_clip_cached(p, 24000, 1.0, 0.0), 0.2, rtol=1e-6)


def test_the_cache_folder_can_live_elsewhere(tmp_path, monkeypatch):
    p = str(tmp_path / "c.wav")
    sf.write(p, 0.1 * np.ones(24000, np.float32), 24000)
    monkeypatch.setenv("TSEL_CLIP_CACHE", str(tmp_path / "cache"))
    assert audio.prepare_clip(p, 24000, 1.0, 0.0)
    assert not os.path.exists(tmp_path / ".tsel-clips") and os.listdir(tmp_path / "cache")
    with pytest.raises(FileNotFoundError):
        audio.prepare_clip(str(tmp_path / "missing.wav"), 24000, 1.0, 0.0)
