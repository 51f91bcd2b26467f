"""Clotho caption CSV: ``file_name,caption_1,...,caption_5``, one row per clip.

Clotho's files are ``clotho_captions_{development,validation,evaluation}.csv``; audio
files sit in one folder per split under their ``file_name`` (which may contain spaces
and commas, hence quoted).
"""
from __future__ import annotations

import re

from ..clip import Clip
from ._common import AudioSearch, CsvTable, empty_error, fail, gc_paused, manifest_name, pick_split, read_text

_CAPTION_COL = re.compile(r"caption_(\d+)$")


@gc_paused()
def read_clotho(path, audio_dir=None, split: str | None = None) -> list[Clip]:
    """Read a Clotho caption CSV into clips, one per row.

    path:      the CSV; columns ``file_name`` and ``caption_1`` .. ``caption_N`` (Clotho
               has N = 5; any N >= 1 is read, in column-number order).
    audio_dir: folder of the split's audio files, or several tried in order; default the
               manifest's folder.
    split:     split of every clip; default from the file name (``development`` ->
               ``train``, ``validation`` -> ``val``, ``evaluation`` -> ``test``).

    Returns clips in file order with ``id = file_name`` (unique in Clotho; the stem
    alone need not be), ``audio = audio_dir/file_name``, ``offset = 0``.
    Raises ManifestError for a missing column, an empty file_name or caption, or a
    file_name that appears twice (naming both lines).
    """
    name = manifest_name(path)
    hint = "file_name,caption_1,caption_2,caption_3,caption_4,caption_5"
    table = CsvTable(name, read_text(name), ("file_name", "caption_1"), hint)
    cap_cols = sorted((int(m.group(1)), i) for i, h in enumerate(table.header)
                      if (m := _CAPTION_COL.match(h)))
    cap_idx = [i for _, i in cap_cols]
    i_file = table.index["file_name"]

    search = AudioSearch(name, audio_dir)
    split = pick_split(split, name)
    first_line: dict[str, int] = {}
    clips = []
    for line, row in table.rows():
        fname = row[i_file].strip()
        if not fname:
            raise fail(f"{name}:{line}", "malformed row: empty file_name",
                       "fill in the audio file name or delete the row")
        if fname in first_line:
            raise fail(f"{name}:{line}",
                       f"duplicate file_name {fname!r} (also on line {first_line[fname]})",
                       "each clip must appear on one row; merge or delete the duplicate")
        first_line[fname] = line
        caps = tuple(row[i].strip() for i in cap_idx)
        for caption, i in zip(caps, cap_idx):
            if not caption:
                raise fail(f"{name}:{line}", f"empty caption in column {table.header[i]}",
                           "write the caption or delete the row")
        clips.append(Clip(id=fname, audio=search.find((fname,)), captions=caps, offset=0.0,
                          split=split, origin=f"{name}:{line}"))
    if not clips:
        raise empty_error(name, "no clip rows after the header")
    return clips
