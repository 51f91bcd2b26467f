"""Every image source of a simulated moving source moves continuously (issue 22.4): the
image-source part of a path, rendered as the toolkit renders it (knots by
placement.knot_hop, image groups each aligned by its own delay), against a dense
physical reference (RIRs every 0.5 ms, input-side crossfade, direct convolution:
acoustics/reference.py). One warp for all images, as before the groups, is the control."""
import math

import numpy as np
import pytest

from tsel_data.acoustics.image_paths import GROUPS
from tsel_data.acoustics.reference import dense_image, image_part_timing
from tsel_data.acoustics.shoebox import shoebox_rirs
from tsel_data.choices import PathKind
from tsel_data.core.geometry import Room
from tsel_data.plan.placement import knot_hop
from tsel_data.receivers import ArrayPose
from tsel_data.render.mix import moving_image_part

FS = 24000
DUR = 1.2


def _line(centre, r, v, height, t_close):
    def pos(t):
        t = np.asarray(t, dtype=np.float64)
        return np.stack([centre[0] + v * (t - t_close), np.full_like(t, centre[1] + r), np.full_like(t, height)], -1)
    return pos


def _arc(centre, r, speed, height):
    def pos(t):
        a = np.radians(90.0 + speed * (np.asarray(t, dtype=np.float64) - DUR / 2))
        return np.stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a), np.full_like(a, height)], -1)
    return pos


CASES = {
    # (room dims, RT60), receiver, path kind, speed °/s, closest distance, path
    "mic4 line 40°/s": (((7.0, 6.0, 3.0), 0.7), ("mic4", (3.5, 2.0, 1.2), 0.12), PathKind.LINE, 40.0, 2.0,
                        lambda c: _line(c, 2.0, math.radians(40.0) * 2.0, 1.5, DUR / 2)),
    # near a side wall and under a low ceiling, where reflections carry most of the early energy
    "foa line 40°/s by a wall": (((6.0, 4.0, 2.6), 0.6), ("foa", (3.0, 1.2, 1.3), None), PathKind.LINE, 40.0, 2.2,
                                 lambda c: _line(c, 2.2, math.radians(40.0) * 2.2, 1.6, DUR / 2)),
    "mic4 arc 40°/s": (((7.0, 6.0, 3.0), 0.7), ("mic4", (3.5, 2.5, 1.2), 0.12), PathKind.ARC, 40.0, 2.0,
                       lambda c: _arc(c, 2.0, 40.0, 1.2)),
    # arcs in the demo preset's two smallest rooms (seed 0), where side walls are near
    "mic4 arc 40°/s, small tall room": (((5.49, 5.19, 8.55), 0.67), ("mic4", (2.745, 2.095, 1.2), 0.12), PathKind.ARC,
                                        40.0, 2.0, lambda c: _arc(c, 2.0, 40.0, 1.5)),
    "mic4 arc 40°/s, small long room": (((5.28, 8.42, 5.54), 1.0), ("mic4", (2.64, 3.71, 1.2), 0.12), PathKind.ARC,
                                        40.0, 2.0, lambda c: _arc(c, 2.0, 40.0, 1.5)),
}


def _snr(ref, y):
    return 10 * np.log10(np.sum(ref**2) / np.sum((ref - y) ** 2))


@pytest.fixture(scope="module")
def pink():
    rng = np.random.default_rng(7)
    w = np.fft.rfft(rng.standard_normal(int(DUR * FS)))
    f = np.fft.rfftfreq(int(DUR * FS), 1 / FS)
    x = np.fft.irfft(w / np.sqrt(np.maximum(f, 20.0)), int(DUR * FS))
    return (x / x.std()).astype(np.float32)


@pytest.mark.parametrize("case", list(CASES))
def test_reflections_of_a_moving_source_move_with_it(case, pink):
    (dims, rt60), (fmt, centre, side), kind, speed, r, path = CASES[case]
    room, array = Room(dims, rt60), ArrayPose(fmt, centre, 0.0, side)
    pos = path(centre)
    hop = knot_hop(kind, speed, r, r)
    knots = np.arange(0.0, DUR + hop, hop)
    timing = image_part_timing(pos(knots), centre, rt60)
    ref = dense_image(room, array, pos, pink, FS, timing=timing)

    def rendered(groups):  # as render.path_image: the knots at once, the DC blocker after the render
        rs = shoebox_rirs(room, array, pos(knots), FS, one_source=True, tail_apart=True, groups=groups,
                          transition=timing[0], length=timing[1], image_highpass=False)
        return moving_image_part(pink, rs, knots, FS)[:, :len(pink)]

    now, one_warp = _snr(ref, rendered(GROUPS)), _snr(ref, rendered(1))
    assert now >= 20.0, (case, now, one_warp)
    assert now >= one_warp + 4.0, (case, now, one_warp)  # the groups, not the knots, make the difference
