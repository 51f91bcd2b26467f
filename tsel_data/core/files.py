"""What a path is before it is opened, and names read from files kept inside their folder.

Three checks every input and every name goes through, so no reader opens a FIFO (it
waits for a writer forever), a device (``/dev/zero`` never ends) or a folder, and no
name written in a file (an export's manifest, a release's list, a plan line) reaches
outside the folder it belongs to:

- :func:`path_problem` says what is wrong with a path that should be a regular file
  (or a folder), from ``lstat``/``stat`` alone: never opened;
- :func:`name_problem` says why a name read from a file may not be joined to its folder
  (absolute, ``..``, empty, control characters);
- :func:`unicode_match` finds a file whose name differs only in its Unicode
  normalisation (a corpus copied from macOS stores ``café.wav`` decomposed, NFD, while
  its manifest spells it composed, NFC).
"""
from __future__ import annotations

import os
import stat
import unicodedata

from ..errors import TselError, broken_link

# what each kind of special file is called in a message
_KINDS = ((stat.S_ISFIFO, "a FIFO (a named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def special_kind(mode: int) -> str | None:
    """What a file of ``mode`` is when it is neither a regular file nor a folder."""
    return next((name for test, name in _KINDS if test(mode)), None)


def path_problem(path, folder: bool = False) -> str | None:
    """Why ``path`` is not a regular file we can read (``folder``: not a folder), or None.

    The answer completes "PATH ...": ``is not a regular file: it is a FIFO (a named
    pipe)``, ``is a folder, not a file``, ``is a symbolic link that loops (a -> b -> a)``, ``does not
    exist``, ``is not readable``. Nothing is opened: a FIFO or a device is judged by its
    mode, so asking never waits and never reads."""
    path = os.fspath(path)
    link = broken_link(path)
    if link:
        return link
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "does not exist"
    except OSError as e:  # ELOOP, ENAMETOOLONG, EACCES on a folder above
        return f"cannot be read ({e.strerror or e})"
    if stat.S_ISDIR(st.st_mode):
        return None if folder else "is a folder, not a file"
    kind = special_kind(st.st_mode)
    if kind:
        return f"is not {'a folder' if folder else 'a regular file'}: it is {kind}"
    if folder:
        return "is a file, not a folder"
    if not os.access(path, os.R_OK):
        return "is not readable (permissions)"
    return None


def check_input(path, error=None, fix: str = "", folder: bool = False) -> None:
    """Refuse an input ``path`` that exists but is no regular file (``folder``: no folder),
    or is a symbolic link that loops or leads nowhere: ``error`` (a TselError class) in
    one line, "PATH is not a regular file: it is a FIFO (a named pipe); FIX". A path that does not
    exist is left to the caller, whose message knows what was looked for."""
    path = os.fspath(path)
    if not os.path.lexists(path):
        return
    why = path_problem(path, folder)
    if why:
        raise (error or TselError)(f"{path} {why}" + (f"; {fix}" if fix else ""))


def replace_problem(path) -> str | None:
    """Why nothing may be written over ``path``, not even with ``--force``, or None: it is
    a device, a FIFO, a socket or a folder (a rename would put a file in place of
    ``/dev/null``). A regular file, a symbolic link (the link is replaced, never what it
    points to) and nothing at all may be replaced, by the rules of who owns them."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode):
        return None
    what = "a folder" if stat.S_ISDIR(mode) else special_kind(mode)
    return f"is {what}, not a file: nothing is written in its place, not even with --force; choose another name"


def blocked_folder(path) -> str | None:
    """Why the folders of ``path`` cannot be made ("P is a file, not a folder", "P is not
    a folder: it is a FIFO ..."): the nearest part of it that exists and is no folder,
    for the ENOTDIR or EEXIST of ``os.makedirs``; None when there is none."""
    p = os.path.abspath(os.fspath(path))
    while True:
        if os.path.lexists(p) and not os.path.isdir(p):
            return f"{p} {path_problem(p, folder=True)}"
        up = os.path.dirname(p)
        if up == p:
            return None
        p = up


def is_regular(path) -> bool:
    """Whether ``path`` is (or links to) a regular file: what may be opened for reading."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def name_problem(name) -> str | None:
    """Why ``name``, read from a file (a manifest, a journal, a release's list), may not
    be joined to the folder it belongs to, or None. A name is relative, uses ``/``, and
    has no empty, ``.`` or ``..`` part: whatever the file says, the path stays inside."""
    if not isinstance(name, str):
        return f"is {type(name).__name__}, not a file name"
    if not name:
        return "is empty"
    if any(ord(c) < 32 or c == "\x7f" for c in name):
        return "holds a control character"
    if name.startswith("/") or "\\" in name or (len(name) > 1 and name[1] == ":"):
        return "is an absolute path; names here are relative to their folder"
    parts = name.split("/")
    if ".." in parts:
        return "climbs out of its folder (..)"
    if any(p in ("", ".") for p in parts):
        return "has an empty or '.' part"
    return None


def inside(folder: str, name) -> str:
    """``folder/name`` for a name that passed :func:`name_problem` (ValueError otherwise),
    also when a link on the way points elsewhere: the real path must stay in ``folder``."""
    why = name_problem(name)
    if why:
        raise ValueError(why)
    full = os.path.join(folder, name)
    real, top = os.path.realpath(full), os.path.realpath(folder)
    if real != top and not real.startswith(top.rstrip(os.sep) + os.sep):
        raise ValueError(f"leads out of its folder, to {real}")
    return full


def unicode_match(path: str) -> str | None:
    """``path`` itself when it exists; else the path of a file whose name differs from it
    only in Unicode normalisation (NFC against NFD, part by part), or None."""
    if os.path.lexists(path):
        return path
    head, tail = os.path.split(path)
    if not tail:
        return None
    if head and not os.path.isdir(head):
        head = unicode_match(head)
        if head is None:
            return None
        if os.path.lexists(os.path.join(head, tail)):
            return os.path.join(head, tail)
    if tail.isascii():
        return None
    want = unicodedata.normalize("NFC", tail)
    try:
        names = os.listdir(head or ".")
    except OSError:
        return None
    for name in names:
        if not name.isascii() and unicodedata.normalize("NFC", name) == want:
            return os.path.join(head, name)
    return None
