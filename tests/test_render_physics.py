"""Labels against the audio: an anechoic room, a known direction, the lags between mics."""
import numpy as np
import pytest

from tsel_data.acoustics import SOUND_SPEED
from tsel_data.acoustics.pyroom import pyroom_rirs
from tsel_data.geometry import Room, sph_to_cart
from tsel_data.receivers import ArrayPose, mic_positions
from tsel_data.recipe import SceneRecipe, Source
from tsel_data.render import convolve, source_labels

FS = 24000


def _recipe(az_room_deg, yaw, side=0.4):
    centre = (5.0, 5.0, 1.5)
    a = np.radians(az_room_deg)
    pos = (centre[0] + 2.5 * np.cos(a), centre[1] + 2.5 * np.sin(a), 2.0)
    src = Source("target", "c", "x.wav", ("noise",), position=tuple(pos))
    other = Source("interferer", "d", "y.wav", ("other",), spatial="additive", tir_db=0.0)
    return SceneRecipe("s-0", "test", 0, 1, "directional+additive", "noise", ArrayPose("mic4", centre, yaw, side),
                       (src, other), Room((10.0, 10.0, 4.0), 0.3), fs=FS, duration=1.0)


def _lag(a, b, max_lag):
    """Lag (samples, to 0.1) of b relative to a, from the cross-correlation peak (upsampled 10x)."""
    n = len(a) + len(b)
    spec = np.fft.rfft(b, n) * np.conj(np.fft.rfft(a, n))
    cc = np.fft.irfft(spec / (np.abs(spec) + 1e-12), n * 10)  # PHAT + interpolation
    lags = np.concatenate([np.arange(0, max_lag * 10 + 1), np.arange(-max_lag * 10, 0)])
    vals = np.concatenate([cc[: max_lag * 10 + 1], cc[-max_lag * 10:]])
    return lags[np.argmax(vals)] / 10


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
            got = _lag(y[i], y[j], 40)
            assert got == pytest.approx(tau[j] - tau[i], abs=1.0), (i, j)
    assert az == pytest.approx(((az_room - yaw + 180) % 360) - 180, abs=0.01)


def test_direct_path_delay_and_gain():
    r = _recipe(45.0, 0.0, side=0.1)
    from tsel_data.geometry import array_to_room

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


@pytest.mark.parametrize("fmt", ["mic4", "foa"])
def test_a_diffuse_additive_source_has_diffuse_field_statistics(fmt):
    """scene.additive = "diffuse": mic4 coherence follows sinc(kd) (the coherent rendering
    is 1 everywhere); FOA W, Y, Z, X are uncorrelated with energies 1 : 1/3 : 1/3 : 1/3;
    the clip's timing stays within a label frame."""
    from tsel_data.acoustics.late import diffuse_coherence, diffuse_filters
    from tsel_data.receivers import mic4_positions
    from tsel_data.timevarying import render_static

    fs = 24000
    rng = np.random.default_rng(0)
    x = (rng.standard_normal(4 * fs) * np.repeat(np.arange(40) % 4 < 2, fs // 10)).astype(np.float32)
    pos = mic4_positions(0.12)
    g = diffuse_filters(fs, np.random.default_rng(1), positions=None if fmt == "foa" else pos, foa=fmt == "foa")
    y = render_static(x, g)[:, : len(x)]
    if fmt == "mic4":
        for a, b in ((0, 1), (0, 2), (1, 3)):
            f, coh = _band_coherence(y, a, b, fs)
            band = (f > 100) & (f < 8000)
            err = np.abs(coh - diffuse_coherence(pos, f)[:, a, b])[band]
            assert err.mean() < 0.16, (a, b, err.mean())
            f, coh1 = _band_coherence(np.stack([x, x]), 0, 1, fs)  # what the coherent rendering gives
            assert np.abs(coh1 - diffuse_coherence(pos, f)[:, a, b])[band].mean() > 0.4
    else:
        e = np.mean(y.astype(np.float64) ** 2, axis=1)
        np.testing.assert_allclose(e[1:] / e[0], 1 / 3, rtol=0.15)
        c = np.corrcoef(y)
        assert np.max(np.abs(c[np.triu_indices(4, 1)])) < 0.1
    # the clip's timing stays: loud in every frame the clip sounds, quiet again one frame
    # after it stops (the waves' delays spread over 60 ms, less than a 100 ms label frame)
    energy = np.mean(y.reshape(len(y), 40, -1).astype(np.float64) ** 2, axis=(0, 2)) / np.mean(y.astype(np.float64) ** 2)
    on = np.arange(40) % 4 < 2
    assert energy[on].min() > 0.5 and energy[np.arange(40) % 4 == 3].max() < 0.01
