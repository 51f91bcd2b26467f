"""Acoustic descriptors of a source as rendered (acoustics/descriptors.py): exact on
responses built by hand, and physically sound on simulated rooms (DRR and C50 fall with
distance, the octave-band T30 agree with the room's)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import spearmanr

from tsel_data.acoustics import simulate_rirs
from tsel_data.acoustics.descriptors import DIRECT_WINDOW, describe_rir
from tsel_data.core.geometry import Room, array_to_room, sph_to_cart
from tsel_data.receivers import ArrayPose

FS = 24000


def test_a_response_built_by_hand_gives_its_numbers():
    """A unit direct impulse at 10 ms, then an exponential tail of known energy and decay
    that starts after the direct window: DRR, C50 and T30 are what it was made with."""
    t60, n = 0.8, 2 * FS
    rng = np.random.default_rng(0)
    t = np.arange(n) / FS
    start = int(0.010 * FS) + int(DIRECT_WINDOW * FS) + 1
    tail = rng.standard_normal(n) * 10 ** (-3 * t / t60)  # -60 dB of amplitude at t60
    tail[:start] = 0
    tail *= np.sqrt(0.25 / np.sum(tail ** 2))  # reverberant energy 0.25: DRR +6.02 dB
    h = tail.copy()
    h[int(0.010 * FS)] = 1.0
    d = describe_rir(np.stack([h, h]), FS)  # two identical channels: the same ratios
    assert d["drr_db"] == pytest.approx(6.02, abs=0.01)
    t0 = int(0.010 * FS)
    early = 1 + np.sum(tail[: t0 + int(0.05 * FS)] ** 2)
    assert d["c50_db"] == pytest.approx(10 * np.log10(early / (1.25 - early)), abs=0.01)
    assert d["t30_s"] == pytest.approx(t60, rel=0.03)
    assert set(d["t30_bands_s"]) == {"125", "250", "500", "1000", "2000", "4000"}  # 8k's edge is above 0.9 fs/2
    for band, t30 in d["t30_bands_s"].items():
        assert t30 == pytest.approx(t60, rel=0.1), band  # white decay: every band decays alike


def test_an_anechoic_response_has_no_drr_or_decay():
    h = np.zeros((1, FS))
    h[0, 100] = 1.0
    d = describe_rir(h, FS)
    assert d["drr_db"] is None and d["c50_db"] is None and d["t30_s"] is None


def _room_descriptors(dims, rt60, distances, seed=0):
    room = Room(dims, rt60)
    centre = np.array(dims) / 2
    pose = ArrayPose("mic4", tuple(centre), 0.0, 0.1)
    pts = np.array([array_to_room(sph_to_cart(40.0, 0.0, r), centre, 0.0) for r in distances])
    rs = simulate_rirs(room, pose, pts, FS, seed=seed)
    return [describe_rir(r, FS) for r in rs.rirs], rs.rt60_measured


@pytest.mark.parametrize("dims,rt60", [((8.0, 6.0, 3.0), 0.6), ((12.0, 9.0, 4.0), 1.0)])
def test_drr_and_c50_fall_with_distance_and_band_t30_is_the_rooms(dims, rt60):
    distances = np.linspace(0.5, 2.8, 8)
    described, measured = _room_descriptors(dims, rt60, distances)
    drr = [d["drr_db"] for d in described]
    c50 = [d["c50_db"] for d in described]
    assert spearmanr(distances, drr)[0] < -0.95 and spearmanr(distances, c50)[0] < -0.8, (drr, c50)
    assert drr[0] > 0 > drr[-1]  # nearer than the critical distance, then beyond it
    # the room's measured RT60 is the T30 of the first point's omni response (acoustics/simulate.py)
    first = described[0]
    assert first["t30_s"] == pytest.approx(measured, rel=0.03)
    for band in ("500", "1000", "2000", "4000"):
        assert first["t30_bands_s"][band] == pytest.approx(measured, rel=0.1), (band, first, measured)
    for d in described:  # elsewhere in the room: the bands decay as the whole response does
        for band in ("500", "1000", "2000", "4000"):
            assert d["t30_bands_s"][band] == pytest.approx(d["t30_s"], rel=0.1), (band, d)
        assert d["t30_s"] == pytest.approx(rt60, rel=0.15)
