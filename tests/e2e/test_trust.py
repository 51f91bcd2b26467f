"""A dataset can be trusted after anything (docs/reliability.md): every shard is the one
its plan asks for, whole; we write only what is ours, inside --out; a full disk is one
line; the pre-flight catches what render would trip on; never a hang or a traceback."""
import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
import soundfile as sf

from support.cli import one_line_error, tsel
from support.files import alive, children, data_files, patience
from tsel_data.config import load_config
from tsel_data.errors import ConfigError, DatasetError
from tsel_data.job.pipeline import finalize, generate, plan_dataset, render_shards
from tsel_data.store.lock import DatasetLock
from tsel_data.store.layout import Layout
from tsel_data.store.reader import open_dataset
from tsel_data.store.check import check_dataset

SMALL = ["audio.duration=1.0", "output.shard_size=2", 'room.rt60=["uniform", 0.2, 0.3]']
SPLITS = {"train": 4, "val": 0, "test": 2}


@pytest.fixture(scope="module")
def corpus(tmp_path_factory, demo_corpus):
    """A private copy of the demo corpus (tests here change clips)."""
    d = str(tmp_path_factory.mktemp("corpus") / "c")
    shutil.copytree(demo_corpus, d)
    return d


@pytest.fixture(scope="module")
def cfg(corpus):
    return load_config(preset="demo", corpus_dir=corpus, overrides=SMALL, splits=SPLITS)


@pytest.fixture(scope="module")
def reference(cfg, tmp_path_factory):
    out = str(tmp_path_factory.mktemp("ref") / "out")
    generate(cfg, out, workers=1, progress=False)
    return out


# --- 1. a finished shard is one this plan asked for, and only that ------------------------------


def test_a_bit_flip_is_rendered_again_on_resume_and_refused_by_finalize(cfg, reference, tmp_path):
    out = str(tmp_path / "ds")
    shutil.copytree(reference, out)
    h5 = os.path.join(out, "train", "shard-00001.h5")
    with open(h5, "r+b") as f:  # flip one bit deep in the audio
        f.seek(os.path.getsize(h5) // 2)
        b = f.read(1)
        f.seek(-1, os.SEEK_CUR)
        f.write(bytes([b[0] ^ 1]))
    assert not check_dataset(out).ok
    with pytest.raises(DatasetError, match=r"train/shard-00001.h5: h5 changed|shard-00001.h5 changed since"):
        finalize(out)
    generate(cfg, out, workers=1, progress=False, resume=True)
    assert check_dataset(out).ok and data_files(out) == data_files(reference)


def test_shards_of_another_renderer_are_rendered_again_on_resume(cfg, reference, tmp_path):
    """A dataset begun by an older tsel-data (its seals name renderer 1, or none) and
    resumed by this one is never a mix of the two: those shards are rendered again, and
    every seal and dataset.json then name this renderer."""
    from tsel_data.core.version import RENDERER
    out = str(tmp_path / "ds")
    shutil.copytree(reference, out)
    os.remove(os.path.join(out, "dataset.json"))
    old = os.path.join(out, "train", "shard-00000.seal.json")
    with open(old) as f:
        seal = json.load(f)
    assert seal["renderer"] == RENDERER
    del seal["renderer"]  # as renderer 1 (tsel-data 0.2.0) wrote it
    with open(old, "w") as f:
        json.dump(seal, f)
    before = os.stat(os.path.join(out, "train", "shard-00000.h5")).st_mtime_ns
    kept = os.stat(os.path.join(out, "train", "shard-00001.h5")).st_mtime_ns
    generate(cfg, out, workers=1, progress=False, resume=True)
    assert os.stat(os.path.join(out, "train", "shard-00000.h5")).st_mtime_ns != before
    assert os.stat(os.path.join(out, "train", "shard-00001.h5")).st_mtime_ns == kept
    with open(old) as f:
        assert json.load(f)["renderer"] == RENDERER
    with open(os.path.join(out, "dataset.json")) as f:
        assert json.load(f)["renderer"] == RENDERER
    assert check_dataset(out).ok and data_files(out) == data_files(reference)


def test_shards_of_another_config_are_never_adopted(cfg, reference, tmp_path):
    out = str(tmp_path / "ds")
    shutil.copytree(reference, out)
    shutil.rmtree(os.path.join(out, "plan"))
    os.remove(os.path.join(out, "dataset.json"))
    other = load_config(preset="demo", corpus_dir=cfg.corpus.dir, overrides=SMALL, splits=SPLITS, seed=1)
    generate(other, out, workers=1, progress=False)  # the leftover seed-0 shards do not verify: rendered again
    fresh = str(tmp_path / "fresh")
    generate(other, fresh, workers=1, progress=False)
    assert data_files(out) == data_files(fresh) and check_dataset(out).ok


def test_a_second_writer_is_locked_out(cfg, reference, tmp_path):
    out = str(tmp_path / "ds")
    plan_dataset(cfg, out)
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time\n"
                               f"fd = os.open({Layout(out).lock_file!r}, os.O_RDWR)\n"
                               "fcntl.flock(fd, fcntl.LOCK_EX); print('held', flush=True); time.sleep(60)"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(DatasetError, match="another tsel process is planning or finalizing"):
            render_shards(out, progress=False)
        other = load_config(preset="demo", corpus_dir=cfg.corpus.dir, overrides=SMALL, splits=SPLITS, seed=1)
        r = tsel("generate", "--preset", "demo", "--corpus-dir", cfg.corpus.dir, "--out", out, "--seed", "1",
                 *[x for o in SMALL for x in ("--set", o)], "--split", "train=4", "--split", "val=0", "--split", "test=2")
        one_line_error(r, "another tsel process")
        assert other.seed == 1
    finally:
        holder.kill()
        holder.wait()
    render_shards(out, progress=False)  # the lock dies with its holder
    finalize(out)
    assert data_files(out) == data_files(reference)


def _other_process_can_lock(root: str, exclusive: bool) -> bool:
    code = ("import sys; from tsel_data.store.lock import DatasetLock; from tsel_data.store.layout import Layout\n"
            f"try:\n    DatasetLock(Layout({root!r}), {exclusive}, 'x').__enter__()\n"
            "except Exception:\n    sys.exit(3)")
    return subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_an_exclusive_holder_reenters_its_lock_and_keeps_others_out_until_it_leaves(tmp_path):
    layout = Layout(str(tmp_path))
    with DatasetLock(layout, exclusive=True, what="generate it"):
        with DatasetLock(layout, exclusive=False, what="render it"):  # a stage of the same run
            pass
        # the inner stage left: the folder is still ours
        assert not _other_process_can_lock(str(tmp_path), exclusive=False)
        with DatasetLock(layout, exclusive=True, what="finalize it"):
            assert not _other_process_can_lock(str(tmp_path), exclusive=True)
    assert _other_process_can_lock(str(tmp_path), exclusive=True)


def test_two_concurrent_runs_never_mix_their_shards(cfg, tmp_path):
    out = str(tmp_path / "ds")
    base = ["generate", "--preset", "demo", "--corpus-dir", cfg.corpus.dir, "--out", out, "--quiet",
            "--workers", "1", *[x for o in SMALL for x in ("--set", o)], "--split", "train=4", "--split", "val=0",
            "--split", "test=2"]
    procs = [subprocess.Popen([sys.executable, "-m", "tsel_data.cli", *base, "--seed", str(s)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for s in (0, 1)]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    assert sum(rc == 0 for rc, _ in results) >= 1
    for rc, err in results:
        assert rc in (0, 2) and "Traceback" not in err, err
    # whatever won, what dataset.json says is what the shards hold
    assert check_dataset(out).ok
    doc = json.load(open(os.path.join(out, "dataset.json")))
    with open_dataset(out, "train") as ds:
        assert ds[0].record.seed is not None and doc["seed"] in (0, 1)
    plan_seed = json.load(open(os.path.join(out, "plan", "config.json")))["config"]["seed"]
    assert plan_seed == doc["seed"]


def test_a_changed_clip_renders_the_shards_that_read_it_again(cfg, reference, tmp_path):
    corpus = str(tmp_path / "corpus")
    shutil.copytree(cfg.corpus.dir, corpus)
    mine = load_config(preset="demo", corpus_dir=corpus, overrides=SMALL, splits=SPLITS)
    out = str(tmp_path / "ds")
    plan_dataset(mine, out)
    render_shards(out, shards=range(0, 1), progress=False)
    with open_dataset(reference, "train") as ds:
        clip = os.path.join(corpus, ds[0].record.sources[0].audio)  # records name clips relative to the corpus
    x, fs = sf.read(clip, dtype="float32")
    time.sleep(0.01)
    sf.write(clip, 0.5 * x, fs, subtype="FLOAT")  # the same clip, quieter: a changed corpus
    generate(mine, out, workers=1, progress=False, resume=True)
    fresh = str(tmp_path / "fresh")
    generate(mine, fresh, workers=1, progress=False)
    assert data_files(out) == data_files(fresh)  # shard 0 was rendered again from the new clip


def test_the_reader_refuses_swapped_shard_files(reference, tmp_path):
    out = str(tmp_path / "ds")
    shutil.copytree(reference, out)
    a, b = (os.path.join(out, "train", f"shard-0000{k}.h5") for k in (0, 1))
    os.rename(a, a + ".x")
    os.rename(b, a)
    os.rename(a + ".x", b)
    with open_dataset(out, "train") as ds, pytest.raises(DatasetError, match="do not hold the same scenes"):
        ds[0]


# --- 2. we write only what is ours, only inside --out ----------------------------------------------


@pytest.mark.parametrize("name", ["../../escaped", "/abs", "a/b", ".hidden", ""])
def test_split_names_are_plain_names(cfg, tmp_path, name):
    p = tmp_path / "c.toml"
    p.write_text(f'[splits."{name}"]\nmanifest = "train.csv"\ncount = 2\n')
    r = tsel("generate", "--preset", "demo", "--config", str(p), "--corpus-dir", cfg.corpus.dir,
             "--out", str(tmp_path / "out"))
    one_line_error(r, "is not a plain name")
    assert not os.path.exists(tmp_path / "out") and not os.path.exists(tmp_path.parent / "escaped")


def test_a_folder_that_is_not_ours_is_refused_without_force(cfg, tmp_path):
    out = tmp_path / "mine"
    (out / "plan").mkdir(parents=True)
    (out / "bad_clips.jsonl").write_text("my notes\n")
    (out / "plan" / "train.jsonl").write_text("my plan\n")
    args = ["generate", "--preset", "demo", "--corpus-dir", cfg.corpus.dir, "--out", str(out), "--quiet",
            *[x for o in SMALL for x in ("--set", o)], "--split", "train=2", "--split", "val=0", "--split", "test=0"]
    one_line_error(tsel(*args), "not a tsel-data dataset", "--force")
    assert (out / "bad_clips.jsonl").read_text() == "my notes\n" and (out / "plan" / "train.jsonl").read_text() == "my plan\n"
    one_line_error(tsel("check", "--preset", "demo", "--corpus-dir", cfg.corpus.dir, "--out", str(out), "--no-plan"),
                   "not a tsel-data dataset")
    r = tsel(*args, "--force")
    assert r.returncode == 0, r.stderr


def test_bank_outputs_are_not_overwritten_without_force(tmp_path):
    out = tmp_path / "bank.h5"
    out.write_bytes(b"precious")
    r = tsel("bank", "build", "--out", str(out), "--rooms", "1", "--step", "30", "--distances", "1.0",
             "--heights", "0")
    one_line_error(r, "already exists", "--force")
    assert out.read_bytes() == b"precious"
    r = tsel("bank", "build", "--out", str(out), "--rooms", "1", "--step", "30", "--distances", "1.0",
             "--heights", "0", "--force")
    assert r.returncode == 0 and out.read_bytes() != b"precious"


# --- 3. a real full disk is one line, everywhere ------------------------------------------------------


def _tmpfs(path, size="12m") -> bool:
    os.makedirs(path, exist_ok=True)
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return False
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                          capture_output=True).returncode == 0


@pytest.fixture
def small_disk(tmp_path):
    d = tmp_path / "disk"
    if not _tmpfs(d):
        pytest.skip("cannot mount a small tmpfs here (needs root)")
    yield d
    subprocess.run(["umount", "-l", str(d)], capture_output=True)


def test_a_real_full_disk_stops_render_in_one_line_and_resume_completes(cfg, small_disk):
    out = small_disk / "ds"
    common = ["--preset", "demo", "--corpus-dir", cfg.corpus.dir, "--set", "audio.duration=3.0",
              "--set", "output.shard_size=2", "--set", 'room.rt60=["uniform", 0.2, 0.3]', "--split", "val=0",
              "--split", "test=0"]
    # too big for the disk: the pre-flight says so before any work
    one_line_error(tsel("generate", *common, "--split", "train=40", "--out", str(out), "--quiet"), "GB free")
    # fits when planned (4 scenes, ~1.2 MB each), then something else fills the disk
    assert tsel("plan", *common, "--split", "train=4", "--out", str(out)).returncode == 0
    filler = small_disk / "filler"
    filler.write_bytes(b"\0" * int(shutil.disk_usage(small_disk).free - 3.2e6))  # room for one shard of two
    line = one_line_error(tsel("render", str(out), "--quiet", "--workers", "1"), "disk full")
    assert "run it again: finished shards are kept" in line and "--resume" not in line  # render has no --resume
    assert not [f for f in os.listdir(out / "train") if ".tmp-" in f]
    filler.unlink()
    assert tsel("render", str(out), "--quiet").returncode == 0
    assert tsel("finalize", str(out)).returncode == 0 and check_dataset(str(out)).ok


def test_tools_on_a_full_disk_leave_no_partial_file(reference, small_disk):
    filler = small_disk / "filler"
    filler.write_bytes(b"\0" * int(shutil.disk_usage(small_disk).free - 64e3))
    for args, target in ((["inspect", reference, "train/0", "--wav", str(small_disk / "x.wav")], "x.wav"),
                         (["inspect", reference, "train/0", "--png", str(small_disk / "x.png")], "x.png"),
                         (["stats", reference, "--png", str(small_disk / "s.png")], "s.png"),
                         (["export", "dcase", reference, "--out", str(small_disk / "exp"), "--quiet"], None),
                         (["corpus", "synth", "--out", str(small_disk / "corpus")], None)):
        r = tsel(*args)
        one_line_error(r, "cannot write")
        if target:
            assert not (small_disk / target).exists(), args
        leftovers = [os.path.join(d, f) for d, _, fs in os.walk(small_disk) for f in fs if ".tmp-" in f]
        assert not leftovers, leftovers


# --- 4. the pre-flight catches what render would trip on ------------------------------------------


def _corpus_with(tmp_path, name, writer, caption="a clip"):
    d = tmp_path / "corpus"
    (d / "audio").mkdir(parents=True, exist_ok=True)
    rows = ["audiocap_id,youtube_id,start_time,caption"]
    rng = np.random.default_rng(0)
    for i in range(3):
        sf.write(d / "audio" / f"ok{i}.wav", 0.1 * rng.standard_normal(16000).astype(np.float32), 16000)
        rows.append(f"{i},ok{i},0,a good clip number {i}")
    writer(d / "audio" / f"{name}.wav")
    rows.append(f"9,{name},0,{caption}")
    (d / "train.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    return str(d)


def _check(corpus, *extra):
    return tsel("check", "--preset", "demo", "--corpus-dir", corpus, "--set", "audio.duration=1.0",
                "--set", 'splits.train.manifest="train.csv"', "--set", 'on_bad_clip="fail"', "--split", "train=2",
                "--split", "val=0", "--split", "test=0", "--no-plan", *extra)


def _noise(path, fs=16000, channels=1):
    sf.write(path, 0.1 * np.random.default_rng(1).standard_normal((fs, channels)).astype(np.float32), fs)


@pytest.mark.parametrize("caption,needle", [("a dog\x00barks", "control characters (U+0000)"),
                                            ("\u200b\u200b\u200b", "no visible character")])
def test_captions_that_cannot_be_queries(tmp_path, caption, needle):
    corpus = _corpus_with(tmp_path, "odd", _noise, caption='"' + caption + '"')
    one_line_error(_check(corpus), "train.csv:5", needle)


@pytest.mark.parametrize("name,writer,needle", [
    ("cancel", lambda p: sf.write(p, np.stack([x := 0.3 * np.random.default_rng(2).standard_normal(16000), -x], 1)
                                  .astype(np.float32), 16000), "channels cancel"),
    ("ultra", lambda p: sf.write(p, (0.5 * np.sin(2 * np.pi * 20000 * np.arange(48000) / 48000)).astype(np.float32),
                                 48000), "no content below 12000 Hz"),
])
def test_clips_a_scene_would_not_hear(tmp_path, name, writer, needle):
    one_line_error(_check(_corpus_with(tmp_path, name, writer)), f"clip {name}_0", needle)


def test_a_wav_declaring_an_absurd_rate(tmp_path):
    def absurd(p):
        _noise(p)
        with open(p, "r+b") as f:  # the fmt chunk's sample rate field
            f.seek(24)
            f.write((3_000_000_000).to_bytes(4, "little"))
    line = one_line_error(_check(_corpus_with(tmp_path, "rate", absurd)), "rate_0")
    assert "sample rate" in line or "unreadable" in line


def test_a_huge_clip_is_checked_by_the_part_a_scene_uses(tmp_path):
    def huge(p):  # 60 s at 48 kHz, silent after its first second: only the first second is read
        x = np.zeros(48000 * 60, np.float32)
        x[:48000] = 0.1
        sf.write(p, x, 48000)
    r = _check(_corpus_with(tmp_path, "huge", huge))
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("damage,needle", [("nan", "holds NaN or Inf"), ("zero", "is all zero")])
def test_damaged_bank_rirs_are_named_before_any_work(tmp_path, demo_corpus, damage, needle):
    import h5py

    from tsel_data.banks.build import build_bank

    bank = tmp_path / "b.h5"
    build_bank(str(bank), format="foa", n_rooms=1, distances=(1.0,), heights=(0.0,), step_deg=30.0, rt60=(0.2, 0.2))
    with h5py.File(bank, "r+") as f:
        rirs = f["rooms/sim01/rirs"]
        rirs[...] = np.nan if damage == "nan" else 0.0
    r = tsel("check", "--preset", "demo-moving", "--corpus-dir", demo_corpus, "--bank", str(bank),
             "--set", "splits.train.rooms=[]", "--set", "splits.val.rooms=[]", "--set", "splits.test.rooms=[]",
             "--split", "train=2", "--split", "val=0", "--split", "test=0", "--no-plan")
    one_line_error(r, "b.h5: room sim01", needle)


@pytest.mark.parametrize("override,needle", [
    ("audio.activity_threshold_db=3.0", "activity_threshold_db must be >= -200 and < 0 dB"),
    ("array.side=0", "array.side must be > 0"),
    ("audio.label_hop=0.00001", "shorter than one sample"),
    ("audio.label_hop=1e-308", "--set audio.label_hop=1e-308: audio.label_hop 1e-308 s is shorter than one sample"),
    ('scene.interferers=["uniform", 1, 3]', "is a count"),
    ("audio.fs=1000000000", "audio.fs must be >= 8000 and <= 192000"),
])
def test_config_values_that_produce_nonsense(override, needle):
    with pytest.raises(ConfigError, match=needle):
        load_config(preset="demo", overrides=[override])


def test_a_bad_clip_met_only_at_render_is_recorded_and_the_run_goes_on(cfg, reference, tmp_path):
    corpus = str(tmp_path / "corpus")
    shutil.copytree(cfg.corpus.dir, corpus)
    mine = load_config(preset="demo", corpus_dir=corpus, overrides=SMALL + ['corpus.check="none"'], splits=SPLITS)
    out = str(tmp_path / "ds")
    plan_dataset(mine, out)
    with open_dataset(reference, "test") as ds:
        clip = os.path.join(corpus, ds[0].record.sources[0].audio)  # records name clips relative to the corpus
    good, fs = sf.read(clip, dtype="float32")
    sf.write(clip, np.zeros_like(good), fs, subtype="FLOAT")  # silent now: the check let it through
    with pytest.raises(DatasetError, match=r"1 shard\(s\) could not be rendered.*test/shard-00000.h5.*silent"):
        render_shards(out, progress=False)
    assert os.path.isfile(os.path.join(out, "train", "shard-00001.seal.json"))  # the others were rendered
    sf.write(clip, good, fs, subtype="FLOAT")  # fixed: resume completes
    render_shards(out, progress=False)
    finalize(out)
    assert check_dataset(out).ok


# --- 5. never a hang, never a traceback, always one line --------------------------------------------


@pytest.mark.parametrize("what", ["manifest", "predictions"])
def test_special_files_are_refused_not_read(tmp_path, reference, what):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    if what == "manifest":
        corpus = tmp_path / "c"
        corpus.mkdir()
        os.mkfifo(corpus / "train.csv")
        r = tsel("check", "--preset", "paper-sim-2dir", "--corpus-dir", str(corpus), "--split", "train=2",
                 "--split", "val=0", "--split", "test=0", timeout=60)
        one_line_error(r, "not a regular file")
    else:
        r = tsel("eval", reference, "--pred", str(fifo), "--split", "test", timeout=60)
        one_line_error(r, "not a regular file")


def test_sigterm_stops_the_workers(cfg, tmp_path):
    out = str(tmp_path / "ds")
    p = subprocess.Popen([sys.executable, "-m", "tsel_data.cli", "generate", "--preset", "demo", "--corpus-dir",
                          cfg.corpus.dir, "--out", out, "--quiet", "--workers", "2", "--split", "train=400",
                          "--split", "val=0", "--split", "test=0", "--set", "output.shard_size=2",
                          "--allow-reuse"],  # minutes of work: it is stopped long before its end, on any machine
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.time() + patience(120)
        while time.time() < deadline and p.poll() is None and not children(p.pid):
            time.sleep(0.2)
        kids = children(p.pid)
        assert kids, f"the pool never started (exit {p.poll()}: {p.stderr.read().decode()[-300:] if p.poll() else ''})"
        time.sleep(1.0)
        p.terminate()
        p.wait(timeout=patience(60))
    finally:  # a failed test leaves no run going on behind it
        if p.poll() is None:
            p.kill()
            p.wait()
    gone = time.time() + patience(10)  # workers leave once they see the run is gone
    while time.time() < gone and any(alive(k) for k in kids):
        time.sleep(0.1)
    left = [k for k in kids if alive(k)]
    assert not left, f"workers outlived the run: {left}"


@pytest.mark.parametrize("args,needles", [
    (["check", "--preset", "demo", "--set", "splits.train=5", "--split", "train=3"], ["splits.train is set to a value"]),
    (["generate", "--bogus"], ["No such option", "tsel generate --help"]),
    (["check", "--preset", "demo", "--set", "scene.x\ny=1"], ["scene.'x\\ny'"]),
])
def test_usage_mistakes_are_one_line(args, needles):
    one_line_error(tsel(*args), *needles)


def test_damaged_plan_lines_and_dataset_json_are_one_line(reference, tmp_path):
    out = str(tmp_path / "ds")
    shutil.copytree(reference, out)
    plan = os.path.join(out, "plan", "train.jsonl")
    lines = open(plan).read().splitlines()
    lines[1] = lines[1][: len(lines[1]) // 2]
    open(plan, "w").write("\n".join(lines) + "\n")
    one_line_error(tsel("render", out), "train.jsonl was edited after planning")
    doc = json.load(open(os.path.join(out, "dataset.json")))
    del doc["splits"]["train"]["shards"][0]["file"]
    json.dump(doc, open(os.path.join(out, "dataset.json"), "w"))
    one_line_error(tsel("stats", out), "dataset.json: incomplete or damaged")


@pytest.mark.parametrize("value,needle", [("true", "JSON numbers"), ('"12"', "JSON numbers"),
                                          ("1e308", "within"), ("[" + ",".join(["0"] * 360) + "]", "flat")])
def test_eval_refuses_values_that_are_not_predictions(reference, tmp_path, value, needle):
    key = "distribution" if value.startswith("[") else "azimuth"
    p = tmp_path / "p.jsonl"
    p.write_text("\n".join(f'{{"scene_id": "test-00000{i}", "{key}": {value}}}' for i in range(2)) + "\n")
    one_line_error(tsel("eval", reference, "--pred", str(p), "--split", "test"), "p.jsonl:1", needle)
    p.write_bytes(b'{"scene_id": "test-000000", "azimuth": 1.0}\n\xff\xfe\n')
    one_line_error(tsel("eval", reference, "--pred", str(p), "--split", "test"), "p.jsonl:2", "not UTF-8")


@pytest.mark.parametrize("template,needle", [("{youtube_id.__class__}.wav", "unknown field"),
                                             ("{youtube_id:>99999999}.wav", "format spec"),
                                             ("{youtube_id!r}.wav", "conversion")])
def test_audio_templates_allow_only_the_documented_fields(demo_corpus, tmp_path, template, needle):
    r = tsel("plan", "--preset", "demo", "--corpus-dir", demo_corpus, "--set",
             f"corpus.audio_template={json.dumps(template)}", "--out", str(tmp_path / "out"))
    one_line_error(r, needle)
    assert len(r.stderr) < 2000
