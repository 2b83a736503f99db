"""Set-up of the local cluster's worker processes (a Dask preload, ``dask_setup``): they ignore
Ctrl-C.

A Ctrl-C in a terminal reaches every process of the foreground process group.  The study
process stops its cluster itself and reports the finished rows; the worker processes must not
die on their own and print their tracebacks.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

__all__ = ["dask_setup"]


def dask_setup(worker: Any) -> None:
    """Called by Dask in each worker process at start: ignore SIGINT there.

    Parameters
    ----------
    worker : distributed.Worker
        The worker starting (unused).
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
