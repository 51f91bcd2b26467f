"""Where shard tasks run: in this process, a local process pool, or a Dask cluster; and
how a run stops on a signal (:mod:`tsel_data.runtime.signals`).

The unit of work is one shard (a pure function of its recipes, written atomically), so
every executor gives the same files, a retried task is harmless, and any scheduler
(Slurm job arrays via ``tsel render --shards``, Dask via ``dask-jobqueue``) can run it.
"""
from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import signal
import sys
from collections import deque
from collections.abc import Callable, Iterator

from threadpoolctl import threadpool_limits

from ..choices import Executor, values
from ..errors import DatasetError, TselError
from .dask import cluster_start, dask_quiet
from .malloc import reuse_freed_memory
from .pool import RemoteTraceback, _Worker, prepare_worker
from .signals import (STOP_GRACE, Stopped, _STOP, _kill_descendants, _signals_blocked, _signals_held, _worker_stopped,
                      stop_signals)

EXECUTORS = values(Executor)


class Runner:
    """Runs ``fn(job)`` for batches of jobs, yielding results as they complete.

    A local pool's workers never outlive the run: on any exit from the ``with`` block
    they are stopped (a worker mid-shard leaves only a temporary file, which the next
    writer removes). A worker that dies (killed, out of memory) ends the run with one
    DatasetError line; one that gets SIGTERM or SIGHUP stops the run as a first signal
    does. ``noun`` names a job in the line a stop prints ("finishing 2 shards in flight").
    """

    def __init__(self, executor: str = "local", workers: int = 1, scheduler: str | None = None,
                 noun: str = "shard"):
        if executor not in EXECUTORS:
            raise TselError(f"unknown executor {executor!r}; use one of {', '.join(EXECUTORS)}")
        if executor == "dask" and not scheduler:
            raise TselError("--executor dask needs --scheduler tcp://HOST:PORT (a running dask scheduler)")
        self.executor, self.workers, self.scheduler = executor, max(1, workers), scheduler
        self.noun = noun
        self.in_flight = 0
        self._workers: list[_Worker] = []
        self._client = None
        self._cluster = None
        self._limits = None
        self._signals = None
        self._outer = None

    def __enter__(self) -> "Runner":
        # a library caller (no `tsel` around it) gets the stop protocol for SIGTERM and
        # SIGHUP while the run lasts; Ctrl-C stays its KeyboardInterrupt
        self._signals = stop_signals((signal.SIGTERM, signal.SIGHUP), whole_process=False)
        self._signals.__enter__()
        try:
            self._start()
        except BaseException:
            self.__exit__(*sys.exc_info())
            raise
        self._outer, _STOP.runner = _STOP.runner, self
        return self

    def _start(self) -> None:
        if self.executor == "local" and self.workers > 1:
            ctx = multiprocessing.get_context()
            with _signals_held():
                for _ in range(self.workers):
                    self._workers.append(_Worker(ctx, prepare_worker))
        elif self.executor.startswith("dask"):
            try:
                from dask.distributed import Client, LocalCluster  # optional extra, slow to import
            except ImportError:
                raise TselError("the dask executors need dask.distributed: pip install 'tsel-data[dask]'") from None
            if self.executor == "dask-local":
                # the cluster's workers get no signal of the group: the main process stops
                # them (a worker killed by a group's SIGTERM would take its shard along)
                with _signals_blocked(), cluster_start():
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

    def __exit__(self, exc_type, exc, tb) -> None:
        if _STOP.runner is self:
            _STOP.runner = self._outer
        try:
            # a graceful stop has nothing in flight; anything else leaving early drops its tasks
            now = exc_type is not None and not (isinstance(exc, Stopped) and not exc.now)
            self._close(now)
        finally:
            if self._signals is not None:
                self._signals.__exit__(None, None, None)
                self._signals = None

    def _close(self, now: bool) -> None:
        if self._limits is not None:
            self._limits.restore_original_limits()
            self._limits = None
        workers, self._workers = self._workers, []
        for w in workers:
            if now:
                w.process.kill()
            else:
                try:
                    w.conn.send(None)
                except OSError:
                    pass
        for w in workers:
            w.process.join(None if now else STOP_GRACE)
            if w.process.is_alive():
                w.process.kill()
                w.process.join()
            w.conn.close()
        client, cluster, self._client, self._cluster = self._client, self._cluster, None, None
        stopping = _STOP.signum is not None
        with dask_quiet() if stopping else contextlib.nullcontext():  # a stop's dropped connections are no news
            if client is not None:
                client.close(timeout=2 if now else 10)
            if cluster is not None:
                cluster.close(timeout=2 if now else 20)
                if now and _STOP.whole_process:  # workers its nannies restarted after the kill
                    _kill_descendants()

    def map_unordered(self, fn: Callable, jobs: list) -> Iterator:
        """``fn(job)`` for every job, in the order they finish. After a first signal no
        new job starts; once the jobs in flight are done, :class:`Stopped` is raised."""
        if not jobs:
            return iter(())
        if self._client is not None:
            return self._dask_results(fn, jobs)
        if self._workers and len(jobs) > 1:
            return self._pool_results(fn, jobs)
        return self._serial_results(fn, jobs)

    def _stop_point(self) -> None:
        """Where a stop asked for meanwhile takes effect: between tasks."""
        if _STOP.signum is not None:
            raise Stopped(_STOP.signum, announced=_STOP.announced, noun=self.noun)

    def _serial_results(self, fn, jobs) -> Iterator:
        for job in jobs:
            self._stop_point()
            self.in_flight = 1
            try:
                result = fn(job)
            finally:
                self.in_flight = 0
            yield result
        self._stop_point()

    def _pool_results(self, fn, jobs) -> Iterator:
        todo = deque(jobs)
        idle = deque(self._workers)
        busy: dict = {}  # conn -> (worker, job)
        while True:
            while todo and idle and _STOP.signum is None:
                w = idle.popleft()
                job = todo.popleft()
                try:
                    w.conn.send((fn, job))
                except OSError:  # it died waiting for work
                    todo.appendleft(job)
                    self.in_flight = len(busy)
                    self._lost(w, None)
                    continue
                busy[w.conn] = (w, job)
            self.in_flight = len(busy)
            if not busy:
                break
            ready = set(multiprocessing.connection.wait(
                [*busy, *(w.process.sentinel for w, _ in busy.values())]))
            for conn, (w, job) in list(busy.items()):
                if conn not in ready and w.process.sentinel not in ready:
                    continue
                del busy[conn]
                self.in_flight = len(busy)  # what a signal during the yield below finds in flight
                try:
                    ok, value, tb, stop = conn.recv()
                except (EOFError, OSError):  # died in the middle of the task
                    self._lost(w, job)
                    continue
                if stop is None:
                    idle.append(w)
                else:  # it got a signal and exits now that its task is done
                    _worker_stopped(w.process.pid, stop, len(busy), self.noun)
                if not ok:
                    value.__cause__ = RemoteTraceback(tb)
                    raise value
                yield value
        self._stop_point()

    def _lost(self, w: _Worker, job) -> None:
        """A worker died: a stop signal asks the run to stop (its task, if any, is rendered
        by the next run); anything else (SIGKILL, out of memory) ends the run now."""
        sig = w.exit_signal()
        if sig is None:
            raise DatasetError("a worker process died (killed, or out of memory?) while rendering; finished "
                               "shards are kept: rerun with --resume, with fewer --workers if memory is short")
        _worker_stopped(w.process.pid, sig, self.in_flight, self.noun)

    def _dask_results(self, fn, jobs) -> Iterator:
        from dask.distributed import as_completed as dask_completed  # optional extra

        # as many tasks submitted as the cluster has threads, so a stop knows what is in
        # flight and starts nothing new; pure=False: a shard is a side effect (files),
        # retries are safe (atomic writes)
        todo = deque(jobs)
        window = max(1, sum(self._client.nthreads().values()))
        running = dask_completed()

        def submit(n):
            for _ in range(n):
                if todo and _STOP.signum is None:
                    running.add(self._client.submit(fn, todo.popleft(), pure=False, retries=2))
                    self.in_flight += 1

        submit(window)
        try:
            for f in running:
                self.in_flight -= 1
                result = f.result()
                submit(1)
                yield result
        finally:
            self.in_flight = 0
            # after a stop, nothing of this run goes on in the cluster
            self._client.cancel([f for f in running.futures])
        self._stop_point()
