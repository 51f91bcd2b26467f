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

from ..core.atomic import atomic_output
from ..core.files import check_input, path_problem
from ..errors import AudioError, DatasetError
from .prepared import REMAKE, lookup, prepared_path, stamp_of, write_prepared

EPS = 1e-12
# Sample rates a recording can have; a header outside says the file is broken (or not audio).
MIN_RATE, MAX_RATE = 1000, 768000
SILENT_PEAK = 1e-5  # -100 dBFS
RELATIVE_SILENCE = 1e-3  # -60 dB: what a mixdown or the scenes' band keeps of a clip, below which it is gone
# +80 dBFS. Float files may exceed full scale a little, never by this much: such samples
# are not audio in full-scale units, and their squares overflow float32 in the mixer.
MAX_PEAK = 1e4
# Extensions libsndfile reads (soundfile.available_formats(), as ambience.AUDIO_SUFFIXES):
# a clip that fails to open under another one (.m4a, .aac, .wma) gets told why.
READ_SUFFIXES = frozenset("." + k.lower() for k in sf.available_formats()) | {".aif", ".oga", ".opus"}


def unread_format(path: str) -> str:
    """Why libsndfile could not open ``path`` when its extension is one it never reads
    (``"; libsndfile does not read .m4a files ..."``), else ``""``."""
    ext = os.path.splitext(path)[1].lower()
    if not ext or ext in READ_SUFFIXES:
        return ""
    return (f"; libsndfile does not read {ext} files (it reads WAV, FLAC, OGG Vorbis/Opus, MP3, AIFF and a few "
            f"more): convert the clips, e.g. to FLAC with ffmpeg, and name them in corpus.audio_template")


def sample_problem(x: np.ndarray) -> str | None:
    """What makes decoded samples unusable in a scene (NaN or Inf, or an absurd peak), or None."""
    if not x.size:
        return None
    hi, lo = float(x.max()), float(x.min())  # a NaN or Inf anywhere shows in one of them
    if not (math.isfinite(hi) and math.isfinite(lo)):
        return "contains NaN or Inf samples"
    peak = max(hi, -lo)
    if peak > MAX_PEAK:
        return f"has samples of amplitude {peak:.3g} (above {MAX_PEAK:g}, +80 dBFS: not audio in full-scale units)"
    return None


def load_clip(path: str, fs: int, duration: float, offset: float = 0.0) -> np.ndarray:
    """Mono float32 [round(duration·fs)] at ``fs``: read, downmix, resample, pad with zeros or cut."""
    check_input(path, AudioError, "point the manifest at an audio file")  # a FIFO would block forever
    try:
        with sf.SoundFile(path) as f:
            sr = f.samplerate
            if not MIN_RATE <= sr <= MAX_RATE:
                raise AudioError(f"{path} declares a sample rate of {sr} Hz; the file is broken or not audio")
            start = int(round(offset * sr))
            if start:
                f.seek(min(start, f.frames))
            x = f.read(frames=_span(duration, sr), dtype="float32", always_2d=True)
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        raise AudioError(f"cannot read audio {path}: {e}" + (unread_format(path) or "; check the file or remove it "
                                                             "from the manifest")) from None
    problem = sample_problem(x)
    if problem:
        # corpus.check below "full" lets such clips through; never mix them into a scene
        raise AudioError(f"{path} {problem}; fix or remove the clip (corpus.check = \"full\" finds such clips "
                         f"before rendering)")
    return _as_scene_clip(x, sr, fs, int(round(duration * fs)))


def _span(duration: float, sr: int) -> int:
    """Frames load_clip reads: a little more than the scene uses, so the resampler's edge
    sees real signal."""
    return int(math.ceil(duration * sr)) + 64


def downmix(x: np.ndarray) -> np.ndarray:
    """Decoded frames [T, C] float32 -> their mean over channels [T] float32, bit for bit
    ``x.mean(axis=1)`` (numpy sums from zero, channel by channel, below 8 channels), in a
    fifth of its time: numpy reduces a short inner axis slowly."""
    C = x.shape[1]
    if C >= 8 or x.dtype != np.float32:
        return x.mean(axis=1)
    acc = np.zeros(len(x), dtype=np.float32)
    for c in range(C):
        acc += x[:, c]
    acc /= np.float32(C)
    return acc


def _as_scene_clip(x: np.ndarray, sr: int, fs: int, n_out: int) -> np.ndarray:
    """Decoded frames [T, C] at ``sr`` -> the mono float32 [n_out] at ``fs`` a scene hears."""
    x = downmix(x) if x.shape[1] > 1 else x[:, 0]
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
    prepared: str | None = None  # the clip is good, but its prepared form is not (audio.keep_prepared)
    kept: bool = False  # its prepared form is there after the check (made now or before)


def check_clip(clip_id: str, path: str, level: str, min_duration: float, max_channels: int,
               offset: float = 0.0, duration: float | None = None, fs: int | None = None,
               prepare: bool = False) -> ClipCheck:
    """Check a clip at ``level`` = exists | header | full (decode: NaN, Inf, absurd peaks,
    silence).

    ``full`` decodes only the part a scene uses, ``offset`` .. ``offset + duration`` (the
    whole file if ``duration`` is None), and judges it as a scene will hear it: mixed
    down to mono (a stereo clip whose channels cancel is silent) and, when the scenes'
    rate ``fs`` is lower than the clip's, in the band below fs/2 (a clip with only
    ultrasonic content is silent after resampling). A clip silent there would be an
    inaudible source whose caption still describes it.

    ``prepare`` (with ``full``, ``duration`` and ``fs``): a good clip that scenes would
    resample or mix down gets its prepared form (corpus/prepared.py) from this same decode.
    Without it, a prepared form that exists is checked (:func:`keep_prepared`).
    """
    problem = path_problem(path)  # judged by its mode: a FIFO or device is never opened
    if problem == "does not exist":
        return ClipCheck(clip_id, f"audio file not found: {path}", missing=True)
    if problem:
        return ClipCheck(clip_id, f"{path} {problem}")
    if level == "exists":
        return ClipCheck(clip_id, None)
    if os.path.getsize(path) == 0:
        return ClipCheck(clip_id, f"empty audio file {path} (0 bytes)")
    try:
        info = sf.info(path)
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        return ClipCheck(clip_id, f"unreadable audio {path}: {str(e).splitlines()[0]}{unread_format(path)}")
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
    making = prepare and duration is not None and fs is not None and wants_preparing(sr, info.channels, fs)
    try:  # only the part a scene uses: a 4 GiB file costs what its 10 s cost
        # (what load_clip reads, when the prepared form is made from this decode)
        read, _ = sf.read(path, start=min(start, info.frames), frames=_span(duration, sr) if making else frames,
                          dtype="float32", always_2d=True)
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        return ClipCheck(clip_id, f"unreadable audio {path}: {str(e).splitlines()[0]}", **base)
    used = read[:frames] if making else read
    problem = sample_problem(read)  # all load_clip reads: what render would refuse
    if problem:
        return ClipCheck(clip_id, f"{path} {problem}", **base)
    span = "" if duration is None else f" in the {duration:g} s a scene uses"
    mono = downmix(used)
    if mono.size == 0 or max(float(mono.max()), -float(mono.min())) < SILENT_PEAK:
        return ClipCheck(clip_id, f"{path} is silent{span} (peak below -100 dBFS)", **base)
    # energies as float32 dot products (BLAS): the thresholds are 60 dB apart, their
    # relative error ~1e-7
    loudest = math.sqrt(max(float(np.dot(used[:, c], used[:, c])) for c in range(used.shape[1])) / len(used))
    mono_rms = math.sqrt(float(np.dot(mono, mono)) / len(mono))
    if mono_rms < RELATIVE_SILENCE * loudest:
        return ClipCheck(clip_id, f"{path} is silent{span} once mixed down to mono (its channels cancel: 60 dB "
                                  f"below the loudest channel)", **base)
    if fs is not None and sr > fs and _in_band_rms(mono, sr, fs / 2, mono_rms) < RELATIVE_SILENCE * mono_rms:
        return ClipCheck(clip_id, f"{path} has no content below {fs / 2:g} Hz{span} (the scenes' band at {fs} Hz): "
                                  f"it would be silent after resampling", **base)
    if duration is None or fs is None:
        return ClipCheck(clip_id, None, **base)
    made = (lambda: _as_scene_clip(read, sr, fs, int(round(duration * fs)))) if making else None
    prepared = keep_prepared(path, fs, duration, offset, prepare, making, made, deep=not prepare)
    # what is there, not what was meant: a cache folder that cannot be written keeps nothing
    kept = making and prepared is None and prepared_state(path, fs, duration, offset) == "ok"
    return ClipCheck(clip_id, None, **base, prepared=prepared, kept=kept)


def wants_preparing(samplerate: int | None, channels: int | None, fs: int) -> bool:
    """Whether a clip's prepared form saves a scene work: it is resampled or mixed down
    (a mono clip at the scenes' rate reads as fast as its prepared form)."""
    return samplerate != fs or (channels or 1) > 1


def prepared_state(path: str, fs: int, duration: float, offset: float) -> str:
    """``absent``, ``ok`` or ``changed``: a clip's prepared form against its record, at
    the cost of a ``stat`` (prepared.lookup)."""
    try:
        stamp = stamp_of(os.stat(path))
    except (OSError, ValueError):
        return "absent"
    return lookup(path, stamp, fs, duration, offset, read=False)[0]


def keep_prepared(path: str, fs: int, duration: float, offset: float, prepare: bool = False, wanted: bool = False,
                  make=None, deep: bool = False) -> str | None:
    """Keep a good clip's prepared form in step with it; None, or what is wrong with it.

    ``prepare``: make it again when it does not match its record, and make it when it is
    absent and ``wanted`` (:func:`wants_preparing`); ``make()`` gives the samples, else
    the clip is decoded. Otherwise a prepared form that exists is
    checked against its record, at the cost of a ``stat`` (``deep``: its samples and the
    clip's bytes are hashed too, and the samples checked as a source clip's are), and
    what is wrong is returned for the check to report: render would refuse it.
    """
    try:
        stamp = stamp_of(os.stat(path))
    except (OSError, ValueError):
        return None  # gone since its check: found again where it is read
    state, x, why = lookup(path, stamp, fs, duration, offset, read=deep, deep=deep)
    if prepare and (state == "changed" or (state == "absent" and wanted)):
        try:
            write_prepared(path, stamp, fs, duration, offset, make() if make else load_clip(path, fs, duration, offset))
        except (OSError, DatasetError):
            pass  # a read-only corpus or a full disk: a prepared clip only ever saves time
        return None
    if state == "changed":
        return f"{path}: its prepared form {prepared_path(path, stamp, fs, duration, offset)}: {why}; {REMAKE}"
    if x is not None:
        problem = sample_problem(x) or ("is silent (peak below -100 dBFS)" if np.max(np.abs(x)) < SILENT_PEAK else None)
        if problem:
            return f"{path}: its prepared form {prepared_path(path, stamp, fs, duration, offset)} {problem}; {REMAKE}"
    return None


def _in_band_rms(x: np.ndarray, sr: int, cutoff: float, rms: float, n_fft: int = 4096, windows: int = 16) -> float:
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
    return rms * float(np.sqrt(share))


def load_clip_cached(path: str, fs: int, duration: float, offset: float) -> np.ndarray:
    """load_clip with a small per-process cache (clips recur across a shard's scenes) and
    prepared clips (corpus/prepared.py) when ``tsel corpus prepare`` or the clip check made them.
    A file that changed (size, modification time, inode or change time) is read again.

    Raises AudioError naming the clip when its prepared form does not match its record
    (the clip or the prepared file changed since it was made) or holds samples no clip
    may (NaN, Inf, absurd peaks): those are the clip's problems, never the simulator's."""
    try:
        stamp = stamp_of(os.stat(path))
    except (OSError, ValueError):  # ValueError: a NUL byte in the name
        stamp = None  # load_clip says what is wrong
    return _load_clip_cached(path, stamp, fs, duration, offset)


@lru_cache(maxsize=64)
def _load_clip_cached(path: str, stamp, fs: int, duration: float, offset: float) -> np.ndarray:
    state, x, why = lookup(path, stamp, fs, duration, offset) if stamp is not None else ("absent", None, "")
    if state == "changed":
        raise AudioError(f"{path}: its prepared form {prepared_path(path, stamp, fs, duration, offset)}: {why}; "
                         f"{REMAKE}")
    if x is None:
        x = load_clip(path, fs, duration, offset)
    else:
        problem = sample_problem(x)
        if problem:
            raise AudioError(f"{path}: its prepared form {prepared_path(path, stamp, fs, duration, offset)} {problem}; "
                             f"{REMAKE}")
    x.setflags(write=False)
    return x


def prepare_clip(path: str, fs: int, duration: float, offset: float) -> bool:
    """Make the prepared form of a clip unless it exists and matches its record (the
    clip's bytes are hashed: preparing is when that is checked in full); True when it was
    made now. A prepared form that no longer matches is made again."""
    stamp = stamp_of(os.stat(path))
    state, x, _ = lookup(path, stamp, fs, duration, offset, deep=True)
    if state == "ok" and sample_problem(x) is None:
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
