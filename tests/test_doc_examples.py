"""The command examples of docs/ run, and show what they print today.

docs/examples.py runs every marked example (``<!-- run -->``) in a sandbox and compares
the output block below it with what the commands print now (durations, rates and free
disk space masked). Regenerate the pages with ``.venv/bin/python docs/examples.py``.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def examples_module():
    spec = importlib.util.spec_from_file_location("doc_examples", DOCS / "examples.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def test_every_page_has_runnable_examples_with_outputs():
    ex = examples_module()
    for page in ex.PAGES:
        found = ex.parse(page, (DOCS / page).read_text(encoding="utf-8"))
        runs = [e for e in found if e.kind == "run"]
        assert runs, f"{page} has no <!-- run --> example"
        assert any(e.out_span for e in runs), f"{page}: no example shows its output"
    # the masking is narrow: numbers other than durations, rates and free space count
    assert ex.normalise("plan 3.4 s, render 12 s (21.98 scenes/s), (82.2 GB free)") == \
        ex.normalise("plan 0.1 s, render 9 s (1.00 scenes/s), (1.0 GB free)")
    assert ex.normalise("340.6 MB on disk") != ex.normalise("340.7 MB on disk")


def test_parser_reads_markers_files_and_outputs():
    ex = examples_module()
    page = ("text\n<!-- file: a.sh -->\n```bash\necho hi\n```\n\n<!-- run: stderr -->\n```bash\nbash a.sh\n```\n\n"
            "```\nhi\n```\n<!-- run -->\n```python\nprint(1)\n```\n")
    a, b, c = ex.parse("x.md", page)
    assert (a.kind, a.options, b.options, b.shown, c.lang, c.out_span) == ("file", "a.sh", "stderr", "hi", "python",
                                                                         None)


@pytest.mark.slow
def test_command_examples_in_docs_show_what_they_print():
    stale = examples_module().run_pages(check=True)
    assert not stale, "\n\n".join(stale) + "\n\nregenerate them: .venv/bin/python docs/examples.py"
