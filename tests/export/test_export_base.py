"""What every export keeps (tsel_data/export/base.py): it writes only into its own --out,
never over a file it did not write (--force to replace), replaces the splits it exports
and keeps the others, finishes an interrupted run, and says a user mistake in one line
(exit 2). The dataset card lists what the dataset holds."""
import json
import os

import pytest

from support.datasets import make_dataset
from tsel_data.cli import main
from tsel_data.errors import DatasetError, TselError
from tsel_data.export import WRITERS, export, resolve_writer, run_export
from tsel_data.export.base import JOURNAL_FILE, MANIFEST_FILE, parse_size
from tsel_data.export.webdataset import WebDatasetWriter

yaml = pytest.importorskip("yaml")  # comes with webdataset (the test extra)

ONE_SCENE = "600kB"  # a 4-channel 2 s scene at 16 kHz is 512 kB of float32: one per shard


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("base") / "ds"
    make_dataset(root, splits={"train": 3, "test": 2})
    return str(root)


def _one_line_exit_2(argv, capsys) -> str:
    with pytest.raises(SystemExit) as ex:
        main(argv)
    err = capsys.readouterr().err
    assert ex.value.code == 2 and err.count("\n") == 1 and err.startswith("error: "), err
    return err


def test_a_folder_of_other_files_is_refused_and_force_writes_beside_them(dataset, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    err = _one_line_exit_2(["export", "webdataset", dataset, "--out", str(out), "--no-card"], capsys)
    assert "holds files that are not a tsel export (notes.txt)" in err and "--force" in err
    assert sorted(os.listdir(out)) == ["notes.txt"]  # nothing written
    export("webdataset", dataset, str(out), force=True, card=False)
    assert (out / "notes.txt").read_text() == "mine" and (out / "index.json").is_file()


def test_a_file_the_export_did_not_write_is_never_written_over(dataset, tmp_path):
    out = tmp_path / "out"
    export("webdataset", dataset, str(out), splits=["train"], card=False)
    (out / "test").mkdir()
    (out / "test" / "test-000000.tar").write_bytes(b"someone else's")
    with pytest.raises(DatasetError, match=r"test-000000.tar already exists and was not written by tsel export .*--force"):
        export("webdataset", dataset, str(out), splits=["test"], card=False)
    assert (out / "test" / "test-000000.tar").read_bytes() == b"someone else's"
    export("webdataset", dataset, str(out), splits=["test"], card=False, force=True)
    assert (out / "test" / "test-000000.tar").stat().st_size > 1000


def test_exporting_a_split_again_replaces_it_and_keeps_the_others(dataset, tmp_path):
    out = tmp_path / "out"
    export("webdataset", dataset, str(out), shard_size=ONE_SCENE, card=False)
    assert sorted(os.listdir(out / "train")) == [f"train-00000{k}.tar" for k in range(3)]
    test_before = {p.name: p.stat().st_mtime_ns for p in (out / "test").iterdir()}
    export("webdataset", dataset, str(out), splits=["train"], shard_size="1GB", card=False)
    assert sorted(os.listdir(out / "train")) == ["train-000000.tar"]  # the finer shards are gone
    assert {p.name: p.stat().st_mtime_ns for p in (out / "test").iterdir()} == test_before
    index = json.loads((out / "index.json").read_text())
    assert {s: v["scenes"] for s, v in index["splits"].items()} == {"train": 3, "test": 2}
    assert [s["file"] for s in index["splits"]["test"]["shards"]] == ["test/test-000000.tar", "test/test-000001.tar"]
    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert manifest["complete"] and manifest["splits"]["train"]["files"] == ["train/train-000000.tar"]
    assert manifest["identity"]["dataset"] == os.path.relpath(dataset, out)  # no folder of this machine


def test_an_export_of_another_kind_is_refused_and_force_replaces_it(dataset, tmp_path, capsys):
    out = tmp_path / "out"
    export("webdataset", dataset, str(out), card=False)
    err = _one_line_exit_2(["export", "lhotse", dataset, "--out", str(out), "--no-card"], capsys)
    assert "holds an export of another kind webdataset (now lhotse)" in err
    export("lhotse", dataset, str(out), card=False, force=True)
    assert not (out / "train").exists() and not (out / "index.json").exists()  # the earlier export is gone
    assert (out / "tsel_cuts_train.jsonl.gz").is_file()


def test_an_interrupted_export_is_finished_by_running_it_again(dataset, tmp_path):
    out = tmp_path / "out"

    class Dies(WebDatasetWriter):
        def write_split(self, job, split):
            if split == "test":
                job.write_bytes("test/test-000000.tar", b"half")  # claimed, then the process dies
                raise KeyboardInterrupt
            return super().write_split(job, split)

    with pytest.raises(KeyboardInterrupt):
        run_export(Dies(shard_size=ONE_SCENE, card=False), dataset, str(out))
    assert (out / JOURNAL_FILE).is_file()
    run_export(WebDatasetWriter(card=False), dataset, str(out))  # ours: no --force needed
    assert not (out / JOURNAL_FILE).exists()
    assert sorted(os.listdir(out / "train")) == ["train-000000.tar"]
    assert (out / "test" / "test-000000.tar").stat().st_size > 1000


@pytest.mark.parametrize("argv,message", [
    (["--split", "val"], "no split 'val'; available splits: train, test"),
    (["--shard-size", "lots"], "size 'lots': expected bytes"),
])
def test_mistakes_are_one_line(dataset, tmp_path, capsys, argv, message):
    err = _one_line_exit_2(["export", "webdataset", dataset, "--out", str(tmp_path / "o"), *argv], capsys)
    assert message in err


def test_the_output_is_never_the_dataset_or_inside_it(dataset):
    with pytest.raises(DatasetError, match="is the dataset itself"):
        export("webdataset", dataset, dataset)
    with pytest.raises(DatasetError, match="is inside the dataset"):
        export("webdataset", dataset, os.path.join(dataset, "wds"))


def test_every_writer_is_a_command_with_its_declared_options(capsys):
    with pytest.raises(TselError, match="no export format 'parquet'; choose one of dcase, webdataset, hf"):
        resolve_writer("parquet")
    for name, writer in WRITERS.items():
        with pytest.raises(SystemExit):
            main(["export", name, "--help"])
        text = capsys.readouterr().out
        for o in (*writer.options, *writer.COMMON):
            assert "--" + o.name.replace("_", "-") in text, (name, o.name)
    assert parse_size("1.5GB") == 1_500_000_000 and parse_size("500kB") == 500_000 and parse_size(2048) == 2048


def test_the_card_says_what_the_dataset_holds(dataset, tmp_path):
    out = tmp_path / "card"
    export("card", dataset, str(out), figure=False)
    text = (out / "README.md").read_text()
    head = yaml.safe_load(text.split("---\n")[1])
    assert head["license"] == "other" and "mic4" in head["tags"] and head["size_categories"] == ["n<1K"]
    doc = json.loads(open(os.path.join(dataset, "dataset.json")).read())
    for needle in ("| train | 3 | yes |", "| test | 2 | yes |", "mic0_front_left", "16000 Hz",
                   "## Sources and licences", "## Known limits", "tsel generate --from REL", "2406.16058",
                   "@software{tsel_data", doc["conventions"]["azimuth"], "split train: 3 scenes"):
        assert needle in text, needle
    from tsel_data.export.card import config_hash

    assert config_hash(doc["config"]) in text
    export("card", dataset, str(out), figure=True)
    assert (out / "stats.png").read_bytes()[:4] == b"\x89PNG" and "![statistics per split](stats.png)" in \
        (out / "README.md").read_text()
