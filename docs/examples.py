"""Run the command examples of docs/ and write what they print back into the pages.

    .venv/bin/python docs/examples.py            # run every example, rewrite the shown outputs (and pictures)
    .venv/bin/python docs/examples.py --check    # run them, report outputs that differ (tests/project/test_doc_examples.py)
    .venv/bin/python docs/examples.py --jobs 2   # the page groups two at a time

An example is a fenced ``bash`` or ``python`` block right after a marker line::

    <!-- run -->                 run it; the plain fenced block after it, if any, is its stdout
    <!-- run: stderr -->         ... stdout and stderr, as a terminal shows them (progress bars aside)
    <!-- run: fails -->          ... it must fail (exit code not 0): an error example; implies stderr
    <!-- run: needs torch -->    ... only when these modules are installed (skipped, its output kept, otherwise;
                                 TSEL_DOC_WITHOUT=torch,lhotse checks the pages as a core install sees them)
    <!-- file: NAME -->          not run: the block is written to NAME for the examples after it
    <!-- no run: REASON -->      not run, and why (a Python block must carry a marker: tests/project/test_doc_examples.py)

Pages run in groups (:data:`GROUPS`), each group in its own sandbox folder, its pages
one after the other, so a page can use what an earlier one of its group made. A sandbox
starts as a copy of one *base* (:func:`build_base`): the sandbox after the first example
of generate.md, ``tsel generate --preset demo --out /tmp/tsel-demo``, whose dataset and
demo corpus the other pages read; or, for pages that read only the corpus, with the
demo corpus alone at ``/tmp/tsel-demo/demo-corpus``. Paths ``/tmp/tsel-*`` in examples are mapped into the sandbox and back
in the outputs, so running the examples touches nothing outside it (temporary files
included: ``TMPDIR`` is in the sandbox). ``sbatch`` is a stand-in that runs the tasks of
a ``--array`` one after the other (scaling.md). Shown outputs are compared with timings,
rates and free disk space masked (:func:`normalise`).

``tsel`` in an example, and every Python example, runs in a process forked from one
server per sandbox that has imported tsel-data and its heavy dependencies once
(:func:`serve`): each call still is its own process, with the caller's stdin, stdout and
stderr (the same pipes, so what is a terminal and what is not stays as it was), its
working folder, environment and exit code, but pays no start-up.
"""
from __future__ import annotations

import argparse
import difflib
import importlib
import importlib.util
import json
import os
import re
import shutil
import socket
import sqlite3
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
# pages checked together in one sandbox, in this order (a page may read what an earlier
# one of its group made: eval.md the DCASE export of export.md), and what the sandbox
# starts with: "dataset" (a copy of the base) or "corpus" (the demo corpus alone).
# Groups are independent of each other: the tests run them side by side (the corpus group
# first, so a second pytest worker has work while the first makes the base)
GROUPS = {
    "build": ("corpus", ["config.md", "scaling.md", "acoustics.md", "banks.md", "queries.md", "handmade.md"]),
    "generate": ("dataset", ["commands/generate.md"]),
    "read": ("dataset", ["commands/check.md", "commands/inspect.md", "commands/stats.md", "reader.md", "format.md"]),
    "verify": ("dataset", ["commands/verify.md", "baseline.md"]),
    "export": ("dataset", ["commands/export.md", "commands/eval.md", "spatial-language.md"]),
    "recorded": ("corpus", ["recorded.md"]),
}
PAGES = [page for _, pages in GROUPS.values() for page in pages]
# the example every sandbox starts from: generate.md's first, the demo dataset others read
BASE_PAGE = "commands/generate.md"
# pictures the pages show, copied from the sandbox when outputs are rewritten
PICTURES = {"work/inspect.png": "commands/img/inspect-test-000000.png", "work/stats.png": "commands/img/stats-demo.png",
            "work/inspect-bank.png": "commands/img/inspect-bank-test-000001.png",
            "work/sheet.png": "commands/img/inspect-sheet-test.png"}
CACHE = Path("home/.cache/tsel-data")  # the sandbox user's cache (HOME is the sandbox's home/)
_MARK = re.compile(r"^<!-- (run|file|no run)(?::\s*(.*?))? -->$")
_FENCE = re.compile(r"^```(\w*)\s*$")
# a stand-in for Slurm's sbatch: runs SCRIPT once per task of --array=A-B, in order
SBATCH = r"""#!/bin/bash
range=""; script=""
for a in "$@"; do case "$a" in --array=*) range="${a#--array=}";; --export=*|--*) ;; *) script="$a";; esac; done
lo="${range%-*}"; hi="${range#*-}"
for ((i = lo; i <= hi; i++)); do SLURM_ARRAY_TASK_ID=$i SLURM_CPUS_PER_TASK=${SLURM_CPUS_PER_TASK:-2} bash "$script" || exit 1; done
echo "Submitted batch job 1 ($((hi - lo + 1)) tasks)"
"""
# `tsel` (and `doc-python -c CODE`) of the sandbox: hands its argv, folder, environment
# and standard streams to the sandbox's server and exits with the command's code. Only
# the standard library, no site: it starts in milliseconds
CLIENT = r"""#!{python} -IS
import array, json, os, socket, sys
s = socket.socket(socket.AF_UNIX)
s.connect({sock!r})
msg = json.dumps({{"mode": os.path.basename(sys.argv[0]), "argv": sys.argv[1:], "cwd": os.getcwd(),
                  "env": dict(os.environ)}}).encode()
s.sendmsg([len(msg).to_bytes(4, "big") + msg], [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", [0, 1, 2]))])
code = b""
while len(code) < 4:
    part = s.recv(4 - len(code))
    if not part:
        sys.exit(1)  # the command's process died without an exit code (a signal)
    code += part
sys.exit(int.from_bytes(code, "big", signed=True))
"""
# imported once by the server, so that no command pays them: what the commands load
PRELOAD = ["numpy", "scipy.signal", "h5py", "soundfile", "pyroomacoustics", "tqdm", "click", "tsel_data.cli",
           *(f"tsel_data.cli.{m}" for m in ("bank", "check", "corpus", "dataset", "eval", "export", "inspect", "presets",
                                            "stats", "verify")),
           "tsel_data.job.pipeline", "tsel_data.job.shards", "tsel_data.render.mix", "tsel_data.plan.sampler", "tsel_data.plan.catalog",
           "tsel_data.job.preflight", "tsel_data.tools.stats", "tsel_data.tools.inspect", "tsel_data.tools.verify", "tsel_data.tools.evaluate",
           "tsel_data.tools.evaluate_dcase", "tsel_data.export", "tsel_data.corpus.demo", "tsel_data.store.check",
           "tsel_data.job.stems", "tsel_data.banks"]


@dataclass
class Example:
    page: str
    kind: str          # "run", "file" or "no run"
    options: str       # after "run:" / the file name after "file:" / the reason after "no run:"
    lang: str
    code: str
    out_span: tuple[int, int] | None  # lines of the shown output block's body, if any
    shown: str

    def needs(self) -> list[str]:
        """The modules a ``run: needs A B`` example needs."""
        m = re.search(r"\bneeds\s+([\w. ]+)", self.options)
        return m.group(1).split() if m else []


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
        f = _FENCE.match(lines[j].strip()) if j < len(lines) else None
        if not f:
            raise ValueError(f"{page}:{i + 1}: a marker must be followed by a fenced block")
        k = j + 1
        while not lines[k].strip().startswith("```"):
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


def unmarked_blocks(page: str, text: str, lang: str = "python") -> list[int]:
    """The lines (1-based) of ``lang`` blocks with no marker line right above them."""
    lines = text.split("\n")
    found, inside = [], False
    for i, line in enumerate(lines):
        f = _FENCE.match(line.strip())
        if not f and not line.strip().startswith("```"):
            continue
        if inside:
            inside = False
            continue
        inside = True
        if f and f.group(1) == lang:
            above = next((x.strip() for x in reversed(lines[:i]) if x.strip()), "")
            if not _MARK.match(above):
                found.append(i + 1)
    return found


def normalise(text: str) -> str:
    """An output with what changes from run to run masked: durations, rates, free space."""
    text = re.sub(r"\b\d+(\.\d+)? s\b", "<t> s", text)
    text = re.sub(r"\b\d+(\.\d+)? scenes/s\b", "<r> scenes/s", text)
    text = re.sub(r"\(\d+(\.\d+)? GB free\)", "(<f> GB free)", text)
    return text.rstrip()


def installed(module: str) -> bool:
    if module in os.environ.get("TSEL_DOC_WITHOUT", "").split(","):
        return False
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


class Sandbox:
    """A folder where the examples run, with /tmp/tsel-* mapped into it, and the server
    its ``tsel`` calls and Python examples are forked from (a context manager: leaving
    it stops the server)."""

    def __init__(self, root: Path):
        self.root = root
        self.work = root / "work"
        self.work.mkdir(parents=True, exist_ok=True)
        (root / "tmp").mkdir(exist_ok=True)
        bin_dir = root / "bin"
        bin_dir.mkdir(exist_ok=True)
        (bin_dir / "sbatch").write_text(SBATCH)
        venv = REPO / ".venv" / "bin"
        self.python = str(venv / "python") if (venv / "python").exists() else sys.executable
        # a folder of its own: a socket's path may not be longer than 107 bytes
        self.sock = os.path.join(tempfile.mkdtemp(prefix="tsel-sock-"), "server")
        client = CLIENT.format(python=self.python, sock=self.sock)
        for name in ("tsel", "doc-python"):
            (bin_dir / name).write_text(client)
        for name in ("sbatch", "tsel", "doc-python"):
            (bin_dir / name).chmod(0o755)
        # the sandbox is the user's home: its cache (prepared clips, clip checks) is
        # ~/.cache/tsel-data, as a user sees it, not a test session's folders
        inherited = {k: v for k, v in os.environ.items() if k not in ("TSEL_CLIP_CACHE", "TSEL_CACHE_DIR",
                                                                         "XDG_CACHE_HOME")}
        home = os.path.expanduser("~")
        self.env = {**inherited, "PATH": f"{bin_dir}:{venv}:{os.environ.get('PATH', '')}", "HOME": str(root / "home"),
                    # matplotlib's font list is the machine's: not built again per sandbox
                    "MPLCONFIGDIR": os.environ.get("MPLCONFIGDIR", os.path.join(home, ".config", "matplotlib")),
                    "PYTHONHASHSEED": "0", "COLUMNS": "120",
                    "TMPDIR": str(root / "tmp"),
                    "HF_HOME": str(root / "hf"), "HF_HUB_OFFLINE": "1"}  # datasets caches in the sandbox
        self.client = str(bin_dir / "doc-python")
        self.server = None

    def __enter__(self) -> "Sandbox":
        self.server = subprocess.Popen([self.python, str(Path(__file__).resolve()), "--serve", self.sock],
                                       cwd=self.work, env=self.env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                       text=True)
        if self.server.stdout.readline().strip() != "ready":
            self.server.wait()
            raise RuntimeError("the examples' server did not start")
        return self

    def __exit__(self, *exc) -> None:
        if self.server is not None:
            self.server.terminate()
            self.server.wait()
            self.server = None
        shutil.rmtree(os.path.dirname(self.sock), ignore_errors=True)

    def into(self, text: str) -> str:
        return re.sub(r"/tmp/(tsel-[\w.-]*)", lambda m: f"{self.root}/{m.group(1)}", text)

    def back(self, text: str) -> str:
        return text.replace(f"{self.root}/work/", "").replace(f"{self.root}/", "/tmp/")

    def run(self, ex: Example) -> str | None:
        """Run one example; its output as the page would show it (None: not run, a
        module it needs is not installed)."""
        if ex.kind == "no run" or not all(installed(m) for m in ex.needs()):
            return None
        if ex.kind == "file":
            (self.work / ex.options).write_text(self.into(ex.code))
            return ""
        fails = "fails" in ex.options
        merge = fails or "stderr" in ex.options
        if ex.lang == "python":
            cmd = [self.client, "-c", self.into(ex.code)]
        else:
            cmd = ["bash", "-e", "-o", "pipefail", "-c", ("exec 2>&1\n" if merge else "") + self.into(ex.code)]
        r = subprocess.run(cmd, cwd=self.work, env=self.env, capture_output=True, text=True, timeout=900)
        if (r.returncode != 0) != fails:
            raise RuntimeError(f"{ex.page}: example {'succeeded' if fails else 'failed'} (exit {r.returncode}):\n"
                               f"{ex.code}\n--- stdout\n{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-3000:]}")
        return self.back(r.stdout).rstrip()


def _share(src: str, dst: str) -> None:
    """Big files of the base are hard links (commands replace files, never write into
    them); the rest is copied, so that no sandbox changes another's."""
    if os.path.getsize(src) > 1 << 20:
        try:
            os.link(src, dst)
            return
        except OSError:  # another file system
            pass
    shutil.copy2(src, dst)


def _rename_remembered(cache: Path, old: Path, new: Path) -> None:
    """The clip checks the base remembered (its ``~/.cache/tsel-data``, keyed by absolute path)
    renamed to the copy's files, so the group's commands find them as they would in the
    folder where generate.md ran (they print the same either way; they only check less)."""
    for db in cache.glob("*.sqlite"):
        try:
            with sqlite3.connect(db) as con:
                con.execute("UPDATE checks SET path = ? || substr(path, ?) WHERE substr(path, 1, ?) = ?",
                            (str(new), len(str(old)) + 1, len(str(old)), str(old)))
            con.close()
        except sqlite3.Error:
            pass  # another layout of the cache: the commands check the clips again


def build_base(root: Path) -> None:
    """Run the first example of :data:`BASE_PAGE` in a sandbox at ``root``, keeping what
    it printed in ``root/base-output.txt`` (written last: its presence means done)."""
    first = parse(BASE_PAGE, (DOCS / BASE_PAGE).read_text(encoding="utf-8"))[0]
    with Sandbox(root) as box:
        out = box.run(first)
    (root / "base-output.txt").write_text(out, encoding="utf-8")


def run_pages(pages=PAGES, check: bool = False, base: Path | None = None, jobs: int = 1) -> list[str]:
    """Run every example of ``pages`` (with the pages of their groups before them) in new
    sandboxes; rewrite the pages' shown outputs (or, with ``check``, return one message per
    output that differs).

    ``base``: a folder :func:`build_base` made (made here, and removed, if not given);
    ``jobs``: groups run at once (each writes its own pages and pictures)."""
    groups = [g for g, (_, members) in GROUPS.items() if set(members) & set(pages)]
    own = base is None and any(GROUPS[g][0] == "dataset" for g in groups)
    if own:
        base = Path(tempfile.mkdtemp(prefix="tsel-doc-"))
        build_base(base)
    try:
        with ThreadPoolExecutor(max(1, jobs)) as pool:
            runs = [pool.submit(run_group, g, base, [p for p in GROUPS[g][1] if p in pages], check) for g in groups]
            return [s for run in runs for s in run.result()]
    finally:
        if own:
            shutil.rmtree(base, ignore_errors=True)


def run_group(group: str, base: Path | None = None, pages=None, check: bool = False) -> list[str]:
    """Run the pages of one group in a new sandbox (a copy of ``base`` for a group that
    starts with the dataset); rewrite (or check) ``pages`` of it (default: all)."""
    start, members = GROUPS[group]
    wanted = set(members if pages is None else pages)
    root = Path(tempfile.mkdtemp(prefix="tsel-doc-"))
    try:
        if start == "dataset":
            root.rmdir()
            shutil.copytree(base, root, copy_function=_share, symlinks=True,
                            ignore=shutil.ignore_patterns("base-output.txt", "home"))
            # the remembered clip checks, renamed to the copy's files (the prepared clips,
            # named by their clip's path, are made again where a page prepares)
            cache = root / CACHE
            cache.mkdir(parents=True)
            for db in (base / CACHE).glob("*.sqlite"):
                shutil.copyfile(db, cache / db.name)
            _rename_remembered(cache, base, root)
        with Sandbox(root) as box:
            if start == "corpus":
                box.run(Example("(corpus)", "run", "", "python", "from tsel_data.corpus.demo import synth_corpus\n"
                                "synth_corpus('/tmp/tsel-demo/demo-corpus', seed=0)\n", None, ""))
            stale = _run_group(box, base, members[:max(members.index(p) for p in wanted) + 1], wanted, check)
        if not check:
            for src, dst in PICTURES.items():
                if (root / src).exists():
                    shutil.copyfile(root / src, DOCS / dst)
        return stale
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _run_group(box: Sandbox, base: Path, pages, wanted, check: bool) -> list[str]:
    stale = []
    timings = os.environ.get("TSEL_DOC_TIMINGS")  # a file to append each example's seconds to
    for page in pages:
        path = DOCS / page
        text = path.read_text(encoding="utf-8")
        examples = parse(page, text)
        outputs = []
        for n, ex in enumerate(examples):
            t0 = time.perf_counter()
            if page == BASE_PAGE and n == 0:  # the base ran it
                outputs.append((base / "base-output.txt").read_text(encoding="utf-8"))
            else:
                outputs.append(box.run(ex))
            if timings:
                with open(timings, "a") as f:
                    f.write(f"{time.perf_counter() - t0:7.2f} {page} #{n} {ex.code.strip().splitlines()[0][:70]}\n")
        if page not in wanted:
            continue
        shown = [(ex, got) for ex, got in zip(examples, outputs) if ex.out_span is not None and got is not None]
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
    return stale


def serve(sock: str) -> None:
    """The server of a sandbox: import :data:`PRELOAD`, then fork one process per client
    connection (see :data:`CLIENT`), which takes the client's standard streams, folder
    and environment and runs ``tsel ARGV`` or ``python -c CODE``."""
    import signal

    os.environ["MPLBACKEND"] = "Agg"  # what the commands that draw ask for; no display is looked for
    for name in PRELOAD:
        try:
            importlib.import_module(name)
        except ImportError:
            pass
    srv = socket.socket(socket.AF_UNIX)
    srv.bind(sock)
    srv.listen(16)
    children = set()

    def stop(*_):
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, stop)
    print("ready", flush=True)
    try:
        while True:
            conn, _ = srv.accept()
            pid = os.fork()
            if pid == 0:
                srv.close()
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
                _serve_one(conn)
            conn.close()
            children.add(pid)
            children -= {p for p in list(children) if os.waitpid(p, os.WNOHANG)[0]}
    finally:
        # waited for, so that their CPU time counts in the caller's (`time`, getrusage)
        for pid in children:
            try:
                os.waitpid(pid, 0)
            except ChildProcessError:
                pass


def _serve_one(conn: socket.socket) -> None:
    """In a forked process: run what the client asks, send its exit code, and leave."""
    import array
    import atexit
    import traceback
    import types

    fds = array.array("i")
    cmsgs, data = [], b""
    while len(data) < 4 or len(data) < 4 + int.from_bytes(data[:4], "big"):
        part, anc, _, _ = conn.recvmsg(1 << 20, socket.CMSG_SPACE(3 * fds.itemsize))
        if not part:
            os._exit(1)
        data += part
        cmsgs += anc
    for level, kind, payload in cmsgs:
        if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
            fds.frombytes(payload[:len(payload) - len(payload) % fds.itemsize])
    msg = json.loads(data[4:])
    for target, fd in enumerate(fds):
        os.dup2(fd, target)
        os.close(fd)
    os.chdir(msg["cwd"])
    os.environ.clear()
    os.environ.update(msg["env"])
    code = 0
    try:
        if msg["mode"] == "tsel":
            sys.argv = ["tsel", *msg["argv"]]
            sys.path[0] = os.path.dirname(sys.executable)  # a console script's: its bin folder
            from tsel_data.cli import main

            main(msg["argv"])
        else:  # doc-python -c CODE: the code as the __main__ module, as python -c runs it
            sys.argv = ["-c", *msg["argv"][2:]]
            sys.path[0] = ""  # python -c imports from the working folder first
            main_module = types.ModuleType("__main__")
            sys.modules["__main__"] = main_module
            exec(compile(msg["argv"][1], "<string>", "exec"), main_module.__dict__)
    except SystemExit as e:
        if e.code is None or isinstance(e.code, int):
            code = e.code or 0
        else:
            print(e.code, file=sys.stderr)
            code = 1
    except BaseException:
        traceback.print_exc()
        code = 1
    try:
        atexit._run_exitfuncs()  # what the interpreter's exit would do: pools, files
        sys.stdout.flush()
        sys.stderr.flush()
    except BaseException:
        pass
    try:
        conn.sendall(int(code).to_bytes(4, "big", signed=True))
    finally:
        os._exit(code & 0xFF)


def main(argv=None) -> int:
    if argv is None and sys.argv[1:2] == ["--serve"]:
        serve(sys.argv[2])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="report stale outputs instead of rewriting them")
    ap.add_argument("--jobs", type=int, default=1, help="page groups to run at once (default: 1)")
    ap.add_argument("pages", nargs="*", help=f"pages to run (default: {', '.join(PAGES)})")
    args = ap.parse_args(argv)
    stale = run_pages(args.pages or PAGES, check=args.check, jobs=args.jobs)
    for s in stale:
        print(s, end="\n\n")
    print(f"{len(stale)} stale output(s)" if args.check else "outputs rewritten")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
