"""Shared plumbing of the manifest readers: file access, CSV rows with line numbers,
path resolution, split inference, audio templates and error messages.

Every reader reports a user mistake as a one-line :class:`ManifestError` of the form
``FILE:ROW: what is wrong; how to fix it``. ``ROW`` is the physical line number in the
file, 1-based, the CSV header being line 1 (for a record whose quoted caption spans
several lines, the line where the record starts). For JSON (WavCaps) it is the
1-based position of the entry in the ``data`` list.
"""
from __future__ import annotations

import contextlib
import csv
import gc
import io
import os
import re
import string
import unicodedata
from typing import Iterator, Sequence

from ...core.files import path_problem, unicode_match
from ...errors import ManifestError

AUDIO_EXTENSIONS = (".wav", ".flac", ".mp3", ".ogg", ".opus", ".m4a", ".aif", ".aiff")

_SPLIT_WORDS = {
    "train": "train", "training": "train", "development": "train",
    "val": "val", "valid": "val", "validation": "val",
    "test": "test", "testing": "test", "eval": "test", "evaluation": "test",
}


def fail(where: str, what: str, fix: str) -> ManifestError:
    """Build the one-line error ``where: what; fix`` (newlines escaped, never wrapped)."""
    msg = f"{where}: {what}; {fix}"
    return ManifestError(msg.replace("\r", "\\r").replace("\n", "\\n"))


def manifest_name(path) -> str:
    """The manifest path as the user gave it: what error messages and origins show."""
    return os.fspath(path)


def check_file(name: str) -> None:
    """Raise if ``name`` is not an existing regular file."""
    if not os.path.exists(name):
        raise fail(name, "manifest file not found",
                   "check the path (relative paths are taken from the current directory "
                   f"{os.getcwd()!r})")
    if os.path.isdir(name):
        raise fail(name, "is a directory, not a manifest file",
                   "pass the CSV/JSON/JSONL file itself")
    problem = path_problem(name)  # a FIFO or device would block or never end
    if problem:
        raise fail(name, problem, "pass the manifest file itself")


def read_text(name: str) -> str:
    """The whole file decoded as UTF-8 (a leading BOM is dropped).

    Raises ManifestError naming the line and byte offset of the first invalid byte.
    """
    check_file(name)
    try:
        with open(name, "rb") as f:
            data = f.read()
    except OSError as e:
        raise fail(name, f"cannot read the manifest ({e.strerror or e})",
                   "check the file's permissions") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise fail(f"{name}:{line}",
                   f"not UTF-8 (invalid byte 0x{data[e.start]:02x} at byte offset {e.start})",
                   "re-save the manifest as UTF-8, e.g. "
                   "`iconv -f latin1 -t utf-8 IN > OUT`") from None


class DuplicateKey(ValueError):
    """A JSON object of a manifest names a key twice (json keeps the last one silently)."""


def unique_keys(pairs: list) -> dict:
    """``object_pairs_hook`` for manifests: a key given twice (``"caption"`` twice) is
    refused, not read as one of its values."""
    obj = dict(pairs)
    if len(obj) != len(pairs):
        seen: set = set()
        raise DuplicateKey(next(k for k, _ in pairs if k in seen or seen.add(k)))
    return obj


def duplicate_key(where: str, e: DuplicateKey) -> ManifestError:
    return fail(where, f"key {e.args[0]!r} appears twice in one object", "remove one of them (several captions go "
                "in one list: \"captions\": [...])")


def empty_error(name: str, what: str = "no clips") -> ManifestError:
    return fail(name, f"{what} (the manifest is empty)",
                "add at least one row, or check that this is the right file")


class CsvTable:
    """A CSV manifest: normalised header and rows with their line numbers.

    header: column names stripped and lower-cased. rows(): yields ``(line, fields)``
    for every non-blank record, after checking it has as many fields as the header.
    """

    def __init__(self, name: str, text: str, required: Sequence[str], hint: str):
        self.name = name
        # strict: a quote left open or text after a closing quote is an error on its row,
        # rather than silently swallowing the following rows into one caption.
        self._reader = csv.reader(io.StringIO(text, newline=""), strict=True)
        header: list[str] = []
        try:
            for header in self._reader:
                if header:
                    break
        except csv.Error as e:
            raise fail(f"{name}:{self._reader.line_num}", f"unreadable CSV header ({e})",
                       "fix the header line") from None
        if not header:
            raise empty_error(name, "no header and no rows")
        self.header_line = self._reader.line_num
        self.header = [h.strip().lower() for h in header]
        self.index = {}
        for i, h in enumerate(self.header):
            if h and h in self.index:  # read by name, the second would be ignored without a word
                raise fail(f"{name}:{self.header_line}",
                           f"column {h!r} appears twice (columns {self.index[h] + 1} and {i + 1})",
                           "rename or remove one of them (one caption per row, or caption_1, caption_2, ... "
                           "where the format reads several)")
            self.index[h] = i
        missing = [c for c in required if c not in self.index]
        if missing:
            raise fail(f"{name}:{self.header_line}",
                       f"missing column(s) {', '.join(missing)}; found: {','.join(self.header)}"
                       f"; required: {','.join(required)}",
                       f"the first line must be the header ({hint})")

    def rows(self) -> Iterator[tuple[int, list[str]]]:
        n = len(self.header)
        reader = self._reader
        prev = reader.line_num
        name = self.name
        try:
            for row in reader:
                line = prev + 1
                prev = reader.line_num
                if len(row) != n:
                    if not row:  # blank line
                        continue
                    raise fail(f"{name}:{line}",
                               f"malformed row: {len(row)} fields, the header has {n} "
                               f"({','.join(self.header)})",
                               "put double quotes around fields that contain commas")
                yield line, row
        except csv.Error as e:
            raise _csv_error(name, prev + 1, reader.line_num, e) from None


def _csv_error(name: str, line: int, reached: int, e: csv.Error) -> ManifestError:
    """The one line for a record the csv module refuses. A field over its size limit is
    a quote opened and never closed when the record ran on over many lines (the rows
    after it swallowed), else a field that long (quoting is not the cure)."""
    if "field larger than field limit" not in str(e):
        return fail(f"{name}:{line}", f"malformed CSV ({e})", "quote the whole field if it holds commas, quotes or "
                    "line breaks, and double the quotes inside (\"\")")
    limit = csv.field_size_limit()
    if reached - line > 1:
        return fail(f"{name}:{line}", f"a field runs on over lines {line}-{reached} past {limit:,} characters",
                    "a quote opened on this line is never closed: close it, or double a quote meant literally (\"\")")
    return fail(f"{name}:{line}", f"a field holds more than {limit:,} characters",
                "no caption is that long: shorten it, or check that this column holds what the header says")


def base_dir(name: str, audio_dir) -> str:
    """Directory relative audio paths resolve against: ``audio_dir`` or the manifest's folder."""
    if audio_dir is None:
        return os.path.dirname(os.path.abspath(name))
    return os.path.abspath(os.path.expanduser(os.fspath(audio_dir)))


def resolve(base: str, rel: str) -> str:
    """``rel`` joined to ``base`` unless absolute (``~`` expanded), normalised.

    ``base`` must be absolute and normalised (as :func:`base_dir` returns it).
    """
    # Fast path for the usual plain relative name: nothing normpath would change.
    if _SIMPLE and rel and rel[0] not in "/~." and "/." not in rel and "//" not in rel:
        return base + "/" + rel if base != "/" else "/" + rel
    if rel.startswith("~"):
        rel = os.path.expanduser(rel)
    return os.path.normpath(os.path.join(base, rel))


_SIMPLE = os.sep == "/" and os.altsep is None


@contextlib.contextmanager
def gc_paused():
    """Pause the cyclic garbage collector while a reader builds its clips.

    Readers allocate several objects per row and no reference cycles; with the
    collector running, its generation scans cost ~30 % of parsing a 50k-row manifest.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def infer_split(name: str) -> str | None:
    """Split named by the manifest's file name, or None.

    ``train.csv`` / ``clotho_captions_development.csv`` -> ``train``; ``val``,
    ``valid``, ``validation`` -> ``val``; ``test``, ``eval``, ``evaluation`` -> ``test``
    (Clotho's development/validation/evaluation). None when no such word, or several.
    """
    stem = os.path.splitext(os.path.basename(name))[0].lower()
    found = {_SPLIT_WORDS[w] for w in re.split(r"[^a-z0-9]+", stem) if w in _SPLIT_WORDS}
    return found.pop() if len(found) == 1 else None


def split_aliases(split: str) -> tuple[str, ...]:
    """The folder or file words that name ``split``: ``train`` -> ``train``, ``training``,
    ``development``; ``val`` -> ``val``, ``valid``, ``validation``; any other name itself."""
    canon = _SPLIT_WORDS.get(split.lower(), split)
    return tuple(dict.fromkeys([split] + [w for w, c in _SPLIT_WORDS.items() if c == canon]))


def pick_split(split: str | None, name: str) -> str | None:
    return split if split is not None else infer_split(name)


def check_template(name: str, template: str, allowed: Sequence[str]) -> None:
    """Raise unless ``template`` is a str.format pattern using only ``allowed`` fields, as
    they are: no attribute or index access, conversion or format spec (a template is
    user input; ``{id.__class__}`` or ``{id:>999999999}`` must not run)."""
    listed = ", ".join("{" + a + "}" for a in allowed)
    try:
        parsed = list(string.Formatter().parse(template))
    except ValueError as e:
        raise fail(name, f"bad audio template {template!r} ({e})",
                   f"use fields {listed} and double braces for literal ones") from None
    for _, field, spec, conversion in parsed:
        if field is None:
            continue
        if field not in allowed:
            shown = "{" + field + "}" if field else "{}"
            raise fail(name, f"unknown field {shown} in audio template {template!r}",
                       f"allowed fields: {listed}")
        if spec or conversion:
            raise fail(name, f"field {{{field}}} of audio template {template!r} has a format spec or conversion",
                       f"write the fields plainly: {listed}")
    try:  # catches bad format specs (e.g. {id:d}) before any row is read
        template.format_map({a: "x" for a in allowed})
    except (ValueError, KeyError, IndexError, AttributeError, TypeError) as e:
        raise fail(name, f"bad audio template {template!r} ({e})",
                   f"fields are strings; use {listed} without format specs") from None


def template_list(template, default: Sequence[str]) -> tuple[str, ...]:
    """The audio templates a reader tries: ``template`` (a string, or a sequence tried in
    order), or ``default`` when it is None or empty."""
    if not template:
        return tuple(default)
    return (template,) if isinstance(template, str) else tuple(template)


class FileIndex:
    """Which files exist, one directory listing per folder (a 50k-file folder lists in
    tens of milliseconds; a ``stat`` per candidate name would take seconds). Names match
    whatever their Unicode normalisation: a corpus copied from macOS stores ``café.wav``
    decomposed (NFD) while its manifest spells it composed (NFC)."""

    def __init__(self):
        self._names: dict[str, frozenset] = {}
        self._audio: dict[str, bool] = {}
        self._nfc: dict[str, dict] = {}  # folder -> {NFC of a non-ASCII name: the name on disk}

    def listing(self, folder: str) -> frozenset:
        """The names in ``folder`` (empty if it does not exist)."""
        names = self._names.get(folder)
        if names is None:
            try:
                names = frozenset(os.listdir(folder))
            except OSError:  # no such folder, or not readable: nothing is there
                names = frozenset()
            self._names[folder] = names
        return names

    def holds_audio(self, folder: str) -> bool:
        """Whether any name in ``folder`` ends with an audio extension."""
        held = self._audio.get(folder)
        if held is None:
            held = self._audio[folder] = any(n.lower().endswith(AUDIO_EXTENSIONS) for n in self.listing(folder))
        return held

    def exists(self, base: str, rel: str) -> bool:
        """Whether ``rel`` (relative to the absolute folder ``base``, or absolute) exists."""
        return self.on_disk(base, rel) is not None

    def on_disk(self, base: str, rel: str) -> str | None:
        """The path of ``rel`` (relative to the absolute folder ``base``, or absolute) as
        the disk spells it, or None when no file has that name in any normalisation."""
        if _SIMPLE and "/" not in rel and rel[:1] not in ("~", "."):
            folder, name = base, rel  # a plain name: no path to build
        else:
            folder, name = os.path.split(resolve(base, rel))
        if name in self.listing(folder):
            return resolve(folder, name)
        if name.isascii():
            return None
        if folder not in self._nfc:
            self._nfc[folder] = {unicodedata.normalize("NFC", n): n for n in self.listing(folder) if not n.isascii()}
        found = self._nfc[folder].get(unicodedata.normalize("NFC", name))
        if found is not None:
            return resolve(folder, found)
        there = unicode_match(os.path.join(folder, name))  # a folder on the way spelt otherwise
        return os.path.normpath(there) if there else None


class AudioSearch:
    """Where a manifest's audio files are: each clip's candidate names (relative, or
    absolute) tried in each folder ``audio_dir`` gives (one folder, or several in order:
    a split's own folder first, then the one all splits share), the first that exists
    being the clip's audio; when none does, the first name in the first folder (the clip
    check then reports it missing). ``audio_dir`` None: the manifest's folder."""

    def __init__(self, name: str, audio_dir=None):
        dirs = [audio_dir] if audio_dir is None or isinstance(audio_dir, (str, os.PathLike)) else list(audio_dir)
        self.bases = tuple(dict.fromkeys(base_dir(name, d) for d in dirs or [None]))
        self.index = FileIndex()

    def find(self, rels: Sequence[str]) -> str:
        """The audio file of a clip whose file may be called any of ``rels``, as the disk
        spells its name (a name the manifest writes composed may be stored decomposed)."""
        if len(rels) == 1 and len(self.bases) == 1 and rels[0].isascii():
            return resolve(self.bases[0], rels[0])  # one name, one folder: no need to look at the disk
        for base in self.bases:
            for rel in rels:
                if "/" not in rel and not self.index.holds_audio(base):
                    break  # no audio file here at all (nothing downloaded yet): no candidate can exist
                found = self.index.on_disk(base, rel)
                if found is not None:
                    return found
        return resolve(self.bases[0], rels[0])


def strip_audio_ext(s: str) -> str:
    """``Yabc.wav`` -> ``Yabc``; other strings unchanged."""
    if "." not in s:
        return s
    root, ext = os.path.splitext(s)
    return root if ext.lower() in AUDIO_EXTENSIONS else s
