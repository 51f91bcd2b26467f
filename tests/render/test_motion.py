"""Moving sources (simulated arcs and RIR-bank walks) and room-based splits, end to end."""
import json
import os

import numpy as np
import pytest

from support.cli import tsel
from support.datasets import plan_recipes
from tsel_data.banks.scenes import resolve_bank
from tsel_data.plan.catalog import build_catalog
from tsel_data.core.geometry import azimuth_difference, sph_to_cart
from tsel_data.job.pipeline import plan_dataset
from tsel_data.plan.sampler import CatalogView, bank_request, plan_roots
from tsel_data.store.layout import Layout
from tsel_data.scene.recipe import SceneRecipe
from tsel_data.render.mix import render_scene, source_labels


def test_simulated_arcs_follow_their_speed(small_config, tmp_path):
    cfg = small_config('scene.motion="moving"', 'scene.scenario="two-directional"', "scene.speed=30.0",
                       "scene.separated_frames=0.5", 'room.length=["uniform", 12.0, 15.0]',
                       'room.width=["uniform", 12.0, 15.0]', splits={"train": 4})
    cat = build_catalog(cfg, cfg.corpus.dir)
    for r in plan_recipes(cfg, "train", CatalogView(cat.clips["train"])):
        for k, s in enumerate(r.sources):
            assert s.moving and s.path and s.position is None
            knots = np.asarray(s.path)
            assert knots[0, 0] <= 0 and knots[-1, 0] >= r.duration  # covers the whole scene
            assert np.all(np.diff(knots[:, 0]) <= 0.1 + 1e-9)        # an RIR at least every 100 ms
            az, el, dist = source_labels(r, k)
            u = sph_to_cart(az, el, 1.0)
            arc = np.degrees(np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1, 1)))
            # 30 deg/s at 0.1 s frames: 3 degrees of arc per frame as seen from the array ...
            np.testing.assert_allclose(arc, 3.0, atol=0.01)
            # ... so the azimuth turns faster by 1 / cos(elevation), always the same way
            step = np.degrees(np.diff(np.unwrap(np.radians(az))))
            np.testing.assert_allclose(np.abs(step), 3.0 / np.cos(np.radians(el[0])), atol=0.01)
            assert np.all(np.sign(step) == np.sign(step[0]))
            assert np.ptp(dist) < 2e-3 and np.ptp(el) < 0.1          # an arc around the array
        assert SceneRecipe.from_json(r.to_json()) == r


def test_simulated_lines_pass_the_array_at_their_speed(small_config, tmp_path):
    cfg = small_config('scene.motion="moving"', 'scene.path="line"', 'scene.scenario="two-directional"',
                       "scene.speed=20.0", "scene.separated_frames=0.5", 'room.length=["uniform", 12.0, 15.0]',
                       'room.width=["uniform", 12.0, 15.0]', splits={"train": 4})
    cat = build_catalog(cfg, cfg.corpus.dir)
    for r in plan_recipes(cfg, "train", CatalogView(cat.clips["train"])):
        for k, s in enumerate(r.sources):
            knots = np.asarray(s.path)
            assert knots[0, 0] <= 0 and knots[-1, 0] >= r.duration and np.all(np.diff(knots[:, 0]) <= 0.1 + 1e-9)
            p = knots[:, 1:3] - np.asarray(r.array.centre[:2])
            step = np.diff(p, axis=0)
            assert np.ptp(knots[:, 3]) == 0                                          # constant height
            cross = step[:, 0] * step[0, 1] - step[:, 1] * step[0, 0]
            assert np.allclose(cross, 0, atol=1e-5)                                   # a straight line
            v = np.linalg.norm(step, axis=1) / np.diff(knots[:, 0])
            assert np.ptp(v) < 1e-3                                                   # at constant speed
            r_close = abs(p[0, 0] * step[0, 1] - p[0, 1] * step[0, 0]) / np.linalg.norm(step[0])  # closest approach
            d_close = np.hypot(r_close, knots[0, 3] - r.array.centre[2])
            assert v[0] == pytest.approx(np.radians(20.0) * d_close, rel=1e-4)        # sweeping 20 deg/s there
            az, el, dist = source_labels(r, k)
            u = sph_to_cart(az, el, 1.0)
            rate = np.degrees(np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1, 1))) / 0.1
            assert rate.max() <= 20.0 + 1e-2 and rate.max() > 15.0                    # fastest when closest
            assert np.all(np.sign(np.diff(np.unwrap(np.radians(az)))) == np.sign(np.diff(np.unwrap(np.radians(az))))[0])
            assert dist.min() >= 1.0 - 1e-3 and dist.max() > dist.min() + 0.1         # passes by, not around


def test_line_passes_longer_than_the_room_walk_wall_to_wall_at_their_speed(small_config):
    """40 °/s at 2-3 m is 14-21 m in 10 s, longer than the paper's 5-15 m rooms: every
    scene still plans; each pass keeps its speed while it walks, stays inside the wall
    margins, passes its closest point, and stands at a wall margin when it runs out of room."""
    cfg = small_config('scene.motion="moving"', 'scene.path="line"', "scene.speed=40.0", "audio.duration=10.0",
                       'sources.distance=["uniform", 2.0, 3.0]', splits={"train": 12})
    m = cfg.sources.wall_margin
    stood = 0
    for r in plan_recipes(cfg, "train", CatalogView(build_catalog(cfg, cfg.corpus.dir).clips["train"])):
        dims = np.asarray(r.room.dims)
        c = np.asarray(r.array.centre)
        for s in r.sources:
            if not s.moving:
                continue
            k = np.asarray(s.path)
            xy = k[:, 1:3]
            assert np.all(xy >= m - 1e-6) and np.all(xy <= dims[:2] - m + 1e-6)
            v = np.linalg.norm(np.diff(xy, axis=0), axis=1) / np.diff(k[:, 0])
            walking = v > 1e-6
            d_close = np.min(np.linalg.norm(k[:, 1:] - c, axis=1))
            full = walking & np.r_[True, walking[:-1]] & np.r_[walking[1:], True]  # not the step it stops in
            np.testing.assert_allclose(v[full], np.radians(40.0) * d_close, rtol=2e-3)
            assert np.all(v <= np.radians(40.0) * d_close * (1 + 2e-3))
            if not walking.all():  # it stopped: at a wall margin, after walking the whole chord
                stood += 1
                ends = xy[[0, -1]]
                at_wall = np.isclose(ends, m, atol=1e-5) | np.isclose(ends, dims[:2] - m, atol=1e-5)
                assert at_wall.any(axis=1)[~walking[[0, -1]]].all()
    assert stood > 0  # the setting is one where passes must stop


@pytest.mark.parametrize("kind", ["arc", "line"])
def test_moving_source_audio_comes_from_its_labels(kind, small_config, tmp_path):
    """A noise source on an arc or a line, rendered in a near-anechoic room: in every label
    frame the lags between mics lie between those of the labelled directions at the
    frame's start and end (the frame's audio is a crossfade of the RIRs of the knots
    there, 4 degrees apart at 40 deg/s: a label one frame late is 4 degrees off, and fails)."""
    from tsel_data.acoustics import SOUND_SPEED
    from tsel_data.core.geometry import sph_to_cart
    from tsel_data.receivers import mic_positions
    from tsel_data.render.mix import spatial_images
    from support.signals import lag as _lag

    cfg = small_config('scene.motion="moving"', f'scene.path="{kind}"', 'scene.scenario="two-directional"',
                       "scene.speed=40.0", "scene.separated_frames=0.5", "room.rt60=0.1", "array.side=0.4",
                       'room.length=["uniform", 14.0, 15.0]', 'room.width=["uniform", 14.0, 15.0]', splits={"train": 1})
    cat = build_catalog(cfg, cfg.corpus.dir)
    r = plan_recipes(cfg, "train", CatalogView(cat.clips["train"]))[0]
    noise = np.random.default_rng(0).standard_normal((len(r.sources), r.n_samples)).astype(np.float32)
    y = spatial_images(r, noise)[0][0]
    az, el, dist = source_labels(r, 0)
    centres, azu = (np.arange(len(az)) + 0.5) * r.label_hop, np.unwrap(az, period=360)
    mics, pairs = mic_positions("mic4", r.array.side), ((0, 2), (1, 3), (0, 1))

    def lags_at(t):
        """Lags for a source at the labelled (azimuth, elevation, distance): a spherical
        wave, since 2 m from a 0.4 m array a plane wave is off by up to 2 samples."""
        p = sph_to_cart(np.interp(t, centres, azu), np.interp(t, centres, el), np.interp(t, centres, dist))
        tau = np.linalg.norm(mics - p, axis=1) / SOUND_SPEED * r.fs
        return np.array([tau[j] - tau[i] for i, j in pairs])

    hop = int(r.label_hop * r.fs)
    for f in range(1, len(az) - 1):
        a, b = lags_at(f * r.label_hop), lags_at((f + 1) * r.label_hop)
        seg = y[:, f * hop : (f + 1) * hop]
        got = np.array([_lag(seg[i], seg[j], 40) for i, j in pairs])
        assert np.all(got >= np.minimum(a, b) - 0.5) and np.all(got <= np.maximum(a, b) + 0.5), (f, got, a, b)


def test_moving_scene_renders_with_full_length_and_finite_audio(small_config, tmp_path):
    cfg = small_config('scene.motion="mixed"', "scene.moving_fraction=1.0", 'scene.scenario="two-directional"',
                       "scene.speed=10.0", splits={"train": 1})
    cat = build_catalog(cfg, cfg.corpus.dir)
    r = plan_recipes(cfg, "train", CatalogView(cat.clips["train"]))[0]
    scene = render_scene(r)
    assert scene.audio.shape == (4, r.n_samples) and np.all(np.isfinite(scene.audio))
    assert scene.record["motion"] == "moving"
    t, i = scene.record["sources"]
    assert t["level_dbfs"] - i["level_dbfs"] == pytest.approx(i["tir_db"], abs=0.01)


@pytest.fixture
def bank_dataset(generated_dataset):
    return generated_dataset("moving")


def test_bank_scenes_stay_in_their_split_rooms(bank_dataset):
    cfg, out = bank_dataset
    for split, rooms in (("train", {"sim01", "sim02"}), ("val", {"sim03"}), ("test", {"sim04"})):
        recipes = [SceneRecipe.from_json(x) for x in open(os.path.join(out, "plan", f"{split}.jsonl"))]
        assert {r.bank.room for r in recipes} <= rooms
        for r in recipes:
            assert all(s.bank.room in rooms for s in r.sources if s.bank)


def test_bank_labels_follow_the_bank_positions(bank_dataset):
    cfg, out = bank_dataset
    js = json.load(open(os.path.join(out, "train", "shard-00000.json")))
    moving = 0
    for scene in js["scenes"]:
        assert scene["array"]["format"] == "foa"
        for src in scene["sources"]:
            b = src["bank"]
            pos = np.asarray(b["positions"])
            times = np.asarray(b["times"])
            az = np.asarray(src["azimuth"], dtype=float)
            if len(times) == 1:
                np.testing.assert_allclose(azimuth_difference(az, pos[0, 0]), 0, atol=1e-3)
                continue
            moving += 1
            # at a knot time that falls on a frame centre the label is that knot's position
            centres = (np.arange(len(az)) + 0.5) * 0.1
            for tk, pk in zip(times, pos):
                hit = np.nonzero(np.abs(centres - tk) < 1e-6)[0]
                if hit.size:
                    assert azimuth_difference(az[hit[0]], pk[0]) < 1e-2
            # labels move between consecutive knots by no more than the knots do
            assert np.all(azimuth_difference(az[1:], az[:-1]) <= np.max(azimuth_difference(pos[1:, 0], pos[:-1, 0])) + 1e-3)
    assert moving > 0


def test_tau_db_with_room_numbers(tmp_path, demo_corpus):
    from support.banks import make_tau_db
    from tsel_data.config import load_config
    from tsel_data.errors import TselError

    make_tau_db(tmp_path / "TAU", rooms=(("bomb_shelter", 1), ("gym", 2), ("pb132", 8), ("pc226", 9)), L=64)
    cfg = load_config(preset="paper-measured", corpus_dir=demo_corpus, bank=str(tmp_path / "TAU"),
                      overrides=["audio.duration=1.0", 'splits.train.rooms=[1, 2]'],
                      splits={"train": 6, "val": 2, "test": 2})
    out = str(tmp_path / "out")
    plan_dataset(cfg, out)
    rooms = {s: {SceneRecipe.from_json(x).bank.room for x in open(os.path.join(out, "plan", f"{s}.jsonl"))}
             for s in ("train", "val", "test")}
    assert rooms["train"] <= {"bomb_shelter", "gym"} and rooms["val"] == {"pb132"} and rooms["test"] == {"pc226"}
    # a measured room: size known, RT60 and the array's place in the room not
    from tsel_data.job.pipeline import finalize, render_shards
    from tsel_data.tools.inspect import find_scene, summary

    render_shards(out, progress=False)
    finalize(out)
    scene = find_scene(out, "train/0")
    assert scene.record["array"]["centre"] is None and scene.record["room"]["rt60"] is None
    text = summary(scene)
    assert "RT60 unknown" in text and "position in the room unknown" in text
    bad = load_config(preset="paper-measured", corpus_dir=demo_corpus, bank=str(tmp_path / "TAU"),
                      splits={"train": 1, "val": 1, "test": 1})
    with pytest.raises(TselError, match="no room 3"):
        resolve_bank(bank_request(bad), str(tmp_path / "x"))


def test_moving_source_knots_share_one_late_tail():
    """Independent tails per knot would be crossfaded into a 3 dB dip between knots."""
    from tsel_data.acoustics import simulate_rirs
    from tsel_data.core.geometry import Room
    from tsel_data.receivers import ArrayPose

    room, array = Room((8.0, 7.0, 3.5), 0.6), ArrayPose("mic4", (4.0, 3.5, 1.2), 0.0, 0.1)
    knots = np.array([[6.0, 3.5, 1.5], [5.9, 4.1, 1.5], [5.6, 4.7, 1.5]])
    one = simulate_rirs(room, array, knots, 24000, "hybrid", seed=3, one_source=True).rirs
    many = simulate_rirs(room, array, knots, 24000, "hybrid", seed=3).rirs
    late = slice(int(0.2 * 24000), None)  # well after the transition to the stochastic tail
    np.testing.assert_array_equal(one[0, :, late], one[2, :, late])
    assert abs(np.corrcoef(many[0, 0, late], many[2, 0, late])[0, 1]) < 0.1


def test_a_split_without_rooms_never_draws_another_splits_rooms(tmp_path, demo_corpus):
    from support.banks import make_tau_db
    from tsel_data.banks.scenes import bank_problems, open_bank_cached, split_rooms
    from tsel_data.config import load_config
    from tsel_data.errors import ConfigError

    make_tau_db(tmp_path / "TAU", rooms=(("bomb_shelter", 1), ("gym", 2), ("pb132", 3), ("se203", 8), ("tb103", 9)), L=16)
    bank = open_bank_cached(str(tmp_path / "TAU"))

    def cfg(**rooms):
        sets = [f"splits.{k}.rooms={v!r}".replace("'", '"') for k, v in rooms.items()]
        return load_config(preset="paper-measured", corpus_dir=demo_corpus, bank=str(tmp_path / "TAU"),
                           overrides=sets, splits={"train": 2, "val": 1, "test": 1})

    c = cfg(train=[1, 2], test=[])  # val keeps the preset's room 8; test names none
    assert split_rooms(bank, c.rooms_by_split(), "test") == ["pb132", "tb103"]      # not val's se203, not train's
    assert split_rooms(bank, c.rooms_by_split(), "train") == ["bomb_shelter", "gym"]
    assert bank_problems(bank_request(c)) == []
    c = cfg(train=[], val=[], test=[])  # nobody splits by room: every split may use every room
    assert split_rooms(bank, c.rooms_by_split(), "test") == bank.rooms
    c = cfg(train=[1, 2, 3, 9], test=[])  # with val's 8, nothing is left for test
    with pytest.raises(ConfigError, match="splits.test.rooms is empty and every room"):
        split_rooms(bank, c.rooms_by_split(), "test")
    assert any("splits.test.rooms is empty" in str(e) for e in bank_problems(bank_request(c)))


def test_banks_holding_two_formats_are_used_in_the_configs_format(tmp_path, demo_corpus):
    """A TAU-SRIR DB folder (foa and mic) and a folder of SpatialScaper's _foa and _mic SOFA
    files serve scene.format = "tetra" and "foa" as they are, with no import."""
    from support.banks import make_sofa, make_tau_db
    from tsel_data.config import load_config
    from tsel_data.core.geometry import sph_to_cart

    make_tau_db(tmp_path / "TAU", rooms=(("bomb_shelter", 1), ("gym", 2), ("se203", 8), ("tb103", 9)), L=32)
    pos = sph_to_cart(np.arange(24) * 15.0 - 180.0, 0.0, 1.5)
    (tmp_path / "SS").mkdir()
    for fmt in ("foa", "mic"):
        for room in ("gym", "tc352"):
            make_sofa(tmp_path / "SS" / f"{room}_{fmt}.sofa", np.full((24, 4, 16), 1.0 if fmt == "foa" else 2.0), pos,
                      room=room, listener_name=fmt)
    for bank, fmt, rooms in ((tmp_path / "TAU", "tetra", "[1, 2]"), (tmp_path / "SS", "foa", '["gym"]'),
                             (tmp_path / "SS", "tetra", '["gym"]')):
        over = ["audio.duration=1.0", f'scene.format="{fmt}"', f"splits.train.rooms={rooms}"]
        if bank.name == "SS":
            over += ['splits.val.rooms=["tc352"]', "splits.test.rooms=[]"]
        cfg = load_config(preset="paper-measured", corpus_dir=demo_corpus, bank=str(bank), overrides=over,
                          splits={"train": 2, "val": 1, "test": 0})
        out = str(tmp_path / f"out-{bank.name}-{fmt}")
        plan_dataset(cfg, out)
        r = SceneRecipe.from_json(open(os.path.join(out, "plan", "train.jsonl")).readline())
        scene = render_scene(r, plan_roots(cfg, Layout(out)))  # the plan names the bank; the roots place it
        assert scene.record["array"]["format"] == fmt and np.all(np.isfinite(scene.audio))
        if bank.name == "SS":  # the mic files hold 2.0, the foa files 1.0: the right files were read
            from tsel_data.banks.scenes import open_bank_cached

            b = open_bank_cached(str(bank), fmt)
            src = r.sources[0].bank
            assert np.all(b.read(src.room, src.trajectory, src.indices[:1]) == (1.0 if fmt == "foa" else 2.0))


def test_speeds_and_distances_are_as_configured(small_config, tmp_path):
    """Over 600 moving sources, each speed's share is within 3 points of its weight and
    the median distance within 5 % of the configured one: placement keeps the drawn speed
    and distance and retries only the rest of the geometry."""
    cfg = small_config('scene.motion="moving"', 'scene.scenario="two-directional"',
                       'scene.path=["choose", ["arc", "line"]]', 'scene.speed=["choose", [10.0, 20.0, 40.0]]',
                       'sources.distance=["uniform", 1.0, 3.0]', "audio.duration=4.0", "scene.separated_frames=0.5",
                       splits={"train": 300})
    view = CatalogView(build_catalog(cfg, cfg.corpus.dir).clips["train"])
    speeds, distances = [], []
    for r in plan_recipes(cfg, "train", view):
        c = np.asarray(r.array.centre)
        for s in r.sources:
            k = np.asarray(s.path, dtype=np.float64)
            t, p = k[:, 0], k[:, 1:] - c
            u = p / np.linalg.norm(p, axis=1, keepdims=True)
            if np.allclose(np.linalg.norm(p, axis=1), np.linalg.norm(p[0])):  # an arc: great-circle rate
                ang = np.degrees(np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1, 1)))
                speeds.append(float(np.median(ang / np.diff(t))))
                distances.append(float(np.linalg.norm(p[0])))
            else:  # a line: v / closest distance, on a step where it walks (it may stand at a wall)
                j = int(np.argmax(np.linalg.norm(np.diff(p, axis=0), axis=1)))
                v = np.linalg.norm(p[j + 1] - p[j]) / (t[j + 1] - t[j])
                e = (p[j + 1] - p[j]) / np.linalg.norm(p[j + 1] - p[j])
                closest = np.linalg.norm(p[0] - np.dot(p[0], e) * e)
                speeds.append(float(np.degrees(v / closest)))
                distances.append(float(closest))
    speeds = np.asarray(speeds)
    assert len(speeds) == 600
    for w in (10.0, 20.0, 40.0):
        share = float(np.mean(np.abs(speeds - w) < 0.5))
        assert abs(share - 1 / 3) <= 0.03, (w, share)
    assert abs(np.median(distances) - 2.0) <= 0.05 * 2.0, np.median(distances)


def test_a_setting_the_rooms_cannot_hold_is_named_by_tsel_check(demo_corpus):
    small_rooms = ("--set", 'room.length=["uniform", 5.0, 6.0]', "--set", 'room.width=["uniform", 5.0, 6.0]')
    common = ("check", "--preset", "demo", "--corpus-dir", demo_corpus, "--split", "train=4", "--split", "val=0",
              "--split", "test=0", "--set", 'scene.motion="moving"', "--set", "scene.speed=40.0",
              "--set", 'sources.distance=["uniform", 2.9, 3.0]', *small_rooms)
    # a 21 m line pass in a 6 m room walks wall to wall; an arc of 3 m radius cannot turn in it
    assert tsel(*common, "--set", 'scene.path="line"').returncode == 0
    r = tsel(*common, "--set", 'scene.path="arc"')
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "an arc path at 40°/s (scene.speed)" in r.stderr and "sources.distance" in r.stderr


def test_one_source_that_does_not_fit_is_not_blamed_on_separation(demo_corpus):
    r = tsel("check", "--preset", "demo", "--corpus-dir", demo_corpus, "--split", "train=4", "--split", "val=0",
              "--split", "test=0", "--set", 'scene.scenario="directional+additive"', "--set", 'scene.motion="moving"',
              "--set", 'scene.path="arc"', "--set", "scene.speed=40.0", "--set", 'sources.distance=["uniform", 2.9, 3.0]',
              "--set", 'room.length=["uniform", 5.0, 6.0]', "--set", 'room.width=["uniform", 5.0, 6.0]')
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("error:")]
    assert lines and all("min_separation" not in ln for ln in lines), r.stderr
    assert "2.9" in lines[0] and "lower the settings named" in lines[0]




def test_simulated_moving_scenes_are_the_same_bytes_with_any_worker_count_and_resume(small_config, tmp_path):
    """Arcs and lines (their knots simulated all at once, acoustics/knots.py): a shard
    rendered by one of two workers, and again by a resumed run of one, is the same file."""
    from tsel_data.core.digest import sha256_file
    from tsel_data.job.pipeline import generate

    cfg = small_config('scene.motion="moving"', 'scene.path=["choose", ["arc", "line"]]',
                       'scene.scenario="two-directional"', "output.shard_size=1", splits={"train": 2, "val": 0, "test": 0})
    out = str(tmp_path / "ds")

    def files():
        return {os.path.relpath(os.path.join(r, f), out): sha256_file(os.path.join(r, f))
                for r, _, fs in os.walk(out) for f in fs if f.endswith((".h5", ".jsonl")) and "demo-corpus" not in r}

    generate(cfg, out, workers=2, progress=False)
    ref = files()
    with open(os.path.join(out, "plan", "train.jsonl")) as f:
        assert all(s.get("path") for line in f for s in json.loads(line)["sources"])  # every source moves
    for shard in ("shard-00000.h5", "shard-00001.h5"):
        assert shard in {os.path.basename(f) for f in ref}
    os.remove(os.path.join(out, "train", "shard-00001.h5"))
    os.remove(os.path.join(out, "dataset.json"))
    generate(cfg, out, workers=1, resume=True, progress=False)
    assert files() == ref
