"""Side outputs never overwrite (issue 24 §1 and §5, docs/reliability.md): a command that
writes a file the user names (inspect --png/--wav, stats --png, export, corpus
synth/prepare/embed, bank build/import) refuses, in one line and exit 2 unless --force,
a path inside a dataset, export or bank folder and an existing file it did not write;
its own earlier outputs it replaces (store/outputs.py)."""
import json
import os

import pytest

from support.banks import make_tau_db
from support.datasets import make_dataset
from tsel_data.core.digest import sha256_file
from tsel_data.store.outputs import REGISTRY_FILE


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("side") / "ds"
    make_dataset(root, splits={"train": 2, "test": 2})
    return str(root)


def hashes(root) -> dict:
    return {os.path.relpath(os.path.join(d, f), root): sha256_file(os.path.join(d, f))
            for d, _, names in os.walk(root) for f in names}


# --- inside a dataset, an export, a bank folder ------------------------------------------------


@pytest.mark.parametrize("target", ["train/shard-00000.h5", "dataset.json", "new.png"])
def test_inspect_and_stats_never_write_inside_the_dataset(dataset, tsel_cli, target):
    before = hashes(dataset)
    path = os.path.join(dataset, target)
    for argv in (["inspect", dataset, "test/0", "--png", path], ["inspect", dataset, "test/0", "--wav", path,
                                                                  "--no-stems"],
                 ["stats", dataset, "--png", path]):
        line = tsel_cli.refused(*argv)
        assert f"is inside the dataset {os.path.realpath(dataset)}" in line and "--force" in line, line
    assert hashes(dataset) == before


def test_force_writes_inside_the_dataset(tmp_path, tsel_cli):
    root = tmp_path / "ds"
    make_dataset(root, splits={"test": 2})
    tsel_cli.ok("stats", root, "--png", root / "stats.png", "--force")
    assert (root / "stats.png").stat().st_size > 1000


def test_nothing_is_written_into_a_bank_folder_or_an_export(dataset, tmp_path, tsel_cli):
    make_tau_db(tmp_path / "TAU-SRIR_DB", rooms=(("bomb_shelter", 1),))
    line = tsel_cli.refused("stats", dataset, "--png", tmp_path / "TAU-SRIR_DB" / "s.png")
    assert "is inside the RIR bank" in line
    line = tsel_cli.refused("bank", "build", "--out", tmp_path / "TAU-SRIR_DB" / "b.h5", "--rooms", "1")
    assert "is inside the RIR bank" in line
    tsel_cli.ok("export", "dcase", dataset, "--out", tmp_path / "dc", "--no-card")
    line = tsel_cli.refused("inspect", dataset, "test/0", "--png", tmp_path / "dc" / "x.png")
    assert "is inside the export" in line


def test_an_export_goes_neither_into_nor_inside_another_dataset(dataset, tmp_path, tsel_cli):
    other = tmp_path / "other"
    make_dataset(other, splits={"test": 1})
    before = hashes(other)
    assert "is a dataset" in tsel_cli.refused("export", "dcase", dataset, "--out", other, "--force")
    assert "is inside the dataset" in tsel_cli.refused("export", "dcase", dataset, "--out", other / "dcase")
    assert hashes(other) == before


# --- files that are not the command's own --------------------------------------------------------


def test_inspect_refuses_the_users_files_and_sibling_stems_before_writing_any(dataset, tmp_path, tsel_cli):
    for sibling in ("x.wav", "x.stereo.wav", "x.target.stereo.wav", "x.interferer1.stereo.wav"):
        d = tmp_path / sibling
        d.mkdir()
        (d / sibling).write_bytes(b"mine")
        line = tsel_cli.refused("inspect", dataset, "test/0", "--png", d / "x.png", "--wav", d / "x.wav")
        assert f"{sibling} already exists and was not written by tsel inspect" in line and "--force" in line, line
        assert sorted(os.listdir(d)) == [sibling] and (d / sibling).read_bytes() == b"mine"


def test_own_outputs_are_replaced_others_never(dataset, tmp_path, tsel_cli):
    png, wav = tmp_path / "i.png", tmp_path / "i.wav"
    argv = ["inspect", dataset, "test/0", "--png", png, "--wav", wav, "--no-stems"]
    tsel_cli.ok(*argv)
    tsel_cli.ok(*argv)  # its own: replaced without --force
    listed = json.loads((tmp_path / REGISTRY_FILE).read_text())["files"]
    assert {n: e["by"] for n, e in listed.items()} == {"i.png": "tsel inspect", "i.wav": "tsel inspect",
                                                       "i.stereo.wav": "tsel inspect"}
    with open(wav, "ab") as f:  # the user edits it: no longer ours
        f.write(b"my notes")
    assert "i.wav already exists and changed since tsel inspect wrote it" in tsel_cli.refused(*argv)
    assert wav.read_bytes().endswith(b"my notes")
    assert "written by tsel inspect, not by tsel stats" in tsel_cli.refused("stats", dataset, "--png", png)
    tsel_cli.ok(*argv, "--force")
    tsel_cli.ok(*argv)  # written under --force, it is ours again


def test_a_name_given_twice_is_refused(dataset, tmp_path, tsel_cli):
    line = tsel_cli.refused("inspect", dataset, "test/0", "--png", tmp_path / "x.wav", "--wav", tmp_path / "x.wav")
    assert "is named twice" in line and not list(tmp_path.iterdir())


def test_stats_png_refuses_a_user_file_and_replaces_its_own(dataset, tmp_path, tsel_cli):
    mine = tmp_path / "mine.png"
    mine.write_bytes(b"my picture")
    line = tsel_cli.refused("stats", dataset, "--png", mine)
    assert "mine.png already exists and was not written by tsel stats" in line
    assert mine.read_bytes() == b"my picture"
    tsel_cli.ok("stats", dataset, "--png", tmp_path / "s.png")
    tsel_cli.ok("stats", dataset, "--png", tmp_path / "s.png")


def test_export_dcase_keeps_a_users_queries_csv_and_wav(dataset, tmp_path, tsel_cli):
    out = tmp_path / "dc"
    tsel_cli.ok("export", "dcase", dataset, "--out", out, "--no-card")
    queries = out / "queries.csv"
    wav = next((out / "mic_dev" / "dev-test-tsel").glob("*.wav"))
    queries.write_text(queries.read_text() + "my,own,annotations,of,these\n")
    line = tsel_cli.refused("export", "dcase", dataset, "--out", out, "--no-card")
    assert "queries.csv already exists and changed since tsel export dcase wrote it" in line, line
    assert queries.read_text().endswith("my,own,annotations,of,these\n")
    tsel_cli.ok("export", "dcase", dataset, "--out", out, "--no-card", "--force")
    wav.write_bytes(b"my own recording")
    line = tsel_cli.refused("export", "dcase", dataset, "--out", out, "--no-card", "--split", "test")
    assert f"{wav.name} already exists and changed since" in line and wav.read_bytes() == b"my own recording"
    tsel_cli.ok("export", "dcase", dataset, "--out", out, "--no-card", "--split", "test", "--force")
    assert wav.stat().st_size > 1000


def test_an_export_does_not_remove_a_file_the_user_changed(dataset, tmp_path, tsel_cli):
    """Exporting fewer files than before removes the earlier ones, but not one the user rewrote."""
    out = tmp_path / "dc"
    tsel_cli.ok("export", "dcase", dataset, "--out", out)
    card = out / "README.md"
    card.write_text("my card")
    tsel_cli.ok("export", "dcase", dataset, "--out", out, "--no-card")
    assert card.read_text() == "my card"


# --- corpus and bank commands -----------------------------------------------------------------------


def test_corpus_synth_refuses_the_users_manifest_and_replaces_its_own(dataset, tmp_path, tsel_cli):
    mine = tmp_path / "c" / "train.csv"
    mine.parent.mkdir()
    mine.write_text("my manifest\n")
    line = tsel_cli.refused("corpus", "synth", "--out", mine.parent, "--clips-per-type", "1,1,1")
    assert "train.csv already exists and was not written by tsel corpus synth" in line
    assert os.listdir(mine.parent) == ["train.csv"] and mine.read_text() == "my manifest\n"
    assert "is inside the dataset" in tsel_cli.refused("corpus", "synth", "--out", os.path.join(dataset, "corpus"))
    tsel_cli.ok("corpus", "synth", "--out", tmp_path / "d", "--clips-per-type", "1,1,1")
    tsel_cli.ok("corpus", "synth", "--out", tmp_path / "d", "--clips-per-type", "1,1,1")


def test_corpus_embed_refuses_before_the_model_runs(tmp_path, tsel_cli, demo_corpus):
    out = tmp_path / "e.npz"
    out.write_bytes(b"my vectors")
    line = tsel_cli.refused("corpus", "embed", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", out)
    assert "e.npz already exists and was not written by tsel corpus embed" in line and out.read_bytes() == b"my vectors"


def test_corpus_prepare_refuses_a_clip_cache_inside_a_dataset(dataset, tsel_cli, demo_corpus, monkeypatch):
    monkeypatch.setenv("TSEL_CLIP_CACHE", os.path.join(dataset, "clips"))
    line = tsel_cli.refused("corpus", "prepare", "--preset", "demo", "--corpus-dir", demo_corpus)
    assert line.startswith("error: $TSEL_CLIP_CACHE ") and "is inside the dataset" in line
    assert not os.path.exists(os.path.join(dataset, "clips"))


def test_bank_build_and_import_replace_their_own_banks_only(tmp_path, tsel_cli):
    small = ["--rooms", "1", "--step", "30", "--distances", "1.0", "--heights", "0"]
    out = tmp_path / "b.h5"
    tsel_cli.ok("bank", "build", "--out", out, *small)
    tsel_cli.ok("bank", "build", "--out", out, *small, "--seed", "1")  # its own: no --force needed
    make_tau_db(tmp_path / "tau", rooms=(("bomb_shelter", 1),))
    tsel_cli.ok("bank", "import", "tau", "--src", tmp_path / "tau", "--out", out)  # a bank replaces a bank
    picture = tmp_path / "p.png"
    picture.write_bytes(b"mine")
    line = tsel_cli.refused("bank", "import", "tau", "--src", tmp_path / "tau", "--out", picture)
    assert "p.png already exists and was not written by tsel bank" in line
    assert picture.read_bytes() == b"mine"


# --- §5: another tool's dataset.json --------------------------------------------------------------


def test_generate_does_not_take_a_folder_with_another_tools_dataset_json(tmp_path, tsel_cli, demo_corpus):
    out = tmp_path / "theirs"
    out.mkdir()
    (out / "dataset.json").write_text(json.dumps({"name": "another tool's dataset", "splits": {}}))
    line = tsel_cli.refused("generate", "--preset", "demo", "--corpus-dir", demo_corpus, "--out", out, "--quiet",
                   "--split", "train=1", "--split", "val=0", "--split", "test=0")
    assert "not a tsel-data dataset" in line and "--force" in line
    assert os.listdir(out) == ["dataset.json"]
