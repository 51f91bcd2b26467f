"""Pictures that read at a glance (issue 26 §7): the layout of tsel inspect's figure, and
the contact sheet (tsel inspect DIR --sheet)."""
import dataclasses
import os
import re

import numpy as np
import pytest

from support.datasets import make_dataset
from tsel_data.tools.inspect import find_scene
from tsel_data.tools.picture import AZIMUTH_LIMITS, scene_figure

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    root = tmp_path_factory.mktemp("pictures") / "ds"
    root.mkdir()
    written = make_dataset(root, splits={"train": 5, "test": 3}, moving={"train-000001"}, additive={"train-000002"},
                           target_az={"test-000000": 177.0})
    return root, written


@pytest.fixture
def figure():
    made = []

    def draw(scene):
        fig = scene_figure(scene)
        made.append(fig)
        fig.canvas.draw()  # lay out, so extents are where the PNG has them
        return fig

    yield draw
    import matplotlib.pyplot as plt

    for fig in made:
        plt.close(fig)


def _axes(fig, title):
    return next(ax for ax in fig.axes if ax.get_title().startswith(title))


def _texts(fig):
    return [t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text"))]


def test_legend_lies_outside_the_room_and_the_query_is_in_the_picture(ds, figure):
    root, _ = ds
    scene = find_scene(root, "test/0")
    fig = figure(scene)
    room = _axes(fig, "room from above")
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    assert len(legends) == 1, "one legend for every panel"
    box, walls = legends[0].get_window_extent(), room.get_window_extent()
    assert not box.overlaps(walls)
    assert any(scene.query in t for t in _texts(fig))
    assert any("query type: caption" in t and "RT60 0.60 s" in t for t in _texts(fig))


def test_a_target_near_180_degrees_is_inside_the_azimuth_axis(ds, figure):
    root, _ = ds
    scene = find_scene(root, "test/0")
    assert scene.azimuth[0, 0] == pytest.approx(177.0)
    ax = _axes(figure(scene), "azimuth and elevation")
    lo, hi = ax.get_ylim()
    assert (lo, hi) == AZIMUTH_LIMITS and lo < -180.0 - 5 and hi > 177.0 + 5
    assert [int(t) for t in ax.get_yticks()] == [-180, -90, 0, 90, 180]


def test_the_target_is_drawn_on_top_of_the_interferers(ds, figure):
    root, _ = ds
    fig = figure(find_scene(root, "train/0"))
    for title in ("azimuth and elevation", "elevation"):
        ax = next(a for a in fig.axes if a.get_ylabel().startswith(title.split()[0]))
        lines = {ln.get_gid(): ln for ln in ax.get_lines() if ln.get_gid()}
        target, other = lines["labels-0"], lines["labels-1"]
        assert target.get_zorder() > other.get_zorder()
        # narrower than the interferer's stroke, so where both share a value both show
        assert target.get_linewidth() < other.get_linewidth()


def test_every_scene_has_an_array_centred_view(ds, figure):
    """A bank that does not say where the array stood: no room, the array frame around
    the array (the array at the centre, every source inside the view)."""
    root, _ = ds
    scene = find_scene(root, "train/2")  # with an additive source: no position, listed only
    rec = scene.record
    object.__setattr__(rec, "array", dataclasses.replace(rec.array, centre=None))
    fig = figure(scene)
    assert not any(ax.get_title() == "room from above" for ax in fig.axes)
    polar = next(ax for ax in fig.axes if ax.name == "polar")
    assert polar.get_ylim()[0] == 0.0 and polar.get_ylim()[1] > np.nanmax(scene.distance)
    assert any("2: interferer (additive, no position)" in t for t in _texts(fig))
    from tsel_data.tools.picture import thumbnail_figure

    thumb = thumbnail_figure(scene)
    assert "+1 additive" in _texts(thumb)  # the sheet's picture says what it cannot draw
    import matplotlib.pyplot as plt

    plt.close(thumb)


def test_query_relation_and_evidence_are_in_the_picture(ds, figure):
    root, _ = ds
    scene = find_scene(root, "train/3")
    rec = scene.record
    for name, value in (("query_type", "relational"), ("query_wanted", "relational"), ("pairing", "hard"),
                        ("query_evidence", {"relation": "louder", "value": 6.5, "unit": "dB", "margin": 3.0,
                                            "against": [1]})):
        object.__setattr__(rec, name, value)
    texts = _texts(figure(scene))
    assert any("query type: relational   relation: louder, by 6.5 dB (margin 3 dB) against source(s) 1" in t
               and "pairing: hard" in t for t in texts)


# An AudioCaps caption as long as they come (the longest run to about 200 characters).
LONG_CAPTION = ("A man speaks over a public address system while a crowd of people cheer and applaud in the distance, "
                "then a vehicle engine revs loudly and tires squeal on the wet pavement as rain keeps falling")
BABBLE = {"kind": "babble", "snr_db": 15.25, "level_dbfs": -41.0, "clips": [["audio/a.wav", 0.0], ["audio/b.wav", 1.5]],
          "directions": [[-87.639, 34.529], [24.115, -57.269]]}


def _with(scene, noise=(), clip_id=None, query=None):
    from tsel_data.store.records import NoiseRecord

    rec = scene.record
    sources = rec.sources if clip_id is None else (rec.sources[0], dataclasses.replace(rec.sources[1], clip_id=clip_id),
                                                   *rec.sources[2:])
    scene.record = dataclasses.replace(rec, noise=tuple(NoiseRecord.from_json(n) for n in noise), sources=sources)
    scene.query = query or scene.query
    return scene


def _by_gid(fig, gid):
    return fig.findobj(lambda a: hasattr(a, "get_gid") and a.get_gid() == gid)


@pytest.mark.parametrize("case", ["caption", "noise", "wide legend"])
def test_the_legend_never_covers_the_query(ds, figure, case):
    """A long caption is wrapped beside the legend (or, beside a legend too wide to leave
    it room, below it): caption, facts and legend never overlap, nor reach a panel."""
    root, _ = ds
    scene = _with(find_scene(root, "train/2"), noise=[BABBLE] if case == "noise" else (), query=LONG_CAPTION,
                  clip_id="a-clip-named-after-its-whole-path-" * 4 if case == "wide legend" else None)
    fig = figure(scene)
    renderer = fig.canvas.get_renderer()
    (query,), (facts,) = _by_gid(fig, "query"), _by_gid(fig, "query-facts")
    legend = next(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)
    boxes = {"query": query.get_window_extent(renderer), "facts": facts.get_window_extent(renderer),
             "legend": legend.get_window_extent(renderer)}
    for a in boxes:
        for b in boxes:
            assert a == b or not boxes[a].overlaps(boxes[b]), (a, b)
    head = legend.axes
    for ax in fig.axes:
        if ax is not head:
            assert not any(box.overlaps(ax.get_tightbbox(renderer)) for box in boxes.values()), ax.get_title()
    if case == "wide legend":
        assert boxes["query"].y1 <= boxes["legend"].y0  # the text went below it
    # wrapped, nothing lost
    assert "\n" in query.get_text()
    assert " ".join(query.get_text().split()) == f"{scene.scene_id}: \u201c{LONG_CAPTION}\u201d"


def test_babble_noise_is_in_the_picture(ds, figure):
    root, _ = ds
    fig = figure(_with(find_scene(root, "train/0"), noise=[BABBLE, {"kind": "sensor", "snr_db": None,
                                                                    "level_dbfs": -60.0}]))
    (facts,) = _by_gid(fig, "query-facts")
    said = " ".join(facts.get_text().split())
    assert ("noise (unlabelled): babble, 2 clips, SNR 15.2 dB, level -41.0 dBFS; sensor, on every channel, "
            "level -60.0 dBFS") in said
    assert any("babble noise: its 2 directions" in t for t in _texts(fig))
    polar = next(ax for ax in fig.axes if ax.name == "polar")
    azimuth = _axes(fig, "azimuth and elevation")
    (rim,) = [ln for ln in polar.get_lines() if ln.get_gid() == "noise-directions"]
    np.testing.assert_allclose(np.degrees(rim.get_xdata()), [-87.639, 24.115])
    assert np.all(rim.get_ydata() == polar.get_ylim()[1])  # far away: on the rim
    (beside,) = [ln for ln in azimuth.get_lines() if ln.get_gid() == "noise-directions"]
    np.testing.assert_allclose(beside.get_ydata(), [-87.639, 24.115])


def _frames_of(x, mask, hop):
    """Whether every drawn x lies within a frame of ``mask`` (its edges included)."""
    k = np.arange(len(mask))[mask]
    x = x[np.isfinite(x)]
    return bool(np.all(np.any((x[:, None] >= k * hop - 1e-9) & (x[:, None] <= (k + 1) * hop + 1e-9), axis=1)))


def test_label_lines_follow_each_source_s_activity(ds, figure):
    """Solid where a source is active, dotted where it is silent, nothing dotted under an
    active stroke: an interferer active the whole scene is one solid stroke."""
    root, _ = ds
    scene = find_scene(root, "train/0")
    scene.active[1] = True
    hop, n = scene.label_hop, scene.n_frames
    fig = figure(scene)
    for ax in (_axes(fig, "azimuth and elevation"), next(a for a in fig.axes if a.get_ylabel().startswith("elev"))):
        lines = {ln.get_gid(): ln for ln in ax.get_lines() if ln.get_gid()}
        always = lines["labels-1"]
        assert always.get_linestyle() == "-" and not np.isnan(always.get_xdata()).any()
        assert always.get_xdata()[0] == 0.0 and always.get_xdata()[-1] == pytest.approx(n * hop)
        assert not np.isfinite(lines["silent-1"].get_xdata()).any()
        active = scene.active[0]
        assert 0 < active.sum() < n
        assert lines["labels-0"].get_linestyle() == "-" and lines["silent-0"].get_linestyle() == ":"
        assert _frames_of(lines["labels-0"].get_xdata(), active, hop)
        assert _frames_of(lines["silent-0"].get_xdata(), ~active, hop)


# --- the contact sheet ----------------------------------------------------------------------------------------------


def test_sheet_shows_each_scene_with_its_query_captions_and_player(ds, tsel_cli, tmp_path):
    root, written = ds
    out = tmp_path / "views"
    printed = tsel_cli.ok("inspect", root, "--sheet", out / "sheet.html", "--scenes", 4)
    assert printed.strip() == f"sheet: {out}/sheet.html (4 scenes of train, test; pictures and previews in " \
                              f"{out}/sheet_files/)"
    page = (out / "sheet.html").read_text(encoding="utf-8")
    ids = re.findall(r'<figure id="([^"]+)"', page)
    assert ids == ["train-000000", "train-000002", "test-000000", "test-000002"]  # spread evenly, ends included
    every = {w.record.scene_id: w for sp in written.values() for w in sp}
    for sid in ids:
        assert f'src="sheet_files/{sid}.png"' in page and f'<audio controls preload="none" ' \
                                                           f'src="sheet_files/{sid}.wav"></audio>' in page
        assert f"<q>{every[sid].query}</q>" in page
        assert all(f"<li>{c}</li>" in page for s in every[sid].record.sources for c in s.captions)
        assert (out / "sheet_files" / f"{sid}.png").read_bytes()[:8] == PNG_MAGIC
        import soundfile as sf

        audio, fs = sf.read(out / "sheet_files" / f"{sid}.wav")
        assert audio.shape == (every[sid].audio.shape[1], 2) and fs == 16000
    assert "no position (additive, everywhere)" in page  # train-000002's third source
    # labels in words: the scene's own numbers
    w = every["train-000000"]
    az = float(w.azimuth[0, 0])
    assert f"azimuth {az:.0f}°" in page and "1.8 m away, elevation 10°" in page
    # nothing names a folder of this machine: links are relative
    assert str(tmp_path) not in page and str(root) not in page
    assert not re.search(r'(src|href)="(/|[a-zA-Z]:|file:)', page)


def test_sheet_rerun_replaces_its_own_files_and_refuses_others(ds, tsel_cli, tmp_path):
    root, _ = ds
    page = tmp_path / "sheet.html"
    tsel_cli.ok("inspect", root, "--sheet", page, "--split", "test")
    tsel_cli.ok("inspect", root, "--sheet", page, "--split", "test")  # its own earlier outputs
    (tmp_path / "mine.html").write_text("my notes")
    line = tsel_cli.refused("inspect", root, "--sheet", tmp_path / "mine.html")
    assert "mine.html already exists and was not written by tsel inspect" in line and "--force" in line
    assert (tmp_path / "mine.html").read_text() == "my notes"
    # a file of the user's where a preview goes: refused before anything is written
    (tmp_path / "other_files").mkdir()
    (tmp_path / "other_files" / "test-000000.wav").write_bytes(b"keep")
    line = tsel_cli.refused("inspect", root, "--sheet", tmp_path / "other.html", "--split", "test")
    assert "other_files/test-000000.wav already exists" in line
    assert not (tmp_path / "other.html").exists()
    line = tsel_cli.refused("inspect", root, "--sheet", root / "sheet.html")
    assert "is inside the dataset" in line


def test_picture_sheet_and_usage(ds, tsel_cli, tmp_path):
    root, _ = ds
    assert "sheet: " in tsel_cli.ok("inspect", root, "--sheet", tmp_path / "s.png", "--scenes", 3)
    assert (tmp_path / "s.png").read_bytes()[:8] == PNG_MAGIC and not (tmp_path / "s_files").exists()
    assert "without SCENE" in tsel_cli.refused("inspect", root, "test/0", "--sheet", tmp_path / "x.html")
    assert "missing SCENE" in tsel_cli.refused("inspect", root)
    assert "no split 'nope'" in tsel_cli.refused("inspect", root, "--sheet", tmp_path / "y.html", "--split", "nope")


def test_sheet_choice_and_words():
    from tsel_data.tools.sheet import pick, side

    assert pick({"a": 2, "b": 1}, 24) == [("a", 0), ("a", 1), ("b", 0)]
    assert pick({"a": 10, "b": 10}, 4) == [("a", 0), ("a", 6), ("b", 3), ("b", 9)]
    assert [side(a) for a in (0, 30, 90, 177, -180, -100, -30)] == \
        ["front", "front-left", "left", "back", "back", "right", "front-right"]


def test_inspect_png_is_written_through_the_command(ds, tsel_cli, tmp_path):
    root, _ = ds
    out = tsel_cli.ok("inspect", root, "train/1", "--png", tmp_path / "m.png")
    assert "picture: " in out and os.path.getsize(tmp_path / "m.png") > 10_000
