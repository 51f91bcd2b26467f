"""Run the command examples of docs/ and write what they print back into the pages.

    .venv/bin/python docs/examples.py            # run every example, rewrite the shown outputs (and pictures)
    .venv/bin/python docs/examples.py --check    # run them, report outputs that differ (tests/test_doc_examples.py)

An example is a fenced ``bash`` or ``python`` block right after a marker line::

    <!-- run -->                 run it; the plain fenced block after it, if any, is its stdout
    <!-- run: stderr -->         ... stdout and stderr, as a terminal shows them (progress bars aside)
    <!-- run: fails -->          ... it must fail (exit code not 0): an error example; implies stderr
    <!-- file: NAME -->          not run: the block is written to NAME for the examples after it

Pages run in the order of :data:`PAGES`, in one sandbox folder, one after the other, so
a page can use what an earlier one made (``/tmp/tsel-demo`` is made by generate.md).
Paths ``/tmp/tsel-*`` in examples are mapped into the sandbox and back in the outputs,
so running the examples touches nothing outside it. ``sbatch`` is a stand-in that runs
the tasks of a ``--array`` one after the other (scaling.md). Shown outputs are compared
with timings, rates and free disk space masked (:func:`normalise`).
"""
from __future__ import annotations

import argparse
import difflib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
PAGES = ["commands/generate.md", "commands/check.md", "commands/inspect.md", "commands/stats.md",
         "commands/export.md", "commands/eval.md", "commands/verify.md", "config.md", "scaling.md", "acoustics.md"]
# pictures the pages show, copied from the sandbox when outputs are rewritten
PICTURES = {"work/inspect.png": "commands/img/inspect-test-000000.png", "work/stats.png": "commands/img/stats-demo.png",
            "work/inspect-bank.png": "commands/img/inspect-bank-test-000001.png",
            "work/sheet.png": "commands/img/inspect-sheet-test.png"}
_MARK = re.compile(r"^<!-- (run|file)(?::\s*(.*?))? -->$")
_FENCE = re.compile(r"^```(\w*)\s*$")
# a stand-in for Slurm's sbatch: runs SCRIPT once per task of --array=A-B, in order
SBATCH = r"""#!/bin/bash
range=""; script=""
for a in "$@"; do case "$a" in --array=*) range="${a#--array=}";; --export=*|--*) ;; *) script="$a";; esac; done
lo="${range%-*}"; hi="${range#*-}"
for ((i = lo; i <= hi; i++)); do SLURM_ARRAY_TASK_ID=$i SLURM_CPUS_PER_TASK=${SLURM_CPUS_PER_TASK:-2} bash "$script" || exit 1; done
echo "Submitted batch job 1 ($((hi - lo + 1)) tasks)"
"""


@dataclass
class Example:
    page: str
    kind: str          # "run" or "file"
    options: str       # after "run:" / the file name after "file:"
    lang: str
    code: str
    out_span: tuple[int, int] | None  # lines of the shown output block's body, if any
    shown: str


def parse(page: str, text: str) -> list[Example]:
    """The marked blocks of a page, in order."""
    lines = text.split("\n")
    out, i = [], 0
    while i < len(lines):
        m = _MARK.match(lines[i].strip())
        if not m:
            i += 1
            continue
        j = i + 1
        f = _FENCE.match(lines[j]) if j < len(lines) else None
        if not f:
            raise ValueError(f"{page}:{i + 1}: a marker must be followed by a fenced block")
        k = j + 1
        while not lines[k].startswith("```"):
            k += 1
        code = "\n".join(lines[j + 1:k]) + "\n"
        span, shown = None, ""
        n = k + 1
        while n < len(lines) and not lines[n].strip():
            n += 1
        if m.group(1) == "run" and n < len(lines) and _FENCE.match(lines[n]) and _FENCE.match(lines[n]).group(1) in ("", "text"):
            e = n + 1
            while not lines[e].startswith("```"):
                e += 1
            span, shown = (n + 1, e), "\n".join(lines[n + 1:e])
            k = e
        out.append(Example(page, m.group(1), (m.group(2) or "").strip(), f.group(1), code, span, shown))
        i = k + 1
    return out


def normalise(text: str) -> str:
    """An output with what changes from run to run masked: durations, rates, free space."""
    text = re.sub(r"\b\d+(\.\d+)? s\b", "<t> s", text)
    text = re.sub(r"\b\d+(\.\d+)? scenes/s\b", "<r> scenes/s", text)
    text = re.sub(r"\(\d+(\.\d+)? GB free\)", "(<f> GB free)", text)
    return text.rstrip()


class Sandbox:
    """A folder where the examples run, with /tmp/tsel-* mapped into it."""

    def __init__(self, root: Path):
        self.root = root
        self.work = root / "work"
        self.work.mkdir(parents=True, exist_ok=True)
        bin_dir = root / "bin"
        bin_dir.mkdir(exist_ok=True)
        (bin_dir / "sbatch").write_text(SBATCH)
        (bin_dir / "sbatch").chmod(0o755)
        venv = REPO / ".venv" / "bin"
        self.env = {**os.environ, "PATH": f"{bin_dir}:{venv}:{os.environ.get('PATH', '')}",
                    "TSEL_CACHE_DIR": str(root / "cache"), "PYTHONHASHSEED": "0", "COLUMNS": "120",
                    "HF_HOME": str(root / "hf"), "HF_HUB_OFFLINE": "1"}  # datasets caches in the sandbox
        self.python = str(venv / "python") if (venv / "python").exists() else sys.executable

    def into(self, text: str) -> str:
        return re.sub(r"/tmp/(tsel-[\w.-]*)", lambda m: f"{self.root}/{m.group(1)}", text)

    def back(self, text: str) -> str:
        return text.replace(f"{self.root}/work/", "").replace(f"{self.root}/", "/tmp/")

    def run(self, ex: Example) -> str:
        """Run one example; its output as the page would show it."""
        if ex.kind == "file":
            (self.work / ex.options).write_text(self.into(ex.code))
            return ""
        fails = "fails" in ex.options
        merge = fails or "stderr" in ex.options
        if ex.lang == "python":
            cmd = [self.python, "-c", self.into(ex.code)]
        else:
            cmd = ["bash", "-e", "-o", "pipefail", "-c", ("exec 2>&1\n" if merge else "") + self.into(ex.code)]
        r = subprocess.run(cmd, cwd=self.work, env=self.env, capture_output=True, text=True, timeout=900)
        if (r.returncode != 0) != fails:
            raise RuntimeError(f"{ex.page}: example {'succeeded' if fails else 'failed'} (exit {r.returncode}):\n"
                               f"{ex.code}\n--- stdout\n{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-3000:]}")
        return self.back(r.stdout).rstrip()


def run_pages(pages=PAGES, check: bool = False) -> list[str]:
    """Run every example of ``pages`` in a new sandbox; rewrite the pages' shown outputs
    (or, with ``check``, return one message per output that differs).

    The sandbox is a fresh ``tempfile.mkdtemp`` folder: its path has the same length on
    every run, and datasets store absolute clip paths, so sizes on disk compare."""
    root = Path(tempfile.mkdtemp(prefix="tsel-doc-"))
    try:
        return _run_pages(root, pages, check)
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _run_pages(root: Path, pages, check: bool) -> list[str]:
    box = Sandbox(root)
    stale = []
    wanted = set(pages)
    last = max(PAGES.index(p) for p in wanted)
    for page in PAGES[:last + 1]:  # the pages before a wanted one make what it uses
        path = DOCS / page
        text = path.read_text(encoding="utf-8")
        examples = parse(page, text)
        outputs = [box.run(ex) for ex in examples]
        if page not in wanted:
            continue
        shown = [(ex, got) for ex, got in zip(examples, outputs) if ex.out_span is not None]
        if check:
            for ex, got in shown:
                if normalise(got) != normalise(ex.shown):
                    diff = "\n".join(difflib.unified_diff(ex.shown.split("\n"), got.split("\n"), "shown", "now",
                                                          lineterm="", n=1))
                    stale.append(f"{page}: the output of\n{ex.code.strip()}\nis stale:\n{diff}")
            continue
        lines = text.split("\n")
        for ex, got in reversed(shown):  # last first: the earlier spans stay where they are
            a, b = ex.out_span
            lines[a:b] = got.split("\n") if got else []
        path.write_text("\n".join(lines), encoding="utf-8")
    if not check:
        for src, dst in PICTURES.items():
            if (root / src).exists():
                shutil.copyfile(root / src, DOCS / dst)
    return stale


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="report stale outputs instead of rewriting them")
    ap.add_argument("pages", nargs="*", help=f"pages to run (default: {', '.join(PAGES)})")
    args = ap.parse_args(argv)
    stale = run_pages(args.pages or PAGES, check=args.check)
    for s in stale:
        print(s, end="\n\n")
    print(f"{len(stale)} stale output(s)" if args.check else "outputs rewritten")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
