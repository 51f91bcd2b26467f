"""Corpora in the layouts people have, each built here with tiny audio: Clotho as
distributed (per-split audio folders, the README's quickstart), one plain CSV/JSONL for
every split, AudioCaps downloads with mixed file names, partial downloads, and the
remembered clip checks."""
from __future__ import annotations

import csv
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from tsel_data.plan.catalog import scan_catalog
from tsel_data.config import load_config
from tsel_data.errors import ManifestError

from support import REPO
from support.cli import cli
FS = 8000
# small and quick: 1 s scenes at 8 kHz in small rooms
FAST = ["audio.fs=8000", "audio.duration=1.0", "output.shard_size=4", 'room.rt60=["uniform", 0.2, 0.3]',
        'room.length=["uniform", 5.0, 6.0]', 'room.width=["uniform", 5.0, 6.0]', 'room.height=["uniform", 3.0, 3.5]',
        'sources.height=["uniform", 1.0, 1.5]']
WORDS = ["dog barks", "rain falls", "engine idles", "bells ring", "birds chirp", "door creaks", "water pours",
         "people chatter", "cat meows", "thunder rumbles", "keys jingle", "wind howls"]


def tone(seed: int, seconds: float = 1.2) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    return (0.2 * rng.standard_normal(n) * np.exp(-((np.arange(n) / FS) % 0.4) * 6)).astype(np.float32)


def wav(path, seed: int) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    sf.write(path, tone(seed), FS)


# --- Clotho as distributed ---------------------------------------------------------------------------------------


def clotho_tree(root: Path, per_split: int = 4) -> Path:
    """clotho_captions_{development,validation,evaluation}.csv + development/ validation/
    evaluation/ holding each split's WAVs, names with spaces and commas as Clotho's."""
    k = 0
    for folder in ("development", "validation", "evaluation"):
        rows = [["file_name"] + [f"caption_{i}" for i in range(1, 6)]]
        for j in range(per_split):
            name = f"{folder[:3]} take {j}, {WORDS[k % len(WORDS)].split()[0]}.wav"
            wav(root / folder / name, k)
            rows.append([name] + [f"{WORDS[k % len(WORDS)]} {w}" for w in ("loudly", "softly", "far", "near", "twice")])
            k += 1
        with open(root / f"clotho_captions_{folder}.csv", "w", newline="", encoding="utf-8") as f:
            csv.writer(f).writerows(rows)
    return root


def readme_clotho_toml() -> str:
    """The clotho.toml of the README's Clotho quickstart, as printed there."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("## Quickstart on Clotho", 1)[1]
    return re.search(r"```toml\n(.*?)```", section, re.S).group(1)


def test_clotho_as_distributed_with_the_readme_quickstart(tmp_path, capsys):
    corpus = clotho_tree(tmp_path / "clotho")
    (tmp_path / "clotho.toml").write_text(readme_clotho_toml(), encoding="utf-8")
    args = ["--preset", "demo", "--config", str(tmp_path / "clotho.toml"), "--corpus-dir", str(corpus),
            "--split", "train=3", "--split", "val=2", "--split", "test=2", *sum((["--set", o] for o in FAST), [])]
    code, out, err = cli(capsys, "generate", *args, "--out", str(tmp_path / "out"), "--quiet", "--workers", "1")
    assert code == 0, err
    for split in ("train", "val", "test"):
        assert f"{split}: 4 of 4 clips present (100.0 %)" in out
    from tsel_data import open_dataset

    for split, folder in (("train", "development"), ("val", "validation"), ("test", "evaluation")):
        for rec in open_dataset(str(tmp_path / "out"), split).records():
            for src in rec.sources:  # every clip read from its own split's folder (named relative to the corpus)
                assert os.path.dirname(src.audio) == folder


def test_clotho_audio_folder_that_is_not_there_is_named(tmp_path, capsys):
    corpus = clotho_tree(tmp_path / "clotho", per_split=2)
    (tmp_path / "clotho.toml").write_text(readme_clotho_toml().replace('"validation"', '"valdation"'),
                                          encoding="utf-8")
    code, _, err = cli(capsys, "check", "--preset", "demo", "--config", str(tmp_path / "clotho.toml"),
                       "--corpus-dir", str(corpus), "--no-plan")
    assert code == 2
    assert ("error: splits.val.audio_dir: audio folder valdation not found in " + str(corpus)) in err
    assert "development, evaluation, validation" in err


# --- one plain manifest for every split -----------------------------------------------------------------------------


def plain_corpus(root: Path, fmt: str = "csv", blank_split_row: bool = False) -> Path:
    rows = []
    for k, word in enumerate(WORDS):
        split = ("train", "train", "train", "train", "val", "val", "test", "test")[k % 8]
        wav(root / "sounds" / f"s{k}.wav", k)
        rows.append({"path": f"sounds/s{k}.wav", "caption": f"{word} nearby", "split": split})
    if blank_split_row:
        rows[5]["split"] = ""
    if fmt == "csv":
        with open(root / "all.csv", "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, ["path", "caption", "split"])
            w.writeheader()
            w.writerows(rows)
    else:
        with open(root / "all.jsonl", "w", encoding="utf-8") as f:
            f.writelines(json.dumps(r) + "\n" for r in rows)
    return root


def plain_config(corpus: Path, name: str, counts=None):
    counts = counts or {"train": 3, "val": 2, "test": 2}
    sets = ['corpus.format="plain"', 'corpus.audio_dir="."'] + [f'splits.{s}.manifest="{name}"' for s in counts]
    return load_config(preset="demo", overrides=FAST + sets, corpus_dir=str(corpus), splits=counts)


@pytest.mark.parametrize("fmt", ["csv", "jsonl"])
def test_one_plain_manifest_serves_every_split_by_its_split_column(tmp_path, fmt):
    corpus = plain_corpus(tmp_path / "mine", fmt)
    scan = scan_catalog(plain_config(corpus, f"all.{fmt}"), str(corpus))
    assert not scan.problems, [str(p) for p in scan.problems]
    ids = {s: [os.path.basename(c.audio) for c in clips] for s, clips in scan.clips.items()}
    assert ids == {"train": ["s0.wav", "s1.wav", "s2.wav", "s3.wav", "s8.wav", "s9.wav", "s10.wav", "s11.wav"],
                   "val": ["s4.wav", "s5.wav"], "test": ["s6.wav", "s7.wav"]}


def test_shared_plain_manifest_row_without_split_is_one_error(tmp_path):
    corpus = plain_corpus(tmp_path / "mine", blank_split_row=True)
    scan = scan_catalog(plain_config(corpus, "all.csv"), str(corpus))
    msgs = sorted({str(p) for p in scan.problems})
    assert msgs == [f"{corpus}/all.csv:7: clip 'sounds/s5.wav' has no split, and all.csv serves splits train, val, "
                    f"test; fill in its split column, or give each split its own manifest"]


def test_split_the_manifest_does_not_name_is_one_error(tmp_path):
    corpus = plain_corpus(tmp_path / "mine")
    cfg = plain_config(corpus, "all.csv", {"train": 2, "valid": 1, "val": 0, "test": 0})
    scan = scan_catalog(cfg, str(corpus))
    (msg,) = [str(p) for p in scan.problems]
    assert msg == (f"{corpus}/all.csv: no row has split 'valid' (the split column holds test, train, val); name the "
                   f"splits alike in the config and the manifest")


# --- AudioCaps with mixed file names ------------------------------------------------------------------------------

NAMINGS = {"a1": "{yt}.wav", "a2": "Y{yt}.wav", "a3": "{yt}_30.wav", "a4": "{aid}.flac", "a5": "Y{yt}.flac"}


def audiocaps_corpus(root: Path, names=NAMINGS, missing=()) -> Path:
    """AudioCaps CSVs whose clips were downloaded by different tools (different names)."""
    root.mkdir(exist_ok=True)
    k = 0
    for split, n in (("train", 5), ("val", 3), ("test", 3)):
        with open(root / f"{split}.csv", "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(["audiocap_id", "youtube_id", "start_time", "caption"])
            for j in range(n):
                yt, aid = f"{split[:2]}{j}x", str(1000 + k)
                w.writerow([aid, yt, "30", WORDS[k % len(WORDS)]])  # no words in common: any two pair
                name = list(names.values())[k % len(names)].format(yt=yt, aid=aid)
                if yt not in missing:
                    wav(root / "audio" / name, k)
                k += 1
    return root


def test_audiocaps_mixed_download_names_are_all_found(tmp_path):
    corpus = audiocaps_corpus(tmp_path / "ac")
    cfg = load_config(preset="demo", overrides=FAST, corpus_dir=str(corpus), splits={"train": 2, "val": 1, "test": 1})
    scan = scan_catalog(cfg, str(corpus))
    assert not scan.problems and not scan.bad
    assert {s: len(c) for s, c in scan.clips.items()} == {"train": 5, "val": 3, "test": 3}
    names = sorted(os.path.basename(c.audio) for c in scan.clips["train"])
    assert names == ["1003.flac", "Ytr1x.wav", "Ytr4x.flac", "tr0x.wav", "tr2x_30.wav"]
    # one explicit template is that name only; a list is tried in order
    one = load_config(preset="demo", overrides=FAST + ['corpus.audio_template="Y{youtube_id}.wav"'],
                      corpus_dir=str(corpus), splits={"train": 2, "val": 0, "test": 0})
    assert scan_catalog(one, str(corpus)).counts["train"] == {"clips": 5, "missing": 4, "bad": 0}
    two = load_config(preset="demo", overrides=FAST + ['corpus.audio_template=["Y{youtube_id}.wav", '
                                                       '"{youtube_id}.wav"]'],
                      corpus_dir=str(corpus), splits={"train": 2, "val": 0, "test": 0})
    assert scan_catalog(two, str(corpus)).counts["train"] == {"clips": 5, "missing": 3, "bad": 0}


# --- partial downloads ----------------------------------------------------------------------------------------------


def test_partial_download_is_counted_listed_compactly_and_not_bad(tmp_path, capsys):
    corpus = audiocaps_corpus(tmp_path / "ac", names={"a": "{yt}.wav"}, missing=("tr1x", "tr3x", "va2x"))
    out_dir = tmp_path / "out"
    code, out, err = cli(capsys, "generate", "--preset", "demo", "--corpus-dir", str(corpus), "--split", "train=2",
                         "--split", "val=1", "--split", "test=1", *sum((["--set", o] for o in FAST), []),
                         "--out", str(out_dir), "--quiet", "--workers", "1")
    assert code == 0, err
    lines = out.splitlines()[:3]
    assert [x.split(";")[0] for x in lines] == ["train: 3 of 5 clips present (60.0 %)",
                                                "val: 2 of 3 clips present (66.7 %)", "test: 3 of 3 clips present (100.0 %)"]
    assert "; a partial download: the 2 others are in no folder below " in lines[0] and ";" not in lines[2], lines
    assert "3 clips missing (see missing_clips.json)" in out
    assert (out_dir / "bad_clips.jsonl").read_text() == ""
    listed = json.loads((out_dir / "missing_clips.json").read_text())["splits"]
    assert {s: (v["listed"], v["missing"], v["clip_ids"]) for s, v in listed.items()} == {
        "train": (5, 2, ["tr1x_30", "tr3x_30"]), "val": (3, 1, ["va2x_30"])}
    assert listed["train"]["audio_dir"] == "audio"  # relative to the corpus


def test_clip_reuse_warning(tmp_path, capsys):
    corpus = audiocaps_corpus(tmp_path / "ac", names={"a": "{yt}.wav"})
    code, out, err = cli(capsys, "check", "--preset", "demo", "--corpus-dir", str(corpus), "--split", "train=13",
                         "--split", "val=1", "--split", "test=1", *sum((["--set", o] for o in FAST), []), "--no-plan")
    assert code == 0, err
    # 13 scenes x 2 sources / 5 clips = 5.2 uses per clip (above 5); val: 2 / 3
    assert ("warning: split train: 13 scenes from 5 usable clips: each clip sounds in about 5.2 scenes; lower "
            "splits.train.count to about 12 or add clips") in err.splitlines()
    assert "split val" not in err


# --- remembered clip checks -------------------------------------------------------------------------------------------


def test_clip_checks_are_remembered_until_a_file_changes(tmp_path, monkeypatch, capsys):
    import tsel_data.plan.catalog as catalog

    monkeypatch.setenv("TSEL_CACHE_DIR", str(tmp_path / "cache"))
    corpus = audiocaps_corpus(tmp_path / "ac", names={"a": "{yt}.wav"})
    cfg = load_config(preset="demo", overrides=FAST, corpus_dir=str(corpus), splits={"train": 2, "val": 1, "test": 1})
    decoded = []
    real = catalog.check_clip
    monkeypatch.setattr(catalog, "check_clip", lambda *a: decoded.append(a[1]) or real(*a))
    first = scan_catalog(cfg, str(corpus), progress=True)
    bars = capsys.readouterr().err
    assert "check train" in bars and "clip/s" in bars and "5/5" in bars  # a bar per split, with a rate
    assert len(decoded) == 11
    decoded.clear()
    again = scan_catalog(cfg, str(corpus), progress=True)
    # nothing left to check: no check bar (the manifest's read bar stays)
    assert decoded == [] and "check" not in capsys.readouterr().err
    assert again.clips == first.clips
    # a rewritten file (new size) is checked again, and its new verdict counts
    sf.write(corpus / "audio" / "tr2x.wav", np.zeros(FS // 2, np.float32), FS)
    third = scan_catalog(cfg, str(corpus))
    assert decoded == [str(corpus / "audio" / "tr2x.wav")]
    assert [b.clip_id for b in third.bad] == ["tr2x_30"] and "0.500 s long" in third.bad[0].problem
    # other settings are other verdicts
    decoded.clear()
    scan_catalog(load_config(preset="demo", overrides=FAST + ["corpus.min_duration=0.2"], corpus_dir=str(corpus),
                             splits={"train": 2, "val": 1, "test": 1}), str(corpus))
    assert len(decoded) == 11


def test_clip_cache_can_be_turned_off_and_survives_a_damaged_file(tmp_path, monkeypatch):
    from tsel_data.corpus.clipcache import ClipCache, cache_dir

    monkeypatch.setenv("TSEL_CACHE_DIR", "off")
    assert cache_dir() is None
    bad = tmp_path / "cache"
    bad.mkdir()
    (bad / "clip-checks.sqlite").write_bytes(b"not a database" * 100)
    with ClipCache(str(bad)) as cache:  # damaged: behaves as an empty cache
        assert cache.get([("/x", 1, 2, "s")]) == {}
        cache.put([(("/x", 1, 2, "s"), None)])


def test_read_split_clips_names_the_manifest_folder(tmp_path):
    from tsel_data.plan.catalog import read_split_clips

    corpus = audiocaps_corpus(tmp_path / "ac")
    cfg = load_config(preset="demo", overrides=FAST + ['splits.val.manifest="valid.csv"'], corpus_dir=str(corpus))
    with pytest.raises(ManifestError) as e:
        read_split_clips(cfg, "val", str(corpus))
    assert str(e.value) == (f"splits.val.manifest: valid.csv not found in {corpus} (it holds test.csv, train.csv, "
                            f"val.csv); set splits.val.manifest to the file's name, or pass the --corpus-dir that "
                            f"holds it")


def test_a_nul_byte_in_a_clip_name_is_a_missing_file_not_a_crash(tmp_path):
    from tsel_data.corpus.clipcache import file_key

    (tmp_path / "ab.wav").write_bytes(b"")
    assert file_key(str(tmp_path / "ab.wav"), "s") is not None
    assert file_key(str(tmp_path / "a\x00b.wav"), "s") is None
