"""Motion classes decided on the labels (scene/motion.py), and in the records of rendered
scenes that moved as their paths say."""
from __future__ import annotations

import numpy as np
import pytest

from tsel_data.scene.motion import CHANGE_M, motion_class

F = 40
ON = np.ones(F, bool)


def labels(az, dist, el=0.0):
    return np.broadcast_to(np.asarray(az, float), (F,)), np.full(F, el), np.broadcast_to(np.asarray(dist, float), (F,))


@pytest.mark.parametrize("az,dist,want", [
    (30.0, 2.0, "stationary"),
    (30.0, np.linspace(3.0, 1.0, F), "approaching"),
    (30.0, np.linspace(1.0, 3.0, F), "receding"),
    (np.degrees(np.arctan2(np.linspace(-2, 2, F), 1.0)), np.hypot(np.linspace(-2, 2, F), 1.0), "passing"),
    (np.linspace(90.0, -90.0, F), 2.0, "circling"),
    (np.linspace(30.0, 40.0, F), 2.0, "circling"),  # a few degrees sideways at the same distance
])
def test_each_class_from_its_labels(az, dist, want):
    assert motion_class(*labels(az, dist), ON) == want


def test_only_the_frames_it_sounds_in_count():
    az, el, d = labels(30.0, np.r_[np.full(F // 2, 1.0), np.linspace(1.0, 3.0, F // 2)])
    heard = np.r_[np.ones(F // 2, bool), np.zeros(F // 2, bool)]
    assert motion_class(az, el, d, ON) == "receding" and motion_class(az, el, d, heard) == "stationary"
    assert motion_class(az, el, d, np.eye(1, F, 3, dtype=bool)[0]) is None  # heard in one frame
    nan = np.full(F, np.nan)
    assert motion_class(nan, nan, nan, ON) is None  # positionless


def test_a_change_of_distance_below_the_threshold_is_not_approaching():
    az, el, d = labels(30.0, np.linspace(2.0, 2.0 - 0.9 * CHANGE_M, F))
    assert motion_class(az, el, d, ON) == "circling"


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """Steady noise, heard in every frame: the class is the whole path's."""
    import soundfile as sf

    path = str(tmp_path_factory.mktemp("clip") / "steady.wav")
    sf.write(path, 0.1 * np.random.default_rng(0).standard_normal(2 * 24000).astype(np.float32), 24000)
    return path


@pytest.mark.parametrize("path,want", [
    ([(0.0, 30, 0, 2.5), (2.0, 30, 0, 1.0)], "approaching"),
    ([(0.0, 30, 0, 1.0), (2.0, 30, 0, 2.5)], "receding"),
    ([(0.0, 80, 0, 2.0), (2.0, -80, 0, 2.0)], "passing"),  # a straight line: nearest in the middle
])
def test_a_rendered_scene_records_how_its_source_moved(clip, path, want):
    from tsel_data.handmade import Event, build_scene

    _, scene = build_scene([Event(clip, "x", path=path), Event(clip, azimuth=180)], duration=2.0, rt60=0.3)
    src = scene.record.sources[0]
    assert src.motion == want == motion_class(scene.azimuth[0], scene.elevation[0], scene.distance[0],
                                              scene.active[0])
    assert scene.record.sources[1].motion == "stationary"
