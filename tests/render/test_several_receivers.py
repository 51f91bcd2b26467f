"""One scene heard by several receivers in one pass (``scene.receivers``): same room,
sources, clips and gains, labels identical in each receiver's frame, each receiver's
audio in its own part of the shard, readable and checkable per receiver."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tsel_data.corpus.audio import active_rms, db
from tsel_data.errors import ConfigError, DatasetError

RECEIVERS = ["foa", "tetra", "respeaker-6"]


@pytest.fixture
def made(generated_dataset):
    return generated_dataset("several-receivers").out


def test_each_receiver_reads_back_with_its_channels_and_the_same_labels(made):
    from tsel_data import open_dataset

    first = open_dataset(made, "train")
    assert first.format == "mic4" and first.doc.receiver_names() == ["mic4", *RECEIVERS]
    for name, channels in (("foa", 4), ("tetra", 4), ("respeaker-6", 6)):
        ds = open_dataset(made, "train", receiver=name)
        assert ds.format == name and len(ds.channel_names) == channels
        for i in range(len(ds)):
            a, b = first[i], ds[i]
            assert b.audio.shape == (channels, a.audio.shape[1]) and b.format == name
            assert b.mic_positions.shape == (channels, 3)
            for key in ("azimuth", "elevation", "distance", "active"):
                np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
            assert not np.allclose(b.audio[:, :1000], 0)  # every receiver heard the scene


def test_levels_are_set_on_the_first_receiver_and_kept_for_the_others(made):
    """The target's image on the first receiver's channels is at target_level_dbfs; the
    gains are the same for every receiver (the record's, one per source)."""
    from tsel_data import open_dataset
    from tsel_data.tools.inspect import find_scene
    from tsel_data.job.stems import dataset_roots, render_stems, scene_recipe

    scene = find_scene(made, "test/0")
    recipe = scene_recipe(made, "test", 0, scene.scene_id)
    stems, same = render_stems(recipe, scene.audio, dataset_roots(made))
    assert same
    level = db(active_rms(stems[0], scene.active[0], scene.fs, scene.label_hop))
    assert level == pytest.approx(recipe.target_level_dbfs + scene.record.levels.normalisation_db, abs=0.05)
    foa = open_dataset(made, "test", receiver="foa")[0]
    stems_foa, same_foa = render_stems(recipe, foa.audio, dataset_roots(made), receiver=1)
    assert same_foa and stems_foa.shape[1] == 4
    assert [r.format for r in scene.record.receivers] == RECEIVERS
    assert all(r.centre == scene.record.array.centre and r.yaw == scene.record.array.yaw
               for r in scene.record.receivers)


def test_the_first_receiver_sounds_as_it_would_alone(made):
    """Its audio is what a dataset of that receiver alone renders (gains, seed, clips),
    scaled only by the shared clipping guard."""
    from dataclasses import replace

    from tsel_data.tools.inspect import find_scene
    from tsel_data.render.mix import render_scene
    from tsel_data.job.stems import dataset_roots, scene_recipe

    scene = find_scene(made, "train/1")
    recipe = scene_recipe(made, "train", 1, scene.scene_id)
    alone = render_scene(replace(recipe, receivers=()), dataset_roots(made))
    norm = 10 ** (scene.record.levels.normalisation_db / 20) / 10 ** (alone.record.levels.normalisation_db / 20)
    np.testing.assert_allclose(scene.audio, alone.audio * norm, atol=1e-6)


def test_verify_and_inspect_per_receiver(made, capsys, tmp_path):
    from tsel_data.cli import main

    for name in RECEIVERS:
        with pytest.raises(SystemExit) as e:
            main(["verify", made, "--receiver", name, "--quiet"])
        assert e.value.code == 0
    with pytest.raises(SystemExit) as e:
        main(["inspect", made, "test/0", "--receiver", "tetra", "--wav", str(tmp_path / "t.wav")])
    assert e.value.code == 0
    import soundfile as sf

    assert sf.info(str(tmp_path / "t.wav")).channels == 4
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main(["verify", made, "--receiver", "em32"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no receiver 'em32'" in err and "mic4, foa, tetra, respeaker-6" in err


@pytest.mark.parametrize("receivers,message", [
    (["mic4"], r"names 'mic4' twice"),
    (["foa", "foa"], r"names 'foa' twice"),
    (["nope"], r"unknown receiver 'nope'"),
    (["binaural"], r"needs array.hrtf"),
])
def test_bad_receiver_lists_are_one_clear_line(receivers, message):
    from tsel_data.config import load_config

    with pytest.raises(ConfigError, match=message):
        load_config(preset="demo", overrides=[f"scene.receivers={receivers!r}".replace("'", '"')])


def test_bank_datasets_take_only_receivers_one_bank_serves():
    from tsel_data.config import load_config

    cfg = load_config(preset="demo-moving", overrides=['scene.receivers=["stereo"]'])
    assert cfg.scene.receivers == ("stereo",)
    with pytest.raises(ConfigError, match=r"RIR banks of \['foa', 'mic4'\]"):
        load_config(preset="demo-moving", overrides=['scene.receivers=["mic4"]'])


def test_an_unknown_receiver_of_a_dataset_is_refused(made):
    from tsel_data import open_dataset

    with pytest.raises(DatasetError, match="it holds mic4, foa, tetra, respeaker-6"):
        open_dataset(made, "train", receiver="uma8")


def test_an_export_holds_the_receiver_asked_for(made, tmp_path, capsys):
    """`tsel export webdataset --receiver foa`: the foa audio, bit for bit, with its channel
    names; the default is the first receiver; an unknown one is one line, exit 2."""
    from tsel_data import open_dataset
    from tsel_data.export import export
    from tsel_data.formats.webdataset import iter_members
    from support.cli import InProcessCli

    def one_line_error(capsys, *args):
        return InProcessCli(capsys).refused(*args)

    for name, want in ((None, "mic4"), ("foa", "foa"), ("respeaker-6", "respeaker-6")):
        out = tmp_path / f"wds-{name}"
        export("webdataset", made, str(out), splits=["test"], card=False, **({"receiver": name} if name else {}))
        ds = open_dataset(made, "test", receiver=want)
        members = dict(iter_members(str(out / "test" / "test-000000.tar")))
        for i in range(len(ds)):
            s = ds[i]
            np.testing.assert_array_equal(members[f"{s.scene_id}.audio.npy"], s.audio)
            doc = json.loads(members[f"{s.scene_id}.json"])
            assert doc["format"] == want and doc["channel_names"] == list(ds.channel_names)
    line = one_line_error(capsys, "export", "webdataset", made, "--out", str(tmp_path / "x"), "--receiver", "em32")
    assert "no receiver 'em32'" in line and "mic4, foa, tetra, respeaker-6" in line
