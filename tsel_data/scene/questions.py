"""Spatial questions about a rendered scene, each answer decided on its labels and
rendered levels with the margins relational queries use (docs/spatial-language.md).

One :class:`QuestionSpec` per question type in :data:`QUESTIONS`: what sounds at a
direction, where a sound is, how far, how high, which of two is nearer / louder / starts
first, how many sounds there are, whether a sound moves and how, and where several sounds
are. A question is asked only when its answer is the only true one with the margins of
``scene.margin_*`` (an angle: ``margin_motion``, the change of direction relational queries
count as a move; comparisons: :func:`~tsel_data.scene.queries.check` itself), and carries
its evidence (the measured value, the margin, the unit). Answers use a
:class:`~tsel_data.scene.vocabularies.Vocabulary`'s words; every question also lists
answers guaranteed wrong (other bins, other sounds, sounds that are not in the scene),
which multiple-choice rows draw their distractors from.

A sound is named by a caption that describes it and no other source of the scene
(:class:`SceneFacts` ``names``, chosen by the caller); a source no caption names alone is
asked about only by direction. Every draw (a wording, which of two is mentioned first)
comes from :func:`draw`, seeded by the dataset seed, the scene and the question: the same
dataset gives the same questions, split by split, in any order.
"""
from __future__ import annotations

import itertools
import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..choices import Relation
from .motion import MOTIONS, STILL_DEG
from .queries import Truth, check, travel
from .vocabularies import MOVING, SourceFacts, Vocabulary

NUMBERS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten", "eleven", "twelve")
HOW = {"stationary": "it stays still", "approaching": "it approaches", "receding": "it moves away",
       "passing": "it passes by", "circling": "it moves around the listener"}
LAYOUT_MOST = 3  # sources named in one "where are ..." question


@dataclass(frozen=True)
class SceneFacts:
    """What a scene's questions are decided on. truth: the labels (positions held over
    frames a recording leaves unlabelled) and rendered levels (NaN where unknown);
    sources: each source's :class:`SourceFacts` (its active frames); names: a caption
    naming each source alone, or None; distinct[k][j]: a caption of source j that does not
    describe source k (None: none); absent: captions of sounds not in the scene that
    describe none of its sources; margins: {relation: margin}; seed: the dataset's."""

    scene_id: str
    truth: Truth
    sources: tuple
    names: tuple
    distinct: tuple
    absent: tuple
    margins: dict
    seed: int = 0

    @property
    def angle(self) -> float:
        return float(self.margins[Relation.MOVING])

    def heard(self, k: int) -> bool:
        return len(self.sources[k].azimuth) > 0

    def placed(self, k: int) -> bool:
        """Heard, with a direction on every frame it sounds in."""
        f = self.sources[k]
        return self.heard(k) and bool(np.isfinite(f.azimuth).all() and np.isfinite(f.elevation).all())

    def positionless(self, k: int) -> bool:
        """No position on any frame (an additive source): it comes from no direction."""
        return not np.isfinite(self.truth.azimuth[k]).any()


@dataclass(frozen=True)
class Question:
    """One question: ``type`` (a :data:`QUESTIONS` key), ``key`` (which one of the scene's,
    stable: the draws are seeded by it), ``question``, ``answer`` (words), ``canonical``
    (the answer's machine form), ``sources`` (the sources it is about), ``evidence``
    (``value``, ``margin``, ``unit``, and what was measured), ``wrong`` (answers
    guaranteed wrong, for distractors) and ``balance`` (the answer class thinned to
    balance the type's answers; None: not balanced)."""

    type: str
    key: str
    question: str
    answer: str
    canonical: object
    sources: tuple
    evidence: dict
    wrong: tuple = ()
    balance: str | None = None


def draw(seed: int, *keys) -> np.random.Generator:
    """The generator of one question's draws: the dataset seed and its keys (scene, question)."""
    return np.random.default_rng([int(seed), zlib.crc32("\x00".join(map(str, keys)).encode("utf-8"))])


def the(caption: str) -> str:
    """A caption as the questions quote it: the sound "a dog barks"."""
    cap = caption.strip().rstrip(".")
    low = cap if cap[1:2].isupper() else cap[:1].lower() + cap[1:]
    return f'the sound "{low}"'


def said(caption: str) -> str:
    """A caption as an answer gives it."""
    cap = caption.strip().rstrip(".")
    return cap[:1].upper() + cap[1:]


def _wording(scene: SceneFacts, key: str, wordings: tuple, **kw) -> str:
    return wordings[int(draw(scene.seed, scene.scene_id, key, "wording").integers(len(wordings)))].format(**kw)


def _depths(axis, values, b) -> float:
    """The least depth of ``values`` inside bin ``b`` (negative: the farthest one outside)."""
    return float(min(axis.depth(float(v), b) for v in values))


def _direction(scene: SceneFacts, vocab: Vocabulary, k: int):
    """(bins per direction axis, least depth) of a placed source inside its bins, or None
    when an axis does not agree over its active frames."""
    az = scene.sources[k].azimuth
    bins = [ax.agreed(az) for ax in vocab.direction]
    if any(why != "ok" for _, why in bins):
        return None
    return [b for b, _ in bins], min(_depths(ax, az, b) for ax, (b, _) in zip(vocab.direction, bins))


def _angle_evidence(value: float, scene: SceneFacts, what: str, **extra) -> dict:
    return {"value": round(value, 3), "margin": scene.angle, "unit": "deg", "measured": what, **extra}


def _sub(truth: Truth, order: list) -> Truth:
    return Truth(truth.level_db[order], truth.active[order], truth.azimuth[order], truth.elevation[order],
                 truth.distance[order], truth.hop)


def _others(scene: SceneFacts, k: int, captions: tuple) -> list:
    """Distractor captions for an answer naming source k: ``captions`` (of other sources
    that do not describe k) first, then sounds that are not in the scene."""
    mine = [said(c) for c in captions if c]
    return mine + [said(c) for c in scene.absent if said(c) not in mine]


def _nearest_first(vocab: Vocabulary, b) -> list:
    """The other direction bins, the nearest to ``b`` first (the hardest distractors)."""
    others = [o for o in vocab.direction_bins() if o != b]
    if len(vocab.direction) != 1:
        return others
    (axis,) = vocab.direction
    centre = axis.region(b)[0]
    return sorted(others, key=lambda o: abs((axis.region(o)[0] - centre + 180.0) % 360.0 - 180.0))


# --- the question types -------------------------------------------------------------------
def ask_where(scene: SceneFacts, vocab: Vocabulary) -> list:
    out = []
    for k, name in enumerate(scene.names):
        if name is None or not scene.placed(k):
            continue
        found = _direction(scene, vocab, k)
        if found is None or found[1] < scene.angle:
            continue
        bins, depth = found
        b = vocab.join_direction(bins)
        answer = vocab.answer("direction", b)
        key = f"where:{k}"
        q = _wording(scene, key, ("Where is {a} coming from?", "From which direction does {a} come?",
                                  "In which direction is {a}, seen from the listener?"), a=the(name))
        wrong = tuple(vocab.answer("direction", o) for o in _nearest_first(vocab, b))
        out.append(Question("where", key, q, answer, b, (k,),
                            _angle_evidence(depth, scene, "least depth inside the direction's bin, every active "
                                                          "frame"), wrong, answer))
    return out


def ask_what_at(scene: SceneFacts, vocab: Vocabulary) -> list:
    out = []
    for i, axis in enumerate(vocab.direction):
        for k, name in enumerate(scene.names):
            if name is None or not scene.placed(k):
                continue
            b, why = axis.agreed(scene.sources[k].azimuth)
            if why != "ok":
                continue
            inside = _depths(axis, scene.sources[k].azimuth, b)
            rivals = [j for j in range(len(scene.sources)) if j != k and scene.heard(j) and not scene.positionless(j)]
            if not all(scene.placed(j) for j in rivals):
                continue  # a source unlabelled on some frame it sounds in cannot be ruled out
            # every other source lies outside the bin by the margin, on every frame it sounds in
            outer = min((-max(axis.depth(float(v), b) for v in scene.sources[j].azimuth) for j in rivals),
                        default=np.inf)
            value = min(inside, outer)
            if value < scene.angle:
                continue
            key = f"what_at:{i}:{b}"
            q = _wording(scene, key, ("What sound is heard {at}?", "Which sound is {at}?", "What can be heard {at}?"),
                         at=vocab.at(i, b))
            wrong = tuple(_others(scene, k, tuple(scene.distinct[k][j] for j in rivals)))
            out.append(Question("what_at", key, q, said(name), {"source": k}, (k,),
                                _angle_evidence(value, scene, "least depth of the answer inside the bin and of every "
                                                              "other source outside it, every active frame",
                                                inside=round(inside, 3),
                                                others_outside=round(outer, 3) if np.isfinite(outer) else None),
                                wrong, None))
    return out


def _binned(scene: SceneFacts, axis, label: str, eligible):
    """(k, name, values, bin) of each named source ``eligible(k)`` whose ``label`` values
    (e.g. "distance") agree on one bin of ``axis`` over every active frame."""
    for k, name in enumerate(scene.names):
        if name is None or not eligible(k):
            continue
        values = getattr(scene.sources[k], label)
        b, why = axis.agreed(values)
        if why == "ok":
            yield k, name, values, b


def ask_distance(scene: SceneFacts, vocab: Vocabulary) -> list:
    axis = vocab.distance
    if axis is None:
        return []
    out = []
    for k, name, d, b in _binned(scene, axis, "distance", scene.heard):
        if axis.step:
            near = [b + s * axis.step for s in (-1, 1, -2, 2, 3, 4)]
            wrong = tuple(vocab.answer("distance", axis.of(x)) for x in near if x >= 0)
            balance = f"{int(b)} m"
        else:
            wrong = tuple(vocab.answer("distance", o) for o in axis.bins if o != b)
            balance = str(b)
        key = f"distance:{k}"
        q = _wording(scene, key, ("How far away is {a}?", "How far from the listener is {a}?",
                                  "At what distance is {a}?"), a=the(name))
        out.append(Question("distance", key, q, vocab.answer("distance", b), b, (k,),
                            {"value": round(_depths(axis, d, b), 3), "margin": 0.0, "unit": "m",
                             "measured": "least depth inside the distance's bin, every active frame"}, wrong, balance))
    return out


def ask_elevation(scene: SceneFacts, vocab: Vocabulary) -> list:
    axis = vocab.elevation
    if axis is None:
        return []
    out = []
    for k, name, el, b in _binned(scene, axis, "elevation", scene.placed):
        depth = _depths(axis, el, b)
        if depth < scene.angle:
            continue
        key = f"elevation:{k}"
        q = _wording(scene, key, ("How high is {a}, relative to the listener?",
                                  "Is {a} above or below the listener's ears?" if len(axis.bins) == 2 else
                                  "Is {a} above, below or level with the listener's ears?",
                                  "At what height is {a}?"), a=the(name))
        wrong = tuple(vocab.answer("elevation", o) for o in axis.bins if o != b)
        out.append(Question("elevation", key, q, vocab.answer("elevation", b), b, (k,),
                            _angle_evidence(depth, scene, "least depth inside the elevation's bin, every active "
                                                          "frame"), wrong, str(b)))
    return out


def _pairwise(kind: str, relation: Relation, opposite: Relation, forms: dict):
    """Which of two named sources stands in ``relation`` (decided by
    :func:`~tsel_data.scene.queries.check` with its margin); the form asked (``forms``:
    {relation: wordings}) and which is mentioned first are drawn."""
    def ask(scene: SceneFacts, vocab: Vocabulary) -> list:
        out = []
        named = [k for k, n in enumerate(scene.names) if n is not None and scene.heard(k)]
        for x, a in enumerate(named):
            for b in named[x + 1:]:
                margin = float(scene.margins[relation])
                ev = check(relation, _sub(scene.truth, [a, b]), [1], margin)
                first = a if ev is not None else b
                if ev is None:
                    ev = check(relation, _sub(scene.truth, [b, a]), [1], margin)
                    if ev is None:
                        continue
                key = f"{kind}:{a}-{b}"
                rng = draw(scene.seed, scene.scene_id, key, "form")
                asked = (relation, opposite)[int(rng.integers(2))]
                answer = first if asked == relation else (b if first == a else a)
                mentioned = [a, b] if rng.integers(2) == 0 else [b, a]
                q = _wording(scene, key, forms[asked], a=the(scene.names[mentioned[0]]),
                             b=the(scene.names[mentioned[1]]))
                other = b if answer == a else a
                wrong = tuple(_others(scene, answer, (scene.names[other],)))  # as the question names it
                evidence = {"value": ev["value"], "margin": ev["margin"], "unit": ev["unit"],
                            "measured": f"{relation}: source {first} against source {b if first == a else a}",
                            **({"onsets": ev["onsets"]} if "onsets" in ev else {})}
                out.append(Question(kind, key, q, said(scene.names[answer]), {"source": answer}, tuple(mentioned),
                                    evidence, wrong, "first" if answer == mentioned[0] else "second"))
        return out
    return ask


ask_nearer = _pairwise("nearer", Relation.NEAREST, Relation.FARTHEST, {
    Relation.NEAREST: ("Which is nearer to the listener, {a} or {b}?", "Which is closer: {a} or {b}?"),
    Relation.FARTHEST: ("Which is farther from the listener, {a} or {b}?", "Which is more distant: {a} or {b}?")})
ask_louder = _pairwise("louder", Relation.LOUDEST, Relation.QUIETEST, {
    Relation.LOUDEST: ("Which is louder, {a} or {b}?", "Which sounds louder at the microphones: {a} or {b}?"),
    Relation.QUIETEST: ("Which is quieter, {a} or {b}?", "Which sounds fainter at the microphones: {a} or {b}?")})
ask_starts_first = _pairwise("starts_first", Relation.STARTS_FIRST, Relation.STARTS_LAST, {
    Relation.STARTS_FIRST: ("Which starts first, {a} or {b}?", "Which is heard first: {a} or {b}?"),
    Relation.STARTS_LAST: ("Which starts later, {a} or {b}?", "Which comes in last: {a} or {b}?")})


def ask_count(scene: SceneFacts, vocab: Vocabulary) -> list:
    heard = [k for k in range(len(scene.sources)) if scene.heard(k)]
    n = len(heard)
    if not n:
        return []
    key = "count"
    q = _wording(scene, key, ("How many sounds can be heard?", "How many sound sources are there?",
                              "How many different sounds does the scene hold?"))
    wrong = tuple(NUMBERS[m] for m in (n - 1, n + 1, n - 2, n + 2, n + 3) if 1 <= m < len(NUMBERS))
    return [Question("count", key, q, NUMBERS[n] if n < len(NUMBERS) else str(n), n, tuple(heard),
                     {"value": n, "margin": 0, "unit": "sources", "measured": "sources active on at least one "
                                                                              "label frame"}, wrong, str(n))]


def _moved(scene: SceneFacts, k: int) -> tuple:
    """(direction travel deg, largest change of distance m) over the source's active frames."""
    f = scene.sources[k]
    turn = travel(f.azimuth, f.elevation) if len(f.azimuth) > 1 else 0.0
    d = f.distance
    change = float(np.max(np.abs(d - d[0]))) if len(d) > 1 and np.isfinite(d).all() else 0.0
    return turn, change


def ask_moving(scene: SceneFacts, vocab: Vocabulary) -> list:
    out = []
    margin_d = float(scene.margins[Relation.NEAREST])
    for k, name in enumerate(scene.names):
        f = scene.sources[k]
        if name is None or not scene.placed(k) or len(f.azimuth) < 2:
            continue
        turn, change = _moved(scene, k)
        if turn >= scene.angle or change >= margin_d:
            moving = True
        elif f.motion == "stationary":
            moving = False
        else:
            continue
        key = f"moving:{k}"
        still = bool(draw(scene.seed, scene.scene_id, key, "form").integers(2))
        q = _wording(scene, key, ("Is {a} standing still?", "Does {a} stay in one place?") if still else
                     ("Is {a} moving?", "Does {a} change position?"), a=the(name))
        answer = "yes" if moving != still else "no"
        out.append(Question("moving", key, q, answer, answer == "yes", (k,),
                            {"value": round(turn, 3), "margin": scene.angle, "unit": "deg",
                             "measured": "direction travelled over the active frames (or the distance changes by "
                                         "margin_distance)", "distance_change_m": round(change, 3),
                             "margin_distance": margin_d, "motion": f.motion} if moving else
                            {"value": round(scene.angle - turn, 3), "margin": scene.angle - STILL_DEG, "unit": "deg",
                             "measured": "how far the direction stays from counting as a move (the angle margin less "
                                         "the travel); motion class stationary", "distance_change_m":
                                 round(change, 3), "motion": f.motion},
                            ("no",) if answer == "yes" else ("yes",), "moving" if moving else "still"))
    return out


def ask_motion(scene: SceneFacts, vocab: Vocabulary) -> list:
    out = []
    margin_d = float(scene.margins[Relation.NEAREST])
    for k, name in enumerate(scene.names):
        f = scene.sources[k]
        if name is None or not scene.placed(k) or f.motion not in MOVING or not np.isfinite(f.distance).all():
            continue
        d = f.distance
        first, last, nearest = float(d[0]), float(d[-1]), float(np.min(d))
        value, margin, unit = {
            "approaching": (first - last, margin_d, "m"), "receding": (last - first, margin_d, "m"),
            "passing": (min(first, last) - nearest, margin_d, "m"),
            "circling": (_moved(scene, k)[0], scene.angle, "deg")}[f.motion]
        if value < margin:
            continue
        key = f"motion:{k}"
        q = _wording(scene, key, ("How does {a} move?", "How is {a} moving, relative to the listener?",
                                  "What does {a} do as it moves?"), a=the(name))
        wrong = tuple(HOW[m] for m in MOTIONS if m != f.motion)
        out.append(Question("motion", key, q, HOW[f.motion], f.motion, (k,),
                            {"value": round(value, 3), "margin": margin, "unit": unit,
                             "measured": {"m": "distance gained or lost over the active frames", "deg":
                                          "direction travelled over the active frames"}[unit]}, wrong, f.motion))
    return out


def ask_layout(scene: SceneFacts, vocab: Vocabulary) -> list:
    placed = []
    for k, name in enumerate(scene.names):
        if name is None or not scene.placed(k):
            continue
        found = _direction(scene, vocab, k)
        if found is not None and found[1] >= scene.angle:
            placed.append((k, vocab.join_direction(found[0]), found[1]))
    if len(placed) < 2:
        return []
    placed = placed[:LAYOUT_MOST]
    ks = tuple(k for k, _, _ in placed)

    def say(assign) -> str:
        return "; ".join(f"{said(scene.names[k])}: {vocab.answer('direction', b)}" for k, b in zip(ks, assign))

    truth = [b for _, b, _ in placed]
    rng = draw(scene.seed, scene.scene_id, "layout", "wrong")
    wrong = []
    orders = list(itertools.permutations(range(len(ks))))
    for p in rng.permutation(len(orders)):  # the same places, bound to other sounds
        assign = [truth[i] for i in orders[p]]
        if assign != truth and say(assign) not in wrong:
            wrong.append(say(assign))
    others = vocab.direction_bins()
    for i in rng.permutation(len(ks)):  # one sound moved to a place it is not
        for o in rng.permutation(len(others)):
            if others[o] != truth[i]:
                assign = list(truth)
                assign[int(i)] = others[o]
                if say(assign) not in wrong:
                    wrong.append(say(assign))
                break
    names = [the(scene.names[k]) for k in ks]
    q = _wording(scene, "layout", ("Where are {x}?", "From which directions do {x} come?"),
                 x=", ".join(names[:-1]) + " and " + names[-1])
    return [Question("layout", "layout", q, say(truth), [{"source": k, "direction": b} for k, b in zip(ks, truth)],
                     ks, _angle_evidence(min(d for _, _, d in placed), scene, "least depth of every sound inside its "
                                                                             "direction's bin, every active frame"),
                     tuple(wrong), None)]


@dataclass(frozen=True)
class QuestionSpec:
    """One question type: ``ask(scene, vocabulary)`` -> its :class:`Question` s, what it
    is decided on (``needs``: ``level``, the rendered levels a recording lacks;
    ``distance``; or labels alone) and one line for the docs."""

    ask: Callable
    summary: str
    needs: str = ""


QUESTIONS: dict[str, QuestionSpec] = {
    "what_at": QuestionSpec(ask_what_at, "what sounds at a direction: the one source inside the bin by the angle "
                                         "margin, every other outside it by the margin"),
    "where": QuestionSpec(ask_where, "where a named sound is: its direction bin, inside by the angle margin"),
    "distance": QuestionSpec(ask_distance, "how far: its distance bin on every active frame", "distance"),
    "elevation": QuestionSpec(ask_elevation, "how high: its elevation bin, inside by the angle margin"),
    "nearer": QuestionSpec(ask_nearer, "which of two is nearer / farther: `nearest` with `margin_distance`",
                           "distance"),
    "louder": QuestionSpec(ask_louder, "which of two is louder / quieter: `loudest` with `margin_level`", "level"),
    "starts_first": QuestionSpec(ask_starts_first, "which of two starts first / later: `starts_first` with "
                                                   "`margin_onset`"),
    "count": QuestionSpec(ask_count, "how many sounds: sources active on a label frame"),
    "moving": QuestionSpec(ask_moving, "whether a sound moves: it travels the angle margin or `margin_distance`, "
                                       "or its motion class is stationary"),
    "motion": QuestionSpec(ask_motion, "how it moves: its motion class, by `margin_distance` (approaching, "
                                       "receding, passing) or the angle margin (circling)", "distance"),
    "layout": QuestionSpec(ask_layout, "where several named sounds are: each inside its bin by the angle margin"),
}


def ask(scene: SceneFacts, vocab: Vocabulary, types=None) -> list:
    """Every question of ``types`` (default: all of :data:`QUESTIONS`) the scene answers."""
    return [q for t in (types or QUESTIONS) for q in QUESTIONS[t].ask(scene, vocab)]


__all__ = ["QUESTIONS", "Question", "QuestionSpec", "SceneFacts", "SourceFacts", "ask", "draw"]
