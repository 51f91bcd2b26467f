"""Where shard tasks run: in this process, a local process pool, or a Dask cluster; and
how a run stops on a signal.

The unit of work is one shard (a pure function of its recipes, written atomically), so
every executor gives the same files, a retried task is harmless, and any scheduler
(Slurm job arrays via ``tsel render --shards``, Dask via ``dask-jobqueue``) can run it.

Stopping (docs/reliability.md, "what each signal does"): the first SIGINT, SIGTERM or
SIGHUP the main process gets stops the run cleanly: no new task starts, the tasks in
flight finish, then :class:`Stopped` (exit code 128 + the signal's number). The second
stops at once: every process below the main one is killed, partial shards are left as
temporary files (removed by the next writer), and the run exits within
:data:`STOP_GRACE` seconds whatever it was doing. Workers ignore SIGINT (Ctrl-C reaches
the whole foreground group: the main process decides); a worker that gets SIGTERM or
SIGHUP finishes its task, then exits, and the run stops as on a first signal.
"""
from __future__ import annotations

import logging
import multiprocessing
import multiprocessing.connection
from multiprocessing import resource_tracker
import os
import signal
import stat
import sys
import threading
import traceback
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

from .choices import Executor, values
from .errors import DatasetError, TselError
from .libc import libc
from .malloc import reuse_freed_memory

EXECUTORS = values(Executor)
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
# After the second signal the exit path (joining threads, closing a Dask cluster) gets
# this long before the process leaves without it: a stop must never become a hang.
STOP_GRACE = 5.0


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


# --- stopping on a signal --------------------------------------------------------------------


class Stopped(SystemExit):
    """A signal stopped the run; everything under a final name is whole.

    ``code`` is 128 + ``signum`` (130 SIGINT, 143 SIGTERM, 129 SIGHUP). ``now``: the
    second signal stopped it at once, discarding ``discarded`` tasks in flight (else
    the tasks in flight were finished, or there were none). ``announced``: the run
    said it was stopping already (the line a first signal prints while tasks finish).
    """

    def __init__(self, signum: int, now: bool = False, discarded: int = 0, noun: str = "task",
                 announced: bool = False):
        super().__init__(128 + signum)
        self.signum, self.now, self.discarded, self.noun, self.announced = signum, now, discarded, noun, announced

    @property
    def signal_name(self) -> str:
        return signal.Signals(self.signum).name


class _StopState:
    """What the process knows of a stop (signals are process-wide, hence one per process)."""

    def __init__(self):
        self.pid: int | None = None  # the process that installed the handlers; forks inherit them
        self.old: dict = {}
        self.signum: int | None = None  # why the run stops (its exit code)
        self.presses = 0  # signals the main process itself got
        self.announced = False
        self.runner: Runner | None = None  # the runner whose tasks a first signal lets finish
        self.whole_process = False  # the process is the run (`tsel`): everything below it is the run's

    def reset(self) -> None:
        self.signum, self.presses, self.announced, self.runner = None, 0, False, None


_STOP = _StopState()


@contextmanager
def stop_signals(signums=STOP_SIGNALS, whole_process: bool = True):
    """Handle ``signums`` as described in the module docstring while the block runs
    (``tsel`` wraps every command in it). A no-op outside the main thread (Python
    delivers signals there only) and when already active. ``whole_process``: a second
    signal kills every process below this one; else (a library caller's process, which
    may have children of its own) only the workers of the runner in use."""
    if threading.current_thread() is not threading.main_thread() or _STOP.pid == os.getpid():
        yield
        return
    _STOP.reset()
    _STOP.pid, _STOP.whole_process = os.getpid(), whole_process
    _STOP.old = {s: signal.signal(s, _on_signal) for s in signums}
    try:
        yield
    finally:
        for s, old in _STOP.old.items():
            signal.signal(s, old)
        _STOP.pid, _STOP.old, _STOP.whole_process = None, {}, False
        _STOP.reset()


def stop_requested() -> int | None:
    """The signal the run is stopping for, or None."""
    return _STOP.signum


def _on_signal(signum, frame) -> None:
    if os.getpid() != _STOP.pid:
        # a forked worker of a pool that is not a Runner's (planning, clip checks) inherited
        # this handler: raising here would unwind that pool's protocol mid-message
        _as_foreign_worker(signum)
        return
    _STOP.presses += 1
    if _STOP.signum is None:
        _STOP.signum = signum
    if _STOP.presses >= 3:  # the exit path itself is stuck: leave without it
        _kill_run()
        os._exit(128 + _STOP.signum)
    n, noun = _in_flight()
    if _STOP.presses == 2:
        _kill_run()
        # the exit path may wait on threads of dead workers (concurrent.futures, dask)
        watchdog = threading.Timer(STOP_GRACE, os._exit, args=(128 + _STOP.signum,))
        watchdog.daemon = True
        watchdog.start()
        raise Stopped(_STOP.signum, now=True, discarded=n, noun=noun, announced=_STOP.announced)
    if _STOP.announced:  # a worker's signal started the stop; this one is the same request
        return
    if n:
        again = "press Ctrl-C again" if signum == signal.SIGINT else "signal again"
        prefix = "stopping" if signum == signal.SIGINT else f"stopping ({signal.Signals(signum).name})"
        _say(f"{prefix}: finishing {_count(n, noun)} in flight, then exit; {again} to stop now")
        _STOP.announced = True
        if signum == signal.SIGHUP:
            _detach_output()
        return
    if signum == signal.SIGHUP:
        _detach_output()
    raise Stopped(_STOP.signum, noun=noun)  # nothing in flight to finish: stop here


def _worker_stopped(pid: int, signum: int, n: int, noun: str) -> None:
    """A worker got ``signum`` (and exits after its task): the run stops as on a first signal."""
    if _STOP.signum is not None:
        return
    _STOP.signum = signum
    if n:
        _say(f"stopping: worker {pid} got {signal.Signals(signum).name}; finishing {_count(n, noun)} in flight, "
             f"then exit; press Ctrl-C to stop now")
        _STOP.announced = True


def _in_flight() -> tuple[int, str]:
    r = _STOP.runner
    return (r.in_flight, r.noun) if r is not None else (0, "task")


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _say(line: str) -> None:
    """One line on stderr from a signal handler: straight to the file descriptor, since the
    interrupted code may be inside a write to sys.stderr (a progress bar) itself."""
    try:
        clear = "\r\x1b[K" if os.isatty(2) else ""  # over the progress bar's half-drawn line
        os.write(2, (clear + line + "\n").encode("utf-8", "replace"))
    except OSError:  # the terminal is gone (SIGHUP)
        pass


def _detach_output() -> None:
    """After a hangup the terminal (or the pipe to a closed terminal's program) is gone and
    every write to it would fail: send stdout and stderr to /dev/null, unless they are
    files, which stay writable."""
    try:
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        return
    for fd in (1, 2):
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                os.dup2(null, fd)
        except OSError:
            pass
    os.close(null)


def _as_foreign_worker(signum: int) -> None:
    """A worker of another pool: ignore Ctrl-C (the main process decides); SIGTERM and
    SIGHUP end it as they would without a handler (its pool then reports it dead)."""
    if signum == signal.SIGINT:
        signal.signal(signum, signal.SIG_IGN)
        return
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)


def _kill_run() -> None:
    if _STOP.whole_process:
        _kill_descendants()
    elif _STOP.runner is not None:
        for w in _STOP.runner._workers:
            w.process.kill()


def _kill_descendants() -> None:
    """SIGKILL every process below this one (pool workers, a local Dask cluster's workers,
    whatever they started), but multiprocessing's own helpers, which leave on their own
    once this process is gone and which clean up what the workers leave."""
    keep = set()
    for mod, attr, pid_attr in (("multiprocessing.resource_tracker", "_resource_tracker", "_pid"),
                                ("multiprocessing.forkserver", "_forkserver", "_forkserver_pid")):
        helper = getattr(sys.modules.get(mod), attr, None)
        if getattr(helper, pid_attr, None):
            keep.add(getattr(helper, pid_attr))
    for pid in _descendants(os.getpid()):
        if pid not in keep:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass


def _descendants(root: int) -> list[int]:
    """Every process below ``root`` (Linux: from /proc; elsewhere multiprocessing's children)."""
    try:
        names = os.listdir("/proc")
    except OSError:
        return [p.pid for p in multiprocessing.active_children() if p.pid]
    children: dict[int, list[int]] = {}
    for name in names:
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                ppid = int(f.read().rsplit(b")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        children.setdefault(ppid, []).append(int(name))
    out, todo = [], [root]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


@contextmanager
def _signals_blocked():
    """Signals held back from this thread, and from every thread and process it starts
    meanwhile (a Dask cluster's event loop and the workers it spawns keep the mask): the
    main process alone gets them. Pending ones arrive when the block ends."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    # started now, or the first spawn starts it inside the block, and multiprocessing then
    # unblocks SIGINT and SIGTERM in the spawning thread whatever they were before
    resource_tracker.ensure_running()
    with _signals_held():
        yield


@contextmanager
def _signals_held():
    """Stop signals held back while the block runs, then delivered. Around the start of
    pool workers: a handler that raises inside ``fork`` runs in the parent's at-fork hooks
    (logging's lock release), where Python prints the exception as "ignored" and drops
    it. The workers start with them held and let them through once their handlers are
    set (:func:`_let_signals_in`)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _let_signals_in() -> None:
    """In a worker started inside :func:`_signals_held`: its handlers are set, the signals
    held back since its start (a stop of the whole group) arrive now."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)


# --- the local pool ----------------------------------------------------------------------------


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


@contextmanager
def _cluster_start():
    """A local Dask cluster that cannot start (a worker process killed while it starts, out
    of memory, no free port) is one DatasetError line. Dask says why in a chained
    RuntimeError ("Nanny failed to start") and logs the same traceback itself: its logs
    are held back while the cluster starts, the first line of the deepest cause is kept."""
    loggers = [logging.getLogger(n) for n in ("distributed", "distributed.nanny", "distributed.deploy.spec")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    except (RuntimeError, OSError, TimeoutError) as e:
        cause = e
        while cause.__cause__ is not None:
            cause = cause.__cause__
        why = (str(cause).splitlines() or [type(cause).__name__])[0][:200]
        raise DatasetError(f"the local Dask cluster did not start ({why}): a worker process died while starting "
                           f"(killed, or out of memory?); nothing was rendered: run the command again, with fewer "
                           f"--workers if memory is short, or with --executor local") from None
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


# --- the runner ----------------------------------------------------------------------------------


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
                with _signals_blocked(), _cluster_start():
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
