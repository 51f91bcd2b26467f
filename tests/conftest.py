import os
import tempfile

import pytest

# keep numerical libraries to one thread: the suite runs on 2 cores
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "PRA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
# remembered clip checks go to a folder of this run, not the user's cache (subprocesses inherit it)
os.environ.setdefault("TSEL_CACHE_DIR", tempfile.mkdtemp(prefix="tsel-test-cache-"))


@pytest.fixture(scope="session")
def demo_corpus(tmp_path_factory):
    """The built-in synthetic corpus, made once per test session."""
    from tsel_data.demo import synth_corpus

    d = tmp_path_factory.mktemp("demo-corpus")
    synth_corpus(str(d), seed=0)
    return str(d)


SMALL = [
    "audio.duration=3.0",
    "output.shard_size=4",
    'room.rt60=["uniform", 0.3, 0.5]',
]


@pytest.fixture
def small_config(demo_corpus):
    """A fast config over the demo corpus: 3 s scenes, few per split."""
    from tsel_data.config import load_config

    def make(*overrides, splits=None, preset="demo"):
        return load_config(preset=preset, overrides=SMALL + list(overrides), corpus_dir=demo_corpus,
                           splits=splits or {"train": 6, "val": 2, "test": 2})

    return make
