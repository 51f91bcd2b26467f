"""Tiny ambience recordings in the layouts tsel_data.corpus.ambience reads, generated at test time.

:func:`make_tau_snoise` writes a TAU-SNoise_DB folder as distributed (``NN_<room>_…``
folders, ``ambience_{foa_sn3d,tetra}_24k_edited.wav``) or with the DCASE generator's
unprefixed names. Every file holds its own signature: float32 noise seeded by its folder
and tag, plus a constant per-room, per-channel offset, so a test can tell from the
samples which room's file (and which offset in it) a segment came from.
"""
from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np
import soundfile as sf

# As distributed (no 07), and as the DCASE generator names them, in room-number order.
TAU_SNOISE_FOLDERS = (
    "01_bomb_center", "02_gym", "03_pb132_paatalo_classroom2", "04_pc226_paatalo_office",
    "05_sa203_sahkotalo_lecturehall", "06_sc203_sahkotalo_classroom2", "08_se203_sahkotalo_classroom",
    "09_tb103_tietotalo_lecturehall", "10_tc352_tietotalo_meetingroom",
)
DCASE_FOLDERS = (
    "bomb_shelter", "gym", "pb132_paatalo_classroom2", "pc226_paatalo_office", "sa203_sahkotalo_lecturehall",
    "sc203_sahkotalo_classroom2", "se203_sahkotalo_classroom", "tb103_tietotalo_lecturehall",
    "tc352_tietotalo_meetingroom",
)
TAGS = ("foa_sn3d", "tetra")


def signature(name: str, tag: str, n: int, channels: int) -> np.ndarray:
    """The samples [C, n] float32 of recording ``tag`` of folder/file ``name``."""
    seed = zlib.crc32(f"{name}/{tag}".encode())
    rng = np.random.default_rng(seed)
    dc = 0.01 * (1 + seed % 50) * (1 + np.arange(channels))[:, None] / channels
    return (0.1 * rng.standard_normal((channels, n)) + dc).astype(np.float32)


def write_recording(path, audio: np.ndarray, fs: int, subtype: str = "FLOAT") -> Path:
    """Write ``audio`` [C, T] to ``path`` (format from the suffix)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sf.write(str(path), np.asarray(audio).T, fs, subtype=subtype)
    return path


def make_tau_snoise(root, rooms=TAU_SNOISE_FOLDERS, fs=24000, seconds=0.5, channels=4, tags=TAGS):
    """Write room folders ``rooms`` under ``root``, each with ``ambience_<tag>_24k_edited.wav``
    for every tag. Returns {folder: {tag: audio [C, T] float32}} (exactly the stored samples)."""
    root = Path(root)
    n = int(round(seconds * fs))
    truth = {}
    for room in rooms:
        truth[room] = {}
        for tag in tags:
            x = signature(room, tag, n, channels)
            write_recording(root / room / f"ambience_{tag}_24k_edited.wav", x, fs)
            truth[room][tag] = x
    return truth


def make_user_folder(root, names, fs=24000, seconds=0.5, channels=4, per_room=True, suffix=".flac"):
    """A user's ambience: ``root/<name>/<name><suffix>`` per room (``per_room``) or
    ``root/<name><suffix>`` flat. Returns {name: audio [C, T]} as stored (FLAC: 16-bit)."""
    root = Path(root)
    n = int(round(seconds * fs))
    truth = {}
    for name in names:
        x = signature(name, "user", n, channels)
        path = root / name / f"{name}{suffix}" if per_room else root / f"{name}{suffix}"
        write_recording(path, x, fs, subtype="PCM_16" if suffix == ".flac" else "FLOAT")
        truth[name] = sf.read(str(path), dtype="float32", always_2d=True)[0].T
    return truth
