"""What a scene hears besides its sources ([noise]): recorded ambience, diffuse noise
with the receiver's coherence, babble, sensor noise; each at its SNR by the DCASE
definition, measured from the audio; never labelled; and levels that follow distance."""
from __future__ import annotations

import numpy as np
import pytest

from support.ambience import make_tau_snoise
from support.banks import make_tau_db
from tsel_data.corpus.ambience import omni_energy
from tsel_data.errors import ConfigError

FS = 24000
SMALL = ["audio.duration=2.0", "output.shard_size=4", 'scene.scenario="two-directional"']


def _make(tmp, corpus, overrides, splits=None, preset="demo", bank=None):
    from tsel_data.config import load_config
    from tsel_data.job.pipeline import generate

    cfg = load_config(preset=preset, corpus_dir=corpus, bank=bank, overrides=SMALL + overrides,
                      splits=splits or {"train": 2, "val": 0, "test": 2})
    generate(cfg, str(tmp), workers=1, progress=False)
    return str(tmp)


def _noise_and_target(root, split, i):
    """The stored mixture's noise (mixture minus every source alone) and the target alone."""
    from tsel_data.tools.inspect import find_scene
    from tsel_data.job.stems import dataset_roots, render_stems, scene_recipe

    scene = find_scene(root, f"{split}/{i}")
    recipe = scene_recipe(root, split, i, scene.scene_id)
    stems, same, noise = render_stems(recipe, scene.audio, dataset_roots(root), with_noise=True)
    assert same
    return scene, recipe, scene.audio - stems.sum(axis=0), stems[0], noise


@pytest.fixture(scope="module")
def noisy(tmp_path_factory, demo_corpus):
    """A mic4 dataset with diffuse pink noise, babble and sensor noise at SNRs."""
    return _make(tmp_path_factory.mktemp("noisy") / "ds", demo_corpus,
                 ['noise.diffuse="pink"', "noise.babble=4", 'noise.sensor="snr"',
                  'noise.sensor_level=["uniform", 35.0, 40.0]'])


def test_every_noise_is_at_its_snr_from_the_audio(noisy):
    """Mixture minus sources = the noise; its SNR against the target by the DCASE
    definition (energy of the mean of the level channels) is the drawn one within 0.2 dB,
    each noise alone too (its record, its HDF5 column)."""
    import h5py

    from tsel_data.scene.recipe import read_plan

    recipes = read_plan(f"{noisy}/plan/test.jsonl")
    for i in range(2):
        scene, recipe, noise, target, stem = _noise_and_target(noisy, "test", i)
        np.testing.assert_allclose(noise, stem, atol=3e-6)
        drawn = {n.kind: n.snr_db for n in recipes[i].noise}
        recorded = {n.kind: n.snr_db for n in scene.record.noise}
        assert set(drawn) == {"diffuse", "babble", "sensor"} and recorded == pytest.approx(drawn, abs=0.01)
        total = 10 * np.log10(omni_energy(target, slice(None)) / omni_energy(noise, slice(None)))
        parts = 10 ** (-np.array(list(drawn.values())) / 10)  # independent noises add in power
        assert total == pytest.approx(-10 * np.log10(parts.sum()), abs=0.2)
        with h5py.File(f"{noisy}/test/shard-00000.h5") as f:
            assert f["noise/diffuse/snr_db"][i] == pytest.approx(drawn["diffuse"], abs=0.01)
    assert scene.record.sources[1].role == "interferer" and np.isfinite(scene.azimuth[:2]).all()  # no noise label


def test_noise_alone_at_its_snr(tmp_path, demo_corpus):
    """One noise at a time: its SNR from the audio is exactly the drawn value (0.2 dB)."""
    root = _make(tmp_path / "ds", demo_corpus, ['noise.diffuse="white"', 'noise.diffuse_snr=12.5'],
                 splits={"train": 0, "val": 0, "test": 1})
    _, _, noise, target, _ = _noise_and_target(root, "test", 0)
    assert 10 * np.log10(omni_energy(target, slice(None)) / omni_energy(noise, slice(None))) == pytest.approx(12.5, abs=0.2)


CUSTOM5 = ((0.05, 0.0, 0.0), (0.0, 0.05, 0.0), (-0.05, 0.0, 0.0), (0.0, -0.05, 0.0), (0.0, 0.0, 0.08))


@pytest.mark.parametrize("pose", [("mic4", dict(side=0.12)), ("tetra", dict(baffle="rigid")), ("foa", {}),
                                  ("custom", dict(capsules=CUSTOM5))], ids=["mic4", "tetra", "foa", "custom"])
def test_diffuse_noise_has_the_receivers_coherence(pose):
    """At 10, 40 and 170 ms windows, every pair above its first sinc zero: within 0.05 of theory."""
    from scipy.signal import csd, welch

    from tsel_data.acoustics.capsules import capsule_model
    from tsel_data.core.geometry import SOUND_SPEED
    from tsel_data.render.noise import noise_image
    from tsel_data.receivers import ArrayPose
    from tsel_data.scene.recipe import NoiseItem

    arr = ArrayPose(pose[0], (3.0, 3.0, 1.5), 0.0, **pose[1])
    y = noise_image(NoiseItem("diffuse", 3, 20.0, spectrum="white"), arr, FS, 6 * FS, 6.0, 0.1, -30.0)
    model, mics = capsule_model(arr, FS), arr.mics()
    for window in (0.010, 0.040, 0.170):
        n = int(window * FS)
        for a in range(len(y)):
            for b in range(a + 1, len(y)):
                f, sxy = csd(y[a], y[b], FS, nperseg=n)
                _, sxx = welch(y[a], FS, nperseg=n)
                _, syy = welch(y[b], FS, nperseg=n)
                phi = model.diffuse_csd(f)
                theory = np.abs(phi[:, a, b]) ** 2 / np.real(phi[:, a, a] * phi[:, b, b])
                d = np.linalg.norm(mics[a] - mics[b])
                band = (f > (SOUND_SPEED / (2 * d) if d > 0 else 100.0)) & (f < 10000)
                assert np.abs(np.abs(sxy) ** 2 / (sxx * syy) - theory)[band].mean() < 0.05, (window, a, b)


def test_pink_and_brown_noise_fall_by_3_and_6_db_an_octave():
    from tsel_data.render.noise import noise_image
    from tsel_data.receivers import ArrayPose
    from tsel_data.scene.recipe import NoiseItem

    arr = ArrayPose("foa", (3.0, 3.0, 1.5), 0.0)
    for spectrum, slope in (("white", 0.0), ("pink", -3.0), ("brown", -6.0)):
        w = noise_image(NoiseItem("diffuse", 1, 20.0, spectrum=spectrum), arr, FS, 4 * FS, 4.0, 0.1, -30.0)[0]
        p = np.abs(np.fft.rfft(w)) ** 2
        f = np.fft.rfftfreq(len(w), 1 / FS)
        band = lambda lo: p[(f >= lo) & (f < 2 * lo)].mean()
        assert 10 * np.log10(band(2000) / band(1000)) == pytest.approx(slope, abs=0.5)


@pytest.fixture(scope="module")
def tau(tmp_path_factory):
    """A TAU-SRIR DB (rooms bomb_shelter #1, se203 #8) and its TAU-SNoise_DB (as distributed)."""
    root = tmp_path_factory.mktemp("tau")
    make_tau_db(root / "TAU-SRIR_DB", rooms=(("bomb_shelter", 1), ("se203", 8)), n_traj=1, heights=(1.2,),
                n_doa=36, L=256, empty=())
    truth = make_tau_snoise(root / "TAU-SNoise_DB", rooms=("01_bomb_center", "08_se203_sahkotalo_classroom"),
                            seconds=5.0)
    return root, truth


def test_ambience_segments_are_the_rooms_own_recording(tau, demo_corpus, tmp_path):
    """Bank scenes hear their room's ambience (TAU-SNoise_DB matched by name), the
    segment the record names, at its SNR."""
    from tsel_data.corpus.ambience import read_segment

    root, truth = tau
    ds = _make(tmp_path / "ds", demo_corpus, [f'noise.ambience="{root / "TAU-SNoise_DB"}"', 'scene.format="foa"',
                                              'splits.train.rooms=[1]', 'splits.test.rooms=[8]', 'scene.motion="static"'],
               preset="demo-moving", bank=str(root / "TAU-SRIR_DB"))
    for split, folder in (("train", "01_bomb_center"), ("test", "08_se203_sahkotalo_classroom")):
        scene, _, noise, target, _ = _noise_and_target(ds, split, 0)
        rec = scene.record.noise[0]
        assert rec.kind == "ambience" and rec.file == f"{folder}/ambience_foa_sn3d_24k_edited.wav"
        seg = read_segment(str(root / "TAU-SNoise_DB" / rec.file), rec.offset, noise.shape[1])
        np.testing.assert_allclose(seg, truth[folder]["foa_sn3d"][:, rec.offset:rec.offset + noise.shape[1]])
        g = np.sum(noise * seg) / np.sum(seg * seg)
        assert np.abs(noise - g * seg).max() < 1e-5 * np.abs(noise).max() + 1e-7
        assert 10 * np.log10(omni_energy(target, [0]) / omni_energy(noise, [0])) == pytest.approx(rec.snr_db, abs=0.2)


@pytest.mark.parametrize("override,message", [
    ('noise.ambience_snr=["uniform", 6.0, 300.0]', r"noise.ambience_snr must be .*<= 100"),
    ('noise.diffuse="grey"', r"noise.diffuse = 'grey' is not one of"),
    ("noise.babble=500", r"noise.babble must be .*<= 64"),
])
def test_noise_settings_that_make_no_sense_are_one_line(override, message):
    from tsel_data.config import load_config

    with pytest.raises(ConfigError, match=message):
        load_config(preset="demo", overrides=[override])


def test_tsel_check_names_a_missing_room_a_wrong_channel_count_and_rate(tau, demo_corpus, tmp_path, capsys):
    """One line each, exit 2."""
    from support.ambience import write_recording
    from tsel_data.cli import main

    root, truth = tau
    one_room = tmp_path / "one"
    make_tau_snoise(one_room, rooms=("01_bomb_center",), seconds=3.0)
    two_ch = tmp_path / "two"
    write_recording(two_ch / "hall" / "hall.wav", np.zeros((2, 3 * FS), np.float32), FS)
    rate = tmp_path / "rate"
    write_recording(rate / "hall" / "hall.wav", np.zeros((4, 3 * 16000), np.float32), 16000)
    base = ["check", "--preset", "demo-moving", "--corpus-dir", demo_corpus, "--bank", str(root / "TAU-SRIR_DB"),
            "--set", "splits.train.rooms=[1]", "--set", "splits.val.rooms=[8]", "--set", "splits.test.rooms=[]",
            "--split", "test=0", "--set", "audio.duration=2.0", "--no-plan"]
    for folder, message in ((one_room, "has no folder for bank room"), (two_ch, "2 channels"),
                            (rate, "16000 Hz")):
        with pytest.raises(SystemExit) as e:
            main([*base, "--set", f'noise.ambience="{folder}"'])
        assert e.value.code == 2
        got = capsys.readouterr()
        err = [line for line in (got.out + got.err).splitlines() if line.startswith("error")]
        assert len(err) == 1 and message in err[0], err


def test_labels_still_agree_with_a_classical_localizer_at_30_db(tmp_path, demo_corpus):
    from tsel_data.tools.verify import verify_dataset

    root = _make(tmp_path / "ds", demo_corpus, ['noise.diffuse="pink"', "noise.diffuse_snr=30.0",
                                                'noise.sensor="snr"', "noise.sensor_level=40.0"],
                 splits={"train": 0, "val": 0, "test": 16})
    rep = verify_dataset(root).splits["test"]
    assert rep["tested"] >= 4 and rep["rate"] >= 0.9, rep


def test_levels_follow_distance(tmp_path, demo_corpus):
    """scene.levels = "distance": two sources of the same power, the nearer is louder by
    about its distance ratio; the target sits at target_level_dbfs; no TIR is recorded."""
    root = _make(tmp_path / "ds", demo_corpus, ['scene.levels="distance"', "sources.power=0.0",
                                                'room.rt60=["uniform", 0.3, 0.35]', 'sources.distance=["uniform", 1.0, 3.0]'],
                 splits={"train": 0, "val": 0, "test": 6})
    from tsel_data import open_dataset

    ds = open_dataset(root, "test")
    agree = 0
    for scene in ds:
        t, i = scene.record.sources[:2]
        assert t.power_db == 0.0 and t.tir_db is None and i.tir_db is None
        assert t.level_dbfs == pytest.approx(-25.0 - (0 if scene.record.levels.normalisation_db is None else
                                                     -scene.record.levels.normalisation_db), abs=0.05)
        d_t, d_i = np.nanmean(scene.distance[0]), np.nanmean(scene.distance[1])
        agree += (t.level_dbfs > i.level_dbfs) == (d_t < d_i)
    assert agree >= 5  # reverberation can reverse a close pair, not most


def test_the_noise_stem_is_written_by_inspect(noisy, tmp_path, capsys):
    from tsel_data.cli import main

    with pytest.raises(SystemExit) as e:
        main(["inspect", noisy, "test/0", "--wav", str(tmp_path / "s.wav")])
    assert e.value.code == 0 and (tmp_path / "s.noise.stereo.wav").exists()
