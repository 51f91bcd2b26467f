"""A scene's audio as files other tools read, in the dataset's own coding and bit-exact:
``.npy`` arrays, WAV and FLAC bytes (docs/format.md, "Audio codings").

float32 datasets give float32 samples (``.npy``, 32-bit float WAV); int16 and flac
datasets give their 16-bit samples (``.npy`` int16, 16-bit WAV, FLAC), which read back as
``sample / 32768``, exactly what the reader returns.
"""
from __future__ import annotations

import io
import struct

import numpy as np

from ..choices import AudioCoding
from ..store.codings import INT16_SCALE, encode, to_int16

WAV_PCM, WAV_FLOAT = 1, 3


def stored_samples(audio: np.ndarray, coding: str) -> np.ndarray:
    """The samples as the dataset stores them: float32 [C, T], or int16 [C, T] for the
    16-bit codings (exact: the reader's float32 is ``int16 / 32768``)."""
    return audio if coding == AudioCoding.FLOAT32 else to_int16(audio)


def npy_header(dtype, shape) -> bytes:
    """The ``.npy`` (version 1.0) header of a C-ordered array; the array's bytes follow it."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": np.lib.format.dtype_to_descr(np.dtype(dtype)),
                                               "fortran_order": False, "shape": tuple(shape)})
    return buf.getvalue()


def npy_array(data) -> np.ndarray:
    """A ``.npy`` file's bytes -> the array, viewing ``data`` (no copy; writable when
    ``data`` is a bytearray)."""
    view = memoryview(data)
    stream = io.BytesIO(view[:128].tobytes())  # headers of our shapes fit in 128 bytes
    major, _ = np.lib.format.read_magic(stream)
    read = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
    try:
        shape, fortran, dtype = read(stream)
        start = stream.tell()
    except ValueError:  # a longer header: parse it whole
        stream = io.BytesIO(view.tobytes())
        np.lib.format.read_magic(stream)
        shape, fortran, dtype = read(stream)
        start = stream.tell()
    a = np.frombuffer(data, dtype=dtype, count=int(np.prod(shape)), offset=start)
    return a.reshape(shape, order="F" if fortran else "C")


def wav_bytes(samples: np.ndarray, fs: int) -> bytes:
    """A WAV file of ``samples`` [C, T] (float32: IEEE float; int16: PCM), all channels.
    Written here rather than by libsndfile, which stamps float files with the time of
    writing: the same samples give the same bytes."""
    pcm = np.ascontiguousarray(samples.T)  # WAV interleaves: [T, C]
    channels, width = pcm.shape[1], pcm.dtype.itemsize
    fmt = WAV_FLOAT if pcm.dtype == np.float32 else WAV_PCM
    data = pcm.astype(pcm.dtype.newbyteorder("<"), copy=False).tobytes()
    head = struct.pack("<4sI4s4sIHHIIHH4sI", b"RIFF", 36 + len(data), b"WAVE", b"fmt ", 16, fmt, channels, fs,
                       fs * channels * width, channels * width, 8 * width, b"data", len(data))
    return head + data


def flac_bytes(audio: np.ndarray, fs: int) -> bytes:
    """A FLAC file (16-bit, all channels) of float32 ``audio`` [C, T] of a 16-bit coding."""
    return encode(audio, AudioCoding.FLAC, fs).tobytes()


def file_audio(audio: np.ndarray, coding: str, fs: int) -> tuple[str, bytes]:
    """(extension, bytes) of one audio file that holds the scene exactly: FLAC for flac
    datasets, WAV otherwise (float32 or 16-bit)."""
    if coding == AudioCoding.FLAC:
        return "flac", flac_bytes(audio, fs)
    return "wav", wav_bytes(stored_samples(audio, coding), fs)


def decode_samples(a: np.ndarray) -> np.ndarray:
    """float32 [C, T] from stored samples (float32 as they are, int16 / 32768)."""
    if a.dtype == np.float32:
        return a
    return a.astype(np.float32) * np.float32(1.0 / INT16_SCALE)
