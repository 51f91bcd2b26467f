"""How a shard stores its audio (``output.audio``; docs/format.md, "Audio codings").

- ``float32`` (default): ``audio`` float32 [N, C, T], one chunk per scene.
- ``int16``: ``audio`` int16 [N, C, T]; sample = ``audio / 32768`` (attribute
  ``audio_scale``). The mix peaks at 0.99 full scale, so nothing clips; the rounding
  error is white at about -101 dBFS.
- ``flac``: ``audio`` variable-length uint8 [N], each row one FLAC file of the scene's
  int16 samples ([T, C], lossless over ``int16``; ``soundfile.read(io.BytesIO(row))``
  decodes it). About a third of float32's bytes on real scenes.

Every coding reads back as float32 [C, T] through the reader and the torch adapter.
"""
from __future__ import annotations

import io

import h5py
import numpy as np
import soundfile as sf

from ..choices import AudioCoding

INT16_SCALE = 32768.0  # sample = stored / INT16_SCALE


def to_int16(audio: np.ndarray) -> np.ndarray:
    """float32 [C, T] in [-1, 1) -> int16, rounded to the nearest step of 1/32768."""
    return np.clip(np.rint(audio * INT16_SCALE), -32768, 32767).astype(np.int16)


def create_audio(h: h5py.File, coding: str, n: int, channels: int, samples: int) -> h5py.Dataset:
    """The shard's ``audio`` dataset for ``n`` scenes of [channels, samples]."""
    if coding == AudioCoding.FLOAT32:
        return h.create_dataset("audio", (n, channels, samples), dtype="float32", chunks=(1, channels, samples),
                                track_times=False)
    if coding == AudioCoding.INT16:
        d = h.create_dataset("audio", (n, channels, samples), dtype="int16", chunks=(1, channels, samples),
                             track_times=False)
    else:
        d = h.create_dataset("audio", (n,), dtype=h5py.vlen_dtype(np.uint8), track_times=False)
        d.attrs["audio_shape"] = np.array([channels, samples], dtype=np.int64)
    d.attrs["audio_coding"] = str(coding)
    d.attrs["audio_scale"] = 1.0 / INT16_SCALE
    return d


def encode(audio: np.ndarray, coding: str, fs: int):
    """One scene's row of the ``audio`` dataset."""
    if coding == AudioCoding.FLOAT32:
        return audio
    pcm = to_int16(audio)
    if coding == AudioCoding.INT16:
        return pcm
    buf = io.BytesIO()
    sf.write(buf, pcm.T, fs, subtype="PCM_16", format="FLAC")
    return np.frombuffer(buf.getvalue(), dtype=np.uint8)


def coding_of(ds: h5py.Dataset) -> str:
    """The coding of an ``audio`` dataset (no attribute: float32, as format version 1 wrote it)."""
    v = ds.attrs.get("audio_coding")
    return AudioCoding.FLOAT32 if v is None else str(v.decode() if isinstance(v, bytes) else v)


def decode(row, coding: str, out: np.ndarray | None = None) -> np.ndarray:
    """A row of the ``audio`` dataset as float32 [C, T] (into ``out`` when given)."""
    if coding == AudioCoding.FLOAT32:
        x = np.asarray(row, dtype=np.float32)
    elif coding == AudioCoding.INT16:
        x = np.asarray(row).astype(np.float32) * np.float32(1.0 / INT16_SCALE)
    else:
        pcm, _ = sf.read(io.BytesIO(np.asarray(row, dtype=np.uint8).tobytes()), dtype="int16", always_2d=True)
        x = pcm.T.astype(np.float32) * np.float32(1.0 / INT16_SCALE)
    if out is None:
        return x
    out[...] = x
    return out
