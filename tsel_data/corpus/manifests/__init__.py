"""Manifest readers: one module per format, all returning ``list[Clip]``.

=========  ===================================================  ==========================
format     file                                                 reader
=========  ===================================================  ==========================
audiocaps  CSV ``audiocap_id,youtube_id,start_time,caption``    :func:`read_audiocaps`
clotho     CSV ``file_name,caption_1..caption_5``               :func:`read_clotho`
wavcaps    JSON ``{"data": [{"id", "caption", ...}]}``          :func:`read_wavcaps`
plain      CSV ``path,caption[,id][,split]`` or JSONL           :func:`read_plain`
=========  ===================================================  ==========================

Every reader takes ``(path, audio_dir=None, ..., split=None)``, resolves relative audio
paths against ``audio_dir`` (default: the manifest's folder), and raises a one-line
:class:`~tsel_data.errors.ManifestError` naming the file and row for any bad input.
Readers never touch the audio files; :func:`missing_audio` checks they exist.
"""
from __future__ import annotations

import csv
import inspect
import json
import os

from ...errors import ManifestError
from ..clip import Clip
from ._common import AUDIO_EXTENSIONS, check_file, fail, manifest_name, split_aliases
from .audiocaps import read_audiocaps
from .clotho import read_clotho
from .plain import JSONL_EXTENSIONS, read_plain
from .wavcaps import read_wavcaps

__all__ = ["AUDIO_EXTENSIONS", "FORMATS", "READERS", "detect_format", "missing_audio", "read_audiocaps",
           "read_clotho", "read_manifest", "read_plain", "read_wavcaps", "split_aliases"]

READERS = {
    "audiocaps": read_audiocaps,
    "clotho": read_clotho,
    "wavcaps": read_wavcaps,
    "plain": read_plain,
}
FORMATS = tuple(READERS)

_HEADERS = ("audiocaps (audiocap_id,youtube_id,start_time,caption), clotho (file_name,"
            "caption_1..caption_5), plain (path,caption[,id][,split])")


def _first_line(name: str, limit: int = 1 << 16) -> str:
    check_file(name)  # a FIFO would keep the read waiting
    with open(name, "rb") as f:
        head = f.read(limit)
    # Undecodable bytes are the chosen reader's to report, with their line and offset.
    return head.split(b"\n", 1)[0].decode("utf-8-sig", errors="replace").strip()


def detect_format(path) -> str:
    """Name of the manifest format of ``path``, from its extension and first line.

    ``.json`` -> wavcaps; ``.jsonl``/``.ndjson`` -> plain; otherwise a first line
    starting with ``{`` or ``[`` is JSON (wavcaps if it holds a ``data`` list or is
    not a complete object on its own, else JSONL -> plain), and a CSV header is matched
    against the AudioCaps, Clotho and plain columns.
    """
    name = manifest_name(path)
    check_file(name)
    ext = os.path.splitext(name)[1].lower()
    if ext == ".json":
        return "wavcaps"
    if ext in JSONL_EXTENSIONS:
        return "plain"
    first = _first_line(name)
    if not first:
        raise fail(f"{name}:1", "cannot detect the manifest format: the first line is empty",
                   f"start with a header; known headers: {_HEADERS}")
    if first[0] == "[":
        return "wavcaps"
    if first[0] == "{":
        try:
            obj = json.loads(first)
        except json.JSONDecodeError:
            return "wavcaps"  # a pretty-printed JSON document
        return "wavcaps" if isinstance(obj, dict) and "data" in obj else "plain"
    header = {h.strip().lower() for h in next(csv.reader([first]))}
    if {"youtube_id", "start_time", "caption"} <= header:
        return "audiocaps"
    if "file_name" in header and any(h.startswith("caption_") for h in header):
        return "clotho"
    if {"path", "caption"} <= header:
        return "plain"
    raise fail(f"{name}:1", f"cannot detect the manifest format from the header {first!r}",
               f"known headers: {_HEADERS}; or pass the format explicitly")


def read_manifest(path, format: str = "auto", audio_dir=None, **options) -> list[Clip]:
    """Read any supported manifest: ``format`` is one of :data:`FORMATS` or ``"auto"``.

    ``options`` go to the reader (``template=`` for audiocaps and wavcaps, ``split=``
    for all); an option the reader does not take is a ManifestError.
    """
    name = manifest_name(path)
    if format == "auto":
        format = detect_format(name)
    reader = READERS.get(format)
    if reader is None:
        raise ManifestError(f"{name}: unknown manifest format {format!r}; "
                            f"use one of {', '.join(FORMATS)} or 'auto'")
    accepted = [p for p in inspect.signature(reader).parameters if p not in ("path", "audio_dir")]
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        raise ManifestError(f"{name}: the {format} reader has no option "
                            f"{', '.join(unknown)}; its options are {', '.join(accepted)}")
    return reader(name, audio_dir=audio_dir, **options)


def missing_audio(clips) -> list[Clip]:
    """The clips whose ``audio`` file does not exist, in input order.

    One ``os.path.exists`` per distinct path (a file shared by several clips is checked
    once). Existence only: whether the audio is readable is the audio stage's job.
    """
    exists: dict[str, bool] = {}
    out = []
    for c in clips:
        ok = exists.get(c.audio)
        if ok is None:
            ok = exists[c.audio] = os.path.isfile(c.audio)
        if not ok:
            out.append(c)
    return out
