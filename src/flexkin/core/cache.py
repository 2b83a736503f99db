"""Arrays cached on disk in the user's cache directory (atlases and search trees).

An entry is an ``.npz`` file named by the entry's name and a version key (a hash of the
arguments, the flexkin version and whatever the caller includes, e.g. a fingerprint of the
code that builds it).  Reading never trusts the file blindly: a missing, stale (other key),
truncated or otherwise unreadable file is rebuilt; a cache directory that cannot be written
leaves the arrays in memory only.  Nothing is ever shipped prebuilt.

The directory is ``<user cache dir>/flexkin/arrays`` (platformdirs; ``FLEXKIN_CACHE_DIR``
overrides the base, see :func:`flexkin.core.jit.cache_base`).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import warnings
import zipfile
from pathlib import Path
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from .jit import cache_base, kernel_cache_dir

__all__ = ["cached_arrays", "cache_dir"]


def cache_dir() -> Path:
    """Where cached arrays live."""
    return cache_base() / "arrays"


def _key(name: str, parts: tuple) -> str:
    from .. import __version__

    h = hashlib.sha256(repr((name, __version__, kernel_cache_dir().name) + tuple(parts)).encode())
    return h.hexdigest()[:16]


def cached_arrays(name: str, parts: tuple, build: Callable[[], dict[str, NDArray]]) -> dict[str, NDArray]:
    """The arrays ``build()`` returns, read from the disk cache when a valid entry exists.

    Parameters
    ----------
    name : str
        Entry name (a file-name-safe word).
    parts : tuple
        Everything the arrays depend on (arguments, grid sizes); with flexkin's version and the
        kernels' fingerprint it forms the entry's key.
    build : callable
        Computes the arrays (a dict of numpy arrays).
    """
    key = _key(name, parts)
    path = cache_dir() / f"{name}-{key}.npz"
    try:
        with np.load(path, allow_pickle=False) as f:
            if str(f["__key__"]) == key:
                return {k: f[k] for k in f.files if k != "__key__"}
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
        pass  # missing, stale or corrupt: rebuild
    arrays = build()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{name}-", suffix=".npz")
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, __key__=np.array(key), **arrays)
        os.replace(tmp, path)  # atomic: readers never see a half-written file
    except OSError as e:
        warnings.warn(f"flexkin: cannot write the cache entry {path} ({e.strerror or e}); kept in memory only",
                      RuntimeWarning, stacklevel=2)
    return arrays
