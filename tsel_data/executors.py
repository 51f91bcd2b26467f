"""Where shard tasks run: in this process, a local process pool, or a Dask cluster.

The unit of work is one shard (a pure function of its recipes, written atomically), so
every executor gives the same files, a retried task is harmless, and any scheduler
(Slurm job arrays via ``tsel render --shards``, Dask via ``dask-jobqueue``) can run it.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed

from .errors import TselError

EXECUTORS = ("local", "dask", "dask-local")


def single_thread_env() -> None:
    """One thread per worker.

    The environment variables reach libraries loaded later (pyroomacoustics reads
    PRA_NUM_THREADS); BLAS is already loaded by numpy, so its pool is limited at run
    time. Measured here: OpenBLAS's second thread made rendering no faster but busy-waited
    on the other core, so two workers ran no faster than one.
    """
    for var in ("PRA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


class Runner:
    """Runs ``fn(job)`` for batches of jobs, yielding results as they complete."""

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
        if self.executor == "local" and self.workers > 1:
            self._pool = ProcessPoolExecutor(self.workers, initializer=single_thread_env)
        elif self.executor.startswith("dask"):
            try:
                from dask.distributed import Client, LocalCluster
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
            self._client.run(single_thread_env)
        else:
            # in this process: limit BLAS for the run only, then give the caller its threads back
            from threadpoolctl import threadpool_limits

            self._limits = threadpool_limits(1)
        return self

    def __exit__(self, *exc) -> None:
        if self._limits is not None:
            self._limits.restore_original_limits()
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def map_unordered(self, fn: Callable, jobs: list) -> Iterator:
        if not jobs:
            return iter(())
        if self._client is not None:
            from dask.distributed import as_completed as dask_completed

            # pure=False: a shard is a side effect (files); retries are safe (atomic writes)
            futures = self._client.map(fn, jobs, pure=False, retries=2)
            return (f.result() for f in dask_completed(futures))
        if self._pool is not None and len(jobs) > 1:
            return (f.result() for f in as_completed([self._pool.submit(fn, j) for j in jobs]))
        return map(fn, jobs)
