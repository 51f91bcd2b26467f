"""What a folder holds and which processes are still there: the before-and-after
evidence of the trust, reliability and signal tests."""
from __future__ import annotations

import os
import subprocess

from tsel_data.core.digest import sha256_file


def data_files(d) -> dict:
    """sha256 of the dataset's data (shards, plan, dataset.json), not seals or the corpus."""
    out = {}
    for root, _, names in os.walk(d):
        for f in names:
            rel = os.path.relpath(os.path.join(root, f), d)
            if rel.startswith("demo-corpus") or f.endswith(".seal.json") or f == ".tsel.lock":
                continue
            out[rel] = sha256_file(os.path.join(root, f))
    return out


def tmp_files(d) -> list[str]:
    return sorted(os.path.relpath(os.path.join(r, f), d) for r, _, names in os.walk(d) for f in names if ".tmp" in f)


def children(pid: int) -> list[int]:
    r = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True)
    return [int(x) for x in r.stdout.split()]


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except OSError:
        return False


def patience(seconds: float) -> float:
    """A wait for an outcome, stretched by how busy the machine is (its load per core, at
    least 1): a test waits for what must happen, never on how fast the machine is now."""
    return seconds * max(1.0, os.getloadavg()[0] / (os.cpu_count() or 1))


class Fifo:
    """``with Fifo(path) as f: run a command``; ``f.opened`` then says whether anything
    opened the FIFO to read it. A watcher thread lets any reader go at once (it opens the
    write end, which succeeds only while a reader waits, and closes it: the reader reads
    the end of the file), so a regression fails its assertion instead of hanging the suite."""

    def __init__(self, path):
        self.path = os.fspath(path)
        self.opened = False
        os.mkfifo(self.path)

    def __enter__(self) -> "Fifo":
        import threading

        self._done = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()
        return self

    def _watch(self) -> None:
        while not self._done.wait(0.02):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:  # no reader (ENXIO), or the FIFO is gone
                continue
            self.opened = True
            os.close(fd)

    def __exit__(self, *exc) -> None:
        self._done.set()
        self._thread.join()
