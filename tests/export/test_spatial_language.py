"""Spatial captions and questions are true on the labels.

Every caption's bins and every answer are derived again here from the scene's labels
(read with the reader, positions on the frames each source sounds in) and its record
(rendered levels, room), with this file's own reading of the vocabularies' tables
(docs/spatial-language.md), never from the exporter's evidence: on a dataset of static
and moving (arcs, lines) sources, two or three per scene, additive ones and diffuse
noise; on moving sources of an RIR bank; on recordings (STARSS23's layout); and on a
dataset heard by several receivers. Every distractor of a multiple-choice row is shown
wrong on the labels too.
"""
import json
import math
import os
import re
from collections import Counter, defaultdict

import numpy as np
import pytest

from tsel_data.export import export
from tsel_data.scene.motion import motion_class
from tsel_data.scene.vocabularies import vocabulary
from tsel_data.store.reader import open_dataset

VOCABS = ("elsa", "sectors8", "oclock", "bat")
DATASETS = ("language", "moving", "recorded", "several-receivers")
MOVING = ("approaching", "receding", "passing", "circling")
SECTORS = ("front", "front-left", "left", "back-left", "back", "back-right", "right", "front-right")
MARGIN_DEG, MARGIN_M, MARGIN_DB, MARGIN_S = 10.0, 0.5, 3.0, 0.5  # the datasets' relational margins (defaults)


# --- the vocabularies' tables, read again ---------------------------------------------------
def wrap(a):
    return (a + 180.0) % 360.0 - 180.0


def az_words(name: str, az: float) -> list:
    """The bins of one azimuth, one per direction axis of the vocabulary."""
    if name == "elsa":
        return ["front" if abs(az) <= 35 else "left" if 55 <= az <= 125 else "right" if -125 <= az <= -55
                else "back" if abs(az) >= 145 else None]
    if name == "sectors8":
        return [SECTORS[int(math.floor((az + 22.5) / 45)) % 8]]
    if name == "oclock":
        return [int(math.floor((15 - az) / 30)) % 12 or 12]
    return ["left" if 0 < az < 180 else "right" if -180 < az < 0 else None,
            "front" if abs(az) < 90 else "back" if abs(az) > 90 else None]


def arcs(name: str, axis: int) -> dict:
    """{bin: (centre, half width)} of a direction axis."""
    return {"elsa": [{"front": (0, 35), "left": (90, 35), "right": (-90, 35), "back": (180, 35)}],
            "sectors8": [{s: (45 * k, 22.5) for k, s in enumerate(SECTORS)}],
            "oclock": [{h: (-30 * (h % 12), 15) for h in range(1, 13)}],
            "bat": [{"left": (90, 90), "right": (-90, 90)}, {"front": (0, 90), "back": (180, 90)}]}[name][axis]


def depth_in_arc(az, arc):
    return arc[1] - abs(wrap(az - arc[0]))


def el_word(name, el):
    return {"elsa": "above" if el > 40 else "below" if el < -40 else None,
            "sectors8": "upper" if el > 20 else "lower" if el < -20 else "horizontal",
            "bat": "above" if el > 0 else "below" if el < 0 else None, "oclock": None}[name]


EL_BANDS = {"elsa": {"above": (40, 90), "below": (-90, -40)}, "bat": {"above": (0, 90), "below": (-90, 0)},
            "sectors8": {"upper": (20, 90), "horizontal": (-20, 20), "lower": (-90, -20)}}


def d_word(name, d):
    return {"elsa": "near" if d < 1 else "far" if d > 2 else None, "sectors8": math.floor(d * 10 + 0.5) / 10,
            "oclock": math.floor(d + 0.5), "bat": math.floor(2 * d + 0.5) / 2}[name]


def one(values):
    """The value every frame agrees on, else None."""
    got = set(values)
    return got.pop() if len(got) == 1 else None


def hold(a):
    ok = np.flatnonzero(np.isfinite(a))
    return a if not len(ok) else a[ok[np.abs(np.arange(len(a))[:, None] - ok[None, :]).argmin(axis=1)]]


class Src:
    """One source of a read scene: its labels on its active frames, and the record's facts."""

    def __init__(self, scene, k):
        self.k, self.rec = k, scene.record.sources[k]
        self.act = np.asarray(scene.active[k], bool)
        self.az_all, self.el_all, self.d_all = (np.asarray(a[k], float) for a in
                                               (scene.azimuth, scene.elevation, scene.distance))
        self.az, self.el, self.d = self.az_all[self.act], self.el_all[self.act], self.d_all[self.act]
        self.heard = bool(self.act.any())
        self.placed = self.heard and bool(np.isfinite(self.az).all())
        self.positionless = not np.isfinite(self.az_all).any()
        d = self.d_all if np.isfinite(self.d).all() else np.where(np.isfinite(self.az_all), 1.0, np.nan)
        self.motion = motion_class(self.az_all, self.el_all, d, self.act)
        frames = np.flatnonzero(self.act)
        self.onset = frames[0] * scene.label_hop if len(frames) else np.inf
        self.span = (frames[0] * scene.label_hop, (frames[-1] + 1) * scene.label_hop) if len(frames) else None

    def direction(self, name):
        """(the exported direction bin, the bins per axis) over the active frames."""
        if not self.placed:
            return None, None
        axes = [one(az_words(name, float(a))[i] for a in self.az) for i in range(2 if name == "bat" else 1)]
        joined = axes[0] if name != "bat" else ", ".join(w for w in axes if w) or None
        return joined, axes

    def depth(self, name, axes):
        return min(depth_in_arc(float(a), arcs(name, i)[b]) for i, b in enumerate(axes) for a in self.az)


def scenes_of(root, split, receiver=None):
    with open_dataset(root, split, receiver=receiver) as ds:
        for i in range(len(ds)):
            scene = ds.get(i, audio=False)
            yield scene, [Src(scene, k) for k in range(scene.n_sources)]


def rows_of(out, split, name):
    path = os.path.join(out, split, name)
    return [json.loads(line) for line in open(path, encoding="utf-8")] if os.path.exists(path) else []


def rows_with_scenes(out, generated_dataset, dataset):
    """(row, scene, sources) of every row of a qa export, with its scene read from the
    dataset; every row's scene is there."""
    for split in splits(generated_dataset, dataset):
        by_scene = defaultdict(list)
        for row in rows_of(out, split, "qa.jsonl"):
            by_scene[row["scene_id"]].append(row)
        for scene, srcs in scenes_of(generated_dataset(dataset).out, split):
            for row in by_scene.pop(scene.scene_id, []):
                yield row, scene, srcs
        assert not by_scene


@pytest.fixture(scope="module")
def made(generated_dataset, tmp_path_factory):
    """made(KIND, DATASET, **options): the export's folder, made once per module."""
    cache = {}

    def make(kind, dataset, **options):
        key = (kind, dataset, tuple(sorted(options.items())))
        if key not in cache:
            out = str(tmp_path_factory.mktemp(f"{kind}-{dataset}"))
            export(kind, generated_dataset(dataset).out, out, force=True, **options)
            cache[key] = out
        return cache[key]

    return make


def splits(generated_dataset, dataset):
    return [s for s, n in json.load(open(os.path.join(generated_dataset(dataset).out, "dataset.json")))["splits"]
            .items() if n["scenes"]]


# --- captions ------------------------------------------------------------------------------------
def expected_bins(name, src: Src, room) -> dict:
    rec = src.rec
    direction = src.direction(name)[0]
    el = one(el_word(name, float(e)) for e in src.el) if src.heard and np.isfinite(src.el).all() else None
    dist = one(d_word(name, float(d)) for d in src.d) if src.heard and np.isfinite(src.d).all() else None
    bins = {"direction": direction, "elevation": el, "distance": dist, "room": None,
            "motion": src.motion if src.motion in MOVING else None}
    dims, t30 = room.dims, room.rt60_measured if room.rt60_measured is not None else room.rt60 if room.bank else None
    if name == "elsa":
        area = dims[0] * dims[1] if dims else None
        size = None if area is None else "small" if area < 50 else "medium" if area <= 100 else "large"
        reverb = None if t30 is None else "highly reverberant" if t30 > 1 else "acoustically dampened" if t30 < 0.2 \
            else None
        bins["room"] = None if size is None and reverb is None else {"size": size, "reverb": reverb}
    if name == "sectors8":
        vol = round(float(np.prod(dims))) if dims else None
        rt = None if t30 is None else math.floor(t30 * 10 + 0.5) / 10
        bins["room"] = None if vol is None and rt is None else {"volume_m3": vol, "rt60_s": rt}
        c50 = (getattr(rec, "acoustics", None) or {}).get("c50_db")
        bins.update(time=None if src.span is None else [math.floor(t * 10 + 0.5) / 10 for t in src.span],
                    loudness=None if rec.level_dbfs is None else math.floor(rec.level_dbfs + 0.5),
                    c50=None if c50 is None else math.floor(c50 + 0.5))
    return bins


@pytest.mark.parametrize("dataset", DATASETS)
@pytest.mark.parametrize("name", VOCABS)
def test_every_caption_says_what_the_labels_say(made, generated_dataset, dataset, name):
    out = made("captions", dataset, vocabulary=name)
    v = vocabulary(name)
    manifest = json.load(open(os.path.join(out, ".tsel-export.json")))
    for split in splits(generated_dataset, dataset):
        rows = {(r["scene_id"], r["source"]): r for r in rows_of(out, split, "captions.jsonl")}
        scene_rows = {r["scene_id"]: r for r in rows_of(out, split, "scenes.jsonl")}
        why = Counter()
        for scene, srcs in scenes_of(generated_dataset(dataset).out, split):
            for src in srcs:
                row = rows[scene.scene_id, src.k]
                assert row["bins"] == expected_bins(name, src, scene.record.room), (row, src.az[:3])
                assert v.parse(row["spatial"]) == row["bins"], row["spatial"]
                assert row["spatial"][1:] in row["caption"] and row["clip_caption"] in src.rec.captions
                assert row["clip_caption"].rstrip(".")[1:] in row["caption"]
                if row["bins"]["direction"] is None:
                    why[row["no_direction"]] += 1
                    if src.heard and src.placed and not src.positionless:
                        crosses = len({tuple(az_words(name, float(a))) for a in src.az}) > 1
                        assert row["no_direction"] == ("moving" if crosses and src.motion in MOVING else
                                                       "crosses" if crosses else "gap"), row
                else:
                    assert row["no_direction"] is None
            listed = scene_rows[scene.scene_id]["sources"]
            assert [s["bins"] for s in listed] == [rows[scene.scene_id, k]["bins"] for k in range(len(srcs))]
        assert manifest["splits"][split]["summary"]["no_direction"] == dict(why)


def test_captions_are_written_with_a_template_and_the_convention(made, generated_dataset):
    out = made("captions", "language", vocabulary="elsa")
    rows = rows_of(out, "train", "captions.jsonl")
    templates = Counter(r["template"] for r in rows)
    assert len(templates) >= 3, templates  # several templates, drawn per (scene, source)
    assert {r["template"] for r in rows if not r["spatial"]} <= {"plain"}
    assert any(r["bins"]["motion"] for r in rows) and any(r["bins"]["room"] for r in rows)
    doc = json.load(open(os.path.join(out, "vocabulary.json")))
    assert "counter-clockwise" in doc["convention"]["azimuth"] and "+90 = left" in doc["convention"]["azimuth"]
    card = open(os.path.join(out, "README.md")).read()
    assert "## Spatial language" in card and "+90° = left" in card and "| direction (azimuth) | left | 55° ≤ az" \
        in card
    sci = made("captions", "language", vocabulary="sectors8")  # the scene rows: Sci-Phi's layout
    sources = {(r["scene_id"], r["source"]): r for r in rows_of(sci, "test", "captions.jsonl")}
    for row in rows_of(sci, "test", "scenes.jsonl"):
        assert re.match(r"room_volume=\d+m\^3; RT60=\d\.\ds; n_src=\d\. noise_label: diffuse noise; "
                        r"noise_loudness=-\d+dB\. Sound label: \(time, direction, distance, loudness, C50\): ",
                        row["caption"]), row["caption"]
        for s in row["sources"]:
            own = sources[row["scene_id"], s["source"]]["spatial"].rsplit("; ", 1)[-1]  # its tuple, the room aside
            assert f"{s['clip_caption'].rstrip('.')[1:]}: {own}" in row["caption"]
    again = made("captions", "language", vocabulary="elsa", figure=False, card=True)  # the same bytes, twice
    assert open(os.path.join(again, "train", "captions.jsonl")).read() == open(
        os.path.join(out, "train", "captions.jsonl")).read()


# --- questions -----------------------------------------------------------------------------------
QUOTED = re.compile(r'the sound "([^"]*)"')


def named(srcs, caption):
    """The one source whose captions hold ``caption`` (as a question quotes it)."""
    hits = [s for s in srcs if any(c.strip().rstrip(".").lower() == caption.lower() for c in s.rec.captions)]
    assert len(hits) == 1, (caption, [s.rec.captions for s in srcs])
    return hits[0]


def said(caption):
    """A caption as an answer gives it: capitalised, no full stop."""
    cap = caption.strip().rstrip(".")
    return cap[:1].upper() + cap[1:]


def at_phrase(v, question):
    hits = [(i, b) for i, ax in enumerate(v.direction) for b in ax.bins if v.at(i, b) in question]
    hits = [h for h in hits if not any(v.at(*o) != v.at(*h) and v.at(*h) in v.at(*o) for o in hits)]
    assert len(hits) == 1, (question, hits)
    return hits[0]


def derive(row, v, scene, srcs):
    """The answer (words) of a so-qa row, decided here on the labels; checks that the
    question names the sources the row says, in order."""
    t, q, name = row["task_type"], row["question"], v.name
    quoted = [named(srcs, c) for c in QUOTED.findall(q)]
    refs = [r["source"] for r in row["source_refs"]]
    heard = [s for s in srcs if s.heard]
    if t == "what_at":
        i, b = at_phrase(v, q)
        arc = arcs(name, i)[b]
        inside = [s for s in srcs if s.placed and min(depth_in_arc(float(a), arc) for a in s.az) >= MARGIN_DEG]
        assert len(inside) == 1
        for s in heard:
            if s is not inside[0] and not s.positionless:
                assert s.placed and max(depth_in_arc(float(a), arc) for a in s.az) <= -MARGIN_DEG
        assert refs == [inside[0].k]
        return row["answer"] if row["answer"] in [said(c) for c in inside[0].rec.captions] \
            else f"not a caption of source {inside[0].k}"
    if t == "count":
        return {2: "two", 3: "three", 4: "four", 1: "one"}[len(heard)]
    assert [s.k for s in quoted] == refs, (q, refs)
    if t in ("where", "layout"):
        words = []
        for s in quoted:
            joined, axes = s.direction(name)
            assert joined is not None and all(axes) and s.depth(name, axes) >= MARGIN_DEG
            words.append(v.answer("direction", joined))
        if t == "where":
            return words[0]
        return "; ".join(f"{said(c)}: {w}" for s, w, c in zip(quoted, words, QUOTED.findall(q)))
    (s, *rest) = quoted
    if t == "distance":
        b = one(d_word(name, float(d)) for d in s.d)
        assert b is not None
        return v.answer("distance", b)
    if t == "elevation":
        b = one(el_word(name, float(e)) for e in s.el)
        lo, hi = EL_BANDS[name][b]
        assert min(min(e - lo, hi - e) for e in s.el) >= MARGIN_DEG
        return v.answer("elevation", b)
    if t == "moving":
        u = np.stack([np.cos(np.radians(s.el)) * np.cos(np.radians(s.az)),
                      np.cos(np.radians(s.el)) * np.sin(np.radians(s.az)), np.sin(np.radians(s.el))], axis=1)
        turn = float(np.degrees(np.arccos(np.clip(u @ u[0], -1, 1))).max())
        change = float(np.max(np.abs(s.d - s.d[0]))) if np.isfinite(s.d).all() else 0.0
        moves = turn >= MARGIN_DEG or change >= MARGIN_M
        assert moves or s.motion == "stationary"
        still_asked = "still" in q or "one place" in q
        return "yes" if moves != still_asked else "no"
    if t == "motion":
        first, last, nearest = s.d[0], s.d[-1], s.d.min()
        assert s.motion in MOVING
        if s.motion == "approaching":
            assert first - last >= MARGIN_M
        elif s.motion == "receding":
            assert last - first >= MARGIN_M
        elif s.motion == "passing":
            assert min(first, last) - nearest >= MARGIN_M
        return {"approaching": "it approaches", "receding": "it moves away", "passing": "it passes by",
                "circling": "it moves around the listener"}[s.motion]
    (o,) = rest
    captions = QUOTED.findall(q)
    if t == "nearer":
        if not (np.isfinite(hold(s.d_all)).all() and np.isfinite(hold(o.d_all)).all()):
            raise AssertionError("a distance question about a source without distances")
        gap = hold(o.d_all) - hold(s.d_all)  # > 0 on every frame: s is the nearer
        nearer_asked = "nearer" in q or "closer" in q
        if gap.min() >= MARGIN_M:
            winner = s if nearer_asked else o
        else:
            assert (-gap).min() >= MARGIN_M
            winner = o if nearer_asked else s
    elif t == "louder":
        ls, lo_ = s.rec.level_dbfs, o.rec.level_dbfs
        assert ls is not None and lo_ is not None and abs(ls - lo_) >= MARGIN_DB
        louder = s if ls > lo_ else o
        winner = louder if "louder" in q else (o if louder is s else s)
    else:
        assert t == "starts_first" and abs(s.onset - o.onset) >= MARGIN_S - 1e-9
        first = s if s.onset < o.onset else o
        winner = first if "first" in q else (o if first is s else s)
    return said(captions[quoted.index(winner)])


@pytest.mark.parametrize("dataset", DATASETS)
@pytest.mark.parametrize("name", VOCABS)
def test_every_answer_is_decided_again_on_the_labels(made, generated_dataset, dataset, name):
    v = vocabulary(name)
    asked = Counter()
    for row, scene, srcs in rows_with_scenes(made("qa", dataset, schema="so-qa", vocabulary=name, balance=False),
                                             generated_dataset, dataset):
        assert derive(row, v, scene, srcs) == row["answer"], row
        assert row["evidence"]["value"] >= row["evidence"]["margin"]
        asked[row["task_type"]] += 1
    assert asked["where"] + asked["what_at"] and asked["count"], asked
    if dataset == "recorded":
        assert not asked["louder"]  # a recording's levels are unknown
    if dataset == "language":
        assert {"nearer", "louder", "starts_first", "moving", "motion", "distance"} <= set(asked), asked


def test_every_schema_writes_the_same_questions(made, generated_dataset):
    so = {(r["question"], r["answer"]) for r in rows_of(made("qa", "language", schema="so-qa", vocabulary="bat",
                                                             balance=False), "train", "qa.jsonl")}
    bat = rows_of(made("qa", "language", schema="spatialsoundqa", balance=False), "train", "qa.jsonl")
    assert {(r["question"], r["answer"]) for r in bat} == so
    assert [r["question_id"] for r in bat] == list(range(len(bat)))
    assert set(bat[0]) == {"question_id", "scene_id", "question_type", "question", "answer", "evidence"}
    mcq = rows_of(made("qa", "language", schema="mcq", vocabulary="bat", balance=False), "train", "qa.jsonl")
    assert mcq and {(r["question"], r["answer_text"]) for r in mcq} <= so


def frame_directions(v, s) -> set:
    """The direction answers true on some active frame of source ``s``."""
    words = [az_words(v.name, float(a)) for a in s.az]
    return {v.answer("direction", ", ".join(w for w in ws if w) if v.name == "bat" else ws[0]) for ws in words}


def _wrong_on_the_labels(row, v, srcs):
    """Every distractor of an mcq row is false on the labels."""
    q, t, name = row["question"], row["question_type"], v.name
    answer = row["answer_text"]
    assert row["options"][ord(row["answer"]) - ord("A")] == answer and len(set(row["options"])) == 4
    quoted = [named(srcs, c) for c in QUOTED.findall(q)]
    for option in row["options"]:
        if option == answer:
            continue
        if t == "where":
            (s,) = quoted
            assert option not in frame_directions(v, s), option
        elif t == "distance":
            (s,) = quoted
            assert option not in {v.answer("distance", d_word(name, float(d))) for d in s.d}
        elif t == "count":
            assert option != answer
        elif t == "motion":
            assert option != answer and option in ("it stays still", "it approaches", "it moves away",
                                                   "it passes by", "it moves around the listener")
        elif t == "layout":
            wrong_somewhere = False
            for part in option.split("; "):
                cap, where = part.rsplit(": ", 1)
                wrong_somewhere |= where not in frame_directions(v, named(srcs, cap))
            assert wrong_somewhere, option
        else:  # the option is a sound: one of the scene's that is not the answer, or one that is not there
            holders = [s for s in srcs if any(said(c) == option for c in s.rec.captions)]
            winner = [s for s in srcs if any(said(c) == answer for c in s.rec.captions)]
            assert winner and not any(h is winner[0] for h in holders), (option, answer)
            if t == "what_at" and holders:
                i, b = at_phrase(v, q)
                for h in holders:
                    assert max(depth_in_arc(float(a), arcs(name, i)[b]) for a in h.az) <= -MARGIN_DEG


@pytest.mark.parametrize("dataset", ["language", "recorded"])
@pytest.mark.parametrize("name", ["elsa", "bat", "sectors8"])
def test_every_distractor_is_wrong(made, generated_dataset, dataset, name):
    v = vocabulary(name)
    n = 0
    for row, _, srcs in rows_with_scenes(made("qa", dataset, schema="mcq", vocabulary=name, balance=False),
                                         generated_dataset, dataset):
        _wrong_on_the_labels(row, v, srcs)
        n += 1
    assert n > 10


def balance_class(row):
    t, c = row["task_type"], row["canonical_answer"]
    if t in ("nearer", "louder", "starts_first"):
        return "first" if row["source_refs"][0]["source"] == c["source"] else "second"
    if t == "distance":
        return f"{int(c)} m" if not isinstance(c, str) else c
    if t == "moving":  # balanced on the truth; yes or no is drawn with the question's form
        still_asked = "still" in row["question"] or "one place" in row["question"]
        return "still" if c == still_asked else "moving"
    return None if t in ("what_at", "layout") else str(c)


@pytest.mark.parametrize("name", ["sectors8", "bat"])
def test_answers_are_balanced_per_type(made, name):
    out = made("qa", "language", schema="so-qa", vocabulary=name)
    rows = rows_of(out, "train", "qa.jsonl")
    classes = defaultdict(Counter)
    for row in rows:
        if balance_class(row) is not None:
            classes[row["task_type"]][balance_class(row)] += 1
    assert len(classes) >= 5, classes
    for t, counts in classes.items():
        assert len(counts) >= 2 and len(set(counts.values())) == 1, (t, counts)  # no "always left"
    manifest = json.load(open(os.path.join(out, ".tsel-export.json")))
    summary = manifest["splits"]["train"]["summary"]
    assert summary["rows"] == len(rows) and sum(summary["types"].values()) == len(rows)


def test_the_same_dataset_gives_the_same_questions_split_by_split(made, generated_dataset, tmp_path):
    full = made("qa", "language", schema="mcq")
    part = str(tmp_path / "test-only")
    export("qa", generated_dataset("language").out, part, splits=["test"], schema="mcq", card=False)
    assert open(os.path.join(part, "test", "qa.jsonl")).read() == open(os.path.join(full, "test", "qa.jsonl")).read()
    letters = Counter(r["answer"] for r in rows_of(full, "train", "qa.jsonl") + rows_of(full, "test", "qa.jsonl"))
    assert set(letters) <= set("ABCD") and len(letters) >= 3, letters


def test_several_receivers_share_the_array_frame(made, generated_dataset):
    a = rows_of(made("qa", "several-receivers", schema="so-qa", balance=False), "train", "qa.jsonl")
    b = rows_of(made("qa", "several-receivers", schema="so-qa", balance=False, receiver="foa"), "train", "qa.jsonl")
    assert any(r["task_type"] == "louder" for r in a)
    # the same answers in every receiver's frame; levels are scene.format's (mic4), so foa's export has no
    # loudness questions
    assert b and b == [r for r in a if r["task_type"] != "louder"]
    caps = rows_of(made("captions", "several-receivers", vocabulary="sectors8", receiver="foa"), "train",
                   "captions.jsonl")
    assert all(r["bins"]["loudness"] is None and r["descriptors"]["level_dbfs"] is None for r in caps)
    card = open(os.path.join(made("qa", "several-receivers", schema="so-qa", balance=False, receiver="foa"),
                             "README.md")).read()
    assert "`foa`" in card


def test_the_exports_load_with_datasets(made):
    datasets = pytest.importorskip("datasets")
    out = made("captions", "language", vocabulary="sectors8")
    ds = datasets.load_dataset(out, split="train")  # the card's configs: captions by default
    assert ds.num_rows == len(rows_of(out, "train", "captions.jsonl")) and "bins" in ds.column_names
    qa = made("qa", "language", schema="mcq")
    rows = datasets.load_dataset(qa, split="test")
    assert rows.num_rows == len(rows_of(qa, "test", "qa.jsonl")) and len(rows[0]["options"]) == 4


def test_mistakes_are_one_line(generated_dataset, tmp_path, tsel_cli):
    root = generated_dataset("language").out
    assert "unknown north; choose from what_at, where" in tsel_cli.refused(
        "export", "qa", root, "--out", tmp_path / "q", "--types", "where,north")
    code, _, err = tsel_cli.run("export", "captions", root, "--out", tmp_path / "c", "--vocabulary", "owl")
    assert code == 2 and "'owl' is not one of" in err and "Traceback" not in err
    tsel_cli.ok("export", "captions", root, "--out", tmp_path / "c", "--vocabulary", "elsa", "--quiet")
    line = tsel_cli.refused("export", "captions", root, "--out", tmp_path / "c", "--vocabulary", "bat", "--quiet")
    assert "another vocabulary elsa (now bat)" in line
