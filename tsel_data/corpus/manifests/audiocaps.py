"""AudioCaps CSV: ``audiocap_id,youtube_id,start_time,caption``, one row per caption.

The train split has one caption per clip, val and test five, and the five rows of a
clip are not adjacent in the official files. Rows with the same
``(youtube_id, start_time)`` become one :class:`Clip` carrying all their captions in
file order. Downloads are cut to the 10 s clip already, so ``offset`` is 0 and
``start_time`` is kept in ``meta`` only.
"""
from __future__ import annotations

import re

from ..clip import Clip
from ._common import (AudioSearch, CsvTable, check_template, empty_error, fail, gc_paused, manifest_name, pick_split,
                      read_text, template_list)

COLUMNS = ("audiocap_id", "youtube_id", "start_time", "caption")
TEMPLATE_FIELDS = ("youtube_id", "audiocap_id", "start_time")
# What AudioCaps downloads are called by the common download tools (plain ids, AudioSet's
# Y prefix, id and start, the caption id), WAV or FLAC: the default tries them in turn.
DEFAULT_TEMPLATES = ("{youtube_id}.wav", "Y{youtube_id}.wav", "{youtube_id}_{start_time}.wav", "{audiocap_id}.wav",
                     "{youtube_id}.flac", "Y{youtube_id}.flac", "{youtube_id}_{start_time}.flac",
                     "{audiocap_id}.flac")
_SECONDS = re.compile(r"\d+(\.\d*)?|\.\d+", re.ASCII)  # plain decimal: no sign, exponent, nan, _


@gc_paused()
def read_audiocaps(path, audio_dir=None, template=None, split: str | None = None) -> list[Clip]:
    """Read an AudioCaps caption CSV into clips, one per ``(youtube_id, start_time)``.

    path:      the CSV (``train.csv``, ``val.csv``, ``test.csv`` or any name).
    audio_dir: folder of the downloaded audio, or several tried in order; default the
               manifest's folder.
    template:  audio file name inside ``audio_dir``, a ``str.format`` pattern with fields
               ``{youtube_id}``, ``{audiocap_id}`` (the clip's first row) and
               ``{start_time}`` (as written), e.g. ``Y{youtube_id}.wav`` or
               ``{audiocap_id}.wav``; may contain sub-folders. A list of patterns is
               tried in order per clip: the first file that exists is the clip's audio
               (none: the first pattern's). Default: :data:`DEFAULT_TEMPLATES`, the
               names the common download tools give, so mixed downloads just work.
    split:     split of every clip; default from the file name (``train.csv`` ->
               ``train``, ``val``, ``test``), else None.

    Returns clips in order of their first row: ``id = f"{youtube_id}_{start_time}"``,
    ``offset = 0``, ``origin = "FILE:LINE"`` of the first row, ``meta`` =
    ``{"youtube_id", "start_time" (s, float), "audiocap_ids" (list, file order)}``.
    Audio files are not opened or checked (see :func:`missing_audio`).
    Raises ManifestError (file and line) for every malformed input.
    """
    name = manifest_name(path)
    templates = template_list(template, DEFAULT_TEMPLATES)
    for t in templates:
        check_template(name, t, TEMPLATE_FIELDS)
    table = CsvTable(name, read_text(name), COLUMNS, ",".join(COLUMNS))
    i_aid, i_yt, i_st, i_cap = (table.index[c] for c in COLUMNS)

    # key -> [line, youtube_id, start_time text, start_time s, audiocap_ids, captions]
    groups: dict[tuple[str, str], list] = {}
    for line, row in table.rows():
        yt = row[i_yt].strip()
        st = row[i_st].strip()
        key = (yt, st)
        g = groups.get(key)
        if g is None:
            if not yt:
                raise fail(f"{name}:{line}", "malformed row: empty youtube_id",
                           "fill in the YouTube id or delete the row")
            if not _SECONDS.fullmatch(st):
                raise fail(f"{name}:{line}",
                           f"malformed row: start_time {st!r} is not a number of seconds >= 0",
                           "write the clip start in seconds, e.g. 30")
            g = groups[key] = [line, yt, st, float(st), [], []]
        aid = row[i_aid].strip()
        if not aid:
            raise fail(f"{name}:{line}", "malformed row: empty audiocap_id",
                       "fill in the AudioCaps caption id or delete the row")
        cap = row[i_cap].strip()
        if not cap:
            raise fail(f"{name}:{line}", "empty caption",
                       "write the caption or delete the row")
        g[4].append(aid)
        g[5].append(cap)
    if not groups:
        raise empty_error(name, "no caption rows after the header")

    search = AudioSearch(name, audio_dir)
    split = pick_split(split, name)
    clips = []
    for line, yt, st, start, aids, caps in groups.values():
        audio = search.find([t.format(youtube_id=yt, audiocap_id=aids[0], start_time=st) for t in templates])
        clips.append(Clip(
            id=f"{yt}_{st}",
            audio=audio,
            captions=tuple(caps),
            offset=0.0,
            split=split,
            origin=f"{name}:{line}",
            meta={"youtube_id": yt, "start_time": start, "audiocap_ids": aids},
        ))
    return clips
