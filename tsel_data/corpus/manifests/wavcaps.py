"""WavCaps JSON: ``{"num_captions_per_audio": 1, "data": [{"id", "caption", ...}]}``.

The four released collections (``AudioSet_SL/as_final.json``, ``FreeSound/fsd_final.json``,
``BBC_Sound_Effects/bbc_final.json``, ``SoundBible/sb_final.json``) share ``id``,
``caption``, ``duration`` and ``audio`` and differ in the rest (``description``,
``title``, ``author``, ``href``, ``download_link``, ``category``, ``tags``, ...),
which are ignored. Quirks handled:

- ``audio`` is usually the placeholder ``"wav_path"``, not a path: an ``audio`` value
  is used as the file's path only if it has a folder separator or a file extension,
  otherwise the file name comes from the template;
- AudioSet_SL ids carry an extension (``"Y---1_cCGK4M.wav"``) while the distributed
  audio is FLAC: the template's ``{id}`` is the id without an audio extension
  (``{raw_id}`` is the id as written), and so is ``Clip.id``;
- ids may be JSON numbers; early releases are a bare list instead of ``{"data": [...]}``;
  an entry may have ``captions`` (a list) instead of ``caption``.
"""
from __future__ import annotations

import json
import math
import os

from ..clip import Clip
from ._common import (AudioSearch, DuplicateKey, check_template, duplicate_key, empty_error, fail, gc_paused,
                      manifest_name, read_text, strip_audio_ext, template_list, unique_keys)

TEMPLATE_FIELDS = ("id", "raw_id")
_PLACEHOLDERS = {"wav_path", "flac_path", "audio_path", "path", "none", "null"}


def _audio_value(v) -> str | None:
    """``v`` if it names a file (has a separator or an extension), else None."""
    if not isinstance(v, str):
        return None
    v = v.strip()
    if not v or v.lower() in _PLACEHOLDERS:
        return None
    if "/" in v or "\\" in v or os.path.splitext(v)[1]:
        return v
    return None


def _captions(entry: dict, where: str) -> tuple[str, ...]:
    raw = entry.get("caption")
    if raw is None:
        raw = entry.get("captions")
    if isinstance(raw, str):
        c = raw.strip()
        if c:
            return (c,)
        raw = [raw]
    if not isinstance(raw, list) or not raw:
        raise fail(where, "no caption (expected a \"caption\" string)",
                   "add the caption or delete the entry")
    caps = []
    for c in raw:
        if not isinstance(c, str):
            raise fail(where, f"caption is {type(c).__name__}, not a string",
                       "write the caption as a JSON string")
        c = c.strip()
        if not c:
            raise fail(where, "empty caption", "write the caption or delete the entry")
        caps.append(c)
    return tuple(caps)


@gc_paused()
def read_wavcaps(path, audio_dir=None, template="{id}.flac",
                 split: str | None = None) -> list[Clip]:
    """Read one WavCaps collection JSON into clips, one per entry of ``data``.

    path:      the JSON file (e.g. ``as_final.json``).
    audio_dir: folder of that collection's audio; default the manifest's folder.
    template:  file name for entries without a usable ``audio`` path; fields ``{id}``
               (id without an audio extension) and ``{raw_id}`` (as written). A list of
               patterns is tried in order per entry (the first file that exists).
    split:     split of every clip (WavCaps defines none; default None).

    Returns clips in file order: ``id`` = id without audio extension, ``offset = 0``,
    ``origin = "FILE:N"`` with N the 1-based position in ``data``, ``meta`` =
    ``{"raw_id", "duration" (s, when given)}``.
    Raises ManifestError for invalid JSON (line, column), a wrong layout, an entry
    without id or caption, or an id that appears twice (naming both entries).
    """
    name = manifest_name(path)
    templates = template_list(template, ("{id}.flac",))
    for t in templates:
        check_template(name, t, TEMPLATE_FIELDS)
    text = read_text(name)
    try:
        doc = json.loads(text, object_pairs_hook=unique_keys)
    except DuplicateKey as e:
        raise duplicate_key(name, e) from None
    except json.JSONDecodeError as e:
        raise fail(f"{name}:{e.lineno}", f"not valid JSON ({e.msg} at line {e.lineno} "
                   f"column {e.colno})", "fix the JSON syntax") from None
    entries = doc.get("data") if isinstance(doc, dict) else doc
    if not isinstance(entries, list):
        found = ", ".join(map(repr, doc)) if isinstance(doc, dict) else type(doc).__name__
        raise fail(name, f"expected a JSON object with a \"data\" list; found {found}",
                   "give a WavCaps json ({\"data\": [{\"id\": ..., \"caption\": ...}, ...]})")
    if not entries:
        raise empty_error(name, "no entries in \"data\"")

    search = AudioSearch(name, audio_dir)
    first: dict[str, int] = {}
    clips = []
    for n, entry in enumerate(entries, start=1):
        where = f"{name}:{n}"
        if not isinstance(entry, dict):
            raise fail(where, f"data entry {n} is a {type(entry).__name__}, not an object",
                       "each entry must be {\"id\": ..., \"caption\": ...}")
        raw_id = entry.get("id")
        if isinstance(raw_id, (int, float)) and not isinstance(raw_id, bool):
            raw_id = str(raw_id)
        if not isinstance(raw_id, str) or not raw_id.strip():
            raise fail(where, f"data entry {n} has no \"id\"", "give every entry an id")
        raw_id = raw_id.strip()
        cid = strip_audio_ext(raw_id)
        if cid in first:
            raise fail(where, f"duplicate id {raw_id!r} in data entry {n} "
                       f"(also entry {first[cid]})", "ids must be unique; drop one entry")
        first[cid] = n
        caps = _captions(entry, where)
        rel = _audio_value(entry.get("audio"))
        audio = search.find((rel,) if rel is not None else [t.format(id=cid, raw_id=raw_id) for t in templates])
        meta = {"raw_id": raw_id}
        dur = entry.get("duration")
        if isinstance(dur, (int, float)) and not isinstance(dur, bool) and math.isfinite(dur):
            meta["duration"] = float(dur)
        clips.append(Clip(id=cid, audio=audio, captions=caps, offset=0.0,
                          split=split, origin=where, meta=meta))
    return clips
