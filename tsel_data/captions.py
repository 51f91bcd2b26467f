"""Caption similarity, so a query describes one source of its scene and not the others.

Word-set Jaccard similarity after lower-casing and dropping function words. Crude but
fast (100k scene plans in seconds) and transparent; the threshold is
``scene.caption_similarity``.
"""
from __future__ import annotations

import re

_WORD = re.compile(r"[a-z0-9']+")
STOPWORDS = frozenset(
    "a an the and or but of in on at to from by with without as is are was were be being been "
    "it its this that these those there here then than while during followed after before "
    "into onto over under up down out off some someone something very far nearby near distance "
    "background foreground loud loudly quiet quietly softly".split()
)


def tokens(caption: str) -> frozenset[str]:
    return frozenset(w for w in _WORD.findall(caption.lower()) if w not in STOPWORDS)


def jaccard(a: frozenset, b: frozenset) -> float:
    if not a and not b:
        return 1.0
    return len(a & b) / len(a | b)


def max_similarity(query: frozenset, others) -> float:
    """Highest similarity between a query's tokens and any of ``others`` (token sets)."""
    return max((jaccard(query, o) for o in others), default=0.0)


def answerable_queries(target_captions, other_captions, max_sim: float) -> list[str]:
    """The target's captions that describe it and not the other sources: those whose
    similarity to every caption of every other source is at most ``max_sim`` (the guard
    the planner applies to the query it draws, ``scene.caption_similarity``)."""
    others = [tokens(c) for caps in other_captions for c in caps]
    return [c for c in target_captions if max_similarity(tokens(c), others) <= max_sim]
