"""The one decorator for flexkin's compiled kernels: ``numba.njit`` with an on-disk cache
that can never be stale.

numba checks a cached function against its *own* source file only: a kernel whose callee in
another module changed would silently reuse old machine code.  flexkin therefore keeps all
its kernel caches in one directory named by a fingerprint of every flexkin source file that
defines kernels (and of the numba version): any change to any kernel gives a new directory
and a fresh compilation, and no process ever recompiles what an earlier one compiled.

The directory is ``<user cache dir>/flexkin/numba/<fingerprint>`` (platformdirs; override the
base with the ``FLEXKIN_CACHE_DIR`` environment variable).  numba never falls back to its own
locations (the package's ``__pycache__``, the user-wide numba cache): those are checked
against one source file only and could hold stale machine code.  If the directory cannot be
created or written (a read-only installation, another user's cache), the process warns once
and uses a private temporary directory that mirrors it: the kernels already compiled there
are read from it (symbolic links, nothing is copied), new ones are compiled into the
temporary directory, which is removed at exit.  If not even a temporary directory can be
made, kernels are compiled in memory.
"""

from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import tempfile
import warnings
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
    """Where this version of the kernels is cached (named by the kernels' fingerprint; the
    cached arrays of :mod:`flexkin.core.cache` are keyed by this name)."""
    return _CACHE_DIR


def _not_writable(d: Path) -> str | None:
    """Why numba could not keep its cache in ``d`` (None if it can): the directory and every
    sub-directory numba made there must take new files."""
    try:
        d.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=d):
            pass
    except OSError as e:
        return e.strerror or str(e)
    try:
        subs = [p for p in d.iterdir() if p.is_dir()]
    except OSError as e:  # pragma: no cover - listable a moment ago
        return e.strerror or str(e)
    for p in subs:
        if not os.access(p, os.W_OK | os.X_OK):
            return f"{p.name} is not writable"
    return None


#: temporary kernel caches of this process (removed at exit by :func:`remove_temporary_caches`)
_TEMPORARY: list[Path] = []


def remove_temporary_caches() -> None:
    """Remove this process's temporary kernel caches (registered with :mod:`atexit`; a caller
    that ends the process with ``os._exit`` calls it first)."""
    while _TEMPORARY:
        shutil.rmtree(_TEMPORARY.pop(), True)


atexit.register(remove_temporary_caches)


def _mirror(src: Path) -> Path | None:
    """A private temporary directory mirroring ``src`` with symbolic links (removed at exit),
    or None if none can be made."""
    try:
        tmp = Path(tempfile.mkdtemp(prefix="flexkin-kernels-"))
    except OSError:
        return None
    _TEMPORARY.append(tmp)
    try:
        for root, _, files in os.walk(src):
            dst = tmp / Path(root).relative_to(src)
            dst.mkdir(exist_ok=True)
            for f in files:
                if not f.endswith(".tmp"):
                    os.symlink(Path(root) / f, dst / f)
    except OSError:
        pass  # what could not be mirrored is compiled again
    return tmp


def _usable_cache(d: Path) -> tuple[Path | None, str]:
    """The directory the kernels are cached in (``d``, a temporary mirror of it, or None: in
    memory only) and a warning to give (empty when ``d`` itself is used)."""
    why = _not_writable(d)
    if why is None:
        return d, ""
    tmp = _mirror(d)
    if tmp is None:
        return None, (f"the kernel cache {d} is not writable ({why}) and no temporary directory can be made: "
                      "kernels are compiled in memory, in every process (set FLEXKIN_CACHE_DIR to a writable "
                      "directory)")
    return tmp, (f"the kernel cache {d} is not writable ({why}): the kernels compiled there are read from it, new "
                 f"ones go to the temporary directory {tmp} for this process only (set FLEXKIN_CACHE_DIR to a "
                 "writable directory to keep them)")


_CACHE_DIR = cache_base() / "numba" / _fingerprint()
_USED_DIR, _WARNING = _usable_cache(_CACHE_DIR)
if _WARNING:
    from ..errors import FlexkinWarning

    warnings.warn(_WARNING, FlexkinWarning, stacklevel=2)


def _decorate(func: Callable, options: dict[str, Any]) -> Callable:
    if _USED_DIR is None:
        options = dict(options, cache=False)
        return numba.njit(**options)(func)
    old = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = str(_USED_DIR)
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
