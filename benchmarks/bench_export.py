"""Exports and streaming against the HDF5 files they come from, measured in one run.

    .venv/bin/python benchmarks/bench_export.py [--dataset DIR] [--repeats 5]

On the demo dataset (72 scenes of 10 s, 24 kHz mic4; made in a temporary folder unless
``--dataset`` names one), warm page cache, best of ``--repeats``, the
contestants taking turns (a busy machine slows each alike):

1. **export vs copy**: ``tsel export webdataset`` (the library call, in the dataset's own
   coding, its card included and left out) against copying the dataset's HDF5 shard files
   to a new folder (``shutil.copyfile``, each file then fsynced, as the export's atomic
   writes are; plain copies without fsync are shown too). The ratio is export / copy;
   issue 23 asks for <= 1.5.
2. **streaming vs the HDF5 reader**: scenes/s of ``SceneStream`` over the export's train
   split (in order, and through a 16-scene shuffle buffer) against ``open_dataset(DIR,
   "train")[i]`` for every scene. The ratio is stream / reader; issue 23 asks for >= 0.8.

A stream tunes its process's malloc to keep freed memory (``tsel_data.runtime.malloc``); the
benchmark sets it before the first run, so every contestant runs with the same setting.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from tsel_data.config import load_config  # noqa: E402
from tsel_data.export import export  # noqa: E402
from tsel_data.runtime.malloc import reuse_freed_memory  # noqa: E402
from tsel_data.job.pipeline import generate  # noqa: E402
from tsel_data.store.dataset import load_dataset_doc  # noqa: E402
from tsel_data.store.reader import open_dataset  # noqa: E402
from tsel_data.tools.streaming import SceneStream  # noqa: E402


def best(fns: dict, repeats: int) -> dict:
    """{name: the shortest of ``repeats`` runs of fn() (s)}, the functions taking turns,
    so that a busy machine slows each of them alike and the ratios stay fair."""
    times = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t0)
    return {name: min(t) for name, t in times.items()}


def h5_files(root: str) -> list[str]:
    doc = load_dataset_doc(root)
    return [os.path.join(root, e.file) for entries in doc.splits.values() for e in entries]


def copy_files(files, dst: str, sync: bool) -> None:
    shutil.rmtree(dst, ignore_errors=True)
    os.makedirs(dst)
    for k, f in enumerate(files):
        target = os.path.join(dst, f"{k:05d}.h5")
        shutil.copyfile(f, target)
        if sync:
            fd = os.open(target, os.O_RDONLY)
            os.fsync(fd)
            os.close(fd)


def fresh(path: str) -> str:
    shutil.rmtree(path, ignore_errors=True)
    return path


def read_reader(root: str) -> int:
    with open_dataset(root, "train") as ds:
        for i in range(len(ds)):
            ds[i]
        return len(ds)


def read_stream(out: str, shuffle: int) -> int:
    n = 0
    for _ in SceneStream(out, "train", shuffle=shuffle, seed=0):
        n += 1
    return n


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", help="A finished dataset (default: the demo preset, made in a temporary folder).")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    reuse_freed_memory()
    work = tempfile.mkdtemp(prefix="tsel-bench-export-")
    try:
        root = args.dataset
        if root is None:
            root = os.path.join(work, "demo")
            print("making the demo dataset (72 scenes) ...", flush=True)
            generate(load_config(preset="demo"), root, workers=os.cpu_count() or 1, progress=False)
        files = h5_files(root)
        size = sum(os.path.getsize(f) for f in files)
        n_train = len(open_dataset(root, "train"))
        for f in files:  # warm the page cache: every run reads from memory
            with open(f, "rb") as fh:
                while fh.read(1 << 24):
                    pass
        out = os.path.join(work, "wds")
        t = best({"copy_sync": lambda: copy_files(files, os.path.join(work, "copy"), True),
                  "copy_plain": lambda: copy_files(files, os.path.join(work, "copy"), False),
                  "exp_card": lambda: export("webdataset", root, fresh(out)),
                  "exp_bare": lambda: export("webdataset", root, fresh(out), card=False)}, args.repeats)
        copy_sync, copy_plain, exp_card, exp_bare = t["copy_sync"], t["copy_plain"], t["exp_card"], t["exp_bare"]
        coding = load_dataset_doc(root).raw.get("audio_coding", "float32")
        print(f"\n1. export vs copy: {len(files)} HDF5 files, {size / 1e6:.1f} MB, {coding} audio")
        print(f"   copy HDF5 files (fsynced)        {copy_sync:6.3f} s")
        print(f"   copy HDF5 files (no fsync)       {copy_plain:6.3f} s")
        print(f"   export webdataset, with card     {exp_card:6.3f} s   ratio {exp_card / copy_sync:.2f} "
              f"(vs plain copy {exp_card / copy_plain:.2f})")
        print(f"   export webdataset, no card       {exp_bare:6.3f} s   ratio {exp_bare / copy_sync:.2f} "
              f"(vs plain copy {exp_bare / copy_plain:.2f})")
        t = best({"reader": lambda: read_reader(root), "stream": lambda: read_stream(out, 0),
                  "shuffled": lambda: read_stream(out, 16)}, args.repeats)
        reader, stream, shuffled = t["reader"], t["stream"], t["shuffled"]
        r = n_train / reader
        print(f"\n2. streaming vs the HDF5 reader: train split, {n_train} scenes")
        print(f"   HDF5 reader open_dataset()[i]     {r:7.1f} scenes/s")
        print(f"   SceneStream, in order             {n_train / stream:7.1f} scenes/s   ratio {reader / stream:.2f}")
        print(f"   SceneStream, shuffle buffer 16    {n_train / shuffled:7.1f} scenes/s   ratio {reader / shuffled:.2f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
