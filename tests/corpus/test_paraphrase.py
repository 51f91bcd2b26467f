"""The default ambiguity guard (``scene.similarity = "lexicon"``) sees paraphrases: the
lemmatiser, the concept table, the measure, and plans that never pair a query with a
clip its caption also describes, while ``none`` (the paper's random pairing) can."""
import numpy as np
import pytest

from tsel_data.corpus.captions import CaptionIndex, answerable_queries, caption_sets, set_similarity
from tsel_data.corpus.clip import Clip
from tsel_data.config import load_config
from tsel_data.corpus.lexicon import concepts, lemma
from tsel_data.plan.sampler import CatalogView, plan_scene

GUARD = load_config(preset="demo").scene.caption_similarity

# shared/notes/pairing-evidence.md: pairs the word guard let through, MiniLM cosine >= 0.5
PARAPHRASES = [
    ("A man is speaking", "A man is giving a speech"),
    ("A woman making a speech", "A woman is speaking"),
    ("Car coming from distance and speeding up quickly", "Cars are speeding by"),
    ("A man is speaking and a quick banging", "A man is speaking and closes a door"),
    ("A male voice narrating", "A man speaks, birds chirp"),
    ("A dog barks", "Barking of a dog"),
    ("People talk", "A crowd is chattering"),
    ("An engine idles", "A vehicle motor is idling"),
    ("Water flows in a stream", "A brook trickles"),
]
DIFFERENT = [
    ("A dog barks", "A car passes"),
    ("Rain falls on a roof", "A man speaks"),
    ("A bell rings", "A cat meows"),
    ("Wind blows", "A clock ticks"),
    ("A helicopter flies overhead", "Birds chirp"),
]


@pytest.mark.parametrize("word, want", [
    ("speaking", "speak"), ("speaks", "speak"), ("spoke", "speak"), ("men", "man"), ("women", "woman"),
    ("cars", "car"), ("children", "child"), ("idling", "idle"), ("revving", "rev"), ("cries", "cry"),
    ("rustling", "rustle"), ("barked", "bark"), ("passes", "pass"), ("horses", "horse"), ("buzzes", "buzz"),
    ("making", "make"), ("vibrating", "vibrate"), ("opening", "open"), ("whimpering", "whimper"),
    ("sneezing", "sneeze"), ("glass", "glass"), ("bus", "bus"), ("speed", "speed"), ("typing", "type"),
])
def test_lemmas_of_caption_words(word, want):
    assert lemma(word) == want


def test_synonyms_and_broader_terms_meet_and_fillers_vanish():
    assert concepts("A man is speaking") == concepts("A male voice narrates") == concepts("The guy talks loudly")
    assert concepts("Speech") == concepts("speaking") == {"speak"}
    assert {"car", "vehicle"} <= concepts("cars") and "vehicle" in concepts("A truck engine")
    assert "dog" in concepts("barking") and "person" in concepts("a woman")
    assert concepts("several loud sounds occur repeatedly in the background") == frozenset()
    assert concepts("A zither twangs") == {"zither", "twang"}  # outside the table: the lemma itself


@pytest.mark.parametrize("a, b", PARAPHRASES)
def test_paraphrases_are_above_the_guard(a, b):
    sim = set_similarity(caption_sets(a, "lexicon"), caption_sets(b, "lexicon"), "lexicon")
    assert sim > GUARD, (sorted(caption_sets(a, "lexicon")), sorted(caption_sets(b, "lexicon")))


@pytest.mark.parametrize("a, b", DIFFERENT)
def test_different_sounds_are_below_the_guard(a, b):
    assert set_similarity(caption_sets(a, "lexicon"), caption_sets(b, "lexicon"), "lexicon") <= 0.2


def test_the_index_agrees_with_the_set_measure_and_none_is_zero():
    caps = [(a,) for pair in PARAPHRASES + DIFFERENT for a in pair] + [("",)]
    ix, none = CaptionIndex(caps, "lexicon"), CaptionIndex(caps, "none")
    sets = [caption_sets(c[0], "lexicon") for c in caps]
    for i in range(len(caps)):
        want = [set_similarity(sets[i], s, "lexicon") for s in sets]
        assert ix.caption_sims(i, np.arange(len(caps))) == pytest.approx(want, abs=1e-12)
    assert not none.caption_sims(0, np.arange(len(caps))).any()
    # the band sampler's prefix filter keeps every clip of the band (it is exhaustive)
    got = {ix.sample(np.random.default_rng(s), 0, 0.5, 1.0, lambda c: c != 0) for s in range(60)}
    assert got == {j for j in range(1, len(caps)) if 0.5 <= ix.clip_sim(0, j) <= 1.0}


def test_answerable_queries_drop_a_paraphrase_of_another_source():
    target = ("A man is giving a speech", "A man speaks and a door closes", "Pigeons coo")
    assert answerable_queries(target, [("A man is speaking",)], GUARD) == ["Pigeons coo"]


def _view(pairs, fillers):
    """Clips of one recording each: both captions of every paraphrase pair, and fillers."""
    caps = [c for pair in pairs for c in pair] + fillers
    return CatalogView([Clip(id=f"c{k}", audio=f"/nowhere/c{k}.wav", captions=(c,), meta={"youtube_id": f"y{k}"})
                        for k, c in enumerate(caps)])


def test_default_plans_never_pair_paraphrases_and_random_pairing_can():
    view = _view(PARAPHRASES[:3], ["Wind blows", "A bell rings"])
    partner = {2 * k: 2 * k + 1 for k in range(3)} | {2 * k + 1: 2 * k for k in range(3)}
    ids = {c.id: k for k, c in enumerate(view.clips)}

    def paired(cfg, n=300):
        hits = 0
        for i in range(n):
            r = plan_scene(cfg, "train", i, view)
            t, o = ids[r.sources[0].clip_id], ids[r.sources[1].clip_id]
            hits += partner.get(t) == o
        return hits

    cfg = load_config(preset="demo", overrides=["scene.interferers=1"])
    assert cfg.scene.similarity == "lexicon" and paired(cfg) == 0
    words = load_config(preset="demo", overrides=["scene.interferers=1", 'scene.similarity="words"'])
    assert paired(words) > 0  # the old guard lets "A man is speaking" ~ "A man is giving a speech" through
    rand = load_config(preset="demo", overrides=["scene.interferers=1", 'scene.similarity="none"'])
    assert paired(rand) > 0


def test_the_lexicon_guard_holds_an_interferer_to_every_caption_of_the_target():
    """A clip captioned several times is one sound: the query is one of its captions, but an
    interferer sharing a sound another caption names is turned away too (words: the query only)."""
    clips = [Clip(id="t", audio="/nowhere/t.wav", captions=("A bell rings", "A man speaks as a bell rings"),
                  meta={"youtube_id": "yt"}),
             Clip(id="m", audio="/nowhere/m.wav", captions=("A man is speaking",), meta={"youtube_id": "ym"}),
             Clip(id="w", audio="/nowhere/w.wav", captions=("Wind blows",), meta={"youtube_id": "yw"})]
    view = CatalogView(clips)

    def partners(cfg, n=200):
        out = set()
        for i in range(n):
            r = plan_scene(cfg, "train", i, view)
            if r.sources[0].clip_id == "t" and r.query == "A bell rings":
                out.add(r.sources[1].clip_id)
        return out

    base = ["scene.interferers=1"]
    assert partners(load_config(preset="demo", overrides=base)) == {"w"}
    assert partners(load_config(preset="demo", overrides=base + ['scene.similarity="words"'])) == {"m", "w"}


def test_a_plan_made_before_the_lexicon_default_still_means_words():
    from tsel_data.config import config_differences, parse_config

    cfg = load_config(preset="demo")
    stored = cfg.to_dict()
    assert stored["scene"]["similarity"] == "lexicon"  # stored from now on, so its absence says "before"
    old = {**stored, "scene": {k: v for k, v in stored["scene"].items() if k != "similarity"}}
    assert parse_config(old, stored=True).scene.similarity == "words"
    assert parse_config(old).scene.similarity == "lexicon"  # a user's config without it: the default
    diffs = config_differences(old, cfg)
    assert [(d.key, d.before, d.after) for d in diffs] == [("scene.similarity", "words", "lexicon")]
    words = load_config(preset="demo", overrides=['scene.similarity="words"'])
    assert config_differences(old, words) == [] and config_differences(stored, cfg) == []
