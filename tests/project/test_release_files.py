"""The files a reviewer looks for agree with each other: one version, one licence, one citation."""
import re
import tomllib

from support import REPO
from tsel_data import __version__
from tsel_data.export import card


def cff_field(name: str) -> str:
    m = re.search(rf"^{name}:\s*\"?([^\"\n]+)\"?\s*$", (REPO / "CITATION.cff").read_text(), re.M)
    assert m, f"CITATION.cff has no {name}"
    return m.group(1)


def test_one_version_everywhere():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert project["version"] == __version__ == cff_field("version")
    changelog = (REPO / "CHANGELOG.md").read_text()
    newest = re.search(r"^## (\d+\.\d+\.\d+)", changelog, re.M)
    assert newest and newest.group(1) == __version__, "CHANGELOG.md's newest entry is not this version"
    assert f"version = {{{__version__}}}" in card.TOOL_BIBTEX


def test_licence_and_citation_agree():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert "MIT License" in (REPO / "LICENSE").read_text()
    assert cff_field("license") == "MIT" and "MIT" in str(project["license"])
    assert "license = {MIT}" in card.TOOL_BIBTEX
    assert re.search(rf"- name: \"{card.TOOL_AUTHORS}\"", (REPO / "CITATION.cff").read_text())
    assert cff_field("date-released").startswith(str(card.TOOL_YEAR))
    assert "2406.16058" in (REPO / "CITATION.cff").read_text() and "2406.16058" in card.PAPER_BIBTEX
