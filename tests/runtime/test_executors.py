"""Local pool, dask-local and shard ranges give the same files."""
import os

import pytest

from tsel_data.job.pipeline import finalize, generate, plan_dataset, render_shards
from tsel_data.core.digest import sha256_file


def _digest(d):
    return {os.path.relpath(os.path.join(r, f), d): sha256_file(os.path.join(r, f))
            for r, _, fs in os.walk(d) for f in fs
            if not os.path.relpath(r, d).startswith("demo-corpus") and not f.endswith(".seal.json")}  # seals hold times


@pytest.mark.slow
def test_dask_local_cluster_and_ranges_match_local(small_config, tmp_path):
    pytest.importorskip("dask.distributed")
    cfg = small_config("audio.duration=2.0", "output.shard_size=2", splits={"train": 4, "val": 2, "test": 2})
    ref = str(tmp_path / "local")
    generate(cfg, ref, workers=1, progress=False)

    dk = str(tmp_path / "dask")
    generate(cfg, dk, workers=2, progress=False, executor="dask-local")
    assert _digest(dk) == _digest(ref)

    ranges = str(tmp_path / "ranges")
    plan_dataset(cfg, ranges)
    for r in (range(3, 4), range(0, 2), range(2, 3)):  # any order, any split of the work
        render_shards(ranges, r, progress=False)
    finalize(ranges)
    assert _digest(ranges) == _digest(ref)


def test_dask_needs_a_scheduler(tmp_path):
    from tsel_data.errors import TselError
    from tsel_data.runtime.runner import Runner

    with pytest.raises(TselError, match="--scheduler"):
        Runner("dask")
    with pytest.raises(TselError, match="unknown executor"):
        Runner("slurm")
