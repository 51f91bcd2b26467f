"""Benchmark: what a process pays before it does any work, in CPU seconds, this tree
against commit ccb3e9f in the same run.

    .venv/bin/python benchmarks/bench_startup.py [--repeats 7] [--against ccb3e9f]

Every pool worker, Dask worker, job-array task, DataLoader worker and ``tsel`` call pays
its imports again, so they are measured as a fresh process sees them: CPU time (user +
system) of a child process, from ``resource.getrusage(RUSAGE_CHILDREN)``, median of
``--repeats`` runs. Both trees run on this interpreter (the same .venv), each with
``PYTHONPATH`` at its own checkout; the other one is checked out into a temporary git
worktree, removed at the end. Runs of the two trees alternate, so both see the same load
of a shared machine; the ratio is the other tree's median over this one's.

Rows:
  import tsel_data.render.mix   ``python -X importtime -c "import tsel_data.render.mix"``
  + the simulator           the same and ``tsel_data.acoustics.shoebox``: what the first
                            simulated scene of a process adds (the methods are imported
                            when used)
  tsel --version, --help    the entry point
  tsel generate, 1 scene    the demo preset, one train scene, ``--workers 1``, from the
                            demo corpus synthesised once before the runs, every clip at
                            the scenes' 24 kHz (a clip at another rate imports
                            scipy.signal to be resampled: ``tsel corpus prepare``)

Goals (issue 25): the render import <= 0.6 s, ``tsel --version`` <= 0.4 s. Afterwards the
heaviest imports of this tree's render path are listed, from ``-X importtime``.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TSEL = os.path.join(os.path.dirname(sys.executable), "tsel")
GOALS = {"import tsel_data.render.mix": 0.6, "tsel --version": 0.4}
# the imports worth naming in the render path's list
NAMED = ("numpy", "scipy.fft", "scipy.signal", "scipy.special", "scipy.linalg", "h5py", "soundfile", "ducc0",
         "tsel_data.acoustics.shoebox")


# the demo corpus, its 16 and 44.1 kHz clips written at 24 kHz: a clip at another rate
# than the scenes' imports scipy.signal to resample it (as a corpus prepared with
# `tsel corpus prepare` never does), which is not what this benchmark is about
SETUP = """
import glob, soundfile as sf
from tsel_data.corpus.audio import load_clip
from tsel_data.corpus.demo import synth_corpus
synth_corpus({corpus!r}, seed=0)
for path in glob.glob({corpus!r} + "/audio/*.wav"):
    info = sf.info(path)
    if info.samplerate != 24000:
        sf.write(path, load_clip(path, 24000, info.duration), 24000, subtype="PCM_16")
"""


def rows(corpus: str, out: str) -> list[tuple[str, list[str]]]:
    py = sys.executable
    return [
        ("import tsel_data.render.mix", [py, "-X", "importtime", "-c", "import tsel_data.render.mix"]),
        ("+ the simulator", [py, "-X", "importtime", "-c", "import tsel_data.render.mix, tsel_data.acoustics.shoebox"]),
        ("tsel --version", [py, TSEL, "--version"]),
        ("tsel --help", [py, TSEL, "--help"]),
        ("tsel generate, 1 scene", [py, TSEL, "generate", "--preset", "demo", "--corpus-dir", corpus, "--split",
                                    "train=1", "--split", "val=0", "--split", "test=0", "--workers", "1", "--quiet",
                                    "--out", out]),
    ]


def child_cpu(cmd: list[str], tree: str, out: str) -> tuple[float, str]:
    """CPU seconds (user + system) of ``cmd`` run with ``tree`` first on the path; its stderr."""
    shutil.rmtree(out, ignore_errors=True)
    env = dict(os.environ, PYTHONPATH=tree)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(cmd, env=env, cwd=tempfile.gettempdir(), capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed in {tree}:\n{done.stderr}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), done.stderr


def heaviest(importtime: str) -> list[tuple[str, float]]:
    """Cumulative import times (s, wall) of the :data:`NAMED` modules in ``-X importtime``
    output (a module is imported once, so its line covers it wherever it was first needed)."""
    found = {}
    for line in importtime.splitlines():
        if line.startswith("import time:") and line.count("|") == 2:
            _, cumulative, name = line.split("|")
            if name.strip() in NAMED:
                found[name.strip()] = int(cumulative) / 1e6
    return sorted(found.items(), key=lambda kv: -kv[1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--against", default="ccb3e9f", help="the commit to compare with")
    opts = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="tsel-startup-") as tmp:
        other = os.path.join(tmp, opts.against)
        subprocess.run(["git", "-C", REPO, "worktree", "add", "--detach", other, opts.against], check=True,
                       capture_output=True)
        try:
            corpus = os.path.join(tmp, "corpus")
            subprocess.run([sys.executable, "-c", SETUP.format(corpus=corpus)], env=dict(os.environ, PYTHONPATH=REPO),
                           check=True)
            out = os.path.join(tmp, "out")
            table = rows(corpus, out)
            # one untimed round: file caches and .pyc files of both trees
            for _, cmd in table:
                for tree in (REPO, other):
                    child_cpu(cmd, tree, out)
            ours = {name: [] for name, _ in table}
            theirs = {name: [] for name, _ in table}
            stderr = ""
            for _ in range(opts.repeats):
                for name, cmd in table:
                    t, err = child_cpu(cmd, REPO, out)
                    ours[name].append(t)
                    stderr = err if name == "+ the simulator" else stderr
                    theirs[name].append(child_cpu(cmd, other, out)[0])
        finally:
            subprocess.run(["git", "-C", REPO, "worktree", "remove", "--force", other], capture_output=True)
            subprocess.run(["git", "-C", REPO, "worktree", "prune"], capture_output=True)

    print(f"bench_startup: CPU seconds of a fresh process (user + system), median of {opts.repeats}, "
          f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}")
    print(f"{'':26s} {'this tree':>10s} {opts.against:>10s} {'ratio':>7s}  goal")
    for name, _ in table:
        a, b = statistics.median(ours[name]), statistics.median(theirs[name])
        goal = GOALS.get(name)
        verdict = "" if goal is None else f"<= {goal:.1f} s: {'met' if a <= goal else 'NOT met'}"
        print(f"{name:26s} {a:10.3f} {b:10.3f} {b / a:6.2f}x  {verdict}")
    print("heaviest imports of this tree's render path with the simulator (wall s, from -X importtime): "
          + ", ".join(f"{m} {s:.3f}" for m, s in heaviest(stderr)))


if __name__ == "__main__":
    main()
