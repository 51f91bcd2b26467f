"""Spatial captions in a named vocabulary (``tsel export captions DIR --vocabulary NAME``;
docs/spatial-language.md).

Output::

    OUT/
      {split}/captions.jsonl   one row per (scene, source): the clip's caption with the
                               spatial words, the words alone, their bins, the template,
                               the descriptors
      {split}/scenes.jsonl     one row per scene: every source with its time span, words
                               and level (Sci-Phi's layout)
      vocabulary.json          the vocabulary: convention, bins, templates, motion words
      README.md                the dataset card

Words come from the labels of the frames each source sounds in
(:mod:`tsel_data.scene.vocabularies`): a word is written only where it is true on every one
of them, so a source in a gap of the vocabulary, one crossing a boundary, or one without
a position gets no direction word; the summary counts each (``no_direction``).
"""
from __future__ import annotations

import json
from collections import Counter

from ..scene.questions import draw
from ..scene.vocabularies import VOCABULARIES, vocabulary
from .base import SplitResult, Writer, WriterOption
from .spatial import language_section, levels_known, room_facts, source_facts, vocabulary_doc, where_of

CAPTIONS_FILE, SCENES_FILE, VOCABULARY_FILE = "captions.jsonl", "scenes.jsonl", "vocabulary.json"


def jsonl(rows) -> str:
    return "".join(json.dumps(r, ensure_ascii=False) + "\n" for r in rows)


class CaptionsWriter(Writer):
    name = "captions"
    summary = ("Spatial captions in a named vocabulary (elsa, sectors8, oclock, bat): a JSONL row per source and per "
               "scene, with the words' bins, true on every frame a source sounds in.")
    options = (WriterOption("vocabulary", "Whose words: elsa, sectors8 (Sci-Phi), oclock, bat (SpatialSoundQA).",
                            "elsa", choices=tuple(VOCABULARIES)),)

    def identity(self, doc) -> dict:
        return {**super().identity(doc), "vocabulary": self.opts["vocabulary"]}

    def check(self, job) -> None:
        job.check_free(VOCABULARY_FILE)  # written last: refused before the splits, not after

    def write_split(self, job, split: str) -> SplitResult:
        v = vocabulary(self.opts["vocabulary"])
        seed = int(job.doc.raw.get("seed", 0))
        rows, scenes, why = [], [], Counter()
        counts = Counter()
        levels = levels_known(job)
        with job.open(split) as ds:
            b = job.bar(len(ds), f"captions {split}")
            for scene in job.scenes(ds, audio=False):
                rec = scene.record
                room = room_facts(rec)
                room_bin = v.room(room)
                counts["no_room"] += v.rooms and room_bin is None
                listed = []
                for k, src in enumerate(rec.sources):
                    facts = source_facts(scene, k, levels)
                    bins = v.bins(facts, room)
                    spatial = v.describe(facts, room)
                    clip = src.captions[int(draw(seed, scene.scene_id, "caption", k).integers(len(src.captions)))] \
                        if src.captions else ""
                    template = int(draw(seed, scene.scene_id, "template", k).integers(len(v.templates)))
                    reason = v.why_no_direction(facts)
                    if reason:
                        why[reason] += 1
                    if "c50" in v.extras and facts.c50_db is None and len(facts.azimuth):
                        counts["no_c50"] += 1
                    rows.append({"scene_id": scene.scene_id, "source": k, "role": src.role, "clip_id": src.clip_id,
                                 "caption": v.caption(clip, spatial, template),
                                 "template": f"{v.name}-{template}" if spatial else "plain", "clip_caption": clip,
                                 "spatial": spatial, "vocabulary": v.name, "bins": bins,
                                 "no_direction": reason, "descriptors": _descriptors(src, facts, room)})
                    listed.append((clip, facts, bins, k))
                noise = [(n.kind, n.level_dbfs) for n in rec.noise if n.level_dbfs is not None]
                scenes.append({"scene_id": scene.scene_id, "caption": v.scene([(c, f) for c, f, _, _ in listed], room,
                                                                               noise),
                               "vocabulary": v.name, "room": room_bin,
                               "sources": [{"source": k, "clip_caption": c, "bins": bb,
                                            "span_s": None if f.span is None else [round(x, 3) for x in f.span],
                                            "level_dbfs": f.level_db} for c, f, bb, k in listed],
                               "noise": [{"kind": kd, "level_dbfs": lv} for kd, lv in noise]})
                b.update()
            b.close()
        files = [job.write_text(f"{split}/{CAPTIONS_FILE}", jsonl(rows)),
                 job.write_text(f"{split}/{SCENES_FILE}", jsonl(scenes))]
        return SplitResult(files, {"scenes": len(scenes), "rows": len(rows),
                                   "no_direction": dict(sorted(why.items())), **{k: int(n) for k, n in counts.items()}})

    def finish(self, job) -> list:
        files = [job.write_json(VOCABULARY_FILE, vocabulary_doc(vocabulary(self.opts["vocabulary"])))]
        return files + super().finish(job)

    def card_yaml(self, job) -> dict:
        splits = job.exported_splits()
        return {"configs": [
            {"config_name": "default", "default": True,
             "data_files": [{"split": s, "path": f"{s}/{CAPTIONS_FILE}"} for s in splits]},
            {"config_name": "scenes", "data_files": [{"split": s, "path": f"{s}/{SCENES_FILE}"} for s in splits]}]}

    def card_sections(self, job) -> list:
        return language_section(vocabulary(self.opts["vocabulary"]), "captions")

    def lines(self, result) -> list:
        out = []
        for split, s in result.splits.items():
            gaps = ", ".join(f"{n} {k}" for k, n in s.get("no_direction", {}).items())
            out.append(f"{split}: {s['rows']} source captions, {s['scenes']} scene captions"
                       + (f"; no direction word: {gaps}" if gaps else ""))
        return out + [f"captions ({self.opts['vocabulary']}) in {result.out}"]


def _descriptors(src, facts, room) -> dict:
    """What is known about a source, beside its words: its place (means over its active
    frames), time span, level, motion class, acoustic descriptors, and the room's."""
    return {**where_of(facts), "span_s": None if facts.span is None else [round(x, 3) for x in facts.span],
            "level_dbfs": facts.level_db, "motion": facts.motion, "acoustics": getattr(src, "acoustics", None),
            "room": {"floor_area_m2": None if room.floor_area_m2 is None else round(room.floor_area_m2, 3),
                     "volume_m3": None if room.volume_m3 is None else round(room.volume_m3, 3),
                     "t30_s": None if room.t30_s is None else round(room.t30_s, 4)}}
