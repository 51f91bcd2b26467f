"""Reliability: `tsel check` (configs and datasets), atomic and resumable writes under
SIGKILL, full disks and unwritable folders, determinism in any shard order, a memory
soak, and property-based tests of the config loader."""
from __future__ import annotations

import copy
import errno
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from dataclasses import fields
from importlib import resources

import h5py
import numpy as np
import pytest

from support.configs import TINY
from support.files import patience, tmp_files
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tsel_data.config import check_raw_config
from tsel_data.job.preflight import check_config
from tsel_data.store.check import check_dataset
from tsel_data.config import SECTIONS, TOP_KEYS, SplitConfig, load_config, parse_config
from tsel_data.scene.distributions import KINDS
from tsel_data.errors import ConfigError, DatasetError, GeometryError
from tsel_data.job.pipeline import finalize, generate, plan_dataset, render_shards
from tsel_data.core import atomic
from tsel_data.store import writer
from tsel_data.core.digest import sha256_file

BOOT = ("from tsel_data.cli import cli, main\n"
        "if 'check' not in cli.commands:\n"
        "    from tsel_data.cli.check import check_cmd\n"
        "    cli.add_command(check_cmd)\n"
        "main()\n")
SMALL = TINY


def tsel(*args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", BOOT, *args], capture_output=True, text=True, **kw)


def files(d) -> dict:
    """sha256 of every file under d but the demo corpus, temporary files and shard seals
    (seals record file times)."""
    out = {}
    for root, _, names in os.walk(d):
        for f in names:
            rel = os.path.relpath(os.path.join(root, f), d)
            if rel.startswith("demo-corpus") or ".tmp" in f or f.endswith(".seal.json"):
                continue
            out[rel] = sha256_file(os.path.join(root, f))
    return out


@pytest.fixture
def cfg(generated_dataset):
    return generated_dataset("tiny").cfg


@pytest.fixture
def dataset(generated_dataset):
    return generated_dataset("tiny").out


# --- tsel check DIR -------------------------------------------------------------------------------


def test_check_dataset_passes_on_a_fresh_dataset(dataset):
    rep = check_dataset(dataset)
    assert rep.ok, rep.messages()
    assert rep.facts["splits"] == {"train": {"scenes": 4, "shards": 2}, "val": {"scenes": 2, "shards": 1},
                                   "test": {"scenes": 2, "shards": 1}}
    assert not rep.warnings
    r = tsel("check", dataset)
    assert r.returncode == 0 and "OK" in r.stdout and not r.stderr, r.stderr
    r = tsel("check", dataset, "--json", "--no-audio")
    doc = json.loads(r.stdout)
    assert doc["ok"] and doc["errors"] == [] and doc["facts"]["splits"]["val"] == {"scenes": 2, "shards": 1}


def _copy(dataset, tmp_path) -> str:
    d = str(tmp_path / "copy")
    shutil.copytree(dataset, d, ignore=shutil.ignore_patterns("demo-corpus"))
    return d


def _rehash(d, rel):
    """Record rel's new sha256 in dataset.json, so only the content checks can notice an edit."""
    doc = json.load(open(os.path.join(d, "dataset.json")))
    for s in doc["splits"].values():
        for sh in s["shards"]:
            if sh["json"] == rel:
                sh["json_sha256"] = sha256_file(os.path.join(d, rel))
    json.dump(doc, open(os.path.join(d, "dataset.json"), "w"))


def test_check_dataset_finds_tampering(dataset, tmp_path):
    d = _copy(dataset, tmp_path)
    h5 = os.path.join(d, "train", "shard-00001.h5")
    data = bytearray(open(h5, "rb").read())
    data[-100] ^= 0xFF
    open(h5, "wb").write(bytes(data))
    os.remove(os.path.join(d, "val", "shard-00000.json"))
    js_rel = "test/shard-00000.json"
    js = json.load(open(os.path.join(d, js_rel)))
    js["scenes"][1]["sources"][0]["azimuth"][7] += 5.0
    json.dump(js, open(os.path.join(d, js_rel), "w"))
    _rehash(d, js_rel)
    open(os.path.join(d, "train", "shard-00000.h5.tmp-12345"), "wb").write(b"partial")
    rep = check_dataset(d, workers=2)
    msgs = rep.messages()
    assert len(msgs) == 3, msgs
    assert any("train/shard-00001.h5: sha256 differs" in m for m in msgs)
    assert any("val/shard-00000.json: listed in dataset.json but missing" in m for m in msgs)
    assert any("test/shard-00000.json" not in m and "scene test-000001 source 0: azimuth labels differ" in m
               for m in msgs)
    assert rep.warnings == ["train/shard-00000.h5.tmp-12345: leftover temporary file of an interrupted write; "
                            "safe to delete"]
    r = tsel("check", d, "--workers", "1")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len([x for x in r.stderr.splitlines() if x.startswith("error: ")]) == 3


def test_check_dataset_counts_and_unfinished_runs(dataset, tmp_path):
    d = _copy(dataset, tmp_path)
    doc = json.load(open(os.path.join(d, "dataset.json")))
    doc["splits"]["train"]["scenes"] = 5
    doc["splits"]["val"]["shards"] = []
    json.dump(doc, open(os.path.join(d, "dataset.json"), "w"))
    msgs = check_dataset(d).messages()
    assert any("split train lists 5 scenes but its shards hold 4" in m for m in msgs)
    assert any("split val holds 0 scenes but the config asks for 2" in m for m in msgs)
    assert any("val: the plan (plan/val.jsonl) has 2 scenes, the shards 0" in m for m in msgs)
    assert any("val/shard-00000.h5: not listed in dataset.json" in w for w in check_dataset(d).warnings)
    # an interrupted run: a plan, some shards, no dataset.json
    os.remove(os.path.join(d, "dataset.json"))
    os.remove(os.path.join(d, "test", "shard-00000.h5"))
    rep = check_dataset(d)
    assert rep.messages() == [f"{d}: unfinished dataset (no dataset.json): 3 of 4 shards rendered; continue with "
                              f"`tsel generate ... --resume` or `tsel render {d}` then `tsel finalize {d}`"]
    assert "not a dataset" in check_dataset(str(tmp_path)).messages()[0]
    r = tsel("check", d)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "3 of 4 shards" in r.stderr


# --- tsel check CONFIG ------------------------------------------------------------------------------


def test_check_config_plans_everything_in_memory(cfg, tmp_path):
    rep = check_config(cfg, out_dir=str(tmp_path / "new"), workers=1)
    assert rep.ok, rep.messages()
    s = rep.facts["splits"]
    assert s["train"]["planned"] == 4 and s["train"]["clips"] == 60 and s["val"]["planned"] == 2
    assert rep.facts["estimated_bytes"] > 8 * 4 * 24000 * 4
    assert not os.path.exists(tmp_path / "new")  # checking writes nothing


def test_check_config_sees_an_old_plan_and_collects_problems(cfg, dataset, tmp_path):
    other = load_config(preset="demo", overrides=SMALL, corpus_dir=cfg.corpus.dir, seed=3,
                        splits={"train": 4, "val": 2, "test": 2})
    msgs = check_config(other, out_dir=dataset).messages()
    assert msgs == [f"{dataset} was planned with a different config ({dataset}/plan/config.json: seed (planned 0, "
                    f"now 3)); choose another --out, use the same config to --resume, or --grow if only "
                    f"splits.NAME.count grew"]
    assert "already holds this finished dataset" in check_config(cfg, out_dir=dataset).warnings[0]
    # several independent problems are reported together
    bad = load_config(preset="demo", corpus_dir=str(tmp_path), splits={"train": 2, "val": 0, "test": 0},
                      overrides=['room.length=["uniform", 1.5, 9.0]', 'sources.height=["uniform", 4.9, 5.0]'],
                      validate=False)
    msgs = check_config(bad).messages()
    assert len(msgs) == 3, msgs
    assert "room.length minimum 1.5 m" in msgs[0] and "sources.height minimum 4.9" in msgs[1]
    assert f"splits.train.manifest: train.csv not found in {tmp_path}" in msgs[2]
    with pytest.raises(GeometryError, match=r"and 2 more problem"):
        check_config(bad).raise_for_errors()


# --- atomic, resumable writes ---------------------------------------------------------------------

KILL_ARGS = ["--preset", "demo", "--split", "train=48", "--split", "val=6", "--split", "test=6",
             "--set", "audio.duration=2.0", "--set", "output.shard_size=3", "--quiet", "--resume"]


def _assert_no_partial_final_files(out):
    """Whatever survived a kill under a final name is whole."""
    for root, _, names in os.walk(out):
        for f in names:
            p = os.path.join(root, f)
            if ".tmp" in f or "demo-corpus" in p:
                continue
            if f.endswith(".h5"):
                with h5py.File(p, "r") as h:
                    assert h["audio"].shape[0] == len(h["scene_id"]) == 3, p
                    assert np.all(np.isfinite(h["audio"][-1]))
            elif f.endswith(".json"):
                json.load(open(p, encoding="utf-8"))
    if os.path.exists(os.path.join(out, "plan", "config.json")):
        for split, n in (("train", 48), ("val", 6), ("test", 6)):
            assert sum(1 for _ in open(os.path.join(out, "plan", f"{split}.jsonl"))) == n


def _progress(out) -> str:
    if not os.path.exists(os.path.join(out, "plan", "config.json")):
        return "unplanned"
    if os.path.exists(os.path.join(out, "dataset.json")):
        return "finished"
    n = sum(f.endswith(".h5") for _, _, names in os.walk(out) for f in names)
    return f"{n}/20 shards"


@pytest.mark.slow
def test_sigkill_at_random_moments_then_resume_gives_identical_files(demo_corpus, tmp_path):
    args = [*KILL_ARGS, "--corpus-dir", demo_corpus]
    ref = str(tmp_path / "ref")
    t0 = time.monotonic()
    r = tsel("generate", *args, "--out", ref, "--workers", "2")
    t_ref = time.monotonic() - t0
    assert r.returncode == 0, r.stderr
    out = str(tmp_path / "killed")
    rng = random.Random(5)
    kills = 0
    stages = []

    def shards():
        return sum(f.endswith(".h5") for _, _, names in os.walk(out) for f in names)

    for k in range(6):
        # kill moments spread over every stage: start-up and planning, right after the
        # plan is written, then mid-render a few shards further each time
        if k == 0:
            ready, jitter = (lambda: True), rng.uniform(0.1, 0.6)
        elif k == 1:
            ready, jitter = (lambda: os.path.exists(os.path.join(out, "plan", "config.json"))), rng.uniform(0, 0.2)
        else:
            target = shards() + rng.randint(1, 4)
            ready, jitter = (lambda: shards() >= target), rng.uniform(0, 0.15)
        workers = 2 if k % 2 == 0 else 1
        p = subprocess.Popen([sys.executable, "-c", BOOT, "generate", *args, "--out", out, "--workers", str(workers)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
        deadline = time.monotonic() + patience(60)
        while p.poll() is None and not ready() and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(jitter)
        if p.poll() is None:
            # a scheduler kills the whole job (the pool's workers too); OOM kills one process
            os.killpg(p.pid, signal.SIGKILL) if workers > 1 else p.kill()
            kills += 1
        p.wait()
        _assert_no_partial_final_files(out)
        stages.append(_progress(out))
    print(f"kill test: reference {t_ref:.1f} s; after each kill: {stages}")
    assert kills >= 5, (kills, stages)
    r = tsel("generate", *args, "--out", out, "--workers", "2")
    assert r.returncode == 0, r.stderr
    assert files(out) == files(ref)
    assert not [f for f in tmp_files(out) if "shard-" in f]  # resumed shards cleaned their leftovers
    assert check_dataset(out).ok


def _readonly(path):
    """Make a folder unwritable even for root (chattr +i); returns the undo function."""
    if os.geteuid() != 0:
        os.chmod(path, 0o555)
        return lambda: os.chmod(path, 0o755)
    if shutil.which("chattr") is None or subprocess.run(["chattr", "+i", str(path)],
                                                        capture_output=True).returncode != 0:
        pytest.skip("running as root and chattr +i is unavailable: cannot make a read-only folder")
    return lambda: subprocess.run(["chattr", "-i", str(path)], check=True)


def test_unwritable_output_is_a_clear_error_and_leaves_nothing(demo_corpus, tmp_path):
    base = ["--preset", "demo", "--corpus-dir", demo_corpus, "--split", "train=4", "--split", "val=2", "--split",
            "test=0", "--set", "audio.duration=1.0", "--set", "output.shard_size=2", "--workers", "1"]
    ro = tmp_path / "ro"
    ro.mkdir()
    undo = _readonly(ro)
    try:
        r = tsel("generate", *base, "--out", str(ro / "ds"), "--quiet")
        assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
        assert str(ro / "ds") in r.stderr and ("not permitted" in r.stderr or "Permission denied" in r.stderr)
        assert os.listdir(ro) == []
    finally:
        undo()
    # the plan is written, then the shard folder turns read-only: render fails cleanly, resumes later
    out = tmp_path / "out"
    assert tsel("plan", *base, "--out", str(out)).returncode == 0
    (out / "train").mkdir()
    undo = _readonly(out / "train")
    try:
        r = tsel("render", str(out), "--quiet", "--workers", "1")
        assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
        assert "error: cannot write train/shard-00000." in r.stderr
        assert "is not writable; fix its permissions or choose another --out" in r.stderr
        assert os.listdir(out / "train") == []
    finally:
        undo()
    assert tsel("render", str(out), "--quiet", "--workers", "1").returncode == 0
    assert tsel("finalize", str(out)).returncode == 0
    assert check_dataset(str(out)).ok


@pytest.mark.parametrize("stage", ["json", "h5"])
def test_full_disk_is_a_clear_error_and_resume_completes(cfg, dataset, tmp_path, monkeypatch, stage):
    out = str(tmp_path / "full")
    plan_dataset(cfg, out)  # the plan is written first; the disk fills while shards are written
    calls = {"n": 0}

    def no_space(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    if stage == "json":  # the disk fills while the 2nd shard's JSON is flushed
        real = os.fsync

        def fsync(fd):
            calls["n"] += 1
            if calls["n"] == 4:  # shard 0: json, h5 and seal fsyncs; then shard 1's json
                no_space()
            return real(fd)
        monkeypatch.setattr(writer.os, "fsync", fsync)
        monkeypatch.setattr(atomic, "_fsync_dir", lambda p: None)
        monkeypatch.setattr(writer, "_fsync_dir", lambda p: None)
        failing = "train/shard-00001.json"
    else:  # the disk fills in the middle of the 2nd shard's HDF5 file
        real = writer._stack_padded

        def stack(*a, **k):
            calls["n"] += 1
            if calls["n"] == 5:  # 4 label arrays per shard
                no_space()
            return real(*a, **k)
        monkeypatch.setattr(writer, "_stack_padded", stack)
        failing = "train/shard-00001.h5"
    with pytest.raises(DatasetError) as ei:
        generate(cfg, out, workers=1, progress=False, resume=True)
    msg = str(ei.value)
    assert msg.startswith(f"cannot write {failing}: disk full; no space left on the device") and "--resume" in msg
    assert "\n" not in msg
    assert os.path.isfile(os.path.join(out, "train", "shard-00000.h5"))
    assert not os.path.exists(os.path.join(out, "train", "shard-00001.h5"))
    assert tmp_files(out) == []
    assert not os.path.exists(os.path.join(out, "dataset.json"))
    monkeypatch.undo()
    generate(cfg, out, workers=1, resume=True, progress=False)
    assert files(out) == files(dataset)


def test_stale_temporary_files_of_dead_writers_are_removed(tmp_path):
    target = str(tmp_path / "shard-00000.h5")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(dead.stdout)
    for pid in (dead_pid, os.getppid(), os.getpid()):
        open(f"{target}.tmp-{pid}", "wb").write(b"x")
    open(str(tmp_path / "shard-00001.h5.tmp-1"), "wb").write(b"other shard")
    removed = atomic.remove_stale_tmp(target)
    assert sorted(removed) == sorted([f"{target}.tmp-{dead_pid}", f"{target}.tmp-{os.getpid()}"])
    assert os.path.exists(f"{target}.tmp-{os.getppid()}")  # a live writer's file is kept
    assert os.path.exists(str(tmp_path / "shard-00001.h5.tmp-1"))


# --- determinism ---------------------------------------------------------------------------------


def test_shards_rendered_in_reverse_order_give_the_same_bytes(cfg, dataset, tmp_path):
    out = str(tmp_path / "rev")
    plan_dataset(cfg, out)
    n = 4
    for i in reversed(range(n)):
        render_shards(out, shards=range(i, i + 1), workers=1, progress=False)
    finalize(out)
    assert files(out) == files(dataset)


def test_plan_is_the_same_on_any_number_of_workers(cfg):
    from tsel_data.plan.catalog import build_catalog
    from tsel_data.plan.sampler import CatalogView, plan_split_json

    big = load_config(preset="demo", corpus_dir=cfg.corpus.dir, splits={"train": 300, "val": 0, "test": 0})
    cat = CatalogView(build_catalog(big, big.corpus.dir).clips["train"])
    one = plan_split_json(big, "train", cat, workers=1, chunk=70)
    two = plan_split_json(big, "train", cat, workers=2, chunk=70)
    assert one == two and len(one) == 300
    assert plan_split_json(big, "train", cat, workers=1, chunk=1000)[123] == one[123]


# --- soak ------------------------------------------------------------------------------------


def _rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="needs /proc")
def test_soak_1000_scenes_memory_stays_flat(demo_corpus, tmp_path, monkeypatch):
    import tsel_data.job.shards as gen

    cfg = load_config(preset="demo", corpus_dir=demo_corpus, splits={"train": 1000, "val": 0, "test": 0},
                      overrides=["audio.duration=1.0", "audio.fs=8000", "output.shard_size=20",
                                 'room.rt60=["uniform", 0.15, 0.25]', 'room.rir_method="hybrid"'])
    rss = []
    real = gen.render_shard

    def measured(*a, **k):
        n = real(*a, **k)
        rss.append(_rss_bytes())
        return n

    monkeypatch.setattr(gen, "render_shard", measured)
    out = str(tmp_path / "soak")
    t0 = time.perf_counter()
    s = generate(cfg, out, workers=1, progress=False, allow_reuse=True)  # 1000 scenes of 60 clips, on purpose
    seconds = time.perf_counter() - t0
    assert s["splits"]["train"] == 1000 and len(rss) == 50
    q = len(rss) // 4
    first, last = np.median(rss[5:q + 5]), np.median(rss[-q:])
    growth_mb = (last - first) / 1e6
    print(f"soak: 1000 scenes in {seconds:.1f} s, RSS {first / 1e6:.1f} -> {last / 1e6:.1f} MB "
          f"(growth {growth_mb:.2f} MB, max {max(rss) / 1e6:.1f} MB)")
    assert growth_mb < 8.0, rss
    assert max(rss) - min(rss[5:]) < 40e6


# --- property-based: the config loader ----------------------------------------------------------


def load_raw(raw):
    """The loader as `tsel` runs it: structural checks (check.check_raw_config), then parse_config."""
    check_raw_config(raw)
    return parse_config(raw)


_scalar = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=6))
_any = st.recursive(_scalar, lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=5), c, max_size=3),
                    max_leaves=6)
_num = st.one_of(st.integers(-5, 30), st.floats(-5, 30), st.floats(), st.integers())
_dist = st.one_of(
    _num,
    st.tuples(st.sampled_from(KINDS + ("gauss",)), _num, _num).map(list),
    st.tuples(st.just("choose"), st.lists(st.one_of(_num, st.text(max_size=4)), max_size=3)).map(list),
    st.tuples(st.just("truncnorm"), _num, _num, _num, _num).map(list),
)
_value = st.one_of(_any, _dist)


def _section(cls):
    names = [f.name for f in fields(cls)]
    return st.dictionaries(st.one_of(st.sampled_from(names), st.text(max_size=6)), _value, max_size=4)


_raw = st.one_of(
    st.fixed_dictionaries({}, optional={
        **{s: st.one_of(_section(c), _any) for s, c in SECTIONS.items()},
        "splits": st.one_of(st.dictionaries(st.text(max_size=5), st.one_of(_section(SplitConfig), _any), max_size=3),
                            _any),
        "seed": st.one_of(st.integers(), _any), "name": _any,
        "on_bad_clip": st.one_of(st.sampled_from(["skip", "fail"]), _any)}),
    st.dictionaries(st.one_of(st.sampled_from(TOP_KEYS), st.text(max_size=6)), _value, max_size=4),
)
PROPERTY = settings(max_examples=400, deadline=None, suppress_health_check=list(HealthCheck))
_DEMO = tomllib.loads((resources.files("tsel_data.config.presets") / "demo.toml").read_text(encoding="utf-8"))
_KEYS = ([(s, f.name) for s, c in SECTIONS.items() for f in fields(c)]
         + [(None, "seed"), (None, "on_bad_clip"), (None, "name"), ("splits.train", "count"),
            ("splits.train", "manifest"), ("splits.val", "rooms")])
_PLAUSIBLE = st.one_of(_value, st.floats(0, 20), st.integers(0, 100), st.sampled_from(
    ["mic4", "foa", "tetra", "static", "moving", "mixed", "hybrid", "ism", "full", "none", "skip", "fail",
     "two-directional", "directional+additive"]))
_SET_VALUES = st.sampled_from(
    ["inf", "nan", "-inf", "-1", "0", "1e400", "1e300", "[]", "{}", "[1,2]", "true", '"x"', '["uniform", 2, 1]',
     '["choose", []]', '["choose", [1], [0]]', '["truncnorm", 0, -1, 0, 1]', "{a = 1}", "2", "0.5",
     "99999999999999999999999"]) | st.text(max_size=8)


def _config_or_config_error(fn, *a, **k):
    try:
        cfg = fn(*a, **k)
    except ConfigError as e:
        assert "\n" not in str(e)
        return None
    # whatever loads must survive its own round trip (dataset.json stores cfg.to_dict())
    again = load_raw(json.loads(json.dumps(cfg.to_dict())))
    assert again.to_dict() == cfg.to_dict()
    return cfg


@PROPERTY
@given(_raw)
def test_config_loader_random_dicts_give_config_or_config_error(raw):
    _config_or_config_error(load_raw, raw)


@PROPERTY
@given(st.lists(st.tuples(st.sampled_from(_KEYS), _PLAUSIBLE), min_size=1, max_size=4))
def test_config_loader_mutated_preset_gives_config_or_config_error(mutations):
    raw = copy.deepcopy(_DEMO)
    for (sec, key), v in mutations:
        node = raw
        for part in (sec.split(".") if sec else []):
            node = node.setdefault(part, {})
        node[key] = v
    _config_or_config_error(load_raw, raw)


@PROPERTY
@given(st.lists(st.tuples(st.sampled_from([f"{s}.{k}" if s else k for s, k in _KEYS]
                                          + ["splits", "room", "splits.train", "splits.x.count"]), _SET_VALUES)
                .map(lambda t: f"{t[0]}={t[1]}") | st.text(max_size=16), min_size=1, max_size=3))
def test_config_loader_random_overrides_give_config_or_config_error(overrides):
    _config_or_config_error(load_config, preset="demo", overrides=overrides)


@pytest.mark.parametrize("override,message", [
    ("splits=inf", "splits must be a table"),
    ("splits=[1]", "splits must be a table"),
    ("audio.duration=inf", "audio.duration = inf is not a finite number"),
    ("audio.duration=nan", "is not a finite number"),
    ("room.rt60=1e400", "is not a finite number"),
    ("audio.duration=1e300", "out of range"),
])
def test_non_finite_and_misshapen_config_values(override, message):
    with pytest.raises(ConfigError, match=message):
        load_config(preset="demo", overrides=[override])
