"""Look at and listen to one scene: text summary, picture, mixture WAV and a headphone
preview of it (per-source stems are rendered again from the recipe by
:mod:`tsel_data.stems`, which the command line calls).

The picture: the room seen from above (walls, the array with an arrow along its front,
+x, every directional source with its trajectory, the target as a star); each source's
azimuth and elevation per label frame (a thick stroke per active frame, dotted where
silent); the active frames of each source; the spectrogram of channel 0; the title is
the query.
"""
from __future__ import annotations

import os
import textwrap

import numpy as np

from .atomic import atomic_output
from .audio import save_wav
from .errors import DatasetError, TselError
from .features import stft
from .geometry import array_to_room, sph_to_cart
from .stereo import stereo_preview
from .store.reader import Scene, list_splits, open_dataset

SOURCE_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")


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
                return ds[ds.position_of(i) if i >= 0 else i]
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
                return ds.by_id(ref)
    where = f"split {split!r}" if split else f"splits {', '.join(splits)}"
    raise DatasetError(f"no scene {ref!r} in {where} of {root}; give a scene id or SPLIT/INDEX such as "
                       f"{splits[0]}/0")


def _fmt_vec(v) -> str:
    return "(" + ", ".join(f"{x:.2f}" for x in v) + ")"


def summary(scene: Scene) -> str:
    """A multi-line human-readable description of a scene."""
    rec = scene.record
    lines = [f"scene {scene.scene_id}  (split {scene.split}, index {scene.index}, seed {rec.seed})",
             f"query: {scene.query!r}"] + query_lines(rec)
    lines.append(f"scenario: {rec.scenario}   motion: {rec.motion}   rir: {rec.rir_method}")
    room = rec.room
    dims = f"{' x '.join(f'{d:.2f}' for d in room.dims)} m" if room.dims else "size unknown"
    rt60, meas = room.rt60, room.rt60_measured
    if room.is_bank:
        lines.append(f"room: {room.name} of RIR bank {room.bank}, {dims}, "
                     + (f"RT60 {rt60:.2f} s" if rt60 is not None else "RT60 unknown"))
    elif room.dims or rt60 is not None:
        lines.append(f"room: {dims}, " + (f"RT60 {rt60:.2f} s requested, " if rt60 is not None else "")
                     + (f"{meas:.2f} s measured" if meas is not None else "RT60 not measured"))
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
        az = scene.azimuth[s]
        if np.isfinite(az).any():
            ok = np.isfinite(az)
            a0, a1 = az[ok][0], az[ok][-1]
            pos = (f"az {a0:7.1f}" + (f" -> {a1:.1f}" if abs(a1 - a0) > 0.05 else "") +
                   f" deg  el {np.nanmean(scene.elevation[s]):5.1f} deg  dist {np.nanmean(scene.distance[s]):.2f} m")
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
        for cap in info.captions:
            lines.append(f"        caption: {cap}")
    return "\n".join(lines)


def query_lines(rec) -> list[str]:
    """The query's type, relation and evidence, and the pairing (docs/queries.md); nothing
    for records made with the default query settings."""
    if not rec.extended:
        return []
    head = f"query type: {rec.query_type}"
    if rec.query_wanted != rec.query_type:
        head += f" (drawn: {rec.query_wanted})"
    ev = rec.query_evidence
    if ev:
        detail = f" {ev['time']:.1f} s" if ev.get("time") is not None else ""
        head += (f"   relation: {ev['relation']}{detail}, by {ev['value']:g} {ev['unit']} (margin {ev['margin']:g} "
                 f"{ev['unit']}) against source(s) {', '.join(map(str, ev['against']))}")
    pair = ", ".join(f"[{k}] {s.pairing}" + (f" {s.caption_similarity:.2f}" if s.caption_similarity is not None
                                             else "") for k, s in enumerate(rec.sources) if k)
    return [head, f"pairing: {rec.pairing} (similarity to the query caption: {pair})"]


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
    """Write the mixture's headphone preview (:mod:`tsel_data.stereo`), float32."""
    if scene.audio is None:
        raise TselError(f"{scene.scene_id}: read with audio=False; no audio to write")
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    save_wav(path, stereo_preview(scene.audio, scene.format, scene.mic_positions).T, scene.fs)
    return path


def source_tracks(scene: Scene) -> tuple[list[np.ndarray | None], np.ndarray, float]:
    """Room-frame xyz per frame [F, 3] of every source (None if positionless).

    Also returns the array centre and yaw used. Scenes that do not know where the array
    stood (measured RIR banks) are drawn in the array frame (centre 0, yaw 0).
    """
    arr, room = scene.record.array, scene.record.room
    if room.dims and arr.centre is not None:
        centre, yaw = np.asarray(arr.centre, dtype=np.float64), float(arr.yaw or 0.0)
    else:
        centre, yaw = np.zeros(3), 0.0
    tracks = []
    for s in range(scene.n_sources):
        az, el, d = scene.azimuth[s], scene.elevation[s], scene.distance[s]
        if not np.isfinite(az).any():
            tracks.append(None)
            continue
        p = sph_to_cart(az, np.nan_to_num(el), np.nan_to_num(d, nan=1.0))
        tracks.append(array_to_room(p, centre, yaw))
    return tracks, centre, yaw


def frame_runs(active: np.ndarray) -> list[tuple[int, int]]:
    """(first, count) of each run of consecutive active frames."""
    a = np.r_[False, np.asarray(active, bool), False]
    edges = np.flatnonzero(np.diff(a.astype(np.int8)))
    return [(int(b), int(e - b)) for b, e in zip(edges[::2], edges[1::2])]


def frame_segments(values: np.ndarray, active: np.ndarray, hop: float, wrap: bool = True):
    """x, y to draw a per-frame label over the frames a source is active in: each run of
    active frames from the start of its first frame to the end of its last, through the
    labels at the frame centres (a single active frame is a stroke the frame's width, so
    a source active in one frame still shows), broken (NaN) between runs and, with
    ``wrap``, where the azimuth wraps between -180° and 180° (no line across the plot)."""
    v = np.asarray(values, dtype=np.float64)
    on = np.asarray(active, bool) & np.isfinite(v)
    xs: list[float] = []
    ys: list[float] = []
    for first, n in frame_runs(on):
        ks = np.arange(first, first + n)
        cut = np.flatnonzero(np.abs(np.diff(v[ks])) > 180.0) + 1 if wrap else []
        for piece in np.split(ks, cut):
            if xs:
                xs.append(np.nan)
                ys.append(np.nan)
            xs += [piece[0] * hop, *((piece + 0.5) * hop), (piece[-1] + 1) * hop]
            ys += [v[piece[0]], *v[piece], v[piece[-1]]]
    return np.asarray(xs), np.asarray(ys)


def wrap_breaks(t: np.ndarray, az: np.ndarray):
    """t, az with NaN inserted where the azimuth wraps (|step| > 180°), for a line plot."""
    az = np.asarray(az, dtype=np.float64)
    jumps = np.flatnonzero(np.abs(np.diff(az)) > 180.0) + 1
    return np.insert(np.asarray(t, dtype=np.float64), jumps, np.nan), np.insert(az, jumps, np.nan)


def plot_scene(scene: Scene, path: str, dpi: int = 110) -> str:
    """Draw the scene to a PNG file: the room from above; azimuth and elevation per label
    frame (a thick stroke per active frame, dotted where silent, no jump where the
    azimuth wraps); which frames each source is active in; the spectrogram of channel 0."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    if scene.audio is None:
        raise TselError(f"{scene.scene_id}: read with audio=False; cannot draw a spectrogram")
    fig = plt.figure(figsize=(13, 8.6))
    gs = fig.add_gridspec(4, 2, width_ratios=(1.0, 1.35), height_ratios=(1.0, 0.8, 0.22 + 0.1 * scene.n_sources, 1.0),
                          hspace=0.55, wspace=0.3)
    ax_room = fig.add_subplot(gs[:, 0])
    ax_az = fig.add_subplot(gs[0, 1])
    ax_el = fig.add_subplot(gs[1, 1], sharex=ax_az)
    ax_act = fig.add_subplot(gs[2, 1], sharex=ax_az)
    ax_spec = fig.add_subplot(gs[3, 1])
    rec = scene.record
    tracks, centre, yaw = source_tracks(scene)
    # measured-bank scenes may know their room's size but not where the array stood: array frame
    dims = rec.room.dims if rec.array.centre is not None else None

    # --- room from above ----------------------------------------------------------
    if dims:
        ax_room.add_patch(Rectangle((0, 0), dims[0], dims[1], fill=False, lw=2, color="0.2"))
        ax_room.set_xlim(-0.3, dims[0] + 0.3)
        ax_room.set_ylim(-0.3, dims[1] + 0.3)
        ax_room.set_xlabel("room x (m)")
        ax_room.set_ylabel("room y (m)")
    else:
        ax_room.set_xlabel("x (m, array front)")
        ax_room.set_ylabel("y (m, array left)")
    mics = array_to_room(scene.mic_positions.astype(np.float64), centre, yaw)
    ax_room.plot(mics[:, 0], mics[:, 1], "k.", ms=4)
    span = max(dims[:2]) if dims else 4.0
    L = 0.09 * span
    ax_room.annotate("", xy=(centre[0] + L * np.cos(np.radians(yaw)), centre[1] + L * np.sin(np.radians(yaw))),
                     xytext=(centre[0], centre[1]), arrowprops=dict(arrowstyle="-|>", color="k", lw=1.8))
    ax_room.plot([centre[0]], [centre[1]], "ks", ms=5, label=f"array ({scene.format}), arrow = front")
    t = scene.frame_times()
    hop = scene.label_hop
    for s, tr in enumerate(tracks):
        col = SOURCE_COLOURS[s % len(SOURCE_COLOURS)]
        name = f"{s}: {rec.sources[s].role}"
        if tr is None:
            ax_room.plot([], [], " ", label=f"{name} (additive, no position)")
            continue
        ax_room.plot(tr[:, 0], tr[:, 1], "-", color=col, lw=1.2, alpha=0.8)
        marker, size = ("*", 16) if s == 0 else ("o", 8)
        ax_room.plot(tr[-1, 0], tr[-1, 1], marker, color=col, ms=size, label=name)
        if np.ptp(tr[:, :2], axis=0).max() > 1e-3:
            ax_room.plot(tr[0, 0], tr[0, 1], "x", color=col, ms=7)  # start of a moving source
    ax_room.set_aspect("equal")
    ax_room.legend(loc="best", fontsize=8, framealpha=0.85)
    ax_room.set_title("room from above" + ("" if dims else " (array frame)"), fontsize=10)

    # --- azimuth and elevation per frame ------------------------------------------------
    for ax, labels, wrap in ((ax_az, scene.azimuth, True), (ax_el, scene.elevation, False)):
        for s in range(scene.n_sources):
            v = labels[s].astype(np.float64)
            if not np.isfinite(v).any():
                continue
            col = SOURCE_COLOURS[s % len(SOURCE_COLOURS)]
            ax.plot(*(wrap_breaks(t, v) if wrap else (t, v)), ":", color=col, lw=1)
            ax.plot(*frame_segments(v, scene.active[s], hop, wrap), "-", color=col, lw=3, solid_capstyle="butt",
                    label=f"{s}: {rec.sources[s].role}")
        ax.grid(alpha=0.3)
    ax_az.set_ylim(-180, 180)
    ax_az.set_yticks(range(-180, 181, 90))
    ax_az.set_ylabel("azimuth (deg)")
    ax_az.set_title("azimuth and elevation per label frame (thick = active, dotted = silent)", fontsize=10)
    if ax_az.has_data():
        ax_az.legend(fontsize=8, loc="best", framealpha=0.8)
    el = scene.elevation[np.isfinite(scene.elevation)]
    lo, hi = (float(el.min()), float(el.max())) if el.size else (-10.0, 10.0)
    pad = max(5.0, 0.15 * (hi - lo))
    ax_el.set_ylim(max(-90.0, lo - pad), min(90.0, hi + pad))
    ax_el.set_ylabel("elevation (deg)")

    # --- activity: every active frame, one row per source ----------------------------------
    for s in range(scene.n_sources):
        col = SOURCE_COLOURS[s % len(SOURCE_COLOURS)]
        runs = [(k * hop, n * hop) for k, n in frame_runs(scene.active[s])]
        ax_act.broken_barh(runs, (s - 0.35, 0.7), facecolors=col)
    ax_act.set_yticks(range(scene.n_sources))
    ax_act.set_yticklabels([f"{s}: {rec.sources[s].role} {100 * scene.active[s].mean():.0f}%"
                            for s in range(scene.n_sources)], fontsize=8)
    ax_act.set_ylim(scene.n_sources - 0.5, -0.5)
    ax_act.set_xlim(0, scene.n_frames * hop)
    ax_act.set_title("active frames", fontsize=10)
    ax_act.grid(axis="x", alpha=0.3)

    # --- spectrogram of channel 0 --------------------------------------------------
    spec = np.abs(stft(scene.audio[:1], 1024, 256))[0].T
    db = 20 * np.log10(spec + 1e-9)
    vmax = db.max()
    dur = scene.audio.shape[1] / scene.fs
    ax_spec.imshow(db, origin="lower", aspect="auto", cmap="magma", vmin=vmax - 80, vmax=vmax,
                   extent=(0, dur, 0, scene.fs / 2000))
    ax_spec.set_xlabel("time (s)")
    ax_spec.set_ylabel("kHz")
    ax_spec.set_title("spectrogram of channel 0", fontsize=10)

    fig.suptitle(textwrap.fill(f"{scene.scene_id}: \u201c{scene.query}\u201d", 110), fontsize=11)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    try:
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format="png")
    finally:
        plt.close(fig)
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
