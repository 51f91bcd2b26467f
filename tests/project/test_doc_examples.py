"""The command examples of docs/ run, and show what they print today.

docs/examples.py runs every marked example (``<!-- run -->``) in a sandbox and compares
the output block below it with what the commands print now (durations, rates and free
disk space masked). Regenerate the pages with ``.venv/bin/python docs/examples.py``.
The pages run in groups, one test each, so that ``pytest -n 2`` runs them side by side;
the groups that read the demo dataset start from one copy of it, made once per run.
"""
from __future__ import annotations

import fcntl
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from support import REPO

DOCS = REPO / "docs"
# Python blocks that cannot run, by page (each says why in its `<!-- no run: ... -->` marker)
NOT_RUN = {
    "design.md": 1,   # lines to add to receivers/builtin.py, using its private helpers
    "scaling.md": 1,  # submits Slurm jobs from a cluster's login node
}


def examples_module():
    spec = importlib.util.spec_from_file_location("doc_examples", DOCS / "examples.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


ex = examples_module()


def doc_pages() -> list[str]:
    return sorted(str(p.relative_to(DOCS)) for p in [*DOCS.glob("*.md"), *DOCS.glob("commands/*.md")])


def test_every_page_has_runnable_examples_with_outputs():
    for page in ex.PAGES:
        found = ex.parse(page, (DOCS / page).read_text(encoding="utf-8"))
        runs = [e for e in found if e.kind == "run"]
        assert runs, f"{page} has no <!-- run --> example"
        # (a page whose examples need an optional extra may show none: training prints losses)
        assert any(e.out_span for e in runs) or all(e.needs() for e in runs), f"{page}: no example shows its output"
    # the masking is narrow: numbers other than durations, rates and free space count
    assert ex.normalise("plan 3.4 s, render 12 s (21.98 scenes/s), (82.2 GB free)") == \
        ex.normalise("plan 0.1 s, render 9 s (1.00 scenes/s), (1.0 GB free)")
    assert ex.normalise("340.6 MB on disk") != ex.normalise("340.7 MB on disk")


def test_every_python_block_of_the_docs_runs():
    """A Python block is a run example of a page the tests run, or one of the few that
    say why they cannot run."""
    not_run = {}
    for page in doc_pages():
        text = (DOCS / page).read_text(encoding="utf-8")
        unmarked = ex.unmarked_blocks(page, text)
        assert not unmarked, f"docs/{page}:{unmarked[0]}: a Python block without <!-- run --> (docs/examples.py)"
        blocks = [e for e in ex.parse(page, text) if e.lang == "python"]
        if any(e.kind == "run" for e in blocks):
            assert page in ex.PAGES, f"docs/{page} has run examples but is in no group of docs/examples.py"
        reasons = [e.options for e in blocks if e.kind == "no run"]
        assert all(reasons), f"docs/{page}: a <!-- no run --> marker says no reason"
        if reasons:
            not_run[page] = len(reasons)
    assert not_run == NOT_RUN


def test_parser_reads_markers_files_needs_and_outputs():
    page = ("text\n<!-- file: a.sh -->\n```bash\necho hi\n```\n\n<!-- run: stderr -->\n```bash\nbash a.sh\n```\n\n"
            "```\nhi\n```\n<!-- run -->\n```python\nprint(1)\n```\n<!-- run: needs torch lhotse -->\n```python\n1\n```\n"
            "  <!-- no run: a fragment -->\n  ```python\n  x = y\n  ```\n")
    a, b, c, d, e = ex.parse("x.md", page)
    assert (a.kind, a.options, b.options, b.shown, c.lang, c.out_span) == ("file", "a.sh", "stderr", "hi", "python",
                                                                         None)
    assert (c.needs(), d.needs(), e.kind, e.options, e.code) == ([], ["torch", "lhotse"], "no run", "a fragment",
                                                                 "  x = y\n")
    assert ex.unmarked_blocks("x.md", page) == []
    assert ex.unmarked_blocks("x.md", "a\n```python\nx\n```\n\n```bash\nls\n```\n    ```python\n    y\n    ```\n") == [2, 9]


def test_groups_hold_every_page_once_and_start_from_what_exists():
    assert sorted(ex.PAGES) == sorted(set(ex.PAGES))
    assert {start for start, _ in ex.GROUPS.values()} <= {"dataset", "corpus"}
    assert ex.GROUPS["generate"][1][0] == ex.BASE_PAGE


def test_a_sandbox_tsel_call_keeps_its_streams_exit_code_folder_and_environment(tmp_path):
    """``tsel`` in an example runs forked from the sandbox's server: stdout and stderr stay
    apart, the exit code and the error line are the command's, and the folder and the
    variables are the caller's."""
    with ex.Sandbox(tmp_path) as box:
        bash = ["bash", "-c", "tsel presets; tsel presets no-such-preset; echo \"rc=$?\"; "
                "X=7 doc-python -c 'import os, sys; print(os.getcwd(), os.environ[\"X\"]); sys.exit(3)' || echo rc=$?"]
        r = subprocess.run(bash, cwd=box.work, env=box.env, capture_output=True, text=True, timeout=120)
    out = r.stdout.splitlines()
    assert "demo" in r.stdout.split("rc=")[0] and out[-3] == "rc=2", r.stdout
    assert out[-2:] == [f"{box.work} 7", "rc=3"]
    assert r.stderr.startswith("error: ") and "no-such-preset" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert box.server is None and not Path(box.sock).exists()


@pytest.fixture(scope="session")
def doc_base(tmp_path_factory):
    """The sandbox after generate.md's first example, made once for every pytest worker
    of the run (they share the parent of their temporary folders)."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    base = root / "doc-base"
    with open(root / "doc-base.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the other workers wait for the one that makes it
        if not (base / "base-output.txt").exists():
            shutil.rmtree(base, ignore_errors=True)
            base.mkdir()
            ex.build_base(base)
    return base


@pytest.mark.slow
@pytest.mark.parametrize("group", list(ex.GROUPS))
def test_command_examples_in_docs_show_what_they_print(group, request):
    base = request.getfixturevalue("doc_base") if ex.GROUPS[group][0] == "dataset" else None
    stale = ex.run_group(group, base, check=True)
    assert not stale, "\n\n".join(stale) + "\n\nregenerate them: .venv/bin/python docs/examples.py"
