"""Spatial vocabularies: the words say where the labels are, in the toolkit's convention
(+90° = left), each vocabulary's bins are as documented at their edges, and every
vocabulary reads its own words back: parse(describe(x)) == bins(x) on 10,000 random label
sets each, edges and unknowns included."""
import numpy as np
import pytest

from tsel_data.scene.motion import MOTIONS
from tsel_data.scene.vocabularies import VOCABULARIES, RoomFacts, SourceFacts, vocabulary


def facts(az, el=0.0, d=2.0, motion=None, span=(0.0, 1.0), level=-20.0, c50=None):
    arr = lambda v: np.atleast_1d(np.asarray(v, dtype=np.float64))  # noqa: E731
    return SourceFacts(arr(az), arr(el), arr(d), motion, span, level, c50)


def direction(name, az, el=0.0):
    return vocabulary(name).bins(facts(az, el))["direction"]


@pytest.mark.parametrize("az, words", [
    (90.0, {"elsa": "left", "sectors8": "left", "oclock": 9, "bat": "left"}),
    (-90.0, {"elsa": "right", "sectors8": "right", "oclock": 3, "bat": "right"}),
    (0.0, {"elsa": "front", "sectors8": "front", "oclock": 12, "bat": "front"}),
    (-180.0, {"elsa": "back", "sectors8": "back", "oclock": 6, "bat": "back"}),
    (45.0, {"elsa": None, "sectors8": "front-left", "oclock": 11, "bat": "left, front"}),
    (-120.0, {"elsa": "right", "sectors8": "back-right", "oclock": 4, "bat": "right, back"}),
])
def test_azimuth_counts_counter_clockwise_from_the_front_left_positive(az, words):
    for name, word in words.items():
        assert direction(name, az) == word, name


@pytest.mark.parametrize("name, edges", [
    ("elsa", [(35.0, "front"), (35.001, None), (54.999, None), (55.0, "left"), (125.0, "left"), (125.001, None),
              (145.0, "back"), (-145.0, "back"), (-144.999, None), (-55.0, "right"), (-125.0, "right")]),
    ("sectors8", [(22.499, "front"), (22.5, "front-left"), (-22.5, "front"), (-22.501, "front-right"),
                  (157.5, "back"), (157.499, "back-left"), (-157.5, "back-right"), (-157.501, "back")]),
    ("oclock", [(15.0, 12), (15.001, 11), (-15.0, 1), (-14.999, 12), (165.0, 7), (165.001, 6), (-165.0, 6),
                (-164.999, 5)]),
    ("bat", [(0.0, "front"), (90.0, "left"), (-90.0, "right"), (0.001, "left, front"), (179.999, "left, back")]),
])
def test_direction_bins_hold_at_their_edges_as_documented(name, edges):
    for az, word in edges:
        assert direction(name, az) == word, (name, az)


def test_elevation_distance_and_room_bins():
    elsa, s8, bat, oc = (vocabulary(n) for n in ("elsa", "sectors8", "bat", "oclock"))
    assert [elsa.bins(facts(0, el))["elevation"] for el in (40.0, 40.01, -40.0, -40.01)] == [None, "above", None,
                                                                                               "below"]
    assert [elsa.bins(facts(0, 0, d))["distance"] for d in (0.99, 1.0, 2.0, 2.01)] == ["near", None, None, "far"]
    assert [s8.bins(facts(0, el))["elevation"] for el in (20.0, 20.01, -20.0, -20.01)] == \
        ["horizontal", "upper", "horizontal", "lower"]
    assert [s8.bins(facts(0, 0, d))["distance"] for d in (0.84, 0.85, 2.349)] == [0.8, 0.9, 2.3]
    assert [bat.bins(facts(0, 0, d))["distance"] for d in (1.24, 1.25, 1.74, 1.75)] == [1.0, 1.5, 1.5, 2.0]
    assert [bat.bins(facts(0, el))["elevation"] for el in (0.0, 0.01, -0.01)] == [None, "above", "below"]
    assert [oc.bins(facts(0, 0, d))["distance"] for d in (0.49, 0.5, 2.49, 2.5)] == [0, 1, 2, 3]
    rooms = [RoomFacts(49.9, 150.0, 1.01), RoomFacts(50.0, None, 0.2), RoomFacts(100.0, None, 0.19),
             RoomFacts(100.1, None, None), RoomFacts(None, None, None)]
    assert [elsa.room(r) for r in rooms] == [{"size": "small", "reverb": "highly reverberant"},
                                             {"size": "medium", "reverb": None},
                                             {"size": "medium", "reverb": "acoustically dampened"},
                                             {"size": "large", "reverb": None}, None]
    assert s8.room(RoomFacts(30.0, 1949.5, 0.45)) == {"volume_m3": 1950, "rt60_s": 0.5}
    assert elsa.describe(facts(90, 0, 2.5), RoomFacts(120, None, 1.3)) == \
        "to the left of the listener, far away, in a large, highly reverberant room"
    assert s8.describe(facts(50, 45, 0.8, span=(5.3, 8.2), level=-18.2, c50=21.6), RoomFacts(None, 1000, 0.4)) == \
        "room_volume=1000m^3; RT60=0.4s; (5.3s-8.2s, upper front-left, 0.8m, -18dB, 22dB)"
    assert bat.describe(facts(30, -10, 1.1)) == "left, front, below; 1m"
    assert oc.describe(facts(-90, 0, 2.2)) == "at 3 o'clock, about 2 m away"


def test_a_word_is_said_only_when_every_active_frame_agrees():
    elsa = vocabulary("elsa")
    crossing = facts([80.0, 100.0, 130.0], motion="circling")
    assert elsa.bins(crossing)["direction"] is None and elsa.why_no_direction(crossing) == "moving"
    assert elsa.describe(crossing) == "moving around the listener"
    jitter = facts([124.9, 125.1], motion="stationary")
    assert elsa.bins(jitter)["direction"] is None and elsa.why_no_direction(jitter) == "crosses"
    inside = facts([60.0, 120.0], d=[2.5, 1.5], motion="approaching")
    assert elsa.bins(inside)["direction"] == "left" and elsa.bins(inside)["distance"] is None
    assert elsa.describe(inside) == "to the left of the listener, approaching"
    assert elsa.why_no_direction(facts(45.0)) == "gap"
    assert elsa.why_no_direction(facts([np.nan])) == "no position"
    assert elsa.why_no_direction(SourceFacts(np.zeros(0), np.zeros(0), np.zeros(0))) == "silent"
    bat = vocabulary("bat")  # one axis agrees while the other crosses: that one's word alone
    assert bat.bins(facts([60.0, 120.0], motion="circling"))["direction"] == "left"


def test_depth_measures_how_far_inside_a_bin_a_label_is():
    (ax,) = vocabulary("elsa").direction
    assert ax.depth(90.0, "left") == 35.0 and ax.depth(60.0, "left") == 5.0 and ax.depth(45.0, "left") == -10.0
    assert ax.depth(-170.0, "back") == 25.0 and ax.depth(175.0, "front") == -140.0
    (hours,) = vocabulary("oclock").direction
    assert hours.depth(-90.0, 3) == 15.0 and hours.depth(0.0, 6) == -165.0
    assert vocabulary("bat").distance.depth(1.6, 1.5) == pytest.approx(0.15)


def _random_facts(rng: np.random.Generator) -> tuple:
    """A random label set, edges of every vocabulary and unknowns included."""
    n = int(rng.integers(0, 5))
    static = rng.random() < 0.5

    def values(edges, lo, hi, step):
        pick = rng.random()
        if pick < 0.3:  # a multiple of the step: the bins' edges (35°, 22.5°, 15°; 0.05 m, 0.5 m)
            v = step * rng.integers(int(lo / step), int(hi / step))
        elif pick < 0.4:
            v = rng.choice(edges) + rng.choice([-1e-9, 0.0, 1e-9])
        else:
            v = rng.uniform(lo, hi)
        if static:
            return np.full(n, v)
        return np.clip(v + rng.normal(0, 20 * step, n), lo, hi - 1e-9)  # a moving source

    az = values([35.0, 55.0, 125.0, 145.0, 22.5, 67.5, 15.0, 165.0, 90.0, 0.0, -180.0], -180.0, 180.0, 2.5)
    el = values([40.0, -40.0, 20.0, -20.0, 0.0], -90.0, 90.0, 2.5)
    d = values([1.0, 2.0, 0.25, 0.5, 0.75, 0.05, 0.15], 0.0, 12.0, 0.05)
    if n and rng.random() < 0.1:
        d[:] = np.nan  # a recording without distances
    motion = rng.choice([None, *MOTIONS])
    span = None if rng.random() < 0.1 else tuple(sorted(rng.uniform(0, 12, 2).round(int(rng.integers(1, 4)))))
    level = None if rng.random() < 0.2 else float(rng.choice([rng.uniform(-60, 0), -18.5, -0.5]))
    c50 = None if rng.random() < 0.3 else float(rng.uniform(-10, 30))
    room = None if rng.random() < 0.2 else RoomFacts(
        *(None if rng.random() < 0.2 else float(x) for x in (rng.choice([50.0, 100.0, rng.uniform(5, 400)]),
                                                              rng.uniform(10, 3000),
                                                              rng.choice([0.2, 1.0, rng.uniform(0.05, 3)]))))
    return SourceFacts(az, el, d, motion, span, level, c50), room


@pytest.mark.parametrize("name", sorted(VOCABULARIES))
def test_every_vocabulary_reads_its_own_words_back(name):
    v = vocabulary(name)
    rng = np.random.default_rng(39)
    said = set()
    for _ in range(10_000):
        f, room = _random_facts(rng)
        text = v.describe(f, room)
        assert v.parse(text) == v.bins(f, room), (text, f, room)
        said.add(text.split(";")[0].split(",")[0])
    assert len(said) > 10  # the label sets reach many words


def test_an_unknown_vocabulary_names_those_there_are():
    with pytest.raises(ValueError, match="no vocabulary 'owl'; choose one of elsa, sectors8, oclock, bat"):
        vocabulary("owl")


def test_the_docs_tables_are_the_registries():
    """docs/spatial-language.md's tables are generated (python -m tsel_data.scene.language_doc
    docs/spatial-language.md)."""
    from support import REPO
    from tsel_data.scene.language_doc import render

    text = (REPO / "docs" / "spatial-language.md").read_text(encoding="utf-8")
    assert render(text) == text, "docs/spatial-language.md is stale: run python -m tsel_data.scene.language_doc"
    for v in VOCABULARIES.values():
        assert f"| `{v.name}` | direction |" in text
