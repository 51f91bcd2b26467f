"""The Python examples in the docs run as written."""
import re
import runpy
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"


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
