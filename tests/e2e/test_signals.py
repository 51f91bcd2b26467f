"""Stopping a run (docs/reliability.md, "what each signal does"): the first SIGINT,
SIGTERM or SIGHUP finishes the shards in flight and exits, the second stops at once; no
signal to the main process, a worker or the group hangs the run or leaves a process, and
`--resume` then gives the bytes of an uninterrupted run."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time

import h5py
import pytest

from support.configs import DATASETS

from tsel_data.job.pipeline import finalize, generate, plan_dataset, render_shards
from support.files import alive as _alive, children as _children, data_files, patience, tmp_files

# image-source rooms that ring for about a second: a 3 s scene takes about 0.3 s here, so
# a shard is still in flight when a test's second signal comes (hybrid rooms take 10 ms)
SETS = list(DATASETS["signals"].overrides)
SPLITS = DATASETS["signals"].splits
SHARDS = 5
STOP_WITHIN = 20.0  # seconds from the signal to the exit, on 2 cores

STOPPING = re.compile(r"stopping( \((SIGTERM|SIGHUP)\))?: finishing \d+ (shard|clip)s? in flight, then exit; "
                      r"(press Ctrl-C again|signal again) to stop now$")
WORKER_STOPPING = re.compile(r"stopping: worker \d+ got SIGTERM; finishing \d+ shards? in flight, then exit; "
                             r"press Ctrl-C to stop now$")
STOPPED_NOW = re.compile(r"stopped now \((SIGINT|SIGTERM)\):( \d+ shards? in flight discarded;)? (rerun with --resume "
                         r"to continue|run it again to render the rest): finished shards are kept$")
STOPPED = re.compile(r"stopped \((SIGINT|SIGTERM|SIGHUP)\); ")


def _cli_args(cfg) -> list[str]:
    return ["--preset", "demo", "--corpus-dir", cfg.corpus.dir, *[f"--split={k}={v}" for k, v in SPLITS.items()],
            *[f"--set={s}" for s in SETS]]


@pytest.fixture
def cfg(generated_dataset):
    return generated_dataset("signals").cfg


@pytest.fixture
def reference(generated_dataset):
    return generated_dataset("signals").out


class Run:
    """A ``tsel`` command in a process group of its own (as a shell runs a job), its
    stderr collected line by line as it comes."""

    def __init__(self, *args, env=None, argv=None):
        self.p = subprocess.Popen(argv or [sys.executable, "-m", "tsel_data.cli", *args], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, start_new_session=True, env=env)
        self.pgid = self.p.pid
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._readers = [threading.Thread(target=self._read, args=(f, into), daemon=True)
                         for f, into in ((self.p.stdout, self.stdout), (self.p.stderr, self.stderr))]
        for t in self._readers:
            t.start()
        self.signalled_at = None
        self.sealed_at = 0  # shards sealed when the first signal was sent

    @staticmethod
    def _read(f, into):
        for line in f:
            into.append(line.rstrip("\n"))

    def until(self, cond, what: str, timeout: float = 90.0) -> None:
        deadline = time.monotonic() + patience(timeout)
        while not cond():
            assert self.p.poll() is None, f"ended before {what}: {self.p.returncode} {self.stderr}"
            assert time.monotonic() < deadline, f"never {what}: {self.stderr}"
            time.sleep(0.005)

    def signal_group(self, sig) -> None:
        self.signalled_at = self.signalled_at or time.monotonic()
        os.killpg(self.pgid, sig)

    def signal_main(self, sig) -> None:
        self.signalled_at = self.signalled_at or time.monotonic()
        os.kill(self.p.pid, sig)

    def end(self) -> float:
        """Seconds from the first signal to the exit; fails if the run outlives STOP_WITHIN."""
        within = patience(STOP_WITHIN)
        try:
            self.p.wait(timeout=within)
        except subprocess.TimeoutExpired:
            left = _group(self.pgid)
            os.killpg(self.pgid, signal.SIGKILL)
            pytest.fail(f"still running {within:.0f} s after the signal; processes {left}; {self.stderr}")
        took = time.monotonic() - self.signalled_at
        for t in self._readers:
            t.join(5)
        return took


def _group(pgid: int) -> list[int]:
    """Processes of the group still alive (zombies waiting for a reaper are not)."""
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return []
    out = []
    for name in os.listdir("/proc"):
        try:
            with open(f"/proc/{name}/stat") as f:
                pgrp = int(f.read().rsplit(")", 1)[1].split()[2])
        except (OSError, ValueError, IndexError):
            continue
        if pgrp == pgid and _alive(int(name)):
            out.append(int(name))
    return out


def _assert_nothing_left(pgid: int) -> None:
    deadline = time.monotonic() + patience(5.0)  # multiprocessing's helper leaves once the main process is gone
    while _group(pgid) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = _group(pgid)
    if left:
        os.killpg(pgid, signal.SIGKILL)
    assert not left, f"processes left after the run: {left}"


def _sealed(out: str) -> int:
    d = os.path.join(out, "train")
    return sum(f.endswith(".seal.json") for f in os.listdir(d)) if os.path.isdir(d) else 0


def _h5_tmps(out: str) -> set[str]:
    d = os.path.join(out, "train")
    return {f for f in os.listdir(d) if ".h5.tmp-" in f} if os.path.isdir(d) else set()


def _rendering(run: Run, out: str) -> None:
    """Until a shard was sealed, both workers run, and a shard's file has just appeared: a
    shard's file appears after its first scene, so that shard has a scene (~0.3 s) to go
    and is surely in flight when the test's signals come. (A seal alone is not enough: a
    worker seals before the main process hears of it, and both of a lockstep pair may
    then finish within the milliseconds between two signals.)"""
    run.until(lambda: len(_children(run.p.pid)) >= 2 and _sealed(out) >= 1, "rendering with 2 workers")
    seen = _h5_tmps(out)

    def a_new_shard_file() -> bool:
        now = _h5_tmps(out)
        new = now - seen
        seen.update(now)
        return bool(new)

    run.until(a_new_shard_file, "a shard's file appearing")


def _assert_whole(out: str) -> None:
    """Whatever the stop left under a final name is whole."""
    for f in os.listdir(os.path.join(out, "train")):
        if f.endswith(".h5"):
            with h5py.File(os.path.join(out, "train", f), "r") as h:
                assert h["audio"].shape[0] == len(h["scene_id"]) == 2, f


def _send(run: Run, case: str, out: str) -> None:
    run.sealed_at = _sealed(out)
    if case == "one SIGINT":
        run.signal_group(signal.SIGINT)
    elif case == "two SIGINTs":
        run.signal_group(signal.SIGINT)
        run.until(lambda: run.stderr, "said it is stopping")
        run.signal_group(signal.SIGINT)
    elif case == "group SIGTERM":
        run.signal_group(signal.SIGTERM)
    elif case == "group SIGTERM, then main SIGTERM":  # what timeout(1) and batch schedulers do
        run.signal_group(signal.SIGTERM)
        time.sleep(0.3)
        if run.p.poll() is None:
            run.signal_main(signal.SIGTERM)
    elif case == "SIGTERM to a worker":
        run.signalled_at = time.monotonic()
        os.kill(_children(run.p.pid)[0], signal.SIGTERM)
    elif case == "SIGHUP":
        run.signal_group(signal.SIGHUP)
    else:
        raise ValueError(case)


def _assert_finished_in_flight(run: Run, case: str, out: str) -> None:
    """After a first signal alone: no shard was dropped half-made, and none was started
    after the signal (those in flight then are sealed by now, none more)."""
    if case not in ("one SIGINT", "group SIGTERM", "SIGHUP"):
        return
    n = int(re.search(r"finishing (\d+) ", run.stderr[0]).group(1))
    now = _sealed(out)
    # + 1: a shard sealed between the count and the signal's arrival
    assert now <= run.sealed_at + n + 1 and now < SHARDS, (run.sealed_at, n, now)
    assert not [f for f in tmp_files(out) if "shard-" in f], tmp_files(out)


def _assert_said(case: str, lines: list[str]) -> None:
    """One line per signal the run acted on, each the documented one, no traceback."""
    assert "Traceback" not in "\n".join(lines), lines
    if case in ("one SIGINT", "group SIGTERM", "SIGHUP"):
        assert len(lines) == 1 and STOPPING.match(lines[0]), lines
    elif case == "two SIGINTs":
        assert len(lines) == 2 and STOPPING.match(lines[0]) and STOPPED_NOW.match(lines[1]), lines
        assert "in flight discarded" in lines[1], lines  # stopped at once, not after the shards
    elif case == "group SIGTERM, then main SIGTERM":  # the second may come after the shards finished
        assert 1 <= len(lines) <= 2 and STOPPING.match(lines[0]), lines
        assert len(lines) == 1 or STOPPED_NOW.match(lines[1]), lines
    elif case == "SIGTERM to a worker":  # the other worker may be between shards: then nothing is in flight
        assert len(lines) == 1 and (WORKER_STOPPING.match(lines[0]) or STOPPED.match(lines[0])), lines


CASES = {"one SIGINT": 130, "two SIGINTs": 130, "group SIGTERM": 143, "group SIGTERM, then main SIGTERM": 143,
         "SIGTERM to a worker": 143, "SIGHUP": 129}


@pytest.mark.slow
@pytest.mark.parametrize("case", [c for c in CASES if c != "group SIGTERM, then main SIGTERM"])  # render's
def test_generate_stops_on_signals_and_resumes_to_the_same_bytes(cfg, reference, tmp_path, case):
    out = str(tmp_path / "ds")
    run = Run("generate", *_cli_args(cfg), "--out", out, "--workers", "2", "--quiet")
    _rendering(run, out)
    _send(run, case, out)
    took = run.end()
    print(f"generate, {case}: stopped in {took:.2f} s, exit {run.p.returncode}: {run.stderr}")
    assert run.p.returncode == CASES[case], (run.p.returncode, run.stderr)
    _assert_said(case, run.stderr)
    _assert_finished_in_flight(run, case, out)
    _assert_nothing_left(run.pgid)
    assert not os.path.exists(os.path.join(out, "dataset.json"))  # it stopped before the end
    _assert_whole(out)
    generate(cfg, out, workers=2, resume=True, progress=False)
    assert data_files(out) == data_files(reference)
    assert not [f for f in tmp_files(out) if "shard-" in f]  # the resumed shards removed what the stop left


@pytest.mark.slow
@pytest.mark.parametrize("case", ["one SIGINT", "group SIGTERM, then main SIGTERM"])  # the others: generate's
def test_render_stops_on_signals_and_renders_the_rest_to_the_same_bytes(cfg, reference, tmp_path, case):
    out = str(tmp_path / "ds")
    plan_dataset(cfg, out)
    run = Run("render", out, "--workers", "2", "--quiet")
    _rendering(run, out)
    _send(run, case, out)
    took = run.end()
    print(f"render, {case}: stopped in {took:.2f} s, exit {run.p.returncode}: {run.stderr}")
    assert run.p.returncode == CASES[case], (run.p.returncode, run.stderr)
    _assert_said(case, run.stderr)
    _assert_finished_in_flight(run, case, out)
    _assert_nothing_left(run.pgid)
    _assert_whole(out)
    render_shards(out, workers=2, progress=False)
    finalize(out)
    assert data_files(out) == data_files(reference)


def test_a_stop_while_planning_is_at_once_and_writes_no_plan(demo_corpus, tmp_path):
    # enough scenes that planning takes seconds on the planning pool
    out = str(tmp_path / "ds")
    run = Run("plan", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", out, "--split", "train=15000",
              "--split", "val=0", "--split", "test=0", "--set", "audio.duration=1.0", "--workers", "2", "--allow-reuse")
    run.until(lambda: len(_children(run.p.pid)) >= 2, "planning on 2 workers")
    run.signal_group(signal.SIGINT)
    took = run.end()
    print(f"plan, one SIGINT: stopped in {took:.2f} s: {run.stderr}")
    assert run.p.returncode == 130, (run.p.returncode, run.stderr)
    assert len(run.stderr) == 1 and run.stderr[0].startswith("stopped (SIGINT); run it again"), run.stderr
    _assert_nothing_left(run.pgid)
    assert not os.path.exists(os.path.join(out, "plan", "config.json"))


@pytest.mark.slow
def test_corpus_prepare_finishes_the_clips_in_flight_then_stops(tmp_path):
    from tsel_data.corpus.demo import synth_corpus

    corpus = str(tmp_path / "corpus")
    synth_corpus(corpus, seed=1, clips_per_type=(6, 1, 1))
    cache = str(tmp_path / "prepared")
    env = {**os.environ, "TSEL_CLIP_CACHE": cache}
    args = ("corpus", "prepare", "--preset", "demo", "--corpus-dir", corpus, "--workers", "2", "--quiet")

    def prepared() -> int:
        return sum(len(fs) for _, _, fs in os.walk(cache)) if os.path.isdir(cache) else 0

    run = Run(*args, env=env)
    run.until(lambda: prepared() >= 2 and len(_children(run.p.pid)) >= 2, "preparing clips")
    run.signal_group(signal.SIGTERM)
    took = run.end()
    print(f"corpus prepare, group SIGTERM: stopped in {took:.2f} s: {run.stderr}")
    assert run.p.returncode == 143, (run.p.returncode, run.stderr)
    assert len(run.stderr) == 1 and (STOPPING.match(run.stderr[0]) or STOPPED.match(run.stderr[0])), run.stderr
    _assert_nothing_left(run.pgid)
    again = subprocess.run([sys.executable, "-m", "tsel_data.cli", *args], env=env, capture_output=True, text=True,
                           timeout=300)
    assert again.returncode == 0, again.stderr
    kept = int(re.search(r"\((\d+) already were\)", again.stdout).group(1))
    assert kept > 0, again.stdout  # what the stopped run prepared is whole, and used


@pytest.mark.slow
def test_the_dask_local_cluster_is_closed_on_a_stop(cfg, reference, tmp_path):
    pytest.importorskip("dask.distributed")
    out = str(tmp_path / "ds")
    run = Run("generate", *_cli_args(cfg), "--out", out, "--workers", "2", "--quiet", "--executor", "dask-local")
    run.until(lambda: _sealed(out) >= 1, "rendering on the cluster", timeout=120)
    run.signal_group(signal.SIGINT)
    run.until(lambda: any(STOPPING.match(x) for x in run.stderr), "said it is stopping")
    run.signal_group(signal.SIGINT)
    took = run.end()
    ours = [x for x in run.stderr if x.startswith(("stopping", "stopped"))]  # dask logs its workers' ends
    print(f"generate --executor dask-local, two SIGINTs: stopped in {took:.2f} s: {ours}")
    assert run.p.returncode == 130, (run.p.returncode, run.stderr)
    assert STOPPING.match(ours[0]) and "Traceback" not in "\n".join(run.stderr), run.stderr
    assert len(ours) == 1 or (len(ours) == 2 and STOPPED_NOW.match(ours[1])), ours
    _assert_nothing_left(run.pgid)
    generate(cfg, out, workers=2, resume=True, progress=False)
    assert data_files(out) == data_files(reference)


DATALOADER = textwrap.dedent("""
    import sys
    import torch
    from tsel_data.job.onthefly import scene_source
    from tsel_data.tools.torch import Dataset, collate, worker_init_fn

    source = scene_source(preset="demo", split="train", home=sys.argv[1], corpus_dir=sys.argv[2],
                          splits={"train": 400, "val": 0, "test": 0}, overrides=["audio.duration=3.0"])
    loader = torch.utils.data.DataLoader(Dataset(source), batch_size=1, num_workers=2, collate_fn=collate,
                                         worker_init_fn=worker_init_fn)
    for i, _ in enumerate(loader):
        print(i, flush=True)
""")


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_on_the_fly_dataloader_workers_end_with_the_run(demo_corpus, tmp_path, sig):
    pytest.importorskip("torch")
    run = Run(argv=[sys.executable, "-c", DATALOADER, str(tmp_path / "home"), demo_corpus])
    run.until(lambda: len(run.stdout) >= 2 and len(_children(run.p.pid)) >= 2, "loading scenes on 2 workers",
              timeout=180)
    run.signal_group(sig)
    took = run.end()
    print(f"on-the-fly DataLoader, group {sig.name}: ended in {took:.2f} s")
    assert run.p.returncode != 0
    _assert_nothing_left(run.pgid)
