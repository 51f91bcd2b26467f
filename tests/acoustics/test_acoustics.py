"""Physics of the shoebox simulator (tsel_data/acoustics): decay, delays, levels, FOA
encoding, diffuse-tail coherence, hybrid/ism agreement. Kept fast (a few seconds)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import resample

from tsel_data.acoustics import SOUND_SPEED, simulate_rirs
from tsel_data.acoustics.ism import add_impulses, grid_to_signal, image_chunks, new_grid
from tsel_data.acoustics.metrics import edc, t30
from tsel_data.acoustics.shoebox import TRANSITION, shoebox_rirs
from tsel_data.errors import GeometryError
from tsel_data.core.geometry import Room, array_to_room, foa_gains
from tsel_data.receivers import ArrayPose

FS = 24000


def render_impulses(delays, weights, length):
    """Band-limited impulse trains [C, length]: channel c = sum_i weights[c][i] h(n - delays[c][i])."""
    grid = new_grid(len(delays), length)
    for c, (d, w) in enumerate(zip(delays, weights)):
        add_impulses(grid, c, d, w)
    return grid_to_signal(grid)


def test_impulses_placed_tap_by_tap_equal_the_polyphase_grid():
    """grid_to_signal's two ways give one sum: few impulses placed tap by tap, many through
    the filtered phase rows (the leading taps cut at 0, nothing beyond the length)."""
    from scipy.fft import next_fast_len

    from tsel_data.acoustics.ism import _filtered, _placed

    rng = np.random.default_rng(3)
    length = 900
    for n in (1, 40, 3000):
        d = np.concatenate([[0.0, 0.3, 5.7, length - 1.2], rng.uniform(0, length + 20, n)])
        w = rng.standard_normal(len(d))
        grid = new_grid(1, length)
        add_impulses(grid, 0, d, w)
        dd, ww = grid.channel(0)
        assert dd.max() < length  # beyond the grid: ignored
        placed, filtered = _placed(dd, ww, length), _filtered([(dd, ww)], length, next_fast_len(length + 31, real=True))[0]
        np.testing.assert_allclose(placed, filtered, rtol=0, atol=1e-12 * np.abs(filtered).max())
        np.testing.assert_array_equal(grid_to_signal(grid)[0], placed if n < 3000 else filtered)


def coherence(x, y, fs, nperseg=512):
    """Real part of the complex coherence Re{S_xy / sqrt(S_xx S_yy)} (Welch): (frequencies Hz, coherence).
    A diffuse field gives sinc(k d) between two omnis d metres apart."""
    from scipy.signal import csd, welch

    f, sxy = csd(x, y, fs=fs, nperseg=nperseg)
    _, sxx = welch(x, fs=fs, nperseg=nperseg)
    _, syy = welch(y, fs=fs, nperseg=nperseg)
    return f, np.real(sxy) / np.sqrt(np.maximum(sxx * syy, np.finfo(float).tiny))


def _passband_gain(seg: np.ndarray) -> float:
    """Mean magnitude response over 1-6 kHz of a short segment holding one impulse: its
    amplitude, independent of the band limit near Nyquist and of the 20 Hz DC blocker."""
    spec = np.abs(np.fft.rfft(seg, 1024))
    f = np.fft.rfftfreq(1024, 1 / FS)
    return float(spec[(f >= 1000) & (f <= 6000)].mean())


def _mic4(dims, yaw=30.0, side=0.12):
    return ArrayPose("mic4", (dims[0] / 2, dims[1] / 2, 1.1), yaw, side)


def _points(dims, n, seed):
    rng = np.random.default_rng(seed)
    lo = np.array([0.5, 0.5, 0.5])
    hi = np.asarray(dims) - 0.5
    return rng.uniform(lo, hi, (n, 3))


# --- building blocks ----------------------------------------------------------------------
def test_image_lattice_matches_brute_force():
    dims, src, ctr, radius = (5.0, 4.0, 3.0), np.array([1.0, 1.5, 1.2]), np.array([3.0, 2.0, 1.1]), 25.0
    got = np.concatenate([np.c_[p, o] for p, o in image_chunks(dims, src, ctr, radius, chunk=300)])
    ref = []
    r = range(-6, 7)
    for i in r:
        for j in r:
            for k in r:
                for q in np.ndindex(2, 2, 2):
                    idx = np.array([i, j, k])
                    sign = 1 - 2 * np.array(q)
                    pos = 2 * idx * np.array(dims) + sign * src
                    if np.linalg.norm(pos - ctr) <= radius:
                        ref.append([*pos, np.abs(2 * idx - np.array(q)).sum()])
    key = lambda a: sorted(map(tuple, np.round(a, 6)))
    assert key(got) == key(np.array(ref))


def test_fractional_impulse_is_centred_on_its_delay():
    delays = np.array([40.0, 100.25, 200.5, 300.9])
    y = render_impulses([delays], [np.ones(4)], 400)[0]
    for d in delays:
        n = int(np.floor(d))
        seg = resample(y[n - 32 : n + 32], 64 * 32)  # band-limited upsampling ×32
        peak = n - 32 + np.argmax(seg) / 32
        assert abs(peak - d) < 0.05
        assert _passband_gain(y[n - 32 : n + 32]) == pytest.approx(1.0, abs=0.005)


def test_t30_of_an_exponential_decay():
    rng = np.random.default_rng(0)
    t = np.arange(FS) / FS
    h = rng.standard_normal(FS) * 10 ** (-3 * t / 0.6)
    assert t30(h, FS) == pytest.approx(0.6, rel=0.03)
    assert edc(h)[0] == 0.0 and np.all(np.diff(edc(h)) <= 1e-9)


# --- calibrated decay -------------------------------------------------------------------
ROOMS = [
    ((10.0, 8.0, 12.0), 0.7),  # paper: every side 5-15 m
    ((6.5, 14.0, 9.0), 0.5),
    ((15.0, 14.0, 2.6), 1.0),  # realistic: low ceiling
    ((6.0, 5.0, 3.0), 0.6),
    ((12.0, 7.0, 3.5), 0.8),
]


@pytest.mark.parametrize("method", ["hybrid", "ism"])
@pytest.mark.parametrize("dims,rt60", ROOMS)
def test_t30_within_10_percent(dims, rt60, method):
    pts = _points(dims, 2, seed=1)
    rs = shoebox_rirs(Room(dims, rt60), _mic4(dims), pts, FS, method, seed=2)
    assert rs.rirs.dtype == np.float32 and rs.rirs.shape[:2] == (2, 4)
    assert rs.rt60_measured == pytest.approx(t30(rs.rirs[0, 0], FS))
    measured = np.array([t30(rs.rirs[s, c], FS) for s in range(2) for c in (0, 2)])
    assert np.all(np.abs(measured / rt60 - 1) < 0.10), measured / rt60
    if method == "ism":  # fitted on this very response: tighter
        assert abs(rs.rt60_measured / rt60 - 1) < 0.04
    # long enough for the decay to be measured, short enough not to waste convolution
    assert rs.rirs.shape[-1] / FS < 1.3 * rt60 + 0.1


# --- direct path ---------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["hybrid", "ism"])
def test_direct_path_delay_and_amplitude(method):
    dims = (7.0, 6.0, 3.0)
    arr = _mic4(dims, yaw=-70.0)
    pts = np.array([[5.3, 4.1, 1.6], [1.2, 2.05, 2.4]])
    rirs = shoebox_rirs(Room(dims, 0.6), arr, pts, FS, method, max_order=0).rirs
    mics = array_to_room(arr.mics(), arr.centre, arr.yaw)
    for s, p in enumerate(pts):
        for c, m in enumerate(mics):
            r = np.linalg.norm(p - m)
            delay = r / SOUND_SPEED * FS
            n = int(delay)
            seg = resample(rirs[s, c, n - 32 : n + 32].astype(np.float64), 64 * 32)
            assert abs(n - 32 + np.argmax(seg) / 32 - delay) < 0.5 / 32 + 0.05
            assert _passband_gain(rirs[s, c, n - 32 : n + 32]) == pytest.approx(1 / (4 * np.pi * r), rel=0.01)
            assert np.abs(rirs[s, c, : n - 16]).max() < 1e-3 * seg.max()  # nothing before it
            assert np.abs(rirs[s, c, n + 16 :]).max() < 0.01 * seg.max()  # nor after (anechoic)


def test_foa_gains_of_an_anechoic_source():
    dims = (8.0, 7.0, 4.0)
    arr = ArrayPose("foa", (3.0, 4.0, 1.5), 30.0)
    az, el = 60.0, 20.0
    d = np.array([np.cos(np.radians(az)) * np.cos(np.radians(el)), np.sin(np.radians(az)) * np.cos(np.radians(el)),
                  np.sin(np.radians(el))])
    p = array_to_room(2.0 * d, arr.centre, arr.yaw)
    h = shoebox_rirs(Room(dims, 0.5), arr, p[None], FS, "hybrid", max_order=0).rirs[0].astype(np.float64)
    ratios = h @ h[0] / (h[0] @ h[0])
    np.testing.assert_allclose(ratios, foa_gains(az, el), atol=1e-3)
    assert np.abs(h[0]).max() == pytest.approx(1 / (4 * np.pi * 2.0), rel=0.02)


# --- late tail -----------------------------------------------------------------------------
def test_tail_coherence_is_diffuse_between_omnis():
    dims = (9.0, 7.0, 3.2)
    arr = _mic4(dims, yaw=10.0, side=0.3)  # wide square: sinc(kd) crosses zero in band
    pts = _points(dims, 12, seed=3)
    rirs = shoebox_rirs(Room(dims, 0.8), arr, pts, FS, "hybrid", seed=4).rirs.astype(np.float64)
    tail = rirs[..., int((TRANSITION + 0.03) * FS) :]
    mics = arr.mics()
    for i, j in ((0, 1), (0, 2)):
        d = np.linalg.norm(mics[i] - mics[j])
        f, coh = coherence(tail[:, i], tail[:, j], FS, nperseg=256)
        coh = coh.mean(axis=0)  # over points: the estimate's noise is ~0.04 (unbiased)
        band = (f >= 100) & (f <= 3000)
        err = coh[band] - np.sinc(2 * f[band] * d / SOUND_SPEED)
        assert np.sqrt(np.mean(err**2)) < 0.07
        assert abs(err.mean()) < 0.03
    # the check: 100-500 Hz between neighbours of a 0.12 m square ≈ 0.9
    arr = _mic4(dims, side=0.12)
    rirs = shoebox_rirs(Room(dims, 0.8), arr, pts, FS, "hybrid", seed=4).rirs.astype(np.float64)
    tail = rirs[..., int((TRANSITION + 0.03) * FS) :]
    f, coh = coherence(tail[:, 0], tail[:, 1], FS)
    band = (f >= 100) & (f <= 500)
    assert coh.mean(axis=0)[band].mean() > 0.85


def test_foa_tail_is_uncorrelated_with_sn3d_energies():
    dims = (9.0, 7.0, 3.2)
    arr = ArrayPose("foa", (4.0, 3.0, 1.2), 45.0)
    pts = _points(dims, 4, seed=5)
    rirs = shoebox_rirs(Room(dims, 0.8), arr, pts, FS, "hybrid", seed=6).rirs.astype(np.float64)
    tail = rirs[..., int((TRANSITION + 0.03) * FS) :]
    energy = (tail**2).sum(axis=(0, 2))
    np.testing.assert_allclose(energy[1:] / energy[0], 1 / 3, rtol=0.15)
    corr = np.corrcoef(tail.transpose(1, 0, 2).reshape(4, -1))
    assert np.abs(corr[np.triu_indices(4, 1)]).max() < 0.1


def test_tail_continues_the_image_sources_without_a_step():
    dims = (6.0, 5.0, 3.0)
    room = Room(dims, 0.6)
    pts = _points(dims, 6, seed=7)
    hyb = shoebox_rirs(room, _mic4(dims), pts, FS, "hybrid", seed=8).rirs.astype(np.float64)
    ism = shoebox_rirs(room, _mic4(dims), pts, FS, "ism").rirs.astype(np.float64)
    for a, b in ((TRANSITION - 0.02, TRANSITION - 0.005), (TRANSITION + 0.005, TRANSITION + 0.03)):
        sl = slice(int(a * FS), int(b * FS))
        ratio_db = 10 * np.log10((hyb[..., sl] ** 2).sum() / (ism[..., sl] ** 2).sum())
        assert abs(ratio_db) < 1.5


def test_hybrid_and_ism_agree_on_direct_path_and_first_reflections():
    dims = (8.0, 6.0, 3.0)
    room = Room(dims, 0.7)
    pts = np.array([[5.5, 4.0, 1.4], [2.0, 1.5, 1.8]])
    hyb = shoebox_rirs(room, _mic4(dims), pts, FS, "hybrid", seed=1).rirs.astype(np.float64)
    ism = shoebox_rirs(room, _mic4(dims), pts, FS, "ism").rirs.astype(np.float64)
    n = int(0.03 * FS)  # direct path at ≤ 10 ms and the first reflections after it
    err = np.linalg.norm(hyb[..., :n] - ism[..., :n]) / np.linalg.norm(ism[..., :n])
    assert err < 0.03


# --- contract ----------------------------------------------------------------------------
def test_deterministic_and_seeded():
    dims = (7.0, 6.0, 3.0)
    room, arr, pts = Room(dims, 0.5), _mic4(dims), _points(dims, 2, seed=9)
    a = shoebox_rirs(room, arr, pts, FS, "hybrid", seed=3).rirs
    b = simulate_rirs(room, arr, pts, FS, "hybrid", seed=3).rirs
    c = shoebox_rirs(room, arr, pts, FS, "hybrid", seed=4).rirs
    np.testing.assert_array_equal(a, b)
    late = int((TRANSITION + 0.01) * FS)
    assert not np.allclose(a[..., late:], c[..., late:])
    np.testing.assert_array_equal(a[..., : int(0.05 * FS)], c[..., : int(0.05 * FS)])


def test_global_random_state_untouched():
    dims = (7.0, 6.0, 3.0)
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    shoebox_rirs(Room(dims, 0.5), _mic4(dims), _points(dims, 1, 0), FS, "hybrid", seed=1)
    assert np.array_equal(np.random.get_state()[1], before)


def test_tetra_channels_have_their_own_delays():
    dims = (7.0, 6.0, 3.0)
    arr = ArrayPose("tetra", (3.5, 3.0, 1.5), 0.0)
    p = np.array([[6.0, 3.0, 1.5]])  # straight ahead (+x)
    h = shoebox_rirs(Room(dims, 0.5), arr, p, FS, "hybrid", max_order=0).rirs[0]
    mics = array_to_room(arr.mics(), arr.centre, arr.yaw)
    expected = np.linalg.norm(p - mics, axis=1) / SOUND_SPEED * FS
    assert np.all(np.abs(np.argmax(np.abs(h), axis=1) - expected) <= 1.0)


def test_bad_geometry_raises_one_clear_error():
    dims = (7.0, 6.0, 3.0)
    with pytest.raises(GeometryError, match="not inside room"):
        shoebox_rirs(Room(dims, 0.5), _mic4(dims), np.array([[8.0, 1.0, 1.0]]), FS)
    with pytest.raises(ValueError, match="unknown shoebox method"):
        shoebox_rirs(Room(dims, 0.5), _mic4(dims), np.array([[1.0, 1.0, 1.0]]), FS, method="raytrace")
