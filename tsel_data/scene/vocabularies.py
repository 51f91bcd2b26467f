"""Spatial vocabularies: the words the field's spatial captions and questions use, one
spec each (``elsa``, ``sectors8``, ``oclock``, ``bat``; docs/spatial-language.md).

Every spec turns a source's labels into words (:meth:`Vocabulary.describe`) and reads its
own words back (:meth:`Vocabulary.parse`): ``parse(describe(x)) == bins(x)``, the machine
form. The labels are the toolkit's (array frame: azimuth counter-clockwise from the
front, +90° = left, in [-180, 180); elevation up positive; distance in metres), whatever a
vocabulary's own convention (o'clock hours run clockwise: 3 o'clock is azimuth −90°).

A word is said only where it is true on every frame the source sounds in: each axis bins
every active frame and says its bin only when all of them agree. A source in a gap of a
vocabulary (ELSA says nothing between 35° and 55°) gets no word on that axis; one that
crosses a boundary gets none either, and its motion class (:mod:`~tsel_data.scene.motion`)
says how it moves. Each bin also knows its region, so questions can ask how deep inside
(or how far outside) a bin a label is (:meth:`Axis.depth`, in the label's unit).
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

MOVING = ("approaching", "receding", "passing", "circling")
MOTION_WORDS = {"approaching": "approaching", "receding": "moving away", "passing": "passing by",
                "circling": "moving around the listener"}
CONVENTION = {"frame": "the array frame: right-handed, origin at the array centre, x front, y left, z up",
              "azimuth": "degrees, counter-clockwise from the front seen from above, +90 = left, [-180, 180)",
              "elevation": "degrees above the horizontal plane (up positive)",
              "distance": "metres from the array centre"}
BIN_KEYS = ("direction", "elevation", "distance", "room", "motion")


def _half_up(x: float) -> int:
    """x rounded to the nearest integer, halves up (the same on every platform)."""
    return int(math.floor(x + 0.5))


def _wrap(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def _deg(a: float) -> str:
    """An angle as the docs' tables write it (a true minus sign)."""
    return f"{a:g}°".replace("-", "−")


@dataclass(frozen=True)
class RoomFacts:
    """What room words are decided on: floor area (m²), volume (m³) and reverberation time
    T30 (s), each None when unknown."""

    floor_area_m2: float | None = None
    volume_m3: float | None = None
    t30_s: float | None = None


@dataclass(frozen=True)
class SourceFacts:
    """What a source's words are decided on. azimuth, elevation (degrees), distance (m):
    its labels on the frames where it sounds, [n] each (NaN where unknown); motion: its
    motion class or None; span: (first active frame's start, last one's end) s; level_db:
    its level in the mix; c50_db: its clarity; None where unknown."""

    azimuth: np.ndarray
    elevation: np.ndarray
    distance: np.ndarray
    motion: str | None = None
    span: tuple | None = None
    level_db: float | None = None
    c50_db: float | None = None


@dataclass(frozen=True)
class Axis:
    """One label binned: ``label`` (``azimuth``, ``elevation`` or ``distance``), ``of`` (a
    value -> its bin, None in a gap), ``region`` (a bin -> (centre, half-width) of an
    azimuth arc, or (low, high) of an interval), ``bins`` (the named bins in order; empty
    for numeric bins) and ``table`` (the bins as the docs show them)."""

    label: str
    of: Callable
    region: Callable
    bins: tuple = ()
    table: tuple = ()
    step: float = 0.0  # numeric bins: their width

    def agreed(self, values) -> tuple:
        """(bin, why) over the active frames: the bin every value falls in, or None with
        why: ``unknown`` (no value), ``gap`` (all in a gap) or ``crosses`` (they differ)."""
        values = np.asarray(values, dtype=np.float64)
        if not len(values) or not np.isfinite(values).all():
            return None, "unknown"
        got = {self.of(float(v)) for v in values}
        if len(got) > 1:
            return None, "crosses"
        b = got.pop()
        return (b, "ok") if b is not None else (None, "gap")

    def depth(self, value: float, b) -> float:
        """How far inside bin ``b`` the value lies (its unit; negative: outside by that much)."""
        if self.label == "azimuth":
            centre, half = self.region(b)
            return half - abs(_wrap(value - centre))
        lo, hi = self.region(b)
        return min(value - lo, hi - value)


def _arcs(named: dict) -> Callable:
    return lambda b: named[b]


def _step(step: float, low: float = 0.0) -> Callable:
    """Regions of numeric bins ``k * step`` (rounded halves up): [b - step/2, b + step/2)."""
    return lambda b: (max(low, b - step / 2), b + step / 2)


class Vocabulary:
    """One vocabulary: its axes and words. Subclasses set the class attributes and
    implement :meth:`words` (bins -> phrases, in order), :meth:`join` and :meth:`parse`."""

    name = ""
    summary = ""
    origin = ""
    direction: tuple = ()  # azimuth axes, their bins joined into the direction
    elevation: Axis | None = None
    distance: Axis | None = None
    extras: tuple = ()  # further keys of the bins
    rooms = False  # whether it has words for the room
    room_table: tuple = ()  # (words, when) of the room, as the docs show them
    # how a clip's caption and the spatial words make one caption: {Cap} / {cap} the
    # caption capitalised / as inside a sentence, {spatial} / {Spatial} the words
    templates: tuple = ("{Cap} {spatial}.", "{Spatial}: {cap}.", "{Cap}; heard {spatial}.")

    # --- labels -> bins ------------------------------------------------------------
    def bins(self, facts: SourceFacts, room: RoomFacts | None = None) -> dict:
        """The machine form: direction, elevation, distance, room, motion (None where no
        word is true or the vocabulary has none), and the vocabulary's ``extras``."""
        d = [ax.agreed(facts.azimuth)[0] for ax in self.direction]
        out = {"direction": self.join_direction(d),
               "elevation": self.elevation.agreed(facts.elevation)[0] if self.elevation else None,
               "distance": self.distance.agreed(facts.distance)[0] if self.distance else None,
               "room": self.room(room) if room is not None else None,
               "motion": facts.motion if facts.motion in MOVING else None}
        return {**out, **self.extra_bins(facts)}

    def join_direction(self, parts: list):
        return parts[0] if len(parts) == 1 else ", ".join(p for p in parts if p) or None

    def room(self, room: RoomFacts) -> dict | None:
        return None

    def extra_bins(self, facts: SourceFacts) -> dict:
        return {}

    def why_no_direction(self, facts: SourceFacts) -> str | None:
        """Why a source gets no direction word: ``silent`` (no active frame), ``no position``
        (additive, or unlabelled), ``gap``, ``moving`` (crosses a boundary; its motion
        says so) or ``crosses`` (crosses one while its motion class is not moving); None
        when it gets one."""
        if not len(facts.azimuth):
            return "silent"
        whys = [ax.agreed(facts.azimuth)[1] for ax in self.direction]
        if "unknown" in whys:
            return "no position"
        if any(w == "ok" for w in whys):
            return None
        if "crosses" in whys:
            return "moving" if facts.motion in MOVING else "crosses"
        return "gap"

    # --- bins <-> words --------------------------------------------------------------
    def words(self, bins: dict) -> dict:
        """{part: phrase} of the bins that have words, in the vocabulary's order."""
        raise NotImplementedError

    def join(self, parts: dict) -> str:
        return ", ".join(parts.values())

    def describe(self, facts: SourceFacts, room: RoomFacts | None = None) -> str:
        """The source's spatial words (and the room's, when ``room`` is given)."""
        return self.join(self.words(self.bins(facts, room)))

    def parse(self, text: str) -> dict:
        """The bins the words ``text`` (as :meth:`describe` writes them) say."""
        raise NotImplementedError

    def scene(self, sources: list, room: RoomFacts | None, noise: list = ()) -> str:
        """All sources of a scene in one text (Sci-Phi's layout): the room, how many
        sources, the noise, then each source's caption, time span and level, and its words.
        ``sources``: [(caption, SourceFacts)]; ``noise``: [(kind, level dB)]."""
        room_words = self.words({**dict.fromkeys(BIN_KEYS), "room": self.room(room)}).get("room") if room else None
        head = ([room_words[:1].upper() + room_words[1:]] if room_words else []) + [f"{len(sources)} sounds"]
        out = [", ".join(head) + "."]
        out += [f"Noise: {kind}, {_half_up(level)}dB." for kind, level in noise]
        for caption, facts in sources:
            when = (f"{_tenths(facts.span[0]):.1f}s-{_tenths(facts.span[1]):.1f}s" if facts.span else "silent") + (
                f", {_half_up(facts.level_db)}dB" if facts.level_db is not None else "")
            words = self.describe(facts)
            out.append(f"{_sentence(caption)} ({when}){': ' + words if words else ''}.")
        return " ".join(out)

    def caption(self, caption: str, spatial: str, template: int) -> str:
        """The clip's ``caption`` with the spatial words by template ``template`` (the
        caption alone, with a full stop, when there are no words)."""
        cap = caption.strip().rstrip(".")
        if not spatial:
            return _sentence(cap) + "."
        return self.templates[template].format(Cap=_sentence(cap), cap=cap if cap[1:2].isupper() else
                                               cap[:1].lower() + cap[1:], spatial=spatial,
                                               Spatial=spatial[:1].upper() + spatial[1:])

    # --- for questions -----------------------------------------------------------------
    def answer(self, key: str, b) -> str:
        """The short answer naming bin ``b`` of ``direction``, ``elevation`` or ``distance``."""
        return str(b)

    def at(self, axis: int, b) -> str:
        """A phrase for "what sounds {at}?": bin ``b`` of direction axis ``axis``."""
        raise NotImplementedError

    def direction_bins(self) -> list:
        """Every combined direction bin (one bin per direction axis)."""
        combos = [[]]
        for ax in self.direction:
            combos = [c + [b] for c in combos for b in ax.bins]
        return [self.join_direction(c) for c in combos]


def _sentence(caption: str) -> str:
    cap = caption.strip().rstrip(".")
    return cap[:1].upper() + cap[1:]


@lru_cache(maxsize=None)
def _word(phrase: str) -> re.Pattern:
    return re.compile(r"(?<![\w-])" + re.escape(phrase) + r"(?![\w-])")


def _find(text: str, table: dict):
    """The key of the one phrase of ``table`` ({key: phrase}) found in ``text``, or None."""
    hits = [k for k, phrase in table.items() if _word(phrase).search(text)]
    if len(hits) > 1:
        raise ValueError(f"{text!r} says several of {list(table.values())}")
    return hits[0] if hits else None


# --- ELSA ------------------------------------------------------------------------------
def _elsa_azimuth(az: float):
    if abs(az) <= 35:
        return "front"
    if 55 <= az <= 125:
        return "left"
    if -125 <= az <= -55:
        return "right"
    if abs(az) >= 145:
        return "back"
    return None


def _elsa_elevation(el: float):
    return "above" if el > 40 else "below" if el < -40 else None


def _elsa_distance(d: float):
    return "near" if d < 1 else "far" if d > 2 else None


ELSA_ARCS = {"front": (0.0, 35.0), "left": (90.0, 35.0), "right": (-90.0, 35.0), "back": (180.0, 35.0)}
ELSA_SIZES = {"small": "small", "medium": "medium-sized", "large": "large"}
ELSA_REVERB = ("highly reverberant", "acoustically dampened")


class Elsa(Vocabulary):
    name = "elsa"
    summary = "ELSA's words: four directions with 20° gaps, above / below, near / far, room size and reverberation"
    origin = "Devnani et al., ELSA: Learning Spatially-Aware Language and Audio Embeddings (NeurIPS 2024)"
    rooms = True
    room_table = (("small / medium-sized / large room", "floor area < 50 / 50–100 / > 100 m²"),
                  ("highly reverberant / acoustically dampened", "T30 > 1 s / T30 < 0.2 s"))
    direction = (Axis("azimuth", _elsa_azimuth, _arcs(ELSA_ARCS), tuple(ELSA_ARCS), (
        ("front", "−35° ≤ az ≤ 35°"), ("left", "55° ≤ az ≤ 125°"), ("right", "−125° ≤ az ≤ −55°"),
        ("back", "az ≥ 145° or az ≤ −145°"))),)
    elevation = Axis("elevation", _elsa_elevation, _arcs({"above": (40.0, 90.0), "below": (-90.0, -40.0)}),
                     ("above", "below"), (("above", "el > 40°"), ("below", "el < −40°")))
    distance = Axis("distance", _elsa_distance, _arcs({"near": (0.0, 1.0), "far": (2.0, math.inf)}),
                    ("near", "far"), (("near", "d < 1 m"), ("far", "d > 2 m")))
    PHRASES = {"front": "in front of the listener", "left": "to the left of the listener",
               "right": "to the right of the listener", "back": "behind the listener"}
    ELEVATION = {"above": "from above", "below": "from below"}
    DISTANCE = {"near": "close by", "far": "far away"}
    _ROOM = re.compile(r"\bin an? (?:(small|medium-sized|large)(?:, | ))?(?:(highly reverberant|acoustically "
                       r"dampened) )?room\b")

    def room(self, room: RoomFacts) -> dict | None:
        a, t = room.floor_area_m2, room.t30_s
        size = None if a is None else "small" if a < 50 else "medium" if a <= 100 else "large"
        reverb = None if t is None else ELSA_REVERB[0] if t > 1 else ELSA_REVERB[1] if t < 0.2 else None
        return None if size is None and reverb is None else {"size": size, "reverb": reverb}

    def words(self, bins: dict) -> dict:
        out = {}
        if bins["direction"]:
            out["direction"] = self.PHRASES[bins["direction"]]
        if bins["elevation"]:
            out["elevation"] = self.ELEVATION[bins["elevation"]]
        if bins["distance"]:
            out["distance"] = self.DISTANCE[bins["distance"]]
        if bins["motion"]:
            out["motion"] = MOTION_WORDS[bins["motion"]]
        if bins["room"]:
            size, reverb = bins["room"]["size"], bins["room"]["reverb"]
            adjectives = ", ".join(w for w in (ELSA_SIZES.get(size), reverb) if w)
            out["room"] = f"in {'an' if adjectives[0] in 'aeiou' else 'a'} {adjectives} room"
        return out

    def parse(self, text: str) -> dict:
        room = self._ROOM.search(text)
        size = {v: k for k, v in ELSA_SIZES.items()}.get(room.group(1)) if room else None
        return {"direction": _find(text, self.PHRASES), "elevation": _find(text, self.ELEVATION),
                "distance": _find(text, self.DISTANCE),
                "room": {"size": size, "reverb": room.group(2)} if room else None,
                "motion": _find(text, MOTION_WORDS)}

    def at(self, axis: int, b) -> str:
        return self.PHRASES[b]


# --- Sci-Phi: 3 elevation bands x 8 sectors ----------------------------------------------
SECTORS = ("front", "front-left", "left", "back-left", "back", "back-right", "right", "front-right")
BAND_DEG = 20.0  # upper: el > 20°, lower: el < -20°, horizontal between (Sci-Phi does not state its bands)


def _sector(az: float) -> str:
    return SECTORS[int(math.floor((az + 22.5) / 45.0)) % 8]


def _band(el: float) -> str:
    return "upper" if el > BAND_DEG else "lower" if el < -BAND_DEG else "horizontal"


def _tenths(x: float) -> float:
    return _half_up(x * 10) / 10


def _num(text: str):
    return None if text == "n/a" else float(text)


class Sectors8(Vocabulary):
    name = "sectors8"
    summary = ("Sci-Phi's scene lines: upper / horizontal / lower × 8 sectors of 45°, metres to 0.1, loudness and "
               "C50 in dB, time spans; room volume and RT60")
    origin = "Jiang, Gamper, Braun, Sci-Phi: A Large Language Model Spatial Audio Descriptor (2025)"
    rooms = True
    room_table = (("room_volume=…m^3", "volume to 1 m³ (halves up)"), ("RT60=…s", "T30 to 0.1 s (halves up)"))
    direction = (Axis("azimuth", _sector, lambda b: (45.0 * SECTORS.index(b), 22.5), SECTORS, tuple(
        (s, f"{_deg(_wrap(45 * k - 22.5))} ≤ az < {_deg(_wrap(45 * k + 22.5))}" if s != "back"
         else "az ≥ 157.5° or az < −157.5°") for k, s in enumerate(SECTORS))),)
    elevation = Axis("elevation", _band, _arcs({"upper": (BAND_DEG, 90.0), "horizontal": (-BAND_DEG, BAND_DEG),
                                                "lower": (-90.0, -BAND_DEG)}), ("upper", "horizontal", "lower"),
                     (("upper", f"el > {BAND_DEG:g}°"), ("horizontal", f"−{BAND_DEG:g}° ≤ el ≤ {BAND_DEG:g}°"),
                      ("lower", f"el < −{BAND_DEG:g}°")))
    distance = Axis("distance", _tenths, _step(0.1), (), (("0.8m", "d to 0.1 m (halves up)"),), 0.1)
    extras = ("time", "loudness", "c50")
    templates = ("{Cap}: {spatial}", "{spatial} {Cap}.")
    _TUPLE = re.compile(r"\(([^()]*)\)\s*$")
    _VOLUME = re.compile(r"room_volume=(\d+)m\^3")
    _RT60 = re.compile(r"RT60=(\d+\.\d)s")

    def room(self, room: RoomFacts) -> dict | None:
        v = None if room.volume_m3 is None else _half_up(room.volume_m3)
        t = None if room.t30_s is None else _tenths(room.t30_s)
        return None if v is None and t is None else {"volume_m3": v, "rt60_s": t}

    def extra_bins(self, facts: SourceFacts) -> dict:
        span = None if facts.span is None else [_tenths(facts.span[0]), _tenths(facts.span[1])]
        return {"time": span, "loudness": None if facts.level_db is None else _half_up(facts.level_db),
                "c50": None if facts.c50_db is None else _half_up(facts.c50_db)}

    def words(self, bins: dict) -> dict:
        out = {}
        room = bins["room"]
        if room:
            out["room"] = "; ".join(([f"room_volume={room['volume_m3']}m^3"] if room["volume_m3"] is not None else [])
                                    + ([f"RT60={room['rt60_s']:.1f}s"] if room["rt60_s"] is not None else []))
        where = " ".join(w for w in (bins["elevation"], bins["direction"]) if w) or "n/a"
        t = bins["time"]
        fields = [f"{t[0]:.1f}s-{t[1]:.1f}s" if t else "n/a", where,
                  "n/a" if bins["distance"] is None else f"{bins['distance']:.1f}m",
                  "n/a" if bins["loudness"] is None else f"{bins['loudness']}dB",
                  "n/a" if bins["c50"] is None else f"{bins['c50']}dB"]
        if bins["motion"]:
            fields.append(MOTION_WORDS[bins["motion"]])
        out["source"] = f"({', '.join(fields)})"
        return out

    def join(self, parts: dict) -> str:
        return "; ".join(parts.values())

    def parse(self, text: str) -> dict:
        m = self._TUPLE.search(text)
        if m is None:
            raise ValueError(f"{text!r} holds no (time, direction, distance, loudness, C50) tuple")
        fields = m.group(1).split(", ")
        span, where, dist, loud, c50 = fields[:5]
        motion = {v: k for k, v in MOTION_WORDS.items()}[fields[5]] if len(fields) > 5 else None
        words = where.split(" ") if where != "n/a" else []
        band = words[0] if words and words[0] in self.elevation.bins else None
        sector = words[-1] if words and words[-1] in SECTORS else None
        vol, rt = self._VOLUME.search(text), self._RT60.search(text)
        room = {"volume_m3": int(vol.group(1)) if vol else None, "rt60_s": float(rt.group(1)) if rt else None} \
            if vol or rt else None
        return {"direction": sector, "elevation": band, "distance": _num(dist.removesuffix("m")), "room": room,
                "motion": motion,
                "time": None if span == "n/a" else [float(x.removesuffix("s")) for x in span.split("s-")],
                "loudness": None if loud == "n/a" else int(loud.removesuffix("dB")),
                "c50": None if c50 == "n/a" else int(c50.removesuffix("dB"))}

    def scene(self, sources: list, room: RoomFacts | None, noise: list = ()) -> str:
        room_words = self.words({**dict.fromkeys((*BIN_KEYS, *self.extras)), "room": self.room(room)}
                                ).get("room") if room else None
        out = "; ".join(([room_words] if room_words else []) + [f"n_src={len(sources)}"]) + "."
        if noise:
            out += " noise_label: " + ", ".join(f"{k} noise" for k, _ in noise) + "; noise_loudness=" + \
                ", ".join(f"{_half_up(v)}dB" for _, v in noise) + "."
        tuples = [f"{_sentence(c)}: {self.describe(f)}" for c, f in sources]
        return out + " Sound label: (time, direction, distance, loudness, C50): " + "; ".join(tuples) + "."

    def answer(self, key: str, b) -> str:
        return f"{b:.1f}m" if key == "distance" else str(b)

    def at(self, axis: int, b) -> str:
        return f"from the {b}"


# --- o'clock ---------------------------------------------------------------------------------
def _hour(az: float) -> int:
    k = int(math.floor((15.0 - az) / 30.0)) % 12
    return 12 if k == 0 else k


class OClock(Vocabulary):
    name = "oclock"
    summary = "clock hours (12 straight ahead, 3 to the right, 9 to the left) and whole metres"
    origin = "OWL-style o'clock directions (a clock face lying flat, 12 ahead), as spatial audio LLMs use them"
    direction = (Axis("azimuth", _hour, lambda h: (_wrap(-30.0 * (h % 12)), 15.0), tuple(range(1, 13)), tuple(
        (f"{h} o'clock", f"{_deg(_wrap(-30 * (h % 12) - 15))} < az ≤ {_deg(_wrap(-30 * (h % 12) + 15))}"
         if h != 6 else "az > 165° or az ≤ −165°") for h in (12, *range(1, 12)))),)
    distance = Axis("distance", lambda d: _half_up(d), _step(1.0), (), (
        ("within half a metre", "d < 0.5 m"), ("about N m away", "N − 0.5 ≤ d < N + 0.5 (N ≥ 1)")), 1.0)
    _HOUR = re.compile(r"\bat (\d+) o'clock\b")
    _METRES = re.compile(r"\babout (\d+) m away\b")
    NEAR = "within half a metre"

    def words(self, bins: dict) -> dict:
        out = {}
        if bins["direction"]:
            out["direction"] = f"at {bins['direction']} o'clock"
        if bins["distance"] is not None:
            out["distance"] = self.NEAR if bins["distance"] == 0 else f"about {bins['distance']} m away"
        if bins["motion"]:
            out["motion"] = MOTION_WORDS[bins["motion"]]
        return out

    def parse(self, text: str) -> dict:
        h, m = self._HOUR.search(text), self._METRES.search(text)
        return {"direction": int(h.group(1)) if h else None, "elevation": None,
                "distance": int(m.group(1)) if m else 0 if self.NEAR in text else None, "room": None,
                "motion": _find(text, MOTION_WORDS)}

    def answer(self, key: str, b) -> str:
        if key == "distance":
            return self.NEAR if b == 0 else f"{b} m"
        return f"{b} o'clock"

    def at(self, axis: int, b) -> str:
        return f"at {b} o'clock"


# --- BAT / SpatialSoundQA ---------------------------------------------------------------------
def _lateral(az: float):
    return "left" if 0 < az < 180 else "right" if -180 < az < 0 else None


def _frontal(az: float):
    return "front" if abs(az) < 90 else "back" if abs(az) > 90 else None


class Bat(Vocabulary):
    name = "bat"
    summary = "BAT / SpatialSoundQA: left or right, front or back, above or below; distance in 0.5 m steps"
    origin = "Zheng et al., BAT: Learning to Reason about Spatial Sounds with Large Language Models (ICML 2024)"
    direction = (Axis("azimuth", _lateral, _arcs({"left": (90.0, 90.0), "right": (-90.0, 90.0)}), ("left", "right"),
                      (("left", "0° < az < 180°"), ("right", "−180° < az < 0°"))),
                 Axis("azimuth", _frontal, _arcs({"front": (0.0, 90.0), "back": (180.0, 90.0)}), ("front", "back"),
                      (("front", "−90° < az < 90°"), ("back", "az > 90° or az < −90°"))))
    elevation = Axis("elevation", lambda el: "above" if el > 0 else "below" if el < 0 else None,
                     _arcs({"above": (0.0, 90.0), "below": (-90.0, 0.0)}), ("above", "below"),
                     (("above", "el > 0°"), ("below", "el < 0°")))
    distance = Axis("distance", lambda d: _half_up(d * 2) / 2, _step(0.5), (), (("1.5m", "d to 0.5 m (halves up)"),),
                    0.5)
    templates = ("{Cap} ({spatial}).", "{Cap}: {spatial}", "{Spatial}: {cap}.")
    _METRES = re.compile(r"^(\d+(?:\.\d+)?)m$")
    AXIS_WORDS = {"left": 0, "right": 0, "front": 1, "back": 1}

    def words(self, bins: dict) -> dict:
        out = {}
        where = ", ".join(w for w in (bins["direction"], bins["elevation"]) if w)
        if where:
            out["direction"] = where
        if bins["distance"] is not None:
            out["distance"] = f"{bins['distance']:g}m"
        if bins["motion"]:
            out["motion"] = MOTION_WORDS[bins["motion"]]
        return out

    def join(self, parts: dict) -> str:
        return "; ".join(parts.values())

    def parse(self, text: str) -> dict:
        out = {"direction": None, "elevation": None, "distance": None, "room": None, "motion": None}
        motions = {v: k for k, v in MOTION_WORDS.items()}
        for part in (p.strip() for p in text.split(";") if p.strip()):
            m = self._METRES.match(part)
            if m:
                out["distance"] = float(m.group(1))
            elif part in motions:
                out["motion"] = motions[part]
            else:
                words = part.split(", ")
                out["elevation"] = next((w for w in words if w in ("above", "below")), None)
                out["direction"] = ", ".join(w for w in words if w in self.AXIS_WORDS) or None
        return out

    def answer(self, key: str, b) -> str:
        return f"{b:g}m" if key == "distance" else str(b)

    def at(self, axis: int, b) -> str:
        return {"left": "on the left", "right": "on the right", "front": "in front", "back": "behind"}[b]


VOCABULARIES: dict[str, Vocabulary] = {v.name: v for v in (Elsa(), Sectors8(), OClock(), Bat())}


def vocabulary(name: str) -> Vocabulary:
    """The vocabulary ``name`` (ValueError naming those there are)."""
    try:
        return VOCABULARIES[name]
    except KeyError:
        raise ValueError(f"no vocabulary {name!r}; choose one of {', '.join(VOCABULARIES)}") from None
