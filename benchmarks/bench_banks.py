"""Bank-based rendering speed and accuracy (issue 3), and the moving renderer's level ripple.

    .venv/bin/python benchmarks/bench_banks.py [--bank PATH] [--scenes 20] [--brute-seconds 3]
        [--sections speed,ab,stft,accuracy,ripple]

speed: scenes/s on one core (median of --repeats runs, with the time per scene spent
   reading RIRs, rendering and mixing) for 2-source, 10 s, FOA scenes from a bank: static
   (one RIR per source) and moving (walks at 10/20/40 °/s, a knot at least every 100 ms):
   along circles (constant distance), and along lines (the distance changes, so the
   renderer aligns the knots' direct paths and warps the input; dsp/timevarying.py). Includes
   reading the RIRs from the bank file, rendering and mixing. Default bank: a TAU-shaped
   synthetic FOA bank (24 kHz, 7200-sample RIRs) written to a temporary native bank file:
   room "room", 2 circular trajectories of 360 positions 1° apart (TAU's circular rooms);
   room "lines", 2 straight lines of positions 5 cm apart 1.5 and 2.5 m in front of the
   array (TAU's linear rooms).
ab: the delay-aware render (default) against the plain crossfade (``delays=None``) of
   the same walks, interleaved source by source, on circles and lines: median of the paired
   time ratios (the machine may be shared; pairs cancel most of its drift).
stft: the moving renderer against a reference STFT-domain renderer written here the way
   the DCASE data generator / SpatialScaper do it (per STFT frame: interpolate every RIR
   frame's spectrum between the RIRs, multiply-accumulate the buffered input spectra,
   inverse FFT, overlap-add; window 0.05 s, hop half of it), and against the same method
   with its frame loops vectorised (each frame's weights touch two knots; the same output
   to 1e-14), so the speed-up is not only that of one Python loop over frames.
accuracy: both against a brute-force sample-by-sample time-varying convolution (SNR in
   dB), on circular walks (the delay-aware model's own sample-by-sample reference is in
   tests/dsp/test_moving_ripple.py).
ripple: white noise through moving sources, frame power over the knot cycle (peak to
   peak, dB), broadband and per octave band 250 Hz - 8 kHz, plain crossfade vs
   delay-aware: simulated line passes and an arc (hybrid RIRs, FOA and mic4), and a walk
   along a simulated linear bank trajectory (RIRs every 5 cm along a line).
against: one 10 s moving FOA source, this renderer against another commit's
   (--against REV, default 7d1f69f: the renderer before the delay-aware model), loaded
   from git into this process, on the same walks, interleaved: median of the paired time
   ratios on circles and lines (needs a git checkout).
planned: line passes planned from a preset's rooms (--preset, default demo; motion
   "moving", path "line", two directional sources, FOA and mic4, --planned scenes each),
   rendered as the toolkit does (render.path_image: knots by placement.knot_hop, the
   shared tail convolved apart) against the same paths the way it did before in the same
   run (knots every 100 ms / 4 degrees, whole RIRs through the moving renderer): ripple
   median / 90th percentile / max over the sources, broadband and the worst octave band
   from 1 kHz (below, the measure's own noise is ~0.3-0.5 dB), knots and ms per source.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from tsel_data.banks import MemoryBank, Trajectory, open_bank, sample_bank_path, sample_bank_point  # noqa: E402
from tsel_data.banks.native import write_bank  # noqa: E402
from tsel_data.runtime.pool import prepare_worker  # noqa: E402
from tsel_data.core.geometry import foa_gains  # noqa: E402
from tsel_data.dsp.timevarying import render_moving, render_static  # noqa: E402

FS = 24000


def tau_shaped_bank(path, L=7200, n=360, seed=0):
    """FOA RIRs: direct path with the position's gains + exponentially decaying diffuse
    noise from the direct path on (independent per RIR, as measured RIRs' late parts
    are; nothing arrives before the direct sound). Room "room": circles;
    room "lines": straight lines (positions every 5 cm, the direct path at its fractional
    delay)."""
    from tsel_data.core.geometry import cart_to_sph
    from tsel_data.dsp.delaypath import fractional_kernel

    rng = np.random.default_rng(seed)
    t = np.arange(L) / FS
    env = np.exp(-6.9 * t / 0.5).astype(np.float32)  # RT60 0.5 s
    circles = []
    for tid, (el, r) in enumerate(((0.0, 1.5), (20.0, 2.5))):
        az = np.arange(n) * 360.0 / n - 180.0
        pos = np.stack([az, np.full(n, el), np.full(n, r)], -1)
        h = (rng.standard_normal((n, 4, L)).astype(np.float32) * 0.05 * env)
        h[:, :, : int(r / 343 * FS)] = 0.0
        h[:, :, int(r / 343 * FS)] += foa_gains(az, el).astype(np.float32) / r
        circles.append((Trajectory("room", f"t{tid}", "circular", pos, True), h))
    lines = []
    for tid, (x_off, z) in enumerate(((1.5, 0.0), (2.5, 0.5))):
        y = np.arange(-4.0, 4.0 + 1e-9, 0.05)
        pos = np.stack(cart_to_sph(np.stack([np.full_like(y, x_off), y, np.full_like(y, z)], -1)), -1)
        h = (rng.standard_normal((len(y), 4, L)).astype(np.float32) * 0.05 * env)
        for i, (az, el, r) in enumerate(pos):
            d = r / 343 * FS
            n0 = int(np.rint(d))
            h[i, :, : n0 - 16] = 0.0
            h[i, :, n0 - 16 : n0 + 17] += np.outer(foa_gains(az, el) / r, fractional_kernel([d - n0])[0]).astype(np.float32)
        lines.append((Trajectory("lines", f"l{tid}", "linear", pos, False), h))
    return write_bank(path, MemoryBank(FS, "foa", {"room": circles, "lines": lines}))


def scene(bank, room, rng, moving, signals, clock=None):
    """One bank-based scene: per source read its RIRs, render, mix. ``clock`` (a dict)
    accumulates process time per stage: read (sampling the walk + bank.read), render, mix."""
    clock = {} if clock is None else clock
    tick = time.process_time
    out = None
    for x in signals:
        t0 = tick()
        if moving:
            tid, idx, times = sample_bank_path(bank, room, rng, len(x) / FS, (10.0, 20.0, 40.0))
        else:
            tid, idx = sample_bank_point(bank, room, rng)
            idx = [idx]
        rirs = bank.views(room, tid, idx)  # what the toolkit's renderer reads
        t1 = tick()
        y = render_moving(x, rirs, times, FS) if moving else render_static(x, rirs[0])
        t2 = tick()
        out = y if out is None else out[:, : y.shape[1]] + y[:, : out.shape[1]]
        t3 = tick()
        for k, dt in (("read", t1 - t0), ("render", t2 - t1), ("mix", t3 - t2)):
            clock[k] = clock.get(k, 0.0) + dt
    return out[:, : len(signals[0])]


def scenes_per_second(bank, n, moving, repeats=3, room=None):
    """Median over ``repeats`` runs of ``n`` scenes: (scenes/s, {stage: ms per scene})."""
    rng = np.random.default_rng(1)
    room = room or bank.rooms[0]
    sig = [rng.standard_normal(10 * FS).astype(np.float32) for _ in range(2)]
    scene(bank, room, rng, moving, sig)  # warm-up (file cache, FFT plans)
    rates, stages = [], []
    for _ in range(repeats):
        clock = {}
        t0 = time.process_time()
        for _ in range(n):
            scene(bank, room, rng, moving, sig, clock)
        rates.append(n / (time.process_time() - t0))
        stages.append({k: v / n * 1e3 for k, v in clock.items()})
    i = int(np.argsort(rates)[len(rates) // 2])
    return rates[i], stages[i]


# --- the STFT-domain reference (structure of the DCASE generator's moving renderer) -------------
def _stft(x, win, hop, nfft):
    """Frames of x (zero-padded at the front by win - hop) times a sin² window: [bins, frames, ...]."""
    w = np.sin(np.pi * np.arange(win) / win) ** 2
    n_frames = 2 * int(np.ceil(len(x) / (2 * hop))) + 1
    pad = np.zeros((win - hop + n_frames * hop + win,) + x.shape[1:])
    pad[win - hop : win - hop + len(x)] = x
    spec = []
    for f in range(n_frames):  # one frame at a time, as the reference does
        seg = pad[f * hop : f * hop + win] * (w if x.ndim == 1 else w[:, None])
        spec.append(np.fft.rfft(seg, nfft, axis=0))
    return np.stack(spec, axis=1)


def stft_reference(x, rirs, times, fs, win=None):
    """Per-frame STFT-domain time-varying filtering with RIR interpolation. rirs [K, C, L]."""
    win = int(win or 0.1 * fs // 2)
    hop, nfft = win // 2, 2 * win
    K, C, L = rirs.shape
    ir_spec = np.stack([_stft(rirs[k].T.astype(np.float64), win, hop, nfft) for k in range(K)], axis=-1)  # [B, F_ir, C, K]
    n_ir_frames = ir_spec.shape[1]
    sig_spec = _stft(x.astype(np.float64), win, hop, nfft)  # [B, F]
    stamps = np.round((np.asarray(times) * fs + hop) / hop).astype(int)
    n_frames = min(sig_spec.shape[1], int(stamps[-1]))
    # interpolation weights per frame (linear between the RIR time stamps)
    g = np.zeros((max(n_frames, int(stamps[-1])) + 1, K))
    for k in range(K - 1):
        pts = np.arange(stamps[k], stamps[k + 1] + 1) - 1
        r = np.arange(len(pts)) / max(len(pts) - 1, 1)
        g[pts, k], g[pts, k + 1] = 1 - r, r
    g_buf = np.zeros((n_ir_frames, K))
    s_buf = np.zeros((nfft // 2 + 1, n_ir_frames), dtype=complex)
    ctf = np.zeros((nfft // 2 + 1, n_ir_frames, C), dtype=complex)
    out = np.zeros((hop * n_frames + nfft, C))
    for f in range(n_frames):
        g_buf[1:], g_buf[0] = g_buf[:-1], g[f]
        for c in range(C):
            for i in range(n_ir_frames):
                ctf[:, i, c] = ir_spec[:, i, c, :] @ g_buf[i]
        s_buf[:, 1:], s_buf[:, 0] = s_buf[:, :-1], sig_spec[:, f]
        y = np.sum(s_buf[:, :, None] * ctf, axis=1)
        out[f * hop : f * hop + nfft] += np.fft.irfft(y, nfft, axis=0)
    return out[win : win + len(x)].T  # drop the analysis delay


def stft_vectorised(x, rirs, times, fs, win=None):
    """:func:`stft_reference` with its frame loops as array operations: every frame
    transformed at once, and each frame's interpolated transfer function built from the
    two knots its weights touch, not all K."""
    win = int(win or 0.1 * fs // 2)
    hop, nfft = win // 2, 2 * win
    K, C, L = rirs.shape
    w = np.sin(np.pi * np.arange(win) / win) ** 2

    def frames(sig):  # [frames, bins, ...]: _stft's frames, all at once
        n = 2 * int(np.ceil(len(sig) / (2 * hop))) + 1
        pad = np.zeros((win - hop + n * hop + win,) + sig.shape[1:])
        pad[win - hop: win - hop + len(sig)] = sig
        seg = pad[np.arange(n)[:, None] * hop + np.arange(win)[None]]
        return np.fft.rfft(seg * (w[None, :] if sig.ndim == 1 else w[None, :, None]), nfft, axis=1)

    ir = np.stack([frames(rirs[k].T.astype(np.float64)) for k in range(K)], axis=1)  # [F_ir, K, B, C]
    sig = frames(x.astype(np.float64))  # [F, B]
    stamps = np.round((np.asarray(times) * fs + hop) / hop).astype(int)
    n_frames = min(sig.shape[0], int(stamps[-1]))
    g = np.zeros((max(n_frames, int(stamps[-1])) + 1, K))
    for k in range(K - 1):
        pts = np.arange(stamps[k], stamps[k + 1] + 1) - 1
        r = np.arange(len(pts)) / max(len(pts) - 1, 1)
        g[pts, k], g[pts, k + 1] = 1 - r, r
    g = g[:n_frames]
    k0 = np.clip(np.argmax(g > 0, axis=1), 0, K - 2)
    s0 = sig[:n_frames] * g[np.arange(n_frames), k0][:, None]
    s1 = sig[:n_frames] * g[np.arange(n_frames), k0 + 1][:, None]
    spec = np.zeros((n_frames, nfft // 2 + 1, C), dtype=complex)
    for i in range(ir.shape[0]):  # input frame f - i through RIR frame i
        m = n_frames - i
        spec[i:] += ir[i, k0[:m]] * s0[:m, :, None] + ir[i, k0[:m] + 1] * s1[:m, :, None]
    y = np.fft.irfft(spec, nfft, axis=1)
    out = np.zeros((hop * n_frames + nfft, C))
    for f in range(n_frames):
        out[f * hop: f * hop + nfft] += y[f]
    return out[win: win + len(x)].T


def brute_force(x, rirs, times, fs):
    """y[c, m] = sum_n x[n] h_c(n)[m - n] with h(n) interpolated per sample (float64)."""
    K, C, L = rirs.shape
    y = np.zeros((C, len(x) + L - 1))
    p = np.asarray(times) * fs
    h64 = rirs.astype(np.float64)
    for n in range(len(x)):
        k = int(np.clip(np.searchsorted(p, n, "right") - 1, 0, K - 1))
        if k == K - 1 or n <= p[0]:
            h = h64[k if n > p[0] else 0]
        else:
            a = (n - p[k]) / (p[k + 1] - p[k])
            h = (1 - a) * h64[k] + a * h64[k + 1]
        y[:, n : n + L] += x[n] * h
    return y


def snr_db(ref, y):
    n = min(ref.shape[1], y.shape[1])
    return float(10 * np.log10(np.sum(ref[:, :n] ** 2) / np.sum((ref[:, :n] - y[:, :n]) ** 2)))


# --- paired timings: delay-aware vs plain crossfade, this renderer vs another commit's ------------
def paired_ratio(bank, room, new, old, rounds=5, walks=6, seed=4):
    """Median over paired renders of time(new) / time(old), and the median times (ms), for
    10 s walks at 10/20/40 °/s in ``room``; ``new`` and ``old`` take (signal, rirs, times)
    and are run interleaved, walk by walk (the machine may be shared; pairs cancel most of
    its drift)."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(10 * FS).astype(np.float32)
    cases = []
    for _ in range(walks):
        tid, idx, times = sample_bank_path(bank, room, rng, 10.0, (10.0, 20.0, 40.0))
        cases.append((bank.views(room, tid, idx), times))
    for fn in (new, old):  # warm-up
        fn(x, *cases[0])
    t_new, t_old = [], []
    for _ in range(rounds):
        for rirs, times in cases:
            for out, fn in ((t_old, old), (t_new, new)):
                t0 = time.process_time()
                fn(x, rirs, times)
                out.append(time.process_time() - t0)
    t_new, t_old = np.array(t_new), np.array(t_old)
    return float(np.median(t_new / t_old)), float(np.median(t_new) * 1e3), float(np.median(t_old) * 1e3)


def renderer_at(rev):
    """tsel_data/timevarying.py as it was at commit ``rev``, as a module of this package."""
    import importlib.util
    import subprocess

    root = os.path.join(os.path.dirname(__file__), "..")
    src = subprocess.run(["git", "-C", root, "show", f"{rev}:tsel_data/timevarying.py"], capture_output=True,
                         text=True, check=True).stdout
    mod = importlib.util.module_from_spec(importlib.util.spec_from_loader(f"tsel_data._timevarying_{rev}", None))
    mod.__package__ = "tsel_data"
    exec(compile(src, f"timevarying.py@{rev}", "exec"), mod.__dict__)
    return mod


# --- the level ripple at the knot period -------------------------------------------------------------
from tsel_data.acoustics.metrics import RIPPLE_BANDS as BANDS, knot_ripple  # noqa: E402  (the tests' measure)


def ripple_cases():
    """(label, rirs [K, C, L], times) of simulated moving sources: line passes 1.5 m from
    the array at 20 and 40 °/s (knots every 100 ms, the planner's "line"), an arc, and a
    20 °/s walk along a linear bank trajectory of RIRs every 5 cm; a 10 x 9 x 6 m room,
    RT60 0.4 s, hybrid RIRs (one late-tail realisation per path, as for simulated paths
    and banks)."""
    from tsel_data.acoustics import simulate_rirs
    from tsel_data.core.geometry import cart_to_sph, room_to_array
    from tsel_data.core.geometry import Room
    from tsel_data.receivers import ArrayPose

    room, centre = Room((10.0, 9.0, 6.0), 0.4), (3.0, 4.5, 1.2)
    t = np.arange(0.0, 6.1 - 1e-9, 0.1)
    d = np.hypot(1.5, 0.3)
    for fmt in ("foa", "mic4"):
        arr = ArrayPose(fmt, centre, 0.0, 0.11 if fmt == "mic4" else None)
        for speed in (20.0, 40.0):
            pts = np.stack([centre[0] - 1.5 + np.radians(speed) * d * t, np.full_like(t, 6.0), np.full_like(t, 1.5)], -1)
            yield f"{fmt} line pass {speed:.0f} deg/s", simulate_rirs(room, arr, pts, FS, "hybrid", seed=0, one_source=True).rirs, t
        a = np.radians(40.0 * t)
        pts = np.stack([centre[0] + 1.5 * np.cos(a), centre[1] + 1.5 * np.sin(a), np.full_like(t, 1.5)], -1)
        yield f"{fmt} arc 40 deg/s", simulate_rirs(room, arr, pts, FS, "hybrid", seed=0, one_source=True).rirs, t
        ys = np.arange(-3.5, 3.5 + 1e-9, 0.05)
        pts = np.stack([np.full_like(ys, centre[0] + 1.5), centre[1] + ys, np.full_like(ys, 1.4)], -1)
        rirs = simulate_rirs(room, arr, pts, FS, "hybrid", seed=0, one_source=True).rirs[:, :, :7200]
        pos = np.stack(cart_to_sph(room_to_array(pts, arr.centre, arr.yaw)), -1)
        lin = MemoryBank(FS, fmt, {"lin": [(Trajectory("lin", "t0", "linear", pos, False), rirs)]})
        tid, idx, times = sample_bank_path(lin, "lin", np.random.default_rng(1), 6.0, 20.0, direction=1)
        yield f"{fmt} linear bank walk 20 deg/s", lin.read("lin", tid, idx), times


def planned_section(preset, n, reps=6):
    """Ripple and cost of planned line passes, now against before (module docstring)."""
    from tsel_data.plan import placement
    from tsel_data.acoustics import simulate_rirs
    from tsel_data.acoustics.metrics import RIPPLE_BANDS
    from tsel_data.errors import GeometryError
    from tsel_data.job.onthefly import scene_source
    from tsel_data.render.mix import path_image

    def before_image(r, path, x, seed):
        rs = simulate_rirs(r.room, r.array, path[:, 1:], FS, method=r.rir_method, seed=seed, one_source=True)
        return render_moving(x, rs.rirs, path[:, 0], FS)[:, : len(x)]

    def now_image(r, path, x, seed):
        return path_image(r.room, r.array, path, x, FS, r.rir_method, seed)[0]

    travel = placement.KNOT_TRAVEL_M
    rows = {"before": [], "now": []}
    with tempfile.TemporaryDirectory() as home:
        for fmt in ("foa", "mic4"):
            # the preset's rooms and array; the clips do not matter (white noise), so the built-in ones
            src = scene_source(preset=preset, split="train", home=home, overrides=[
                'corpus.dir="builtin:demo"', 'corpus.format="audiocaps"', 'scene.motion="moving"', 'scene.path="line"', f'scene.format="{fmt}"',
                'scene.scenario="two-directional"', 'scene.interferers=1'])
            for label, render in (("before", before_image), ("now", now_image)):
                placement.KNOT_TRAVEL_M = dict.fromkeys(travel, np.inf) if label == "before" else travel
                for i in range(n):
                    try:
                        r = src.recipe(i)
                    except GeometryError:  # the preset's rooms cannot hold this draw
                        continue
                    for k, s in enumerate(r.sources):
                        if not s.path:
                            continue
                        path = np.asarray(s.path)
                        times, T = path[:, 0], int(min(path[-1, 0], r.duration) * FS)
                        t0 = time.process_time()
                        render(r, path, np.ones(T, np.float32), r.seed + 1 + k)
                        cost = time.process_time() - t0
                        rip = knot_ripple(lambda v: render(r, path, v, r.seed + 1 + k)[:, :T], times, FS, T, reps=reps)
                        rows[label].append((rip[None], max(rip[b] for b in RIPPLE_BANDS if b >= 1000), len(path), cost))
    placement.KNOT_TRAVEL_M = travel
    print(f"planned line passes ({preset} rooms, FOA and mic4, {len(rows['now'])} sources; peak to peak dB, "
          f"median / p90 / max):")
    for label, got in rows.items():
        bb, ob = np.array([g[0] for g in got]), np.array([g[1] for g in got])
        q = lambda v: f"{np.median(v):.2f} / {np.percentile(v, 90):.2f} / {v.max():.2f}"
        print(f"  {label:7s} broadband {q(bb)}; worst octave >= 1 kHz {q(ob)}; knots {np.mean([g[2] for g in got]):.0f}, "
              f"{np.median([g[3] for g in got]) * 1e3:.0f} ms per source (simulate + render)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bank", help="bank to use (default: a TAU-shaped synthetic FOA bank)")
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--brute-seconds", type=float, default=2.0)
    ap.add_argument("--repeats", type=int, default=3, help="runs per measurement; medians are reported")
    ap.add_argument("--sections", default="speed,ab,against,stft,accuracy,ripple,planned",
                    help="comma-separated: speed, ab, against, stft, accuracy, ripple, planned (default: all)")
    ap.add_argument("--against", default="7d1f69f", help="against: the commit whose renderer to time")
    ap.add_argument("--preset", default="demo", help="planned: the preset whose rooms the line passes are planned in")
    ap.add_argument("--planned", type=int, default=12, help="planned: scenes per format")
    args = ap.parse_args()
    sections = set(args.sections.split(","))
    prepare_worker()  # as every render worker is set up (one thread, freed memory reused)
    if sections & {"speed", "ab", "against", "stft", "accuracy"}:
        bank_sections(args, sections)
    if "ripple" in sections:
        ripple_section()
    if "planned" in sections:
        planned_section(args.preset, args.planned)


def bank_sections(args, sections):
    with tempfile.TemporaryDirectory() as tmp:
        path = args.bank or tau_shaped_bank(os.path.join(tmp, "bank.h5"))
        bank = open_bank(path)
        bank.require_fs(FS)
        print(f"bank: {bank.source} ({bank.format}, {bank.fs} Hz, {bank.summary()['rirs']} RIRs, "
              f"L = {bank.read(bank.rooms[0], bank.trajectories(bank.rooms[0])[0].id, [0]).shape[-1]})")
        room = bank.rooms[0]
        lines = "lines" if "lines" in bank.rooms else None
        if "speed" in sections:
            runs = [("static", False, room), ("moving (circles)", True, room)]
            if lines:
                runs.append(("moving (lines)", True, lines))
            for label, moving, r in runs:
                rate, ms = scenes_per_second(bank, args.scenes, moving, args.repeats, r)
                parts = ", ".join(f"{k} {v:.1f}" for k, v in ms.items())
                print(f"{label} 2-source 10 s FOA scenes: {rate:6.1f} scenes/s per core (goal >= 20); "
                      f"ms per scene: {parts}")
        if "ab" in sections:
            for label, r in (("circles", room), ("lines", lines)):
                if r:
                    ratio, t_new, t_old = paired_ratio(
                        bank, r, lambda x, h, t: render_moving(x, h, t, FS),
                        lambda x, h, t: render_moving(x, h, t, FS, delays=None), rounds=max(3, args.repeats + 2))
                    print(f"delay-aware vs plain crossfade, one 10 s moving FOA source ({label}): {t_new:.1f} vs "
                          f"{t_old:.1f} ms, paired ratio {ratio:.3f}")

        if "against" in sections:
            try:
                other = renderer_at(args.against)
            except Exception as exc:  # no git, or no such commit here
                print(f"against {args.against}: skipped ({str(exc).strip().splitlines()[-1] if str(exc).strip() else exc})")
            else:
                for label, r in (("circles", room), ("lines", lines)):
                    if r:
                        ratio, t_new, t_old = paired_ratio(
                            bank, r, lambda x, h, t: render_moving(x, h, t, FS),
                            lambda x, h, t: other.render_moving(x, h, t, FS), rounds=3, walks=12, seed=5)
                        print(f"this renderer vs {args.against}'s, one 10 s moving FOA source ({label}): {t_new:.1f} vs "
                              f"{t_old:.1f} ms, paired ratio {ratio:.3f}")

        rng = np.random.default_rng(2)
        tid, idx, times = sample_bank_path(bank, room, rng, 10.0, 20.0, direction=1)
        rirs = bank.read(room, tid, idx)
        x = rng.standard_normal(10 * FS).astype(np.float32)
        if "stft" in sections:
            laps = []
            for _ in range(max(3, 2 * args.repeats + 1)):
                t0 = time.process_time()
                ours = render_moving(x, rirs, times, FS)
                laps.append(time.process_time() - t0)
            t_ours = float(np.median(laps))
            t0 = time.process_time()
            ref = stft_reference(x, rirs, times, FS)
            t_ref = time.process_time() - t0
            t0 = time.process_time()
            vec = stft_vectorised(x, rirs, times, FS)
            t_vec = time.process_time() - t0
            print(f"moving render, one 10 s source, {len(idx)} knots: ours {t_ours * 1e3:.1f} ms (median), "
                  f"STFT-domain reference {t_ref * 1e3:.0f} ms -> {t_ref / t_ours:.0f}x faster (goal >= 50x); "
                  f"the same vectorised {t_vec * 1e3:.0f} ms -> {t_vec / t_ours:.0f}x "
                  f"(max difference to the reference {np.max(np.abs(vec - ref)):.1e})")

        if "accuracy" in sections:
            # Exactness, on every trajectory of the room (knot spacings differ: a whole number
            # of samples or not, which changes how the renderer's block grid meets the knots).
            n = int(args.brute_seconds * FS)
            for traj in bank.trajectories(room)[:3]:
                w_tid, w_idx, w_times = sample_bank_path(bank, room, rng, 10.0, 20.0, trajectory=traj.id, direction=1)
                keep = w_times <= args.brute_seconds + 0.2
                sub_r, sub_t = bank.read(room, w_tid, w_idx)[keep], w_times[keep]
                t0 = time.process_time()
                bf = brute_force(x[:n], sub_r, sub_t, FS)
                t_bf = time.process_time() - t0
                ours = render_moving(x[:n], sub_r, sub_t, FS)
                ref = stft_reference(x[:n], sub_r, sub_t, FS)
                spacing = np.median(np.diff(sub_t)) * FS
                print(f"accuracy vs brute-force sample-by-sample convolution, trajectory {w_tid} (knots {spacing:.1f} "
                      f"samples apart; {args.brute_seconds:g} s, {t_bf:.1f} s to compute): ours {snr_db(bf, ours):.1f} dB SNR "
                      f"(goal >= 60), STFT-domain reference {snr_db(bf[:, :n], ref):.1f} dB")
            same = np.repeat(rirs[:1], len(rirs), axis=0)
            y_static = render_static(x, rirs[0])
            err = np.max(np.abs(render_moving(x, same, times, FS) - y_static)) / np.max(np.abs(y_static))
            print(f"identical RIRs at every knot vs static convolution: max |difference| = {err:.1e} of the peak")
        bank.close()


def ripple_section():
    print("level ripple at the knot period, white noise, peak to peak dB (plain crossfade -> delay-aware):")
    print(f"{'':32s} {'broadband':>13s} " + " ".join(f"{b:>12d}" for b in BANDS))
    T = int(5.5 * FS)
    for i, (label, rirs, times) in enumerate(ripple_cases()):
        before = knot_ripple(lambda v: render_moving(v, rirs, times, FS, delays=None), times, FS, T)
        after = knot_ripple(lambda v: render_moving(v, rirs, times, FS), times, FS, T)
        cells = [f"{before[b]:4.2f} -> {after[b]:4.2f}" for b in (None,) + BANDS]
        print(f"{label:32s} " + " ".join(f"{c:>13s}" if j == 0 else f"{c:>12s}" for j, c in enumerate(cells)))
        if i == 0:  # what the measure reads for a source that does not move (its noise)
            floor = knot_ripple(lambda v: render_static(v, rirs[len(rirs) // 2]), times, FS, T)
            print(f"{'  (static source: noise floor)':32s} " + " ".join(
                f"{floor[b]:13.2f}" if j == 0 else f"{floor[b]:12.2f}" for j, b in enumerate((None,) + BANDS)))


if __name__ == "__main__":
    main()
