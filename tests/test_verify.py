import json

import numpy as np
import pytest
from click.testing import CliRunner

from datasetfixture import make_dataset, plane_wave
from tsel_data.cli.verify import verify_cmd
from tsel_data.features import gcc_phat, mic_pairs
from tsel_data.geometry import mic4_positions
from tsel_data.verify import doa_maps, verify_dataset


@pytest.mark.parametrize("fmt", ["mic4", "foa", "tetra"])
def test_good_data_passes_and_rotated_labels_are_flagged(tmp_path, fmt):
    make_dataset(tmp_path, fmt=fmt, splits={"train": 5}, moving={"train-000001"}, additive={"train-000003"},
                 rotate={"train-000002": 90.0}, seed=3)
    rep = verify_dataset(str(tmp_path))
    sp = rep.splits["train"]
    assert sp["tested"] == 5 and sp["agree"] == 4 and sp["rate"] == pytest.approx(0.8)
    assert [d["scene_id"] for d in sp["disagree"]] == ["train-000002"]
    bad = sp["disagree"][0]["sources"]
    # Both directional labels were rotated: each is ~90 deg from what the audio says.
    assert all(abs(s["error"] - 90.0) < 10.0 for s in bad)
    assert sp["median_error"] < 5.0
    text = rep.format_text()
    assert "train-000002" in text and "80.0%" in text


def test_no_dominant_frames_falls_back_or_is_untested(tmp_path):
    make_dataset(tmp_path, splits={"train": 1}, seed=1)
    from tsel_data.reader import open_dataset
    from tsel_data.verify import verify_scene

    s = open_dataset(tmp_path, "train")[0]
    s.active[:] = True  # both sources "always on": no frame where one dominates
    r = verify_scene(s, min_frames=3)
    assert r["mode"] == "overlap" and r["status"] == "agree"
    s.azimuth[0] += 60.0
    assert verify_scene(s)["status"] == "disagree"


def test_srp_map_peaks_at_the_source():
    fs, n = 24000, 24000
    rng = np.random.default_rng(0)
    mics = mic4_positions(0.1)
    for az in (-170.0, -45.0, 0.0, 100.0):
        x = plane_wave(rng.standard_normal(n), np.full(10, az), np.zeros(10), "mic4", mics, fs, 2400)
        m = doa_maps(x.astype(np.float32), fs, 0.1, 10, "mic4", mics)
        est = np.argmax(m.sum(0))
        assert min(abs(est - az % 360), 360 - abs(est - az % 360)) <= 3


def test_gcc_phat_shape_and_lag():
    fs, n, delay = 24000, 24000, 5
    rng = np.random.default_rng(1)
    s = rng.standard_normal(n + delay)
    x = np.stack([s[delay:], s[:-delay], s[delay:]]).astype(np.float32)  # ch1 hears it 5 samples later
    g = gcc_phat(x)
    assert g.shape == (3, 1 + n // 640, 96) and g.dtype == np.float32
    assert mic_pairs(3) == [(0, 1), (0, 2), (1, 2)]
    mid = g[:, 5:-5].mean(axis=1)
    lags = np.argmax(mid, axis=-1) - 48
    # Pair (0,1): ch0 is 5 samples earlier, so τ = t0 - t1 = -5; (0,2): 0; (1,2): +5.
    assert lags.tolist() == [-delay, 0, delay]


def test_cli_fail_under_and_json(tmp_path):
    make_dataset(tmp_path, splits={"train": 3}, rotate={"train-000000": 120.0}, seed=2)
    res = CliRunner().invoke(verify_cmd, [str(tmp_path), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["splits"]["train"]["agree"] == 2
    res = CliRunner().invoke(verify_cmd, [str(tmp_path), "--fail-under", "0.9"])
    assert res.exit_code == 1 and "train-000000" in res.output
