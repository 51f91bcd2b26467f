"""Relational and composite queries: each relation decided on a rendered scene's truth,
and its wordings (docs/queries.md).

The renderer measures what the relations talk about, so a query is decided on what
was rendered, never on what the planner meant: the level of each source's image at the
array (active-frame RMS, as ``level_dbfs``), the activity labels (onsets, who sounds
when), and the position labels (distances, travel). :func:`decide` takes the scene's
:class:`~tsel_data.scene.recipe.QueryPlan` (the wanted type, the relations in the order drawn,
the sources the caption also describes) and returns the first query that holds with its
margin, or the caption when it is unambiguous. Everything here is a pure function of
its inputs: the same recipe gives the same query on any worker.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..choices import QueryType, Relation
from ..core.geometry import sph_to_cart
from ..errors import AudioError

# A source counts as still when its direction never moves more than this (static sources
# have constant labels; this only absorbs float rounding).
STILL_DEG = 0.5

# Composite: a caption that fits n sources, and the relation that tells them apart.
# {cap}: the caption (first letter lower-cased), {Cap}: as written, {n}: "two", "three"...,
# {one}: the relation as a noun phrase.
COMPOSITE_WORDINGS = ("{Cap}: the {one}", "of the {n} sounds that fit \"{cap}\", the {one}",
                      "the {one} of the {n} sources where {cap}", "{Cap} (the {one} of the {n})")
_NUMBERS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten")


@dataclass(frozen=True)
class Truth:
    """What a rendered scene's relations are decided on (S sources, F label frames).

    level_db: [S] active-frame level of each source's image in the mixture, dB.
    active: [S, F] bool. azimuth, elevation (deg), distance (m): [S, F], NaN for additive
    sources. hop: label hop, s.
    """

    level_db: np.ndarray
    active: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    distance: np.ndarray
    hop: float

    @property
    def directional(self) -> np.ndarray:
        return np.isfinite(self.distance).all(axis=1)


@dataclass(frozen=True)
class Decision:
    """The query of a scene: ``type``, ``relation`` (None for a caption), ``text``,
    ``evidence`` (the measured margin and what it was measured against), and
    ``alternatives`` (every wording as true and unambiguous as ``text``)."""

    type: str
    relation: str | None
    text: str
    evidence: dict | None
    alternatives: tuple[str, ...]


def onsets(active: np.ndarray, hop: float) -> np.ndarray:
    """Start time (s) of each source's first active frame [S]; inf if never active."""
    any_ = active.any(axis=1)
    return np.where(any_, np.argmax(active, axis=1) * hop, np.inf)


def travel(azimuth: np.ndarray, elevation: np.ndarray) -> float:
    """Largest angle (deg) between a source's direction at its first frame and at any frame."""
    u = sph_to_cart(azimuth, elevation, 1.0)
    return float(np.degrees(np.arccos(np.clip(u @ u[0], -1.0, 1.0))).max())


def solo_time(truth: Truth, others, window: float):
    """(T, run) for "heard at T": T (s, one decimal) is the centre of the longest run of
    frames where the target is active and none of ``others`` is, and every frame
    overlapping [T - window/2, T + window/2] is such a frame; run: that run's length (s).
    None when no run is long enough."""
    a = truth.active
    solo = a[0] & ~a[list(others)].any(axis=0) if len(others) else a[0].copy()
    best, start = (0, 0), None
    for k, s in enumerate(np.append(solo, False)):
        if s and start is None:
            start = k
        elif not s and start is not None:
            if k - start > best[1] - best[0]:
                best = (start, k)
            start = None
    lo, hi = best[0] * truth.hop, best[1] * truth.hop
    if hi - lo < window:
        return None
    t = round((lo + hi) / 2, 1)
    first = int(np.floor((t - window / 2) / truth.hop + 1e-9))
    last = int(np.ceil((t + window / 2) / truth.hop - 1e-9))  # frames first .. last-1 overlap the window
    if first < 0 or last > len(solo) or not solo[first:last].all():
        return None
    return t, hi - lo


def _level(sign: int):
    def measure(truth: Truth, others: list[int], margin: float):
        lv = truth.level_db
        return (lv[0] - lv[others].max() if sign > 0 else lv[others].min() - lv[0]), {}
    return measure


def _distance(sign: int):
    def measure(truth: Truth, others: list[int], margin: float):
        if not truth.directional[[0] + others].all():
            return None  # an additive source has no distance: "the nearest" would be ill-posed
        d0, do = truth.distance[0], truth.distance[others]
        return float(np.min(do.min(axis=0) - d0) if sign > 0 else np.min(d0 - do.max(axis=0))), {}
    return measure


def _onset(sign: int):
    def measure(truth: Truth, others: list[int], margin: float):
        on = onsets(truth.active, truth.hop)
        value = on[others].min() - on[0] if sign > 0 else on[0] - on[others].max()
        return value, {"onsets": [round(float(on[k]), 3) for k in [0] + others]}
    return measure


def _moving(truth: Truth, others: list[int], margin: float):
    if not truth.directional[0]:
        return None
    moved = [travel(truth.azimuth[k], truth.elevation[k]) if truth.directional[k] else 0.0 for k in others]
    if max(moved) > STILL_DEG:
        return None
    return travel(truth.azimuth[0], truth.elevation[0]), {"others_travel": round(max(moved), 3)}


def _heard_at(truth: Truth, others: list[int], margin: float):
    found = solo_time(truth, others, margin)
    return None if found is None else (found[1], {"time": found[0]})


@dataclass(frozen=True)
class RelationSpec:
    """Everything about one relation: its wordings (``{t}``: seconds), the noun phrase a
    composite query uses for two sources and for more (``one``), the unit of its evidence,
    the ``scene`` config key of its margin, what it is measured on (``needs``: ``level``,
    the rendered levels a recording does not have; ``distance``; or nothing beyond
    activity and direction), and ``measure(truth, others, margin)`` -> (value, extra
    evidence), or None when it cannot hold."""

    wordings: tuple[str, ...]
    one: tuple[str, str]
    unit: str
    margin_key: str
    measure: Callable
    needs: str = ""


# One entry per relation (choices.Relation): adding a relation is its enum value, its
# spec here and its margin key in config/schema.py.
RELATIONS = {
    Relation.LOUDEST: RelationSpec(
        ("the loudest sound", "the sound that is loudest at the microphones", "whatever is loudest in the scene",
         "the most prominent sound"), ("louder one", "loudest one"), "dB", "margin_level", _level(+1), "level"),
    Relation.QUIETEST: RelationSpec(
        ("the quietest sound", "the faintest sound in the scene", "the softest of the sounds",
         "the sound that is quietest at the microphones"), ("quieter one", "quietest one"), "dB", "margin_level",
        _level(-1), "level"),
    Relation.NEAREST: RelationSpec(
        ("the nearest sound", "the sound closest to the microphones", "the source nearest to the array",
         "whatever is making a sound closest by"), ("nearer one", "nearest one"), "m", "margin_distance",
        _distance(+1), "distance"),
    Relation.FARTHEST: RelationSpec(
        ("the farthest sound", "the sound farthest from the microphones", "the most distant source",
         "whatever is making a sound furthest away"), ("farther one", "farthest one"), "m", "margin_distance",
        _distance(-1), "distance"),
    Relation.STARTS_FIRST: RelationSpec(
        ("the sound that starts first", "the first sound to begin", "whatever is heard first",
         "the source that begins before the others"), ("one that starts first", "one that starts first"), "s",
        "margin_onset", _onset(+1)),
    Relation.STARTS_LAST: RelationSpec(
        ("the sound that starts last", "the last sound to begin", "the sound that comes in last",
         "the source that begins after the others"), ("one that starts last", "one that starts last"), "s",
        "margin_onset", _onset(-1)),
    Relation.MOVING: RelationSpec(
        ("the moving sound", "the sound that moves", "the source that is in motion",
         "the one sound that changes position"), ("one that moves", "one that moves"), "deg", "margin_motion",
        _moving),
    Relation.HEARD_AT: RelationSpec(
        ("the sound heard at {t} seconds", "what is audible at {t} s", "the only sound at the {t} second mark",
         "the source sounding at {t} s"), ("one heard at {t} s", "one heard at {t} s"), "s", "margin_solo",
        _heard_at),
}
WORDINGS = {r: spec.wordings for r, spec in RELATIONS.items()}
UNITS = {r: spec.unit for r, spec in RELATIONS.items()}
# each margin key's default (config/schema.py declares the keys with these): a finished
# dataset's stored config names a margin only when it was set (the keys are ``new``)
DEFAULT_MARGINS = {"margin_level": 3.0, "margin_distance": 0.5, "margin_onset": 0.5, "margin_motion": 10.0,
                   "margin_solo": 1.0}


def margins(scene_config) -> dict:
    """{relation: margin} of a config's ``scene`` section (each spec's ``margin_key``)."""
    return {r: getattr(scene_config, spec.margin_key) for r, spec in RELATIONS.items()}


def stored_margins(scene: dict) -> dict:
    """{relation: margin} of a stored config's ``scene`` section (``dataset.json``: a plain
    dict, naming the margins that were set)."""
    return {r: float(scene.get(spec.margin_key, DEFAULT_MARGINS[spec.margin_key])) for r, spec in RELATIONS.items()}


def held(a: np.ndarray) -> np.ndarray:
    """A label row [F] with each NaN frame given the value of its nearest labelled frame
    (ties: the earlier): a recording says where a source is only while it sounds."""
    ok = np.flatnonzero(np.isfinite(a))
    if not len(ok) or len(ok) == len(a):
        return a
    return a[ok[np.abs(np.arange(len(a))[:, None] - ok[None, :]).argmin(axis=1)]]


def check(relation: str, truth: Truth, others, margin: float) -> dict | None:
    """The evidence that the target (source 0) stands in ``relation`` to every source of
    ``others`` with at least ``margin``, or None when it does not."""
    others = [int(k) for k in others]
    if not others:
        return None
    try:
        spec = RELATIONS[relation]
    except KeyError:
        raise ValueError(f"unknown relation {relation!r}") from None
    found = spec.measure(truth, others, margin)
    if found is None:
        return None
    value, extra = found
    if not np.isfinite(value) or value < margin:
        return None
    return {"relation": str(relation), "value": round(float(value), 3), "unit": spec.unit, "margin": margin,
            "against": others, **extra}


def relational_wordings(relation: str, evidence: dict) -> tuple[str, ...]:
    t = evidence.get("time")
    return tuple(w.format(t=f"{t:.1f}" if t is not None else "") for w in RELATIONS[relation].wordings)


def composite_wordings(relation: str, caption: str, n: int, evidence: dict) -> tuple[str, ...]:
    t = evidence.get("time")
    one = RELATIONS[relation].one[0 if n == 2 else 1].format(t=f"{t:.1f}" if t is not None else "")
    cap = caption.strip().rstrip(".")
    low = cap if cap[1:2].isupper() else cap[:1].lower() + cap[1:]  # "TV ..." keeps its capitals
    return tuple(w.format(Cap=cap[:1].upper() + cap[1:], cap=low, n=_NUMBERS[n] if n < len(_NUMBERS) else str(n),
                          one=one) for w in COMPOSITE_WORDINGS)


def decide(plan, caption: str, truth: Truth, scene_id: str = "") -> Decision:
    """The scene's query from its :class:`~tsel_data.scene.recipe.QueryPlan` and rendered truth.

    A caption is used when it is wanted and unambiguous (no same-kind distractor). A
    relational query tries ``plan.relations`` in order against every other source; a
    composite one against the caption's other matches (``plan.matches``). The first
    relation that holds with its margin wins. Falling back: relational -> composite ->
    caption; composite -> relational -> caption; a caption with same-kind distractors
    -> composite -> relational. A scene with same-kind distractors always has a true
    loudness relation (the planner sets their TIR), so it never falls to a bare caption.

    Raises
    ------
    AudioError
        Nothing holds and the caption is ambiguous (the rendered levels contradict the
        recipe's TIRs: a renderer fault, reported with the scene).
    """
    everyone = list(range(1, len(truth.level_db)))
    matches = list(plan.matches)
    if plan.wanted == QueryType.CAPTION and not matches:
        return Decision(QueryType.CAPTION, None, caption, None, tuple(plan.alternatives) or (caption,))
    if plan.wanted == QueryType.RELATIONAL:
        order = [QueryType.RELATIONAL] + ([QueryType.COMPOSITE] if matches else [])
    else:  # composite, or a caption made ambiguous by a same-kind distractor
        order = [QueryType.COMPOSITE, QueryType.RELATIONAL] if matches else []
    for kind in order:
        against = matches if kind == QueryType.COMPOSITE else everyone
        for rel in plan.relations:
            ev = check(rel, truth, against, plan.margin(rel))
            if ev is None:
                continue
            if kind == QueryType.COMPOSITE:
                words = composite_wordings(rel, caption, len(matches) + 1, ev)
            else:
                words = relational_wordings(rel, ev)
            return Decision(kind, rel, words[plan.wording % len(words)], ev, words)
    if not matches:
        return Decision(QueryType.CAPTION, None, caption, None, tuple(plan.alternatives) or (caption,))
    raise AudioError(f"{scene_id}: no relation holds with its margin and the caption {caption!r} also describes "
                     f"source(s) {matches}; levels {np.round(truth.level_db, 2).tolist()} dB contradict the recipe: "
                     f"report it with the scene's recipe")
