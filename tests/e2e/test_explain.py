"""Presets and errors that explain themselves, and growing a dataset.

Each message is checked whole or by its telling parts, through the command line (one
line on stderr, exit code 2, no traceback)."""
from __future__ import annotations

import hashlib
import json
import os
import tomllib
from pathlib import Path

import pytest

from support import REPO
from support.cli import InProcessCli, cli
SMALL = ["--set", "audio.duration=1.0", "--set", "audio.fs=8000", "--set", "output.shard_size=4",
         "--set", 'room.rt60=["uniform", 0.2, 0.3]', "--quiet", "--workers", "1"]


def one_line_error(capsys, *args) -> str:
    return InProcessCli(capsys).refused(*args)


# --- presets ----------------------------------------------------------------------------------------------------------


def test_presets_say_what_they_need(capsys):
    code, out, _ = cli(capsys, "presets")
    lines = {line.split()[0]: line for line in out.splitlines()}
    assert lines["paper-measured"].endswith("(needs --corpus-dir, --bank)")
    assert lines["paper-sim-2dir"].endswith("(needs --corpus-dir)")
    assert "needs" not in lines["demo"] and "needs" not in lines["demo-moving"]
    code, out, _ = cli(capsys, "presets", "paper-measured")
    assert "# What it needs on the command line:" in out
    assert ("#   --bank PATH: an RIR bank in foa with the rooms the splits name (train 1, 2, 3, 4, 5, 6, 10; val 8; "
            "test 9); see rir_banks/README.md") in out
    assert "#   --corpus-dir DIR: your corpus, the folder with train.csv, val.csv, test.csv (audiocaps" in out
    assert "TAU-SRIR DB: --bank" in out
    tomllib.loads(out)  # still a config to start from


# --- errors ---------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("override, needle", [
    ("scene.format=xyz", "error: --set scene.format=xyz: scene.format = 'xyz' is not one of mic4, foa, tetra, em32"),
    ('room.width=["uniform", 9.0, 6.0]', 'error: --set room.width=["uniform", 9.0, 6.0]: room.width: uniform range '
                                         'has min 9.0 > max 6.0; swap them'),
    ("room.rt7=1", "error: --set room.rt7=1: unknown config key room.'rt7'; did you mean room.rt60?"),
    ('room.length=["uniform", 1.5, 10]', 'error: --set room.length=["uniform", 1.5, 10]: room.length minimum 1.5 m'),
])
@pytest.mark.parametrize("command", ["generate", "check"])
def test_set_errors_name_the_set_not_the_preset(capsys, tmp_path, override, needle, command, demo_corpus):
    # a geometry problem does not stop `tsel check` from checking the corpus too: give it one made already
    extra = ["--out", tmp_path / "o"] if command == "generate" else ["--no-plan", "--corpus-dir", demo_corpus]
    line = one_line_error(capsys, command, "--preset", "demo", "--set", override, *extra)
    assert line.startswith(needle) and "preset demo" not in line


def test_preset_values_are_still_blamed_on_the_preset(capsys, tmp_path):
    (tmp_path / "mine.toml").write_text("[room]\nrt60 = -1.0\n")
    line = one_line_error(capsys, "check", "--preset", "demo", "--config", tmp_path / "mine.toml", "--no-plan")
    assert line.startswith(f"error: {tmp_path / 'mine.toml'}: room.rt60 must be > 0 and <= 20 s, got -1.0")


def test_impossible_separation_says_the_largest_possible(capsys):
    line = one_line_error(capsys, "check", "--preset", "demo", "--set", "scene.min_separation=200", "--no-plan")
    assert line == ("error: --set scene.min_separation=200: scene.min_separation 200° is impossible with 2 directional "
                    "sources: the largest possible is 180° (360° / 2); lower scene.min_separation")
    line = one_line_error(capsys, "check", "--preset", "demo", "--set", "scene.interferers=3",
                          "--set", "scene.min_separation=100", "--no-plan")
    assert "the largest possible is 90° (360° / 4)" in line


def test_manifest_not_found_names_the_folder(capsys, tmp_path, demo_corpus):
    line = one_line_error(capsys, "check", "--preset", "demo", "--corpus-dir", demo_corpus,
                          "--set", 'splits.val.manifest="valid.csv"', "--no-plan")
    assert line == (f"error: splits.val.manifest: valid.csv not found in {demo_corpus} (it holds clips.json, test.csv, "
                    f"train.csv, val.csv); set splits.val.manifest to the file's name, or pass the --corpus-dir that holds it")


def test_licence_is_an_spdx_string():
    """setuptools >= 77 warns at every install about a licence table; an SPDX string does not."""
    doc = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert doc["project"]["license"] == "MIT"
    assert any(r.startswith("setuptools>=77") for r in doc["build-system"]["requires"])


# --- resume and grow ---------------------------------------------------------------------------------------------------


def _digests(root: Path) -> dict[str, str]:
    # a seal records its files' modification times, so it is the one file of two equal
    # datasets that differs; its fingerprint must not
    return {str(p.relative_to(root)): (json.loads(p.read_text())["fingerprint"] if p.name.endswith(".seal.json")
                                       else hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.slow
def test_grow_adds_scenes_and_equals_a_fresh_dataset(capsys, tmp_path, demo_corpus):
    base = ["generate", "--preset", "demo", "--corpus-dir", demo_corpus, *SMALL, "--split", "test=2"]
    grown, fresh = tmp_path / "grown", tmp_path / "fresh"
    assert cli(capsys, *base, "--split", "train=6", "--split", "val=2", "--out", grown)[0] == 0
    kept = grown / "train" / "shard-00000.h5"
    stamp = kept.stat().st_mtime_ns
    # more scenes with --resume: refused, naming the keys and the flag that does it
    line = one_line_error(capsys, *base, "--split", "train=10", "--split", "val=5", "--out", grown, "--resume")
    assert line == (f"error: {grown} was planned with a different config: splits.train.count (planned 6, now 10); "
                    f"splits.val.count (planned 2, now 5); to add the scenes to this dataset pass --grow (the planned "
                    f"scenes stay as they are)")
    code, out, err = cli(capsys, *base, "--split", "train=10", "--split", "val=5", "--out", grown, "--grow")
    assert code == 0, err
    assert "train 10, val 5, test 2 scenes (17 total)" in out
    assert kept.stat().st_mtime_ns == stamp  # a full shard is not rendered again
    assert cli(capsys, *base, "--split", "train=10", "--split", "val=5", "--out", fresh)[0] == 0
    assert _digests(grown) == _digests(fresh)
    # fewer scenes, or another key, are refused
    line = one_line_error(capsys, *base, "--split", "train=4", "--split", "val=5", "--out", grown, "--grow")
    assert "splits.train.count (planned 10, now 4); a dataset does not shrink" in line
    line = one_line_error(capsys, *base, "--split", "train=12", "--split", "val=5", "--set", "scene.min_separation=30",
                          "--out", grown, "--grow")
    assert ("scene.min_separation (planned 20.0, now 30.0); --resume needs the config the plan was made with" in line
            and "(--grow changes only splits.NAME.count)" in line)


def test_grow_refuses_a_changed_corpus(capsys, tmp_path, demo_corpus):
    import shutil

    corpus = tmp_path / "corpus"
    shutil.copytree(demo_corpus, corpus)
    base = ["plan", "--preset", "demo", "--corpus-dir", corpus, "--set", "audio.duration=1.0", "--split", "val=0",
            "--split", "test=0"]
    assert cli(capsys, *base, "--split", "train=5", "--out", tmp_path / "o")[0] == 0
    first = (corpus / "train.csv").read_text().splitlines()[1].split(",")[1]
    os.remove(corpus / "audio" / f"{first}.wav")  # one train clip fewer: other draws
    line = one_line_error(capsys, *base, "--split", "train=8", "--out", tmp_path / "o", "--grow")
    assert "would now be planned differently (the corpus, its clip checks or the RIR bank changed" in line
    assert "generate the larger dataset into a new --out" in line
