"""A local Dask cluster's start and close, each held to what the user needs to see: a
cluster that cannot start is one line, and one closed on a stop says nothing of its own
(Dask logs the connections its closing workers drop, tracebacks included).

A stop signal while the cluster starts waits until it has started, so that the run can
close it: raised inside ``LocalCluster(...)``, the stop left a cluster half made and
unnamed, its worker processes and the nannies' queues never closed, and on the way out
multiprocessing's resource tracker reported their semaphores ("resource_tracker: There
appear to be 12 leaked semaphore objects"). Blocking the signals in the main thread does
not hold them back: the kernel hands a process's signal to any thread that does not
block it, and Python runs the handler in the main thread all the same.
"""
from __future__ import annotations

import logging
import signal
import threading
from contextlib import contextmanager

from ..errors import DatasetError
from .signals import STOP_SIGNALS

# Dask's loggers that speak while workers start or stop (children inherit their level)
_LOGGERS = ("distributed", "distributed.nanny", "distributed.deploy.spec", "distributed.worker",
            "distributed.core", "distributed.comm", "distributed.scheduler", "distributed.client")


@contextmanager
def dask_quiet():
    """Dask's own logging held back for the block."""
    loggers = [logging.getLogger(n) for n in _LOGGERS]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


@contextmanager
def stops_deferred():
    """Stop signals that come while the block runs take effect when it ends (their handlers
    are called then, in order), so that what the block starts is whole and named when the
    stop unwinds it. A second one acts at once: a second signal stops now (it kills what
    runs below this process), and a start that hangs stays stoppable. A no-op outside the
    main thread, and for a signal without a Python handler."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    old = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    old = {s: h for s, h in old.items() if callable(h)}

    def replay():
        for s, h in old.items():
            signal.signal(s, h)
        stop = None
        while pending:
            signum = pending.pop(0)
            try:
                old[signum](signum, None)
            except BaseException as e:  # noqa: BLE001 (the stop, raised once every signal is handled)
                stop = e
        if stop is not None:
            raise stop

    def remember(signum, frame):
        pending.append(signum)
        if len(pending) > 1:
            replay()

    for s in old:
        signal.signal(s, remember)
    try:
        yield
    finally:
        replay()


@contextmanager
def cluster_start():
    """A local Dask cluster that cannot start (a worker process killed while it starts, out
    of memory, no free port) is one DatasetError line. Dask says why in a chained
    RuntimeError ("Nanny failed to start") and logs the same traceback itself: its logs
    are held back while the cluster starts, the first line of the deepest cause is kept.
    A stop signal meanwhile takes effect once the cluster has started (:func:`stops_deferred`)."""
    with stops_deferred(), dask_quiet():
        try:
            yield
        except (RuntimeError, OSError, TimeoutError) as e:
            cause = e
            while cause.__cause__ is not None:
                cause = cause.__cause__
            why = (str(cause).splitlines() or [type(cause).__name__])[0][:200]
            raise DatasetError(f"the local Dask cluster did not start ({why}): a worker process died while "
                               f"starting (killed, or out of memory?); nothing was rendered: run the command again, "
                               f"with fewer --workers if memory is short, or with --executor local") from None
