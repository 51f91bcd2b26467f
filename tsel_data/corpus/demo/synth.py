"""Write the built-in demo corpus: synthetic captioned clips in AudioCaps layout.

``synth_corpus(out_dir)`` writes::

    out_dir/
      audio/{youtube_id}.wav    one pre-cut clip per row group (offset 0)
      train.csv val.csv test.csv  AudioCaps format: audiocap_id,youtube_id,start_time,caption
      clips.json                every clip's type, split, captions and file format
      README.txt                what this is

Read it back with ``read_audiocaps(out_dir/"train.csv", audio_dir=out_dir/"audio")``.

Determinism: a clip's sound comes from a numpy Generator seeded with
``SeedSequence([seed, crc32(type name), split index, clip index])``; its file format
(rate, channels, length, subtype) is a fixed function of its position in the corpus;
the CSV row order and caption ids come from a Generator seeded with ``[seed, 0]``. The
time stamp libsndfile puts in float WAVs is zeroed, so the same ``seed`` and
``clips_per_type`` give byte-identical files (on the same platform and library
versions: numpy's elementary functions may differ in the last bit elsewhere).

The file formats vary on purpose, to exercise the audio-loading stage: most clips are
10 s, 24 kHz, mono, PCM_16; some are 16 or 44.1 kHz, stereo, 4-9 s or 12 s long, or
32-bit float.
"""
from __future__ import annotations

import base64
import csv
import hashlib
import io
import json
import os
import textwrap
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ...core.atomic import write_text
from ...errors import ConfigError
from ..audio import save_wav
from .sounds import SOUND_TYPES, SoundType

SPLITS = ("train", "val", "test")
CAPTIONS_PER_CLIP = {"train": 1, "val": 5, "test": 5}
CSV_HEADER = ("audiocap_id", "youtube_id", "start_time", "caption")
PEAK_RANGE = (0.3, 0.9)       # clip peak level, linear full scale
FLOOR_DB = -60.0              # background noise floor relative to the clip peak


@dataclass(frozen=True)
class ClipFormat:
    """How one clip is stored: rate (Hz), channels, duration (s), soundfile subtype."""

    fs: int
    channels: int
    duration: float
    subtype: str


@dataclass(frozen=True)
class ClipSpec:
    """One clip of the corpus, fully determined before any audio is made."""

    youtube_id: str
    start_time: int
    split: str
    index: int            # index of the clip within its type and split
    kind: str             # sound type name
    temporal: str         # "continuous" or "intermittent"
    captions: tuple[str, ...]
    peak: float
    format: ClipFormat


def youtube_id(seed: int, kind: str, split: str, index: int) -> str:
    """An 11-character YouTube-style id ([A-Za-z0-9_-]) from a hash of the clip's key."""
    digest = hashlib.sha256(f"tsel-demo:{seed}:{kind}:{split}:{index}".encode()).digest()
    return base64.urlsafe_b64encode(digest).decode("ascii")[:11]


def clip_format(position: int, rng: np.random.Generator) -> ClipFormat:
    """The file format of the corpus' ``position``-th clip.

    Fixed cycles of co-prime lengths (8, 7, 9, 5), so every corpus of a few dozen
    clips has every variant, in varied combinations: 16 kHz and 44.1 kHz one clip in 8
    each (else 24 kHz), stereo 1 in 7, 4-9 s (drawn from ``rng``, 10 ms steps) and
    12 s 1 in 9 each (else 10 s), FLOAT 1 in 5 (else PCM_16).
    """
    fs = {6: 16000, 7: 44100}.get(position % 8, 24000)
    channels = 2 if position % 7 == 3 else 1
    slot = position % 9
    duration = round(float(rng.uniform(4.0, 9.0)), 2) if slot == 2 else (
        12.0 if slot == 6 else 10.0)
    subtype = "FLOAT" if position % 5 == 1 else "PCM_16"
    return ClipFormat(fs, channels, duration, subtype)


def _seed_sequence(seed: int, kind: str, split_index: int, index: int):
    return np.random.SeedSequence([seed, zlib.crc32(kind.encode()), split_index, index])


def plan_corpus(seed: int = 0, clips_per_type=(4, 1, 1),
                types: tuple[SoundType, ...] = SOUND_TYPES) -> list[ClipSpec]:
    """Every clip's spec (no audio): split-major, then clip index, then type, so each
    split cycles through all types and all file formats."""
    specs, position = [], 0
    for si, split in enumerate(SPLITS):
        for index in range(clips_per_type[si]):
            for st in types:
                meta_rng = np.random.default_rng(_seed_sequence(seed, st.name, si, index)
                                                 .spawn(2)[0])
                k = CAPTIONS_PER_CLIP[split]
                pick = meta_rng.choice(len(st.captions), size=k, replace=False)
                specs.append(ClipSpec(
                    youtube_id=youtube_id(seed, st.name, split, index),
                    start_time=10 * int(meta_rng.integers(0, 30)),
                    split=split, index=index, kind=st.name, temporal=st.temporal,
                    captions=tuple(st.captions[i] for i in pick),
                    peak=round(float(meta_rng.uniform(*PEAK_RANGE)), 3),
                    format=clip_format(position, meta_rng),
                ))
                position += 1
    ids = [s.youtube_id for s in specs]
    if len(set(ids)) != len(ids):  # 66-bit hashes: never expected
        raise ConfigError(f"demo corpus: youtube_id collision for seed {seed}; "
                          "choose another --seed")
    return specs


def render_clip(spec: ClipSpec, seed: int, types=SOUND_TYPES) -> np.ndarray:
    """The clip's audio, float32 (frames, channels), peak exactly ``spec.peak``.

    The sound is generated at the file's own rate (no resampling). A faint white
    floor at FLOOR_DB under the peak keeps the gaps of intermittent sounds from being
    digital silence, as in real recordings. The second channel of a stereo clip is
    the first delayed by 1-20 samples and scaled by 0.7-1.0, with its own floor.
    """
    st = {t.name: t for t in types}[spec.kind]
    fmt = spec.format
    rng = np.random.default_rng(
        _seed_sequence(seed, spec.kind, SPLITS.index(spec.split), spec.index).spawn(2)[1])
    n = int(round(fmt.duration * fmt.fs))
    x = st.generate(rng, fmt.fs, n)
    x = x / np.max(np.abs(x))
    floor = 10.0 ** (FLOOR_DB / 20.0)
    chans = [x + floor * rng.standard_normal(n)]
    if fmt.channels == 2:
        d = int(rng.integers(1, 21))
        chans.append(rng.uniform(0.7, 1.0) * np.concatenate([np.zeros(d), x[:n - d]])
                     + floor * rng.standard_normal(n))
    y = np.stack(chans, axis=1)
    y *= spec.peak / np.max(np.abs(y))
    return y.astype(np.float32)


def _write_wav(path: Path, audio: np.ndarray, fmt: ClipFormat) -> None:
    save_wav(path, audio, fmt.fs, subtype=fmt.subtype)


def _write_text(path: Path, text: str) -> None:
    write_text(os.fspath(path), text)


def _csv_text(rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_HEADER)
    w.writerows(rows)
    return buf.getvalue()


def _readme(seed, clips_per_type, specs, types) -> str:
    counts = {s: sum(c.split == s for c in specs) for s in SPLITS}
    lines = [
        "tsel-data demo corpus",
        "=====================",
        "",
        "Synthetic, captioned sound clips made by tsel_data.corpus.demo.synth_corpus",
        f"(seed={seed}, clips_per_type={tuple(clips_per_type)}), so that the whole",
        "tsel-data pipeline can run without downloading anything. Every sound was",
        "generated from simple signal models with numpy/scipy; nothing here comes from",
        "a recording, so there are no third-party rights in it.",
        "",
        "Layout (the AudioCaps layout):",
        "  train.csv, val.csv, test.csv   audiocap_id,youtube_id,start_time,caption;",
        "                                 one row per caption; train has 1 caption per",
        "                                 clip, val and test 5 (rows of a clip are not",
        "                                 adjacent, as in the real files)",
        "  audio/{youtube_id}.wav         the clip, already cut (start_time is",
        "                                 informational; the clip starts at 0 s)",
        "  clips.json                     per clip: sound type, split, captions, format",
        "",
        f"Clips: train {counts['train']}, val {counts['val']}, test {counts['test']}.",
        *textwrap.wrap(f"Sound types ({len(types)}): " + ", ".join(
            f"{t.name} ({t.temporal})" for t in types) + ".", 79),
        "",
        "File formats vary on purpose, to exercise audio loading: most clips are 10 s,",
        "24 kHz, mono, 16-bit PCM; some are 16 kHz or 44.1 kHz, stereo, 4-9 s or 12 s",
        "long, or 32-bit float. Peaks are 0.3-0.9 full scale, never clipped.",
        "",
        "Read it with tsel_data.corpus.manifests.read_audiocaps(DIR/'train.csv',",
        "audio_dir=DIR/'audio'). Rebuild it, byte for byte, with",
        f"tsel_data.corpus.demo.synth_corpus(DIR, seed={seed}, "
        f"clips_per_type={tuple(clips_per_type)});",
        "`tsel corpus synth --out DIR` makes the default corpus (seed 0, (4, 1, 1)).",
        "",
    ]
    return "\n".join(lines)


def _check_args(seed, clips_per_type) -> tuple[int, tuple[int, int, int]]:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"demo corpus: seed must be an integer >= 0, got {seed!r}")
    try:
        counts = tuple(int(c) for c in clips_per_type)
        ok = len(counts) == 3 and all(c >= 0 and c == float(f) for c, f in
                                      zip(counts, clips_per_type)) and sum(counts) > 0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ConfigError(
            f"demo corpus: clips_per_type must be three integers >= 0 (train, val, "
            f"test) with at least one > 0, got {clips_per_type!r}; e.g. (4, 1, 1)")
    return int(seed), counts


def corpus_files(out_dir, seed: int = 0, clips_per_type=(4, 1, 1)) -> list[str]:
    """Every file :func:`synth_corpus` writes into ``out_dir``, without writing any."""
    seed, counts = _check_args(seed, clips_per_type)
    out = Path(out_dir)
    return [str(p) for p in (*(out / "audio" / f"{c.youtube_id}.wav" for c in plan_corpus(seed, counts)),
                             *(out / f"{s}.csv" for s in SPLITS), out / "clips.json", out / "README.txt")]


def synth_corpus(out_dir, seed: int = 0, clips_per_type=(4, 1, 1)) -> dict:
    """Synthesise the demo corpus into ``out_dir`` (created if needed).

    out_dir:        output folder; existing files of the same names are replaced,
                    other files are left alone (``tsel corpus synth`` claims them
                    first: :func:`corpus_files`, store/outputs.py).
    seed:           integer >= 0; the corpus is a pure function of (seed, clips_per_type).
    clips_per_type: clips of every sound type in (train, val, test).

    Returns a dict of plain values::

        {"out_dir": str, "audio_dir": str, "readme": str, "clips_json": str,
         "csv": {"train": str, "val": str, "test": str},
         "types": [names], "clips": {split: count}, "rows": {split: caption rows},
         "seconds": {split: total audio duration (s)}, "bytes": total size written}

    Raises ConfigError for a bad seed or clips_per_type.
    """
    seed, counts = _check_args(seed, clips_per_type)
    out = Path(out_dir)
    audio_dir = out / "audio"
    audio_dir.mkdir(parents=True, exist_ok=True)
    specs = plan_corpus(seed, counts)

    written = 0
    for spec in specs:
        path = audio_dir / f"{spec.youtube_id}.wav"
        _write_wav(path, render_clip(spec, seed), spec.format)
        written += path.stat().st_size

    # Caption ids: a shuffled block of integers; rows shuffled so a clip's captions are
    # scattered through the file, as in the real AudioCaps val/test CSVs.
    rows = {s: [(c, cap) for c in specs if c.split == s for cap in c.captions]
            for s in SPLITS}
    order_rng = np.random.default_rng(np.random.SeedSequence([seed, 0]))
    n_rows = sum(len(r) for r in rows.values())
    ids = iter(1000 + order_rng.permutation(n_rows))
    csv_paths = {}
    for split in SPLITS:
        perm = order_rng.permutation(len(rows[split]))
        table = [(int(next(ids)), rows[split][i][0].youtube_id,
                  rows[split][i][0].start_time, rows[split][i][1]) for i in perm]
        csv_paths[split] = out / f"{split}.csv"
        _write_text(csv_paths[split], _csv_text(table))

    meta = [{**{k: v for k, v in asdict(c).items() if k != "format"},
             "captions": list(c.captions), "format": asdict(c.format),
             "audio": f"audio/{c.youtube_id}.wav"} for c in specs]
    _write_text(out / "clips.json", json.dumps(
        {"seed": seed, "clips_per_type": list(counts), "clips": meta},
        indent=1, ensure_ascii=False) + "\n")
    _write_text(out / "README.txt", _readme(seed, counts, specs, SOUND_TYPES))
    for p in [*csv_paths.values(), out / "clips.json", out / "README.txt"]:
        written += p.stat().st_size

    return {
        "out_dir": str(out),
        "audio_dir": str(audio_dir),
        "readme": str(out / "README.txt"),
        "clips_json": str(out / "clips.json"),
        "csv": {s: str(p) for s, p in csv_paths.items()},
        "types": [t.name for t in SOUND_TYPES],
        "clips": {s: sum(c.split == s for c in specs) for s in SPLITS},
        "rows": {s: len(rows[s]) for s in SPLITS},
        "seconds": {s: round(sum(c.format.duration for c in specs if c.split == s), 2)
                    for s in SPLITS},
        "bytes": written,
    }
