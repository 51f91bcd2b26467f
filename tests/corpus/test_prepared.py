"""Prepared clips (tsel corpus prepare): scenes are bit for bit the same, and made without
decoding or resampling any clip again."""
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf

from tsel_data.corpus import audio, prepared
from tsel_data.config import load_config
from tsel_data.errors import AudioError, DatasetError
from tsel_data.job.pipeline import generate
from tsel_data.core.digest import sha256_file


def _stereo_44k_corpus(src, dst):
    """The demo corpus as 44.1 kHz stereo FLAC files, as real downloads come."""
    from scipy.signal import resample_poly

    shutil.copytree(src, dst)
    for f in os.listdir(os.path.join(src, "audio")):
        if not f.endswith(".wav"):
            continue
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


ARGS = dict(preset="demo", splits={"train": 3, "val": 0, "test": 0},
            overrides=["audio.duration=2.0", "output.shard_size=3"])


def _config(corpus, *more):
    return load_config(**{**ARGS, "corpus_dir": corpus, "overrides": ARGS["overrides"] + list(more)})


def _forbid_decoding(monkeypatch):
    audio._load_clip_cached.cache_clear()

    def no_decoding(*a, **k):
        raise AssertionError("a prepared clip was decoded again")
    monkeypatch.setattr(audio, "load_clip", no_decoding)


@pytest.fixture(scope="module")
def decoded(tmp_path_factory, demo_corpus):
    """44.1 kHz stereo clips and the shards rendered from them decoded (nothing prepared)."""
    root = tmp_path_factory.mktemp("decoded")
    corpus = _stereo_44k_corpus(demo_corpus, str(root / "corpus"))
    generate(_config(corpus, "corpus.prepare_on_check=false"), str(root / "a"), workers=1, progress=False)
    return corpus, _shards(str(root / "a"))


def _tree(root):
    """Every file and folder below ``root``: its mode, size, mtime and bytes' sha256."""
    out = {}
    for folder, dirs, names in os.walk(root):
        for n in dirs + names:
            p = os.path.join(folder, n)
            st = os.lstat(p)
            out[os.path.relpath(p, root)] = (st.st_mode, st.st_size, st.st_mtime_ns,
                                             None if os.path.isdir(p) else sha256_file(p))
    return out


def test_prepared_clips_give_the_same_scenes_without_decoding(tmp_path, decoded, monkeypatch):
    src, want = decoded
    corpus = shutil.copytree(src, str(tmp_path / "corpus"))
    before = _tree(corpus)
    monkeypatch.delenv("TSEL_CLIP_CACHE", raising=False)  # the per-user cache, as by default
    monkeypatch.setenv("TSEL_CACHE_DIR", str(tmp_path / "user-cache"))
    r = subprocess.run([sys.executable, "-m", "tsel_data.cli", "corpus", "prepare", "--preset", "demo",
                        "--corpus-dir", corpus, "--split", "train=3", "--split", "val=0", "--split", "test=0",
                        "--set", "audio.duration=2.0", "--quiet", "--workers", "1"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "prepared 60 clips" in r.stdout
    kept = os.path.join(tmp_path, "user-cache", "clips")
    n, size = sum(len([f for f in fs if f.endswith(".npy")]) for _, _, fs in os.walk(kept)), 0
    assert n == 60 and _tree(corpus) == before  # the corpus is left as it was
    for folder, _, names in os.walk(kept):
        size += sum(os.path.getsize(os.path.join(folder, f)) for f in names if f.endswith(".npy"))
    assert f": 60 in {kept}, {size / 1e6:,.1f} MB" in r.stdout, r.stdout
    _forbid_decoding(monkeypatch)
    generate(_config(corpus, "corpus.prepare_on_check=false"), str(tmp_path / "b"), workers=1, progress=False)
    assert _shards(str(tmp_path / "b")) == want


def test_generate_leaves_a_read_only_corpus_as_it_was(tmp_path, decoded, monkeypatch, tsel_cli):
    """The full clip check prepares clips (44.1 kHz stereo: all of them) into the user's
    cache, never beside the audio; a corpus the user may not write works the same."""
    src, want = decoded
    corpus = shutil.copytree(src, str(tmp_path / "corpus"))
    monkeypatch.delenv("TSEL_CLIP_CACHE", raising=False)
    monkeypatch.setenv("TSEL_CACHE_DIR", str(tmp_path / "user-cache"))
    for folder, dirs, names in os.walk(corpus):
        for n in names:
            os.chmod(os.path.join(folder, n), 0o444)
    for folder, dirs, _ in sorted(os.walk(corpus), reverse=True):
        os.chmod(folder, 0o555)
    try:
        before = _tree(corpus)
        code, out, err = tsel_cli.run("generate", "--preset", "demo", "--corpus-dir", corpus, "--split", "train=3",
                                      "--split", "val=0", "--split", "test=0", "--set", "audio.duration=2.0",
                                      "--set", "output.shard_size=3", "--set", 'corpus.check="full"',
                                      "--out", str(tmp_path / "d"), "--workers", "1")
        assert code == 0, err
        assert _tree(corpus) == before
    finally:
        for folder, _, _ in os.walk(corpus):
            os.chmod(folder, 0o755)
    assert _shards(str(tmp_path / "d")) == want
    assert re.search(r"train: 60 of 60 clips present \(100\.0 %\), 60 kept prepared", out + err), out + err
    assert f"60 in {tmp_path / 'user-cache' / 'clips'}" in out + err


def test_the_full_clip_check_prepares_the_clips_and_they_render_the_same_shards(tmp_path, decoded, monkeypatch):
    src, want = decoded
    corpus = shutil.copytree(src, str(tmp_path / "corpus"))
    _forbid_decoding(monkeypatch)  # the check decodes each clip once, and scenes read what it prepared
    generate(_config(corpus, 'corpus.check="full"'), str(tmp_path / "c"), workers=1, progress=False)
    assert _shards(str(tmp_path / "c")) == want
    monkeypatch.undo()
    r = subprocess.run([sys.executable, "-m", "tsel_data.cli", "corpus", "prepare", "--preset", "demo",
                        "--corpus-dir", corpus, "--split", "train=3", "--split", "val=0", "--split", "test=0",
                        "--set", "audio.duration=2.0", "--quiet", "--workers", "1"], capture_output=True, text=True)
    assert "prepared 0 clips (60 already were)" in r.stdout, r.stderr


def _prepared_clip(tmp_path, x=None):
    p = str(tmp_path / "c.wav")
    sf.write(p, 0.1 * np.sin(np.arange(48000, dtype=np.float32) / 7), 48000, subtype="FLOAT")
    assert audio.prepare_clip(p, 24000, 1.0, 0.0)
    st = prepared.stamp_of(os.stat(p))
    if x is not None:  # a prepared clip with a valid record, holding what no clip may
        prepared.write_prepared(p, st, 24000, 1.0, 0.0, x)
    audio._load_clip_cached.cache_clear()
    return p, prepared.prepared_path(p, st, 24000, 1.0, 0.0)


def test_a_prepared_clip_replaced_by_other_audio_of_its_shape_is_refused(tmp_path):
    p, npy = _prepared_clip(tmp_path)
    np.save(npy, np.full(24000, 0.3, np.float32))  # same dtype and shape, other samples
    with pytest.raises(AudioError, match=r"c\.wav: its prepared form .*: the prepared file changed since it was "
                                         r"written.*tsel corpus prepare"):
        audio.load_clip_cached(p, 24000, 1.0, 0.0)
    problem = audio.keep_prepared(p, 24000, 1.0, 0.0, deep=True)  # what tsel check reports
    assert problem and "prepared file changed" in problem
    assert audio.prepare_clip(p, 24000, 1.0, 0.0)  # preparing again mends it
    audio._load_clip_cached.cache_clear()
    np.testing.assert_array_equal(audio.load_clip_cached(p, 24000, 1.0, 0.0), audio.load_clip(p, 24000, 1.0, 0.0))


def test_a_clip_rewritten_with_its_old_size_and_mtime_is_not_served_its_old_preparation(tmp_path):
    p, _ = _prepared_clip(tmp_path)
    st = os.stat(p)
    sf.write(p, 0.2 * np.cos(np.arange(48000, dtype=np.float32) / 5), 48000, subtype="FLOAT")
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert os.path.getsize(p) == st.st_size and os.stat(p).st_mtime_ns == st.st_mtime_ns
    with pytest.raises(AudioError, match="the clip changed since it was prepared"):
        audio.load_clip_cached(p, 24000, 1.0, 0.0)


@pytest.mark.parametrize("bad,why", [(np.nan, "contains NaN or Inf samples"), (3e36, "has samples of amplitude 3e")])
def test_a_prepared_clip_holding_what_no_clip_may_is_blamed_on_the_clip(tmp_path, bad, why):
    x = np.zeros(24000, np.float32)
    x[100] = bad
    p, npy = _prepared_clip(tmp_path, x)
    with pytest.raises(AudioError, match=rf"c\.wav: its prepared form {npy} {why}"):
        audio.load_clip_cached(p, 24000, 1.0, 0.0)
    assert why in audio.keep_prepared(p, 24000, 1.0, 0.0, deep=True)


def test_tsel_check_refuses_a_changed_prepared_clip(tmp_path, decoded, tsel_cli):
    src, _ = decoded
    corpus = shutil.copytree(src, str(tmp_path / "corpus"))
    cfg = _config(corpus)
    args = ["check", "--preset", "demo", "--corpus-dir", corpus, "--split", "train=3", "--split", "val=0",
            "--split", "test=0", "--set", "audio.duration=2.0", "--set", 'corpus.check="full"']
    from tsel_data.plan.catalog import build_catalog, prepare_corpus
    clips = build_catalog(_config(corpus, "corpus.prepare_on_check=false"), corpus).clips
    victim = clips["train"][0]
    st = prepared.stamp_of(os.stat(victim.audio))
    assert tsel_cli.run(*args)[0] == 0
    assert prepared.lookup(victim.audio, st, 24000, 2.0, victim.offset)[0] == "absent"  # a check writes nothing
    prepare_corpus(cfg, clips)
    np.save(prepared.prepared_path(victim.audio, st, 24000, 2.0, victim.offset), np.zeros(48000, np.float32))
    code, out, err = tsel_cli.run(*args)
    assert code == 2, (out, err)  # a config check's problems
    assert f"clip {victim.id}: " in out + err and "prepared file changed" in out + err


def test_a_huge_clip_is_blamed_on_the_clip_not_the_simulator(tmp_path, demo_corpus):
    corpus = shutil.copytree(demo_corpus, str(tmp_path / "corpus"))
    for f in os.listdir(os.path.join(corpus, "audio")):
        if f.endswith(".wav"):
            x, fs = sf.read(os.path.join(corpus, "audio", f), dtype="float32")
            sf.write(os.path.join(corpus, "audio", f), x * np.float32(3e36 / max(np.max(np.abs(x)), 1e-9)), fs,
                     subtype="FLOAT")
    cfg = _config(corpus, 'corpus.check="none"')
    with pytest.raises(DatasetError) as e:
        generate(cfg, str(tmp_path / "out"), workers=1, progress=False)
    msg = str(e.value)
    assert "has samples of amplitude " in msg and "e+36" in msg and "simulator" not in msg, msg
    assert " audio/" in msg and corpus not in msg, msg  # named relative to the corpus
    wav = os.path.join(corpus, "audio", sorted(f for f in os.listdir(os.path.join(corpus, "audio"))
                                              if f.endswith(".wav"))[0])
    assert "has samples of amplitude " in audio.check_clip("x", wav, "full", 1.0, 8, 0.0, 2.0, 24000).problem


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


@pytest.mark.parametrize("record", ["not json", '{"version": 1, "source": [], "prepared": 3}', None])
def test_a_prepared_clip_without_a_readable_record_is_never_used(tmp_path, record):
    p, npy = _prepared_clip(tmp_path)
    np.save(npy, np.full(24000, 0.3, np.float32))
    rec = prepared.record_path(npy)
    if record is None:
        os.remove(rec)  # a prepared file of an older toolkit, or an interrupted write
    else:
        with open(rec, "w") as f:
            f.write(record)
    np.testing.assert_array_equal(audio.load_clip_cached(p, 24000, 1.0, 0.0), audio.load_clip(p, 24000, 1.0, 0.0))
    assert audio.prepare_clip(p, 24000, 1.0, 0.0)  # made again, with its record


def test_a_remembered_clip_check_still_prepares_the_clip(tmp_path, decoded):
    from tsel_data.plan.catalog import build_catalog, check_clips

    corpus = shutil.copytree(decoded[0], str(tmp_path / "corpus"))
    cfg = _config(corpus, 'corpus.check="full"')
    clips = build_catalog(_config(corpus, "corpus.prepare_on_check=false", 'corpus.check="full"'), corpus).clips["train"]
    assert {audio.prepared_state(c.audio, 24000, 2.0, c.offset) for c in clips} == {"absent"}
    check_clips(clips, cfg)  # the verdicts are remembered from the check above; the prepared forms are made now
    assert {audio.prepared_state(c.audio, 24000, 2.0, c.offset) for c in clips} == {"ok"}


def test_planning_says_which_clips_it_keeps_prepared_and_how_not_to(demo_corpus, tmp_path, tsel_cli):
    """corpus.check = "full" writes prepared clips itself: the user is told how many and
    where (files written for them), and how to turn it off."""
    common = ["--preset", "demo", "--corpus-dir", demo_corpus, "--split", "train=4", "--split", "val=0",
              "--split", "test=0", "--set", "audio.duration=1.0", "--set", 'corpus.check="full"']
    code, out, err = tsel_cli.run("plan", *common, "--out", str(tmp_path / "a"))
    assert code == 0, err
    line = next(x for x in (out + err).splitlines() if x.startswith("train:"))  # the demo holds 16, 44.1 kHz and stereo clips
    kept = re.search(r", (\d+) kept prepared$", line)
    assert kept and int(kept[1]) >= 1, line
    where = next(x for x in (out + err).splitlines() if x.startswith("prepared clips"))
    assert f" in {os.environ['TSEL_CLIP_CACHE']}, " in where and "corpus.prepare_on_check = false" in where, where
    code, out, err = tsel_cli.run("plan", *common, "--out", str(tmp_path / "b"), "--set",
                                  "corpus.prepare_on_check=false")
    assert code == 0 and "clips present" in out + err and "kept prepared" not in out + err
