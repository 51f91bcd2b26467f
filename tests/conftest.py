import atexit
import fcntl
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

from support.cli import InProcessCli
from support.configs import DATASETS, SMALL

# keep numerical libraries to one thread: the suite runs on 2 cores
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "PRA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

# One temporary folder per run, made by the process that runs the session (pytest itself,
# or xdist's controller, before it starts the workers) and removed by it when the run ends
# (pytest_unconfigure), after every worker: the workers and every subprocess inherit it as
# TMPDIR, so what anything of the run puts in "the temporary folder" (the commands' own
# mkdtemp, a test module's, the caches below) goes there, not beside other runs in /tmp.
# pytest's own folders (tmp_path, shared_dir) stay where pytest keeps its last runs.
RUN_TMP = "TSEL_TEST_RUN_TMP"
_OWN_RUN_TMP = None
if not os.environ.get(RUN_TMP):
    os.environ.setdefault("PYTEST_DEBUG_TEMPROOT", tempfile.gettempdir())
    _OWN_RUN_TMP = os.environ[RUN_TMP] = tempfile.mkdtemp(prefix="tsel-test-run-")
    atexit.register(shutil.rmtree, _OWN_RUN_TMP, True)  # should the run end before unconfigure
os.environ["TMPDIR"] = tempfile.tempdir = os.environ[RUN_TMP]
# remembered clip checks go to a folder of this run, not the user's cache (subprocesses
# inherit it), and prepared clips (made by every full clip check) too, not beside the
# shared demo corpus's audio; datasets' downloads and caches (HF_HOME) too
for _v, _name in (("TSEL_CACHE_DIR", "cache"), ("TSEL_CLIP_CACHE", "clips"), ("HF_HOME", "hf")):
    if _v not in os.environ:
        os.environ[_v] = os.path.join(os.environ[RUN_TMP], _name)
        os.makedirs(os.environ[_v], exist_ok=True)


def pytest_unconfigure(config):
    """The run's temporary folder goes when the run ends: in the process that made it (not
    an xdist worker), once every worker is done."""
    if _OWN_RUN_TMP and not hasattr(config, "workerinput"):
        shutil.rmtree(_OWN_RUN_TMP, ignore_errors=True)


@pytest.fixture(scope="session")
def shared_dir(tmp_path_factory) -> Path:
    """A folder every worker of this run sees (xdist's workers each have a base folder
    below one parent): what is built here is built once per run, not once per worker."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def built_once(path: Path, build) -> Path:
    """``path``, made by ``build(folder)`` by the first worker that asks (the others wait
    on a lock), under a temporary name renamed when whole."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(path.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            tmp = path.with_name(path.name + ".building")
            shutil.rmtree(tmp, ignore_errors=True)
            tmp.mkdir()
            build(tmp)
            tmp.rename(path)
    return path


@pytest.fixture(scope="session")
def demo_corpus(shared_dir):
    """The built-in synthetic corpus, made once per test run. Read it, never change it:
    a test that edits clips works on a copy."""
    from tsel_data.corpus.demo import synth_corpus

    return str(built_once(shared_dir / "demo-corpus", lambda d: synth_corpus(str(d), seed=0)))


def _recordings(shared_dir: Path) -> str:
    from tsel_data.corpus.demo.recordings import synth_recordings

    return str(built_once(shared_dir / "demo-recordings", lambda d: synth_recordings(str(d), seed=0)))


@pytest.fixture(scope="session")
def demo_recordings(shared_dir):
    """The stand-in for STARSS23 in its exact layout (corpus/demo/recordings.py), made once
    per test run. Read it, never change it."""
    return _recordings(shared_dir)


@dataclass(frozen=True)
class Generated:
    cfg: object  # the Config it was generated with
    out: str  # the dataset folder: read it, copy it to change it

    def __iter__(self):  # cfg, out = generated_dataset("small")
        return iter((self.cfg, self.out))


@pytest.fixture(scope="session")
def generated_dataset(shared_dir, demo_corpus):
    """``generated_dataset(NAME)``: the dataset of ``support.configs.DATASETS[NAME]`` over
    the demo corpus, made by the real ``generate()`` once per run and shared by every test
    and worker that asks for it. Read it; a test that changes a dataset copies it first."""
    from tsel_data.job.pipeline import generate

    # a dataset stores its corpus folder relative to itself: at the depth of a test's
    # ``tmp_path / "out"``, a test's own dataset made from the same config has the same bytes
    home = shared_dir / "generated" if os.environ.get("PYTEST_XDIST_WORKER") else shared_dir

    def make(name: str) -> Generated:
        spec = DATASETS[name]
        cfg = spec.load(_recordings(shared_dir) if spec.corpus == "recordings" else demo_corpus)
        folder = built_once(home / (name if home != shared_dir else f"generated-{name}"),
                            lambda d: generate(cfg, str(d / "ds"), workers=1, progress=False))
        return Generated(cfg, str(folder / "ds"))

    return make


@pytest.fixture
def small_config(demo_corpus):
    """A fast config over the demo corpus: 3 s scenes, few per split."""
    from tsel_data.config import load_config

    def make(*overrides, splits=None, preset="demo"):
        return load_config(preset=preset, overrides=SMALL + list(overrides), corpus_dir=demo_corpus,
                           splits=splits or {"train": 6, "val": 2, "test": 2})

    return make


@pytest.fixture
def tsel_cli(capsys):
    return InProcessCli(capsys)


def pytest_collection_modifyitems(items):
    """Under ``--dist loadgroup`` every test of a module that uses a module-scoped fixture
    runs on one worker, so the fixture is built once; all other tests spread one by one
    (``make test``). Generated datasets need no group: ``generated_dataset`` is shared."""
    for item in items:
        defs = getattr(item, "_fixtureinfo", None)
        if defs and any(d.scope == "module" for fd in defs.name2fixturedefs.values() for d in fd):
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))

