"""A moving source whose distance changes: no level ripple at the knot period.

Crossfading knot RIRs whose direct paths arrive at different times is a comb filter at
every midpoint between knots (a 1-sample difference is already -3 dB for white noise at
the midpoint), so line passes and walks along linear bank trajectories dipped 1.5-2.5 dB
every 100 ms. The renderer now aligns the direct paths and moves the direct path
continuously (dsp/timevarying.py). Measured here: white noise through line passes in
simulated rooms and along a synthetic linear bank trajectory, frame power folded over the
knot cycle, broadband and per octave band 250 Hz - 8 kHz.
"""
import numpy as np
import pytest

import tsel_data.dsp.delaypath as dp
import tsel_data.dsp.timevarying as tv
from tsel_data.acoustics import SOUND_SPEED, simulate_rirs
from tsel_data.acoustics.metrics import RIPPLE_BANDS as BANDS
from tsel_data.acoustics.highpass import sosfilt
from tsel_data.acoustics.metrics import knot_ripple
from tsel_data.acoustics.shoebox import shoebox_rirs
from tsel_data.core.geometry import Room, array_to_room, cart_to_sph, room_to_array
from tsel_data.receivers import ArrayPose
from tsel_data.dsp.timevarying import render_moving

FS = 24000


# --- cases (the measure: tsel_data.acoustics.metrics.knot_ripple) -----------------------------------


def _line_pass(fmt, speed=40.0, dur=6.0, rt60=0.4, max_order=None):
    """Knot RIRs [K, C, L] and times of a straight pass 1.5 m from the array (closest after
    ~1.4 s) at ``speed`` deg/s seen from there, knots every 100 ms: the planner's "line"."""
    room, centre = Room((10.0, 9.0, 6.0), rt60), (3.0, 4.5, 1.2)
    arr = ArrayPose(fmt, centre, 0.0, 0.11 if fmt == "mic4" else None)
    d = np.hypot(1.5, 0.3)
    t = np.arange(0.0, dur + 0.1 - 1e-9, 0.1)
    pts = np.stack([centre[0] - 1.5 + np.radians(speed) * d * t, np.full_like(t, 6.0), np.full_like(t, 1.5)], -1)
    if max_order is None:
        return simulate_rirs(room, arr, pts, FS, "hybrid", seed=0, one_source=True).rirs, t, arr, pts
    return shoebox_rirs(room, arr, pts, FS, "hybrid", max_order=max_order, length=0.05).rirs, t, arr, pts


def _linear_bank(fmt):
    """A TAU-like linear trajectory: RIRs measured (here simulated) every 5 cm along a
    straight line 1.5 m in front of the array, as a bank."""
    from tsel_data.banks import MemoryBank, Trajectory

    room, centre = Room((10.0, 9.0, 6.0), 0.4), (3.0, 4.5, 1.2)
    arr = ArrayPose(fmt, centre, 0.0, 0.11 if fmt == "mic4" else None)
    ys = np.arange(-3.5, 3.5 + 1e-9, 0.05)
    pts = np.stack([np.full_like(ys, centre[0] + 1.5), centre[1] + ys, np.full_like(ys, 1.4)], -1)
    rirs = simulate_rirs(room, arr, pts, FS, "hybrid", seed=0, one_source=True).rirs[:, :, :7200]
    pos = np.stack(cart_to_sph(room_to_array(pts, arr.centre, arr.yaw)), -1)
    return MemoryBank(FS, fmt, {"lin": [(Trajectory("lin", "t0", "linear", pos, False), rirs)]})


# --- the ripple ------------------------------------------------------------------------------------
def _assert_the_warp_removes_the_ripple(rirs, times, T):
    before = knot_ripple(lambda x: render_moving(x, rirs, times, FS, delays=None), times, FS, T)
    after = knot_ripple(lambda x: render_moving(x, rirs, times, FS), times, FS, T)
    # the plain crossfade: ~1.6 dB broadband, ~2.5 dB in the 2-4 kHz octaves
    assert before[None] > 1.2 and max(before[b] for b in BANDS) > 2.0, before
    assert after[None] <= 0.5, after
    assert all(after[b] <= 1.0 for b in BANDS), after


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["foa", "mic4"])
def test_line_pass_has_no_ripple_at_the_knot_period(fmt):
    rirs, t, _, _ = _line_pass(fmt)
    _assert_the_warp_removes_the_ripple(rirs, t, int(5.5 * FS))


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["foa", "mic4"])
def test_linear_bank_walk_has_no_ripple_at_the_knot_period(fmt):
    from tsel_data.banks import sample_bank_path

    bank = _linear_bank(fmt)
    tid, idx, times = sample_bank_path(bank, "lin", np.random.default_rng(1), 5.0, 20.0, direction=1)
    rirs = bank.views("lin", tid, idx)
    _assert_the_warp_removes_the_ripple(rirs, times, int(5.0 * FS))


def test_the_direct_path_moves_without_ripple():
    """Anechoic line pass (the direct path only): the comb is the whole story, and it goes."""
    rirs, t, _, _ = _line_pass("mic4", max_order=0)
    T = int(5.5 * FS)
    before = knot_ripple(lambda x: render_moving(x, rirs, t, FS, delays=None), t, FS, T, reps=3)
    after = knot_ripple(lambda x: render_moving(x, rirs, t, FS), t, FS, T, reps=3)
    assert before[None] > 2.0 and before[4000] > 2.0, before
    # (white noise without reverberation fluctuates: the bands below 4 kHz measure ~0.3-0.9 dB
    # of noise here whatever the renderer, the same as a static source's)
    assert after[None] <= 0.15 and after[4000] <= 0.35 and after[8000] <= 0.35, after


def test_arcs_are_rendered_as_before():
    """At constant distance the direct path does not move: nothing is warped, the render
    is bit for bit the plain crossfade (FOA: coincident channels; mic4: the capsules'
    own small steps stay under the threshold)."""
    room, centre = Room((8.0, 7.0, 4.0), 0.4), (4.0, 3.5, 1.2)
    x = np.random.default_rng(0).standard_normal(2 * FS).astype(np.float32)
    t = np.arange(0.0, 2.1, 0.1)
    a = np.radians(40.0 * t)
    pts = np.stack([centre[0] + 1.5 * np.cos(a), centre[1] + 1.5 * np.sin(a), np.full_like(t, 1.5)], -1)
    for fmt in ("foa", "mic4"):
        arr = ArrayPose(fmt, centre, 0.0, 0.11 if fmt == "mic4" else None)
        rirs = simulate_rirs(room, arr, pts, FS, "hybrid", seed=0, one_source=True).rirs
        assert dp._delay_groups(dp._steps_from("auto", rirs, t * FS), rirs.shape[1]) is None
        assert np.array_equal(render_moving(x, rirs, t, FS), render_moving(x, rirs, t, FS, delays=None))


# --- simulated paths: the shared tail apart, knots along lines ----------------------------------------
# The line passes with the most ripple among 62 planned from the demo preset's rooms and 62
# from realistic-sim's (motion "moving", path "line", FOA and mic4): room, array, first and
# last position of the path (room frame), and when it is at the last.
WORST_LINES = {
    "tall room, 1 m from a wall": (Room((5.5326, 13.5041, 12.3567), 0.7031),
                                   ArrayPose("mic4", (2.28473, 2.42388, 1.03589), -37.5856, 0.11708),
                                   (4.450506, 0.912996, 1.733864), (4.575333, 8.932199, 1.733864), 10.0),
    "3.3 m ceiling": (Room((7.5679, 13.9205, 3.2844), 0.5433),
                      ArrayPose("mic4", (1.29851, 11.94112, 1.05019), 142.0003, 0.11665),
                      (2.260945, 5.347834, 1.525691), (3.120555, 11.861356, 1.525691), 10.022118),
}


def _path(a, b, t_end, hop, dur=10.0):
    """Knots (t, x, y, z) every ``hop`` s of a straight path from ``a`` (t = 0) to ``b`` (t_end)."""
    t = np.arange(0.0, dur + hop - 1e-9, hop)
    a, b = np.asarray(a), np.asarray(b)
    return np.column_stack([t, a + np.outer(t / t_end, b - a)])


@pytest.mark.slow
@pytest.mark.parametrize("case", list(WORST_LINES))
def test_a_line_pass_in_a_reverberant_room_keeps_its_level(case):
    """With the shared tail convolved apart, knots every 6 cm of travel and the image
    sources in groups each aligned by its own delay, the worst planned line passes meet
    the goal with room to spare, where whole RIRs at 100 ms knots (the renderer's input
    before) do not."""
    from tsel_data.plan.placement import knot_hop
    from tsel_data.render.mix import path_image

    room, arr, a, b, t_end = WORST_LINES[case]
    speed = np.linalg.norm(np.subtract(b, a)) / t_end
    d = 2.0  # its closest approach: it sweeps degrees(speed / d) there
    hop = knot_hop("line", np.degrees(speed / d), d, d)
    assert speed * hop == pytest.approx(0.06) and hop < 0.1  # 6 cm of travel
    T = int(9.5 * FS)
    path = _path(a, b, t_end, hop)
    now = knot_ripple(lambda x: path_image(room, arr, path, x, FS, "hybrid", 3)[0][:, :T], path[:, 0], FS, T)
    old = _path(a, b, t_end, 0.1)
    rirs = simulate_rirs(room, arr, old[:, 1:], FS, "hybrid", seed=3, one_source=True).rirs
    before = knot_ripple(lambda x: render_moving(x, rirs, old[:, 0], FS), old[:, 0], FS, T)
    assert before[None] > 0.55, before
    assert now[None] <= 0.4 and all(now[f] <= 1.0 for f in BANDS), now


def test_the_shared_tail_apart_is_the_same_response():
    """tail_apart returns the image-source parts and the one tail the knots share: they sum
    to the whole RIRs bit for bit and the measured RT60 is the same; in image groups the
    parts are the same images, split (the groups sum to the ungrouped part)."""
    from tsel_data.render.mix import path_image

    room, centre = Room((8.0, 7.0, 4.0), 0.6), (4.0, 3.5, 1.2)
    t = np.arange(0.0, 2.1, 0.1)
    ang = np.radians(40.0 * t)
    path = np.column_stack([t, centre[0] + 1.5 * np.cos(ang), centre[1] + 1.5 * np.sin(ang), np.full_like(t, 1.5)])
    x = np.random.default_rng(0).standard_normal(2 * FS).astype(np.float32)
    for fmt in ("foa", "mic4"):
        arr = ArrayPose(fmt, centre, 0.0, 0.11 if fmt == "mic4" else None)
        whole = simulate_rirs(room, arr, path[:, 1:], FS, "hybrid", seed=5, one_source=True)
        apart = simulate_rirs(room, arr, path[:, 1:], FS, "hybrid", seed=5, one_source=True, tail_apart=True)
        L = apart.rirs.shape[-1]
        assert apart.tail.shape == whole.rirs.shape[1:] and L < whole.rirs.shape[-1] // 2
        summed = apart.tail[None].repeat(len(t), 0)
        summed[..., :L] += apart.rirs
        assert np.array_equal(summed, whole.rirs)
        assert apart.rt60_measured == whole.rt60_measured
        grouped = simulate_rirs(room, arr, path[:, 1:], FS, "hybrid", seed=5, one_source=True, tail_apart=True,
                                groups=4)
        K, G, C = grouped.delays.shape
        assert G == 4 and grouped.rirs.shape == (K, G * C, L) and np.array_equal(grouped.tail, apart.tail)
        parts = grouped.rirs.reshape(K, G, C, L)
        assert all(np.abs(parts[:, g]).max() > 0 for g in range(G))  # every group holds images
        np.testing.assert_allclose(parts.sum(axis=1), apart.rirs, rtol=0, atol=1e-6 * np.abs(apart.rirs).max())
        # the knots all at once, their DC blocker left for the render (image_highpass=False):
        # the same parts once it is applied
        raw = simulate_rirs(room, arr, path[:, 1:], FS, "hybrid", seed=5, one_source=True, tail_apart=True,
                            groups=4, image_highpass=False)
        assert raw.highpass is not None and np.array_equal(raw.delays, grouped.delays)
        summed = raw.rirs.reshape(K, G, C, -1).sum(axis=1)
        blocked = sosfilt(raw.highpass, np.pad(summed, ((0, 0), (0, 0), (0, L - summed.shape[-1]))))
        np.testing.assert_allclose(blocked, apart.rirs, rtol=0, atol=1e-5 * np.abs(apart.rirs).max())
        image, rt60 = path_image(room, arr, path, x, FS, "hybrid", 5)
        assert rt60 == pytest.approx(whole.rt60_measured, rel=1e-4)  # blocked once, after the groups are summed
        ref = render_moving(x, whole.rirs, t, FS)[:, : len(x)]  # one warp: the same level, reflections apart
        assert abs(10 * np.log10(np.sum(image**2) / np.sum(ref**2))) < 0.2
        # methods without a shared tail return whole RIRs
        assert simulate_rirs(room, arr, path[:3, 1:], FS, "ism", one_source=True, tail_apart=True).tail is None


def test_line_knots_follow_the_travel():
    """Knots at least every 100 ms, every 4° of azimuth and every 6 cm of travel
    (v = speed·distance), on arcs and lines alike."""
    from tsel_data.plan.placement import knot_hop

    assert knot_hop("arc", 20.0, 1.0, 0.5) == pytest.approx(0.1)  # 4° of azimuth at 40°/s, 3.5 cm
    assert knot_hop("arc", 40.0, 1.0, 0.5) == pytest.approx(0.05)  # 4° of azimuth at 80°/s
    assert knot_hop("arc", 40.0, 3.0, 3.0) == pytest.approx(0.045 / (np.radians(40.0) * 3.0))  # 4.5 cm of travel
    for kind, travel in (("arc", 0.045), ("line", 0.06)):
        for speed, d in ((10.0, 1.0), (20.0, 2.0), (40.0, 3.0)):
            hop = knot_hop(kind, speed, d, d)
            assert hop <= 0.1 and np.radians(speed) * d * hop <= travel + 1e-12
    assert knot_hop("line", 10.0, 1.0, 1.0) == pytest.approx(0.1)  # 1.7 cm per 100 ms
    assert knot_hop("line", 40.0, 2.0, 2.0) == pytest.approx(0.06 / (np.radians(40.0) * 2.0))
    assert knot_hop("line", 0.0, 2.0, 2.0) is None


# --- the model: Doppler, the engine against its definition, the estimate --------------------------
def test_a_moving_pure_delay_is_a_continuous_time_warp():
    """Knots that are pure delays d_k (here 80 -> 30 -> 95 samples: approaching, then
    receding): the output is x(t - d(t)) with d linear between knots (emission time),
    i.e. the Doppler-shifted signal, not a crossfade of two copies."""
    rng = np.random.default_rng(3)
    T, L = 3 * FS, 200
    x = rng.standard_normal(T)
    spec = np.fft.rfft(x)
    spec[np.fft.rfftfreq(T) > 0.4] = 0  # band-limited to 0.8 Nyquist
    x = np.fft.irfft(spec, T).astype(np.float32)
    times = np.linspace(0.0, 3.0, 31)
    d = np.interp(times, [0.0, 1.4, 3.0], [80.0, 30.0, 95.0]) + 0.37
    h = np.zeros((len(times), 1, L), dtype=np.float32)
    for k, dk in enumerate(d):
        n0 = int(np.rint(dk))
        h[k, 0, n0 - 16 : n0 + 17] = dp.fractional_kernel([dk - n0])[0]
    y = render_moving(x, h, times, FS)[0]
    # the ideal: sample m receives x at the emission time n with n + d(n) = m
    n = np.arange(T, dtype=np.float64)
    m = n + np.interp(n, times * FS, d)
    t_out = np.arange(200, T - 200)
    n_of_m = np.interp(t_out, m, n)
    k = np.floor(n_of_m).astype(int)[:, None] + np.arange(-40, 41)
    u = n_of_m[:, None] - k
    window = np.i0(10 * np.sqrt(np.clip(1 - (u / 41) ** 2, 0, None))) / np.i0(10)
    ideal = np.sum(x.astype(np.float64)[np.clip(k, 0, T - 1)] * np.sinc(u) * window, axis=1)
    err = y[t_out] - ideal
    assert 10 * np.log10(np.sum(ideal**2) / np.sum(err**2)) > 35
    # while the plain crossfade of two delayed copies is far off
    y0 = render_moving(x, h, times, FS, delays=None)[0]
    assert 10 * np.log10(np.sum(ideal**2) / np.sum((y0[t_out] - ideal) ** 2)) < 10


def _hat(p, t):
    """Crossfade weights [K, len(t)]: hat functions on knot positions p, constant outside."""
    K = len(p)
    w = np.ones((K, len(t)))
    for k in range(K):
        if k > 0:
            w[k] = np.where(t < p[k], np.clip((t - p[k - 1]) / (p[k] - p[k - 1]), 0, 1), w[k])
        if k < K - 1:
            w[k] = np.where(t >= p[k], np.clip((p[k + 1] - t) / (p[k + 1] - p[k]), 0, 1), w[k])
    return w


def reference(x, h, times, fs, delays):
    """The delay-aware model (timevarying module docstring), sample by sample in float64.

    Per group of channels sharing a warp with knot shifts σ_k (cumulative direct-path
    steps): z(t) = Σ_j x[t - I - j] K_μ[j], s(t) = σ at warped time t (linear between the
    warped knots p_k + σ_k), I = rint(s), μ = s - I, zero where t - I is outside x; knot k
    takes hat(p + σ)_k(t) · z(t), moved by -σ_k (whole samples, then K_{-frac}), convolved
    with h_k. Channels without a warp: the plain crossfade Σ_k (hat(p)_k x) * h_k.
    """
    x = np.asarray(x, np.float64)
    h = np.asarray(h, np.float64)
    K, C, L = h.shape
    T, p = len(x), np.asarray(times, np.float64) * fs
    groups = dp._delay_groups(dp._steps_from(delays, h.astype(np.float32), p), C) or [(np.arange(C), None)]
    y = np.zeros((C, T + L - 1))
    H = dp.FD_HALF
    j = np.arange(-H, H + 1)
    for chans, sig in groups:
        if sig is None:
            w = _hat(p, np.arange(T, dtype=np.float64))
            for k in range(K):
                for c in chans:
                    y[c] += np.convolve(w[k] * x, h[k, c])
            continue
        t0, t1 = int(np.floor(sig.min())) - 40, T + int(np.ceil(sig.max())) + 40
        t = np.arange(t0, t1, dtype=np.float64)
        s = np.interp(t, p + sig, sig)
        whole = np.rint(s)
        src = (t - whole).astype(int)[:, None] - j
        xv = np.where((src >= 0) & (src < T), x[np.clip(src, 0, T - 1)], 0.0)
        z = np.sum(xv * dp.fractional_kernel(s - whole), axis=1)
        z[((t - whole) < 0) | ((t - whole) >= T)] = 0.0
        w = _hat(p + sig, t)
        for k in range(K):
            I = int(np.rint(sig[k]))
            u = np.convolve(w[k] * z, dp.fractional_kernel([-(sig[k] - I)])[0])  # u[0] is at t0 - H - I
            start = t0 - H - I
            for c in chans:
                full = np.convolve(u, h[k, c])
                a, b = max(0, -start), min(len(full), T + L - 1 - start)
                if b > a:
                    y[c, start + a : start + b] += full[a:b]
    return y


def _snr(ref, y):
    return 10 * np.log10(np.sum(ref**2) / np.sum((ref - y) ** 2))


@pytest.mark.parametrize("case", ["shared", "per-channel", "mixed"])
@pytest.mark.parametrize("B", [None, 100, 333, 700])
def test_the_engine_is_exact_against_the_delay_aware_model(monkeypatch, case, B):
    """Given direct-path delays, the partitioned engine equals the sample-by-sample model:
    one warp for all channels, one per channel, and warped next to unwarped channels; at the
    planner's block size and forced ones (blocks shorter and longer than the knot spacing
    and the RIR)."""
    if B is not None:
        monkeypatch.setattr(tv, "_plan", lambda e, C, L, T: tv._sizes(B, L))
    rng = np.random.default_rng([["shared", "per-channel", "mixed"].index(case), B or 0])
    K, C, L, T = 11, 3, 300, 4000
    x = rng.standard_normal(T).astype(np.float32)
    h = rng.standard_normal((K, C, L)).astype(np.float32)
    times = -0.05 + np.cumsum(rng.uniform(0.02, 0.09, K))  # irregular, from before the clip to after it
    d = 60 + np.cumsum(rng.uniform(-6, 6, K))
    if case == "per-channel":
        d = d[:, None] + np.linspace(0, 1, K)[:, None] * np.array([[-12.0, 0.0, 14.0]])
    elif case == "mixed":  # channel 2 does not move
        d = np.stack([d, d + 0.2, np.full(K, 50.0)], -1)
    groups = dp._delay_groups(dp._steps_from(d, h, times * 8000), C)
    assert groups is not None and len(groups) == {"shared": 1, "per-channel": 3, "mixed": 2}[case]
    y = render_moving(x, h, times, 8000, delays=d)
    assert y.shape == (C, T + L - 1) and y.dtype == np.float32
    assert _snr(reference(x, h, times, 8000, d), y) > 90


@pytest.mark.parametrize("T,first", [(1, 0.0), (5, 0.15), (700, -0.2), (3000, 0.05)])
def test_warped_edges_are_exact(T, first):
    """Short clips, knots starting after the clip or ending long before the clip does,
    per-channel warps whose shifts run far apart: still the model."""
    rng = np.random.default_rng(T)
    K, C, L = 9, 3, 120
    times = first + np.cumsum(rng.uniform(0.01, 0.06, K))
    steps = rng.uniform(-0.4, 0.4, (K - 1, C)) * np.minimum(np.diff(times)[:, None] * 8000, 25)
    d = 200 + np.r_[np.zeros((1, C)), np.cumsum(steps, axis=0)]
    x = rng.standard_normal(T).astype(np.float32)
    h = rng.standard_normal((K, C, L)).astype(np.float32)
    y = render_moving(x, h, times, 8000, delays=d)
    assert y.shape == (C, T + L - 1)
    assert _snr(reference(x, h, times, 8000, d), y) > 90


def test_random_warps_are_exact():
    """Random knots, channels, RIR lengths and clip lengths (down to one sample; knots
    before, inside and long after the clip), shared and per-channel warps: the model."""
    rng = np.random.default_rng(3)
    for _ in range(30):
        K, C, L = int(rng.integers(2, 14)), int(rng.integers(1, 5)), int(rng.integers(1, 400))
        T = int(rng.choice([1, 5, 50, 300, 2000, 5000]))
        times = rng.uniform(-0.1, 0.1) + np.cumsum(rng.uniform(0.005, 0.12, K))
        room = np.minimum(np.diff(times) * 8000, 30)
        d = 300 + np.r_[0, np.cumsum(rng.uniform(-0.45, 0.45, K - 1) * room)]
        if rng.random() < 0.5 and C > 1:
            d = d[:, None] + np.cumsum(np.r_[np.zeros((1, C)), rng.uniform(-0.2, 0.2, (K - 1, C)) * room[:, None]], axis=0)
        x = rng.standard_normal(T).astype(np.float32)
        h = rng.standard_normal((K, C, L)).astype(np.float32)
        ref = reference(x, h, times, 8000, d)
        y = render_moving(x, h, times, 8000, delays=d)
        assert y.shape == ref.shape
        if np.any(ref):
            assert _snr(ref, y) > 90, (K, C, L, T)


@pytest.mark.parametrize("fmt", ["foa", "mic4"])
def test_estimated_steps_match_the_geometry(fmt):
    """The direct path's steps estimated from simulated RIRs equal the geometric ones
    (distance / c · fs per channel) to 0.1 sample; FOA channels are found coincident."""
    rirs, t, arr, pts = _line_pass(fmt, dur=3.0)
    mics = array_to_room(arr.mics(), arr.centre, arr.yaw)
    d = np.linalg.norm(pts[:, None, :] - mics[None], axis=-1) / SOUND_SPEED * FS  # [K, C]
    steps, ok, ref, coincident = dp._delay_steps(rirs, t * FS)
    assert coincident == (fmt == "foa") and ok.all()
    est = dp.delay_steps(rirs, t, FS)
    assert est.shape == (len(t) - 1, rirs.shape[1])
    assert np.max(np.abs(est - np.diff(d, axis=0))) < 0.1
    assert np.max(np.abs(np.diff(d, axis=0))) > 4  # the pass really moves the direct path


def test_rirs_without_a_common_direct_path_are_not_warped():
    """Unrelated knots (noise RIRs, the exactness tests' kind) and identical ones: no step
    is trusted, the plain crossfade is used (and identical RIRs stay the static convolution)."""
    rng = np.random.default_rng(5)
    h = rng.standard_normal((20, 4, 500)).astype(np.float32)
    times = np.linspace(0, 2, 20)
    assert dp._delay_groups(dp._steps_from("auto", h, times * 8000), 4) is None
    same = np.repeat(h[:1], 20, axis=0)
    assert dp._delay_groups(dp._steps_from("auto", same, times * 8000), 4) is None


def test_labels_follow_the_moving_direct_path():
    """The label path is the rendered one: with pure-delay FOA knots along a line pass, a
    click emitted at each 100 ms label-frame centre arrives after the label's distance / c
    (labels: positions at frame centres, linear between knots, as interpolate_positions
    gives them), to a hundredth of a sample."""
    from tsel_data.core.geometry import foa_gains
    from tsel_data.dsp.timevarying import interpolate_positions

    K = 31
    times = np.linspace(0.0, 3.0, K)
    pts = np.stack([np.full(K, 1.2), np.linspace(-2.5, 2.0, K), np.zeros(K)], -1)  # array frame
    az, el, dist = cart_to_sph(pts)
    d = dist / SOUND_SPEED * FS
    h = np.zeros((K, 4, 400), dtype=np.float32)
    for k in range(K):
        n0 = int(np.rint(d[k]))
        h[k, :, n0 - 16 : n0 + 17] = np.outer(foa_gains(az[k], el[k]), dp.fractional_kernel([d[k] - n0])[0])
    hop = FS // 10
    centres = np.arange(30) * hop + hop // 2
    x = np.zeros(3 * FS, dtype=np.float32)
    x[centres] = 1.0
    labels = interpolate_positions(times, np.stack([az, el, dist], -1), centres / FS)

    def arrival_errors(y):
        errs = []
        for f in range(1, 29):
            expect = labels[f, 2] / SOUND_SPEED * FS
            a = int(centres[f] + expect) - 32
            fine = np.fft.irfft(np.fft.rfft(y[a : a + 64].astype(np.float64)), 64 * 64) * 64  # band-limited, 1/64 sample
            i = int(np.argmax(fine))
            frac = 0.5 * (fine[i - 1] - fine[i + 1]) / (fine[i - 1] - 2 * fine[i] + fine[i + 1])
            errs.append(a + (i + frac) / 64 - centres[f] - expect)
        return np.abs(errs)

    assert arrival_errors(render_moving(x, h, times, FS)[0]).max() < 0.05
    # the frame centres are midway between knots: the plain crossfade has two clicks there
    assert arrival_errors(render_moving(x, h, times, FS, delays=None)[0]).max() > 2.0
