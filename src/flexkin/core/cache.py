"""Arrays cached on disk in the user's cache directory (atlases and search trees).

An entry is an ``.npz`` file named by the entry's name and a version key (a hash of the
arguments, the flexkin version and whatever the caller includes, e.g. a fingerprint of the
code that builds it).  Reading never trusts the file blindly: a missing, stale (other key),
truncated or otherwise unreadable file is rebuilt; a cache directory that cannot be written
(read-only, full) leaves the arrays in memory only, with one warning per process, and never a
temporary file behind.  Nothing is ever shipped prebuilt.

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
from .version import __version__

__all__ = ["cached_arrays", "cache_dir"]


def cache_dir() -> Path:
    """Where cached arrays live."""
    return cache_base() / "arrays"


def _key(name: str, parts: tuple) -> str:
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
    _store(path, key, arrays)
    return arrays


#: directories whose write failure was already reported (one warning per process and directory)
_WARNED: set[str] = set()


def _store(path: Path, key: str, arrays: dict[str, NDArray]) -> None:
    """Write an entry atomically; on failure warn (once per directory) and leave nothing behind."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}-", suffix=".npz")
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, __key__=np.array(key), **arrays)
        os.replace(tmp, path)  # atomic: readers never see a half-written file
        tmp = None
    except OSError as e:
        if str(path.parent) not in _WARNED:
            _WARNED.add(str(path.parent))
            from ..errors import FlexkinWarning

            warnings.warn(f"cannot write to the array cache {path.parent} ({e.strerror or e}): atlases are kept in "
                          "memory only and built again in every process (set FLEXKIN_CACHE_DIR to a writable "
                          "directory)", FlexkinWarning, stacklevel=3)
    finally:
        if tmp is not None:  # a failed write (disk full, ...) leaves no temporary file behind
            try:
                os.unlink(tmp)
            except OSError:
                pass
