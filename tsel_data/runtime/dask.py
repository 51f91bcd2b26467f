"""A local Dask cluster's start and close, each held to what the user needs to see: a
cluster that cannot start is one line, and one closed on a stop says nothing of its own
(Dask logs the connections its closing workers drop, tracebacks included)."""
from __future__ import annotations

import logging
from contextlib import contextmanager

from ..errors import DatasetError

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
def cluster_start():
    """A local Dask cluster that cannot start (a worker process killed while it starts, out
    of memory, no free port) is one DatasetError line. Dask says why in a chained
    RuntimeError ("Nanny failed to start") and logs the same traceback itself: its logs
    are held back while the cluster starts, the first line of the deepest cause is kept."""
    with dask_quiet():
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
