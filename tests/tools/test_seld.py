"""The DCASE 2024 SELD metrics (tsel_data/tools/seld.py) on hand-computed cases, and `tsel eval
--dcase` on a DCASE export scored against itself."""
import math
import os
import shutil

import numpy as np
import pytest

from support.datasets import make_dataset
from tsel_data.tools.seld import SeldAccumulator, angular_distance, frames_of


def _score(frames_ref, frames_pred):
    acc = SeldAccumulator(classes=(0, 1))
    for r, p in zip(frames_ref, frames_pred):
        acc.add_frame(r, p)
    return acc.scores()


def test_a_perfect_prediction():
    ref = [{0: [(30.0, 10.0, 2.0)]} for _ in range(10)]
    s = _score(ref, ref)
    assert (s.er, s.f, s.le, s.lr, s.rde, s.seld) == pytest.approx((0, 1, 0, 1, 0, 0), abs=1e-9)
    assert list(s.classes) == [0]  # a class that never occurs is not averaged in


def test_hand_computed_detection_localisation_and_distance():
    """10 frames of a class-0 reference at 0°, 2 m. Frames 0-4: 10° off, 2.5 m (a hit,
    relative distance error 0.25); 5-7: 30° off (a spatial false positive); 8-9 missed;
    frame 9 also predicts a class-1 event that is not there."""
    ref = [{0: [(0.0, 0.0, 2.0)]} for _ in range(10)]
    pred = [{0: [(10.0, 0.0, 2.5)]}] * 5 + [{0: [(30.0, 0.0, 2.0)]}] * 3 + [{}, {1: [(90.0, 0.0, 1.0)]}]
    s = _score(ref, pred)
    c0, c1 = s.classes[0], s.classes[1]
    assert c0["f"] == pytest.approx(5 / (5 + 3 + 0.5 * 2))  # TP 5, spatial FP 3, FN 2
    assert c0["le"] == pytest.approx((5 * 10 + 3 * 30) / 8)  # over every matched pair
    assert c0["lr"] == pytest.approx(8 / 10)
    assert c0["rde"] == pytest.approx(5 * 0.25 / 8) and c0["de"] == pytest.approx(5 * 0.5 / 8)
    assert c0["seld"] == pytest.approx(np.mean([1 - 5 / 9, 17.5 / 180, 0.15625]))
    assert c1["f"] == pytest.approx(0.0) and math.isnan(c1["le"]) and c1["seld"] == pytest.approx(1.0)
    # insertions 3 (frames 5-7), a deletion (8), a substitution (9): 5 errors over 10 references
    assert s.er == pytest.approx(0.5)
    assert s.f == pytest.approx((5 / 9 + 0) / 2) and s.lr == pytest.approx(0.4) and s.le == pytest.approx(17.5)
    assert s.seld == pytest.approx((np.mean([1 - 5 / 9, 17.5 / 180, 0.15625]) + 1) / 2)


def test_events_of_one_class_are_matched_by_the_hungarian_algorithm_and_distance_counts():
    # matched in order, the pairs would be 85° and 85° off; the assignment finds 5° and 5°
    s = _score([{1: [(0.0, 0.0, 1.0), (90.0, 0.0, 1.0)]}], [{1: [(85.0, 0.0, 1.0), (5.0, 0.0, 1.0)]}])
    assert s.classes[1]["le"] == pytest.approx(5.0) and s.classes[1]["f"] == pytest.approx(1.0)
    # right direction, 2.5 m for 1 m: relative error 1.5 > 1, a spatial false positive
    s = _score([{0: [(0.0, 0.0, 1.0)]}], [{0: [(0.0, 0.0, 2.5)]}])
    assert s.classes[0]["f"] == pytest.approx(0.0) and s.classes[0]["rde"] == pytest.approx(1.5)
    assert s.er == pytest.approx(1.0)  # one insertion over one reference


def test_without_distances_the_2023_score():
    ref = [{0: [(0.0, 0.0, math.nan)]}] * 4
    pred = [{0: [(10.0, 0.0, math.nan)]}] * 2 + [{}, {}]
    s = _score(ref, pred)
    f, le, lr, er = 2 / (2 + 0.5 * 2), 10.0, 0.5, 0.5
    assert (s.f, s.le, s.lr, s.er) == pytest.approx((f, le, lr, er))
    assert math.isnan(s.rde) and s.seld == pytest.approx(np.mean([er, 1 - f, le / 180, 1 - lr]))


def test_angles_are_great_circles():
    assert angular_distance(179.0, 0.0, -179.0, 0.0) == pytest.approx(2.0)
    assert angular_distance(0.0, 90.0, 123.0, 90.0) == pytest.approx(0.0, abs=1e-6)
    rows = [(3, 0, 0, 10, 5, 250), (3, 1, 0, -20, 0, 100), (99, 0, 0, 0, 0, 100)]
    f = frames_of(rows, 5)
    assert f[3] == {0: [(10.0, 5.0, 2.5)], 1: [(-20.0, 0.0, 1.0)]} and len(f) == 5  # frame 99 is past the clip


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    from tsel_data.export.dcase import export_dcase

    root = tmp_path_factory.mktemp("seld")
    make_dataset(root / "ds", splits={"test": 3}, moving={"test-000001"}, additive={"test-000002"})
    summary = export_dcase(str(root / "ds"), str(root / "dcase"))
    return str(root / "ds"), summary["splits"]["test"]["metadata_dir"]


def test_tsel_eval_dcase_scores_an_export_against_its_dataset(exported, tmp_path, tsel_cli):
    ds, meta = exported
    out = tsel_cli.ok("eval", "--dcase", "--pred", meta, ds, "--split", "test")
    macro = next(line for line in out.splitlines() if line.startswith("macro"))
    assert "100.0%" in macro and "error rate ER 0.000" in out  # the labels themselves: perfect
    # every target row turned 30° away: the target's F drops to 0, its LE is 30°
    bad = tmp_path / "bad"
    shutil.copytree(meta, bad)
    for name in os.listdir(bad):
        rows = np.loadtxt(bad / name, delimiter=",", dtype=np.int64, ndmin=2)
        rows[rows[:, 1] == 0, 3] += 30
        np.savetxt(bad / name, rows, fmt="%d", delimiter=",")
    import json
    scores = json.loads(tsel_cli.ok("eval", "--dcase", "--json", "--pred", str(bad), ds, "--split", "test"))
    assert scores["classes"]["0"]["f"] == pytest.approx(0.0) and scores["classes"]["0"]["le"] == pytest.approx(30, abs=0.6)
    assert scores["classes"]["1"]["f"] == pytest.approx(1.0)


def test_tsel_eval_dcase_names_a_missing_scene_and_a_bad_row(exported, tmp_path, tsel_cli):
    ds, meta = exported
    few = tmp_path / "few"
    shutil.copytree(meta, few)
    os.remove(few / sorted(os.listdir(few))[0])
    assert "have no prediction file" in tsel_cli.refused("eval", "--dcase", "--pred", str(few), ds)
    (few / "fold1_test-000000.csv").write_text("0,0,0,ten,0\n")
    line = tsel_cli.refused("eval", "--dcase", "--pred", str(few), ds)
    assert "fold1_test-000000.csv:1" in line and "frame,class,source" in line
