"""Time-varying convolution: exactness, static equivalence, level, labels."""
import numpy as np
import pytest

import tsel_data.dsp.timevarying as tv
from tsel_data.core.geometry import foa_gains
from tsel_data.dsp.timevarying import interpolate_positions, render_moving, render_static

FS = 8000


def knot_weights(times, fs: float, n: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The model's definition, independent of the renderer: w_k(n), the crossfade weight of knot ``k`` at sample ``n`` (broadcasting arrays).

    Linear between neighbouring knots, 1 before the first and after the last knot; the
    weights of all knots sum to 1 at every sample.
    """
    p = np.asarray(times, dtype=np.float64) * fs
    K = len(p)
    k = np.asarray(k)
    n = np.asarray(n, dtype=np.float64)
    pk = p[k]
    left = p[np.maximum(k - 1, 0)]
    right = p[np.minimum(k + 1, K - 1)]
    with np.errstate(divide="ignore", invalid="ignore"):
        rise = np.where(k == 0, 1.0, (n - left) / (pk - left))
        fall = np.where(k == K - 1, 1.0, (right - n) / (right - pk))
    return np.clip(np.where(n <= pk, rise, fall), 0.0, 1.0)


def _brute(x, h, times, fs):
    """y[c, m] = sum_n x[n] h_c(n)[m - n], h(n) = sum_k w_k(n) h_k: one sample at a time."""
    K, C, L = h.shape
    n = np.arange(len(x))
    hn = np.einsum("kn,kcl->ncl", knot_weights(times, fs, n[None, :], np.arange(K)[:, None]), h.astype(np.float64))
    y = np.zeros((C, len(x) + L - 1))
    for m in range(len(x)):
        y[:, m : m + L] += x[m] * hn[m]
    return y


def _snr(ref, y):
    return 10 * np.log10(np.sum(ref**2) / np.sum((ref - y) ** 2))


@pytest.mark.parametrize("K,L,span", [(9, 300, (-0.05, 0.6)), (3, 40, (0.1, 0.2)), (25, 700, (-0.5, 0.9))])
def test_equals_sample_by_sample_convolution(K, L, span):
    rng = np.random.default_rng(K)
    x = rng.standard_normal(4000).astype(np.float32)
    h = rng.standard_normal((K, 3, L)).astype(np.float32)
    times = np.sort(rng.uniform(*span, K))
    y = render_moving(x, h, times, FS)
    assert y.shape == (3, 4000 + L - 1) and y.dtype == np.float32
    assert _snr(_brute(x, h, times, FS), y) > 90


def test_weights_are_a_partition_of_unity():
    times = np.array([-0.1, 0.02, 0.05, 0.3, 0.31, 0.9])
    n = np.arange(0, 8000, 7)
    w = knot_weights(times, FS, n[None, :], np.arange(len(times))[:, None])
    assert np.allclose(w.sum(axis=0), 1.0, atol=1e-12)
    assert np.all(w >= 0) and np.all(w <= 1)


def test_identical_rirs_give_the_static_convolution():
    rng = np.random.default_rng(1)
    x = rng.standard_normal(24000).astype(np.float32)
    h = rng.standard_normal((4, 500)).astype(np.float32)
    y = render_moving(x, np.repeat(h[None], 31, axis=0), np.linspace(-0.2, 3.3, 31), FS)
    ref = render_static(x, h)
    assert np.max(np.abs(y - ref)) <= 1e-5 * np.max(np.abs(ref))
    direct = np.stack([np.convolve(x.astype(np.float64), c) for c in h.astype(np.float64)])
    assert np.max(np.abs(ref - direct)) <= 1e-5 * np.max(np.abs(direct))


def test_single_knot_is_static():
    rng = np.random.default_rng(2)
    x, h = rng.standard_normal(1000).astype(np.float32), rng.standard_normal((1, 2, 64)).astype(np.float32)
    assert np.allclose(render_moving(x, h, [0.4], FS), render_static(x, h[0]))


def test_pure_gain_delay_bank_matches_analytic_render():
    """RIR k = FOA gains of position k at a delay of d samples: y_c[n + d] = x[n] g_c(n)."""
    rng = np.random.default_rng(3)
    T, d = 16000, 37
    az = np.linspace(-170, 170, 18)
    el = np.linspace(-20, 20, 18)
    g = foa_gains(az, el)  # [K, 4]
    h = np.zeros((18, 4, 64), dtype=np.float32)
    h[:, :, d] = g
    times = np.linspace(0.0, 2.0, 18)
    x = rng.standard_normal(T).astype(np.float32)
    y = render_moving(x, h, times, FS)
    t = np.arange(T) / FS
    expect = x[None, :] * np.stack([np.interp(t, times, g[:, c]) for c in range(4)])
    assert np.max(np.abs(y[:, d : d + T] - expect)) < 1e-5
    assert np.max(np.abs(y[:, :d])) < 1e-6 and np.max(np.abs(y[:, d + T :])) < 1e-6


def test_level_does_not_depend_on_clip_length():
    rng = np.random.default_rng(4)
    h = rng.standard_normal((6, 2, 300)).astype(np.float32)
    times = np.linspace(0, 1.0, 6)
    long = rng.standard_normal(4 * FS).astype(np.float32)
    short = long[: FS // 2]
    y_long, y_short = render_moving(long, h, times, FS), render_moving(short, h, times, FS)
    # causal and unnormalised: the short clip's output is the long one's beginning
    assert np.max(np.abs(y_short[:, : len(short)] - y_long[:, : len(short)])) < 1e-4
    # full reverb tail kept
    assert y_short.shape[1] == len(short) + 299 and np.abs(y_short[:, -50:]).max() > 0


def test_labels_follow_the_rendered_direction():
    """FOA pure-gain knots: the active-intensity azimuth of the render tracks the labels."""
    rng = np.random.default_rng(5)
    K = 21
    times = np.linspace(0, 2.0, K)
    az = np.linspace(-150, 150, K)
    pos = np.stack([az, np.zeros(K), np.ones(K)], axis=-1)
    h = foa_gains(az, 0.0)[:, :, None].astype(np.float32)
    x = rng.standard_normal(2 * FS).astype(np.float32)
    y = render_moving(x, h, times, FS)[:, : 2 * FS]
    hop = FS // 10
    centres = (np.arange(20) + 0.5) * hop / FS
    labels = interpolate_positions(times, pos, centres)
    frames = y.reshape(4, 20, hop)
    wy, wx = (frames[0] * frames[1]).sum(-1), (frames[0] * frames[3]).sum(-1)
    measured = np.degrees(np.arctan2(wy, wx))
    err = (measured - labels[:, 0] + 180) % 360 - 180
    # within a frame the gains blend linearly, so the intensity direction is within ~1° of the centre
    assert np.max(np.abs(err)) < 1.5


def test_interpolate_positions_unwraps_azimuth():
    pos = np.array([[170.0, 0, 1], [-170.0, 10, 2]])
    p = interpolate_positions([0.0, 1.0], pos, [0.5, -1.0, 2.0])
    assert np.allclose(p[0], [-180.0, 5.0, 1.5]) or np.allclose(p[0], [180.0 - 360, 5.0, 1.5])
    assert np.allclose(p[1], pos[0]) and np.allclose(p[2], pos[1])


def test_rejects_bad_knots():
    with pytest.raises(ValueError):
        render_moving(np.zeros(10), np.zeros((2, 1, 4)), [0.1, 0.1], FS)
    with pytest.raises(ValueError):
        render_moving(np.zeros(10), np.zeros((3, 1, 4)), [0.1, 0.2], FS)


# --- the partitioned engine: every grid, partition count and group size is exact -----------------
def _force_blocks(monkeypatch, B):
    """Make the renderer use blocks (and RIR partitions) of B samples."""
    monkeypatch.setattr(tv, "_plan", lambda e, C, L, T: tv._sizes(B, L))


@pytest.mark.parametrize("B", [64, 100, 250, 299, 300, 301, 640, 5000])
def test_any_block_size_is_exact(monkeypatch, B):
    """Blocks shorter, equal and longer than the RIR (P = 5..1 partitions, N > 2B for
    non-smooth sizes) and than the knot spacing, on a grid not aligned with the knots."""
    _force_blocks(monkeypatch, B)
    rng = np.random.default_rng(B)
    x = rng.standard_normal(3000).astype(np.float32)
    h = rng.standard_normal((12, 3, 300)).astype(np.float32)
    times = np.sort(rng.uniform(-0.02, 0.4, 12))  # irregular, first knot before the clip
    y = render_moving(x, h, times, FS)
    assert y.shape == (3, 3299) and y.dtype == np.float32
    assert _snr(_brute(x, h, times, FS), y) > 90


@pytest.mark.parametrize("group_bytes", [1, 150_000])
def test_knot_groups_do_not_change_the_result(monkeypatch, group_bytes):
    """One knot per group, and a few per group: the spectra carried between groups add up."""
    rng = np.random.default_rng(7)
    x = rng.standard_normal(6000).astype(np.float32)
    h = rng.standard_normal((40, 2, 200)).astype(np.float32)
    times = np.linspace(0.0, 0.75, 40) + rng.uniform(0, 0.004, 40)
    ref = render_moving(x, h, times, FS)
    monkeypatch.setattr(tv, "_GROUP_BYTES", group_bytes)
    y = render_moving(x, h, times, FS)
    assert np.max(np.abs(y - ref)) <= 1e-5 * np.max(np.abs(ref))
    assert _snr(_brute(x, h, times, FS), y) > 90


def test_regular_knots_align_the_grid_two_knots_per_block():
    """Knots exactly D samples apart: the planner picks B = D and every block holds two knots."""
    D, K, T = 2400, 105, 240000
    times = (np.arange(K) * D - 818.3) / 24000
    e = np.r_[0, np.clip(np.ceil(times[1:] * 24000), 0, T), T].astype(np.int64)
    B, P, N = tv._plan(e, 4, 7200, T)
    assert (B, P, N) == (2400, 3, 4800)
    nb, pairs = tv._pairs_per_block(e, T, B)
    assert pairs <= 2 * nb


def test_knots_closer_than_a_sample_and_outside_the_clip():
    """Knots that touch no sample (two within one sample, several before/after the clip)."""
    rng = np.random.default_rng(8)
    x = rng.standard_normal(2000).astype(np.float32)
    times = np.array([-0.5, -0.3, -0.01, 0.05, 0.05 + 1e-6, 0.05 + 2e-6, 0.12, 0.2, 0.3, 0.6, 0.9])
    h = rng.standard_normal((len(times), 2, 150)).astype(np.float32)
    y = render_moving(x, h, times, FS)
    assert _snr(_brute(x, h, times, FS), y) > 90


@pytest.mark.parametrize("C", [1, 3, 5])
def test_any_channel_count(C):
    rng = np.random.default_rng(C)
    x = rng.standard_normal(2500).astype(np.float32)
    h = rng.standard_normal((7, C, 120)).astype(np.float32)
    times = np.linspace(0.0, 0.3, 7)
    assert _snr(_brute(x, h, times, FS), render_moving(x, h, times, FS)) > 90


@pytest.mark.parametrize("T,L", [(1, 50), (49, 50), (5000, 1), (3000, 700), (240000, 7200)])
def test_static_is_plain_convolution(T, L):
    """render_static (the engine with one knot) equals np.convolve, short and long clips."""
    rng = np.random.default_rng(T + L)
    x = rng.standard_normal(T).astype(np.float32)
    h = rng.standard_normal((2, L)).astype(np.float32)
    y = render_static(x, h)
    if T * L > 10**8:  # check a stretch in the middle and the tail against np.convolve on slices
        ref = np.stack([np.convolve(x[100000:110000].astype(np.float64), c) for c in h.astype(np.float64)])
        # samples 110000-1 .. 110000+L-2 would need earlier/later input: compare the full-overlap part
        seg = y[:, 100000 + L - 1 : 110000]
        assert np.max(np.abs(seg - ref[:, L - 1 : 10000])) <= 1e-4 * np.max(np.abs(ref))
        assert y.shape == (2, T + L - 1)
    else:
        ref = np.stack([np.convolve(x.astype(np.float64), c) for c in h.astype(np.float64)])
        assert y.shape == ref.shape and y.dtype == np.float32
        assert np.max(np.abs(y - ref)) <= 1e-5 * max(np.max(np.abs(ref)), 1e-12)


@pytest.mark.parametrize("T,L,K", [(3000, 700, 3000), (3000, 700, 3699), (3000, 700, 5000), (3000, 700, 10),
                                   (100000, 7200, 100000), (100000, 7200, 70000), (100000, 7200, 120000),
                                   (40, 50, 40), (40, 50, 200), (0, 5, 7)])
def test_static_into_a_buffer_gives_the_same_bits(T, L, K):
    """``out=``: the first K samples of what render_static returns, bit for bit (sign of
    zero included: a silent stretch of the clip), zeros past T + L - 1, in rows that need
    not be contiguous with each other."""
    rng = np.random.default_rng(T + L + K)
    x = rng.standard_normal(T).astype(np.float32)
    x[T // 3: T // 2] = 0.0
    h = rng.standard_normal((3, L)).astype(np.float32)
    want = np.zeros((3, K), dtype=np.float32)
    y = render_static(x, h)
    want[:, :min(K, y.shape[1])] = y[:, :K]
    out = np.full((2, 3, K), np.nan, dtype=np.float32)
    row = out[1]
    assert render_static(x, h, out=row) is row
    assert np.array_equal(out[1].view(np.uint32), want.view(np.uint32))
    assert np.isnan(out[0]).all()  # nothing written outside its rows


def test_empty_signal_gives_the_bare_tail_length():
    h = np.ones((3, 2, 40), dtype=np.float32)
    assert render_static(np.zeros(0), h[0]).shape == (2, 39)
    assert render_moving(np.zeros(0), h, [0.0, 0.1, 0.2], FS).shape == (2, 39)


def test_rirs_as_a_list_of_read_only_views_render_the_same():
    """What Bank.views gives the renderer (read-only rows of a map) equals the stacked array."""
    rng = np.random.default_rng(11)
    x = rng.standard_normal(4000).astype(np.float32)
    h = rng.standard_normal((9, 4, 256)).astype(np.float32)
    times = np.linspace(-0.01, 0.3, 9)
    rows = [r.copy() for r in h]
    for r in rows:
        r.flags.writeable = False
    assert np.array_equal(render_moving(x, rows, times, FS), render_moving(x, h, times, FS))
    with pytest.raises(ValueError, match="one shape"):
        render_moving(x, rows[:8] + [h[0, :, :100]], times, FS)


@pytest.mark.parametrize("n", [8192, 4800, 1000])
def test_fft_round_trip_on_padded_rows(n):
    """fft.empty pads power-of-two rows (ducc0 slows 2x on them otherwise); values are unaffected."""
    from tsel_data.dsp import fft

    a = fft.empty((3, 5, n))
    assert a.shape == (3, 5, n) and (a.strides[-2] // 4 != n) == (n % 512 == 0)
    a[:] = np.random.default_rng(n).standard_normal((3, 5, n))
    spec = fft.rfft(a)
    assert np.allclose(spec, np.fft.rfft(a.astype(np.float64)), atol=1e-3 * np.sqrt(n))
    assert np.allclose(fft.irfft(spec, n), a, atol=1e-5)


def test_the_stored_farrow_filters_are_their_design_and_delay_by_mu():
    from tsel_data.dsp.delaypath import design_farrow, farrow_coefficients, fractional_kernel

    np.testing.assert_allclose(farrow_coefficients(), design_farrow(), rtol=0, atol=1e-12)
    # the filter delays a band-limited tone by mu: -50 dB error below half the Nyquist
    w = 0.4 * np.pi
    for mu in (-0.5, -0.2, 0.3, 0.5):
        k = fractional_kernel(mu)[0]
        j = np.arange(-len(k) // 2 + 1, len(k) // 2 + 1)
        resp = np.sum(k * np.exp(-1j * w * j))
        assert abs(resp - np.exp(-1j * w * mu)) < 10 ** (-50 / 20)
