"""Channel-swap augmentation (tsel_data.augment): each receiver's symmetries, checked from
the audio: for every transform, a classical localizer on the transformed audio of an
anechoic scene finds the transformed label (FOA: the intensity vector; tetra on its rigid
sphere and mic4: SRP-PHAT); the identity is bit-exact; receivers without symmetries are
refused in one line; the reader's options draw transforms per (seed, epoch, index)."""
from __future__ import annotations

import numpy as np
import pytest

from support.datasets import make_dataset
from tsel_data.acoustics.shoebox import shoebox_rirs
from tsel_data.acoustics.sphere import rigid_sphere_delay
from tsel_data.augment import channel_swaps, random_swap, swap_scene
from tsel_data.core.geometry import SOUND_SPEED, Room, array_to_room, azimuth_difference, sph_to_cart
from tsel_data.dsp.features import mic_pairs
from tsel_data.errors import TselError
from tsel_data.receivers import ArrayPose

FS = 24000
FREE = Room((30.0, 30.0, 30.0), 0.5)  # with max_order = 0: the free field
CENTRE = (15.0, 15.0, 15.0)
DIRECTIONS = ((30.0, 20.0), (-110.0, -25.0), (160.0, 12.0))


def _anechoic(pose, az, el, seconds=0.5):
    """White noise from (az, el), 2 m away, as ``pose`` hears it in the free field: [C, T]."""
    pt = array_to_room(sph_to_cart(az, el, 2.0), pose.centre, pose.yaw)[None]
    h = shoebox_rirs(FREE, pose, pt, FS, max_order=0).rirs[0].astype(np.float64)
    x = np.random.default_rng([int(abs(az)), int(abs(el))]).standard_normal(int(seconds * FS))
    return np.stack([np.convolve(x, hc)[: len(x)] for hc in h]).astype(np.float32)


def _intensity(audio) -> tuple[float, float]:
    """FOA (W, Y, Z, X): the direction of the mean active intensity Re{W* [X, Y, Z]}."""
    spec = np.fft.rfft(audio.astype(np.float64), axis=-1)
    i = [np.sum(np.real(np.conj(spec[0]) * spec[ch])) for ch in (3, 1, 2)]
    return float(np.degrees(np.arctan2(i[1], i[0]))), float(np.degrees(np.arctan2(i[2], np.hypot(i[0], i[1]))))


def _srp(audio, mics, sphere: float | None = None, up: int = 16) -> tuple[float, float]:
    """SRP-PHAT over a 1° grid of azimuth and elevation (elevation >= 0 for a planar array),
    steered at free-field delays or a rigid sphere's (as tsel verify): each pair's GCC-PHAT
    (200 Hz - 8 kHz, 1/up sample) read at the pair's delay for each direction."""
    n = audio.shape[-1]
    spec = np.fft.rfft(audio.astype(np.float64), axis=-1)
    f = np.fft.rfftfreq(n, 1 / FS)
    pairs = np.array(mic_pairs(len(mics)))
    cross = spec[pairs[:, 0]] * np.conj(spec[pairs[:, 1]])
    cross = np.where((f > 200) & (f < 8000), cross / (np.abs(cross) + 1e-20), 0.0)
    gcc = np.fft.irfft(cross, n * up, axis=-1)  # lag τ at index τ·fs·up mod n·up
    planar = np.ptp(mics[:, 2]) < 1e-9
    az, el = np.meshgrid(np.arange(-180.0, 180.0), np.arange(0.0 if planar else -60.0, 61.0))
    u = sph_to_cart(az, el, 1.0).reshape(-1, 3)
    if sphere:
        normals = mics / np.linalg.norm(mics, axis=1, keepdims=True)
        grid = np.linspace(-1.0, 1.0, 721)
        delay = np.interp(u @ normals.T, grid, rigid_sphere_delay(grid, sphere))  # [G, C] s
    else:
        delay = -(u @ mics.T) / SOUND_SPEED  # a mic nearer the source hears it earlier
    power = np.zeros(len(u))
    for p, (a, b) in enumerate(pairs):
        power += gcc[p, np.rint((delay[:, a] - delay[:, b]) * FS * up).astype(int) % (n * up)]
    k = int(np.argmax(power))
    return float(az.reshape(-1)[k]), float(el.reshape(-1)[k])


@pytest.mark.parametrize("fmt, count", [("foa", 16), ("tetra", 8), ("mic4", 8)])
def test_every_transform_is_heard_where_its_labels_say(fmt, count):
    """Anechoic scenes: for each of the receiver's transforms and each direction, the
    localizer on the transformed audio finds the transformed label (azimuth within 2°,
    elevation within 3°; a planar array's elevation is not heard); the identity gives the
    audio back bit for bit."""
    pose = ArrayPose(fmt, CENTRE, 0.0, 0.11 if fmt == "mic4" else None, baffle="rigid" if fmt == "tetra" else None)
    swaps = channel_swaps(fmt, pose.mics())
    assert len(swaps) == count and swaps[0].identity
    mics = pose.mics()
    for az, el in DIRECTIONS:
        audio = _anechoic(pose, az, el)
        for sw in swaps:
            moved = sw.audio(audio)
            if sw.identity:
                assert moved is audio
            want_az, want_el = (float(v) for v in sw.labels(np.float32(az), np.float32(el)))
            got_az, got_el = _intensity(moved) if fmt == "foa" else _srp(moved, mics, 0.042 if fmt == "tetra" else None)
            assert azimuth_difference(got_az, want_az) <= 2.0, (sw.name, az, el, got_az, want_az)
            if fmt != "mic4":
                assert abs(got_el - want_el) <= 3.0, (sw.name, az, el, got_el, want_el)


def test_the_tables_are_the_receivers_symmetries():
    names = {fmt: [s.name for s in channel_swaps(fmt)] for fmt in ("foa", "tetra", "mic4", "linear8", "stereo")}
    assert names["tetra"] == ["az", "az+180", "-az+90", "-az-90", "az+90 -el", "az-90 -el", "-az -el", "-az+180 -el"]
    assert names["mic4"] == ["az", "az+90", "az+180", "az-90", "-az", "-az+90", "-az+180", "-az-90"]
    assert len(set(names["foa"])) == 16 and len(names["linear8"]) == len(names["stereo"]) == 2
    foa = {s.name: s for s in channel_swaps("foa")}
    # φ → φ + 90°: Y' = X, X' = -Y (ACN W, Y, Z, X); θ → -θ: Z' = -Z
    assert foa["az+90"].order == (0, 3, 2, 1) and foa["az+90"].signs == (1, 1, 1, -1)
    assert foa["az -el"].order == (0, 1, 2, 3) and foa["az -el"].signs == (1, 1, -1, 1)
    # a custom 6-mic circle keeps what of the 16 maps a hexagon onto itself
    circle = [(0.05 * np.cos(np.radians(a)), 0.05 * np.sin(np.radians(a)), 0.0) for a in range(0, 360, 60)]
    assert [s.name for s in channel_swaps("custom", circle)] == ["az", "az+180", "-az", "-az+180"]
    # ... unless its cardioids point the same way: then only the mirror that keeps their axes
    assert [s.name for s in channel_swaps("custom", circle, ["cardioid"] * 6, [(0.0, 0.0)] * 6)] == ["az", "-az"]


@pytest.mark.parametrize("fmt, why", [("em32", "no channel-swap symmetry besides the identity"),
                                      ("binaural", "a measured head is not exactly symmetric")])
def test_a_receiver_without_symmetries_says_so_in_one_line(fmt, why):
    with pytest.raises(TselError, match=why) as e:
        channel_swaps(fmt)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("fmt", ["foa", "tetra", "mic4"])
def test_a_swapped_scene_keeps_its_labels_with_its_audio(tmp_path, fmt):
    """A stored scene through each transform: its labels (and its record's) move as the
    transform says, NaN labels stay NaN, the audio's channels are the permuted ones, and
    random_swap draws per (seed, epoch, index)."""
    from tsel_data.store.reader import open_dataset

    make_dataset(tmp_path, fmt=fmt, splits={"train": 2}, additive={"train-000001"}, seed=2)
    with open_dataset(tmp_path, "train") as ds:
        for i in range(2):
            s = ds[i]
            for sw in channel_swaps(fmt, s.mic_positions):
                t = swap_scene(s, sw)
                if sw.identity:  # bit for bit: the very arrays
                    assert t.audio is s.audio and t.azimuth is s.azimuth and t.channel_swap == "az"
                    continue
                assert t.channel_swap == sw.name and t.audio.dtype == s.audio.dtype
                np.testing.assert_array_equal(np.abs(t.audio), np.abs(s.audio[list(sw.order)]))
                u = sph_to_cart(s.azimuth.astype(np.float64), s.elevation.astype(np.float64), 1.0) @ sw.matrix.T
                v = sph_to_cart(t.azimuth.astype(np.float64), t.elevation.astype(np.float64), 1.0)
                ok = np.isfinite(s.azimuth)
                np.testing.assert_allclose(v[ok], u[ok], atol=1e-5)
                assert np.array_equal(np.isnan(t.azimuth), np.isnan(s.azimuth))
                np.testing.assert_allclose(t.record.sources[0].labels("azimuth"), t.azimuth[0], atol=2e-3)
            a, sw_a = random_swap(s, 7, 3, i)
            b, sw_b = random_swap(s, 7, 3, i)
            assert sw_a == sw_b and np.array_equal(a.audio, b.audio)
        drawn = {random_swap(ds[0], 7, e, 0)[1].name for e in range(40)}
        assert len(drawn) > 4  # epochs draw different transforms


def test_the_torch_dataset_and_the_stream_swap_channels(tmp_path):
    """``channel_swap=True``: each item is its scene through the transform drawn for (seed,
    epoch, index), named in the item; the streaming reader draws the same one for the same
    scene; a receiver without symmetries is refused when the dataset is made."""
    torch = pytest.importorskip("torch")
    from tsel_data.export import export
    from tsel_data.store.reader import open_dataset
    from tsel_data.torch import Dataset, StreamingDataset

    make_dataset(tmp_path / "ds", fmt="foa", splits={"train": 4}, seed=5)
    plain, swapped = Dataset(str(tmp_path / "ds"), "train"), Dataset(str(tmp_path / "ds"), "train", channel_swap=True)
    assert "channel_swap" not in plain[0]
    with open_dataset(tmp_path / "ds", "train") as ds:
        for e in (0, 1):
            swapped.set_epoch(e)
            for i in range(4):
                item = swapped[i]
                want, sw = random_swap(ds[i], ds.seed, e, i)
                assert item["channel_swap"] == sw.name
                assert torch.equal(item["audio"], torch.from_numpy(want.audio))
                assert torch.equal(item["azimuth"], torch.from_numpy(want.azimuth))
    export("webdataset", str(tmp_path / "ds"), str(tmp_path / "wds"), card=False)
    stream = StreamingDataset(str(tmp_path / "wds"), "train", seed=swapped.scenes.seed, channel_swap=True)
    stream.set_epoch(1)
    got = {it["scene_id"]: it["channel_swap"] for it in stream}
    assert got == {f"train-00000{i}": swapped[(1, i)]["channel_swap"] for i in range(4)}
