"""A researcher's first day (issue 26, sections 1 and 2): corpora where the download tools
put them, safe first runs. CLI messages are checked in process, through the real entry
point (tsel_data.cli:main)."""
from __future__ import annotations

import csv
import os
import re
import shutil

import pytest
import soundfile as sf

from support.corpora import CAPTIONS, FS, SPLITS, make_corpus, tone
from support import REPO
from support.cli import InProcessCli, cli as tsel

TINY = ["--set", "audio.duration=1.0", "--set", "output.shard_size=4"]


def refused(capsys, *argv) -> str:
    return InProcessCli(capsys).refused(*argv)


def ok(capsys, *argv) -> str:
    code, out, err = tsel(capsys, *argv)
    assert code == 0, err
    return out + err


def counts(train=2, val=0, test=0):
    return ["--split", f"train={train}", "--split", f"val={val}", "--split", f"test={test}"]


# --- 1. corpora where the download tools put them ------------------------------------------

def _move_audio(corpus, folder_of):
    """Move each split's audio/{id}.wav into the folder ``folder_of(split)`` (relative)."""
    for split, ids in SPLITS.items():
        dest = os.path.join(corpus, folder_of(split))
        os.makedirs(dest, exist_ok=True)
        for cid in ids:
            shutil.move(os.path.join(corpus, "audio", f"{cid}.wav"), os.path.join(dest, f"{cid}.wav"))


def test_audio_in_per_split_subfolders_is_found(tmp_path, capsys):
    corpus = make_corpus(tmp_path / "c")
    _move_audio(corpus, lambda split: os.path.join("audio", {"val": "validation"}.get(split, split)))
    out = ok(capsys, "check", "--preset", "demo", "--corpus-dir", corpus, *counts(2, 1, 1), *TINY, "--no-plan")
    assert "missing" not in out and "train: 4 clips" in out and "val: 2 clips" in out, out


def test_audio_elsewhere_names_the_setting(tmp_path, capsys):
    corpus = make_corpus(tmp_path / "c")
    _move_audio(corpus, lambda split: os.path.join("downloads", f"{split}_wavs"))
    line = refused(capsys, "generate", "--preset", "demo", "--corpus-dir", corpus, *counts(), *TINY,
                   "--out", tmp_path / "out", "--quiet")
    assert "4 of 4 audio files missing" in line and 'set splits.train.audio_dir = "downloads/train_wavs"' in line, line
    _, _, err = tsel(capsys, "check", "--preset", "demo", "--corpus-dir", corpus, *counts(), *TINY, "--no-plan")
    assert 'splits.train.audio_dir = "downloads/train_wavs"' in err, err


def test_train_files_in_audio_and_val_files_in_a_folder_of_their_own_are_all_found(tmp_path, capsys):
    corpus = make_corpus(tmp_path / "c")
    _move_audio(corpus, lambda split: os.path.join("audio", "val") if split == "val" else "audio")
    out = ok(capsys, "check", "--preset", "demo", "--corpus-dir", corpus, *counts(2, 1, 1), *TINY, "--no-plan")
    assert "missing" not in out and "train: 4 clips" in out and "val: 2 clips" in out, out


def test_a_partial_download_is_said_as_such_without_a_setting_to_change(tmp_path, capsys):
    corpus = make_corpus(tmp_path / "c")
    gone = SPLITS["train"][:1]
    for cid in gone:
        os.remove(os.path.join(corpus, "audio", f"{cid}.wav"))
    out = ok(capsys, "plan", "--preset", "demo", "--corpus-dir", corpus, *counts(2), *TINY, "--out", tmp_path / "o")
    line = next(x for x in out.splitlines() if x.startswith("train:"))
    n = len(SPLITS["train"])
    assert line.startswith(f"train: {n - 1} of {n} clips present") and "a partial download" in line, line
    assert "set " not in line, line


def test_missing_files_under_other_names_in_the_audio_folder_name_the_template(tmp_path, capsys):
    corpus = make_corpus(tmp_path / "c")
    for cid in SPLITS["train"]:  # the download tool's names: AudioSet's Y and an extension no template tries
        os.rename(os.path.join(corpus, "audio", f"{cid}.wav"), os.path.join(corpus, "audio", f"{cid}.aiff"))
    _, out, err = tsel(capsys, "check", "--preset", "demo", "--corpus-dir", corpus, *counts(2), *TINY, "--no-plan")
    assert "are in audio under other names (e.g. " in err and "corpus.audio_template" in err, err


def _plain_corpus(root) -> str:
    """Own recordings: rec/*.wav and one all.csv (path,caption,split)."""
    root = str(root)
    os.makedirs(os.path.join(root, "rec"))
    with open(os.path.join(root, "all.csv"), "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["path", "caption", "split"])
        for k, (split, ids) in enumerate((s, i) for s, ids in SPLITS.items() for i in ids):
            sf.write(os.path.join(root, "rec", f"{ids}.wav"), tone(k), FS)
            w.writerow([f"rec/{ids}.wav", CAPTIONS[ids], split])
    return root


def test_a_plain_manifest_under_a_preset_names_the_format(tmp_path, capsys):
    corpus = _plain_corpus(tmp_path / "c")
    line = refused(capsys, "plan", "--preset", "demo", "--corpus-dir", corpus, *counts(), *TINY,
                   "--set", 'splits.train.manifest="all.csv"', "--out", tmp_path / "out")
    assert 'plain manifest' in line and 'corpus.format = "plain"' in line and "--manifest" in line, line
    assert "missing column" not in line, line


def test_one_manifest_for_every_split(tmp_path, capsys):
    corpus = _plain_corpus(tmp_path / "c")
    manifest = os.path.join(corpus, "all.csv")
    out = ok(capsys, "check", "--preset", "demo", "--manifest", manifest, *counts(2, 1, 1), *TINY, "--no-plan")
    assert "train: 4 clips" in out and "val: 2 clips" in out and "test: 2 clips" in out, out
    ok(capsys, "plan", "--preset", "demo", "--manifest", manifest, *counts(2, 1, 1), *TINY, "--out", tmp_path / "o")
    from tsel_data.store.layout import Layout
    from tsel_data.store.plans import stored_config

    stored = stored_config(Layout(str(tmp_path / "o")))
    assert stored["splits"]["val"]["manifest"] == "all.csv" and stored["corpus"]["format"] == "auto"


def test_band_limited_clips_are_counted_and_can_be_left_out(demo_corpus, capsys):
    from tsel_data.plan.catalog import scan_catalog
    from tsel_data.config import load_config

    out = ok(capsys, "check", "--preset", "demo", "--corpus-dir", demo_corpus, "--no-plan")
    narrow = re.search(r"train: 60 clips, (\d+) band-limited \(16 kHz: \d+, empty above 8 of the scenes' 12 kHz", out)
    assert narrow and int(narrow.group(1)) > 0, out
    cfg = load_config(preset="demo", corpus_dir=demo_corpus, overrides=["corpus.min_samplerate=24000"])
    scan = scan_catalog(cfg, demo_corpus)
    assert scan.left_out["train"] == int(narrow.group(1)) and not scan.rates["train"]
    assert all(sf.info(c.audio).samplerate >= 24000 for clips in scan.clips.values() for c in clips)
    line = refused(capsys, "check", "--preset", "demo", "--corpus-dir", demo_corpus, "--no-plan",
                   "--set", "corpus.min_samplerate=24000", "--set", 'corpus.check="exists"')
    assert "corpus.min_samplerate" in line and 'corpus.check = "header"' in line, line


@pytest.fixture
def tiny_dataset(generated_dataset):
    """4 train scenes of 1 s over the demo corpus, in shards of 3 (the last one partial)."""
    return generated_dataset("partial-shard").out


def test_stats_count_band_limited_targets(tiny_dataset, demo_corpus):
    from tsel_data.tools.stats import band_limited_targets, format_text, split_stats

    narrow = [n for n in sorted(os.listdir(os.path.join(demo_corpus, "audio")))
              if sf.info(os.path.join(demo_corpus, "audio", n)).samplerate == 16000][:2]
    wide = [n for n in sorted(os.listdir(os.path.join(demo_corpus, "audio")))
            if sf.info(os.path.join(demo_corpus, "audio", n)).samplerate >= 24000][:3]
    got = band_limited_targets(tiny_dataset, {n: f"audio/{n}" for n in narrow + wide})
    assert got == {"clips": 2, "rates": {16000: 2}, "fs": 24000}
    st = split_stats(tiny_dataset, "train")
    st["clips"]["target_band_limited"] = got
    assert "target clips band-limited: 2 of " in format_text({"train": st})


# --- 2. safe first runs ----------------------------------------------------------------------

def test_the_readme_quickstarts_say_how_many_scenes():
    readme = open(REPO / "README.md", encoding="utf-8").read()
    runs = [line for line in readme.splitlines() if re.match(r"\.venv/bin/tsel generate --preset paper", line)]
    assert runs and all("--split" in line for line in runs), runs


def test_generate_stops_before_rendering_when_clips_would_be_reused_too_often(tmp_path, capsys):
    corpus = make_corpus(tmp_path / "c")
    out = tmp_path / "out"
    line = refused(capsys, "generate", "--preset", "demo", "--corpus-dir", corpus, *counts(200), *TINY,
                   "--out", out, "--quiet")
    assert ("split train: 200 scenes from 4 usable clips, each clip in about 100 scenes (more than "
            "corpus.max_reuse = 20)") in line and "--split train=40" in line and "--allow-reuse" in line, line
    assert not os.path.exists(os.path.join(out, "plan", "config.json"))
    ok(capsys, "plan", "--preset", "demo", "--corpus-dir", corpus, *counts(200), *TINY, "--out", out, "--allow-reuse")
    # nothing rendered yet: the same folder is planned again, smaller
    said = ok(capsys, "plan", "--preset", "demo", "--corpus-dir", corpus, *counts(8), *TINY, "--out", out)
    assert "nothing was rendered yet" in said and "planned train 8," in said, said
    with open(os.path.join(out, "plan", "train.jsonl"), encoding="utf-8") as f:
        assert len(f.read().splitlines()) == 8


def test_a_rendered_dataset_does_not_shrink_and_grow_says_why_it_renders_a_shard_again(tmp_path, tiny_dataset,
                                                                                        demo_corpus, capsys):
    out = tmp_path / "ds"
    shutil.copytree(tiny_dataset, out)
    base = ["--preset", "demo", "--corpus-dir", demo_corpus, "--set", "audio.duration=1.0",
            "--set", "output.shard_size=3", "--out", out, "--quiet"]
    line = refused(capsys, "generate", *base, *counts(3))
    assert "does not shrink once shards are rendered" in line, line
    code, said, err = tsel(capsys, "generate", *base, *counts(5), "--grow")
    assert code == 0, err
    assert "do not verify" not in err and "another plan" not in err, err
    assert "train: rendering shard-00001.h5 again, the last shard: it held 1 of 3 scenes" in said, said


def test_manifests_clip_checks_and_planning_show_progress(demo_corpus, tmp_path, capsys):
    from tsel_data.config import load_config
    from tsel_data.job.pipeline import plan_dataset

    cfg = load_config(preset="demo", corpus_dir=demo_corpus, splits={"train": 6, "val": 2, "test": 2},
                      overrides=['corpus.check="exists"'])
    plan_dataset(cfg, str(tmp_path / "p"), progress=True)
    err = capsys.readouterr().err
    for what in ("read train", "check train", "plan train", "plan test"):
        assert what in err, (what, err)


def test_check_takes_a_generate_command_line_as_it_is(demo_corpus, tmp_path, capsys):
    """docs/commands/check.md: paste the generate command, change the verb."""
    line = ["--preset", "demo", "--corpus-dir", demo_corpus, "--split", "train=2", "--split", "val=0", "--split",
            "test=0", "--out", str(tmp_path / "ds"), "--workers", "1", "--quiet", "--resume", "--grow", "--force",
            "--allow-reuse", "--executor", "local", "--set", "audio.duration=1.0"]
    code, out, err = tsel(capsys, "check", *line)
    assert code == 0, err
    assert "note: --resume, --grow, --force, --allow-reuse, --executor steer(s) a run, not what it makes" in err
    assert "train: 2 scenes" in out or "2 scenes planned" in out
    assert not (tmp_path / "ds").exists()  # a check writes nothing
