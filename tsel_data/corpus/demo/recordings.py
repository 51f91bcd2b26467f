"""A stand-in for STARSS23, in its exact layout: synthetic plane-wave recordings with known
events, so the recorded-dataset path runs anywhere (``--preset demo-recorded``, the tests,
docs/recorded.md). Not a recording of anything: each event is a plane wave of noise from
its labelled direction (FOA: W = s, Y = s sin(az) cos(el), Z = s sin(el),
X = s cos(az) cos(el); MIC: free-field delays at the tetrahedral capsules), its direction
moving linearly between frame centres when the event moves, over a faint diffuse floor.

Layout (STARSS23's)::

    OUT/foa_dev/dev-{train,test}-sony/fold{3,4}_room{R}_mix{NNN}.wav   24 kHz, 4 channels
    OUT/mic_dev/...                                                    the same scenes, MIC
    OUT/metadata_dev/dev-{train,test}-sony/fold{3,4}_room{R}_mix{NNN}.csv

Fold 3 (dev-train) writes the 2024 edition's 6-column rows (distance in cm), fold 4
(dev-test) the 5-column rows. The events exercise what a real set holds: two actors of one
class talking at once (a relation must tell them apart), one actor's speech and laughter
(two sources), two non-actor sources of one class at once, moving sources, events shorter
than a second, and a pair of same-class events no relation tells apart (skipped).
"""
from __future__ import annotations

import csv
import os
from dataclasses import dataclass

import numpy as np
import soundfile as sf

from ...core.geometry import SOUND_SPEED, sph_to_cart
from ...receivers import tetra_positions

FS = 24000
HOP = 0.1


@dataclass(frozen=True)
class Event:
    """One labelled event: ``cls``, ``source`` (the actor column), frames [``on``, ``off``),
    direction at ``on`` and at ``off`` (deg; linear in between), distance (m)."""

    cls: int
    source: int
    on: int
    off: int
    az: tuple[float, float]
    el: tuple[float, float]
    dist: float

    def direction(self, frame) -> tuple[np.ndarray, np.ndarray]:
        """(azimuth, elevation) at fractional frame positions (frame k's centre is k + 0.5)."""
        t = np.clip((np.asarray(frame, dtype=np.float64) - self.on - 0.5) / max(self.off - self.on - 1, 1), 0, 1)
        az0, az1 = self.az
        az = az0 + t * (((az1 - az0 + 180.0) % 360.0) - 180.0)
        return (az + 180.0) % 360.0 - 180.0, self.el[0] + t * (self.el[1] - self.el[0])


# (folder, fold, room, mix, seconds, events): classes are STARSS23's (corpus/ontologies.py)
RECORDINGS = (
    ("dev-train-sony", 3, 1, 1, 30, (
        Event(1, 1, 10, 120, (30.0, 30.0), (0.0, 0.0), 1.5),      # a man speaking ...
        Event(1, 2, 45, 150, (-60.0, -60.0), (10.0, 10.0), 2.5),  # ... and another, 3.5 s later
        Event(8, 0, 0, 300, (120.0, 120.0), (0.0, 0.0), 3.0),     # music all along
        Event(3, 0, 160, 200, (-90.0, -20.0), (0.0, 0.0), 2.0),   # a telephone carried round
        Event(8, 0, 200, 280, (-150.0, -150.0), (20.0, 20.0), 2.0),  # a second music source at once
    )),
    ("dev-train-sony", 3, 2, 2, 30, (
        Event(0, 1, 20, 140, (90.0, 90.0), (-10.0, -10.0), 1.2),   # a woman speaks ...
        Event(4, 1, 150, 190, (90.0, 90.0), (-10.0, -10.0), 1.2),  # ... and laughs: another source
        Event(6, 2, 30, 230, (-30.0, 150.0), (-20.0, -20.0), 2.0),  # footsteps walking round
        Event(12, 0, 100, 106, (0.0, 0.0), (0.0, 0.0), 1.0),       # a knock too short to be a target
    )),
    ("dev-test-sony", 4, 3, 3, 30, (
        Event(0, 1, 0, 90, (-45.0, -45.0), (0.0, 0.0), 1.0),
        Event(0, 2, 30, 180, (135.0, 135.0), (15.0, 15.0), 3.0),  # two women, the second from 3 s
        Event(10, 0, 100, 260, (60.0, 60.0), (-30.0, -30.0), 1.5),  # a tap running
        Event(11, 0, 200, 240, (-120.0, -120.0), (30.0, 30.0), 2.0),
    )),
    ("dev-test-sony", 4, 4, 4, 20, (
        Event(1, 1, 20, 120, (10.0, 10.0), (0.0, 0.0), 1.0),   # two men starting and stopping
        Event(1, 2, 20, 120, (-100.0, -100.0), (0.0, 0.0), 1.0),  # together: no relation holds
        Event(2, 0, 130, 180, (170.0, 170.0), (0.0, 0.0), 2.0),
    )),
)


def synth_recordings(out_dir, seed: int = 0, seconds: float | None = None) -> dict:
    """Write the stand-in into ``out_dir`` (created; files of the same names replaced).
    ``seconds``: cut every recording to this long (faster tests). Returns {"out_dir",
    "recordings": [relative WAV paths], "events": {relative CSV path: [Event]}}."""
    out = {"out_dir": str(out_dir), "recordings": [], "events": {}}
    rng = np.random.default_rng(seed)
    for folder, fold, room, mix, length, events in RECORDINGS:
        length = min(length, seconds) if seconds else length
        frames = int(round(length / HOP))
        events = tuple(e for e in events if e.on < frames)
        events = tuple(Event(e.cls, e.source, e.on, min(e.off, frames), e.az, e.el, e.dist) for e in events)
        name = f"fold{fold}_room{room}_mix{mix:03d}"
        signals = [_signal(rng, e, frames) for e in events]
        for top in ENCODERS:
            audio = _diffuse(rng, frames) + sum(_encode(s, e, top) for s, e in zip(signals, events))
            rel = os.path.join(top, folder, f"{name}.wav")
            os.makedirs(os.path.join(out_dir, os.path.dirname(rel)), exist_ok=True)
            sf.write(os.path.join(out_dir, rel), audio.T.astype(np.float32), FS, subtype="PCM_16")
            out["recordings"].append(rel.replace(os.sep, "/"))
        meta = os.path.join("metadata_dev", folder, f"{name}.csv")
        os.makedirs(os.path.join(out_dir, os.path.dirname(meta)), exist_ok=True)
        _write_labels(os.path.join(out_dir, meta), events, six=fold == 3)
        out["events"][meta.replace(os.sep, "/")] = list(events)
    return out


def _signal(rng: np.random.Generator, e: Event, frames: int) -> np.ndarray:
    """The event's dry sound: noise with a class-dependent colour, zero outside its frames
    (a 5 ms ramp at each end)."""
    n = frames * int(HOP * FS)
    x = np.zeros(n)
    a, b = e.on * int(HOP * FS), e.off * int(HOP * FS)
    s = rng.standard_normal(b - a)
    k = np.fft.rfftfreq(b - a, 1 / FS)
    tilt = (np.maximum(k, 50.0) / 1000.0) ** (-0.25 * (e.cls % 4))  # each class its own spectral tilt
    s = np.fft.irfft(np.fft.rfft(s) * tilt, b - a)
    ramp = min(120, (b - a) // 2)
    env = np.ones(b - a)
    env[:ramp], env[-ramp:] = np.linspace(0, 1, ramp), np.linspace(1, 0, ramp)
    x[a:b] = 0.05 * s / np.sqrt(np.mean(s ** 2)) * env
    return x


def _foa(s: np.ndarray, u: np.ndarray) -> np.ndarray:
    """ACN/SN3D of a plane wave from unit directions ``u`` [T, 3]: W, Y, Z, X."""
    return np.stack([s, s * u[:, 1], s * u[:, 2], s * u[:, 0]])


def _mic(s: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The tetrahedral capsules as free-field omnis: each hears the wave when it passes."""
    out = np.empty((4, len(s)))
    t = np.arange(len(s), dtype=np.float64)
    for c, p in enumerate(tetra_positions()):
        lead = (u @ p) / SOUND_SPEED * FS  # samples: a capsule nearer the source hears it earlier
        out[c] = np.interp(t + lead, t, s, left=0.0, right=0.0)
    return out


ENCODERS = {"foa_dev": _foa, "mic_dev": _mic}  # the DCASE layout's audio folders


def _encode(s: np.ndarray, e: Event, folder: str) -> np.ndarray:
    """A plane wave of ``s`` from the event's direction at each sample, [4, T]."""
    az, el = e.direction(np.arange(len(s)) / (HOP * FS))
    return ENCODERS[folder](s, sph_to_cart(az, el, 1.0))


def _diffuse(rng: np.random.Generator, frames: int) -> np.ndarray:
    """A faint uncorrelated floor (-70 dBFS), so no channel is digital silence."""
    return 3e-4 * rng.standard_normal((4, frames * int(HOP * FS)))


def _write_labels(path: str, events, six: bool) -> None:
    rows = []
    for e in events:
        for f in range(e.on, e.off):
            az, el = e.direction(f + 0.5)
            azi = int(np.floor(float(az) + 0.5))
            azi = azi - 360 if azi >= 180 else azi
            row = [f, e.cls, e.source, azi, int(np.floor(float(el) + 0.5))]
            rows.append(row + [int(round(e.dist * 100))] if six else row)
    rows.sort()
    with open(path, "w", newline="", encoding="utf-8") as fh:
        csv.writer(fh, lineterminator="\n").writerows(rows)
