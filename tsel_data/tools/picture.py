"""The picture of one scene (``tsel inspect --png``) and its small array-centred view
(the contact sheet's, :mod:`tsel_data.tools.sheet`).

The picture: above, the query, its type, relation and evidence, the scene and its noise,
wrapped to the width the legend leaves them, and beside them one legend for every panel;
on the left the room seen from above (walls, the array with an arrow along its front,
+x, every directional source with its trajectory, the target as a star) and the array
frame seen from above (azimuth and distance around the array, front up, left to the
left, babble noise's directions on its rim), which shows every scene, even one whose
bank does not say where the array stood; on the right each source's azimuth and
elevation per label frame (a stroke per active frame, dotted over silent ones only; the
target drawn narrow on top of the interferers' wide strokes, so both show where they
share a value; babble's directions beside the azimuth axis), the active frames of each
source and the spectrogram of channel 0.
"""
from __future__ import annotations

import os
import re

import numpy as np

from ..choices import NoiseKind
from ..core.atomic import atomic_output
from ..core.geometry import array_to_room, sph_to_cart
from ..dsp.features import stft
from ..errors import TselError

SOURCE_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")
# The azimuth axis runs a little past ±180° so a source at 177° does not sit on the frame.
AZIMUTH_LIMITS = (-195.0, 195.0)
# Drawing order and strokes: interferers wide and pale below, the target narrow on top.
TARGET_Z, INTERFERER_Z = 5.0, 2.0
TARGET_LW, INTERFERER_LW = 2.4, 6.0
# Noise is no source: grey, and a marker no source uses.
NOISE_COLOUR, NOISE_MARKER = "0.35", "D"
# The figure in inches: the panels keep their size, the header above them is as tall as
# its text or its legend; left and right as matplotlib's defaults.
FIG_WIDTH, BODY_HEIGHT = 14.0, 6.7
MARGIN_TOP, HEADER_GAP, MARGIN_BOTTOM = 0.3, 0.45, 1.0
PLOT_LEFT, PLOT_RIGHT = 0.125, 0.9
LEGEND_GAP = 0.3  # inches between the header's text and the legend
# Text narrower than this share of the header reads badly: below the legend instead.
MIN_TEXT_SHARE = 0.35
CAPTION_SIZE, FACTS_SIZE, LEGEND_SIZE = 13.0, 9.0, 8.5


def source_colour(s: int) -> str:
    return SOURCE_COLOURS[s % len(SOURCE_COLOURS)]


def source_tracks(scene) -> tuple[list[np.ndarray | None], np.ndarray, float]:
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


def room_text(rec) -> str | None:
    """The room in words (size, RT60, the bank it comes from), or None when unknown."""
    room = rec.room
    dims = f"{' x '.join(f'{d:.2f}' for d in room.dims)} m" if room.dims else "size unknown"
    if room.volume_m3 is not None:
        dims += f" ({room.volume_m3:.0f} m³, floor {room.floor_area_m2:.0f} m²)"
    rt60, meas = room.rt60, room.rt60_measured
    if room.is_bank:
        return (f"{room.name} of RIR bank {room.bank}, {dims}, "
                + (f"RT60 {rt60:.2f} s" if rt60 is not None else "RT60 unknown"))
    if room.dims or rt60 is not None:
        return (f"{dims}, " + (f"RT60 {rt60:.2f} s requested, " if rt60 is not None else "")
                + (f"{meas:.2f} s measured" if meas is not None else "RT60 not measured"))
    return None


# What a noise's record says it is, by kind (render/noise.py NOISE_KINDS); a kind not
# named here is told by its kind and levels alone.
NOISE_DETAILS = {
    NoiseKind.AMBIENCE: lambda n: f"recording {n.file}" + (f" from sample {n.offset}" if n.offset is not None else ""),
    NoiseKind.DIFFUSE: lambda n: f"{n.spectrum} spectrum" + (f" of {n.clips[0][0]}" if n.clips else ""),
    NoiseKind.BABBLE: lambda n: f"{len(n.clips or ())} clips",
    NoiseKind.SENSOR: lambda n: "on every channel",
}


def noise_parts(noise, directions: bool = True) -> list[str]:
    """One noise of a scene's record in words: its kind, what it is, where it comes from
    (with ``directions``, for noise that has them), its SNR and its level in the mixture."""
    detail = NOISE_DETAILS.get(noise.kind)
    parts = [str(noise.kind)] + ([detail(noise)] if detail else [])
    if directions and noise.directions:
        parts.append("from (az, el) deg " + " ".join(f"({a:.1f}, {e:.1f})" for a, e in noise.directions))
    if noise.snr_db is not None:
        parts.append(f"SNR {noise.snr_db:.1f} dB")
    if noise.level_dbfs is not None:
        parts.append(f"level {noise.level_dbfs:.1f} dBFS")
    return parts


def noise_directions(rec) -> np.ndarray:
    """[K, 2] azimuth, elevation (degrees, array frame) of every noise that comes from
    somewhere (babble)."""
    dirs = [d for n in rec.noise for d in (n.directions or ())]
    return np.asarray(dirs, dtype=np.float64).reshape(-1, 2)


def pyplot():
    # matplotlib loads in a second; only the commands that draw pay for it
    import matplotlib  # seconds to import: loaded only when a picture is drawn

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _source_order(scene) -> list[int]:
    """Interferers first, the target last: what is drawn later lies on top."""
    return [*range(1, scene.n_sources), 0]


def _marker(s: int, small: bool) -> tuple[str, float]:
    if s == 0:
        return "*", 11 if small else 17
    return "o", 5 if small else 8


def draw_array_view(ax, scene, small: bool = False) -> None:
    """The array frame from above on polar axes ``ax``: the array at the centre, its
    front (0°) up and its left (+90°) to the left, every directional source at its
    azimuth and distance (a moving one as its trajectory from an ``x`` to its marker)."""
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(1)  # counter-clockwise, as azimuth counts
    far, seen = 1.0, []
    for s in _source_order(scene):
        az, dist = scene.azimuth[s].astype(np.float64), scene.distance[s].astype(np.float64)
        if not np.isfinite(dist).any():  # a direction without a distance (a recording's 5 columns): the 1 m ring
            dist = np.ones_like(dist)
        ok = np.isfinite(az) & np.isfinite(dist)
        if not ok.any():
            continue
        # unwrapped, a trajectory across ±180° goes the short way round, not through the front
        th, r = np.unwrap(np.radians(az[ok])), dist[ok]
        far = max(far, float(r.max()))
        seen.append(az[ok])
        col, z = source_colour(s), TARGET_Z if s == 0 else INTERFERER_Z
        lw, alpha = (1.2 if small else 1.6, 0.9) if s == 0 else (2.6 if small else 4.0, 0.45)
        ax.plot(th, r, "-", color=col, lw=lw, alpha=alpha, zorder=z)
        marker, size = _marker(s, small)
        ax.plot(th[-1], r[-1], marker, color=col, ms=size, mec="k" if s == 0 else col, mew=0.6, zorder=z + 0.5)
        if np.ptp(th) > 1e-3 or np.ptp(r) > 1e-3:
            ax.plot(th[0], r[0], "x", color=col, ms=5 if small else 7, zorder=z + 0.5)
    ax.plot([0.0], [0.0], "ks", ms=4 if small else 6, zorder=TARGET_Z + 1)
    ax.set_rlim(0.0, 1.15 * far)
    noise = np.zeros((0, 2)) if small else noise_directions(scene.record)  # the sheet's view: sources only
    if noise.size:
        # babble is far away (render/noise.py BABBLE_DISTANCE): on the rim, not out of the view
        ax.plot(np.radians(noise[:, 0]), np.full(len(noise), 1.15 * far), ls="", marker=NOISE_MARKER,
                color=NOISE_COLOUR, ms=6, clip_on=False, zorder=TARGET_Z + 1, gid="noise-directions")
        seen.append(noise[:, 0])
    ax.tick_params(labelsize=8)
    if small:
        # a thumbnail has no room for distance numbers: rings 1 m apart, said once beside it
        ax.set_yticks(np.arange(1.0, 1.15 * far, 1.0))
        ax.set_yticklabels([])
        ax.set_thetagrids((0, 90, 180, 270), ("front", "left", "back", "right"), fontsize=7)
        additive = sum(not np.isfinite(scene.azimuth[s]).any() for s in range(scene.n_sources))
        if additive:  # a source without a position is not drawn: say that it is there
            ax.text(0.0, 0.0, f"+{additive} additive", transform=ax.transAxes, fontsize=7, color="0.3")
        return
    ax.set_rlabel_position(_free_angle(np.concatenate(seen) if seen else np.zeros(0)))
    ax.set_thetagrids(range(0, 360, 45), ("0° front", "45°", "90° left", "135°", "±180° back", "−135°", "−90° right",
                                          "−45°"), fontsize=8)
    ax.set_title("array frame from above: azimuth, distance (m)", fontsize=10, pad=14)


def _free_angle(azimuths: np.ndarray) -> float:
    """Of the angles between the grid lines, the one farthest from every source: where
    the distance ticks are written, so no number sits under a marker."""
    candidates = np.arange(22.5, 360.0, 45.0)
    if not azimuths.size:
        return 202.5
    gap = np.abs((candidates[:, None] - azimuths[None, :] + 180.0) % 360.0 - 180.0).min(axis=1)
    return float(candidates[np.argmax(gap)])


def _draw_room(ax, scene, tracks, centre, yaw, dims) -> None:
    ax.add_patch(pyplot().Rectangle((0, 0), dims[0], dims[1], fill=False, lw=2, color="0.2"))
    ax.set_xlim(-0.3, dims[0] + 0.3)
    ax.set_ylim(-0.3, dims[1] + 0.3)
    ax.set_xlabel("room x (m)")
    ax.set_ylabel("room y (m)")
    mics = array_to_room(scene.mic_positions.astype(np.float64), centre, yaw)
    ax.plot(mics[:, 0], mics[:, 1], "k.", ms=4)
    arrow = 0.09 * max(dims[:2])
    ax.annotate("", xy=(centre[0] + arrow * np.cos(np.radians(yaw)), centre[1] + arrow * np.sin(np.radians(yaw))),
                xytext=(centre[0], centre[1]), arrowprops=dict(arrowstyle="-|>", color="k", lw=1.8))
    ax.plot([centre[0]], [centre[1]], "ks", ms=5)
    for s in _source_order(scene):
        tr = tracks[s]
        if tr is None:
            continue
        col, z = source_colour(s), TARGET_Z if s == 0 else INTERFERER_Z
        ax.plot(tr[:, 0], tr[:, 1], "-", color=col, lw=1.4 if s == 0 else 3.5, alpha=0.9 if s == 0 else 0.45, zorder=z)
        marker, size = _marker(s, False)
        ax.plot(tr[-1, 0], tr[-1, 1], marker, color=col, ms=size, mec="k" if s == 0 else col, mew=0.6,
                zorder=z + 0.5)
        if np.ptp(tr[:, :2], axis=0).max() > 1e-3:
            ax.plot(tr[0, 0], tr[0, 1], "x", color=col, ms=7, zorder=z + 0.5)  # start of a moving source
    ax.set_aspect("equal")
    ax.set_title("room from above", fontsize=10)


def _legend_handles(scene, room: bool):
    from matplotlib.lines import Line2D  # matplotlib loads only when a picture is drawn

    rec = scene.record
    handles = [Line2D([], [], ls="", marker="s", color="k", ms=6,
                      label=f"array ({scene.format}); " + ("arrow in the room, up in the array frame = its front" if room
                                                           else "its front up (where it stood is not known)"))]
    for s in range(scene.n_sources):
        info = rec.sources[s]
        marker, size = _marker(s, False)
        name = f"{s}: {info.role}" + (" (moving, from x)" if info.moving else "")
        if not np.isfinite(scene.azimuth[s]).any():
            handles.append(Line2D([], [], ls="", label=f"{name} (additive, no position)"))
            continue
        handles.append(Line2D([], [], color=source_colour(s), marker=marker, ms=size, mec="k" if s == 0 else None,
                              lw=TARGET_LW if s == 0 else INTERFERER_LW, alpha=1.0 if s == 0 else 0.5,
                              label=name + (f": {info.clip_id}" if info.clip_id else "")))
    n_dirs = len(noise_directions(rec))
    if n_dirs:
        handles.append(Line2D([], [], ls="", marker=NOISE_MARKER, color=NOISE_COLOUR, ms=6,
                              label=f"babble noise: its {n_dirs} directions (unlabelled)"))
    return handles


def _header_lines(scene) -> list[str]:
    rec = scene.record
    lines = query_lines(rec) or [f"query type: {scene.query_type} (a caption of the target)   pairing: {scene.pairing}"]
    where = room_text(rec)
    lines.append(f"{rec.scenario}, {rec.motion}, {rec.rir_method} RIRs" + (f"; room {where}" if where else ""))
    if rec.noise:
        lines.append("noise (unlabelled): " + "; ".join(", ".join(noise_parts(n, directions=False))
                                                        for n in rec.noise))
    return lines


def fit_lines(text: str, fits, indent: str = "") -> list[str]:
    """``text`` broken into lines that each ``fits`` (a test of the drawn width): between
    words, inside a word only where it alone is too wide; each line after the first of a
    paragraph starts with ``indent``; the spaces between words kept as they are."""
    lines: list[str] = []
    for para in text.split("\n"):
        line = ""
        for word in re.findall(r"\S+\s*", para):
            if line.strip() and not fits(line + word.rstrip()):
                lines.append(line.rstrip())
                line = indent
            if fits(line + word.rstrip()):
                line += word
                continue
            for ch in word:  # a word wider than a line: cut where it must be
                if line.strip() and not ch.isspace() and not fits(line + ch):
                    lines.append(line.rstrip())
                    line = indent
                line += ch
        lines.append(line.rstrip())
    return lines


def _text_fits(renderer, width_px: float, size: float, weight: str = "normal"):
    from matplotlib.font_manager import FontProperties  # matplotlib loads only when a picture is drawn

    prop = FontProperties(size=size, weight=weight)
    return lambda s: renderer.get_text_width_height_descent(s, prop, ismath=False)[0] <= width_px


def _draw_header(fig, scene, room: bool):
    """The query and its facts at the top left, the legend at the top right; the text is
    wrapped, as drawn, to the width the legend leaves it, so the two never overlap (below
    a legend too wide to leave it room). Returns the header's axes, to be placed, and its
    height in inches."""
    from matplotlib.transforms import ScaledTranslation  # matplotlib loads only when a picture is drawn

    ax = fig.add_axes((PLOT_LEFT, 0.0, PLOT_RIGHT - PLOT_LEFT, 1.0))
    ax.axis("off")
    legend = ax.legend(handles=_legend_handles(scene, room), loc="upper right", fontsize=LEGEND_SIZE, framealpha=0.9,
                       borderaxespad=0.0)
    renderer = fig.canvas.get_renderer()
    box, frame = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
    width = frame.width - box.width - LEGEND_GAP * fig.dpi
    below = width < MIN_TEXT_SHARE * frame.width
    drop = box.height / fig.dpi + LEGEND_GAP if below else 0.0
    width = frame.width if below else width
    query = fit_lines(f"{scene.scene_id}: \u201c{scene.query}\u201d", _text_fits(renderer, width, CAPTION_SIZE, "bold"))
    facts = _text_fits(renderer, width, FACTS_SIZE)
    head = ax.text(0.0, 1.0, "\n".join(query), fontsize=CAPTION_SIZE, weight="bold", va="top", parse_math=False,
                   transform=ax.transAxes + ScaledTranslation(0.0, -drop, fig.dpi_scale_trans), gid="query")
    text = ax.annotate("\n".join(x for line in _header_lines(scene) for x in fit_lines(line, facts, "    ")),
                       xy=(0.0, 0.0), xycoords=head, xytext=(0.0, -8.0), textcoords="offset points", va="top",
                       fontsize=FACTS_SIZE, parse_math=False, gid="query-facts")
    return ax, max(frame.y1 - text.get_window_extent(renderer).y0, box.height) / fig.dpi


def _draw_labels(ax, scene, labels, wrap: bool) -> None:
    hop = scene.label_hop
    for s in _source_order(scene):
        v = labels[s].astype(np.float64)
        if not np.isfinite(v).any():
            continue
        col, target = source_colour(s), s == 0
        lw, z, alpha = (TARGET_LW, TARGET_Z, 1.0) if target else (INTERFERER_LW, INTERFERER_Z, 0.45)
        active = np.asarray(scene.active[s], bool)
        # dotted over the silent frames only: an interferer's pale stroke would let a dotted
        # line under it show through where it is active
        ax.plot(*frame_segments(v, ~active, hop, wrap), ":", color=col, lw=1.2, zorder=z - 0.5, gid=f"silent-{s}")
        ax.plot(*frame_segments(v, active, hop, wrap), "-", color=col, lw=lw, alpha=alpha, zorder=z,
                solid_capstyle="butt", gid=f"labels-{s}")
    ax.grid(alpha=0.3)


def _draw_noise_beside(ax, azimuths: np.ndarray) -> None:
    """Babble's azimuths just right of the azimuth axis: directions without a time course,
    beside the sources' tracks, not on them."""
    ax.plot(np.full(len(azimuths), 1.012), azimuths, ls="", marker=NOISE_MARKER, color=NOISE_COLOUR, ms=6,
            clip_on=False, transform=ax.get_yaxis_transform(), gid="noise-directions")


def scene_figure(scene):
    """The picture of ``scene`` as a matplotlib Figure (:func:`plot_scene` saves it)."""
    if scene.audio is None:
        raise TselError(f"{scene.scene_id}: read with audio=False; cannot draw a spectrogram")
    plt = pyplot()
    rec = scene.record
    tracks, centre, yaw = source_tracks(scene)
    # measured-bank scenes may know their room's size but not where the array stood: array frame only
    dims = rec.room.dims if rec.array.centre is not None else None
    fig = plt.figure(figsize=(FIG_WIDTH, BODY_HEIGHT))
    ax_head, head = _draw_header(fig, scene, bool(dims))
    total = MARGIN_TOP + head + HEADER_GAP + BODY_HEIGHT + MARGIN_BOTTOM
    fig.set_size_inches(FIG_WIDTH, total)
    ax_head.set_position((PLOT_LEFT, 1.0 - (MARGIN_TOP + head) / total, PLOT_RIGHT - PLOT_LEFT, head / total))
    outer = fig.add_gridspec(1, 2, width_ratios=(1.0, 1.45), left=PLOT_LEFT, right=PLOT_RIGHT, wspace=0.22,
                             top=1.0 - (MARGIN_TOP + head + HEADER_GAP) / total, bottom=MARGIN_BOTTOM / total)
    if dims:
        left = outer[0, 0].subgridspec(2, 1, height_ratios=(float(np.clip(dims[1] / dims[0], 0.45, 1.4)), 1.1),
                                       hspace=0.42)
        _draw_room(fig.add_subplot(left[0]), scene, tracks, centre, yaw, dims)
        ax_polar = fig.add_subplot(left[1], projection="polar")
    else:
        ax_polar = fig.add_subplot(outer[0, 0], projection="polar")
    draw_array_view(ax_polar, scene)
    right = outer[0, 1].subgridspec(4, 1, height_ratios=(1.0, 0.75, 0.25 + 0.12 * scene.n_sources, 0.95),
                                    hspace=0.55)
    ax_az = fig.add_subplot(right[0])
    ax_el = fig.add_subplot(right[1], sharex=ax_az)
    ax_act = fig.add_subplot(right[2], sharex=ax_az)
    ax_spec = fig.add_subplot(right[3])

    # --- azimuth and elevation per frame ---------------------------------------------------
    _draw_labels(ax_az, scene, scene.azimuth, True)
    _draw_labels(ax_el, scene, scene.elevation, False)
    noise = noise_directions(rec)
    if noise.size:
        _draw_noise_beside(ax_az, noise[:, 0])
    ax_az.axhspan(180.0, AZIMUTH_LIMITS[1], color="0.92", zorder=0)
    ax_az.axhspan(AZIMUTH_LIMITS[0], -180.0, color="0.92", zorder=0)
    ax_az.set_ylim(*AZIMUTH_LIMITS)
    ax_az.set_yticks(range(-180, 181, 90))
    ax_az.set_ylabel("azimuth (deg)")
    ax_az.set_title("azimuth and elevation per label frame (solid = active, dotted = silent)", fontsize=10)
    el = scene.elevation[np.isfinite(scene.elevation)]
    lo, hi = (float(el.min()), float(el.max())) if el.size else (-10.0, 10.0)
    pad = max(5.0, 0.15 * (hi - lo))
    ax_el.set_ylim(max(-92.0, lo - pad), min(92.0, hi + pad))
    ax_el.set_ylabel("elevation (deg)")

    # --- activity: every active frame, one row per source ----------------------------------
    hop = scene.label_hop
    for s in range(scene.n_sources):
        runs = [(k * hop, n * hop) for k, n in frame_runs(scene.active[s])]
        ax_act.broken_barh(runs, (s - 0.35, 0.7), facecolors=source_colour(s))
    ax_act.set_yticks(range(scene.n_sources))
    ax_act.set_yticklabels([f"{s}: {rec.sources[s].role} {100 * scene.active[s].mean():.0f}%"
                            for s in range(scene.n_sources)], fontsize=8)
    ax_act.set_ylim(scene.n_sources - 0.5, -0.5)
    ax_act.set_xlim(0, scene.n_frames * hop)
    ax_act.set_title("active frames", fontsize=10)
    ax_act.grid(axis="x", alpha=0.3)

    # --- spectrogram of channel 0 ----------------------------------------------------------
    db = 20 * np.log10(np.abs(stft(scene.audio[:1], 1024, 256))[0].T + 1e-9)
    vmax = db.max()
    ax_spec.imshow(db, origin="lower", aspect="auto", cmap="magma", vmin=vmax - 80, vmax=vmax,
                   extent=(0, scene.audio.shape[1] / scene.fs, 0, scene.fs / 2000))
    ax_spec.set_xlabel("time (s)")
    ax_spec.set_ylabel("kHz")
    ax_spec.set_title("spectrogram of channel 0", fontsize=10)
    return fig


def thumbnail_figure(scene, size: float = 2.6):
    """The contact sheet's small picture of ``scene``: its array-centred view alone."""
    fig = pyplot().figure(figsize=(size, size))
    draw_array_view(fig.add_subplot(projection="polar"), scene, small=True)
    return fig


def save_figure(fig, path: str, dpi: int = 110) -> str:
    """Write ``fig`` as a PNG (atomically, cropped to what is drawn) and close it."""
    try:
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format="png", metadata={"Software": None})
    finally:
        pyplot().close(fig)
    return path


def plot_scene(scene, path: str, dpi: int = 110) -> str:
    """Draw the scene to a PNG file (:func:`scene_figure`)."""
    return save_figure(scene_figure(scene), path, dpi)
