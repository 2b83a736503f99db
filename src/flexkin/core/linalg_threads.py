"""BLAS threads for flexkin's many small matrices.

OpenBLAS spreads matrices of a few dozen rows over every core; on small problems the
synchronisation costs far more than the work (measured on a 2-core machine: a 66 x 66
symmetric eigenproblem takes 3.3 ms with 2 threads and 0.12 ms with 1).  flexkin's batched
eigenproblems run inside :func:`single_threaded_blas`, which limits the BLAS libraries to one
thread through threadpoolctl (the scikit-learn project's tool) and restores them afterwards.
Nested uses cost nothing: only the outermost one switches.  The libraries are found once per
process (a :class:`threadpoolctl.ThreadpoolController`, after loading the LAPACK that numba's
``np.linalg`` calls use, SciPy's): scanning them on every call cost ~15 ms in a process that
has loaded flexkin's kernels.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager
from typing import Iterator

__all__ = ["single_threaded_blas"]

_state = threading.local()
_controller = None


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
    global _controller
    if _controller is None:
        import scipy.linalg.cython_lapack  # noqa: F401  (numba's LAPACK: load it before the scan)
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    _state.depth = 1
    try:
        with _controller.limit(limits=1, user_api="blas"):
            yield
    finally:
        _state.depth = 0
