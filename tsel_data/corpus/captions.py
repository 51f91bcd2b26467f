"""Caption similarity, so a query describes one source of its scene and not the others.

One measure serves the ambiguity guard (``scene.caption_similarity``), pairing
(``scene.pairing``: hard and easy interferers) and same-kind distractors
(``scene.same_kind_similarity``); ``scene.similarity`` picks it:

- ``lexicon`` (the default): cosine of the captions' concept sets
  (:func:`tsel_data.corpus.lexicon.concepts`: content words lemmatised and mapped to their
  synonym groups and broader terms), ``|A ∩ B| / sqrt(|A| |B|)``. Paraphrases meet:
  "A man is speaking" ~ "A male voice narrates" is 1.0 (Jaccard of the words 0.0).
- ``words`` (the default before 0.x; datasets planned with it are rebuilt with it):
  word-set Jaccard after lower-casing and dropping function words. Crude, fast, transparent.
- ``tfidf``: cosine of TF-IDF vectors over the split's captions: content words cut to a
  crude stem ("barks", "barking" -> "bark"), binary term frequency (captions are short),
  smooth idf ``log((1 + N) / (1 + df)) + 1``. Rare shared words count more than common
  ones, and inflections match: "A dog barks" ~ "Barking of a dog" is 1.0 (Jaccard 0.33).
- ``embeddings``: cosine of vectors made elsewhere (CLAP, MiniLM: ``tsel corpus embed``),
  read from ``corpus.caption_embeddings`` (an ``.npz`` with ``captions`` and ``vectors``).
- ``none``: no guard, every similarity 0: interferers drawn at random, as the paper did.

:class:`CaptionIndex` holds one split's captions under one measure, precomputed once,
and answers similarities for many clips at once and draws a clip whose similarity to a
query caption lies in a band (see :meth:`CaptionIndex.sample`).
"""
from __future__ import annotations

import functools
import re

import numpy as np

from ..errors import ConfigError
from ..core.files import check_input
from .lexicon import BROAD, NAMED, concepts, weight

_WORD = re.compile(r"[a-z0-9']+")
STOPWORDS = frozenset(
    "a an the and or but of in on at to from by with without as is are was were be being been "
    "it its this that these those there here then than while during followed after before "
    "into onto over under up down out off some someone something very far nearby near distance "
    "background foreground loud loudly quiet quietly softly".split()
)
MEASURES = ("lexicon", "words", "tfidf", "embeddings", "none")


def tokens(caption: str) -> frozenset[str]:
    return frozenset(w for w in _WORD.findall(caption.lower()) if w not in STOPWORDS)


def stem(word: str) -> str:
    """A crude English stem: one common suffix off, a doubled final consonant undone
    ("running" -> "run"), so inflections of a word share a TF-IDF term."""
    for suffix in ("ing", "ed", "es", "s"):
        if word.endswith(suffix) and len(word) - len(suffix) >= 3:
            word = word[: -len(suffix)]
            break
    if len(word) > 3 and word[-1] == word[-2] and word[-1] not in "lsz":
        word = word[:-1]
    return word


def stems(caption: str) -> frozenset[str]:
    return frozenset(stem(w) for w in tokens(caption))


def jaccard(a: frozenset, b: frozenset) -> float:
    if not a and not b:
        return 1.0
    return len(a & b) / len(a | b)


def concept_similarity(a: frozenset, b: frozenset) -> float:
    """The ``lexicon`` similarity of two concept sets: the square root of the cosine of
    their weighted indicator vectors (:func:`tsel_data.corpus.lexicon.weight`), so 1.0 for the
    same concepts, 0.71 for two captions sharing one of their two events, 0.5 for one of
    four; 0.0 when one is empty (a caption of fillers names no sound)."""
    if not a or not b:
        return 0.0
    dot = sum(weight(c) ** 2 for c in a & b)
    return float(np.sqrt(dot / np.sqrt(_norm2(a) * _norm2(b))))


@functools.lru_cache(maxsize=1 << 17)
def _norm2(concept_set: frozenset) -> float:
    # the planner compares one query with many clips: each set's norm is summed once
    return sum(weight(c) ** 2 for c in concept_set)


def caption_sets(caption: str, measure: str) -> frozenset[str]:
    """What a set measure compares of a caption: its words, or its concepts."""
    return concepts(caption) if measure == "lexicon" else tokens(caption)


def set_similarity(a: frozenset, b: frozenset, measure: str = "words") -> float:
    """The similarity of two :func:`caption_sets` under ``measure`` (``none``: 0)."""
    if measure == "none":
        return 0.0
    return concept_similarity(a, b) if measure == "lexicon" else jaccard(a, b)


def max_similarity(query: frozenset, others, measure: str = "words") -> float:
    """Highest similarity between a query's sets and any of ``others`` (sets of one measure)."""
    return max((set_similarity(query, o, measure) for o in others), default=0.0)


def answerable_queries(target_captions, other_captions, max_sim: float) -> list[str]:
    """The target's captions that describe it and not the other sources: those whose
    similarity to every caption of every other source is at most ``max_sim`` under both
    the word-set and the lexicon guard (records of datasets planned with either;
    datasets planned otherwise list their answerable queries in each record,
    ``query_alternatives``)."""
    out = []
    for measure in ("words", "lexicon"):
        others = [caption_sets(c, measure) for caps in other_captions for c in caps]
        out.append({c for c in target_captions if max_similarity(caption_sets(c, measure), others, measure) <= max_sim})
    return [c for c in target_captions if c in out[0] and c in out[1]]


def sound_events(captions) -> frozenset[str]:
    """The sound events a clip's ``captions`` (one caption, or several) name together: their
    lexicon concepts that the table knows (:mod:`tsel_data.corpus.lexicon`), broad terms
    (person, vehicle, water, animal) aside. "A telephone rings" names {phone, bell}, "A
    large bell tolls" {bell}, "Footsteps on a hard floor" {footstep}."""
    if isinstance(captions, str):
        captions = (captions,)
    return frozenset(c for cap in captions for c in concepts(cap) if c in NAMED and c not in BROAD)


def same_kind(query_events: frozenset, target_events: frozenset, other_events: frozenset) -> bool:
    """Whether another clip fits a composite query's caption as a sound of the target's kind:
    it names every sound event the query caption names, and none the target clip does not
    (query ⊆ other ⊆ target, as sets of :func:`sound_events`). "A telephone rings" and "A
    bell rings" share the lexicon's bell (to ring) but not the phone: not of a kind; a clip
    of bells and a car horn is not of a bell clip's kind either. A caption that names no
    event of the table constrains nothing (the similarity band alone decides)."""
    if not query_events:
        return True
    return query_events <= other_events <= (target_events | query_events)


def load_embeddings(path: str) -> dict[str, np.ndarray]:
    """caption -> unit vector from an ``.npz`` with ``captions`` [N] str and ``vectors``
    [N, D] (ConfigError naming the file on any problem)."""
    check_input(path, ConfigError, "give the .npz of `tsel corpus embed`")
    try:
        with np.load(path, allow_pickle=False) as z:
            caps, vecs = z["captions"], z["vectors"]
    except (OSError, ValueError, KeyError) as e:
        raise ConfigError(f"corpus.caption_embeddings {path}: not an .npz with arrays 'captions' and 'vectors' "
                          f"({type(e).__name__}: {str(e)[:80]}); write one with `tsel corpus embed`") from None
    vecs = np.asarray(vecs, dtype=np.float32)
    if vecs.ndim != 2 or len(caps) != len(vecs) or not np.isfinite(vecs).all():
        raise ConfigError(f"corpus.caption_embeddings {path}: 'vectors' must be finite numbers [{len(caps)}, D], one "
                          f"row per caption, got shape {list(vecs.shape)}")
    norms = np.linalg.norm(vecs, axis=1, keepdims=True)
    vecs = vecs / np.where(norms > 0, norms, 1.0)
    return {str(c): v for c, v in zip(caps.tolist(), vecs)}


class CaptionIndex:
    """The captions of one split's clips under one measure, ready for fast look-ups.

    Captions are numbered clip by clip: clip ``j`` owns captions ``first[j] ..
    first[j + 1] - 1``. The similarity of a caption to a *clip* is the highest over the
    clip's captions. Everything per caption is precomputed: term ids and weights padded
    to one width (lexical measures) with an inverted index, or the unit vectors.

    Parameters
    ----------
    captions : list of tuple of str
        Each clip's captions, in clip order.
    measure : str
        One of :data:`MEASURES`.
    vectors : dict, optional
        caption -> unit vector (``embeddings``; :func:`load_embeddings`).
    where : str
        Names the vectors' file in messages.
    """

    def __init__(self, captions, measure: str = "lexicon", vectors: dict | None = None,
                 where: str = "corpus.caption_embeddings"):
        if measure not in MEASURES:
            raise ValueError(f"unknown caption similarity {measure!r}; expected one of {MEASURES}")
        self.measure = measure
        counts = np.array([len(c) for c in captions], dtype=np.int64)
        self.first = np.concatenate([[0], np.cumsum(counts)])
        self.clip_of = np.repeat(np.arange(len(captions), dtype=np.int64), counts)
        flat = [c for caps in captions for c in caps]
        self.n_clips, self.n_captions = len(captions), len(flat)
        self._one_each = bool(np.all(counts == 1))
        if measure == "embeddings":
            missing = [c for c in flat if c not in (vectors or {})]
            if missing:
                raise ConfigError(f"{where} lacks vectors for {len(missing)} of {len(flat)} captions "
                                  f"(first: {missing[0][:60]!r}); make the file from this corpus with "
                                  f"`tsel corpus embed`")
            self.vectors = np.stack([vectors[c] for c in flat]).astype(np.float32) if flat else np.zeros((0, 1))
            return
        sets = [frozenset() if measure == "none" else stems(c) if measure == "tfidf" else caption_sets(c, measure)
                for c in flat]
        vocab: dict[str, int] = {}
        for s in sets:
            for w in sorted(s):
                vocab.setdefault(w, len(vocab))
        v = len(vocab)  # id v is padding: weight 0, never in a query
        width = max((len(s) for s in sets), default=1) or 1
        ids = np.full((len(flat), width), v, dtype=np.int32)
        for i, s in enumerate(sets):
            ids[i, : len(s)] = sorted(vocab[w] for w in s)
        self.ids, self.n_terms = ids, (ids < v).sum(axis=1).astype(np.int32)
        self.vocab_size = v
        df = np.bincount(ids[ids < v], minlength=v).astype(np.float64)
        if measure in ("tfidf", "lexicon"):  # lexicon: the concepts' own weights, no idf
            terms = sorted(vocab, key=vocab.get)
            own = np.array([weight(t) for t in terms]) if measure == "lexicon" else None
            idf = np.append(np.log((1.0 + len(flat)) / (1.0 + df)) + 1.0 if own is None else own, 0.0)
            w = idf[ids]
            norms = np.sqrt((w ** 2).sum(axis=1, keepdims=True))
            self.weights = (w / np.where(norms > 0, norms, 1.0)).astype(np.float64)
        else:
            self.weights = (ids < v).astype(np.float64)
        # inverted index: the captions holding term t are post[ptr[t]:ptr[t + 1]]
        rows = np.repeat(np.arange(len(flat), dtype=np.int32), width)
        cols = ids.ravel()
        keep = cols < v
        order = np.argsort(cols[keep], kind="stable")
        self.post = rows[keep][order]
        self.ptr = np.concatenate([[0], np.cumsum(np.bincount(cols[keep], minlength=v))]).astype(np.int64)

    # --- similarities ------------------------------------------------------------------
    def caption_id(self, clip: int, k: int) -> int:
        """The number of caption ``k`` of clip ``clip``."""
        return int(self.first[clip] + k)

    def _query(self, cap: int):
        if self.measure == "embeddings":
            return self.vectors[cap]
        q = np.zeros(self.vocab_size + 1, dtype=np.float64)
        row = self.ids[cap]
        q[row] = self.weights[cap]
        q[self.vocab_size] = 0.0
        return q

    def caption_sims(self, cap: int, caps: np.ndarray, q=None) -> np.ndarray:
        """Similarity of caption ``cap`` to each caption of ``caps`` (float64)."""
        q = self._query(cap) if q is None else q
        if self.measure == "embeddings":
            return (self.vectors[caps] @ q).astype(np.float64)
        if self.measure == "none":
            return np.zeros(len(caps))
        rows = self.ids[caps]
        if self.measure == "tfidf":
            return (q[rows] * self.weights[caps]).sum(axis=1)
        if self.measure == "lexicon":  # as concept_similarity
            return np.sqrt(np.maximum((q[rows] * self.weights[caps]).sum(axis=1), 0.0))
        inter = (q[rows] > 0).sum(axis=1)
        union = self.n_terms[cap] + self.n_terms[caps] - inter
        # both empty: Jaccard 1.0, as jaccard() says
        return np.where(union > 0, inter / np.maximum(union, 1), 1.0)

    def clip_sims(self, cap: int, clips: np.ndarray, q=None) -> np.ndarray:
        """Similarity of caption ``cap`` to each clip of ``clips``: the highest over the clip's captions."""
        clips = np.asarray(clips, dtype=np.int64)
        if self._one_each:
            return self.caption_sims(cap, clips, q)
        counts = self.first[clips + 1] - self.first[clips]
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        caps = np.repeat(self.first[clips] - starts, counts) + np.arange(int(counts.sum()))
        return np.maximum.reduceat(self.caption_sims(cap, caps, q), starts) if len(caps) else np.zeros(0)

    def clip_sim(self, cap: int, clip: int) -> float:
        return float(self.clip_sims(cap, np.array([clip]))[0])

    # --- drawing within a band -----------------------------------------------------------
    def _needed_terms(self, cap: int, lo: float) -> np.ndarray:
        """Query terms of which a caption with similarity >= ``lo`` must share at least one
        (prefix filtering): terms whose weight cannot reach ``lo`` on their own together
        are dropped. TF-IDF: cos <= sqrt(sum of the shared terms' squared query weights),
        so the lightest terms whose squares sum below lo² are dropped (lexicon: the same
        bound on the cosine, lo⁴, the most common terms dropped first). Jaccard: a caption
        sharing m of the query's n terms has J <= m / n, so it shares at least ceil(lo·n)
        of them; the ceil(lo·n) - 1 most common terms are dropped."""
        row = self.ids[cap]
        terms = row[row < self.vocab_size].astype(np.int64)
        if self.measure == "lexicon":
            lo = lo * lo  # the bound is on the cosine, lexicon is its square root
        if self.measure in ("tfidf", "lexicon"):
            w = self.weights[cap][: len(terms)]
            lens = self.ptr[terms + 1] - self.ptr[terms]
            order = np.argsort(w if self.measure == "tfidf" else -lens, kind="stable")
            drop = int(np.searchsorted(np.cumsum(w[order] ** 2), lo * lo - 1e-12, side="left"))
            return np.sort(terms[order[drop:]])
        lens = self.ptr[terms + 1] - self.ptr[terms]
        drop = max(int(np.ceil(lo * len(terms) - 1e-9)) - 1, 0)
        return np.sort(terms[np.argsort(lens, kind="stable")[: len(terms) - drop]])

    def sample(self, rng: np.random.Generator, cap: int, lo: float, hi: float, allowed, batch: int = 256,
               tries: int = 3, excluded=None) -> int | None:
        """A clip whose similarity to caption ``cap`` lies in [lo, hi] and that
        ``allowed(clips) -> bool mask`` accepts, drawn from ``rng``; None if the split has none.

        Candidates come in vectorised batches. For a lexical measure with ``lo > 0`` only
        captions sharing one of :meth:`_needed_terms` can qualify, so candidates are drawn
        from the inverted index, uniformly over the captions holding any of those terms (a
        caption holding m of them is kept with probability 1/m); otherwise uniformly over
        clips. The first qualifying candidate of a batch is taken. After ``tries`` batches
        without one, every possible candidate is scored and one of the qualifying clips is
        drawn uniformly, so a rare band is found when it exists and absence is certain.
        ``excluded(clips) -> bool mask``: clips never taken (a full check found them bad,
        plan/drawn.py), passed over as if drawn and turned down, so that a draw that
        lands on none of them is the draw without them.
        """
        q = self._query(cap)
        lexical = self.measure != "embeddings" and lo > 0
        if lexical:
            terms = self._needed_terms(cap, lo)
            lens = self.ptr[terms + 1] - self.ptr[terms]
            cum = np.cumsum(lens)
            total = int(cum[-1]) if len(cum) else 0
            if total == 0:
                return None
            offset = self.ptr[terms] - (cum - lens)
            needed = np.zeros(self.vocab_size + 1, dtype=bool)
            needed[terms] = True
        for _ in range(tries):
            if lexical:
                u = rng.integers(total, size=batch)
                caps = self.post[offset[np.searchsorted(cum, u, side="right")] + u]
                shared = needed[self.ids[caps]].sum(axis=1)
                clips = self.clip_of[caps][rng.random(batch) * shared < 1.0]
            else:
                clips = rng.integers(self.n_clips, size=batch)
            if not len(clips):
                continue
            s = self.clip_sims(cap, clips, q)
            ok = np.flatnonzero((s >= lo) & (s <= hi))
            if len(ok):
                ok = ok[allowed(clips[ok])]
                if len(ok) and excluded is not None:
                    ok = ok[~excluded(clips[ok])]
                if len(ok):
                    return int(clips[ok[0]])
        if lexical:  # every caption holding a needed term, once
            every = np.unique(self.clip_of[np.concatenate([self.post[self.ptr[t]:self.ptr[t + 1]] for t in terms])])
        else:
            every = np.arange(self.n_clips)
        s = self.clip_sims(cap, every, q)
        ok = every[(s >= lo) & (s <= hi)]
        ok = ok[allowed(ok)] if len(ok) else ok
        while len(ok):
            j = int(ok[rng.integers(len(ok))])
            if excluded is None or not excluded(np.array([j]))[0]:
                return j
            ok = ok[ok != j]
        return None
