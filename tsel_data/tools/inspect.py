"""Look at and listen to one scene: text summary, picture (:mod:`tsel_data.tools.picture`),
mixture WAV and a headphone preview of it (per-source stems are rendered again from the
recipe by :mod:`tsel_data.job.stems`, which the command line calls); many scenes at once on
a contact sheet (:mod:`tsel_data.tools.sheet`).
"""
from __future__ import annotations

import os

import numpy as np

from ..corpus.audio import save_wav
from ..errors import DatasetError, TselError
from ..receivers.stereo import stereo_preview
from ..store.reader import Scene, list_splits, open_dataset
from .picture import (frame_runs, frame_segments, noise_parts, plot_scene, query_lines, room_text, source_tracks,
                      wrap_breaks)

# the drawing lives in tools/picture.py; these names stay importable from here
__all__ = ["find_scene", "summary", "hardware_lines", "query_lines", "write_wav", "write_stereo", "stereo_path", "inspect_outputs",
           "inspect_scene", "plot_scene", "source_tracks", "frame_runs", "frame_segments", "wrap_breaks"]


def find_scene(root: str, ref: str, split: str | None = None, receiver: str | None = None) -> Scene:
    """A scene by id (``test-000012``) or by ``split/index`` (``test/12``; negative counts
    from the end). A dataset still being made is searched in its finished shards.
    receiver: whose audio the scene carries, for datasets heard by several."""
    splits = list_splits(root, unfinished=True)
    if "/" in ref:
        sp, _, idx = ref.partition("/")
        try:
            i = int(idx)
        except ValueError:
            raise TselError(f"scene {ref!r}: expected SPLIT/INDEX with an integer index, e.g. test/0") from None
        with open_dataset(root, sp, unfinished=True, receiver=receiver) as ds:
            try:
                return ds.finite(ds[ds.position_of(i) if i >= 0 else i])
            except IndexError:
                if not ds.doc.finished and 0 <= i < ds.doc.planned.get(sp, 0):
                    raise DatasetError(f"scene {ref!r} is not rendered yet (its shard is unfinished; {len(ds)} "
                                       f"scenes of split {sp!r} are)") from None
                raise DatasetError(f"scene {ref!r}: split {sp!r} has {len(ds)} scenes (index 0..{len(ds) - 1})") from None
    # Scene ids start with their split by convention; look there first, then everywhere.
    order = [split] if split else sorted(splits, key=lambda s: not ref.startswith(s + "-"))
    for sp in order:
        with open_dataset(root, sp, unfinished=True, receiver=receiver) as ds:
            if ref in ds:
                return ds.finite(ds.by_id(ref))
    where = f"split {split!r}" if split else f"splits {', '.join(splits)}"
    raise DatasetError(f"no scene {ref!r} in {where} of {root}; give a scene id or SPLIT/INDEX such as "
                       f"{splits[0]}/0")


def _fmt_vec(v) -> str:
    return "(" + ", ".join(f"{x:.2f}" for x in v) + ")"


def _span(labels: np.ndarray, fmt: str) -> str | None:
    """A label row's first labelled value, and its last after ``->`` when that reads
    differently (a moving source); None when no frame is labelled."""
    known = labels[np.isfinite(labels)]
    if not known.size:
        return None
    first, last = fmt.format(known[0]), fmt.format(known[-1]).strip()
    return first if first.strip() == last else f"{first} -> {last}"


def summary(scene: Scene) -> str:
    """A multi-line human-readable description of a scene."""
    rec = scene.record
    lines = [f"scene {scene.scene_id}  (split {scene.split}, index {scene.index}, seed {rec.seed})",
             f"query: {scene.query!r}"] + query_lines(rec)
    lines.append(f"scenario: {rec.scenario}   motion: {rec.motion}   rir: {rec.rir_method}")
    if rec.recording is not None:
        r = rec.recording
        lines.append(f"recorded: {r.dataset} {r.audio}, {r.start:g}-{r.start + r.frames * scene.label_hop:g} s "
                     f"(label frames {r.start_frame}-{r.start_frame + r.frames - 1} of {r.metadata}), fold "
                     f"{r.fold}, room {r.room}")
        lines.append("classes: " + "; ".join(f"[{k}] {c} (source {a})"
                                             for k, (c, a) in enumerate(zip(r.classes, r.actors))))
    room = room_text(rec)
    if room:
        lines.append(f"room: {room}")
    arr = rec.array
    if arr.format:
        side = f" (side {arr.side:.3f} m)" if arr.side else ""
        where = (f" at {_fmt_vec(arr.centre)} m, front (yaw) {arr.yaw or 0.0:.1f} deg"
                 if arr.centre is not None else ", position in the room unknown (labels are in the array frame)")
        lines.append(f"array: {arr.format}{side}{where}")
    dur = scene.audio.shape[1] / scene.fs if scene.audio is not None else scene.n_frames * scene.label_hop
    if scene.audio is not None:
        peak = float(np.max(np.abs(scene.audio)))
        rms = float(np.sqrt(np.mean(scene.audio.astype(np.float64) ** 2)))
        lines.append(f"audio: {scene.audio.shape[0]} ch x {dur:.2f} s at {scene.fs} Hz, "
                     f"peak {20 * np.log10(peak + 1e-12):.1f} dBFS, rms {20 * np.log10(rms + 1e-12):.1f} dBFS")
    lines.append(f"labels: {scene.n_frames} frames of {scene.label_hop:g} s, {scene.n_sources} sources")
    for s in range(scene.n_sources):
        info = rec.sources[s]
        act = scene.active[s]
        if np.isfinite(scene.azimuth[s]).any():
            el = _span(scene.elevation[s], "{:5.1f}")
            dist = _span(scene.distance[s], "{:.2f}")
            pos = (f"az {_span(scene.azimuth[s], '{:7.1f}')} deg  el "
                   + (f"{el} deg" if el else "    - (not labelled)") + "  dist "
                   + (f"{dist} m" if dist else "- (not labelled)"))
        else:
            pos = "no position (additive)"
        extra = []
        if info.tir_db is not None:
            extra.append(f"TIR {info.tir_db:.1f} dB")
        if info.level_dbfs is not None:
            extra.append(f"level {info.level_dbfs:.1f} dBFS")
        lines.append(f"  [{s}] {info.role:<10} {info.clip_id or '?'}  {info.spatial}"
                     f"{' moving' if info.moving else ''}  {pos}  active {100 * act.mean():.0f}% of frames"
                     + (f"  {', '.join(extra)}" if extra else ""))
        described = acoustics_text(info)
        if described:
            lines.append(f"        {described}")
        for cap in info.captions:
            lines.append(f"        caption: {cap}")
    hw = getattr(rec.receiver(scene.format), "hardware", None)
    if hw is not None:
        lines += hardware_lines(hw, dur)
    if rec.noise:
        lines.append("noise (unlabelled):")
        lines += [f"  {kind:<9} {'  '.join(rest)}" for kind, *rest in (noise_parts(n) for n in rec.noise)]
    return "\n".join(lines)


PROFILE_WORDS = {"mems": "a typical MEMS board", "measurement": "a typical measurement-grade array"}


def _range(values, unit: str, fmt: str = "{:+.2f}", spread: bool = False) -> str:
    lo, hi = min(values), max(values)
    if lo == hi:
        return f"{fmt.format(lo)} {unit}"
    return f"{fmt.format(lo)} to {fmt.format(hi)} {unit}" + (f" (spread {hi - lo:.2f})" if spread else "")


def hardware_lines(hw, duration: float) -> list[str]:
    """The receiver's microphones as built (``[hardware]``, a HardwareRecord), in words."""
    who = PROFILE_WORDS.get(hw.profile, "as configured")
    lines = [f"microphones as built ({who}; not in the labels, which stay the geometry):"]
    lines.append(f"  gain off nominal {_range(hw.gain_db, 'dB', spread=True)}: " + " ".join(f"{g:+.2f}" for g in hw.gain_db))
    lines.append(f"  delay off nominal {_range(hw.delay_us, 'us', spread=True)}: " + " ".join(f"{d:+.2f}" for d in hw.delay_us))
    parts = []
    corners = [f for f in hw.highpass_hz if f > 0]
    if corners:
        order = {1: "1st", 2: "2nd", 3: "3rd"}.get(hw.highpass_order, f"{hw.highpass_order}th")
        parts.append(f"high-pass at {_range(corners, 'Hz', '{:.0f}')} ({order} order)")
    if any(hw.tilt_db):
        parts.append(f"tilt {_range(hw.tilt_db, 'dB per octave about 1 kHz')}")
    if hw.response_file:
        parts.append(f"measured response {hw.response_file}")
    if parts:
        lines.append("  response: " + "; ".join(parts))
    if hw.self_noise_dba:
        lines.append(f"  self-noise {_range(hw.self_noise_dba, 'dB SPL(A)', '{:.1f}')}, i.e. "
                     f"{_range(hw.self_noise_dbfs, 'dBFS(A)', '{:.1f}')} at {hw.sensitivity_dbfs:g} dBFS for "
                     f"94 dB SPL")
    for d in range(1, len(hw.clock_offset_us or ())):
        off, ppm = hw.clock_offset_us[d], hw.clock_ppm[d]
        caps = [c for c, dev in enumerate(hw.devices) if dev == d]
        lines.append(f"  device {d} (channels {', '.join(map(str, caps))}) lags device 0 by {off:+.1f} us at the "
                     f"start, drifting {ppm:+.2f} ppm ({off + ppm * duration:+.1f} us at the end)")
    return lines


def acoustics_text(source) -> str | None:
    """A source's motion class and acoustic descriptors in words (``output.descriptors``),
    or None for a record without them."""
    a, parts = source.acoustics or {}, []
    if source.motion:
        parts.append(source.motion)
    for key, label, fmt in (("drr_db", "DRR", "{:.1f} dB"), ("c50_db", "C50", "{:.1f} dB"),
                            ("edt_s", "EDT", "{:.2f} s"), ("t30_s", "T30", "{:.2f} s")):
        if a.get(key) is not None:
            parts.append(f"{label} {fmt.format(a[key])}")
    bands = {int(b): t for b, t in (a.get("t30_bands_s") or {}).items() if t is not None}
    if bands:
        parts.append("T30 by octave " + " ".join(f"{_hz(b)} {t:.2f}" for b, t in sorted(bands.items())) + " s")
    return ", ".join(parts) or None


def _hz(f: int) -> str:
    return f"{f // 1000}k" if f >= 1000 else str(f)


def write_wav(scene: Scene, path: str, subtype: str = "FLOAT") -> str:
    """Write the mixture [C, T] as a WAV file (float32 by default, nothing clipped)."""
    if scene.audio is None:
        raise TselError(f"{scene.scene_id}: read with audio=False; no audio to write")
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    save_wav(path, scene.audio.T, scene.fs, subtype=subtype)
    return path


def stereo_path(path: str) -> str:
    """Where the headphone preview of the mixture written to ``path`` goes: ``X.stereo.wav``."""
    return f"{os.path.splitext(path)[0]}.stereo.wav"


def inspect_outputs(png: str | None = None, wav: str | None = None) -> list[str]:
    """Every file :func:`inspect_scene` writes, so all can be claimed before any is
    written (store/outputs.py)."""
    return [p for p in (png, wav, wav and stereo_path(wav)) if p]


def write_stereo(scene: Scene, path: str) -> str:
    """Write the mixture's headphone preview (:mod:`tsel_data.receivers.stereo`), float32."""
    if scene.audio is None:
        raise TselError(f"{scene.scene_id}: read with audio=False; no audio to write")
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    save_wav(path, stereo_preview(scene.audio, scene.format, scene.mic_positions).T, scene.fs)
    return path


def inspect_scene(root: str, ref: str | Scene, split: str | None = None, png: str | None = None,
                  wav: str | None = None, receiver: str | None = None) -> tuple[Scene, str]:
    """Find a scene (``ref``: an id, SPLIT/INDEX, or the Scene found already), optionally
    write its picture, its mixture (``wav``) and the mixture's headphone preview
    (:func:`stereo_path`), as ``receiver`` heard it (default the dataset's first);
    returns (scene, summary text). The files are written as asked: the command claims
    them first (:func:`inspect_outputs`, store/outputs.py)."""
    scene = ref if isinstance(ref, Scene) else find_scene(root, ref, split, receiver)
    if png:
        plot_scene(scene, png)
    if wav:
        write_wav(scene, wav)
        write_stereo(scene, stereo_path(wav))
    return scene, summary(scene)
