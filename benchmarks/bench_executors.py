"""What each executor costs for the same job, and what it leaves behind.

    .venv/bin/python benchmarks/bench_executors.py [--scenes 16] [--workers 2] [--repeats 3]

One ``tsel generate`` of the demo preset (``--scenes`` train scenes of 2 s, shards of 2)
per executor, each a fresh process into a fresh folder, from one demo corpus synthesised
before the runs; the executors take turns, so a busy machine slows each alike. Printed
per executor, median of ``--repeats``: wall seconds, CPU seconds the machine was busy
during the run (``/proc/stat``: every process the run started, however re-parented, and
whatever else ran meanwhile: run it on a quiet machine), the CPU ratio against ``local``, and the processes still alive afterwards that the run started
(children re-parented away are found by an environment tag each run carries). All three
write the same shard bytes (checked).
"""
from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
import uuid

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EXECUTORS = ("local", "dask-local")


def cpu_busy() -> float:
    """CPU seconds the whole machine has spent busy (user, nice, system, irq) since boot:
    counts every process a run started, however re-parented (a Dask forkserver's workers
    are not this script's children to wait for), plus whatever else ran meanwhile."""
    with open("/proc/stat") as f:
        user, nice, system, _idle, _iowait, irq, softirq, *_ = (int(v) for v in f.readline().split()[1:])
    return (user + nice + system + irq + softirq) / os.sysconf("SC_CLK_TCK")


def tagged(tag: str) -> list[int]:
    """Processes whose environment carries ``tag`` (started by one run, however re-parented)."""
    pids = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            with open(f"/proc/{pid}/environ", "rb") as f:
                if f"TSEL_BENCH_TAG={tag}".encode() in f.read().split(b"\0"):
                    pids.append(int(pid))
        except OSError:
            continue
    return pids


def shard_digest(out: str) -> str:
    h = hashlib.sha256()
    for split in sorted(os.listdir(out)):
        d = os.path.join(out, split)
        if not os.path.isdir(d) or split in ("plan", "demo-corpus"):
            continue
        for name in sorted(os.listdir(d)):
            if name.endswith(".h5"):
                with open(os.path.join(d, name), "rb") as f:
                    h.update(f.read())
    return h.hexdigest()[:12]


def run(executor: str, corpus: str, out: str, scenes: int, workers: int) -> dict:
    tag = uuid.uuid4().hex
    env = {**os.environ, "PYTHONPATH": ROOT, "TSEL_BENCH_TAG": tag}
    cmd = [sys.executable, "-m", "tsel_data.cli", "generate", "--preset", "demo", "--corpus-dir", corpus,
           "--out", out, "--split", f"train={scenes}", "--split", "val=0", "--split", "test=0",
           "--set", "audio.duration=2.0", "--set", "output.shard_size=2", "--workers", str(workers),
           "--executor", executor, "--quiet", "--allow-reuse"]
    c0, t0 = cpu_busy(), time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, cpu_busy() - c0
    if done.returncode:
        raise SystemExit(f"{executor}: exit {done.returncode}: {done.stderr.strip()[-400:]}")
    time.sleep(1.0)  # a process that is leaving has a moment to go
    return {"wall": wall, "cpu": cpu, "left": len(tagged(tag)), "digest": shard_digest(out)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=int, default=16)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="tsel-bench-exec-")
    try:
        corpus = os.path.join(tmp, "corpus")
        subprocess.run([sys.executable, "-m", "tsel_data.cli", "corpus", "synth", "--out", corpus],
                       env={**os.environ, "PYTHONPATH": ROOT}, check=True, capture_output=True)
        runs: dict[str, list[dict]] = {e: [] for e in EXECUTORS}
        for k in range(args.repeats):
            for e in EXECUTORS:
                out = os.path.join(tmp, f"{e}-{k}")
                runs[e].append(run(e, corpus, out, args.scenes, args.workers))
                shutil.rmtree(out)
        med = {e: {key: sorted(r[key] for r in rs)[len(rs) // 2] for key in ("wall", "cpu", "left")}
               for e, rs in runs.items()}
        digests = {r["digest"] for rs in runs.values() for r in rs}
        print(f"bench_executors: {args.scenes} demo scenes of 2 s, --workers {args.workers}, median of "
              f"{args.repeats}, load {os.getloadavg()[0]:.2f}")
        print(f"{'executor':<12}{'wall s':>8}{'CPU s':>8}{'CPU ratio':>11}{'left running':>14}")
        for e in EXECUTORS:
            m = med[e]
            print(f"{e:<12}{m['wall']:>8.2f}{m['cpu']:>8.2f}{m['cpu'] / med['local']['cpu']:>10.2f}x"
                  f"{max(r['left'] for r in runs[e]):>14d}")
        print("shard bytes: " + ("the same for every executor" if len(digests) == 1 else f"DIFFER: {digests}"))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
