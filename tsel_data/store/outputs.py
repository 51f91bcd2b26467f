"""Files a command writes where the user says: ``tsel inspect --png/--wav``, ``tsel stats
--png``, ``tsel corpus synth/prepare/embed``, ``tsel bank build/import``, and the folder of
``tsel export`` (export/base.py). One rule for all of them, unless ``force``:

- nothing goes inside a dataset, an export or an RIR bank folder (the TAU-SRIR DB as
  distributed): a file put there is published, checked or read as part of it;
- nothing replaces a file the command did not write.

How a command knows its own earlier output: once a file is written it is listed in
``.tsel-outputs.json`` (:data:`REGISTRY_FILE`) of the file's folder, with the command and
the file's size and modification time. The file is the command's own while the entry
names that command and the file still has that size and time; a file rewritten since,
by anyone, or written by another command (a bank is not a picture's to replace) is not.
Exports keep the same stamps in their own manifest (export/base.py).
"""
from __future__ import annotations

import fcntl
import json
import os
import stat
from contextlib import contextmanager

from ..banks.tau import is_tau_folder
from ..core.atomic import write_json
from ..core.files import is_regular, replace_problem
from ..errors import DatasetError, TselError, broken_link
from .layout import EXPORT_MANIFEST_FILE, Layout

REGISTRY_FILE = ".tsel-outputs.json"
TOOL = "tsel-data"


def stamp(path: str) -> list | None:
    """``[size, mtime_ns]`` of a regular file (a final symlink is not followed: a rename
    replaces the link, not its target), None for anything else or nothing."""
    try:
        st = os.lstat(path)
    except OSError:
        return None
    return [st.st_size, st.st_mtime_ns] if stat.S_ISREG(st.st_mode) else None


def container(path: str, itself: bool = False) -> tuple[str, str] | None:
    """The dataset, export or bank folder holding ``path`` (its folder or any above it;
    with ``itself``, the folder ``path`` too): ``(what, folder)``, or None."""
    full = os.path.abspath(path)
    folder = os.path.realpath(full if itself else os.path.dirname(full))
    while True:
        if Layout(folder).is_ours():
            return "dataset", folder
        if os.path.isfile(os.path.join(folder, EXPORT_MANIFEST_FILE)):
            return "export", folder
        if is_tau_folder(folder):
            return "RIR bank", folder
        parent = os.path.dirname(folder)
        if parent == folder:
            return None
        folder = parent


def refuse_inside(path: str, force: bool = False, what: str = "", itself: bool = False) -> None:
    """DatasetError when ``path`` would land in a dataset, export or bank folder (unless
    ``force``); ``itself``: ``path`` is a folder to write into, and may not be one either."""
    inside = None if force else container(path, itself)
    if inside:
        kind, folder = inside
        where = "is" if os.path.realpath(path) == folder else "is inside"
        raise DatasetError(f"{what}{path} {where} the {kind} {folder}; write outside the {kind}, or pass --force to "
                           f"write there anyway")


def foreign_file(path: str, why: str) -> DatasetError:
    """The one refusal for an existing file that is not the command's own."""
    return DatasetError(f"{path} already exists and {why}; choose another name, move it away, or pass --force to "
                        f"write over it")


@contextmanager
def claim_outputs(paths, force: bool = False, owner: str = "tsel"):
    """``with claim_outputs([png, wav], force, "tsel inspect"): write them``.

    Every path is checked before anything is written (DatasetError, one line, for the
    first refused); when the block ends, however it ends, the files it wrote are listed
    as ``owner``'s, so a rerun may replace them."""
    before: dict[str, list | None] = {}
    for p in (os.fspath(p) for p in paths if p):
        full = os.path.abspath(p)
        if full in before:
            raise DatasetError(f"{p} is named twice; give each output its own file")
        before[full] = _check(p, full, force, owner)
    try:
        yield
    finally:
        _record(owner, before)


def claim_output(path, force: bool = False, owner: str = "tsel"):
    """:func:`claim_outputs` for one file."""
    return claim_outputs([path], force, owner)


def _check(shown: str, full: str, force: bool, owner: str) -> list | None:
    if os.path.isdir(full):
        raise DatasetError(f"{shown} is a folder; give the name of a file")
    special = replace_problem(full)  # /dev/null, a FIFO: never replaced, --force or not
    if special:
        raise DatasetError(f"{shown} {special}")
    if os.path.basename(full) == REGISTRY_FILE:
        raise DatasetError(f"{shown}: {REGISTRY_FILE} lists what tsel wrote in its folder; choose another name")
    refuse_inside(shown, force)
    now = stamp(full)
    if broken_link(full) and not force:  # "already exists" would send the user looking for a file
        raise DatasetError(f"{shown} {broken_link(full)}; remove the link, choose another name, or pass --force to "
                           f"write in its place")
    if os.path.lexists(full) and not force:
        entry = (_registry(os.path.dirname(full)) or {}).get(os.path.basename(full)) or {}
        if not entry:
            raise foreign_file(shown, f"was not written by {owner}")
        if entry.get("by") != owner:
            raise foreign_file(shown, f"was written by {entry.get('by')}, not by {owner}")
        if entry.get("stamp") != now:
            raise foreign_file(shown, f"changed since {owner} wrote it")
    return now


def _registry(folder: str) -> dict | None:
    """{name: {"by", "stamp"}} of ``folder`` ({} when it has no list); None when the file
    under the list's name is not ours (or unreadable): it is never written over."""
    path = os.path.join(folder, REGISTRY_FILE)
    if not os.path.lexists(path):
        return {}
    if not is_regular(path):
        return None  # a FIFO would keep the read waiting; not ours either way
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, ValueError):
        return None
    files = doc.get("files") if isinstance(doc, dict) and doc.get("tool") == TOOL else None
    return files if isinstance(files, dict) else None


def _record(owner: str, before: dict) -> None:
    """List the files written since their claim (their stamp changed) as ``owner``'s."""
    by_folder: dict[str, dict] = {}
    for full, old in before.items():
        now = stamp(full)
        if now is not None and now != old:
            by_folder.setdefault(os.path.dirname(full), {})[os.path.basename(full)] = {"by": owner, "stamp": now}
    for folder, entries in by_folder.items():
        _update(folder, entries)


def _update(folder: str, entries: dict) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # two commands writing into one folder keep both their entries
        files = _registry(folder)
        if files is None:
            return  # unlisted, the outputs are only refused next time (--force)
        files = {n: e for n, e in files.items() if os.path.lexists(os.path.join(folder, n))}
        files.update(entries)
        write_json(os.path.join(folder, REGISTRY_FILE),
                   {"tool": TOOL, "about": "files tsel-data wrote here; it replaces only these (docs/reliability.md)",
                    "files": dict(sorted(files.items()))})
    except (OSError, TselError):
        pass  # as above: the outputs are whole, a full disk only costs their listing
    finally:
        os.close(fd)
