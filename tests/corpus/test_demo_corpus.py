"""The built-in demo corpus: determinism, AudioCaps format, audio validity, the file
format variations it promises, and physics checks that each type is what it says."""
from __future__ import annotations

import csv
import json
import re
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from scipy import signal

from tsel_data.corpus.demo import CSV_HEADER, SOUND_TYPES, TYPES_BY_NAME, synth_corpus
from tsel_data.errors import ConfigError

SPLITS = ("train", "val", "test")


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    info = synth_corpus(out, seed=0)
    clips = json.loads((out / "clips.json").read_text(encoding="utf-8"))["clips"]
    return out, info, clips


def read_rows(path):
    with open(path, encoding="utf-8", newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def load(out, clip):
    """Channel 0 of a clip as float64, and its rate."""
    x, fs = sf.read(out / clip["audio"], always_2d=True)
    return x[:, 0], fs


def clips_of(clips, kind):
    found = [c for c in clips if c["kind"] == kind]
    assert found, kind
    return found


def all_files(root: Path):
    return sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())


# ------------------------------------------------------------------ determinism, API
def test_same_seed_gives_identical_bytes(corpus, tmp_path):
    out, info, _ = corpus
    again = synth_corpus(tmp_path / "again", seed=0)
    files = all_files(out)
    assert files == all_files(tmp_path / "again")
    for rel in files:
        assert (out / rel).read_bytes() == (tmp_path / "again" / rel).read_bytes(), rel
    assert again["clips"] == info["clips"] and again["bytes"] == info["bytes"]


def test_other_seed_gives_other_clips(corpus, tmp_path):
    out, _, clips = corpus
    other = synth_corpus(tmp_path / "s1", seed=1, clips_per_type=(1, 0, 0))
    _, rows = read_rows(other["csv"]["train"])
    ids0 = {c["youtube_id"] for c in clips}
    assert not ids0 & {r[1] for r in rows}
    # the same type and slot with another seed sounds different
    a = sf.read(out / clips[0]["audio"])[0]
    b_id = [r[1] for r in rows if r[3] in TYPES_BY_NAME[clips[0]["kind"]].captions][0]
    b = sf.read(Path(other["audio_dir"]) / f"{b_id}.wav")[0]
    assert a.shape != b.shape or not np.array_equal(a, b)


def test_return_value(corpus):
    out, info, clips = corpus
    assert Path(info["audio_dir"]).is_dir()
    assert all(Path(p).is_file() for p in info["csv"].values())
    assert Path(info["readme"]).read_text(encoding="utf-8").startswith("tsel-data demo")
    n = len(SOUND_TYPES)
    assert info["clips"] == {"train": 4 * n, "val": n, "test": n}
    assert info["rows"] == {"train": 4 * n, "val": 5 * n, "test": 5 * n}
    assert info["types"] == [t.name for t in SOUND_TYPES]
    assert info["bytes"] == sum(p.stat().st_size for p in out.rglob("*") if p.is_file())


@pytest.mark.parametrize("bad", [(4, 1), (4, -1, 1), (0, 0, 0), "abc", (1.5, 1, 1), None])
def test_bad_clips_per_type_is_a_config_error(tmp_path, bad):
    with pytest.raises(ConfigError, match="clips_per_type"):
        synth_corpus(tmp_path, clips_per_type=bad)
    assert not (tmp_path / "train.csv").exists()


@pytest.mark.parametrize("bad", [-1, 1.5, "0", True])
def test_bad_seed_is_a_config_error(tmp_path, bad):
    with pytest.raises(ConfigError, match="seed"):
        synth_corpus(tmp_path, seed=bad)


# --------------------------------------------------------------------- types, captions
def test_at_least_twelve_types_with_five_wordings_each():
    assert len(SOUND_TYPES) >= 12
    assert len({t.name for t in SOUND_TYPES}) == len(SOUND_TYPES)
    every = [c for t in SOUND_TYPES for c in t.captions]
    assert len(every) == len(set(every)), "a caption is shared by two types"
    for t in SOUND_TYPES:
        assert len(set(t.captions)) >= 5, t.name
        assert t.temporal in ("continuous", "intermittent")


def test_every_type_in_every_split(corpus):
    _, _, clips = corpus
    for split in SPLITS:
        kinds = Counter(c["kind"] for c in clips if c["split"] == split)
        assert set(kinds) == set(TYPES_BY_NAME), split


# ------------------------------------------------------------------------- CSV format
def test_csv_format(corpus):
    out, _, clips = corpus
    by_id = {c["youtube_id"]: c for c in clips}
    seen_aids, seen_yids = set(), {}
    for split in SPLITS:
        header, rows = read_rows(out / f"{split}.csv")
        assert tuple(header) == CSV_HEADER
        assert (out / f"{split}.csv").read_bytes().count(b"\r") == 0
        caps = defaultdict(list)
        for aid, yid, start, cap in rows:
            assert re.fullmatch(r"[0-9]+", aid), aid
            assert aid not in seen_aids
            seen_aids.add(aid)
            assert re.fullmatch(r"[A-Za-z0-9_-]{11}", yid), yid
            assert re.fullmatch(r"[0-9]+", start), start
            assert cap and cap == cap.strip()
            caps[(yid, start)].append(cap)
        per_clip = 1 if split == "train" else 5
        for (yid, start), cl in caps.items():
            assert len(cl) == per_clip and len(set(cl)) == per_clip, (split, yid)
            assert (out / "audio" / f"{yid}.wav").is_file()
            assert seen_yids.setdefault(yid, split) == split, "clip in two splits"
            # the captions describe the clip's sound type
            assert set(cl) <= set(TYPES_BY_NAME[by_id[yid]["kind"]].captions)
        if split != "train":  # rows of a clip are scattered, as in the real files
            order = [r[1] for r in rows]
            assert any(a != b for a, b in zip(order, order[1:4]))
    wavs = {p.stem for p in (out / "audio").glob("*.wav")}
    assert wavs == set(seen_yids) == set(by_id)
    assert not list(out.rglob("*.part"))


def test_quoting_and_unicode_round_trip(corpus):
    out, _, _ = corpus
    caps = [r[3] for s in SPLITS for r in read_rows(out / f"{s}.csv")[1]]
    assert any("," in c for c in caps)
    text = "".join((out / f"{s}.csv").read_text(encoding="utf-8") for s in SPLITS)
    assert '"' in text  # captions with commas are quoted
    # a non-ASCII caption survives writing and reading
    cafe = [c for c in TYPES_BY_NAME["babble"].captions if not c.isascii()]
    assert cafe
    assert all(c.isascii() or c in cafe for c in caps)


def test_manifest_reader_groups_the_demo_corpus(corpus):
    ac = pytest.importorskip("tsel_data.corpus.manifests.audiocaps")
    out, info, _ = corpus
    for split in SPLITS:
        clips = ac.read_audiocaps(out / f"{split}.csv", audio_dir=out / "audio")
        assert len(clips) == info["clips"][split]
        assert {len(c.captions) for c in clips} == {1 if split == "train" else 5}
        assert all(Path(c.audio).is_file() for c in clips)


# ----------------------------------------------------------------------------- audio
def test_audio_valid_and_as_described(corpus):
    out, _, clips = corpus
    for c in clips:
        info = sf.info(out / c["audio"])
        fmt = c["format"]
        assert info.samplerate == fmt["fs"]
        assert info.channels == fmt["channels"]
        assert info.frames == round(fmt["duration"] * fmt["fs"])
        assert info.subtype == fmt["subtype"]
        x, _ = sf.read(out / c["audio"], always_2d=True)
        assert np.all(np.isfinite(x))
        peak = np.abs(x).max()
        assert 0.25 <= peak <= 0.9 + 1e-4, (c["audio"], peak)
        # clearly active: the loudest 100 ms frame is far above the -60 dB floor
        h = int(0.1 * fmt["fs"])
        frames = x[: x.shape[0] // h * h, 0].reshape(-1, h)
        rms = np.sqrt((frames ** 2).mean(axis=1))
        assert 20 * np.log10(rms.max() / peak) > -30
        assert np.mean(rms > rms.max() * 0.1) > 0.08  # at least ~1 s worth of events


def test_file_formats_vary_as_intended(corpus):
    _, _, clips = corpus
    fmts = [c["format"] for c in clips]
    n = len(fmts)
    fs = Counter(f["fs"] for f in fmts)
    assert set(fs) == {16000, 24000, 44100} and fs[24000] > n / 2
    ch = Counter(f["channels"] for f in fmts)
    assert set(ch) == {1, 2} and ch[1] > n / 2
    dur = [f["duration"] for f in fmts]
    assert sum(d == 10.0 for d in dur) > n / 2
    assert any(d == 12.0 for d in dur)
    short = [d for d in dur if d < 10]
    assert short and all(4.0 <= d <= 9.0 for d in short)
    sub = Counter(f["subtype"] for f in fmts)
    assert set(sub) == {"PCM_16", "FLOAT"} and sub["PCM_16"] > n / 2
    # the variants reach every split
    for split in SPLITS:
        s = [c["format"] for c in clips if c["split"] == split]
        assert len({(f["fs"], f["channels"], f["duration"]) for f in s}) > 1


def test_stereo_channels_are_related_not_identical(corpus):
    out, _, clips = corpus
    c = [c for c in clips if c["format"]["channels"] == 2][0]
    x, _ = sf.read(out / c["audio"])
    assert not np.array_equal(x[:, 0], x[:, 1])
    r = signal.correlate(x[:, 1], x[:, 0], mode="full", method="fft")
    lag = int(np.argmax(r)) - (len(x) - 1)
    assert 1 <= lag <= 20  # channel 1 is channel 0 delayed


# --------------------------------------------------------------------------- physics
def test_siren_sweeps_between_500_and_1500_hz(corpus):
    out, _, clips = corpus
    for c in clips_of(clips, "siren"):
        x, fs = load(out, c)
        f, _, s = signal.stft(x, fs, nperseg=int(0.04 * fs))
        dom = f[np.argmax(np.abs(s[:, 1:-1]), axis=0)]
        lo, hi = np.percentile(dom, [2, 98])
        assert 500 <= lo and hi <= 1500, (lo, hi)
        assert hi - lo > 500, "the pitch does not sweep"


def test_clock_ticks_are_periodic_at_1_or_2_hz(corpus):
    out, _, clips = corpus
    for c in clips_of(clips, "clock"):
        x, fs = load(out, c)
        h = int(0.001 * fs)
        env = np.abs(x[: len(x) // h * h]).reshape(-1, h).max(axis=1)  # 1 ms frames
        peaks, _ = signal.find_peaks(env, height=0.3 * env.max(), distance=200)
        d = np.diff(peaks) / 1000.0
        period = np.median(d)
        assert min(abs(period - 1.0), abs(period - 0.5)) < 0.01, period
        assert np.all(np.abs(d - period) < 0.005), d
        assert len(peaks) >= c["format"]["duration"] / period - 2


def test_rain_is_broadband_and_flat(corpus):
    out, _, clips = corpus
    for c in clips_of(clips, "rain"):
        x, fs = load(out, c)
        f, p = signal.welch(x, fs, nperseg=1024)
        band = (f >= 300) & (f <= min(7000, 0.45 * fs))
        flatness = np.exp(np.mean(np.log(p[band]))) / np.mean(p[band])
        assert flatness > 0.6, flatness
        octaves = [p[(f >= a) & (f < 2 * a)].mean() for a in (400, 800, 1600, 3200)]
        assert np.ptp(10 * np.log10(octaves)) < 6
    # a tonal type fails the same test
    x, fs = load(out, clips_of(clips, "siren")[0])
    f, p = signal.welch(x, fs, nperseg=1024)
    band = (f >= 300) & (f <= 7000)
    assert np.exp(np.mean(np.log(p[band]))) / np.mean(p[band]) < 0.2


def band_fraction(x, fs, lo, hi):
    f, p = signal.welch(x, fs, nperseg=4096)
    return p[(f >= lo) & (f < hi)].sum() / p.sum()


def test_energy_sits_where_the_type_says(corpus):
    out, _, clips = corpus
    for kind, lo, hi, share in [("engine", 0, 500, 0.9), ("knock", 0, 1000, 0.9),
                                ("wind", 0, 700, 0.85), ("birds", 2000, 8000, 0.9),
                                ("telephone", 1400, 8000, 0.9), ("rain", 1000, np.inf, 0.8)]:
        for c in clips_of(clips, kind):
            x, fs = load(out, c)
            assert band_fraction(x, fs, lo, hi) > share, (kind, c["audio"])


def test_intermittent_types_have_gaps_and_continuous_ones_do_not(corpus):
    out, _, clips = corpus
    for c in clips:
        x, fs = load(out, c)
        h = int(0.1 * fs)  # the default label hop
        e = 10 * np.log10((x[: len(x) // h * h].reshape(-1, h) ** 2).mean(axis=1))
        quiet = np.mean(e < e.max() - 20)
        if c["temporal"] == "continuous":
            assert quiet <= 0.05, (c["kind"], quiet)
        else:
            assert quiet >= 0.1, (c["kind"], quiet)


def spectro_temporal_features(x, fs):
    """Long-term spectrum in 24 log bands 60-7600 Hz (dB re the loudest band, floored at
    -30 dB) and envelope modulation energy in 5 bands 0.25-50 Hz (dB), scaled by 1/10."""
    edges = np.geomspace(60, 7600, 25)
    f, p = signal.welch(x, fs, nperseg=int(0.08 * fs))
    b = 10 * np.log10([p[(f >= a) & (f < z)].mean() + 1e-20
                       for a, z in zip(edges[:-1], edges[1:])])
    b = np.maximum(b, b.max() - 30) - b.max()
    h = int(0.01 * fs)
    env = np.sqrt((x[: len(x) // h * h].reshape(-1, h) ** 2).mean(axis=1))
    mf, m = signal.welch(env / env.mean() - 1, 100, nperseg=256)
    mod = 10 * np.log10([m[(mf >= a) & (mf < z)].sum() + 1e-6
                         for a, z in [(0.25, 1), (1, 3), (3, 8), (8, 20), (20, 50)]])
    return np.concatenate([b, mod]) / 10


def test_types_are_acoustically_distinct(corpus):
    """Leave-one-out nearest-centroid classification on crude spectro-temporal
    features: if the types were not clearly different, this would be near chance
    (1/15), not near 1."""
    out, _, clips = corpus
    feats = np.array([spectro_temporal_features(*load(out, c)) for c in clips])
    kinds = np.array([c["kind"] for c in clips])
    names = sorted(set(kinds))
    hits = 0
    for i in range(len(clips)):
        keep = np.arange(len(clips)) != i
        cents = np.array([feats[keep & (kinds == k)].mean(axis=0) for k in names])
        hits += names[int(np.argmin(np.linalg.norm(cents - feats[i], axis=1)))] == kinds[i]
    assert hits / len(clips) >= 0.9, hits / len(clips)
