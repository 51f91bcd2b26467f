"""Relational and composite queries are true on the rendered scene.

Every relation a query states is checked here from the rendered audio and labels, not
from the planner's intentions nor from the renderer's own evidence: each source's stem
is rebuilt (its spatial image times the gain the record reports), the stems are shown to
add up to the mixture, levels are measured on the stems over their active label frames,
onsets and solo stretches come from the activity labels, distances and travel from the
position labels, and "heard at T" reads T from the query text itself. Composite queries
are checked against every source of the target's sound type, known from the demo
corpus' own sound types (not from caption similarity).
"""
import re

import numpy as np
import pytest

from tsel_data.corpus.audio import load_clip_cached
from tsel_data.config import load_config
from tsel_data.corpus.demo.sounds import SOUND_TYPES
from tsel_data.core.geometry import sph_to_cart
from tsel_data.job.onthefly import SceneSource
from tsel_data.scene.queries import COMPOSITE_WORDINGS, WORDINGS
from tsel_data.render.mix import spatial_images

KIND_OF = {c: t.name for t in SOUND_TYPES for c in t.captions}
FAST = ["audio.duration=3.0", 'room.rt60=["uniform", 0.3, 0.4]', 'scene.similarity="tfidf"']


def stems(source: SceneSource, i: int, scene) -> np.ndarray:
    """Each source's contribution to the mixture [S, C, T], rebuilt from the recipe's clips
    and the record's gains, and checked to add up to the rendered mixture."""
    r = source.view.roots.resolve(source.recipe(i))  # the clips where they are here
    dry = np.zeros((len(r.sources), r.n_samples))
    for k, s in enumerate(r.sources):  # each clip from its start in the scene (scene.onset)
        n0 = int(round(s.start * r.fs))
        dry[k, n0:] = load_clip_cached(s.audio, r.fs, r.duration, s.offset)[: r.n_samples - n0]
    images, _ = spatial_images(r, dry.astype(np.float32))
    gains = np.array([10 ** (s.gain_db / 20) for s in scene.record.sources])
    parts = images.astype(np.float64) * gains[:, None, None]
    np.testing.assert_allclose(parts.sum(axis=0), scene.audio, atol=2e-4 * np.abs(scene.audio).max())
    return parts


def level_db(stem: np.ndarray, active: np.ndarray, fs: int, hop: float, fmt: str) -> float:
    x = stem[:1] if fmt == "foa" else stem
    frames = np.flatnonzero(active) if active.any() else np.arange(len(active))
    idx = np.concatenate([np.arange(int(round(k * hop * fs)), int(round((k + 1) * hop * fs))) for k in frames])
    return 20 * np.log10(np.sqrt(np.mean(x[:, idx] ** 2)))


def onset(active: np.ndarray, hop: float) -> float:
    return float(np.argmax(active) * hop) if active.any() else np.inf


def travel(az, el) -> float:
    u = sph_to_cart(np.asarray(az, float), np.asarray(el, float), 1.0)
    return float(np.degrees(np.arccos(np.clip(u @ u[0], -1, 1))).max())


def assert_relation_holds(source, i, scene, cfg):
    """The scene's query relation, verified from its audio and labels."""
    rec, sc = scene.record, cfg.scene
    rel, qtype = rec.query_relation, rec.query_type
    n = scene.n_sources
    target_kind = KIND_OF[rec.sources[0].captions[0]]
    same_kind = [k for k in range(1, n) if KIND_OF[rec.sources[k].captions[0]] == target_kind]
    if qtype == "caption":
        assert not same_kind or rec.pairing != "same-kind", "a same-kind scene got a bare caption"
        assert scene.query in rec.sources[0].captions
        return
    if qtype == "composite":
        others = sorted(set(rec.query_evidence["against"]))
        # the relation must single the target out among every source of its kind
        assert set(same_kind) <= set(others), (same_kind, others)
        caption = [c for c in rec.sources[0].captions if c.rstrip(".").lower() in scene.query.lower()]
        assert caption, f"composite query {scene.query!r} holds none of the target's captions"
    else:
        others = list(range(1, n))
    assert others
    hop, act = scene.label_hop, scene.active
    if rel in ("loudest", "quietest"):
        parts = stems(source, i, scene)
        lv = [level_db(parts[k], act[k], scene.fs, hop, scene.format) for k in range(n)]
        gap = lv[0] - max(lv[k] for k in others) if rel == "loudest" else min(lv[k] for k in others) - lv[0]
        assert gap >= sc.margin_level - 0.01, (rel, lv)
    elif rel in ("nearest", "farthest"):
        d = scene.distance.astype(np.float64)
        assert np.isfinite(d[[0] + others]).all()
        gap = (d[others].min(axis=0) - d[0]) if rel == "nearest" else (d[0] - d[others].max(axis=0))
        assert gap.min() >= sc.margin_distance - 1e-3, (rel, gap.min())
    elif rel in ("starts_first", "starts_last"):
        on = [onset(act[k], hop) for k in range(n)]
        gap = min(on[k] for k in others) - on[0] if rel == "starts_first" else on[0] - max(on[k] for k in others)
        assert gap >= sc.margin_onset - 1e-9, (rel, on)
    elif rel == "moving":
        assert travel(scene.azimuth[0], scene.elevation[0]) >= sc.margin_motion
        for k in others:
            if np.isfinite(scene.azimuth[k]).all():
                assert travel(scene.azimuth[k], scene.elevation[k]) < 0.5
    elif rel == "heard_at":
        t = float(re.search(r"(\d+(?:\.\d+)?) s", scene.query.replace("seconds", "s").replace(" second mark", " s"))
                  .group(1))
        half = sc.margin_solo / 2
        frames = [k for k in range(scene.n_frames) if k * hop < t + half and (k + 1) * hop > t - half]
        assert frames and act[0, frames].all(), (t, frames)
        assert not act[others][:, frames].any(), (t, frames)
    else:
        raise AssertionError(f"unknown relation {rel!r}")


def _source(demo_corpus, tmp_path, *overrides, n=8):
    cfg = load_config(preset="demo", corpus_dir=demo_corpus, overrides=FAST + list(overrides),
                      splits={"train": n, "val": 0, "test": 0})
    return cfg, SceneSource(cfg, "train", home=str(tmp_path))


@pytest.mark.slow
@pytest.mark.parametrize("relation, extra", [
    ("loudest", []), ("quietest", []),
    ("loudest", ["scene.interferers=3", 'scene.tir_db=["uniform", 3.5, 8.0]', 'scene.scenario="two-directional"']), ("nearest", ['scene.scenario="two-directional"']),
    ("farthest", ['scene.scenario="two-directional"']),
    ("starts_first", ['scene.onset=["uniform", 0.0, 1.5]']), ("starts_last", ['scene.onset=["uniform", 0.0, 1.5]']),
    ("moving", ['scene.motion="mixed"', "scene.moving_fraction=0.5", 'scene.speed=40.0']),
    ("heard_at", ["scene.margin_solo=0.5"]),
])
def test_every_relation_is_true_on_the_rendered_scene(demo_corpus, tmp_path, relation, extra):
    cfg, source = _source(demo_corpus, tmp_path, 'scene.query="relational"', f'scene.relations=["{relation}"]',
                          *extra, n=10)
    got = 0
    for i in range(len(source)):
        scene = source[i]
        rec = scene.record
        assert rec.query_wanted == "relational" and rec.query_type in ("relational", "caption")
        if rec.query_type == "relational":
            got += 1
            assert rec.query_relation == relation and rec.query_evidence["value"] >= rec.query_evidence["margin"]
            assert scene.query in rec.query_alternatives
        assert_relation_holds(source, i, scene, cfg)
    assert got, f"no scene of 10 could say {relation!r}"


@pytest.mark.slow
def test_same_kind_scenes_get_a_true_composite_or_relational_query(demo_corpus, tmp_path):
    cfg, source = _source(demo_corpus, tmp_path, 'scene.query="composite"', "scene.same_kind_distractors=0.3",
                          'scene.interferers=["choose", [1, 2]]', 'scene.scenario="two-directional"', n=12)
    types = set()
    for i in range(len(source)):
        scene = source[i]
        rec = scene.record
        types.add(rec.query_type)
        if rec.pairing == "same-kind":
            assert rec.query_type in ("composite", "relational")
            assert not set(rec.query_alternatives) & set(rec.sources[0].captions)  # never a bare caption
            kinds = [KIND_OF[s.captions[0]] for s in rec.sources]
            assert kinds.count(kinds[0]) >= 2, kinds  # the distractor really is of the target's kind
        assert_relation_holds(source, i, scene, cfg)
    assert "composite" in types


def test_wordings_are_varied_and_fill_in():
    assert all(len(w) >= 3 for w in WORDINGS.values()) and len(COMPOSITE_WORDINGS) >= 3
    from tsel_data.scene.queries import composite_wordings, relational_wordings

    assert relational_wordings("heard_at", {"time": 2.3})[0] == "the sound heard at 2.3 seconds"
    two = composite_wordings("loudest", "A dog barks.", 2, {})
    assert two[0] == "A dog barks: the louder one" and 'fit "a dog barks"' in two[1] and "two" in two[1]
    assert "loudest one of the three" in composite_wordings("loudest", "A dog barks", 3, {})[2]


@pytest.mark.slow
def test_cli_generates_true_queries_and_tools_break_results_down(demo_corpus, tmp_path, capsys):
    """`tsel generate --preset demo --set scene.query=...`: every query true (from the
    rendered audio and labels), `tsel stats` shows the mix, `tsel eval` rows per type,
    `tsel inspect` the evidence."""
    import json

    from tsel_data.cli import main
    from tsel_data.tools.evaluate import write_predictions
    from tsel_data.store.reader import open_dataset

    out = str(tmp_path / "out")
    sets = FAST + ['scene.query=["choose", ["caption", "relational", "composite"]]', "scene.same_kind_distractors=0.2",
                   'scene.interferers=["choose", [1, 2]]',
                   'scene.onset=["uniform", 0.0, 1.0]', "output.shard_size=6"]
    args = ["generate", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", out, "--split", "train=12",
            "--split", "val=0", "--split", "test=0", "--workers", "1", "--quiet"]
    for s in sets:
        args += ["--set", s]
    with pytest.raises(SystemExit) as e:
        main(args)
    assert e.value.code == 0
    cfg = load_config(preset="demo", corpus_dir=demo_corpus, overrides=sets,
                      splits={"train": 12, "val": 0, "test": 0})
    source = SceneSource(cfg, "train", home=out)  # for the recipes the stems are rebuilt from
    with open_dataset(out, "train") as ds:
        for i in range(len(ds)):
            assert_relation_holds(source, i, ds[i], cfg)
        scenes = list(ds.iter_labels())
    assert {s.n_sources for s in scenes} == {2, 3}  # shards pad S; the reader trims it
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["stats", out, "--json"])
    mix = json.loads(capsys.readouterr().out)["train"]["queries"]
    assert sum(mix["types"].values()) == 12 and set(mix["types"]) == {s.query_type for s in scenes}
    pred = str(tmp_path / "pred.jsonl")
    write_predictions(pred, [{"scene_id": s.scene_id, "azimuth": float(np.nanmean(s.azimuth[0]))} for s in scenes])
    with pytest.raises(SystemExit):
        main(["eval", out, "--pred", pred, "--split", "train"])
    text = capsys.readouterr().out
    for t in {s.query_type for s in scenes}:
        assert f"query={t}" in text
    assert "pairing=" in text
    shown = next(s for s in scenes if s.query_relation)
    with pytest.raises(SystemExit):
        main(["inspect", out, shown.scene_id])
    text = capsys.readouterr().out
    assert f"query type: {shown.query_type}" in text and f"relation: {shown.query_relation}" in text
