"""BLAS threads for flexkin's many small matrices.

OpenBLAS spreads matrices of a few dozen rows over every core; on small problems the
synchronisation costs far more than the work (measured on a 2-core machine: a 66 x 66
symmetric eigenproblem takes 3.3 ms with 2 threads and 0.12 ms with 1).  flexkin's batched
eigenproblems run inside :func:`single_threaded_blas`, which limits the BLAS libraries to one
thread through threadpoolctl (the scikit-learn project's tool) and restores them afterwards.
Nested uses cost nothing: only the outermost one switches.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager
from typing import Iterator

__all__ = ["single_threaded_blas"]

_state = threading.local()


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Limit BLAS to one thread inside the block (reentrant, thread-safe)."""
    depth = getattr(_state, "depth", 0)
    if depth:
        _state.depth = depth + 1
        try:
            yield
        finally:
            _state.depth -= 1
        return
    from threadpoolctl import threadpool_limits

    _state.depth = 1
    try:
        with threadpool_limits(1, user_api="blas"):
            yield
    finally:
        _state.depth = 0
