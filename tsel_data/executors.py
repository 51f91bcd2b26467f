"""Where shard tasks run: in this process, a local process pool, or a Dask cluster.

The unit of work is one shard (a pure function of its recipes, written atomically), so
every executor gives the same files, a retried task is harmless, and any scheduler
(Slurm job arrays via ``tsel render --shards``, Dask via ``dask-jobqueue``) can run it.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool

from threadpoolctl import threadpool_limits

from .choices import Executor, values
from .errors import DatasetError, TselError

EXECUTORS = values(Executor)


def prepare_worker() -> None:
    """Set up a process that renders: one thread, and freed memory kept for reuse.

    Threads: the environment variables reach libraries loaded later (pyroomacoustics
    reads PRA_NUM_THREADS); BLAS is already loaded by numpy, so its pool is limited at
    run time. Measured here: OpenBLAS's second thread made rendering no faster but
    busy-waited on the other core, so two workers ran no faster than one.
    """
    for var in ("PRA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    threadpool_limits(1)
    reuse_freed_memory()


def reuse_freed_memory() -> None:
    """Ask glibc's malloc to keep freed memory for the next scene instead of handing it
    back to the kernel.

    A render allocates and frees tens of MB of buffers per scene. By default glibc maps
    blocks over a threshold afresh and unmaps them on free, so every scene pays page
    faults on fresh pages (~0.4 ms per MB here): a moving bank scene rendered in 29 ms
    per source with the default, 24 ms with these settings (benchmarks/bench_banks.py).
    Blocks up to 32 MB now come from the heap, and up to 256 MB of freed heap is kept.
    The setting is process-wide and stays after a run in the caller's own process (a
    serial ``generate``); a no-op where the C library is not glibc.
    """
    global _MALLOC_SET
    if _MALLOC_SET:
        return
    _MALLOC_SET = True
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc
        return
    M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
    mallopt(M_MMAP_THRESHOLD, 32 << 20)
    mallopt(M_TRIM_THRESHOLD, 256 << 20)


_MALLOC_SET = False


class Terminated(SystemExit):
    """SIGTERM reached the main process: leave the run (finished shards are kept)."""


def _on_sigterm(signum, frame):
    raise Terminated(128 + signal.SIGTERM)


class Runner:
    """Runs ``fn(job)`` for batches of jobs, yielding results as they complete.

    A local pool's workers never outlive the run: on any exit from the ``with`` block,
    SIGTERM to the main process included, they are stopped (a worker mid-shard leaves
    only a temporary file, which the next writer removes). A worker that dies (killed,
    out of memory) ends the run with one DatasetError line.
    """

    def __init__(self, executor: str = "local", workers: int = 1, scheduler: str | None = None):
        if executor not in EXECUTORS:
            raise TselError(f"unknown executor {executor!r}; use one of {', '.join(EXECUTORS)}")
        if executor == "dask" and not scheduler:
            raise TselError("--executor dask needs --scheduler tcp://HOST:PORT (a running dask scheduler)")
        self.executor, self.workers, self.scheduler = executor, max(1, workers), scheduler
        self._pool = None
        self._client = None
        self._cluster = None

    def __enter__(self) -> "Runner":
        self._limits = None
        self._old_term = None
        if self.executor == "local" and self.workers > 1:
            self._pool = ProcessPoolExecutor(self.workers, initializer=prepare_worker)
            if threading.current_thread() is threading.main_thread():
                self._old_term = signal.signal(signal.SIGTERM, _on_sigterm)
        elif self.executor.startswith("dask"):
            try:
                from dask.distributed import Client, LocalCluster  # optional extra, slow to import
            except ImportError:
                raise TselError("the dask executors need dask.distributed: pip install 'tsel-data[dask]'") from None
            if self.executor == "dask-local":
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                             host="127.0.0.1", dashboard_address=None)
                self._client = Client(self._cluster)
            else:
                try:
                    self._client = Client(self.scheduler, timeout="20s")
                except OSError as e:
                    raise TselError(f"cannot reach the dask scheduler at {self.scheduler}: {e}") from None
            self._client.run(prepare_worker)
        else:
            # in this process: limit BLAS for the run only, then give the caller its threads back
            self._limits = threadpool_limits(1)
            reuse_freed_memory()
        return self

    def __exit__(self, *exc) -> None:
        if self._limits is not None:
            self._limits.restore_original_limits()
        if self._pool is not None:
            if exc[0] is not None:
                # leaving early: do not wait for shards in flight. _processes is the only
                # handle on the workers ProcessPoolExecutor gives.
                for p in list((self._pool._processes or {}).values()):
                    p.terminate()
            self._pool.shutdown(cancel_futures=True)
            if self._old_term is not None:
                signal.signal(signal.SIGTERM, self._old_term)
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def map_unordered(self, fn: Callable, jobs: list) -> Iterator:
        if not jobs:
            return iter(())
        if self._client is not None:
            from dask.distributed import as_completed as dask_completed  # optional extra

            # pure=False: a shard is a side effect (files); retries are safe (atomic writes)
            futures = self._client.map(fn, jobs, pure=False, retries=2)
            return (f.result() for f in dask_completed(futures))
        if self._pool is not None and len(jobs) > 1:
            return self._results(as_completed([self._pool.submit(fn, j) for j in jobs]))
        return map(fn, jobs)

    @staticmethod
    def _results(futures) -> Iterator:
        try:
            for f in futures:
                yield f.result()
        except BrokenProcessPool:
            raise DatasetError("a worker process died (killed, or out of memory?) while rendering; finished "
                               "shards are kept: rerun with --resume, with fewer --workers if memory is short") from None
