"""What the spatial-language exports (``captions``, ``qa``) read from a finished scene:
each source's facts over the frames it sounds in, the room, the truth relations are
decided on, and the captions that name each source alone (docs/spatial-language.md).

Everything comes from the scene's labels and record, as the reader gives them (the
labels are the array frame's, the same for every receiver of a dataset heard by several):
positions on the active frames, the level measured in the mix (``level_dbfs``, on the
audio of ``scene.format``: unknown for a further receiver's export), C50 from
the source's acoustic descriptors when the record has them, the motion class from the
record, or decided on the labels (:func:`~tsel_data.scene.motion.motion_class`; a
recording without distances: on its directions alone), and the room's floor area,
volume (the record's, or a shoebox's from its dimensions) and reverberation time (the
measured one, or the one a bank states).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.geometry import circular_mean
from ..corpus.captions import answerable_queries
from ..scene.motion import motion_class
from ..store.dataset import load_dataset_doc
from ..scene.queries import Truth, held
from ..scene.questions import SceneFacts, draw
from ..scene.vocabularies import CONVENTION, MOTION_WORDS, RoomFacts, SourceFacts

ABSENT = 3  # sounds that are not in a scene, offered as wrong answers
RULE = ("A word is written only where it is true on every label frame the source sounds in: a source in a gap of "
        "the vocabulary, or crossing one of its boundaries, gets no word on that axis (a moving one: its motion "
        "word).")


def room_facts(record) -> RoomFacts:
    """Floor area, volume and T30 of a scene's room, each None when unknown."""
    room = record.room
    area, volume = getattr(room, "floor_area_m2", None), getattr(room, "volume_m3", None)
    dims = room.dims
    if dims is not None and len(dims) == 3 and all(isinstance(v, (int, float)) for v in dims):
        area = float(dims[0]) * float(dims[1]) if area is None else area
        volume = float(math.prod(dims)) if volume is None else volume
    t30 = room.rt60_measured if room.rt60_measured is not None else room.rt60 if room.is_bank else None
    return RoomFacts(area, volume, t30)


def _motion(source, az, el, d, active) -> str | None:
    known = getattr(source, "motion", None)  # the record's, where it has one
    if known is not None:
        return known
    heard = np.asarray(active, dtype=bool) & np.isfinite(az)
    if heard.any() and not np.isfinite(d[heard]).all():  # a recording without distances: directions alone
        d = np.where(np.isfinite(az), 1.0, np.nan)
    return motion_class(az, el, d, active)


def source_facts(scene, k: int, levels: bool = True) -> SourceFacts:
    """Source ``k`` of a read :class:`~tsel_data.store.scene.Scene`: its labels on its
    active frames, motion, time span, level (``levels=False``: unknown) and C50."""
    rec = scene.record.sources[k]
    act = np.asarray(scene.active[k], dtype=bool)
    az, el, d = (np.asarray(a[k], dtype=np.float64) for a in (scene.azimuth, scene.elevation, scene.distance))
    frames = np.flatnonzero(act)
    span = None if not len(frames) else (float(frames[0] * scene.label_hop), float((frames[-1] + 1) * scene.label_hop))
    acoustics = getattr(rec, "acoustics", None) or {}
    c50 = acoustics.get("c50_db")
    return SourceFacts(az[act], el[act], d[act], _motion(rec, az, el, d, act), span,
                       rec.level_dbfs if levels else None, None if c50 is None else float(c50))


def scene_truth(scene, levels: bool = True) -> Truth:
    """The scene's truth as relational queries decide it: levels as measured (NaN where
    unknown, or all with ``levels=False``), activity, and positions held over the frames a
    recording leaves unlabelled."""
    level = np.array([np.nan if s.level_dbfs is None or not levels else float(s.level_dbfs)
                      for s in scene.record.sources])
    rows = [np.array([held(np.asarray(r, dtype=np.float64)) for r in a])
            for a in (scene.azimuth, scene.elevation, scene.distance)]
    return Truth(level, np.asarray(scene.active, dtype=bool), *rows, scene.label_hop)


def names(scene, similarity: float, seed: int) -> tuple:
    """Per source, a caption that describes it and no other source of the scene (the
    dataset's ambiguity guard, ``scene.caption_similarity``), drawn; None when none does."""
    caps = [list(s.captions) for s in scene.record.sources]
    out = []
    for k, mine in enumerate(caps):
        ok = answerable_queries(mine, [c for j, c in enumerate(caps) if j != k], similarity)
        out.append(ok[int(draw(seed, scene.scene_id, "name", k).integers(len(ok)))] if ok else None)
    return tuple(out)


def distinct(scene, similarity: float) -> tuple:
    """distinct[k][j]: a caption of source j that does not describe source k (None: none)."""
    caps = [list(s.captions) for s in scene.record.sources]
    return tuple(tuple(None if j == k else next(iter(answerable_queries(cj, [ck], similarity)), None)
                       for j, cj in enumerate(caps)) for k, ck in enumerate(caps))


def absent(scene, pool: list, similarity: float, seed: int) -> tuple:
    """Up to :data:`ABSENT` captions of ``pool`` (the split's) that describe none of the
    scene's sources, nor each other: sounds that are not there."""
    caps = [list(s.captions) for s in scene.record.sources]
    mine = {c for cs in caps for c in cs}
    out = []
    rng = draw(seed, scene.scene_id, "absent")
    for i in rng.permutation(len(pool))[:8 * ABSENT]:
        c = pool[int(i)]
        # not one of the scene's sounds, nor the same sound as another one offered
        if c not in mine and c not in out and answerable_queries([c], caps + [[o] for o in out], similarity):
            out.append(c)
            if len(out) == ABSENT:
                break
    return tuple(out)


def scene_facts(scene, margins: dict, seed: int, similarity: float, pool: list,
                levels: bool = True) -> SceneFacts:
    """Everything a scene's questions are decided on."""
    return SceneFacts(scene.scene_id, scene_truth(scene, levels),
                      tuple(source_facts(scene, k, levels) for k in range(scene.n_sources)),
                      names(scene, similarity, seed), distinct(scene, similarity),
                      absent(scene, pool, similarity, seed), margins, seed)


def levels_known(job) -> bool:
    """Whether the records' levels are the exported receiver's: they are measured on the
    audio of ``scene.format``, not on a further receiver's (``--receiver``)."""
    return job.receiver in (None, load_dataset_doc(job.root).format)


def caption_pool(ds) -> list:
    """Every caption of every source of a split, sorted (the split's sounds)."""
    return sorted({c for rec in ds.records() for s in rec.sources for c in s.captions})


def where_of(facts: SourceFacts) -> dict:
    """A source's place as one reference: circular mean azimuth, mean elevation and mean
    distance over its active frames (None where unknown)."""
    def known(a):
        return len(a) > 0 and bool(np.isfinite(a).all())

    return {"azimuth_deg": round(circular_mean(facts.azimuth), 3) if known(facts.azimuth) else None,
            "elevation_deg": round(float(np.mean(facts.elevation)), 3) if known(facts.elevation) else None,
            "distance_m": round(float(np.mean(facts.distance)), 3) if known(facts.distance) else None}


def vocabulary_doc(v) -> dict:
    """What an export's ``vocabulary.json`` says: the vocabulary, the labels' convention,
    every axis's bins, the templates and the motion words."""
    axes = {**{f"direction ({ax.label})" if len(v.direction) == 1 else f"direction ({ax.label}, {'/'.join(ax.bins)})":
               dict(ax.table) for ax in v.direction},
            **({"elevation": dict(v.elevation.table)} if v.elevation else {}),
            **({"distance": dict(v.distance.table)} if v.distance else {}),
            **({"room": dict(v.room_table)} if v.room_table else {})}
    return {"vocabulary": v.name, "summary": v.summary, "origin": v.origin, "convention": CONVENTION,
            "rule": RULE, "bins": axes, "templates": list(v.templates), "motion_words": MOTION_WORDS}


def language_section(v, what: str) -> list:
    """The card's lines on the spatial language of an export (``what``: captions or qa)."""
    out = ["## Spatial language", "",
           f"The {what} speak in the `{v.name}` vocabulary ({v.summary}; after {v.origin}). Every direction is in "
           "the array frame: azimuth counter-clockwise from the front, +90° = left, [-180°, 180°); elevation up "
           "positive; distances in metres. " + RULE, "", "| axis | word | when |", "|---|---|---|"]
    for name, table in vocabulary_doc(v)["bins"].items():
        out += [f"| {name} | {word} | {when} |" for word, when in table.items()]
    return out + ["", "`vocabulary.json` says the same for programs; docs/spatial-language.md of tsel-data says "
                      "how each answer is decided.", ""]
