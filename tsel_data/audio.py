"""Audio in: load, mono, resample, pad/trim, frame activity, levels.

Only the part of a file a scene needs is read (``offset`` .. ``offset + duration``).
Resampling is polyphase (``scipy.signal.resample_poly``, Kaiser-windowed FIR), so
44.1 kHz -> 24 kHz is exact in rate with no drift. Everything returned is float32.
"""
from __future__ import annotations

import errno
import math
import os
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import soundfile as sf

from .atomic import atomic_output
from .prepared import read_prepared, write_prepared
from .errors import AudioError

EPS = 1e-12
# Sample rates a recording can have; a header outside says the file is broken (or not audio).
MIN_RATE, MAX_RATE = 1000, 768000
SILENT_PEAK = 1e-5  # -100 dBFS
RELATIVE_SILENCE = 1e-3  # -60 dB: what a mixdown or the scenes' band keeps of a clip, below which it is gone


def load_clip(path: str, fs: int, duration: float, offset: float = 0.0) -> np.ndarray:
    """Mono float32 [round(duration·fs)] at ``fs``: read, downmix, resample, pad with zeros or cut."""
    n_out = int(round(duration * fs))
    if os.path.exists(path) and not os.path.isfile(path):  # a FIFO would block forever
        raise AudioError(f"{path} is not a regular file (a pipe, device or socket); point the manifest at an audio file")
    try:
        with sf.SoundFile(path) as f:
            sr = f.samplerate
            if not MIN_RATE <= sr <= MAX_RATE:
                raise AudioError(f"{path} declares a sample rate of {sr} Hz; the file is broken or not audio")
            start = int(round(offset * sr))
            if start:
                f.seek(min(start, f.frames))
            # read a little more than needed so the resampler's edge sees real signal
            need = int(math.ceil(duration * sr)) + 64
            x = f.read(frames=need, dtype="float32", always_2d=True)
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        raise AudioError(f"cannot read audio {path}: {e}; check the file or remove it from the manifest") from None
    if not np.all(np.isfinite(x)):
        # corpus.check below "full" lets such clips through; never mix NaN into a scene
        raise AudioError(f"{path} contains NaN or Inf samples; fix or remove the clip "
                         f"(corpus.check = \"full\" finds such clips before rendering)")
    x = x.mean(axis=1) if x.shape[1] > 1 else x[:, 0]
    if sr != fs:
        from scipy.signal import resample_poly  # imported here: scipy.signal costs ~0.6 s at CLI start-up

        g = math.gcd(int(sr), int(fs))
        x = resample_poly(x, fs // g, sr // g).astype(np.float32)
    return fit_length(x, n_out)


def fit_length(x: np.ndarray, n: int) -> np.ndarray:
    """Zero-pad or cut the last axis to ``n`` samples."""
    if x.shape[-1] >= n:
        return np.ascontiguousarray(x[..., :n], dtype=np.float32)
    pad = [(0, 0)] * (x.ndim - 1) + [(0, n - x.shape[-1])]
    return np.pad(x, pad).astype(np.float32, copy=False)


def frame_energy(x: np.ndarray, fs: int, hop: float, n_frames: int) -> np.ndarray:
    """Mean power of each label frame [k·hop, (k+1)·hop) of a mono signal: [F] (0 for a
    frame past the end of ``x``)."""
    edges = np.minimum(np.round(np.arange(n_frames + 1) * hop * fs).astype(int), len(x))
    sums = np.zeros(n_frames)
    full = np.flatnonzero(np.diff(edges) > 0)
    if full.size:
        # a sum per frame rather than differences of one running sum: ~5x faster, and a
        # quiet frame late in a loud clip keeps its digits
        sums[full] = np.add.reduceat(np.square(x[: edges[-1]], dtype=np.float64), edges[full])
    return sums / np.maximum(np.diff(edges), 1)


def frame_activity(x: np.ndarray, fs: int, hop: float, n_frames: int, threshold_db: float) -> np.ndarray:
    """True where a frame's energy is within ``threshold_db`` (negative) of the loudest frame."""
    e = frame_energy(x, fs, hop, n_frames)
    peak = e.max()
    if peak <= EPS:
        return np.zeros(n_frames, dtype=bool)
    return 10 * np.log10(np.maximum(e, EPS) / peak) >= threshold_db


def active_rms(x: np.ndarray, active: np.ndarray, fs: int, hop: float) -> float:
    """RMS of ``x`` ([..., T]) over its active label frames (all frames if none are active).

    A level measured on active frames does not depend on how much silence or padding a
    clip has, so gains do not depend on clip length.
    """
    n_frames = len(active)
    edges = np.minimum(np.round(np.arange(n_frames + 1) * hop * fs).astype(int), x.shape[-1])
    frames = np.asarray(active, dtype=bool) if np.any(active) else np.ones(n_frames, dtype=bool)
    step = np.diff(np.r_[False, frames, False].astype(np.int8))  # runs of active frames: +1 starts, -1 ends
    starts, stops = edges[step == 1], edges[step == -1]
    runs = [(a, b) for a, b in zip(starts.tolist(), stops.tolist()) if b > a]
    if not runs:
        return 0.0
    used = x[..., runs[0][0]:runs[0][1]] if len(runs) == 1 else np.concatenate([x[..., a:b] for a, b in runs], axis=-1)
    # the active samples as slices, not a boolean mask: the mean reads the same float64
    # squares in the same order (the same level, bit for bit) in a third of the time
    return float(np.sqrt(np.mean(np.square(used, dtype=np.float64))))


def db(x: float) -> float:
    return 20.0 * math.log10(max(x, EPS))


@dataclass(frozen=True)
class ClipCheck:
    """What the up-front check found about one clip; ``problem`` is None for a good clip,
    ``missing`` says the problem is that the file does not exist."""

    clip_id: str
    problem: str | None
    duration: float | None = None
    samplerate: int | None = None
    channels: int | None = None
    missing: bool = False  # the file does not exist (a partial download), not a bad file


def check_clip(clip_id: str, path: str, level: str, min_duration: float, max_channels: int,
               offset: float = 0.0, duration: float | None = None, fs: int | None = None) -> ClipCheck:
    """Check a clip at ``level`` = exists | header | full (decode: NaN, silence).

    ``full`` decodes only the part a scene uses, ``offset`` .. ``offset + duration`` (the
    whole file if ``duration`` is None), and judges it as a scene will hear it: mixed
    down to mono (a stereo clip whose channels cancel is silent) and, when the scenes'
    rate ``fs`` is lower than the clip's, in the band below fs/2 (a clip with only
    ultrasonic content is silent after resampling). A clip silent there would be an
    inaudible source whose caption still describes it.
    """
    if os.path.exists(path) and not os.path.isfile(path):
        return ClipCheck(clip_id, f"{path} is not a regular file (a pipe, device or socket)")
    if not os.path.isfile(path):
        return ClipCheck(clip_id, f"audio file not found: {path}", missing=True)
    if level == "exists":
        return ClipCheck(clip_id, None)
    if os.path.getsize(path) == 0:
        return ClipCheck(clip_id, f"empty audio file {path} (0 bytes)")
    try:
        info = sf.info(path)
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        return ClipCheck(clip_id, f"unreadable audio {path}: {str(e).splitlines()[0]}")
    dur = info.frames / info.samplerate if info.samplerate else 0.0
    base = dict(duration=dur, samplerate=info.samplerate, channels=info.channels)
    if info.frames == 0:
        return ClipCheck(clip_id, f"empty audio file {path}", **base)
    if not MIN_RATE <= info.samplerate <= MAX_RATE:
        return ClipCheck(clip_id, f"{path} declares a sample rate of {info.samplerate} Hz (not {MIN_RATE}-{MAX_RATE} "
                                  f"Hz): the file is broken or not audio", **base)
    if info.channels > max_channels:
        return ClipCheck(clip_id, f"{path} has {info.channels} channels (more than corpus.max_channels = {max_channels})", **base)
    if dur - offset < min_duration:
        return ClipCheck(clip_id, f"{path} is {dur - offset:.3f} s long (shorter than corpus.min_duration = {min_duration} s)", **base)
    if level == "header":
        return ClipCheck(clip_id, None, **base)
    sr = info.samplerate
    start = int(round(offset * sr))
    frames = -1 if duration is None else int(round(duration * sr))
    try:  # only the part a scene uses: a 4 GiB file costs what its 10 s cost
        used, _ = sf.read(path, start=min(start, info.frames), frames=frames, dtype="float32", always_2d=True)
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        return ClipCheck(clip_id, f"unreadable audio {path}: {str(e).splitlines()[0]}", **base)
    if not np.all(np.isfinite(used)):
        return ClipCheck(clip_id, f"{path} contains NaN or Inf samples", **base)
    span = "" if duration is None else f" in the {duration:g} s a scene uses"
    mono = used.mean(axis=1)
    if mono.size == 0 or float(np.max(np.abs(mono))) < SILENT_PEAK:
        return ClipCheck(clip_id, f"{path} is silent{span} (peak below -100 dBFS)", **base)
    loudest = float(np.sqrt(np.max(np.mean(used.astype(np.float64) ** 2, axis=0))))
    if _rms(mono) < RELATIVE_SILENCE * loudest:
        return ClipCheck(clip_id, f"{path} is silent{span} once mixed down to mono (its channels cancel: 60 dB "
                                  f"below the loudest channel)", **base)
    if fs is not None and sr > fs and _in_band_rms(mono, sr, fs / 2) < RELATIVE_SILENCE * _rms(mono):
        return ClipCheck(clip_id, f"{path} has no content below {fs / 2:g} Hz{span} (the scenes' band at {fs} Hz): "
                                  f"it would be silent after resampling", **base)
    return ClipCheck(clip_id, None, **base)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x.astype(np.float64) ** 2)))


def _in_band_rms(x: np.ndarray, sr: int, cutoff: float, n_fft: int = 4096, windows: int = 16) -> float:
    """RMS of ``x`` below ``cutoff`` Hz, from the power spectra of up to ``windows``
    evenly spaced Hann windows (a cheap estimate: a full-length FFT per clip would cost
    more than decoding it)."""
    if len(x) < n_fft:
        x = np.pad(x, (0, n_fft - len(x)))
    starts = np.linspace(0, len(x) - n_fft, min(windows, max(1, len(x) // n_fft))).astype(int)
    win = np.hanning(n_fft)
    power = np.mean([np.abs(np.fft.rfft(x[s:s + n_fft] * win)) ** 2 for s in starts], axis=0)
    band = np.fft.rfftfreq(n_fft, 1.0 / sr) < 0.9 * cutoff  # inside the resampler's pass band
    share = float(power[band].sum() / max(power.sum(), EPS))
    return _rms(x) * float(np.sqrt(share))


def load_clip_cached(path: str, fs: int, duration: float, offset: float) -> np.ndarray:
    """load_clip with a small per-process cache (clips recur across a shard's scenes) and
    prepared clips (prepared.py) when ``tsel corpus prepare`` made them. A file that
    changed (size or modification time) is read again."""
    try:
        st = os.stat(path)
        stamp = (st.st_size, st.st_mtime_ns)
    except OSError:
        stamp = None  # load_clip says what is wrong
    return _load_clip_cached(path, stamp, fs, duration, offset)


@lru_cache(maxsize=64)
def _load_clip_cached(path: str, stamp, fs: int, duration: float, offset: float) -> np.ndarray:
    x = read_prepared(path, stamp, fs, duration, offset) if stamp is not None else None
    if x is None:
        x = load_clip(path, fs, duration, offset)
    x.setflags(write=False)
    return x


def prepare_clip(path: str, fs: int, duration: float, offset: float) -> bool:
    """Make the prepared form of a clip unless it exists; True when it was made now."""
    st = os.stat(path)
    stamp = (st.st_size, st.st_mtime_ns)
    if read_prepared(path, stamp, fs, duration, offset) is not None:
        return False
    write_prepared(path, stamp, fs, duration, offset, load_clip(path, fs, duration, offset))
    return True


def save_wav(path, audio: np.ndarray, fs: int, subtype: str = "FLOAT") -> None:
    """Write ``audio`` [T] or [T, C] as a WAV file, atomically (temporary name, then
    rename: a failed write leaves no truncated file under ``path``) and reproducibly
    (the same samples give the same bytes)."""
    with atomic_output(os.fspath(path)) as tmp:
        try:
            sf.write(tmp, audio, fs, subtype=subtype, format="WAV")
        except sf.LibsndfileError as e:  # libsndfile's own error for a failed write (full disk, ...)
            raise OSError(errno.EIO, str(e)) from None
        _zero_peak_timestamp(tmp)


def _zero_peak_timestamp(path) -> None:
    """Zero the time stamp of a WAV file's PEAK chunk, if it has one.

    libsndfile adds a PEAK chunk (version u32, time stamp u32, then per-channel peaks)
    to float WAV files, stamped with the wall-clock time of writing; zeroing it makes
    the file a pure function of its samples. Walks the RIFF chunk list: 4-byte id,
    u32 little-endian size, data padded to an even length.
    """
    with open(path, "r+b") as f:
        head = f.read(12)
        if head[:4] != b"RIFF" or head[8:12] != b"WAVE":
            return
        while True:
            chunk = f.read(8)
            if len(chunk) < 8:
                return
            size = int.from_bytes(chunk[4:], "little")
            if chunk[:4] == b"PEAK" and size >= 8:
                f.seek(4, os.SEEK_CUR)
                f.write(b"\0\0\0\0")
                return
            f.seek(size + (size & 1), os.SEEK_CUR)
