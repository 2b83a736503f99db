"""The one decorator for flexkin's compiled kernels: ``numba.njit`` with an on-disk cache
that can never be stale.

numba checks a cached function against its *own* source file only: a kernel whose callee in
another module changed would silently reuse old machine code.  flexkin therefore keeps all
its kernel caches in one directory named by a fingerprint of every flexkin source file that
defines kernels (and of the numba version): any change to any kernel gives a new directory
and a fresh compilation, and no process ever recompiles what an earlier one compiled.

The directory is ``<user cache dir>/flexkin/numba/<fingerprint>`` (platformdirs; override the
base with the ``FLEXKIN_CACHE_DIR`` environment variable).  If it cannot be created or
written, numba falls back to its own locations (the package's ``__pycache__``, then the
user-wide numba cache), and kernels still run, compiled in memory if nothing is writable.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any, Callable

import numba

__all__ = ["njit", "kernel_cache_dir", "cache_base"]

_PKG = Path(__file__).resolve().parents[1]


def cache_base() -> Path:
    """flexkin's cache directory (``FLEXKIN_CACHE_DIR`` or the platform's user cache dir)."""
    env = os.environ.get("FLEXKIN_CACHE_DIR")
    if env:
        return Path(env)
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("flexkin", appauthor=False))


def _fingerprint() -> str:
    h = hashlib.sha256(numba.__version__.encode())
    for p in sorted(_PKG.rglob("*.py")):
        data = p.read_bytes()
        if b"njit" in data:
            h.update(p.relative_to(_PKG).as_posix().encode())
            h.update(data)
    return h.hexdigest()[:16]


def kernel_cache_dir() -> Path:
    """Where this version of the kernels is cached."""
    return _CACHE_DIR


_CACHE_DIR = cache_base() / "numba" / _fingerprint()


def _decorate(func: Callable, options: dict[str, Any]) -> Callable:
    old = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = str(_CACHE_DIR)
    try:
        return numba.njit(**options)(func)
    finally:
        numba.config.CACHE_DIR = old


def njit(*args: Any, **options: Any) -> Any:
    """``numba.njit`` with ``cache=True``, IEEE floating-point semantics (``error_model="numpy"``:
    a division by zero gives inf or NaN, which the kernels test for, instead of raising) and
    the cache directory above."""
    options.setdefault("cache", True)
    options.setdefault("error_model", "numpy")
    if args and callable(args[0]):
        return _decorate(args[0], options)
    return lambda func: _decorate(func, options)
