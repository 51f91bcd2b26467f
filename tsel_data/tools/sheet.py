"""A contact sheet: many scenes of a dataset at a glance (``tsel inspect DIR --sheet F``).

``F.html``: per scene a small picture (its array-centred view, :mod:`tsel_data.tools.picture`),
the query, every source's captions and labels in words (azimuth, distance, elevation,
how much of the scene it sounds), and an audio player of the mixture's headphone
preview (:mod:`tsel_data.receivers.stereo`). The pictures and previews go into the folder
``F_files/`` beside it, named in the page by relative links only, so the page and its
folder can be moved or shared together and name no folder of this machine.
``F.png``: the pictures alone, on one image, each with its scene id and query.

Which scenes: ``count`` of them, spread evenly over the chosen splits in their order
(always the same ones for the same dataset: no random choice).
"""
from __future__ import annotations

import html
import os
import textwrap

import numpy as np

from ..core.atomic import atomic_output
from ..corpus.audio import save_wav
from ..errors import DatasetError
from ..receivers.stereo import stereo_preview
from ..store.reader import Scene, list_splits, open_dataset
from .picture import SOURCE_COLOURS, pyplot, draw_array_view, save_figure, thumbnail_figure

DEFAULT_SCENES = 24
SHEET_COLUMNS = 6  # pictures per row of a PNG sheet


def is_picture_sheet(path: str) -> bool:
    """A sheet named ``*.png`` is the pictures alone; any other name is a page."""
    return path.lower().endswith(".png")


def files_dir(path: str) -> str:
    """The folder of a page's pictures and previews: ``F_files`` beside ``F.html``."""
    return f"{os.path.splitext(path)[0]}_files"


def pick(sizes: dict[str, int], count: int) -> list[tuple[str, int]]:
    """(split, position) of ``count`` scenes spread evenly over splits of ``sizes``
    (in order), first and last included; all of them when there are fewer."""
    every = [(sp, i) for sp, n in sizes.items() for i in range(n)]
    if len(every) <= count:
        return every
    return [every[k] for k in np.unique(np.round(np.linspace(0, len(every) - 1, count)).astype(int))]


def chosen_scenes(root: str, count: int = DEFAULT_SCENES, split: str | None = None,
                  receiver: str | None = None) -> list[tuple[str, int]]:
    """Which scenes a sheet of ``root`` shows: (split, position in the split)."""
    splits = [split] if split else list_splits(root, unfinished=True)
    sizes = {}
    for sp in splits:
        with open_dataset(root, sp, unfinished=True, receiver=receiver, load_records=False) as ds:
            sizes[sp] = len(ds)
    chosen = pick(sizes, count)
    if not chosen:
        raise DatasetError(f"{root} has no rendered scenes in {'split ' + repr(split) if split else 'any split'}; "
                           f"nothing to put on a sheet")
    return chosen


def sheet_outputs(path: str, scene_ids: list[str]) -> list[str]:
    """Every file :func:`write_sheet` writes for these scenes, to be claimed before any is
    written (store/outputs.py)."""
    if is_picture_sheet(path):
        return [path]
    folder = files_dir(path)
    return [path] + [os.path.join(folder, f"{sid}{ext}") for sid in scene_ids for ext in (".png", ".wav")]


def scene_ids(root: str, chosen: list[tuple[str, int]], receiver: str | None = None) -> list[str]:
    ids = []
    for sp in dict.fromkeys(sp for sp, _ in chosen):
        with open_dataset(root, sp, unfinished=True, receiver=receiver, load_records=False) as ds:
            names = ds.scene_ids()
            ids += [names[i] for s, i in chosen if s == sp]
    return ids


def _scenes(root: str, chosen, receiver):
    """The chosen scenes one at a time (their audio read when needed, not all at once)."""
    for sp in dict.fromkeys(sp for sp, _ in chosen):
        with open_dataset(root, sp, unfinished=True, receiver=receiver) as ds:
            for s, i in chosen:
                if s == sp:
                    yield ds.finite(ds[i])


# --- labels in words ------------------------------------------------------------------------------------------------

_SIDES = ("front", "front-left", "left", "back-left", "back", "back-right", "right", "front-right")


def side(azimuth: float) -> str:
    """Where an azimuth (degrees, counter-clockwise from the front) is, in words."""
    return _SIDES[int(np.floor((azimuth + 22.5) % 360.0 / 45.0)) % 8]


def position_words(scene: Scene, s: int) -> str:
    """Source ``s``'s labels in words: azimuth (and side), distance, elevation; a moving
    source from its first to its last frame."""
    az, el, dist = (np.asarray(v[s], dtype=np.float64) for v in (scene.azimuth, scene.elevation, scene.distance))
    ok = np.isfinite(az)
    if not ok.any():
        return "no position (additive, everywhere)"
    a0, a1 = az[ok][0], az[ok][-1]
    where = f"azimuth {a0:.0f}° ({side(a0)})"
    if abs((a1 - a0 + 180.0) % 360.0 - 180.0) > 0.5:
        where = f"azimuth {a0:.0f}° ({side(a0)}) moving to {a1:.0f}° ({side(a1)})"
    return f"{where}, {np.nanmean(dist):.1f} m away, elevation {np.nanmean(el):.0f}°"


def scene_block(scene: Scene, picture: str, audio: str) -> str:
    """One scene's card of the page; ``picture`` and ``audio`` are links relative to it."""
    rec = scene.record
    e = html.escape
    rows = []
    for s in range(scene.n_sources):
        info = rec.sources[s]
        caps = "".join(f"<li>{e(c)}</li>" for c in info.captions)
        rows.append(f'<li><span class="role" style="color:{SOURCE_COLOURS[s % len(SOURCE_COLOURS)]}">'
                    f"{s}: {e(info.role)}</span> {e(position_words(scene, s))}; "
                    f"sounds in {100 * scene.active[s].mean():.0f}% of frames"
                    f'<ul class="caps">{caps}</ul></li>')
    kind = scene.query_type + (f", {scene.query_relation}" if scene.query_relation else "")
    return (f'<figure id="{e(scene.scene_id)}"><img src="{e(picture)}" alt="array-frame view of {e(scene.scene_id)}">'
            f'<figcaption><div class="id">{e(scene.scene_id)} <span class="kind">{e(kind)}; '
            f"{e(rec.scenario)}, {e(rec.motion)}</span></div>"
            f'<q>{e(scene.query)}</q><ul class="sources">{"".join(rows)}</ul>'
            f'<audio controls preload="none" src="{e(audio)}"></audio></figcaption></figure>')


_STYLE = """body{font:14px/1.35 system-ui,sans-serif;margin:1.2em;color:#222}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(320px,1fr));gap:14px}
figure{margin:0;border:1px solid #ccc;border-radius:6px;padding:8px}
img{width:100%;max-width:260px;display:block;margin:auto}
.id{font-weight:600}.kind{font-weight:400;color:#666;font-size:12px}
q{display:block;font-size:15px;margin:4px 0;font-style:italic}
ul{margin:2px 0;padding-left:18px}.caps{color:#555;font-size:12px}.role{font-weight:600}
audio{width:100%;margin-top:6px}"""


def write_sheet(root: str, path: str, chosen: list[tuple[str, int]], receiver: str | None = None) -> int:
    """Write the sheet of ``chosen`` scenes (:func:`chosen_scenes`) to ``path``: a page
    with its ``F_files/`` folder, or, for ``*.png``, the pictures alone. The files are
    written as asked: the command claims them first (:func:`sheet_outputs`). Returns the
    number of scenes on it."""
    if is_picture_sheet(path):
        return _write_picture_sheet(root, path, chosen, receiver)
    folder = files_dir(path)
    link = os.path.basename(folder)
    os.makedirs(folder, exist_ok=True)
    blocks = []
    for scene in _scenes(root, chosen, receiver):
        save_figure(thumbnail_figure(scene), os.path.join(folder, f"{scene.scene_id}.png"), dpi=90)
        preview = stereo_preview(scene.audio, scene.format, scene.mic_positions)
        # 16-bit: a page of 24 ten-second previews stays small, and every browser plays it
        save_wav(os.path.join(folder, f"{scene.scene_id}.wav"), np.clip(preview, -1.0, 1.0).T, scene.fs,
                 subtype="PCM_16")
        blocks.append(scene_block(scene, f"{link}/{scene.scene_id}.png", f"{link}/{scene.scene_id}.wav"))
    name = html.escape(os.path.basename(os.path.normpath(root)))
    splits = ", ".join(dict.fromkeys(sp for sp, _ in chosen))
    page = (f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8">'
            f"<title>{name}: {len(blocks)} scenes</title><style>{_STYLE}</style></head><body>\n"
            f"<h1>{name}: {len(blocks)} scenes of {html.escape(splits)}</h1>\n"
            f"<p>Each picture is the array frame seen from above: the array at the centre, its front up and its "
            f"left to the left; the target is the red star, interferers are dots, a moving source runs from an x "
            f"to its marker; the rings are 1 m apart. The players play a headphone preview of the mixture.</p>\n"
            f'<div class="grid">\n' + "\n".join(blocks) + "\n</div></body></html>\n")
    with atomic_output(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(page)
    return len(blocks)


def _write_picture_sheet(root: str, path: str, chosen, receiver) -> int:
    plt = pyplot()
    cols = min(SHEET_COLUMNS, len(chosen))
    rows = -(-len(chosen) // cols)
    height = 2.9 * rows + 0.5
    fig = plt.figure(figsize=(2.7 * cols, height))
    for k, scene in enumerate(_scenes(root, chosen, receiver)):
        ax = fig.add_subplot(rows, cols, k + 1, projection="polar")
        draw_array_view(ax, scene, small=True)
        ax.set_title(textwrap.fill(f"{scene.scene_id}: {scene.query}", 34), fontsize=7.5, pad=12)
    fig.suptitle(f"{os.path.basename(os.path.normpath(root))}: the array frame from above (front up, left to the "
                 f"left, rings 1 m apart); red star = target, dots = interferers, x = start of a moving source",
                 fontsize=9, y=1.0 - 0.1 / height, va="top")
    fig.subplots_adjust(hspace=0.5, wspace=0.45, top=1.0 - 1.05 / height)
    save_figure(fig, path, dpi=90)
    return len(chosen)
