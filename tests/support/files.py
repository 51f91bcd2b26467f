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
