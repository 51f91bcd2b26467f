"""Spatial question-answer pairs in a named schema (``tsel export qa DIR --schema NAME``;
docs/spatial-language.md).

Output::

    OUT/
      {split}/qa.jsonl   one row per question, in the schema's columns, with its evidence
      schema.json        the schema, the vocabulary (convention, bins), the question types
                         and the margins answers were decided with
      README.md          the dataset card

Questions are decided per scene by :mod:`tsel_data.scene.questions` on the labels and the
rendered levels with the dataset's own relational margins (``scene.margin_*``); loudness
questions need levels, so recordings get none. Per split and question type the answers are
balanced: every answer class is thinned to as many questions as the rarest one has (which
questions stay is drawn per question, from the dataset seed, the scene and the question);
a type with one answer class only is left out. ``--no-balance`` keeps every question.
"""
from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import TselError
from ..scene.queries import DEFAULT_MARGINS, RELATIONS, stored_margins
from ..scene.questions import QUESTIONS, ask, draw
from ..scene.vocabularies import VOCABULARIES, vocabulary
from .base import SplitResult, Writer, WriterOption
from .captions import jsonl
from .spatial import caption_pool, language_section, levels_known, scene_facts, vocabulary_doc, where_of

QA_FILE, SCHEMA_FILE = "qa.jsonl", "schema.json"
LETTERS = "ABCD"


def _spatialsoundqa(q, facts, n: int) -> dict:
    return {"question_id": n, "scene_id": facts.scene_id, "question_type": q.type.upper(), "question": q.question,
            "answer": q.answer, "evidence": q.evidence}


def _so_qa(q, facts, n: int) -> dict:
    refs = [{"source": k, "caption": facts.names[k], **where_of(facts.sources[k])} for k in q.sources]
    return {"qa_id": f"{facts.scene_id}/{q.key}", "scene_id": facts.scene_id, "task_type": q.type,
            "question": q.question, "answer": q.answer, "canonical_answer": q.canonical, "source_refs": refs,
            "evidence": q.evidence}


def options(q, seed: int, scene_id: str) -> tuple | None:
    """(four options, the answer's letter) of a question: its first three wrong answers
    (the most telling: the other sound compared, the neighbouring bins) and the answer, in
    an order drawn; None when it has fewer than three wrong answers."""
    wrong = list(dict.fromkeys(w for w in q.wrong if w != q.answer))[:3]
    if len(wrong) < 3:
        return None
    order = [[q.answer, *wrong][int(i)] for i in draw(seed, scene_id, q.key, "options").permutation(4)]
    return order, LETTERS[order.index(q.answer)]


def _mcq(q, facts, n: int) -> dict | None:
    found = options(q, facts.seed, facts.scene_id)
    if found is None:
        return None
    opts, letter = found
    return {"qa_id": f"{facts.scene_id}/{q.key}", "scene_id": facts.scene_id, "question_type": q.type,
            "question": q.question, "options": opts, "answer": letter, "answer_text": q.answer,
            "evidence": q.evidence}


@dataclass(frozen=True)
class QaSchema:
    """One row format: ``row(question, scene facts, running number)`` -> a row, or None
    when the question cannot be written in it; its default vocabulary; one line of help."""

    row: Callable
    vocabulary: str
    summary: str


SCHEMAS: dict[str, QaSchema] = {
    "spatialsoundqa": QaSchema(_spatialsoundqa, "bat", "BAT's SpatialSoundQA rows: question_id, question_type, "
                                                       "question, answer"),
    "so-qa": QaSchema(_so_qa, "sectors8", "qa_id, task_type, question, answer, canonical_answer and source_refs "
                                          "(azimuth_deg, elevation_deg, distance_m, caption of each source asked "
                                          "about)"),
    "mcq": QaSchema(_mcq, "elsa", "four options and the answer's letter; the three distractors are answers the "
                                  "labels rule out"),
}


def _types(text) -> tuple:
    names = tuple(t.strip() for t in (text.split(",") if isinstance(text, str) else text) if t.strip())
    bad = [t for t in names if t not in QUESTIONS]
    if bad or not names:
        raise TselError(f"--types {text!r}: {'unknown ' + ', '.join(bad) if bad else 'none given'}; choose from "
                        f"{', '.join(QUESTIONS)}")
    return names


def balance(candidates: list, seed: int) -> tuple:
    """The candidates [(facts, question)] kept when each type's answer classes are thinned
    to the rarest one's count (a type with one class: none kept), and {type: why} of the
    types left out."""
    groups = defaultdict(lambda: defaultdict(list))
    for i, (facts, q) in enumerate(candidates):
        if q.balance is not None:
            groups[q.type][q.balance].append(i)
    drop, dropped = set(), {}
    for t, classes in groups.items():
        if len(classes) < 2:
            drop.update(i for members in classes.values() for i in members)
            dropped[t] = f"one answer only ({next(iter(classes))})"
            continue
        cap = min(len(m) for m in classes.values())
        for members in classes.values():
            order = sorted(members, key=lambda i: (draw(seed, candidates[i][0].scene_id, candidates[i][1].key,
                                                        "keep").random(), i))
            drop.update(order[cap:])
    return [c for i, c in enumerate(candidates) if i not in drop], dropped


class QaWriter(Writer):
    name = "qa"
    summary = ("Spatial question-answer pairs (spatialsoundqa, so-qa, mcq), each answer decided on the labels and "
               "rendered levels with the relational margins, with its evidence: JSONL per split.")
    options = (WriterOption("schema", "Row format: spatialsoundqa (BAT), so-qa, mcq (four options).", "spatialsoundqa",
                            choices=tuple(SCHEMAS)),
               WriterOption("vocabulary", "Whose words the answers use (default: the schema's: spatialsoundqa bat, "
                            "so-qa sectors8, mcq elsa).", choices=tuple(VOCABULARIES)),
               WriterOption("types", f"Question types to ask, comma-separated (default: all: {', '.join(QUESTIONS)}).",
                            parse=_types),
               WriterOption("balance", "Thin each question type's answer classes to the rarest one's count.", True,
                            flag=True))

    def __init__(self, **options):
        super().__init__(**options)
        self.vocab = vocabulary(self.opts["vocabulary"] or SCHEMAS[self.opts["schema"]].vocabulary)
        self.dropped: dict = {}

    def identity(self, doc) -> dict:
        return {**super().identity(doc), "schema": self.opts["schema"], "vocabulary": self.vocab.name,
                "types": ",".join(self.opts["types"] or QUESTIONS), "balance": bool(self.opts["balance"])}

    def check(self, job) -> None:
        job.check_free(SCHEMA_FILE)

    def margins(self, job) -> dict:
        return stored_margins(job.doc.config.get("scene") or {})

    def write_split(self, job, split: str) -> SplitResult:
        schema = SCHEMAS[self.opts["schema"]]
        seed = int(job.doc.raw.get("seed", 0))
        margins = self.margins(job)
        candidates, n_scenes, levels = [], 0, levels_known(job)
        with job.open(split) as ds:
            pool = caption_pool(ds)
            b = job.bar(len(ds), f"qa {split}")
            for scene in job.scenes(ds, audio=False):
                facts = scene_facts(scene, margins, seed, ds.caption_similarity, pool, levels)
                candidates += [(facts, q) for q in ask(facts, self.vocab, self.opts["types"])]
                n_scenes += 1
                b.update()
            b.close()
        asked = Counter(q.type for _, q in candidates)
        writable = [(f, q, row) for f, q in candidates for row in [schema.row(q, f, 0)] if row is not None]
        kept = [(f, q) for f, q, _ in writable]
        if self.opts["balance"]:
            kept, dropped = balance(kept, seed)
            self.dropped[split] = dropped
        rows = [schema.row(q, f, n) for n, (f, q) in enumerate(kept)]
        files = [job.write_text(f"{split}/{QA_FILE}", jsonl(rows))]
        return SplitResult(files, {"scenes": n_scenes, "rows": len(rows),
                                   "types": dict(sorted(Counter(q.type for _, q in kept).items())),
                                   "asked": dict(sorted(asked.items())),
                                   "unwritable": len(candidates) - len(writable),
                                   "left_out": self.dropped.get(split, {})})

    def finish(self, job) -> list:
        doc = {"schema": self.opts["schema"], "summary": SCHEMAS[self.opts["schema"]].summary,
               "question_types": {t: QUESTIONS[t].summary for t in (self.opts["types"] or QUESTIONS)},
               "margins": {RELATIONS[r].margin_key: m for r, m in self.margins(job).items()},
               "margin_defaults": DEFAULT_MARGINS, "balance": bool(self.opts["balance"]),
               "vocabulary": vocabulary_doc(self.vocab)}
        return [job.write_json(SCHEMA_FILE, doc)] + super().finish(job)

    def card_yaml(self, job) -> dict:
        return {"configs": [{"config_name": "default", "default": True,
                             "data_files": [{"split": s, "path": f"{s}/{QA_FILE}"} for s in job.exported_splits()]}]}

    def card_sections(self, job) -> list:
        return language_section(self.vocab, "answers")

    def lines(self, result) -> list:
        out = []
        for split, s in result.splits.items():
            types = ", ".join(f"{t} {n}" for t, n in s.get("types", {}).items())
            out.append(f"{split}: {s['rows']} questions from {s['scenes']} scenes" + (f" ({types})" if types else ""))
            for t, why in s.get("left_out", {}).items():
                out.append(f"  {t} left out: {why}")
        return out + [f"qa ({self.opts['schema']}, {self.vocab.name} words) in {result.out}"]
