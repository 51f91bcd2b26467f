"""The sha256 of a file, read in blocks: seals, releases, prepared clips and content
fingerprints all name a file's bytes this one way."""
from __future__ import annotations

import hashlib


def sha256_file(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()
