"""Recorded room ambience: find the recordings, cut a scene's segment, set its level.

    amb = find_ambience("TAU-SNoise_DB", channels=4, fs=24000, fmt="foa")
    rec = amb.for_room("pb132")                    # or 3; None for a simulated room (drawn)
    offset, noise = rec.segment(rng, n_samples)    # [C, n_samples] float32, read alone
    g = snr_gain(target_image, noise, snr_db, spec.level_channels)

Layouts :func:`find_ambience` recognises in ``root`` (headers are read, never audio):

- **TAU-SNoise_DB** (Politis, Adavanne, Virtanen; shipped with the TAU-SRIR DB, Zenodo
  6408611): one folder per room, ``01_bomb_center``, ``02_gym``,
  ``03_pb132_paatalo_classroom2`` … ``10_tc352_tietotalo_meetingroom`` (no 07), each
  with ``ambience_foa_sn3d_24k_edited.wav`` and ``ambience_tetra_24k_edited.wav``
  (4 channels, 24 kHz). The DCASE generator's names without the number prefix
  (``bomb_shelter``, ``gym``, ``pb132_paatalo_classroom2`` …) work too. The file of a
  receiver is chosen through :data:`AMBIENCE_FILE_TAGS`, keyed by the tag in the file
  name (``ambience_<tag>_<N>k[_edited].wav``).
- **Room folders of the user's own recordings**: one recording (any format soundfile
  reads: WAV, FLAC, …) per room folder; folders are matched to bank rooms as TAU's are.
- **A flat folder of recordings**: used for any room, one drawn per scene.

Matching a bank room (:meth:`AmbienceSet.for_room`): a TAU-SRIR DB room name
(``bomb_shelter``, ``gym``, ``pb132`` …) or number (1–10) finds, in this order, the
folder of that exact name, then the one of that name after its number prefix, then the
one whose name starts with it as a whole ``_`` token (``pb132`` ->
``03_pb132_paatalo_classroom2``), then the one of the same room number (``bomb_shelter`` is room 1 -> ``01_bomb_center``;
the numbers of unprefixed folders come from :data:`TAU_ROOM_NAMES`).

Decisions, each for a reason:

- **Sample rate**: a recording at another rate than the scenes is refused (resample it
  once, offline). Resampling per segment would make an offset a point between samples
  of the file, and a 24 kHz recording brought up to 48 kHz carries nothing above 12 kHz,
  a band edge a model could learn as "this room".
- **Short recordings**: a recording shorter than one scene is refused, not tiled as
  SpatialScaper tiles it: the seam of a tiled recording is a periodic click and a
  repeated stretch of noise that no real room makes.
- **Segments**: ``random`` draws the offset uniformly over every whole sample where a
  scene fits, from the scene's own generator (SpatialScaper draws whole seconds);
  ``consecutive`` is the DCASE generator's rule, scene *i* takes non-overlapping block
  *i* of the recording, and wraps to block 0 after the last (where the generator falls
  back to random blocks), so it stays a pure function of *i*.

Level: :func:`snr_gain` follows the DCASE generator (danielkrause/DCASE2022-data-generator,
``audio_mixer.py``): the SNR is the ratio of two energies summed over the whole scene,
silences included, each the energy of one "omni" signal — the mean over the receiver's
level channels (W alone for FOA, every capsule for a mic array)::

    E(x) = Σ_t ( (1/|L|) Σ_{c∈L} x[c, t] )²        SNR = 10·log10(E(target) / E(g·noise))

so g = sqrt(E(target) · 10^(−SNR/10) / E(noise)).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import soundfile as sf

from ..core.files import check_input
from ..errors import ConfigError
from .audio import SILENT_PEAK
from ..receivers import canonical

# The tag in a TAU-SNoise_DB file name (ambience_<tag>_24k_edited.wav) -> the receiver it
# was recorded with. A new recorded format is one entry here.
AMBIENCE_FILE_TAGS = {"foa_sn3d": "foa", "tetra": "tetra"}
_TAG_OF_RECEIVER = {name: tag for tag, name in AMBIENCE_FILE_TAGS.items()}
_TAU_FILE = re.compile(r"^ambience_(?P<tag>[a-z0-9_]+?)_(?P<khz>\d+)k(?:_edited)?\.wav$", re.I)

# Room number -> the names a room goes by: the TAU-SRIR DB's (rirs_NN_<name>.mat), the
# DCASE generator's folder token, and TAU-SNoise_DB's own spelling where it differs
# (its room 1 is "bomb_center"). Room 7 (se201) has ambience in the generator's list but
# no RIRs and no folder in the distribution.
TAU_ROOM_NAMES = {
    1: ("bomb_shelter", "bomb_center"), 2: ("gym",), 3: ("pb132",), 4: ("pc226",), 5: ("sa203",),
    6: ("sc203",), 7: ("se201",), 8: ("se203",), 9: ("tb103",), 10: ("tc352",),
}
_PREFIX = re.compile(r"^(\d+)_(.+)$")

SEGMENT_RULES = ("random", "consecutive")
# Every extension soundfile can read, so any recording it opens counts as one.
AUDIO_SUFFIXES = frozenset("." + k.lower() for k in sf.available_formats())
AUDIO_SUFFIXES |= {".aif", ".oga", ".opus"}


@dataclass(frozen=True)
class Recording:
    """One ambience recording, known by its header.

    path: the file. room: its room folder's name ("" in a flat folder). channels,
    fs (Hz), frames (samples per channel): from the header.
    """

    path: str
    room: str
    channels: int
    fs: int
    frames: int

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.frames / self.fs

    def blocks(self, n_samples: int) -> int:
        """How many non-overlapping scenes of ``n_samples`` fit (the consecutive rule's period)."""
        return self.frames // n_samples

    def check_length(self, n_samples: int) -> None:
        """ConfigError unless one scene of ``n_samples`` fits."""
        if n_samples > self.frames:
            raise ConfigError(
                f"ambience {self.path} is {self.duration:.3f} s long, shorter than one scene "
                f"({n_samples / self.fs:.3f} s); use a recording at least as long as a scene "
                f"(short recordings are not tiled) or remove it")

    def segment(self, rng: np.random.Generator | None, n_samples: int, rule: str = "random",
                index: int = 0) -> tuple[int, np.ndarray]:
        """The scene's stretch of this recording: (offset in samples, audio float32 [C, n_samples]).

        ``random``: offset uniform over 0 … frames − n_samples, drawn from ``rng`` (the
        scene's generator; one draw). ``consecutive``: offset = (index mod blocks) ·
        n_samples, ``rng`` unused. Only those samples are read from the file.
        """
        offset = self.offset(rng, n_samples, rule, index)
        return offset, read_segment(self.path, offset, int(n_samples), self.frames)

    def offset(self, rng: np.random.Generator | None, n_samples: int, rule: str = "random", index: int = 0) -> int:
        """Where the scene's stretch starts (samples), by ``rule`` (see :meth:`segment`),
        without reading the file: the planner draws it, the renderer reads it."""
        if rule not in SEGMENT_RULES:
            raise ConfigError(f"unknown ambience segment rule {rule!r}; choose one of {', '.join(SEGMENT_RULES)}")
        n_samples = int(n_samples)
        self.check_length(n_samples)
        if rule == "consecutive":
            return (int(index) % self.blocks(n_samples)) * n_samples
        if rng is None:
            raise ValueError("a random ambience segment needs the scene's generator (rng)")
        return int(rng.integers(0, self.frames - n_samples + 1))


def read_segment(path: str, offset: int, n_samples: int, frames: int | None = None) -> np.ndarray:
    """Samples ``offset`` … ``offset + n_samples`` of an ambience recording, float32 [C, n]
    (only those are read); ConfigError for an unreadable, truncated or non-finite file."""
    check_input(path, ConfigError, "an ambience recording is a file")
    try:
        x, _ = sf.read(path, start=offset, stop=offset + n_samples, dtype="float32", always_2d=True)
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        raise ConfigError(f"cannot read ambience {path}: {_first_line(e)}; replace the file or "
                          f"remove it from the ambience folder") from None
    if x.shape[0] != n_samples:
        declared = f"the {frames} its header declares" if frames is not None else "the scene's end"
        raise ConfigError(f"ambience {path} ends at sample {offset + x.shape[0]}, before {declared}: the file is "
                          f"truncated; replace it")
    if not np.all(np.isfinite(x)):
        raise ConfigError(f"ambience {path} holds NaN or Inf samples in {offset} … "
                          f"{offset + n_samples}; replace the file")
    return np.ascontiguousarray(x.T)


@dataclass(frozen=True)
class AmbienceSet:
    """The recordings found in ``root``: ``by_room`` maps a room folder's name to its
    recording (empty for a flat folder, whose recordings are ``recordings``)."""

    root: str
    fs: int
    channels: int
    recordings: tuple
    by_room: dict

    @property
    def flat(self) -> bool:
        """A flat folder: any recording serves any room."""
        return not self.by_room

    @property
    def rooms(self) -> tuple:
        """The room folders' names (empty for a flat folder)."""
        return tuple(self.by_room)

    def for_room(self, room=None, rng: np.random.Generator | None = None) -> Recording:
        """The recording of bank room ``room`` (a TAU-SRIR DB name such as ``pb132``, or
        its number 1–10); for ``room=None`` (a simulated room) or a flat folder, one of
        all recordings drawn from ``rng`` (the scene's generator; not drawn from when
        there is only one). ConfigError naming the folders when none matches."""
        if room is None or self.flat:
            if len(self.recordings) == 1:
                return self.recordings[0]
            if rng is None:
                raise ValueError("choosing among several ambience recordings needs the scene's generator (rng)")
            return self.recordings[int(rng.integers(len(self.recordings)))]
        folder = _match_room(room, list(self.by_room), self.root)
        return self.by_room[folder]

    def check_length(self, n_samples: int) -> None:
        """ConfigError naming the first recording shorter than one scene of ``n_samples``."""
        for rec in self.recordings:
            rec.check_length(n_samples)


def find_ambience(root, channels: int, fs: int, fmt: str | None = None,
                  scene_samples: int | None = None) -> AmbienceSet:
    """Find the ambience recordings in ``root`` (module docstring: layouts) for a receiver
    of ``channels`` channels and scenes at ``fs`` Hz.

    fmt: the receiver's name (or alias), which picks its file in a TAU-SNoise_DB room
    folder (:data:`AMBIENCE_FILE_TAGS`); not needed for the user's own recordings.
    scene_samples: when given, recordings shorter than one scene are refused here rather
    than at the first segment. Reads headers only. Every problem is one ConfigError line
    naming the folder or file and how to fix it.
    """
    base = Path(root)
    if not base.exists():
        raise ConfigError(f"ambience folder {base} not found; point at the TAU-SNoise_DB folder (room folders "
                          f"01_bomb_center …) or at a folder of recordings")
    check_input(base, ConfigError, "point at the TAU-SNoise_DB folder or at a folder of recordings", folder=True)
    if not base.is_dir():
        raise ConfigError(f"ambience {base} is not a folder; point at the TAU-SNoise_DB folder or at a folder "
                          f"of recordings")
    audio = _audio_files(base)
    subdirs = [d for d in sorted(base.iterdir()) if d.is_dir() and not d.name.startswith((".", "__"))]
    room_dirs = [d for d in subdirs if _audio_files(d)]
    if audio and room_dirs:
        raise ConfigError(f"ambience folder {base} holds both recordings ({audio[0].name} …) and room folders "
                          f"({room_dirs[0].name} …); keep one layout: room folders, or recordings only")
    if not audio and not room_dirs:
        nested = next((d for d in subdirs if any(_audio_files(s) for s in d.iterdir() if s.is_dir())), None)
        hint = f"; {nested} holds room folders: point there" if nested else ""
        raise ConfigError(f"ambience folder {base} holds no recordings and no room folders with recordings{hint}")
    want = _TAG_OF_RECEIVER.get(canonical(fmt) or fmt) if fmt is not None else None
    by_room = {}
    if audio:
        paths = [(p, "") for p in audio]
    else:
        for d in subdirs:
            if d not in room_dirs:
                raise ConfigError(f"ambience room folder {d} holds no recordings; add the room's recording or "
                                  f"remove the folder")
        paths = [(_pick(d, fmt, want), d.name) for d in room_dirs]
    recs = []
    for path, room in paths:
        rec = _header(path, room, channels, fs, fmt)
        if scene_samples is not None:
            rec.check_length(int(scene_samples))
        recs.append(rec)
        if room:
            by_room[room] = rec
    return AmbienceSet(str(base), int(fs), int(channels), tuple(recs), by_room)


def omni_energy(x: np.ndarray, level_channels=()) -> float:
    """E(x) = Σ_t ((1/|L|) Σ_{c∈L} x[c, t])²: the energy of the mean of the level channels
    L of ``x`` [C, T] over all T samples (float64 sums).

    level_channels: channel indices (a receiver's ``level_channels``: (0,) = W for FOA),
    or a slice; empty or None means every channel (a mic array's capsules).
    """
    x = np.asarray(x)
    if x.ndim == 1:
        x = x[None, :]
    sel = slice(None) if level_channels is None or (not isinstance(level_channels, slice)
                                                     and len(level_channels) == 0) else level_channels
    if not isinstance(sel, slice):
        sel = list(sel)
    omni = x[sel].astype(np.float64).mean(axis=0)
    return float(np.dot(omni, omni))


def snr_gain(target_image: np.ndarray, noise: np.ndarray, snr_db: float, level_channels=()) -> float:
    """The gain g for ``noise`` [C, T] so that 10·log10(E(target) / E(g·noise)) = ``snr_db``
    (dB), E being :func:`omni_energy` over the whole scene (the DCASE generator's
    definition, module docstring): g = sqrt(E(target) · 10^(−snr_db/10) / E(noise)).

    target_image: the target as the receiver hears it, [C, T]. Returns 0.0 for a silent
    target (no level to refer to). ValueError for noise silent in the level channels.
    """
    target_image, noise = np.asarray(target_image), np.asarray(noise)
    if target_image.shape[-1] != noise.shape[-1]:
        # both energies are sums over the scene: a shorter one would read as quieter
        raise ValueError(f"target has {target_image.shape[-1]} samples and noise {noise.shape[-1]}; "
                         f"both must span the whole scene")
    e_target = omni_energy(target_image, level_channels)
    e_noise = omni_energy(noise, level_channels)
    if e_target == 0.0:
        return 0.0
    if e_noise == 0.0:
        raise ValueError("the noise is silent in its level channels; no gain gives it an SNR")
    return float(np.sqrt(e_target * 10.0 ** (-float(snr_db) / 10.0) / e_noise))


# --- discovery -------------------------------------------------------------------------------

def _audio_files(d: Path) -> list[Path]:
    return sorted(p for p in d.iterdir()
                  if p.suffix.lower() in AUDIO_SUFFIXES and p.is_file() and not p.name.startswith("."))


def _pick(d: Path, fmt, want) -> Path:
    """The recording of room folder ``d`` for the receiver: its TAU-tagged file, else its only file."""
    files = _audio_files(d)
    tagged = {}
    for p in files:
        m = _TAU_FILE.match(p.name)
        if m:
            tagged[m.group("tag").lower()] = p
    if tagged:
        known = ", ".join(f"{t} ({AMBIENCE_FILE_TAGS.get(t, 'no receiver')})" for t in sorted(tagged))
        if fmt is None:
            if len(tagged) == 1:
                return next(iter(tagged.values()))
            raise ConfigError(f"ambience room folder {d} holds recordings for several receivers ({known}); "
                              f"say which receiver the scenes use")
        if want is None:
            raise ConfigError(f"ambience room folder {d} holds TAU-SNoise recordings for {known}, none for "
                              f"receiver {fmt!r}; give a folder of {fmt} recordings")
        if want not in tagged:
            raise ConfigError(f"ambience room folder {d} has no {_tau_name(want)} for receiver {fmt!r}; it holds "
                              f"{', '.join(p.name for p in tagged.values())}")
        return tagged[want]
    if len(files) > 1:
        raise ConfigError(f"ambience room folder {d} holds {len(files)} recordings ({files[0].name}, "
                          f"{files[1].name} …); keep one per room folder, or put them all in one flat folder "
                          f"to use them for any room")
    return files[0]


def check_sounds(path, fs: int) -> None:
    """ConfigError when the recording is silent throughout (peak below -100 dBFS): no gain
    puts silence at an SNR, and every scene would record none. Read a second at a time,
    up to the first that sounds (the first, for any real recording); discovery itself
    reads headers only."""
    try:
        with sf.SoundFile(str(path)) as f:
            for block in f.blocks(blocksize=int(fs), dtype="float32", always_2d=True):
                if block.size and float(np.max(np.abs(block))) >= SILENT_PEAK:
                    return
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        raise ConfigError(f"cannot read ambience {path}: {_first_line(e)}; replace the file or remove it") from None
    raise ConfigError(f"ambience {path} is silent (peak below -100 dBFS throughout); no gain gives silence an SNR: "
                      f"replace it or remove it")


def _tau_name(tag: str) -> str:
    return f"ambience_{tag}_24k_edited.wav"


def _header(path: Path, room: str, channels: int, fs: int, fmt) -> Recording:
    """The recording of ``path`` from its header, checked against the receiver and the scenes."""
    try:
        if os.path.getsize(path) == 0:
            raise ConfigError(f"ambience {path} is empty (0 bytes); replace it or remove it")
        info = sf.info(str(path))
    except (sf.LibsndfileError, RuntimeError, OSError) as e:
        raise ConfigError(f"cannot read ambience {path}: {_first_line(e)}; replace the file or remove it") from None
    if info.frames <= 0:
        raise ConfigError(f"ambience {path} holds no samples; replace it or remove it")
    who = f"the receiver ({fmt})" if fmt else "the receiver"
    if info.channels != channels:
        raise ConfigError(f"ambience {path} has {info.channels} channels but {who} has {channels}; use a "
                          f"{channels}-channel recording made with (or encoded to) the receiver's format")
    if info.samplerate != fs:
        raise ConfigError(f"ambience {path} is at {info.samplerate} Hz but the scenes are at {fs} Hz; resample "
                          f"it to {fs} Hz (e.g. sox in.wav -r {fs} out.wav)")
    return Recording(str(path), room, int(info.channels), int(info.samplerate), int(info.frames))


# --- room matching ---------------------------------------------------------------------------

def _split(folder: str) -> tuple[int | None, str]:
    """(number prefix or None, the name after it), lower case: ``03_pb132_x`` -> (3, "pb132_x")."""
    m = _PREFIX.match(folder)
    if m:
        return int(m.group(1)), m.group(2).lower()
    return None, folder.lower()


def _starts(name: str, token: str) -> bool:
    return name == token or name.startswith(token + "_")


def _tau_number(name: str) -> int | None:
    """The TAU room number of a name that begins with one of its names, else None."""
    for number, names in TAU_ROOM_NAMES.items():
        if any(_starts(name, n) for n in names):
            return number
    return None


def _folder_number(folder: str) -> int | None:
    number, name = _split(folder)
    return number if number is not None else _tau_number(name)


def _match_room(room, folders: list[str], root: str) -> str:
    """The folder of bank room ``room`` (name or number): its full name, its name after the
    number prefix, its leading token, then its room number; the first tier with a match decides."""
    key = str(room).strip().lower()
    if key.isdigit():
        names, number = [], int(key)
    else:
        names, number = [key], _tau_number(key)
    tiers = [
        [f for f in folders if names and f.lower() == key],
        [f for f in folders if names and _split(f)[1] == key],
        [f for f in folders if names and _starts(_split(f)[1], key)],
        [f for f in folders if number is not None and _folder_number(f) == number],
    ]
    for found in tiers:
        if len(found) == 1:
            return found[0]
        if len(found) > 1:
            raise ConfigError(f"ambience folder {root}: room {room!r} matches several folders "
                              f"({', '.join(found)}); keep one")
    label = f"{room!r}" + (f" (TAU room {number:02d})" if number is not None else "")
    raise ConfigError(f"ambience folder {root} has no folder for bank room {label}; it holds "
                      f"{', '.join(folders)}: add the room's folder (TAU-SNoise_DB names it "
                      f"NN_<room>_…) or use a flat folder of recordings for every room")


def _first_line(e: Exception) -> str:
    s = str(e).strip()
    return s.splitlines()[0] if s else type(e).__name__
