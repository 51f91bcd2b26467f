import json

import numpy as np
import pytest
from click.testing import CliRunner

from support.datasets import make_dataset
from tsel_data.cli.eval import eval_cmd
from tsel_data.core.geometry import azimuth_difference, circular_mean
from tsel_data.tools.evaluate import PredictionError, evaluate, summarise, write_predictions
from tsel_data.tools.labels import gaussian_target
from tsel_data.store import open_dataset


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    root = tmp_path_factory.mktemp("ev")
    # test-000000 sits at 179.5 deg, next to the ±180 seam; test-000002 has a moving target.
    make_dataset(root, splits={"test": 4}, moving={"test-000002"}, additive={"test-000003"},
                 target_az={"test-000000": 179.5, "test-000001": -90.0})
    return root


def _truth(root):
    return {s.scene_id: s for s in open_dataset(root, "test").iter_labels()}


def _write(tmp_path, rows, name="p.jsonl"):
    path = tmp_path / name
    write_predictions(path, rows)
    return str(path)


def test_perfect_prediction_scores_zero(ds, tmp_path):
    rows = []
    for sid, s in _truth(ds).items():
        az = s.azimuth[0]
        rows.append({"scene_id": sid, "azimuth": az if s.target_moving else float(az[0])})
    r = evaluate(ds, "test", _write(tmp_path, rows))
    assert r.overall["mae"] == pytest.approx(0.0, abs=1e-4)
    assert r.overall["acc5"] == 1.0 and r.overall["scenes"] == 4
    # One unit per static clip, one per active frame of the moving target (70 % of 20).
    assert r.overall["units"] == 3 + 14
    assert r.by_motion["moving"]["units"] == 14 and r.by_motion["static"]["units"] == 3
    assert set(r.by_scenario) == {"two-directional", "directional+additive"}


def test_known_wrong_prediction_wraps_around(ds, tmp_path):
    truth = _truth(ds)
    rows = [
        {"scene_id": "test-000000", "azimuth": -178.5},   # 179.5 -> -178.5 is 2 deg, not 358
        {"scene_id": "test-000001", "azimuth": 90.0},     # opposite: 180 deg
        {"scene_id": "test-000002", "azimuth": (truth["test-000002"].azimuth[0] + 12.0).tolist()},
        {"scene_id": "test-000003", "azimuth": float(truth["test-000003"].azimuth[0][0]) + 367.0},  # = +7
    ]
    r = evaluate(ds, "test", _write(tmp_path, rows))
    errs = {p["scene_id"]: p["error"] for p in r.per_scene}
    assert errs["test-000000"] == pytest.approx(2.0, abs=1e-4)
    assert errs["test-000001"] == pytest.approx(180.0, abs=1e-4)
    assert errs["test-000002"] == pytest.approx(12.0, abs=1e-3)
    assert errs["test-000003"] == pytest.approx(7.0, abs=1e-3)
    units = np.array([2.0, 180.0, 7.0] + [12.0] * 14)
    assert r.overall["mae"] == pytest.approx(units.mean(), abs=1e-3)
    assert r.overall["acc5"] == pytest.approx(1 / 17)
    assert r.overall["acc10"] == pytest.approx(2 / 17)
    assert r.overall["acc20"] == pytest.approx(16 / 17)


def test_predictions_exactly_on_a_threshold_count_for_it(tmp_path):
    """Predictions exactly 5 deg off score acc@5 = 100 %: against the circular mean of a
    static target's frames such an error computes as 5.000000000000028 (docs/reader.md)."""
    on_edge = {"test-000000": -34.3613395690918, "test-000001": -158.59291076660156}
    make_dataset(tmp_path / "ds", splits={"test": 3}, moving={"test-000002"}, target_az=on_edge)
    truth = _truth(tmp_path / "ds")
    for sid in on_edge:  # what used to miss acc@5: the truth is the mean over the active frames
        s = truth[sid]
        assert azimuth_difference(on_edge[sid] + 5.0, circular_mean(s.azimuth[0][s.active[0]].astype(float))) > 5.0
    rows = []
    for sid, s in truth.items():
        az = s.azimuth[0].astype(np.float64)
        rows.append({"scene_id": sid, "azimuth": az + 5.0 if s.target_moving else float(az[0]) + 5.0})
    r = evaluate(tmp_path / "ds", "test", _write(tmp_path, rows))
    assert r.overall["mae"] == pytest.approx(5.0, abs=1e-9)
    assert (r.overall["acc5"], r.overall["acc10"], r.overall["acc20"]) == (1.0, 1.0, 1.0)
    assert r.format_text().splitlines()[2].endswith("100.0%   100.0%   100.0%")
    # the tolerance covers rounding only: a thousandth of a degree over still misses
    row = summarise([np.array([5.000000000000028, 5.001, 10.0 + 1e-9, 20.01])])
    assert (row["acc5"], row["acc10"], row["acc20"]) == (0.25, 0.75, 0.75)


def test_distribution_and_static_per_frame(ds, tmp_path):
    truth = _truth(ds)
    rows = []
    for sid, s in truth.items():
        if sid == "test-000001":  # per-frame azimuths for a static target -> circular mean
            rows.append({"scene_id": sid, "azimuth": [-80.0, -100.0] * 10})
        else:
            rows.append({"scene_id": sid, "distribution": gaussian_target(s.azimuth[0] + 3.0)})
    r = evaluate(ds, "test", _write(tmp_path, rows))
    errs = {p["scene_id"]: p["error"] for p in r.per_scene}
    assert errs["test-000001"] == pytest.approx(0.0, abs=1e-6)
    # argmax of a Gaussian centred 3 deg off: the 1-degree bin nearest to truth + 3.
    for sid in ("test-000000", "test-000002", "test-000003"):
        assert 2.0 <= errs[sid] <= 4.0


@pytest.mark.parametrize("lines, match", [
    (['{"scene_id": "test-000000", "azimuth": 1}', "not json"], r"p.jsonl:2: not valid JSON"),
    (['{"scene_id": "test-000000"}'], r"p.jsonl:1: give exactly one of"),
    (['{"scene_id": "test-000000", "azimuth": 1}', '{"scene_id": "test-000000", "azimuth": 2}'], "predicted twice"),
    (['{"scene_id": "test-000000", "distribution": [1, 2, 3]}'], "360 numbers"),
    (['{"scene_id": "test-000000", "azimuth": null}'], "not strings, booleans or null"),
])
def test_malformed_files_name_the_line(ds, tmp_path, lines, match):
    p = tmp_path / "p.jsonl"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(PredictionError, match=match):
        evaluate(ds, "test", str(p))


def test_missing_unknown_and_wrong_length(ds, tmp_path):
    ids = list(_truth(ds))
    with pytest.raises(PredictionError, match=r"1 of 4 scenes .* no prediction, e.g. 'test-000003'"):
        evaluate(ds, "test", _write(tmp_path, [{"scene_id": i, "azimuth": 0.0} for i in ids[:3]]))
    rows = [{"scene_id": i, "azimuth": 0.0} for i in ids] + [{"scene_id": "train-000009", "azimuth": 0.0}]
    with pytest.raises(PredictionError, match="not in split 'test'"):
        evaluate(ds, "test", _write(tmp_path, rows))
    rows = [{"scene_id": i, "azimuth": [0.0] * 7} for i in ids]
    with pytest.raises(PredictionError, match="7 frame azimuths, but the scene has 20"):
        evaluate(ds, "test", _write(tmp_path, rows))


def test_cli_text_and_json(ds, tmp_path):
    rows = [{"scene_id": i, "azimuth": float(s.azimuth[0][0])} for i, s in _truth(ds).items()]
    path = _write(tmp_path, rows)
    res = CliRunner().invoke(eval_cmd, ["--pred", path, str(ds), "--split", "test"])
    assert res.exit_code == 0, res.output
    assert "MAE(deg)" in res.output and "motion=moving" in res.output
    res = CliRunner().invoke(eval_cmd, ["--pred", path, str(ds), "--json"])
    doc = json.loads(res.output)
    assert doc["split"] == "test" and len(doc["per_scene"]) == 4
    # The moving target is scored per frame even with one azimuth for the clip.
    assert doc["by_motion"]["moving"]["units"] == 14


@pytest.mark.parametrize("value, message", [("1e400", "infinity"), ("9" * 5000, "thousands of digits"),
                                            ("[" * 100000 + "]" * 100000, "nested too deeply")])
def test_numbers_no_prediction_holds_are_one_line(ds, tmp_path, value, message):
    path = tmp_path / "p.jsonl"
    path.write_text('{"scene_id": "test-000000", "azimuth": %s}\n' % value)
    with pytest.raises(PredictionError, match=message):
        evaluate(ds, "test", str(path))
