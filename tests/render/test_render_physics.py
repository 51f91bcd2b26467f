"""Labels against the audio: an anechoic room, a known direction, the lags between mics."""
import numpy as np
import pytest

from support.signals import lag

from tsel_data.acoustics import SOUND_SPEED
from tsel_data.acoustics.pyroom import pyroom_rirs
from tsel_data.core.geometry import Room, sph_to_cart
from tsel_data.receivers import ArrayPose, mic_positions
from tsel_data.scene.recipe import SceneRecipe, Source
from tsel_data.render.mix import convolve, source_labels

FS = 24000


def _recipe(az_room_deg, yaw, side=0.4):
    centre = (5.0, 5.0, 1.5)
    a = np.radians(az_room_deg)
    pos = (centre[0] + 2.5 * np.cos(a), centre[1] + 2.5 * np.sin(a), 2.0)
    src = Source("target", "c", "x.wav", ("noise",), position=tuple(pos))
    other = Source("interferer", "d", "y.wav", ("other",), spatial="additive", tir_db=0.0)
    return SceneRecipe("s-0", "test", 0, 1, "directional+additive", "noise", ArrayPose("mic4", centre, yaw, side),
                       (src, other), Room((10.0, 10.0, 4.0), 0.3), fs=FS, duration=1.0)


@pytest.mark.parametrize("az_room,yaw", [(0.0, 0.0), (90.0, 30.0), (200.0, -75.0), (-30.0, 160.0)])
def test_anechoic_mic_lags_match_labelled_direction(az_room, yaw):
    r = _recipe(az_room, yaw)
    rirs = pyroom_rirs(r.room, r.array, np.array([r.target.position]), FS, max_order=0).rirs
    noise = np.random.default_rng(0).standard_normal((1, FS)).astype(np.float32)
    y = convolve(noise, rirs, FS)[0]
    az, el, dist = (v[0] for v in source_labels(r, 0))
    # the labelled direction, as a plane wave on the labelled mic positions: expected delays
    u = sph_to_cart(az, el, 1.0)
    mics = mic_positions("mic4", r.array.side)
    tau = -(mics @ u) / SOUND_SPEED * FS  # arrival-time offset of each mic vs the centre
    for i in range(4):
        for j in range(i + 1, 4):
            got = lag(y[i], y[j], 40)
            assert got == pytest.approx(tau[j] - tau[i], abs=1.0), (i, j)
    assert az == pytest.approx(((az_room - yaw + 180) % 360) - 180, abs=0.01)


def test_direct_path_delay_and_gain():
    r = _recipe(45.0, 0.0, side=0.1)
    from tsel_data.core.geometry import array_to_room

    near, far = (6.0, 5.0, 1.5), (9.0, 5.0, 1.5)  # 1 m and 4 m in front of the array
    rirs = pyroom_rirs(r.room, r.array, np.array([near, far]), FS, max_order=0).rirs
    mics_room = array_to_room(mic_positions("mic4", 0.1), r.array.centre, r.array.yaw)
    for s, p in enumerate((near, far)):
        for c in range(4):
            d = np.linalg.norm(np.asarray(p) - mics_room[c])
            assert abs(int(np.argmax(np.abs(rirs[s, c]))) - d / SOUND_SPEED * FS) <= 1.0
    # amplitude falls as 1/r: the direct path's energy at 4 m is 1/16 of that at 1 m
    d_near = np.linalg.norm(np.asarray(near) - mics_room, axis=1)
    d_far = np.linalg.norm(np.asarray(far) - mics_room, axis=1)
    ratio = np.sqrt((rirs[0] ** 2).sum(axis=-1) / (rirs[1] ** 2).sum(axis=-1))
    np.testing.assert_allclose(ratio, d_far / d_near, rtol=0.02)


def test_additive_source_has_no_position():
    r = _recipe(10.0, 0.0)
    az, el, dist = source_labels(r, 1)
    assert np.all(np.isnan(az)) and np.all(np.isnan(el)) and np.all(np.isnan(dist))
    assert len(az) == r.n_frames == 10


@pytest.mark.parametrize("length", [1, 300, 20000, 40000])
def test_convolve_equals_direct_convolution(length):
    rng = np.random.default_rng(length)
    x = rng.standard_normal((2, 5000)).astype(np.float32)
    h = rng.standard_normal((2, 3, length)).astype(np.float32)
    y = convolve(x, h, 4000)
    for s in range(2):
        for c in range(3):
            ref = np.convolve(x[s].astype(np.float64), h[s, c].astype(np.float64))[:4000]
            np.testing.assert_allclose(y[s, c], ref, atol=2e-3 * np.abs(ref).max())


def _band_coherence(y, a, b, fs, k=4):
    """Real coherence of channels a, b in bands of k Welch bins (Welch, 256 samples)."""
    from scipy.signal import csd, welch

    f, sxy = csd(y[a], y[b], fs=fs, nperseg=256)
    _, sxx = welch(y[a], fs=fs, nperseg=256)
    _, syy = welch(y[b], fs=fs, nperseg=256)
    m = len(f) // k * k

    def avg(v):
        return v[:m].reshape(-1, k).mean(axis=1)
    return avg(f), np.real(avg(sxy)) / np.sqrt(avg(sxx) * avg(syy))


def _msc(y, a, b, fs, window):
    """Welch magnitude-squared coherence of channels a, b at STFT windows of ``window`` s."""
    from scipy.signal import csd, welch

    n = int(window * fs)
    f, sxy = csd(y[a], y[b], fs=fs, nperseg=n)
    _, sxx = welch(y[a], fs=fs, nperseg=n)
    _, syy = welch(y[b], fs=fs, nperseg=n)
    return f, np.abs(sxy) ** 2 / (sxx * syy)


CUSTOM5 = ((0.05, 0.0, 0.0), (0.0, 0.05, 0.0), (-0.05, 0.0, 0.0), (0.0, -0.05, 0.0), (0.0, 0.0, 0.08))


@pytest.mark.parametrize("pose", [
    ("mic4", dict(side=0.12)), ("tetra", dict(baffle="rigid")), ("foa", {}), ("custom", dict(capsules=CUSTOM5)),
], ids=["mic4", "tetra", "foa", "custom"])
def test_a_diffuse_additive_source_is_diffuse_at_every_window(pose):
    """scene.additive = "diffuse": at 10, 40 and 170 ms STFT windows the magnitude-squared
    coherence of every pair, above the pair's first sinc zero, is within 0.05 of the
    receiver's diffuse-field theory (delayed copies of one clip, the old rendering, stay
    coherent at long windows); the clip's level per label frame stays its own."""
    from tsel_data.acoustics.capsules import capsule_model
    from tsel_data.acoustics.diffuse import diffuse_image
    from tsel_data.core.geometry import SOUND_SPEED
    from tsel_data.receivers import ArrayPose

    fs = 24000
    rng = np.random.default_rng(0)
    gate = np.repeat(np.arange(60) % 5 < 2, fs // 10)  # 2 frames sounding, 3 silent
    x = (rng.standard_normal(6 * fs) * gate).astype(np.float32)
    arr = ArrayPose(pose[0], (3.0, 3.0, 1.5), 20.0, **pose[1])
    model = capsule_model(arr, fs)
    y = diffuse_image(x, fs, model.diffuse_csd, np.random.default_rng(1))
    mics = arr.mics()
    for window in (0.010, 0.040, 0.170):
        for a in range(len(y)):
            for b in range(a + 1, len(y)):
                f, msc = _msc(y, a, b, fs, window)
                phi = model.diffuse_csd(f)
                theory = np.abs(phi[:, a, b]) ** 2 / np.real(phi[:, a, a] * phi[:, b, b])
                d = np.linalg.norm(mics[a] - mics[b])
                band = (f > (SOUND_SPEED / (2 * d) if d > 0 else 100.0)) & (f < 10000)
                assert np.abs(msc - theory)[band].mean() < 0.05, (window, a, b)
    # per label frame: the image's level channels follow the clip (the sphere adds its
    # diffuse-field gain, the same in every frame); a tile (~10 ms) leaks into the frames
    # on either side of a sound, none further
    level_ch = arr.spec.level_slice()
    power = np.mean(y[level_ch].reshape(-1, 60, fs // 10).astype(np.float64) ** 2, axis=(0, 2))
    on = gate.reshape(60, -1)[:, 0]
    level = 10 * np.log10(power[on])
    assert np.ptp(level) < 1.0
    beside = ~on & (np.roll(on, 1) | np.roll(on, -1))
    assert 10 * np.log10(power[beside].max()) < level.min() - 10
    assert power[~on & ~beside].max() == 0.0
