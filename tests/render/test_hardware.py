"""Microphones as built ([hardware]): what was drawn is recovered from the audio (each
capsule's delay by GCC-PHAT, its gain, its high-pass corner, its self-noise in a silent
scene, a second device's clock drift over a 10 s scene), every receiver gets its own
draw, it is in the record and the shard, the stems still add up to the mixture, FOA is
refused in one line, and datasets without it keep their recipes."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tsel_data.config import load_config
from tsel_data.dsp.hardware import a_weighted_dbfs
from tsel_data.errors import ConfigError
from tsel_data.job.onthefly import SceneSource
from tsel_data.render.mix import render_scene

FS = 24000


def _source(corpus, tmp_path, *overrides, fmt="mic4", duration=3.0, n=2):
    cfg = load_config(preset="demo", corpus_dir=corpus, splits={"train": n},
                      overrides=[f"audio.duration={duration}", 'scene.scenario="two-directional"',
                                 f'scene.format="{fmt}"', *overrides])
    return SceneSource(cfg, "train", home=str(tmp_path))


def _pair(source, i):
    """Scene i as rendered with its hardware and without (the same recipe, ideal capsules):
    (recipe, [audio as built [C, T] of each receiver], [ideal audio of each receiver])."""
    recipe = source.recipe(i)
    roots = source.view.roots
    built, ideal = render_scene(recipe, roots), render_scene(replace(recipe, hardware=()), roots)

    def every(scene):
        return [scene.audio.astype(np.float64)] + [scene.receivers[p.format][0].astype(np.float64)
                                                   for p in recipe.receivers]

    return recipe, every(built), every(ideal)


def gcc_phat_lag(x, y, fs, up: int = 32) -> float:
    """How far y lags x (s): the GCC-PHAT peak, found on the sample grid, then on a grid of
    1/up sample around it (the cross-spectrum's inverse transform evaluated there) and a parabola."""
    n = 2 * len(x)
    cross = np.fft.rfft(y, n) * np.conj(np.fft.rfft(x, n))
    cross /= np.maximum(np.abs(cross), 1e-20)
    coarse = np.fft.irfft(cross, n)
    k0 = int(np.argmax(np.r_[coarse[-64:], coarse[:65]])) - 64  # lags within ±64 samples
    lags = k0 + np.arange(-up, up + 1) / up
    w = np.full(len(cross), 2.0)
    w[0] = w[-1] = 1.0
    g = np.real(np.exp(2j * np.pi * np.outer(lags, np.arange(len(cross))) / n) @ (w * cross))
    k = int(np.clip(np.argmax(g), 1, len(g) - 2))
    y0, y1, y2 = g[k - 1:k + 2]
    return (lags[k] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) / up) / fs


def test_capsule_delays_and_gains_are_heard_as_drawn(demo_corpus, tmp_path):
    """Each capsule's delay mismatch by GCC-PHAT against the same scene with ideal
    capsules, and so every inter-capsule delay, within 2 µs of the drawn; its gain within
    0.2 dB (two receivers in one scene, each with its own draw)."""
    source = _source(demo_corpus, tmp_path, 'hardware.delay_us=["uniform", -20.0, 20.0]',
                     'hardware.gain_db=["uniform", -3.0, 3.0]', 'scene.receivers=["respeaker-4"]')
    for i in range(2):
        recipe = source.recipe(i)
        assert recipe.hardware[0].gain_db != recipe.hardware[1].gain_db  # each receiver its own capsules
        _, builts, ideals = _pair(source, i)
        for hw, built, ideal in zip(recipe.hardware, builts, ideals):
            lags = np.array([gcc_phat_lag(ideal[c], built[c], FS) for c in range(len(built))]) * 1e6
            drawn = np.array(hw.delay_us)
            inter = (lags[:, None] - lags[None, :]) - (drawn[:, None] - drawn[None, :])
            assert np.abs(lags - drawn).max() < 2.0 and np.abs(inter).max() < 2.0, (lags, drawn)
            gains = 10 * np.log10(np.sum(built ** 2, axis=1) / np.sum(ideal ** 2, axis=1))
            assert np.abs(gains - np.array(hw.gain_db)).max() < 0.2, (gains, hw.gain_db)
            assert np.ptp(hw.gain_db) > 0.5  # a draw that the check can tell from none


def test_the_high_pass_corner_is_read_from_the_response(demo_corpus, tmp_path):
    """|built / ideal| per capsule, from cross-spectra of the two renders, falls 3 dB at the
    drawn corner (within 5 %), and 12 dB per octave below it (second order)."""
    from scipy.signal import csd, welch

    source = _source(demo_corpus, tmp_path, 'hardware.highpass_hz=["uniform", 100.0, 300.0]', n=1)
    recipe, (built,), (ideal,) = _pair(source, 0)
    for c, corner in enumerate(recipe.hardware[0].highpass_hz):
        f, pxy = csd(ideal[c], built[c], fs=FS, nperseg=8192)
        _, pxx = welch(ideal[c], fs=FS, nperseg=8192)
        mag = 20 * np.log10(np.abs(pxy) / pxx)
        ok = (f > 20) & (f < 2000)
        found = np.interp(-3.0, mag[ok], f[ok])  # rising through -3 dB
        assert abs(found - corner) < 0.05 * corner, (found, corner)
        slope = np.interp(corner / 4, f, mag) - np.interp(corner / 8, f, mag)
        assert 10.0 < slope < 13.0, slope


def test_self_noise_in_a_silent_scene_is_at_its_setting(demo_corpus, tmp_path):
    """With the sources 20-30 dB below it (at the lowest target level the config
    allows), each channel's A-weighted level is the capsule's self-noise (dB SPL(A) at
    the stated sensitivity) within 0.5 dB."""
    source = _source(demo_corpus, tmp_path, 'hardware.self_noise_dba=["uniform", 65.0, 75.0]',
                     "hardware.sensitivity_dbfs=-30.0", "audio.target_level_dbfs=-80.0", n=1)
    scene = source[0]
    hw = scene.record.array.hardware
    got = a_weighted_dbfs(scene.audio, FS)
    want = np.array(hw.self_noise_dba) - 94.0 - 30.0
    np.testing.assert_allclose(hw.self_noise_dbfs, want, atol=1e-3)
    assert np.abs(got - want).max() < 0.5, (got, want)


def test_a_second_devices_clock_drifts_as_drawn_over_ten_seconds(demo_corpus, tmp_path):
    """Two stereo pairs on two devices: the second pair's lag behind the ideal rendering,
    read by GCC-PHAT in half-second windows over a 10 s scene and fitted with a line, grows
    by the drawn drift (within 1 ppm) from the drawn offset (within 2 µs); the first pair
    does not move."""
    caps = "[[0.0, 0.1, 0.0], [0.0, 0.05, 0.0], [0.0, -0.05, 0.0], [0.0, -0.1, 0.0]]"
    source = _source(demo_corpus, tmp_path, f"array.capsules={caps}", "hardware.devices=[0, 0, 1, 1]",
                     'hardware.clock_offset_us=["uniform", -100.0, 100.0]',
                     'hardware.clock_ppm=["uniform", -50.0, 50.0]', fmt="custom", duration=10.0, n=1)
    recipe, (built,), (ideal,) = _pair(source, 0)
    hw = recipe.hardware[0]
    offset, ppm = hw.clock_offset_us[1], hw.clock_ppm[1]
    assert abs(ppm) > 5  # a drift the check can see
    win = FS // 2
    for c in range(4):
        starts = np.arange(0, built.shape[1] - win + 1, win)
        energy = np.array([np.sum(ideal[c, s:s + win] ** 2) for s in starts])
        keep = starts[energy > 0.01 * energy.max()]  # windows that hold sound
        lags = np.array([gcc_phat_lag(ideal[c, s:s + win], built[c, s:s + win], FS) for s in keep]) * 1e6
        drift, start = np.polyfit((keep + win / 2) / FS, lags, 1)  # µs per s (= ppm), µs
        assert len(keep) > 10
        if c < 2:
            assert np.abs(lags).max() < 0.5
        else:
            assert abs(drift - ppm) < 1.0 and abs(start - offset) < 2.0, (drift, ppm, start, offset)


def test_record_and_shard_hold_what_was_drawn_and_stems_add_up(demo_corpus, tmp_path):
    """A dataset with the typical MEMS board on a tetra and a mic4: each receiver's draw is
    in its ArrayRecord and in the shard's hardware group, as the recipe has it; the stems,
    through the hardware, add up to the stored mixture."""
    import h5py

    from tsel_data.job.pipeline import generate
    from tsel_data.job.stems import dataset_roots, render_stems, scene_recipe
    from tsel_data.scene.recipe import read_plan
    from tsel_data.store.reader import open_dataset

    cfg = load_config(preset="demo", corpus_dir=demo_corpus, splits={"train": 2, "val": 0, "test": 0},
                      overrides=["audio.duration=2.0", 'scene.format="tetra"', 'scene.receivers=["mic4"]',
                                 'hardware.profile="mems"'])
    out = str(tmp_path / "ds")
    generate(cfg, out, workers=1, progress=False)
    recipes = read_plan(f"{out}/plan/train.jsonl")
    with open_dataset(out, "train") as ds, h5py.File(f"{out}/train/shard-00000.h5") as f:
        for i in range(2):
            scene, recipe = ds[i], recipes[i]
            for k, (rec, hw) in enumerate(zip((scene.record.array, *scene.record.receivers), recipe.hardware)):
                assert rec.hardware.gain_db == list(hw.gain_db) and rec.hardware.profile == "mems"
                assert rec.hardware.self_noise_dbfs == list(hw.self_noise_dbfs())
                group = "hardware" if k == 0 else f"receivers/{rec.format}/hardware"
                for key in ("gain_db", "delay_us", "highpass_hz", "tilt_db", "self_noise_dba"):
                    np.testing.assert_allclose(f[f"{group}/{key}"][i], getattr(hw, key), atol=1e-4)
                assert f[f"{group}/sensitivity_dbfs"][i] == -26.0 and f[f"{group}/highpass_order"][i] == 2
            stems, same, noise = render_stems(scene_recipe(out, "train", i, scene.scene_id), scene.audio,
                                              dataset_roots(out), with_noise=True)
            assert same
            np.testing.assert_allclose(stems.sum(axis=0) + noise, scene.audio, atol=2e-5)
    # tsel inspect says it in words, for the receiver it shows
    from tsel_data.tools.inspect import inspect_scene

    for fmt, k in (("tetra", 0), ("mic4", 1)):
        _, text = inspect_scene(out, "train/0", receiver=fmt)
        hw = recipes[0].hardware[k]
        assert "microphones as built (a typical MEMS board" in text
        assert " ".join(f"{g:+.2f}" for g in hw.gain_db) in text and "dBFS(A) at -26 dBFS for 94 dB SPL" in text


def test_inspect_words_a_second_devices_clock():
    from tsel_data.store.records import HardwareRecord
    from tsel_data.tools.inspect import hardware_lines

    hw = HardwareRecord("none", [0.0] * 4, [0.0] * 4, [0.0] * 4, 2, [0.0] * 4, devices=[0, 0, 1, 1],
                        clock_offset_us=[0.0, 12.5], clock_ppm=[0.0, -8.0])
    text = "\n".join(hardware_lines(hw, 10.0))
    assert "device 1 (channels 2, 3) lags device 0 by +12.5 us at the start, drifting -8.00 ppm (-67.5 us" in text


def test_datasets_without_hardware_keep_their_recipes(demo_corpus, tmp_path):
    """No [hardware] (or profile "none") writes no hardware key: the recipe is the one made
    before the layer existed; turned on, it adds the key and changes nothing else."""
    plain = _source(demo_corpus, tmp_path, n=2)
    none = _source(demo_corpus, tmp_path, 'hardware.profile="none"', n=2)
    mems = _source(demo_corpus, tmp_path, 'hardware.profile="mems"', n=2)
    for i in range(2):
        d = plain.recipe(i).to_dict()
        assert "hardware" not in d and none.recipe(i).to_json() == plain.recipe(i).to_json()
        m = mems.recipe(i).to_dict()
        assert m.pop("hardware") and m == d
    assert "hardware" not in plain.cfg.to_dict() and "hardware" not in none.cfg.to_dict()


@pytest.mark.parametrize("fmt", ["foa", "stereo"])
def test_foa_is_a_format_not_a_microphone(fmt, tsel_cli, tmp_path):
    """[hardware] on FOA (or the stereo pair mixed from it) is refused in one line."""
    with pytest.raises(ConfigError, match=f"cannot go on {fmt}.*format, not a microphone"):
        load_config(preset="demo", overrides=[f'scene.format="{fmt}"', 'hardware.profile="mems"'])
    code, out, err = tsel_cli.run("check", "--preset", "demo", "--set", f'scene.format="{fmt}"', "--set",
                                  'hardware.gain_db=["uniform", -1.0, 1.0]')
    assert code == 2 and "format, not a microphone" in err and "Traceback" not in err


def test_hardware_config_mistakes_are_one_line(tmp_path):
    bad = tmp_path / "response.csv"
    bad.write_text("frequency_hz,gain_db\n100,-3\nnot,numbers\n")
    for over, message in ((["hardware.devices=[0, 0, 1]"], "names 3 capsules but mic4 has 4"),
                          (["hardware.devices=[1, 1, 2, 2]"], "whole number from 0"),
                          ([f'hardware.response="{bad}"'], r"response.csv:3: 'not,numbers' is not numbers"),
                          (["hardware.highpass_hz=5000.0"], "hardware.highpass_hz must be"),
                          (["hardware.profile=[]"], "hardware.profile must be a str")):
        with pytest.raises(ConfigError, match=message) as e:
            load_config(preset="demo", overrides=over)
        assert "\n" not in str(e.value)
    with pytest.raises(ConfigError, match="recorded scenes were made with real microphones"):
        load_config(preset="demo-recorded", overrides=['hardware.profile="mems"'])


def test_a_measured_response_shapes_every_capsule(demo_corpus, tmp_path):
    """hardware.response: a CSV read when planning (the recipe holds it): the level ratio
    of the built and ideal renderings per third octave follows the file (within 0.3 dB)."""
    from scipy.signal import welch

    resp = tmp_path / "capsule.csv"
    resp.write_text("frequency_hz,gain_db\n100,0\n1000,0\n2000,-6\n4000,-6\n8000,3\n")
    source = _source(demo_corpus, tmp_path, f'hardware.response="{resp}"', n=1)
    recipe, (built,), (ideal,) = _pair(source, 0)
    assert recipe.hardware[0].response[2] == (2000.0, -6.0) and recipe.hardware[0].response_file == "capsule.csv"
    f, pb = welch(built[0], fs=FS, nperseg=4096)
    _, pi = welch(ideal[0], fs=FS, nperseg=4096)
    for freq, want in ((500, 0.0), (3000, -6.0), (8000, 3.0)):
        assert abs(10 * np.log10(np.interp(freq, f, pb) / np.interp(freq, f, pi)) - want) < 0.3


def test_a_profile_and_a_key_set_to_the_default_read_back_the_same():
    """What a dataset stores of [hardware] parses back to the same config (resume, rebuild):
    a key set to its default under a profile stays set, not the profile's."""
    from tsel_data.config import parse_config

    cfg = load_config(preset="demo", overrides=['hardware.profile="mems"', "hardware.gain_db=0.0",
                                                "hardware.sensitivity_dbfs=-26.0"])
    stored = cfg.to_dict()["hardware"]
    assert stored["gain_db"] == 0.0 and stored["delay_us"] == ["uniform", -5.0, 5.0]
    assert parse_config(cfg.to_dict(), stored=True).hardware == cfg.hardware


def test_a_presets_file_takes_a_profile(tmp_path):
    """`tsel presets NAME` writes the keys a profile fills commented out: the file reads back
    to the preset, and with `profile = "mems"` set in it, to the profile's values."""
    from tsel_data.config import to_toml
    from tsel_data.config.load import preset_text

    cfg = load_config(preset="demo")
    text = to_toml(cfg, comments=True, header=preset_text("demo").splitlines()[0])
    assert "\n# gain_db = 0.0\n" in text and '\nprofile = "none"\n' in text
    path = tmp_path / "my.toml"
    path.write_text(text)
    assert load_config(path=str(path)) == cfg
    path.write_text(text.replace('\nprofile = "none"\n', '\nprofile = "mems"\n'))
    assert load_config(path=str(path)).hardware == load_config(preset="demo",
                                                               overrides=['hardware.profile="mems"']).hardware
