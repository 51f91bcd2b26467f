import os
import tempfile

import pytest

# keep numerical libraries to one thread: the suite runs on 2 cores
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "PRA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
# remembered clip checks go to a folder of this run, not the user's cache (subprocesses inherit it)
os.environ.setdefault("TSEL_CACHE_DIR", tempfile.mkdtemp(prefix="tsel-test-cache-"))
# and prepared clips (made by every full clip check) too, not beside the shared demo corpus's audio
os.environ.setdefault("TSEL_CLIP_CACHE", tempfile.mkdtemp(prefix="tsel-test-clips-"))


@pytest.fixture(scope="session")
def demo_corpus(tmp_path_factory):
    """The built-in synthetic corpus, made once per test session."""
    from tsel_data.corpus.demo import synth_corpus

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


class InProcessCli:
    """``tsel ARGS`` through the real entry point (tsel_data.cli:main), in this process,
    its output captured: quicker than a subprocess, and what a user sees."""

    def __init__(self, capsys):
        self.capsys = capsys

    def run(self, *argv) -> tuple[int, str, str]:
        from tsel_data.cli import main

        with pytest.raises(SystemExit) as ex:
            main([str(a) for a in argv])
        out = self.capsys.readouterr()
        return ex.value.code, out.out, out.err

    def ok(self, *argv) -> str:
        code, out, err = self.run(*argv)
        assert code == 0, err
        return out

    def refused(self, *argv) -> str:
        """The one ``error:`` line of a command that must fail with exit 2."""
        code, _, err = self.run(*argv)
        lines = [x for x in err.splitlines() if x.strip()]
        assert code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
        return lines[0]


@pytest.fixture
def tsel_cli(capsys):
    return InProcessCli(capsys)
