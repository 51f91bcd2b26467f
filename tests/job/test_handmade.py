"""One scene by hand (tsel_data.handmade): events placed in the array frame are heard
and labelled where they were put, the scene renders the same bytes twice, and a dataset of
hand-made scenes opens with every reader and tool."""
from __future__ import annotations

import os

import numpy as np
import pytest

from support.signals import lag
from tsel_data.errors import ConfigError, GeometryError
from tsel_data.handmade import Event, build_scene, scene_recipe, write_scenes

C = 343.0


@pytest.fixture(scope="module")
def clips(demo_corpus):
    """Two demo clips at the scenes' rate, active from the start (the first of each list)."""
    import soundfile as sf

    audio = os.path.join(demo_corpus, "audio")
    names = sorted(n for n in os.listdir(audio) if sf.info(os.path.join(audio, n)).samplerate == 24000)
    return [os.path.join(audio, n) for n in names[:2]]


def test_an_event_is_heard_and_labelled_where_it_was_put(clips):
    recipe, scene = build_scene([Event(clips[0], "a dog barks", azimuth=60, distance=1.5),
                                 Event(clips[1], azimuth=-120, distance=2.0, tir_db=-6)],
                                room=(7, 6, 3), rt60=0.2, receiver="mic4", side=0.2, duration=3)
    assert scene.query == "a dog barks" and scene.audio.shape == (4, 3 * 24000)
    for k, (az, dist) in enumerate([(60, 1.5), (-120, 2.0)]):
        np.testing.assert_allclose(scene.azimuth[k], az, atol=1e-4)
        np.testing.assert_allclose(scene.distance[k], dist, atol=1e-4)
        np.testing.assert_allclose(scene.elevation[k], 0.0, atol=1e-4)
    from tsel_data.job.stems import render_stems

    stems, same = render_stems(recipe, scene.audio)
    assert same
    mics = recipe.array.mics()
    for k, az in enumerate((60, -120)):  # each event's arrival across the array: the delays of its direction
        u = np.array([np.cos(np.radians(az)), np.sin(np.radians(az)), 0.0])
        for i, j in ((0, 1), (0, 2), (1, 3)):
            want = (mics[i] - mics[j]) @ u / C * recipe.fs  # b (mic j) lags a (mic i) by this
            got = lag(stems[k, i, :24000], stems[k, j, :24000], 20)
            assert abs(got - want) < 0.6, (k, i, j, got, want)


def test_a_moving_event_follows_its_path_and_the_scene_is_the_same_every_time(clips):
    events = [Event(clips[0], ["a car passes", "traffic"], path=[(0.0, 90, 0, 2.0), (2.0, 0, 0, 2.0)]),
              Event(clips[1], azimuth=180, distance=1.5, start=0.5)]
    recipe, scene = build_scene(events, receiver="foa", duration=2, receivers=["tetra"], seed=3)
    az = scene.azimuth[0]
    assert abs(az[0] - 90) < 5 and abs(az[-1]) < 5 and np.all(np.diff(az) < 0)  # from the left to the front
    assert scene.record.sources[0].captions == ["a car passes", "traffic"] and scene.query == "a car passes"
    assert scene.receivers["tetra"][0].shape == (4, 48000)  # heard in the same pass
    assert not scene.active[1][:4].any()  # the interferer starts 0.5 s in
    again = build_scene(events, receiver="foa", duration=2, receivers=["tetra"], seed=3)[1]
    assert again.audio.tobytes() == scene.audio.tobytes()


def test_hand_made_scenes_are_a_dataset_every_tool_reads(clips, tmp_path, tsel_cli):
    built = [build_scene([Event(clips[0], "a dog barks", azimuth=az), Event(clips[1], azimuth=az + 90)],
                         receiver="foa", duration=2) for az in (-30, 45)]
    out = write_scenes(str(tmp_path / "mine"), built)
    from tsel_data import open_dataset

    with open_dataset(out, "test") as ds:
        assert len(ds) == 2 and [s.scene_id for s in ds] == ["test-000000", "test-000001"]
        for (recipe, scene), stored in zip(built, ds):
            assert stored.audio.tobytes() == scene.audio.tobytes() and stored.record.scene_id == stored.scene_id
            np.testing.assert_array_equal(stored.azimuth, scene.azimuth)
    code, out_text, err = tsel_cli.run("inspect", out, "test-000001")
    assert code == 0 and "az    45.0 deg" in out_text and "az   135.0 deg" in out_text, out_text + err
    assert tsel_cli.run("check", out)[0] == 0
    other = tmp_path / "notmine"
    other.mkdir()
    (other / "keep.txt").write_text("a user's file")
    with pytest.raises(Exception, match="pass --force"):
        write_scenes(str(other), built)
    assert os.listdir(other) == ["keep.txt"]


@pytest.mark.parametrize("events,kw,error,message", [
    (lambda c: [Event(c[0], "x", azimuth=0, distance=9)], {}, GeometryError, r"event 0 \(azimuth 0°, elevation 0°, 9 m"),
    (lambda c: [Event("/nowhere/x.wav", "x")], {}, ConfigError, "event 0: clip /nowhere/x.wav not found"),
    (lambda c: [Event(c[0])], {}, ConfigError, "the target .* needs a caption"),
    (lambda c: [Event(c[0], "x")], {"receiver": "tetrahedron9"}, ConfigError, "unknown receiver"),
    (lambda c: [Event(c[0], "x", distance=0)], {}, GeometryError, "distance 0"),
])
def test_what_cannot_be_built_is_one_line(clips, events, kw, error, message):
    with pytest.raises(error, match=message) as e:
        scene_recipe(events(clips), **kw)
    assert "\n" not in str(e.value)
