"""Plain manifests for your own audio: CSV with header ``path,caption[,id][,split]``, or
JSONL with one object per line ``{"path": ..., "caption": ..., "id": ..., "split": ...}``.

Several rows with the same id (or, without an id, the same path) are one clip with
several captions, in file order, as in AudioCaps.
"""
from __future__ import annotations

import json
import os

from ..clip import Clip
from ._common import (AudioSearch, CsvTable, DuplicateKey, duplicate_key, empty_error, fail, gc_paused,
                      manifest_name, read_text, unique_keys)

JSONL_EXTENSIONS = (".jsonl", ".ndjson")


def _is_jsonl(name: str, text: str) -> bool:
    if os.path.splitext(name)[1].lower() in JSONL_EXTENSIONS:
        return True
    if name.lower().endswith(".csv"):
        return False
    return text.lstrip()[:1] == "{"


def _csv_records(name: str, text: str):
    """Yield ``(line, path, [caption], id | None, split | None)`` from a CSV."""
    hint = "path,caption and optionally id,split"
    table = CsvTable(name, text, ("path", "caption"), hint)
    i_path, i_cap = table.index["path"], table.index["caption"]
    i_id, i_split = table.index.get("id"), table.index.get("split")
    for line, row in table.rows():
        yield (line, row[i_path], [row[i_cap]],
               None if i_id is None else row[i_id],
               None if i_split is None else row[i_split])


def _jsonl_records(name: str, text: str):
    """Yield ``(line, path, captions, id | None, split | None)`` from JSONL."""
    for line, s in enumerate(text.split("\n"), start=1):
        if not s.strip():
            continue
        where = f"{name}:{line}"
        try:
            obj = json.loads(s, object_pairs_hook=unique_keys)
        except DuplicateKey as e:
            raise duplicate_key(where, e) from None
        except json.JSONDecodeError as e:
            raise fail(where, f"line is not valid JSON ({e.msg} at column {e.colno})",
                       "write one JSON object per line") from None
        if not isinstance(obj, dict):
            raise fail(where, f"line is a JSON {type(obj).__name__}, not an object",
                       "write {\"path\": ..., \"caption\": ...} on each line")
        if "path" not in obj or ("caption" not in obj and "captions" not in obj):
            raise fail(where, f"missing key(s): found {','.join(obj)}; required: path,caption",
                       "give every line a \"path\" and a \"caption\"")
        caps = obj.get("caption", obj.get("captions"))
        caps = caps if isinstance(caps, list) else [caps]
        for c in caps:
            if not isinstance(c, str):
                raise fail(where, f"caption is a {type(c).__name__}, not a string",
                           "write captions as JSON strings")
        p = obj["path"]
        if not isinstance(p, str):
            raise fail(where, f"path is a {type(p).__name__}, not a string",
                       "write the audio path as a JSON string")
        cid = obj.get("id")
        if isinstance(cid, (int, float)) and not isinstance(cid, bool):
            cid = str(cid)
        sp = obj.get("split")
        yield line, p, caps, cid if isinstance(cid, str) else None, \
            sp if isinstance(sp, str) else None


@gc_paused()
def read_plain(path, audio_dir=None, split: str | None = None) -> list[Clip]:
    """Read a plain CSV or JSONL manifest into clips.

    path:      ``*.csv`` (header ``path,caption[,id][,split]``, other columns ignored) or
               ``*.jsonl`` (keys ``path``, ``caption`` (string or list), ``id``, ``split``).
               Other extensions: JSONL if the text starts with ``{``, else CSV.
    audio_dir: folder relative ``path`` values resolve against; default the manifest's folder.
    split:     split for rows whose ``split`` is missing or empty (default None; the file
               name is not used: your file names are yours). A row's ``split`` wins.

    Clip ``id`` is the row's ``id``, or ``path`` as written when there is none. Rows with
    the same id are grouped into one clip (captions in file order); they must agree on
    path and split. Raises ManifestError (file, line) for every malformed input.
    """
    name = manifest_name(path)
    text = read_text(name)
    records = _jsonl_records(name, text) if _is_jsonl(name, text) else _csv_records(name, text)
    default_split = split

    groups: dict[str, list] = {}  # id -> [line, path, split, captions]
    for line, p, caps, cid, sp in records:
        p = p.strip()
        if not p:
            raise fail(f"{name}:{line}", "malformed row: empty path",
                       "fill in the audio file path or delete the row")
        caps = [c.strip() for c in caps]
        if not caps or not all(caps):
            raise fail(f"{name}:{line}", "empty caption", "write the caption or delete the row")
        cid = (cid or "").strip() or p
        sp = (sp or "").strip() or default_split
        g = groups.get(cid)
        if g is None:
            groups[cid] = [line, p, sp, caps]
            continue
        if g[1] != p:
            raise fail(f"{name}:{line}", f"id {cid!r} has path {p!r} here but {g[1]!r} "
                       f"on line {g[0]}", "one id is one audio file: fix the id or the path")
        if g[2] != sp:
            raise fail(f"{name}:{line}", f"id {cid!r} has split {sp!r} here but {g[2]!r} "
                       f"on line {g[0]}", "all rows of a clip must have the same split")
        g[3].extend(caps)
    if not groups:
        raise empty_error(name, "no rows")

    search = AudioSearch(name, audio_dir)
    return [Clip(id=cid, audio=search.find((p,)), captions=tuple(caps), offset=0.0,
                 split=sp, origin=f"{name}:{line}")
            for cid, (line, p, sp, caps) in groups.items()]
