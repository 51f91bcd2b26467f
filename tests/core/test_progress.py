"""Long work shows a bar with a count and a rate, on a terminal: verify, export, bank
build, bank import, the clip check (test_corpora), generate (test_pipeline)."""
from __future__ import annotations

import re

import pytest

from support import banks as bankfixtures
from support import datasets as datasetfixture


@pytest.fixture
def terminal(monkeypatch):
    """stderr counts as a terminal (bars show); capsys still captures it."""
    import tsel_data.core.progress

    monkeypatch.setattr(tsel_data.core.progress, "on_terminal", lambda: True)


def cli(capsys, *args) -> tuple[int, str, str]:
    from tsel_data.cli import main

    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


def final_bars(err: str) -> dict[str, str]:
    """{description: the bar's last state} from tqdm's carriage-return updates."""
    out = {}
    for part in re.split(r"[\r\n]", err):
        m = re.match(r"\s*([\w .-]+?): +\d+%", part)
        if m:
            out[m.group(1)] = part
    return out


def test_verify_and_export_show_a_bar_per_split(tmp_path, capsys, terminal):
    datasetfixture.make_dataset(tmp_path / "ds", splits={"train": 3, "test": 2})
    code, _, err = cli(capsys, "verify", tmp_path / "ds")
    assert code == 0
    bars = final_bars(err)
    assert "3/3" in bars["verify train"] and "2/2" in bars["verify test"] and "scene/s" in bars["verify test"]
    code, _, err = cli(capsys, "export", "dcase", tmp_path / "ds", "--out", tmp_path / "dc", "--subtype", "FLOAT")
    assert code == 0
    bars = final_bars(err)
    assert "3/3" in bars["export train"] and "2/2" in bars["export test"] and "scene/s" in bars["export train"]
    # --quiet: none
    code, _, err = cli(capsys, "verify", tmp_path / "ds", "--quiet")
    assert code == 0 and err == ""


def test_bank_build_and_import_show_a_bar(tmp_path, capsys, terminal):
    code, _, err = cli(capsys, "bank", "build", "--out", tmp_path / "b.h5", "--rooms", "2", "--step", "45",
                       "--distances", "1.0", "--heights", "0", "--fs", "8000", "--rir-seconds", "0.05")
    assert code == 0, err
    assert re.search(r"2/2 \[.*(room/s|s/room)\]", final_bars(err)["simulate"])  # count and rate
    bankfixtures.make_tau_db(tmp_path / "tau")
    code, _, err = cli(capsys, "bank", "import", "tau", "--src", tmp_path / "tau", "--out", tmp_path / "t.h5")
    assert code == 0, err
    shown = final_bars(err)["import"]
    assert "RIR/s" in shown and re.search(r"(\d+)/\1", shown)  # every RIR counted


def test_no_bar_off_a_terminal(tmp_path, capsys):
    datasetfixture.make_dataset(tmp_path / "ds", splits={"test": 2})
    code, _, err = cli(capsys, "verify", tmp_path / "ds")
    assert code == 0 and err == ""
