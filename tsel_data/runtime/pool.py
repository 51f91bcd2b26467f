"""Worker processes: how a process that renders is set up, the pool workers a
:class:`~tsel_data.runtime.runner.Runner` feeds one task at a time, and an ordered pool for
short maps (planning, clip checks). Workers die with the main process and take their
stop signals from it (:mod:`tsel_data.runtime.signals`).
"""
from __future__ import annotations

import os
import signal
import traceback
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

from ..core.libc import libc
from .malloc import reuse_freed_memory
from .signals import STOP_GRACE, STOP_SIGNALS, _let_signals_in, _signals_held


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


class RemoteTraceback(Exception):
    """The traceback of an exception raised in a worker (its ``__cause__`` in the main process)."""

    def __str__(self) -> str:
        return self.args[0]


class _WorkerState:
    stop: int | None = None


def _on_worker_signal(signum, frame) -> None:
    if _WorkerState.stop is not None:  # the second: stop now, as without a handler
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
    # finish the task in hand, or the one the main process may have sent already (it
    # counts it in flight), then exit; an idle worker is stopped by the pool's close
    _WorkerState.stop = signum


def _die_with_parent(parent: int) -> None:
    """Linux: SIGKILL this worker when the main process dies, however it dies (SIGKILL
    included, which no handler sees): a worker never renders on for a run that is gone."""
    prctl = getattr(libc(), "prctl", None)
    if prctl is None:  # not Linux
        return
    PR_SET_PDEATHSIG = 1
    prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # it died before the line above
        os._exit(1)


def _worker_main(conn, initializer, parent: int) -> None:
    """A pool worker: tasks one at a time from its own pipe, results back on it. Its own
    pipe, not a queue shared by all workers: a worker killed mid-read can hold no lock
    another worker waits on."""
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for s in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, _on_worker_signal)
    _let_signals_in()
    if initializer is not None:
        initializer()
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):  # the main process is gone
            return
        if msg is None:
            return
        fn, job = msg
        try:
            out = (True, fn(job), None)
        except BaseException as e:  # noqa: BLE001 (every failure goes back to the main process)
            out = (False, e, traceback.format_exc())
        try:
            conn.send((*out, _WorkerState.stop))
        except (OSError, EOFError):
            return
        except Exception:  # noqa: BLE001 (an exception that does not pickle: its text does)
            conn.send((False, RuntimeError(f"{type(out[1]).__name__}: {out[1]}"), out[2], _WorkerState.stop))
        if _WorkerState.stop is not None:
            os._exit(128 + _WorkerState.stop)


class _Worker:
    def __init__(self, ctx, initializer):
        self.conn, child = ctx.Pipe()
        # daemonic: should a run ever leave without closing its pool, interpreter exit
        # stops the workers instead of waiting for them
        self.process = ctx.Process(target=_worker_main, args=(child, initializer, os.getpid()), daemon=True)
        self.process.start()
        child.close()

    def exit_signal(self) -> int | None:
        """The stop signal this (dead) worker got, if a signal ended it."""
        self.process.join(1.0)
        code = self.process.exitcode
        if code is None:
            return None
        sig = -code if code < 0 else code - 128
        return sig if sig in STOP_SIGNALS else None


# --- an ordered pool for short maps ----------------------------------------------------------------


def _ordered_worker_init(parent: int, initializer, initargs) -> None:
    _die_with_parent(parent)
    _let_signals_in()
    if initializer is not None:
        initializer(*initargs)


@contextmanager
def ordered_pool(workers: int, initializer: Callable | None = None, initargs: tuple = ()):
    """A ``concurrent.futures`` pool for maps whose results come back in order (planning,
    clip checks). Its workers die with the main process, and any exit from the block but
    a normal one (a stop, an error) kills them at once: none plans on for a run that
    stopped, and ``shutdown`` never waits for the queued tasks."""
    ex = ProcessPoolExecutor(workers, initializer=_ordered_worker_init, initargs=(os.getpid(), initializer, initargs))
    with _signals_held():
        ex.submit(int)  # its workers start now (forked: all at the first task), with the stop signals held
    try:
        yield ex
    except BaseException:
        procs = list((getattr(ex, "_processes", None) or {}).values())  # no public handle on them
        for p in procs:
            p.kill()
        ex.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            p.join(STOP_GRACE)
        raise
    ex.shutdown(wait=True)
