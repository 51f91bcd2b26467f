"""A lean start-up and a lean scene (issue 25): what a process imports, and the faster
paths computing the same numbers as the ones they replaced."""
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from tsel_data.acoustics import highpass
from tsel_data.corpus.audio import active_rms, frame_activity, frame_energy
from tsel_data.core.geometry import Room
from tsel_data.receivers import ArrayPose
from tsel_data.scene.recipe import SceneRecipe, Source
from tsel_data.render.mix import convolve, spatial_images

HEAVY = ("numpy", "scipy", "h5py", "soundfile", "ducc0", "pyroomacoustics", "matplotlib", "dask", "torch")


def _loaded_after(code: str) -> set[str]:
    """Top-level packages in sys.modules after ``code`` ran in a fresh interpreter."""
    probe = textwrap.dedent(code) + "\nimport sys\nprint(' '.join(sorted({m.split('.')[0] for m in sys.modules})))\n"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(done.stdout.split())


def _tsel(*args: str) -> str:
    return f"""
import sys
sys.argv = ["tsel", *{list(args)!r}]
from tsel_data.cli import main
try:
    main()
except SystemExit:
    pass
"""


# --- start-up -------------------------------------------------------------------------
def test_tsel_version_imports_no_library():
    assert not _loaded_after(_tsel("--version")) & set(HEAVY)


@pytest.mark.parametrize("args", [("--help",), ("generate", "--help"), ("check", "--help")])
def test_help_loads_no_scipy_nor_audio_libraries(args):
    assert not _loaded_after(_tsel(*args)) & {"scipy", "soundfile", "h5py", "pyroomacoustics", "matplotlib", "dask",
                                             "torch"}


def test_every_command_is_listed_and_found():
    from tsel_data.cli import COMMANDS, cli

    import click

    ctx = click.Context(cli)
    assert cli.list_commands(ctx) == sorted(COMMANDS)
    for name in COMMANDS:
        assert cli.get_command(ctx, name).name == name
    assert cli.get_command(ctx, "no-such-command") is None


def test_a_simulated_scene_renders_without_scipy_signal_nor_scipy_fft(tmp_path):
    """The shoebox simulator's DC blocker no longer pulls in scipy.signal (only a clip at
    another rate does, to resample), and its filter runs in scipy's compiled loop; the
    simulators' real FFTs run in scipy's compiled pocketfft without scipy.fft, scipy.special
    or scipy's array-API layer."""
    code = f"""
    import numpy as np, soundfile as sf
    from tsel_data.acoustics.highpass import _compiled_loop
    from tsel_data.core.geometry import Room
    from tsel_data.receivers import ArrayPose
    from tsel_data.scene.recipe import SceneRecipe, Source
    from tsel_data.render.mix import render_scene
    sf.write({str(tmp_path / "x.wav")!r}, np.random.default_rng(0).standard_normal(24000).astype(np.float32) * 0.1, 24000)
    src = Source("target", "c", {str(tmp_path / "x.wav")!r}, ("noise",), position=(3.0, 2.0, 1.5))
    recipe = SceneRecipe("s-0", "test", 0, 1, "two-directional", "noise", ArrayPose("mic4", (2.0, 2.5, 1.2), 10.0, 0.1),
                         (src,), Room((5.0, 4.0, 3.0), 0.4), fs=24000, duration=1.0, rir_method="hybrid")
    assert render_scene(recipe).audio.shape == (4, 24000)
    assert _compiled_loop() is not None, "scipy's sosfilt loop was not found where scipy keeps it"
    import sys
    assert not [m for m in sys.modules if m.startswith("scipy.signal") and m != "scipy.signal._sosfilt"], \\
        sorted(m for m in sys.modules if m.startswith("scipy.signal"))
    heavy = [m for m in sys.modules if m.startswith(("scipy.fft", "scipy.special", "scipy._lib._array_api"))]
    assert heavy == ["scipy.fft._pocketfft.pypocketfft"], sorted(m for m in sys.modules if m.startswith("scipy"))
    """
    subprocess.run([sys.executable, "-c", textwrap.dedent(code)], check=True)


# --- the DC blocker without scipy.signal -----------------------------------------------
RATES = [8000, 11025, 16000, 22050, 24000, 32000, 44100, 48000, 88200, 96000, 192000, *range(1000, 200000, 4999)]


def test_butter2_highpass_is_scipys_butter_bit_for_bit():
    from scipy.signal import butter

    for fs in RATES:
        for cutoff in (20.0, 80.0):
            assert np.array_equal(highpass.butter2_highpass(cutoff, fs),
                                  butter(2, cutoff, "highpass", fs=fs, output="sos")), (fs, cutoff)


@pytest.mark.parametrize("compiled", [True, False])
def test_sosfilt_is_scipys_bit_for_bit(monkeypatch, compiled):
    from scipy.signal import sosfilt

    if not compiled:  # another scipy layout: the same numbers through scipy.signal
        monkeypatch.setattr(highpass, "_compiled_loop", lambda: None)
    rng = np.random.default_rng(3)
    sos = highpass.butter2_highpass(20.0, 24000)
    for x in (rng.standard_normal((4, 3000)).astype(np.float32), rng.standard_normal(24000),
              rng.standard_normal((2, 3, 500)).astype(np.float32), rng.standard_normal((1, 1))):
        kept = x.copy()
        got, want = highpass.sosfilt(sos, x), sosfilt(sos, x)
        assert got.dtype == want.dtype and got.shape == want.shape and np.array_equal(got, want)
        assert np.array_equal(x, kept)  # filtered in a copy


# --- scipy.fft's real transforms without scipy.fft -------------------------------------
@pytest.mark.parametrize("compiled", [True, False])
def test_realfft_is_scipy_fft_bit_for_bit(monkeypatch, compiled):
    import scipy.fft

    from tsel_data.dsp import realfft

    if not compiled:  # another scipy layout: the public functions
        monkeypatch.setattr(realfft, "_pocketfft", lambda: None)
    rng = np.random.default_rng(5)
    for n in (1, 2, 99, 512, 4800, 30870, 100003):
        assert realfft.next_fast_len(n, real=True) == scipy.fft.next_fast_len(n, real=True)
        assert realfft.next_fast_len(n) == scipy.fft.next_fast_len(n)
        assert np.array_equal(realfft.rfftfreq(n, 1 / 24000), scipy.fft.rfftfreq(n, 1 / 24000))
        for x in (rng.standard_normal((3, n)).astype(np.float32), rng.standard_normal(n),
                  rng.integers(-5, 5, (2, n)), rng.standard_normal((n, 2)).astype(np.float32)[:, 0]):
            for m in (None, n + 7, max(1, n // 2), scipy.fft.next_fast_len(n, real=True)):
                got, want = realfft.rfft(x, m, axis=-1, workers=1), scipy.fft.rfft(x, m, axis=-1, workers=1)
                assert got.dtype == want.dtype and got.shape == want.shape and np.array_equal(got, want), (n, m)
                back_n = m or n
                got, want = realfft.irfft(want, back_n, axis=-1), scipy.fft.irfft(want, back_n, axis=-1)
                assert got.dtype == want.dtype and got.shape == want.shape and np.array_equal(got, want), (n, m)
    x = rng.standard_normal((4, 6))
    assert np.array_equal(realfft.rfft(x, axis=0), scipy.fft.rfft(x, axis=0))
    assert np.array_equal(realfft.irfft(realfft.rfft(x, axis=0), 4, axis=0), scipy.fft.irfft(scipy.fft.rfft(x, axis=0), 4,
                                                                                             axis=0))
    with pytest.raises(ValueError):
        realfft.rfft(np.zeros(0))
    with pytest.raises(TypeError):
        realfft.rfft(np.zeros(4, complex))


# --- levels and activity ---------------------------------------------------------------
def _clip(rng, n):
    """Loud and very quiet stretches (a running sum loses the quiet ones' digits)."""
    env = np.repeat(10.0 ** rng.uniform(-6, 0, -(-n // 1000)), 1000)[:n]
    return (rng.standard_normal(n) * env).astype(np.float32)


@pytest.mark.parametrize("fs,hop,n,frames", [(24000, 0.1, 24000, 10), (22050, 0.05, 22050, 20),
                                             (44100, 0.1, 30000, 10), (16000, 0.1, 16000, 12)])
def test_frame_energy_is_each_frames_mean_power(fs, hop, n, frames):
    x = _clip(np.random.default_rng(n), n)
    edges = np.minimum(np.round(np.arange(frames + 1) * hop * fs).astype(int), n)
    want = [math.fsum(float(v) ** 2 for v in x[a:b]) / max(b - a, 1) for a, b in zip(edges[:-1], edges[1:])]
    np.testing.assert_allclose(frame_energy(x, fs, hop, frames), want, rtol=1e-12, atol=0)
    active = frame_activity(x, fs, hop, frames, -30.0)
    assert np.array_equal(active, 10 * np.log10(np.maximum(want, 1e-12) / max(want)) >= -30.0)


def _masked_rms(x, active, fs, hop):
    """The level as it was computed before: the active frames' samples through a mask."""
    n_frames = len(active)
    edges = np.minimum(np.round(np.arange(n_frames + 1) * hop * fs).astype(int), x.shape[-1])
    mask = np.zeros(x.shape[-1], dtype=bool)
    for k in np.flatnonzero(active) if active.any() else range(n_frames):
        mask[edges[k]:edges[k + 1]] = True
    return float(np.sqrt(np.mean(x[..., mask].astype(np.float64) ** 2))) if mask.any() else 0.0


def test_active_rms_is_the_masked_level_bit_for_bit():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((4, 24000)).astype(np.float32)
    patterns = [rng.random(10) < p for p in (0.2, 0.5, 0.8)] + [np.ones(10, bool), np.zeros(10, bool),
                                                                 np.r_[np.zeros(9, bool), True]]
    for active in patterns:
        for part in (x, x[:1], x[:, :15000], x[2:3, :100]):
            assert active_rms(part, active, 24000, 0.1) == _masked_rms(part, active, 24000, 0.1)


# --- the scene's buffers --------------------------------------------------------------
def test_convolve_into_rows_equals_convolve():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((2, 3000)).astype(np.float32)
    h = rng.standard_normal((2, 4, 700)).astype(np.float32)
    out = np.full((3, 4, 5000), np.nan, dtype=np.float32)
    convolve(list(x), h, 5000, out=[out[2], out[0]])
    want = convolve(x, h, 5000)
    assert np.array_equal(out[2], want[0]) and np.array_equal(out[0], want[1]) and np.all(np.isnan(out[1]))


def test_every_channel_of_every_image_is_written():
    """The images buffer starts uninitialised: an additive source on FOA is W alone and
    Y, Z, X are exact zeros."""
    rng = np.random.default_rng(2)
    src = Source("target", "c", "x.wav", ("noise",), position=(3.0, 2.0, 1.5))
    other = Source("interferer", "d", "y.wav", ("other",), spatial="additive", tir_db=0.0)
    recipe = SceneRecipe("s-0", "test", 0, 1, "directional+additive", "noise", ArrayPose("foa", (2.0, 2.5, 1.2), 0.0),
                         (src, other), Room((5.0, 4.0, 3.0), 0.4), fs=8000, duration=0.5)
    dry = rng.standard_normal((2, 4000)).astype(np.float32)
    for _ in range(3):  # freed buffers come back holding the previous scene's samples
        images, _ = spatial_images(recipe, dry)
        assert np.array_equal(images[1, 0], dry[1]) and not np.any(images[1, 1:])
        assert np.all(np.isfinite(images)) and np.any(images[0, 1:])
