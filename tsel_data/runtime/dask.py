"""A local Dask cluster's start, held to one line when it fails."""
from __future__ import annotations

import logging
from contextlib import contextmanager

from ..errors import DatasetError


@contextmanager
def cluster_start():
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
