"""Bad input, through the CLI: one line (file, row, what, how to fix), exit 2, no traceback.

Every case builds a tiny AudioCaps-format corpus with one defect and runs
``tsel check`` and (where the same validation applies) ``tsel generate`` on it, through
the real entry point in this process (an exception that escapes is a traceback, as a
user would see it).
"""
from __future__ import annotations

import os
import subprocess

import h5py
import numpy as np
import pytest
import soundfile as sf

from support.cli import completed
from support.corpora import CAPTIONS, FS, make_corpus, tone

def run_all(*commands) -> list[subprocess.CompletedProcess]:
    return [completed(*c) for c in commands]


def common(corpus, *extra, fail=True):
    a = ["--preset", "demo", "--corpus-dir", str(corpus), "--split", "train=2", "--split", "val=0",
         "--split", "test=0", "--set", "audio.duration=1.0"]
    if fail:
        a += ["--set", 'on_bad_clip="fail"']
    return a + list(extra)


def assert_one_line_error(r, *needles):
    assert r.returncode == 2, (r.args, r.stdout, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("error: "), lines
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def _no_shards(out):
    for root, _, files in os.walk(out):
        assert not [f for f in files if f.endswith(".h5")], (root, files)


# --- defects -------------------------------------------------------------------------------
def _wav(c, cid):
    return os.path.join(c, "audio", f"{cid}.wav")


def _rewrite_csv(c, split, rows_text: bytes):
    with open(os.path.join(c, f"{split}.csv"), "wb") as f:
        f.write(rows_text)


def _csv_bytes(c, split) -> bytes:
    with open(os.path.join(c, f"{split}.csv"), "rb") as f:
        return f.read()


def _garbage(p):
    with open(p, "wb") as f:
        f.write(b"RIFF\x00\x01junk" + bytes(range(256)) * 4)


def _empty(p):
    open(p, "wb").close()


def _one_bad_sample(value):
    def write(p):
        x = tone(1, 2.0)
        x[500] = value
        sf.write(p, x, FS, subtype="FLOAT")
    return write


CLIP_DEFECTS = {
    # name: (write the defect to a wav path, needles of the problem)
    "missing-audio": (os.remove, ["audio file not found"]),
    "corrupt-audio": (_garbage, ["unreadable audio"]),
    "empty-file": (_empty, ["empty audio file", "(0 bytes)"]),
    "empty-wav": (lambda p: sf.write(p, np.zeros(0, np.float32), FS), ["empty audio file"]),
    "silent": (lambda p: sf.write(p, np.zeros(FS * 2, np.float32), FS), ["silent"]),
    "nan": (_one_bad_sample(np.nan), ["NaN or Inf"]),
    "inf": (_one_bad_sample(np.inf), ["NaN or Inf"]),
    "too-short": (lambda p: sf.write(p, tone(1, 0.4), FS),
                  ["0.400 s long", "shorter than corpus.min_duration = 1.0 s"]),
    "channels": (lambda p: sf.write(p, tone(1, 1.5, channels=12), FS), ["12 channels", "corpus.max_channels = 8"]),
}

MANIFEST_DEFECTS = {
    "malformed-row": (lambda c: _rewrite_csv(c, "train", _csv_bytes(c, "train") + b"999,zzz,0,a caption, with comma\n"),
                      ["train.csv:6", "malformed row", "5 fields", "double quotes"]),
    "bad-start-time": (lambda c: _rewrite_csv(c, "train", _csv_bytes(c, "train").replace(b"rainB,0", b"rainB,abc")),
                       ["train.csv:3", "start_time 'abc'"]),
    "not-utf8": (lambda c: _rewrite_csv(c, "train", _csv_bytes(c, "train").replace(b"metal", b"m\xe9tal")),
                 ["train.csv:3", "not UTF-8", "0xe9", "iconv"]),
    "empty-caption": (lambda c: _rewrite_csv(c, "train", _csv_bytes(c, "train").replace(b"church bells ring slowly", b"")),
                      ["train.csv:5", "empty caption", "write the caption or delete the row"]),
    "empty-manifest": (lambda c: _rewrite_csv(c, "train", b"audiocap_id,youtube_id,start_time,caption\n"),
                       ["train.csv", "no caption rows", "(the manifest is empty)"]),
    "missing-manifest": (lambda c: os.remove(os.path.join(c, "train.csv")),
                         ["splits.train.manifest: train.csv not found in", "corpus (it holds test.csv, val.csv)"]),
}

DEFECTS = {**{k: (lambda c, f=f: f(_wav(c, "dogA")), ["train.csv:2", "dogA", *n, "fix or remove it"])
              for k, (f, n) in CLIP_DEFECTS.items()}, **MANIFEST_DEFECTS}


@pytest.mark.parametrize("name", list(DEFECTS))
def test_bad_input_is_one_clear_line(name, tmp_path):
    apply, needles = DEFECTS[name]
    corpus = make_corpus(tmp_path / "corpus")
    apply(corpus)
    out = tmp_path / "out"
    chk, gen = run_all(["check", *common(corpus)], ["generate", *common(corpus), "--out", str(out), "--quiet",
                                                      "--workers", "1"])
    line = assert_one_line_error(chk, *needles)
    assert_one_line_error(gen, *needles)
    assert "corpus" in line or "train.csv" in line  # names the file
    _no_shards(out)


def test_duplicate_clip_ids_across_splits(tmp_path):
    corpus = make_corpus(tmp_path / "corpus")
    # val.csv's second row names a clip that is in train.csv: a leak from train into val
    _rewrite_csv(corpus, "val", _csv_bytes(corpus, "val").replace(b"doorF,0,wooden door creaks open",
                                                                  b"rainB,0,rain falls on a metal roof"))
    args = ["--preset", "demo", "--corpus-dir", corpus, "--split", "train=2", "--split", "val=1", "--split",
            "test=0", "--set", "audio.duration=1.0"]
    chk, gen = run_all(["check", *args], ["generate", *args, "--out", str(tmp_path / "out"), "--quiet"])
    for r in (chk, gen):
        assert_one_line_error(r, "val.csv:3", "duplicate clip id 'rainB_0'", "train.csv:3", "split train",
                              "remove the duplicate")


def test_duplicate_ids_in_plain_manifest(tmp_path):
    corpus = make_corpus(tmp_path / "corpus")
    with open(os.path.join(corpus, "mine.csv"), "w", encoding="utf-8") as f:
        f.write("id,path,caption\nc1,dogA.wav,a dog barks\nc2,rainB.wav,rain on a roof\nc1,carC.wav,an engine\n")
    args = ["--preset", "demo", "--corpus-dir", corpus, "--set", 'corpus.format="plain"', "--set",
            'splits.train.manifest="mine.csv"', "--split", "train=2", "--split", "val=0", "--split", "test=0"]
    chk, = run_all(["check", *args])
    assert_one_line_error(chk, "mine.csv:4", "id 'c1'", "line 2")


def test_unknown_config_key_suggests_closest(tmp_path, demo_corpus):
    cfg = tmp_path / "my.toml"
    cfg.write_text('name = "x"\n[corpus]\nformat = "audiocaps"\n[splits.train]\nmanifest = "train.csv"\ncount = 2\n'
                   '[room]\nrt6 = 0.5\n')
    chk, gen = run_all(["check", "--config", str(cfg), "--corpus-dir", demo_corpus],
                       ["generate", "--config", str(cfg), "--corpus-dir", demo_corpus, "--out", str(tmp_path / "o")])
    for r in (chk, gen):
        assert_one_line_error(r, "my.toml", "unknown config key room.'rt6'", "did you mean room.rt60")
    chk, = run_all(["check", "--preset", "demo", "--set", "scene.min_seperation=30"])
    assert_one_line_error(chk, "did you mean scene.min_separation")


GEOMETRY = {
    # override, needles, whether `tsel generate` rejects it too (it runs the same validation)
    "room-smaller-than-array": ('room.length=["uniform", 1.5, 10.0]',
                                ["room.length minimum 1.5 m", "array plus its margins", "raise the minimum"], True),
    "min-greater-than-max": ('room.width=["uniform", 9.0, 6.0]', ["room.width", "min 9.0 > max 6.0", "swap"], True),
    "separation-impossible": ("scene.min_separation=200", ["min_separation 200", "impossible"], True),
    "separation-unplaceable": ("scene.min_separation=179.9", ["could not place", "lower scene.min_separation"], True),
    "distance-unreachable": ('sources.distance=["uniform", 8.0, 9.0]',
                             ["sources.distance minimum 8.0 m cannot fit in the smallest room"], True),
    "sources-above-ceiling": ('sources.height=["uniform", 4.8, 5.0]', ["sources.height minimum 4.8 m",
                                                                       "lowest room"], True),
    "unknown-path": ('scene.path=["choose", ["arc", "spiral"]]', ['scene.path must be "arc", "line"', "spiral"], True),
}


@pytest.mark.parametrize("name", list(GEOMETRY))
def test_impossible_geometry(name, tmp_path, demo_corpus):
    override, needles, by_generate = GEOMETRY[name]
    args = ["--preset", "demo", "--corpus-dir", demo_corpus, "--split", "train=8", "--split", "val=0", "--split",
            "test=0", "--set", "audio.duration=1.0", "--set", override]
    cmds = [["check", *args]]
    if by_generate:
        cmds.append(["generate", *args, "--out", str(tmp_path / "out"), "--quiet", "--workers", "1"])
    results = run_all(*cmds)
    assert_one_line_error(results[0], *needles)
    if by_generate:
        assert_one_line_error(results[1], needles[0])
        _no_shards(tmp_path / "out")


# --- RIR banks -------------------------------------------------------------------------------


def _bank(path, fs=24000, fmt="mic4", rooms=("roomA", "roomB"), nan_room=None, side=0.11):
    from tsel_data.banks import MemoryBank, Trajectory
    from tsel_data.banks.native import write_bank

    rng = np.random.default_rng(0)
    az = np.arange(0.0, 360.0, 10.0) - 180.0
    pos = np.stack([az, np.zeros_like(az), np.full_like(az, 1.5)], axis=1)
    items = {}
    for r in rooms:
        p = pos.copy()
        if r == nan_room:
            p[3, 0] = np.nan
        items[r] = [(Trajectory(r, "0", "circular", p, closed=True),
                     rng.standard_normal((len(p), 4, 64)).astype(np.float32) * 0.1)]
    info = {r: {"array": {"format": fmt, "side": side if fmt == "mic4" else None}} for r in rooms}
    write_bank(path, MemoryBank(fs, fmt, items, info=info), check=False)  # some cases are damaged on purpose
    return str(path)


def _bank_case(tmp_path, name):
    p = tmp_path / "bank.h5"
    extra = []
    if name == "missing-room":
        _bank(p)
        extra = ["--set", 'splits.train.rooms=["roomZ"]']
        needles = ["splits.train.rooms", "no room 'roomZ'", "roomA, roomB"]
    elif name == "sample-rate":
        _bank(p, fs=16000)
        needles = ["RIRs are at 16000 Hz but the scenes are at 24000 Hz", "set audio.fs = 16000"]
    elif name == "positions-missing":
        _bank(p)
        with h5py.File(p, "a") as h:
            del h["rooms/roomA/positions"]
        needles = ["room roomA lacks positions", "incomplete"]
    elif name == "positions-nan":
        _bank(p, nan_room="roomB")
        needles = ["room roomB", "positions missing or invalid", "index 3"]
    elif name == "mic4-without-side":
        _bank(p, side=None)
        extra = ["--set", 'splits.train.rooms=["roomA"]']
        needles = ["room roomA is a mic4 room without the array's side length", "tsel bank build"]
    elif name == "format":
        _bank(p, fmt="foa")
        needles = ["holds foa RIRs but scene.format = 'mic4'", 'scene.format = "foa"']
    elif name == "not-found":
        p = tmp_path / "nope.h5"
        needles = ["nope.h5 not found"]
    else:  # rooms given without a bank
        return ["--set", 'splits.train.rooms=["roomA"]'], ["splits.train.rooms", "room.bank"]
    return ["--set", f'room.bank="{p}"', *extra], needles


@pytest.mark.parametrize("name", ["missing-room", "sample-rate", "positions-missing", "positions-nan",
                                  "mic4-without-side", "format",
                                  "not-found", "rooms-without-bank"])
def test_bank_problems(name, tmp_path, demo_corpus):
    extra, needles = _bank_case(tmp_path, name)
    args = ["--preset", "demo", "--corpus-dir", demo_corpus, "--split", "train=2", "--split", "val=0", "--split",
            "test=0", "--set", "audio.duration=1.0", *extra]
    chk, = run_all(["check", *args, "--no-plan"])
    assert_one_line_error(chk, *needles)


def test_bank_problems_library(tmp_path):
    """The same checks through the library, several problems at once."""
    from tsel_data.banks.scenes import bank_problems
    from tsel_data.config import load_config
    from tsel_data.plan.sampler import bank_request

    p = _bank(tmp_path / "b.h5", fs=16000, nan_room="roomA")
    cfg = load_config(preset="demo", overrides=[f'room.bank="{p}"', 'splits.train.rooms=["roomA", "roomQ"]'],
                      splits={"train": 2, "val": 0, "test": 0})
    msgs = [str(e) for e in bank_problems(bank_request(cfg))]
    assert any("16000 Hz" in m for m in msgs)
    assert any("no room 'roomQ'" in m for m in msgs)
    assert any("roomA" in m and "positions missing" in m for m in msgs)
    good = _bank(tmp_path / "g.h5")
    cfg = load_config(preset="demo", overrides=[f'room.bank="{good}"', 'splits.train.rooms=["roomA"]',
                                                'splits.val.rooms=["roomA"]'], splits={"train": 2, "val": 2, "test": 0})
    msgs = [str(e) for e in bank_problems(bank_request(cfg))]
    assert len(msgs) == 1 and "also used by split train" in msgs[0]


# --- the bad-clip policy -------------------------------------------------------------------------

POLICY_DEFECTS = {  # clip -> defect; bad_clips.jsonl must give the defect's reason
    "dogA": "missing-audio", "rainB": "corrupt-audio", "carC": "empty-file", "bellD": "silent",
    "birdE": "nan", "doorF": "too-short", "waterG": "channels",
}


def _policy_corpus(tmp_path):
    CAPTIONS.update(goodI="a cat meows loudly", goodJ="thunder rumbles far away", goodK="keys jingle in pocket")
    corpus = make_corpus(tmp_path / "corpus", {"train": [*POLICY_DEFECTS, "crowdH", "goodI", "goodJ", "goodK"]})
    for cid, defect in POLICY_DEFECTS.items():
        CLIP_DEFECTS[defect][0](_wav(corpus, cid))
    return corpus


def test_bad_clip_policy_skip_and_fail(tmp_path):
    """corpus.check = "full": every clip checked before planning, every bad one listed
    (tests/plan/test_drawn.py: the default, bad clips found where the plan draws them)."""
    import json

    corpus = _policy_corpus(tmp_path)
    base = ["--preset", "demo", "--corpus-dir", corpus, "--split", "train=4", "--split", "val=0", "--split", "test=0",
            "--set", "audio.duration=1.0", "--set", "output.shard_size=2", "--set", 'corpus.check="full"']
    skip, fail, chk_skip = run_all(
        ["generate", *base, "--out", str(tmp_path / "skip"), "--quiet", "--workers", "1"],
        ["generate", *base, "--set", 'on_bad_clip="fail"', "--out", str(tmp_path / "fail"), "--quiet"],
        ["check", *base])
    # skip: the run completes, every bad clip is listed with its reason, the summary counts them
    assert skip.returncode == 0, skip.stderr
    # a missing file is a partial download, not a bad clip: counted and listed apart
    assert "6 bad clips skipped (see bad_clips.jsonl), 1 clips missing (see missing_clips.json)" in skip.stdout
    assert "train: 10 of 11 clips present (90.9 %), 6 of them bad" in skip.stdout
    missing = json.load(open(tmp_path / "skip" / "missing_clips.json", encoding="utf-8"))
    assert missing == {"splits": {"train": {"listed": 11, "missing": 1, "audio_dir": "audio",  # relative to the corpus
                                            "audio_dirs": ["audio"], "clip_ids": ["dogA_0"]}}}
    bad = [json.loads(line) for line in open(tmp_path / "skip" / "bad_clips.jsonl", encoding="utf-8")]
    assert {b["clip_id"]: b["split"] for b in bad} == {f"{c}_0": "train" for c in POLICY_DEFECTS if c != "dogA"}
    for b in bad:
        for needle in CLIP_DEFECTS[POLICY_DEFECTS[b["clip_id"][:-2]]][1]:
            assert needle in b["problem"], b
        assert b["origin"].startswith("train.csv:")  # relative to the corpus
    plan = open(tmp_path / "skip" / "plan" / "train.jsonl", encoding="utf-8").read()
    for cid in POLICY_DEFECTS:
        assert f'"{cid}_0"' not in plan  # no scene uses a bad clip
    doc = json.load(open(tmp_path / "skip" / "plan" / "config.json"))
    assert doc["bad_clips"] == 6 and doc["missing_clips"] == {"train": 1}
    # fail: stops before rendering with the first bad clip, the count of the others, and the fix
    line = assert_one_line_error(fail, "train.csv:2", "dogA", "(and 6 more", 'on_bad_clip = "skip"')
    assert "audio file not found" in line
    _no_shards(tmp_path / "fail")
    assert not (tmp_path / "fail" / "plan" / "config.json").exists()
    # check under skip: exit 0, one warning per bad clip, the count in the summary
    assert chk_skip.returncode == 0, chk_skip.stderr
    warnings = [w for w in chk_skip.stderr.splitlines() if w.startswith("warning:")]
    assert len(warnings) == 7 and sum('skipped: on_bad_clip = "skip"' in w for w in warnings) == 6
    assert any("split train: 1 of 11 audio files are missing" in w and "missing_clips.json" in w for w in warnings)
    assert "train: 11 clips (10 present, 90.9 %), 6 bad (skip), 4 scenes planned" in chk_skip.stdout


def test_nan_clip_never_reaches_a_scene(tmp_path):
    """With corpus.check below "full", NaN samples are caught when the clip is loaded."""
    from tsel_data.corpus.audio import load_clip
    from tsel_data.errors import AudioError

    p = str(tmp_path / "n.wav")
    x = tone(3, 2.0)
    x[100] = np.nan
    sf.write(p, x, FS, subtype="FLOAT")
    with pytest.raises(AudioError, match="NaN or Inf"):
        load_clip(p, FS, 1.0)


def test_a_good_bank_passes_and_its_scenes_are_planned(tmp_path, demo_corpus):
    from tsel_data.job.preflight import check_config
    from tsel_data.config import load_config

    p = _bank(tmp_path / "good.h5")
    cfg = load_config(preset="demo", corpus_dir=demo_corpus, splits={"train": 3, "val": 2, "test": 0},
                      overrides=["audio.duration=1.0", f'room.bank="{p}"', 'splits.train.rooms=["roomA"]',
                                 'splits.val.rooms=["roomB"]'])
    rep = check_config(cfg)
    assert rep.ok, rep.messages()
    assert rep.facts["splits"]["train"]["planned"] == 3 and rep.facts["splits"]["val"]["planned"] == 2


def test_clip_silent_in_the_part_a_scene_uses_is_a_bad_clip(tmp_path):
    """Loud after 12 s, silent in the first 10 s a scene reads: caught before planning."""
    import numpy as np
    import soundfile as sf

    from tsel_data.corpus.audio import check_clip

    x = np.zeros(20 * 16000, dtype=np.float32)
    x[12 * 16000:] = 0.5 * np.sin(np.arange(8 * 16000) / 5.0)
    p = tmp_path / "late.wav"
    sf.write(p, x, 16000)
    assert check_clip("c", str(p), "full", 1.0, 8).problem is None  # the whole file is not silent
    problem = check_clip("c", str(p), "full", 1.0, 8, offset=0.0, duration=10.0).problem
    assert "silent in the 10 s a scene uses" in problem
