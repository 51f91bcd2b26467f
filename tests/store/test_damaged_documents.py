"""A dataset's own documents edited or cut short are named by `tsel check`, never a
traceback, never trusted (issue 24.5): a truncated plan line, dataset.json fields of the
wrong type."""
import json
import os
import shutil

import pytest

from support.datasets import make_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("damaged") / "ds"
    scenes = make_dataset(root, splits={"test": 3})
    os.makedirs(root / "plan")
    with open(root / "plan" / "test.jsonl", "w") as f:
        for s in scenes["test"]:
            f.write(json.dumps({"scene_id": s.scene_id}) + "\n")
    return root


def _copy(dataset, tmp_path):
    out = tmp_path / "ds"
    shutil.copytree(dataset, out)
    return out


def _errors(tsel_cli, root):
    code, out, err = tsel_cli.run("check", str(root))
    assert "Traceback" not in err and code != 0, (code, err)
    return [line for line in err.splitlines() if line.startswith("error:")]


def test_a_plan_cut_short_is_named_with_its_line(dataset, tmp_path, tsel_cli):
    root = _copy(dataset, tmp_path)
    assert tsel_cli.run("check", str(root))[0] == 0
    plan = root / "plan" / "test.jsonl"
    text = plan.read_text()
    plan.write_text(text[: len(text) - 12])  # the last line loses its end
    errors = _errors(tsel_cli, root)
    assert len(errors) == 1 and "plan/test.jsonl:3: a damaged plan line" in errors[0]


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["splits"]["test"].__setitem__("scenes", "3"), "splits.test.scenes is '3'"),
    (lambda d: d["splits"]["test"]["shards"][0].__setitem__("scenes", "2"), "splits.test.shards[0].scenes is '2'"),
    (lambda d: d["splits"]["test"]["shards"][0].__setitem__("scenes", True), "splits.test.shards[0].scenes is True"),
    (lambda d: d["splits"]["test"]["shards"][1].__setitem__("file", 7), "splits.test.shards[1].file is 7"),
    (lambda d: d.__setitem__("fs", "16000"), "fs is '16000'"),
])
def test_dataset_json_fields_of_the_wrong_type_are_refused(dataset, tmp_path, tsel_cli, edit, field):
    root = _copy(dataset, tmp_path)
    doc = json.loads((root / "dataset.json").read_text())
    edit(doc)
    (root / "dataset.json").write_text(json.dumps(doc))
    errors = _errors(tsel_cli, root)
    assert errors and field in errors[0] and "rerun `tsel finalize" in errors[0]
