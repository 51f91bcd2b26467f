"""Acoustic descriptors as a dataset keeps them (output.descriptors): the shard's
descriptors/ group says what the records say, bank scenes are measured from the bank's
RIRs, and the switch turned off, or a plan made before it, stores none."""
from __future__ import annotations

import glob

import h5py
import numpy as np
import pytest

from tsel_data.store import open_dataset
from tsel_data.store.layout import DESCRIPTORS_GROUP


def _nan(v):
    return np.nan if v is None else v


@pytest.mark.parametrize("name", ["small", "moving"])
def test_the_shards_hold_what_the_records_say(generated_dataset, name):
    root = generated_dataset(name).out
    with open_dataset(root, "test") as ds:
        scenes = list(ds)
    shard = sorted(glob.glob(f"{root}/test/shard-*.h5"))[0]
    with h5py.File(shard) as f:
        g = f[DESCRIPTORS_GROUP]
        bands = [str(b) for b in g["t30_bands_s"].attrs["bands_hz"]]
        n = g["drr_db"].shape[0]
        for i, scene in enumerate(scenes[:n]):
            rec = scene.record
            if rec.room.dims:
                assert g["volume_m3"][i] == pytest.approx(np.prod(rec.room.dims), rel=1e-4)
            for k, src in enumerate(rec.sources):
                a = src.acoustics
                if src.spatial != "directional":
                    assert a is None and src.motion is None and np.isnan(g["drr_db"][i, k])
                    continue
                for key in ("drr_db", "c50_db", "edt_s", "t30_s"):
                    np.testing.assert_allclose(g[key][i, k], _nan(a[key]), rtol=1e-5)
                np.testing.assert_allclose(g["t30_bands_s"][i, k], [_nan(a["t30_bands_s"].get(b)) for b in bands],
                                           rtol=1e-5)
                assert g["motion"][i, k].decode() == src.motion
                assert src.motion == ("stationary" if not src.moving else src.motion)
                assert a["t30_s"] == pytest.approx(rec.room.rt60_measured or a["t30_s"], rel=0.35)


def test_off_or_planned_before_it_no_descriptors(tmp_path, demo_corpus):
    from tsel_data.config import load_config, parse_config
    from tsel_data.job.pipeline import generate

    cfg = load_config(preset="demo", corpus_dir=demo_corpus, splits={"train": 0, "val": 0, "test": 2},
                      overrides=["audio.duration=1.0", "output.descriptors=false"])
    generate(cfg, str(tmp_path / "off"), workers=1, progress=False)
    with open_dataset(str(tmp_path / "off"), "test") as ds:
        rec = ds[0].record
    assert all(s.acoustics is None and s.motion is None for s in rec.sources) and rec.room.volume_m3 is None
    assert "acoustics" not in rec.to_json()["sources"][0] and "volume_m3" not in rec.to_json()["room"]
    with h5py.File(next((tmp_path / "off" / "test").glob("*.h5"))) as f:
        assert DESCRIPTORS_GROUP not in f
    stored = cfg.to_dict()
    del stored["output"]["descriptors"]  # a plan made before the switch: its scenes keep their bytes
    assert parse_config(stored, stored=True).output.descriptors is False
    assert load_config(preset="demo").output.descriptors is True
