"""Every RIR method on one scale: the direct path of a point r metres away has amplitude
1 / (4π r) (docs/acoustics.md), and pyroomacoustics' limits are reported, not a traceback."""
import numpy as np
import pytest

from tsel_data.acoustics import SOUND_SPEED, simulate_rirs
from tsel_data.errors import GeometryError
from tsel_data.core.geometry import Room, array_to_room
from tsel_data.receivers import ArrayPose

FS = 24000


def _passband_gain(seg: np.ndarray) -> float:
    """Mean magnitude response over 1-6 kHz of a segment holding one impulse: its amplitude,
    whatever the interpolator's band limit near Nyquist or the high-pass near DC."""
    spec = np.abs(np.fft.rfft(seg, 1024))
    f = np.fft.rfftfreq(1024, 1 / FS)
    return float(spec[(f >= 1000) & (f <= 6000)].mean())


@pytest.mark.parametrize("method", ["hybrid", "ism", "pyroomacoustics"])
@pytest.mark.parametrize("dist", [1.0, 2.5])
def test_direct_path_amplitude_is_one_over_4_pi_r(method, dist):
    """The direct path (a window around its arrival, before the first reflection) of a
    source ``dist`` metres in front of a mic4 array, in a room with reflections."""
    room = Room((9.0, 8.0, 4.0), 0.5)
    arr = ArrayPose("mic4", (3.0, 4.0, 2.0), 0.0, 0.1)
    src = np.array([[3.0 + dist, 4.0, 2.0]])
    h = simulate_rirs(room, arr, src, FS, method=method, seed=1).rirs[0].astype(np.float64)
    mics = array_to_room(arr.mics(), arr.centre, arr.yaw)
    for c, m in enumerate(mics):
        r = float(np.linalg.norm(src[0] - m))
        n = int(round(r / SOUND_SPEED * FS))
        # the first reflections (floor, ceiling: 2 m away) arrive > 60 samples later
        gain = _passband_gain(h[c, n - 24 : n + 24])
        assert gain * 4 * np.pi * r == pytest.approx(1.0, rel=0.02), (method, c, gain * 4 * np.pi * r)


def test_pyroomacoustics_scale_is_measured_on_the_installed_version():
    """pyroomacoustics 0.10 gives image sources 1 / r (not 1 / (4π r)): the factor that puts
    it on our scale is measured from the library, so another version cannot be silently
    22 dB off."""
    import pyroomacoustics as pra

    from tsel_data.acoustics.pyroom import pyroom_scale

    scale = pyroom_scale(FS)
    assert scale in (1.0, pytest.approx(1 / (4 * np.pi)))
    if tuple(int(v) for v in pra.__version__.split(".")[:2]) >= (0, 10):
        assert scale == pytest.approx(1 / (4 * np.pi))


def test_pyroomacoustics_rejects_an_rt60_below_sabines_limit():
    """inverse_sabine cannot reach RT60 < 24 ln10 V / (c S); that is a GeometryError (one
    line from the CLI) naming the limit, not pyroomacoustics' bare ValueError."""
    from tsel_data.acoustics.pyroom import sabine_min_rt60

    dims = (12.0, 10.0, 9.0)
    limit = sabine_min_rt60(dims)
    V, S = 12 * 10 * 9, 2 * (12 * 10 + 12 * 9 + 10 * 9)
    assert limit == pytest.approx(24 * np.log(10) * V / (SOUND_SPEED * S))
    arr = ArrayPose("mic4", (6.0, 5.0, 1.5), 0.0, 0.1)
    with pytest.raises(GeometryError, match=r"cannot decay faster than 0\.\d+ s"):
        simulate_rirs(Room(dims, 0.2), arr, np.array([[8.0, 5.0, 1.5]]), FS, method="pyroomacoustics")
    # just above the limit it works, and the other methods have no such limit
    simulate_rirs(Room(dims, round(limit + 0.01, 3)), arr, np.array([[8.0, 5.0, 1.5]]), FS, method="pyroomacoustics")
    for method in ("hybrid", "ism"):
        simulate_rirs(Room(dims, 0.2), arr, np.array([[8.0, 5.0, 1.5]]), FS, method=method)
