"""lhotse manifests: recordings, supervisions and cuts that ``lhotse`` loads as they are,
beside one audio file per scene.

Output::

    OUT/
      audio/{split}/{scene_id}.wav          every channel (32-bit float or 16-bit; .flac for flac datasets)
      tsel_recordings_{split}.jsonl.gz      RecordingSet: one multi-channel Recording per scene
      tsel_supervisions_{split}.jsonl.gz    SupervisionSet: one supervision per source
      tsel_cuts_{split}.jsonl.gz            CutSet: one MultiCut per scene, its supervisions and recording inline
      README.md

A recording's channel ids are 0..C-1 in the dataset's channel order (the names are in
each cut's ``custom["channel_names"]``). Supervision ``{scene_id}-{k}`` is source k (0:
the target, whose ``text`` is the query); its ``custom`` holds ``role``, ``clip_id``,
``captions``, ``label_hop`` and the per-frame ``azimuth``, ``elevation``, ``distance``
(null where positionless) and ``active``. A cut's ``custom`` holds the query fields,
``format``, ``channel_names``, ``mic_positions`` and the scene's ``record``.

Audio paths are relative to OUT, so the export can move: load with
``CutSet.from_file(p).with_recording_path_prefix(OUT)``. Written with the standard
library: lhotse (which needs torch) is only needed to read them.
"""
from __future__ import annotations

import gzip
import io
import json

from .base import SplitResult, Writer
from ..formats.coding import file_audio


def manifest_names(split: str) -> dict:
    """{kind: file} of a split's manifests."""
    return {kind: f"tsel_{kind}_{split}.jsonl.gz" for kind in ("recordings", "supervisions", "cuts")}


def _labels(a) -> list:
    return [None if v != v else float(v) for v in a.tolist()]  # NaN != NaN: positionless frames are null


def recording(scene, path: str) -> dict:
    channels = list(range(scene.audio.shape[0]))
    samples = int(scene.audio.shape[1])
    return {"id": scene.scene_id, "sources": [{"type": "file", "channels": channels, "source": path}],
            "sampling_rate": scene.fs, "num_samples": samples, "duration": samples / scene.fs,
            "channel_ids": channels}


def supervisions(scene) -> list[dict]:
    """One per source; the target's text is the query."""
    duration = scene.audio.shape[1] / scene.fs
    channels = list(range(scene.audio.shape[0]))
    out = []
    for k in range(scene.n_sources):
        src = scene.record.sources[k] if scene.record is not None and k < len(scene.record.sources) else None
        out.append({"id": f"{scene.scene_id}-{k}", "recording_id": scene.scene_id, "start": 0.0, "duration": duration,
                    "channel": channels, "text": scene.query if k == 0 else None,
                    "custom": {"role": "target" if k == 0 else "interferer",
                               "clip_id": None if src is None else src.clip_id,
                               "captions": [] if src is None else list(src.captions), "label_hop": scene.label_hop,
                               "azimuth": _labels(scene.azimuth[k]), "elevation": _labels(scene.elevation[k]),
                               "distance": _labels(scene.distance[k]), "active": scene.active[k].tolist()}})
    return out


def cut(scene, rec: dict, sups: list, channel_names) -> dict:
    return {"id": scene.scene_id, "start": 0.0, "duration": rec["duration"], "channel": rec["channel_ids"],
            "supervisions": sups, "recording": rec,
            "custom": {"query": scene.query, "query_type": scene.query_type, "query_relation": scene.query_relation,
                       "pairing": scene.pairing, "split": scene.split, "index": int(scene.index), "format": scene.format,
                       "channel_names": list(channel_names), "mic_positions": scene.mic_positions.tolist(),
                       "record": None if scene.record is None else scene.record.to_json()},
            "type": "MultiCut"}


def jsonl_gz(items) -> bytes:
    """JSON lines, gzipped without a time stamp or a name (the same items, the same bytes)."""
    buf = io.BytesIO()
    with gzip.GzipFile(fileobj=buf, mode="wb", mtime=0, filename="") as f:
        for item in items:
            f.write((json.dumps(item, ensure_ascii=False) + "\n").encode("utf-8"))
    return buf.getvalue()


class LhotseWriter(Writer):
    name = "lhotse"
    summary = "lhotse manifests (recordings, supervisions, cuts) and one multi-channel audio file per scene."

    def identity(self, doc) -> dict:
        return {**super().identity(doc), "audio coding": str(doc.raw.get("audio_coding", "float32"))}

    def write_split(self, job, split: str) -> SplitResult:
        coding = str(job.doc.raw.get("audio_coding", "float32"))
        files, recs, sups, cuts = [], [], [], []
        with job.open(split) as ds:
            b = job.bar(len(ds), f"export {split}")
            for scene in job.scenes(ds):
                ext, data = file_audio(scene.audio, coding, scene.fs)
                rel = f"audio/{split}/{scene.scene_id}.{ext}"
                files.append(job.write_bytes(rel, data))
                rec, sup = recording(scene, rel), supervisions(scene)
                recs.append(rec)
                sups.extend(sup)
                cuts.append(cut(scene, rec, sup, ds.channel_names))
                b.update()
            b.close()
        names = manifest_names(split)
        for kind, items in (("recordings", recs), ("supervisions", sups), ("cuts", cuts)):
            files.append(job.write_bytes(names[kind], jsonl_gz(items)))
        return SplitResult(files, {"scenes": len(recs), "supervisions": len(sups), "manifests": names})

    def lines(self, result) -> list:
        out = [f"{split}: {v['scenes']} recordings, {v['supervisions']} supervisions -> {result.out}/{v['manifests']['cuts']}"
               for split, v in result.splits.items()]
        return out + [f"audio: {result.out}/audio/ (paths relative to {result.out}: "
                      f"CutSet.from_file(...).with_recording_path_prefix({result.out!r}))"]
