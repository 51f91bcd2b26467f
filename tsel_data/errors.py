"""User-facing errors.

Anything a user can fix (a bad manifest row, a missing file, an impossible config)
raises a :class:`TselError`. The CLI prints its message on one line and exits with 2;
it never shows a traceback for these. Library callers can catch the subclasses.
Every error class of the package is defined here, and how a message names a file
(:func:`shown_path`, :func:`tidy_message`).
"""
import os
import re


class TselError(Exception):
    """A mistake in user input: the message says what, where and how to fix it."""


class ManifestError(TselError):
    """A manifest file cannot be read or one of its rows is malformed."""


class AudioError(TselError):
    """An audio file is missing, unreadable or unusable."""


class ConfigError(TselError):
    """A config or preset is invalid."""


class GeometryError(ConfigError):
    """A room, array or source layout that cannot be realised (a kind of config error)."""


class BankError(TselError):
    """An RIR bank is missing, of the wrong kind, or does not hold what was asked for."""


class DatasetError(TselError):
    """An output dataset is missing, incomplete or inconsistent."""


class PredictionError(TselError):
    """A prediction file is malformed or does not match the split."""


class WriteError(DatasetError):
    """A file could not be written: a full disk, a folder that is not writable or not there.

    ``problem`` names the file, says why and what to fix ("cannot write x.wav: disk
    full; no space left on the device; free space or write to another disk").
    ``resumable``: what was written before it stays, and a rerun goes on from there (a
    dataset's shards). How to go on depends on the command that failed: the message
    says it for a library caller, and ``tsel`` for each command (cli/__init__.py), so a
    command without ``--resume`` never advises it.
    """

    def __init__(self, problem: str, resumable: bool = False):
        super().__init__(problem, resumable)  # both in args: the error survives pickling from a worker
        self.problem, self.resumable = problem, resumable

    def __str__(self) -> str:
        return f"{self.problem}, then {RESUME if self.resumable else AGAIN}"


RESUME = "rerun with --resume: finished shards are kept"
AGAIN = "run the command again"


# --- how messages name files --------------------------------------------------------------------


def shown_path(path: str, base: str | None = None) -> str:
    """``path`` as a message names it: relative to ``base`` (the corpus, the dataset)
    when it is inside it, else to the working folder when inside that, else under the
    home folder as ``~/...``, else as it is. No folder of the machine is printed that
    the user did not name, and a name the user gave relative stays relative."""
    full = os.path.abspath(os.path.expanduser(path))
    for root in (base, os.getcwd()):
        if root:
            root = os.path.abspath(os.path.expanduser(root))
            if full == root or full.startswith(root.rstrip(os.sep) + os.sep):
                return os.path.relpath(full, root)
    home = os.path.expanduser("~")
    if home not in ("", os.sep, "~") and full.startswith(home.rstrip(os.sep) + os.sep):
        return "~" + full[len(home.rstrip(os.sep)):]
    return path


# an absolute path begins a message, or follows a space, a quote, a bracket, "=" or ","
_BEFORE = r"(?<![^\s'\"(\[=,])"
# what may follow a folder named alone (not as the start of a longer path)
_AFTER_FOLDER = r"(?=[\s'\":;,)\]]|$)"
# libsndfile repeats the file's name: "cannot read a.wav: Error opening 'a.wav': Format not recognised."
_SNDFILE_OPENING = re.compile(r"Error opening '([^']*)': ")


def tidy_message(message: str) -> str:
    """A message as ``tsel`` prints it: absolute paths under the working folder relative
    to it, those under the home folder as ``~/...`` (:func:`shown_path`), and a file
    that libsndfile names a second time named once."""
    message = _SNDFILE_OPENING.sub(lambda m: "" if message.count(m.group(1)) > 1 else m.group(0), message)
    home = os.path.expanduser("~")
    for root, shown in ((os.getcwd(), "."), (home, "~")):
        root = root.rstrip(os.sep)
        if not root or root == "~":
            continue
        inside = "" if shown == "." else "~/"
        message = re.sub(_BEFORE + re.escape(root) + r"(?:/(?=[^\s/])|" + _AFTER_FOLDER + ")",
                         lambda m: inside if m.group(0).endswith("/") else shown, message)
    return message


def broken_link(path: str) -> str | None:
    """What is wrong when ``path`` is a symbolic link that leads nowhere ("is a symbolic
    link to x.csv, which does not exist", "is a symbolic link that loops: a -> b -> a"),
    else None: a message then says that instead of "not found"."""
    if not os.path.islink(path) or os.path.exists(path):
        return None
    chain, p = [path], path
    while os.path.islink(p) and len(chain) <= 40:
        p = os.path.join(os.path.dirname(p), os.readlink(p))
        if any(os.path.abspath(p) == os.path.abspath(q) for q in chain):
            names = " -> ".join(shown_path(q) for q in [*chain, p])
            return f"is a symbolic link that loops ({names})"
        chain.append(p)
    if len(chain) > 40:
        return "is a symbolic link through too many others"
    through = f" (through {', '.join(shown_path(q) for q in chain[1:-1])})" if len(chain) > 2 else ""
    return f"is a symbolic link to {shown_path(p)}{through}, which does not exist"
