"""The Python examples in the docs run as written."""
import re
import runpy
from pathlib import Path
from support import REPO

DOCS = REPO / "docs"


def python_blocks(md: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", md.read_text(), re.S)


def test_banks_api_example_runs(tmp_path, monkeypatch):
    (code,) = python_blocks(DOCS / "banks.md")
    script = tmp_path / "example.py"
    script.write_text(code)
    monkeypatch.chdir(tmp_path)
    ns = runpy.run_path(str(script))
    bank, y, labels = ns["bank"], ns["y"], ns["labels"]
    assert bank.format == "foa" and bank.rooms == ["sim01"]
    assert y.shape[0] == 4 and y.shape[1] == 10 * bank.fs + ns["rirs"].shape[-1] - 1
    assert labels.shape == (100, 3) and (tmp_path / "demo-bank.h5").exists()


def test_config_doc_tables_match_the_schema():
    """docs/config.md's key tables are the schema's (regenerate: python -m tsel_data.config.doc docs/config.md)."""
    from tsel_data.config import SECTIONS
    from tsel_data.config.doc import render, tables

    text = (DOCS / "config.md").read_text(encoding="utf-8")
    assert render(text) == text, "docs/config.md is stale: run python -m tsel_data.config.doc docs/config.md"
    for name in ("top", "splits", *SECTIONS):
        assert f"<!-- keys:{name} -->" in text, f"docs/config.md has no table for {name}"
    assert "| `rt60` |" in tables()["room"] and "| s |" in tables()["room"]


def test_queries_example_runs(capsys):
    """docs/queries.md's on-the-fly example runs and prints one line per scene."""
    (code,) = python_blocks(DOCS / "queries.md")
    exec(compile(code, "queries.md", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4 and any(" relational " in line for line in lines)


def test_format_lists_every_spatial_kind():
    """Every value records write as a source's ``spatial`` is in docs/format.md's table."""
    from tsel_data.choices import Spatial

    row = next(line for line in (DOCS / "format.md").read_text(encoding="utf-8").splitlines()
               if line.startswith("| `spatial` |"))
    assert all(f"`{v.value}`" in row for v in Spatial), row
