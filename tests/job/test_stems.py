"""Per-source stems of a stored scene, rendered again from its recipe: they add up to
the stored mixture; tsel inspect --wav writes them as headphone previews."""
from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf


@pytest.fixture
def made(generated_dataset):
    return generated_dataset("stems").out


def test_stems_add_up_to_the_stored_mixture(made):
    from tsel_data.tools.inspect import find_scene
    from tsel_data.job.stems import dataset_roots, render_stems, scene_recipe

    for i in range(3):
        scene = find_scene(str(made), f"test/{i}")
        recipe = scene_recipe(str(made), "test", i, scene.scene_id)
        stems, same = render_stems(recipe, scene.audio, dataset_roots(str(made)))
        assert same and stems.shape == (len(recipe.sources), *scene.audio.shape)
        np.testing.assert_allclose(stems.sum(axis=0), scene.audio, atol=2e-6)
        # the target alone is the target: its level is the one the record gives
        assert np.max(np.abs(stems[0])) > 0 and not np.allclose(stems[0], scene.audio)


def test_inspect_wav_writes_stereo_and_stems(made, tmp_path, capsys):
    from tsel_data.cli import main

    with pytest.raises(SystemExit) as e:
        main(["inspect", str(made), "test/0", "--wav", str(tmp_path / "s.wav")])
    out = capsys.readouterr().out
    assert e.value.code == 0
    assert f"stems: {tmp_path}/s.target.stereo.wav, {tmp_path}/s.interferer1.stereo.wav" in out
    mix, _ = sf.read(tmp_path / "s.stereo.wav", dtype="float32")
    parts = [sf.read(tmp_path / f"s.{n}.stereo.wav", dtype="float32")[0] for n in ("target", "interferer1")]
    np.testing.assert_allclose(parts[0] + parts[1], mix, atol=2e-6)


def test_stems_need_the_clips(made, tmp_path, capsys, demo_corpus, monkeypatch):
    import tsel_data.corpus.audio
    from tsel_data.cli import main

    def gone(path, *a, **k):
        raise tsel_data.corpus.audio.AudioError(f"cannot read audio {path}: No such file; check the file or remove it "
                                         f"from the manifest")

    monkeypatch.setattr(tsel_data.render.mix, "load_clip_cached", gone)
    with pytest.raises(SystemExit) as e:
        main(["inspect", str(made), "test/1", "--wav", str(tmp_path / "s.wav")])
    out = capsys.readouterr()
    assert e.value.code == 0 and (tmp_path / "s.wav").exists() and (tmp_path / "s.stereo.wav").exists()
    assert out.err.startswith("note: no stems: cannot read audio ")


def test_the_documented_call_finds_the_clips_from_the_dataset(made, tmp_path, monkeypatch):
    """docs/commands/inspect.md: render_stems(scene_recipe(DIR, ...), scene.audio), no roots,
    from any folder: the recipe names its clips where they are on this machine."""
    from tsel_data.errors import DatasetError
    from tsel_data.tools.inspect import find_scene
    from tsel_data.job.stems import render_stems, scene_recipe

    monkeypatch.chdir(tmp_path)  # clip paths relative to the corpus must not be read from here
    scene = find_scene(str(made), "test/2")
    stems, same = render_stems(scene_recipe(str(made), "test", 2, scene.scene_id), scene.audio)
    assert same and stems.shape == (2, *scene.audio.shape)
    stored = scene_recipe(str(made), "test", 2, as_stored=True)
    assert not stored.sources[0].audio.startswith("/")  # the plan keeps names relative to its corpus
    # a recipe as stored, without its roots: the file it cannot find is named, not libsndfile's "System error."
    with pytest.raises(DatasetError, match=rf"^{stored.sources[0].audio}, which the recipe of test-000002 names, "
                                           r"is not there; .*roots=dataset_roots\(DATASET_DIR\)"):
        render_stems(stored, scene.audio)
    with pytest.raises(DatasetError, match="line 3 is test-000002, not test-000001"):
        scene_recipe(str(made), "test", 2, "test-000001")
