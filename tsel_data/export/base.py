"""What every export shares: one writer interface, and the run that walks a dataset's
splits into a folder the export owns.

An export folder says whose it is in ``.tsel-export.json`` (:data:`MANIFEST_FILE`): the
writer, the dataset (relative to the folder), the options that make two exports
incompatible (:meth:`Writer.identity`) and every file it wrote, per split, with the size
and modification time it left (store/outputs.py's stamps). So:

- a folder that holds other files (no manifest), or an export of another writer,
  dataset or identity, is refused in one line; ``force`` replaces it (an earlier
  export's files are removed first; other files of the same names are written over);
- exporting some splits into an export of the same kind replaces those splits (their
  files not written again are removed) and keeps the others;
- a file the export did not write, or one changed since it wrote it, is never written
  over (unless ``force``) nor removed;
- ``--out`` is never a dataset, nor inside a dataset, another export or a bank folder
  (the dataset exported, never; the others unless ``force``);
- every file is claimed in ``.tsel-export.journal`` before it is written and written
  under a temporary name, so an interrupted export is still known as ours: running it
  again finishes it.

A writer (one module per format, registered in ``tsel_data/export/__init__.py``)
implements :meth:`Writer.write_split` and perhaps :meth:`Writer.finish`; everything else
is here.
"""
from __future__ import annotations

import json
import math
import os
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from typing import Callable, ClassVar

from ..core.atomic import atomic_output, write_json, write_text
from ..core.progress import bar
from ..core.version import __version__
from ..core.files import check_input, inside, name_problem, replace_problem
from ..errors import DatasetError, TselError, broken_link
from ..store.dataset import DatasetDoc, load_dataset_doc
from ..store.layout import EXPORT_LOCK_FILE, EXPORT_MANIFEST_FILE, Layout
from ..store.lock import export_lock
from ..store.outputs import foreign_file, refuse_inside, stamp
from ..store.reader import SceneDataset, open_dataset
from ..tools.stats import SplitTally, dataset_stats
from .card import FIGURE_FILE, CARD_FILE, card_text, draw_figure

MANIFEST_FILE = EXPORT_MANIFEST_FILE
JOURNAL_FILE = ".tsel-export.journal"
MANIFEST_VERSION = 2  # 2: stamps of the files (version 1 manifests own their files by name)


@dataclass(frozen=True)
class WriterOption:
    """One option of a writer, declared once: the command line (``--name-with-dashes``)
    and the Python keyword (``name``) both follow. ``parse`` turns the command line's
    text into the value (a TselError for a bad one); ``flag``: a boolean switch; ``bound``:
    the setting of the config schema whose bounds the command line holds it to
    (``config.schema.CommandOptions``)."""

    name: str
    help: str
    default: object = None
    choices: tuple = ()
    parse: Callable | None = None
    flag: bool = False
    bound: str = ""


def parse_size(text) -> int:
    """``"500MB"``, ``"1GB"``, ``"2.5G"`` or a number of bytes -> bytes (powers of 1000)."""
    if isinstance(text, (int, float)):
        value = float(text)
    else:
        s = str(text).strip().upper().removesuffix("B")
        scale = {"K": 1e3, "M": 1e6, "G": 1e9, "T": 1e12}.get(s[-1:], 1.0)
        try:
            value = float(s[:-1] if s[-1:] in "KMGT" else s) * scale
        except ValueError:
            value = -1.0
    if not math.isfinite(value) or value < 1:
        raise TselError(f"size {text!r}: expected bytes or a number with KB, MB or GB, e.g. 500MB")
    return int(value)


@dataclass
class SplitResult:
    """What a writer wrote for one split: ``files`` (paths relative to the export, with
    ``/``) and ``summary`` (plain JSON: the counts it reports, kept in the manifest)."""

    files: list
    summary: dict = field(default_factory=dict)


class Writer:
    """One export format. Subclasses set ``name`` (the registry key and the command),
    ``summary`` (one line of help) and ``options``, and implement :meth:`write_split`."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    options: ClassVar[tuple] = ()
    # every export carries a dataset card (README.md); the stats figure costs a second
    COMMON: ClassVar[tuple] = (
        WriterOption("card", "Write the dataset card (README.md).", True, flag=True),
        WriterOption("figure", f"Draw the card's statistics figure ({FIGURE_FILE}).", False, flag=True),
        WriterOption("receiver", "A dataset heard by several receivers (scene.receivers): export this one's audio "
                     "(default: scene.format's)."),
    )

    def __init__(self, **options):
        known = {o.name: o for o in (*self.options, *self.COMMON)}
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise TselError(f"export {self.name}: unknown option(s) {', '.join(unknown)}; it takes "
                            f"{', '.join(known)}")
        self.opts = {}
        for name, o in known.items():
            value = options.get(name, o.default)
            if o.parse is not None and value is not None:
                value = o.parse(value)
            if o.choices and value is not None and value not in o.choices:
                raise TselError(f"export {self.name}: {name} {value!r} is not one of {', '.join(map(str, o.choices))}")
            self.opts[name] = value

    def identity(self, doc: DatasetDoc) -> dict:
        """What two exports into one folder must share ({label: value}; labels read in
        the refusal: "another format mic4 (now foa)")."""
        return {"format": doc.format}

    def check(self, job: "ExportJob") -> None:
        """Refuse, before anything is written, a dataset this format cannot hold."""

    def write_split(self, job: "ExportJob", split: str) -> SplitResult:
        raise NotImplementedError

    def finish(self, job: "ExportJob") -> list:
        """Files that span the splits, written after them (paths relative to the export)."""
        return job.write_card(self.card_yaml(job), self.card_sections(job)) if self.opts["card"] else []

    def card_yaml(self, job: "ExportJob") -> dict:
        """Keys this format adds to the card's YAML header (the Hub's ``configs``)."""
        return {}

    def card_sections(self, job: "ExportJob") -> list:
        """Markdown lines this format adds to the card (what its own files hold)."""
        return []

    def lines(self, result: "ExportResult") -> list:
        """What the command prints."""
        out = [f"{split}: {s.get('scenes', 0)} scenes, {len(result.files[split])} files" for split, s in
               result.splits.items()]
        return out + [f"{self.name} export in {result.out}"]


@dataclass
class ExportResult:
    """``splits``: {split: summary} written now; ``files``: {split: files} and ``shared``."""

    out: str
    writer: str
    splits: dict
    files: dict
    shared: list


class ExportJob:
    """One export run: the dataset, the folder, what the folder held before, and the only
    way writers create files (:meth:`output` and friends), so nothing foreign is written over."""

    def __init__(self, writer: Writer, root: str, out: str, splits: list, force: bool, progress):
        self.writer, self.root, self.out, self.splits = writer, root, out, splits
        self.force, self.progress = force, progress
        self.receiver = writer.opts.get("receiver")
        self.doc = load_dataset_doc(root).heard_by(self.receiver)  # format and channels: the exported receiver's
        self.all_splits = list(self.doc.splits)
        self.identity = {"kind": writer.name, "dataset": _portable(root, out), **writer.identity(self.doc)}
        self.earlier = _earlier(out, writer, self.identity, root, force)
        self._ours = _files_of(self.earlier) | _journal(out, force)
        self._stamps = dict((self.earlier or {}).get("stamps") or {})
        self._claimed: set = set()
        self._journal = None
        self._current = ""
        self._shared: list | None = None
        self.summaries = {s: v["summary"] for s, v in ((self.earlier or {}).get("splits") or {}).items()}
        self._split_files = {s: list(v["files"]) for s, v in ((self.earlier or {}).get("splits") or {}).items()}
        self._tallied: dict = {}  # split -> SplitTally of the scenes a writer read: the card's figures

    # --- reading ----------------------------------------------------------------------
    def open(self, split: str) -> SceneDataset:
        return open_dataset(self.root, split, receiver=self.receiver)

    def scenes(self, ds: SceneDataset, audio: bool = True):
        """Every scene of ``ds`` (a split :meth:`open` gave), in order, ``audio=False``
        without its audio; read through here, a split's scenes are counted for the
        card's statistics as they go, and the card does not read them again."""
        tally = SplitTally(self.root, ds.split) if self.writer.opts.get("card") else None
        for i in range(len(ds)):
            scene = ds.finite(ds.get(i, audio=audio))
            if tally is not None:
                tally.add(scene)
            yield scene
        if tally is not None:
            self._tallied[ds.split] = tally

    def bar(self, total: int, desc: str):
        return bar(total, desc, "scene", self.progress)

    def fold(self, split: str) -> int:
        """A split's number in the dataset (1-based, in dataset.json order)."""
        return self.all_splits.index(split) + 1

    def exported_splits(self) -> list:
        """The splits the export holds after this run, in dataset order."""
        return [s for s in self.all_splits if s in self.summaries]

    # --- writing ----------------------------------------------------------------------
    def path(self, rel: str) -> str:
        """The full path of ``rel``, claimed for this export: a DatasetError when a file
        is there that no export of this kind wrote (unless ``force``), or when ``rel``
        would leave the folder (a name made from a document: a split of dataset.json)."""
        try:
            full = inside(self.out, rel)
        except ValueError as e:
            why = ("a symbolic link in --out leads elsewhere: remove it, or choose another --out"
                   if name_problem(rel) is None else "is dataset.json edited?")
            raise DatasetError(f"{self.root}: the export would write {rel!r}, which {e}; an export writes only inside "
                               f"--out: {why}") from None
        if rel not in self._claimed:
            self.check_free(rel)
            self._journal_line(rel)
            self._claimed.add(rel)
        os.makedirs(os.path.dirname(full), exist_ok=True)
        return full

    def check_free(self, rel: str) -> None:
        """A DatasetError unless ``rel`` may be written: absent, this export's own, or ``force``
        (a writer calls it in :meth:`Writer.check` for files it writes last). A device,
        FIFO, socket or folder under the name is never written over, not even with ``force``."""
        special = replace_problem(os.path.join(self.out, rel))
        if special:
            raise DatasetError(f"{os.path.join(self.out, rel)} {special}")
        if os.path.lexists(os.path.join(self.out, rel)) and not self.force:
            why = self._not_ours(rel)
            if why:
                raise foreign_file(os.path.join(self.out, rel), why)

    def owns(self, rel: str) -> bool:
        """Whether ``rel`` is there as this export (or an earlier one of its kind) left it."""
        return os.path.lexists(os.path.join(self.out, rel)) and self._not_ours(rel) is None

    def _not_ours(self, rel: str) -> str | None:
        """Why the file ``rel`` is not this export's to replace or remove (None: it is).
        A file claimed by an interrupted run has no stamp yet: its name is enough."""
        if rel not in self._ours:
            return f"was not written by tsel export {self.writer.name}"
        known = self._stamps.get(rel)
        if known is not None and known != stamp(os.path.join(self.out, rel)):
            return f"changed since tsel export {self.writer.name} wrote it"
        return None

    def _remove(self, rels) -> None:
        """Remove files of an earlier export that this one does not write again; one
        changed since is someone's now, and stays (unlisted)."""
        _remove(self.out, {rel for rel in rels if self.force or not self._not_ours(rel)})

    @contextmanager
    def output(self, rel: str):
        """``with job.output("train/x.tar") as tmp:`` write ``tmp``; it becomes the file
        when the block ends (atomic_output)."""
        full = self.path(rel)
        with atomic_output(full) as tmp:  # a failure names the file with its folder
            yield tmp

    def write_text(self, rel: str, text: str) -> str:
        write_text(self.path(rel), text)
        return rel

    def write_json(self, rel: str, doc) -> str:
        write_json(self.path(rel), doc)
        return rel

    def write_bytes(self, rel: str, data) -> str:
        with self.output(rel) as tmp, open(tmp, "wb") as f:
            f.write(data)
        return rel

    def write_card(self, yaml_extra: dict, sections: list | None = None) -> list:
        """README.md (and the figure, with the ``figure`` option): the dataset card, with
        the export's own ``sections`` (Markdown lines)."""
        files = []
        figure = None
        stats = dataset_stats(self.root, tallied=self._tallied)
        if self.writer.opts.get("figure"):
            with self.output(FIGURE_FILE) as tmp:
                draw_figure(self.root, tmp, stats)
            figure = FIGURE_FILE
            files.append(FIGURE_FILE)
        text = card_text(self.root, self.doc, export=self.writer.name, splits=self.exported_splits(),
                         yaml_extra=yaml_extra, figure=figure, stats=stats, sections=sections)
        files.append(self.write_text(CARD_FILE, text))
        return files

    # --- the run ----------------------------------------------------------------------
    def begin(self) -> None:
        """Claim the folder: files an interrupted run left of splits it did not finish go
        (they would be rewritten anyway), then the manifest says whose the folder is."""
        os.makedirs(self.out, exist_ok=True)
        self._remove(_journal(self.out, self.force) - _files_of(self.earlier))
        self._ours = _files_of(self.earlier)
        self._write_manifest(complete=False)
        self._journal = open(os.path.join(self.out, JOURNAL_FILE), "w", encoding="utf-8")

    def write_split(self, split: str) -> SplitResult:
        """The writer's files of ``split``; then its files an earlier export wrote that
        this one did not are removed (the dataset has fewer scenes now, shards are sized
        anew), and the manifest records the split."""
        self._current = split
        result = self.writer.write_split(self, split)
        self._remove(set(self._split_files.get(split, ())) - set(result.files))
        self.summaries[split] = result.summary
        self._split_files[split] = list(result.files)
        self._current = ""  # the manifest is written at the end: until then the journal knows what is ours
        return result

    def end(self, shared: list) -> None:
        """The manifest, complete; shared files an earlier export wrote and this one did not go."""
        self._remove(set((self.earlier or {}).get("files") or ()) - set(shared))
        self._shared = list(shared)
        self._write_manifest(complete=True)
        self._journal.close()
        os.remove(os.path.join(self.out, JOURNAL_FILE))

    def _journal_line(self, rel: str) -> None:
        if self._journal is not None:
            self._journal.write(json.dumps([self._current, rel]) + "\n")
            self._journal.flush()

    def _manifest_splits(self) -> dict:
        return {s: {"files": self._split_files[s], "summary": self.summaries[s]} for s in self.exported_splits()}

    def _write_manifest(self, complete: bool) -> None:
        shared = self._shared if self._shared is not None else list((self.earlier or {}).get("files") or ())
        splits = self._manifest_splits()
        listed = [*shared, *(rel for v in splits.values() for rel in v["files"])]
        write_json(os.path.join(self.out, MANIFEST_FILE), {
            "tool": "tsel-data", "version": __version__, "manifest_version": MANIFEST_VERSION,
            "identity": self.identity, "complete": complete, "splits": splits, "files": shared,
            "stamps": self._stamps_of(listed)})

    def _stamps_of(self, rels: list) -> dict:
        """The stamps of the files listed: as written now, or as an earlier export left them."""
        out = {}
        for rel in rels:
            known = stamp(os.path.join(self.out, rel)) if rel in self._claimed else self._stamps.get(rel)
            if known is not None:
                out[rel] = known
        return out


class Shards:
    """Files written one after another, each opened by ``opener(temporary path)`` (a tar
    writer, a Parquet writer: anything with ``close()``). ``next(rel)`` closes the
    current file under its final name and opens the next; leaving the ``with`` block by
    an exception removes the unfinished file."""

    def __init__(self, job: "ExportJob", opener):
        self.job, self.opener = job, opener
        self.current, self._stack = None, None

    def next(self, rel: str):
        self.close()
        self._stack = ExitStack()
        self.current = self.opener(self._stack.enter_context(self.job.output(rel)))
        return self.current

    def close(self) -> None:
        if self._stack is not None:
            stack, current, self._stack, self.current = self._stack, self.current, None, None
            with stack:  # a close that fails (a full disk as a writer flushes) is the file's failed write
                current.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if exc[0] is None:
            self.close()
        elif self._stack is not None:
            try:
                self.current.close()
            except Exception:  # the file is abandoned anyway; the first error is the one to show
                pass
            stack, self._stack, self.current = self._stack, None, None
            stack.__exit__(*exc)
        return False


def run_export(writer: Writer, root: str, out: str, splits=None, force: bool = False,
               progress: bool | None = False) -> ExportResult:
    """Export ``splits`` (default: all) of the dataset ``root`` into ``out`` with ``writer``.

    Raises DatasetError (one line) for an unknown split, an ``out`` that is the dataset
    or inside it, a folder that holds other files or another export (without ``force``),
    and whatever the writer refuses.
    """
    root, out = os.fspath(root), os.fspath(out)
    doc = load_dataset_doc(root)
    all_splits = list(doc.splits)
    splits = list(dict.fromkeys(splits)) if splits else all_splits
    for s in splits:
        if s not in all_splits:
            raise DatasetError(f"{root}: no split {s!r}; available splits: {', '.join(all_splits)}")
    _check_places(root, out, force)
    with _locked(out) as begun:
        job = ExportJob(writer, root, out, splits, force, progress)
        writer.check(job)
        for rel, wanted in ((CARD_FILE, writer.opts["card"]), (FIGURE_FILE, writer.opts["figure"])):
            if wanted:  # written last: refused before the splits, not after
                job.check_free(rel)
        begun.append(True)
        job.begin()
        results = {split: job.write_split(split) for split in splits}
        shared = writer.finish(job)
        job.end(shared)
    return ExportResult(out, writer.name, {s: r.summary for s, r in results.items()},
                        {s: r.files for s, r in results.items()}, shared)


@contextmanager
def _locked(out: str):
    """Hold ``out``'s export lock for the run (store/lock.py): a second export into the
    same folder is refused, never mixed with this one. A run refused before it writes
    anything leaves the folder as it found it: the lock file it made goes, and the folder
    too if it made that. Yields a list the run appends to once it writes."""
    made = not os.path.lexists(out)
    os.makedirs(out, exist_ok=True)
    lock_file = os.path.join(out, EXPORT_LOCK_FILE)
    had_lock = os.path.lexists(lock_file)
    begun: list = []
    with export_lock(out):
        try:
            yield begun
        finally:
            if not begun:  # refused before anything was written: leave no trace
                for remove, path in ((os.remove, None if had_lock else lock_file), (os.rmdir, made and out)):
                    try:
                        if path:
                            remove(path)
                    except OSError:
                        pass


def _check_places(root: str, out: str, force: bool) -> None:
    r, o = os.path.realpath(root), os.path.realpath(out)
    if o == r:
        raise DatasetError(f"--out {out} is the dataset itself; choose a new folder")
    if o.startswith(r + os.sep):
        raise DatasetError(f"--out {out} is inside the dataset {root}; choose a folder outside it")
    if os.path.isfile(out):
        raise DatasetError(f"--out {out} is a file; choose a folder")
    if os.path.exists(out):
        check_input(out, DatasetError, "choose a folder for --out", folder=True)
    if broken_link(out):
        raise DatasetError(f"--out {out} {broken_link(out)}; create the folder it points to, or choose another --out")
    if Layout(out).is_ours():
        raise DatasetError(f"--out {out} is a dataset; export into a folder of its own")
    refuse_inside(out, force, "--out ")


def _portable(root: str, out: str) -> str:
    """The dataset as the manifest names it: relative to the export, so no folder of this
    machine is written into a folder people publish."""
    return os.path.relpath(os.path.realpath(root), os.path.realpath(out) if os.path.exists(out)
                           else os.path.abspath(out)).replace(os.sep, "/")


def read_manifest(out: str) -> dict | None:
    """The manifest of the export in ``out`` (None when there is none; DatasetError when
    it is unreadable, of the wrong shape, or names a file outside ``out``: a manifest can
    come from anywhere, and the files it names are the ones an export replaces and removes)."""
    path = os.path.join(out, MANIFEST_FILE)
    if not os.path.lexists(path):
        return None
    again = "export into a new --out, or pass --force to replace the export"
    check_input(path, DatasetError, again)
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        _check_manifest(doc)
        return doc
    except (OSError, ValueError, RecursionError) as e:
        raise DatasetError(f"{path} is unreadable ({e}); {again}") from None


def _check_manifest(doc) -> None:
    """ValueError unless ``doc`` has a manifest's shape and every name it lists stays in the folder."""
    if not isinstance(doc, dict) or not isinstance(doc.get("identity"), dict):
        raise ValueError("no identity")
    splits, files, stamps = doc.get("splits") or {}, doc.get("files") or [], doc.get("stamps") or {}
    if not isinstance(splits, dict) or not all(isinstance(v, dict) and isinstance(v.get("files", []), list)
                                                for v in splits.values()):
        raise ValueError("'splits' is not {split: {\"files\": [...]}}")
    if not isinstance(files, list) or not isinstance(stamps, dict):
        raise ValueError("'files' is not a list of names, or 'stamps' not an object")
    for rel in [*files, *(r for v in splits.values() for r in v.get("files", [])), *stamps]:
        why = name_problem(rel)
        if why or rel in (MANIFEST_FILE, JOURNAL_FILE, EXPORT_LOCK_FILE):
            raise ValueError(f"it lists {rel!r} as a file of the export, which {why or 'is the export’s own'}")


def _earlier(out: str, writer: Writer, identity: dict, root: str, force: bool) -> dict | None:
    """The export already in ``out`` when this one may add to it; None for a new or empty
    folder (or one ``force`` takes over). Refuses anything else."""
    if not os.path.isdir(out):
        return None
    try:
        doc = read_manifest(out)
    except DatasetError:
        if not force:
            raise
        doc = None
    if doc is None:
        held = sorted(n for n in os.listdir(out) if n not in (JOURNAL_FILE, EXPORT_LOCK_FILE))
        if held and not force:
            raise DatasetError(f"{out} holds files that are not a tsel export ({', '.join(held[:3])}"
                               f"{', ...' if len(held) > 3 else ''}); export into a new or empty --out, or pass "
                               f"--force to write into it (files of the same names are replaced)")
        return None
    theirs = doc["identity"]
    differ = []
    for key, mine in identity.items():
        other = theirs.get(key)
        if key == "dataset":
            same = os.path.realpath(os.path.join(out, str(other))) == os.path.realpath(root)
            other, mine = os.path.normpath(os.path.join(os.path.abspath(out), str(other))), os.path.abspath(root)
        else:
            same = other == mine
        if not same:
            differ.append(f"{key} {other} (now {mine})")
    if not differ:
        return doc
    if not force:
        raise DatasetError(f"{out} holds an export of another {', '.join(differ)}; adding this one would mix them: "
                           f"export into another --out, or pass --force to replace it")
    _remove(out, _files_of(doc) | _journal(out, force) | {MANIFEST_FILE, JOURNAL_FILE})
    return None


def _files_of(doc: dict | None) -> set:
    if not doc:
        return set()
    files = set(doc.get("files") or ())
    for v in (doc.get("splits") or {}).values():
        files |= set(v.get("files") or ())
    return files


def _journal_entries(out: str, force: bool = False) -> list:
    """(split, file) of every claim in the journal; a name that would leave the folder is
    refused (the journal is only ever written by an export: it was edited), or with
    ``force`` left out (never removed)."""
    path = os.path.join(out, JOURNAL_FILE)
    entries = []
    if not os.path.lexists(path):
        return entries
    check_input(path, DatasetError, "remove it: an export writes it as a file")
    try:
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                try:
                    split, rel = json.loads(line)
                except (ValueError, TypeError, RecursionError):
                    continue  # a line cut by a kill: its file was never written
                why = name_problem(rel)
                if why and force:
                    continue
                if why:
                    raise DatasetError(f"{path}:{n}: names {rel!r}, which {why}; an export writes only inside its "
                                       f"folder: the journal was edited, remove it")
                entries.append((split, rel))
    except OSError:
        pass
    return entries


def _journal(out: str, force: bool = False) -> set:
    """The files an interrupted run claimed."""
    return {rel for _, rel in _journal_entries(out, force)}


def _remove(out: str, rels) -> None:
    for rel in sorted(rels):
        try:
            path = inside(out, rel)  # never a file outside the export, whatever its manifest says
        except ValueError:
            continue
        if os.path.isdir(path) and not os.path.islink(path):
            continue
        try:
            os.remove(path)
        except FileNotFoundError:
            continue
        folder = os.path.dirname(path)
        while os.path.realpath(folder) != os.path.realpath(out):  # folders the export emptied go too
            try:
                os.rmdir(folder)
            except OSError:
                break
            folder = os.path.dirname(folder)
