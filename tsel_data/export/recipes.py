"""Recipe releases: a dataset as its plan, config and per-scene checksums, with the list of
clips it needs, and no audio (a few MB). ``tsel generate --from REL --corpus-dir MY_COPY``
rebuilds it, scene by scene bit-identical where the clips are the same. The layout and the
checksums are :mod:`tsel_data.store.release`'s.
"""
from __future__ import annotations

import hashlib
import json
import os
from collections import defaultdict

from ..core.digest import sha256_file
from ..core.version import RENDERER, __version__
from ..errors import DatasetError
from ..scene.recipe import corpus_files
from ..store.layout import CONFIG_FILE, DATASET_FILE, Layout
from ..store.plans import local_roots, read_plan_doc, read_plan_lines
from ..store.release import (CLIPS_FILE, DIGESTS, RELEASE_FILE, RELEASE_KIND, RELEASE_VERSION, checksums_file,
                             plan_file, scene_digest)
from .base import SplitResult, Writer, WriterOption
from .card import config_hash

BUILTIN = {"builtin:demo": "demo_corpus", "builtin:demo-bank": "demo_bank",
           "builtin:demo-recorded": "demo_recordings"}


def recipe_clips(line: str) -> list[str]:
    """The files (relative to the corpus) a recipe line reads: clips, or a recording and
    its labels."""
    return [name for name, _, _ in corpus_files(json.loads(line))]


class RecipesWriter(Writer):
    name = "recipes"
    summary = "A recipe release: plan, config, per-scene checksums and the clips it needs; no audio."
    options = (WriterOption("corpus_dir", "Where the dataset's corpus is now (default: where its plan says).", None),
               WriterOption("bank", "Where the dataset's RIR bank is now (default: where its plan says).", None))

    def check(self, job) -> None:
        layout = Layout(job.root)
        self.plan_doc = read_plan_doc(layout)
        config = local_roots(self.plan_doc["config"], job.root)
        self.corpus = self._root(layout, self.opts["corpus_dir"] or (config.get("corpus") or {}).get("dir", ""))
        self.bank = self._root(layout, self.opts["bank"] or (config.get("room") or {}).get("bank", ""))
        if not self.corpus or not os.path.isdir(self.corpus):
            raise DatasetError(f"the corpus of {job.root} is not at {self.corpus or '(none given)'}; the release "
                               f"lists its clips with their checksums: pass --corpus-dir with where it is now")

    @staticmethod
    def _root(layout: Layout, value: str) -> str:
        if value in BUILTIN:
            return getattr(layout, BUILTIN[value])
        return os.path.abspath(os.path.expanduser(value)) if value else ""

    def write_split(self, job, split: str) -> SplitResult:
        lines = read_plan_lines(Layout(job.root), split)
        rows = []
        with job.open(split) as ds:
            if [json.loads(line)["scene_id"] for line in lines] != ds.scene_ids():
                raise DatasetError(f"{job.root}: the plan of {split} and its shards hold different scenes; run "
                                   f"`tsel check {job.root}` and render the dataset again")
            b = job.bar(len(ds), f"checksums {split}")
            for scene, line in zip(job.scenes(ds), lines):  # scenes first: their end completes the tally
                rows.append({"scene_id": scene.scene_id, "index": int(scene.index), **scene_digest(scene),
                             "clips": recipe_clips(line)})
                b.update()
            b.close()
        files = [job.write_text(plan_file(split), "".join(line + "\n" for line in lines)),
                 job.write_text(checksums_file(split), "".join(json.dumps(r, ensure_ascii=False) + "\n"
                                                                for r in rows))]
        return SplitResult(files, {"scenes": len(rows), "clips": len({c for r in rows for c in r["clips"]})})

    def finish(self, job) -> list:
        splits = job.exported_splits()
        uses: dict[str, dict] = {}
        scenes_of: dict[str, int] = defaultdict(int)
        for split in splits:
            with open(os.path.join(job.out, plan_file(split)), encoding="utf-8") as f:
                for line in f:
                    if not line.strip():
                        continue
                    for name, clip_id, captions in corpus_files(json.loads(line)):
                        entry = uses.setdefault(name, {"clip_id": clip_id, "captions": captions, "splits": []})
                        if captions and not entry["captions"]:  # heard as noise first, a source too: its id
                            entry.update(clip_id=clip_id, captions=captions)
                        if split not in entry["splits"]:
                            entry["splits"].append(split)
                        scenes_of[name] += 1
        clips = []
        b = job.bar(len(uses), "hash clips")
        for name in sorted(uses):
            path = os.path.join(self.corpus, name)
            if not os.path.isfile(path):
                raise DatasetError(f"clip {name} of the plan is not in the corpus at {self.corpus}; pass "
                                   f"--corpus-dir with the corpus the dataset was made from")
            clips.append({"audio": name, **uses[name], "sha256": sha256_file(path), "bytes": os.path.getsize(path),
                          "scenes": scenes_of[name]})
            b.update()
        b.close()
        files = [job.write_text(CLIPS_FILE, "".join(json.dumps(c, ensure_ascii=False) + "\n" for c in clips))]
        for rel in (DATASET_FILE, CONFIG_FILE):
            with open(os.path.join(job.root, rel), encoding="utf-8") as f:
                files.append(job.write_text(rel, f.read()))
        doc = {"kind": RELEASE_KIND, "release_version": RELEASE_VERSION, "tool": "tsel-data", "version": __version__,
               "renderer": RENDERER, "name": job.doc.config.get("name"), "seed": job.doc.raw.get("seed"),
               "config_sha256": config_hash(job.doc.config), "format": job.doc.format,
               "splits": {s: {"scenes": job.summaries[s]["scenes"], "recipes": plan_file(s),
                              "checksums": checksums_file(s)} for s in splits},
               "inputs": {"clips": CLIPS_FILE, "clip_count": len(clips), "bank": self._bank_entry()},
               "checksums": DIGESTS}
        files.append(job.write_json(RELEASE_FILE, doc))
        return files + super().finish(job)

    def _bank_entry(self) -> dict | None:
        """The RIR bank the plan reads: its name and a checksum (of its file, or of the list
        of its files' checksums for a folder bank)."""
        if not self.bank:
            return None
        if os.path.isdir(self.bank):
            listing = []
            for folder, _, names in sorted(os.walk(self.bank)):
                for n in sorted(names):
                    p = os.path.join(folder, n)
                    listing.append([os.path.relpath(p, self.bank).replace(os.sep, "/"), sha256_file(p)])
            digest = hashlib.sha256(json.dumps(listing).encode()).hexdigest()
        elif os.path.isfile(self.bank):
            digest = sha256_file(self.bank)
        else:
            return {"name": os.path.basename(self.bank), "sha256": None}
        return {"name": os.path.basename(os.path.normpath(self.bank)), "sha256": digest}

    def lines(self, result) -> list:
        out = [f"{split}: {v['scenes']} scenes, {v['clips']} clips" for split, v in result.splits.items()]
        total = sum(os.path.getsize(os.path.join(result.out, f)) for fs in result.files.values() for f in fs)
        total += sum(os.path.getsize(os.path.join(result.out, f)) for f in result.shared)
        return out + [f"recipe release in {result.out} ({total / 1e6:.2f} MB; no audio): rebuild with `tsel generate "
                      f"--from {result.out} --corpus-dir YOUR_COPY --out DIR`"]
