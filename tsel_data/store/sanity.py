"""The last look at a scene before it is written: finite samples, levels near the ones its
config asked for, a target the noise does not bury. Every scene a shard takes passes
here (store/writer.py): rendered, recorded or made by hand.

A scene that fails stops the run with one line naming the scene and the setting to
blame (``audio.target_level_dbfs = 1000 dBFS``, ``noise.sensor_level``, the RIRs of a
room), never a shard of NaN. The check only reads: the bytes of a scene that passes
are what they were.
"""
from __future__ import annotations

import math

import numpy as np

from ..choices import NoiseKind
from ..errors import ConfigError

MAX_DROP_DB = 80.0  # the clipping guard may lower the target this far below audio.target_level_dbfs
MIN_TARGET_SNR_DB = -40.0  # the target against all the noise together, as the records measure them
MAX_PEAK = 1e4  # +80 dBFS: no scene of full-scale audio (rendered ones stay below 0.99)
MAX_GAIN_DB = 150.0  # a source's image amplified beyond this: its RIRs are all but silent

# the setting behind each noise's level, as a message names it
NOISE_SETTINGS = {NoiseKind.AMBIENCE: "noise.ambience_snr", NoiseKind.DIFFUSE: "noise.diffuse_snr",
                  NoiseKind.BABBLE: "noise.babble_snr", NoiseKind.SENSOR: "noise.sensor_level"}


def scene_problem(scene) -> str | None:
    """What makes ``scene`` unfit to be written ("holds NaN or Inf samples; ..."), with
    the setting to blame, or None."""
    for name, audio in (("", scene.audio), *((f" ({n}'s audio)", a) for n, (a, _) in (scene.receivers or {}).items())):
        if audio is None:
            continue
        if not np.isfinite(audio).all():
            return f"holds NaN or Inf samples{name}; {_blame(scene.record, overflow=True)}"
        peak = float(np.max(np.abs(audio))) if audio.size else 0.0
        if peak > MAX_PEAK:
            return f"has samples of amplitude {peak:.3g}{name}, not audio in full-scale units; {_blame(scene.record)}"
    rec = scene.record
    levels = getattr(rec, "levels", None)
    wanted, norm = getattr(levels, "target_level_dbfs", None), getattr(levels, "normalisation_db", None)
    if _finite(wanted) and _finite(norm) and norm < -MAX_DROP_DB:
        return (f"was scaled down by {-norm:.0f} dB to stay below full scale, which leaves its target "
                f"{-norm:.0f} dB below audio.target_level_dbfs = {wanted:g} dBFS; {_blame(rec)}")
    target = rec.sources[0].level_dbfs if rec is not None and rec.sources else None
    noise = [n.level_dbfs for n in getattr(rec, "noise", ()) if _finite(n.level_dbfs)]
    if _finite(target) and noise:
        snr = target - 10 * math.log10(sum(10 ** (v / 10) for v in noise))
        if snr < MIN_TARGET_SNR_DB:
            return (f"has its target {-snr:.0f} dB below the noise it is labelled over (its labels say it is "
                    f"heard); {_blame(rec)}")
    return None


def check_scene(scene) -> None:
    """ConfigError (one line, the scene and the setting to blame) for a scene unfit to be
    written (:func:`scene_problem`)."""
    problem = scene_problem(scene)
    if problem:
        raise ConfigError(f"scene {scene.scene_id} {problem}; nothing of it was written")


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


def _blame(rec, overflow: bool = False) -> str:
    """The setting that made the scene what it is, from its record: a target level above
    full scale, a source whose RIRs needed an absurd gain, the loudest part of the mix."""
    if rec is None or not rec.sources:
        return "the recording or the scene's parts are not audio in full-scale units: check them"
    wanted = getattr(rec.levels, "target_level_dbfs", None)
    if _finite(wanted) and wanted > 0:
        return f"audio.target_level_dbfs = {wanted:g} dBFS is above full scale: set a level below 0 dBFS, e.g. -25"
    for k, s in enumerate(rec.sources):
        gain = s.gain_db
        if (gain is None and overflow) or (_finite(gain) and gain > MAX_GAIN_DB):
            where = f"room {rec.room.name} of the bank {rec.room.bank}" if rec.room.is_bank else \
                f"the simulated room {rec.room.dims}"
            return (f"source {k} ({s.clip_id}) needed a gain of {'overflowing' if gain is None else f'+{gain:.0f}'} dB: "
                    f"its RIRs ({where}) are all but silent: re-import the bank or drop the room")
    parts = [(s.level_dbfs, _source_setting(k, s)) for k, s in enumerate(rec.sources)]
    parts += [(n.level_dbfs, _noise_setting(n)) for n in rec.noise]
    loud = [(v, what) for v, what in parts if _finite(v)]
    if loud:
        level, what = max(loud, key=lambda p: p[0])
        return f"the loudest part of the mix ({level:.0f} dBFS) comes from {what}"
    return "report it with the scene's recipe (plan/SPLIT.jsonl)"


def _source_setting(k: int, s) -> str:
    if k == 0:
        return "the target: audio.target_level_dbfs"
    if s.power_db is not None:
        return f"source {k} at sources.power = {s.power_db:g} dB: narrow sources.power"
    return f"interferer {k} at scene.tir_db = {s.tir_db} dB: narrow scene.tir_db"


def _noise_setting(n) -> str:
    key = NOISE_SETTINGS.get(n.kind, f"noise.{n.kind}")
    if n.kind == NoiseKind.SENSOR and n.snr_db is None:
        return f"{n.kind} noise: lower {key} (in dBFS: keep it well below audio.target_level_dbfs)"
    value = f" ({n.snr_db:g} dB)" if _finite(n.snr_db) else ""
    return f"{n.kind} noise: raise {key}{value}"
