"""WebDataset tar shards: one sample per scene, every channel, in the dataset's own coding.

Output::

    OUT/
      {split}/{split}-000000.tar    shards of at most ``shard_size`` bytes (a scene is never split)
      index.json                    per split its shards (file, scenes, bytes), and the audio facts
      README.md                     the dataset card

What a sample holds and how it reads back: :mod:`tsel_data.formats.webdataset`.
"""
from __future__ import annotations

import os
import queue
import threading

import numpy as np

from ..choices import AudioCoding
from ..core.atomic import start_writeback
from ..formats.webdataset import (BLOCK, INDEX_FILE, INDEX_KIND, INDEX_VERSION, audio_member, header_block,
                                  member_bytes, sample_members, shard_name)
from ..store.extents import Extent, audio_extents, read_extent
from .base import Shards, SplitResult, Writer, WriterOption, parse_size

DEFAULT_SHARD_SIZE = "1GB"
WRITEBACK_STEP = 16 << 20  # bytes a tar is written before they go to disk in the background


class TarWriter:
    """A tar file written member by member: the data straight from the arrays, or read
    from the HDF5 shard into one reused buffer (an
    :class:`~tsel_data.store.extents.Extent`; tarfile's loop would copy each 4 MB scene
    through Python in 16 kB pieces). A scene's small members go out in one ``writev``
    with the next scene's audio: a kernel file-to-file copy (``copy_file_range``) between
    small writes was slower here, and its pages read back at half the speed (the stream
    of an export is read from them). The reads and writes run on a thread of their own
    (the calls release the GIL), so the next scene's JSON is made while the last one goes
    to disk; the first error they meet is raised by the next :meth:`add` or by
    :meth:`close`. Members carry mtime 0: the same scenes, the same bytes."""

    def __init__(self, path: str, sources: dict, buf: np.ndarray):
        self.f = open(path, "wb", buffering=0)
        self.bytes = 0
        self.sources = sources  # path -> open descriptor, shared across shards (used by the thread only)
        self.buf = buf  # the largest extent's size, shared across shards too
        self._parts: list = []
        self._pending = 0
        self._synced = 0
        self._error: BaseException | None = None
        self._queue: queue.Queue = queue.Queue(maxsize=8)  # bounds what waits: a scene's parts each
        self._thread = threading.Thread(target=self._run, name="tar-writer", daemon=True)
        self._thread.start()

    def add(self, name: str, chunks) -> None:
        if self._error is not None:
            raise self._error
        size = sum(len(c) for c in chunks)
        header, pad = header_block(name, size), b"\0" * (-size % BLOCK)
        self._parts += [header, *chunks, pad]
        self._pending += size
        self.bytes += len(header) + size + len(pad)  # a long name's PAX record included
        if any(isinstance(c, Extent) for c in chunks) or self._pending > 1 << 22:
            self._flush()  # one extent a batch: the buffer is read into again for the next

    def _flush(self) -> None:
        parts, self._parts, self._pending = self._parts, [], 0
        self._queue.put(parts)

    def _run(self) -> None:
        while (parts := self._queue.get()) is not None:
            if self._error is None:  # after an error the rest is dropped: the file is abandoned
                try:
                    self._write(parts)
                except BaseException as e:  # raised again where the caller is
                    self._error = e

    def _write(self, parts: list) -> None:
        fd, views = self.f.fileno(), []
        for p in parts:
            if isinstance(p, Extent):
                if p.path not in self.sources:
                    self.sources[p.path] = os.open(p.path, os.O_RDONLY)
                p = read_extent(p, self.sources[p.path], self.buf)
            views.append(memoryview(p).cast("B"))
        while views:
            n = os.writev(fd, views[:1024])  # IOV_MAX
            while views and n >= len(views[0]):
                n -= len(views[0])
                views.pop(0)
            if views and n:
                views[0] = views[0][n:]
        written = self.f.tell()
        if written - self._synced >= WRITEBACK_STEP:
            start_writeback(fd, self._synced, written - self._synced)
            self._synced = written

    def close(self) -> None:
        try:
            if self._error is None:
                self._parts.append(b"\0" * (2 * BLOCK))  # the end-of-archive marker
                self._flush()
        finally:
            self._queue.put(None)
            self._thread.join()
            self.f.close()
        if self._error is not None:
            raise self._error




class WebDatasetWriter(Writer):
    name = "webdataset"
    summary = "WebDataset tar shards: every channel in the dataset's own coding, labels, query and record as JSON."
    options = (WriterOption("shard_size", "Most bytes per tar shard (e.g. 500MB, 1GB).", DEFAULT_SHARD_SIZE,
                            parse=parse_size, bound="shard_bytes"),)

    def identity(self, doc) -> dict:
        return {**super().identity(doc), "audio coding": str(doc.raw.get("audio_coding", "float32"))}

    def check(self, job) -> None:
        self._coding = str(job.doc.raw.get("audio_coding", AudioCoding.FLOAT32))

    def write_split(self, job, split: str) -> SplitResult:
        shards = write_tars(job, split, self._coding, self.opts["shard_size"], shard_name)
        return SplitResult([s["file"] for s in shards], {"scenes": sum(s["scenes"] for s in shards),
                                                         "shards": shards})

    def finish(self, job) -> list:
        return [job.write_json(INDEX_FILE, index_doc(job, self._coding))] + super().finish(job)

    def card_yaml(self, job) -> dict:
        return {"configs": [{"config_name": "default", "data_files": [
            {"split": s, "path": f"{s}/{s}-*.tar"} for s in job.exported_splits()]}]}

    def lines(self, result) -> list:
        out = [f"{split}: {v['scenes']} scenes in {len(v['shards'])} tar shard(s) -> {result.out}/{split}/"
               for split, v in result.splits.items()]
        return out + [f"index: {result.out}/{INDEX_FILE}; card: {result.out}/README.md"]


def write_tars(job, split: str, coding: str, max_bytes: int, name_of) -> list[dict]:
    """Every scene of ``split`` into tar shards of at most ``max_bytes`` (a scene that
    alone is larger gets a shard of its own); [{"file", "scenes", "bytes"}]. Raw float32
    and int16 shards give their samples by extent (their bytes copied as they are); others are
    read through the reader."""
    shards: list[dict] = []
    extents = audio_extents(job.root, split, job.receiver) if coding != AudioCoding.FLAC else None
    sources: dict = {}
    buf = np.empty(max((e.nbytes for e in extents or ()), default=0), dtype=np.uint8)
    try:
        with job.open(split) as ds, Shards(job, lambda tmp: TarWriter(tmp, sources, buf)) as out:
            names = ds.channel_names
            b = job.bar(len(ds), f"export {split}")
            for i, scene in enumerate(job.scenes(ds, audio=extents is None)):
                members = sample_members(scene, coding, names, None if extents is None else extents[i])
                size = sum(member_bytes(c) for _, c in members)
                tar = out.current
                if tar is None or tar.bytes + size + 2 * BLOCK > max_bytes:
                    rel = name_of(split, len(shards))
                    tar = out.next(rel)
                    shards.append({"file": rel, "scenes": 0, "bytes": 0})
                for name, chunks in members:
                    tar.add(name, chunks)
                shards[-1]["scenes"] += 1
                shards[-1]["bytes"] = tar.bytes + 2 * BLOCK
                b.update()
            b.close()
    finally:
        for fd in sources.values():
            os.close(fd)
    return shards


def index_doc(job, coding: str) -> dict:
    """``index.json``: what the shards hold, for readers that want lengths and shard lists."""
    doc = job.doc
    return {"kind": INDEX_KIND, "index_version": INDEX_VERSION, "fs": doc.fs, "label_hop": doc.label_hop,
            "format": doc.format, "channel_names": list(doc.channel_names), "audio_coding": coding,
            "members": {"audio": audio_member(coding), "labels": "json", "record": "record.json"},
            "splits": {s: {"scenes": job.summaries[s]["scenes"], "shards": job.summaries[s]["shards"]}
                       for s in job.exported_splits()}}
