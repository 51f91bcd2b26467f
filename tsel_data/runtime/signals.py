"""How a run stops on a signal (docs/reliability.md, "what each signal does").

The first SIGINT, SIGTERM or SIGHUP the main process gets stops the run cleanly: no new
task starts, the tasks in flight finish, then :class:`Stopped` (exit code 128 + the
signal's number). The second stops at once: every process below the main one is killed,
partial shards are left as temporary files (removed by the next writer), and the run
exits within :data:`STOP_GRACE` seconds whatever it was doing. Workers ignore SIGINT
(Ctrl-C reaches the whole foreground group: the main process decides); a worker that gets
SIGTERM or SIGHUP finishes its task, then exits, and the run stops as on a first signal.
"""
from __future__ import annotations

import multiprocessing
import os
import signal
import stat
import sys
import threading
from contextlib import contextmanager
from multiprocessing import resource_tracker

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
# After the second signal the exit path (joining threads, closing a Dask cluster) gets
# this long before the process leaves without it: a stop must never become a hang.
STOP_GRACE = 5.0


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
        self.runner = None  # a Runner  # the runner whose tasks a first signal lets finish
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
