"""Cache faults (issue 27, item 6).

* A filled but read-only cache directory: flexkin reads the kernels compiled there and compiles
  nothing (it used to recompile every kernel in every process, 184 s, or to write machine code
  into the package's ``__pycache__``, where numba cannot tell when it is stale), with one
  warning line; the read-only directory is left as it was and the temporary directory used
  instead is removed at exit.
* A failed write of a cached array (a full disk) leaves no temporary file behind (it left a
  1.7 MB one) and warns once.

The read-only directory is real (``chmod a-w``).  Tests may run as root, for whom permission
bits do not stop writes: the child process then drops the capabilities that override them
(``CAP_DAC_OVERRIDE``, ``CAP_DAC_READ_SEARCH``) from its bounding set before it starts, so the
directory is read-only for it too.
"""

from __future__ import annotations

import ctypes
import errno
import hashlib
import os
import shutil
import stat
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.core import cache as cache_mod
from flexkin.core.jit import kernel_cache_dir

ROOT = Path(__file__).resolve().parents[1]
PKG = Path(flexkin.__file__).resolve().parent
RFR = str(ROOT / "examples" / "unit_3rfr.toml")
COMMAND = ["ik", RFR, "--pose", "0.05", "0.02", "20", "--json", "--quiet"]
_PR_CAPBSET_DROP = 24
_CAP_DAC_OVERRIDE, _CAP_DAC_READ_SEARCH = 1, 2


def _drop_dac_capabilities() -> None:  # pragma: no cover - runs in the child
    libc = ctypes.CDLL(None, use_errno=True)
    for cap in (_CAP_DAC_OVERRIDE, _CAP_DAC_READ_SEARCH):
        if libc.prctl(_PR_CAPBSET_DROP, cap, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


def _numba_subdirs() -> list[str]:
    """The sub-directories numba uses in the kernel cache for flexkin's source directories."""
    names = []
    for d in sorted({p.parent for p in PKG.rglob("*.py")}):
        names.append(f"{d.name}_{hashlib.sha1(str(d).encode()).hexdigest()}")
    return names


def _read_only(path: Path) -> None:
    for root, dirs, files in os.walk(path):
        for n in files + dirs:
            p = Path(root) / n
            p.chmod(p.stat().st_mode & ~0o222)
    path.chmod(path.stat().st_mode & ~0o222)


def _writable_again(path: Path) -> None:
    if not path.exists():
        return
    path.chmod(path.stat().st_mode | stat.S_IWUSR)
    for root, dirs, files in os.walk(path):
        for n in files + dirs:
            p = Path(root) / n
            p.chmod(p.stat().st_mode | stat.S_IWUSR)


def _snapshot(path: Path) -> dict[str, tuple[int, float]]:
    out = {}
    for root, _, files in os.walk(path):
        for f in files:
            st = (Path(root) / f).stat()
            out[os.path.relpath(Path(root) / f, path)] = (st.st_size, st.st_mtime)
    return out


def _pycache_kernels() -> set[Path]:
    return set(PKG.rglob("__pycache__/*.nbi")) | set(PKG.rglob("__pycache__/*.nbc"))


@pytest.mark.skipif(sys.platform != "linux", reason="capabilities and chmod semantics of Linux")
def test_read_only_filled_cache_compiles_nothing_and_warns_once(tmp_path):
    from flexkin.cli import main

    # the cache is filled: everything the command needs is compiled and its atlases built
    import contextlib
    import io

    with contextlib.redirect_stdout(io.StringIO()):
        assert main(COMMAND) == 0
    base = tmp_path / "cache"
    src = kernel_cache_dir()
    dst = base / "numba" / src.name
    dst.mkdir(parents=True)
    for sub in _numba_subdirs():
        if (src / sub).is_dir():
            shutil.copytree(src / sub, dst / sub)
    shutil.copytree(cache_mod.cache_dir(), base / "arrays")
    assert any(dst.iterdir())
    _read_only(base)
    before, kernels_in_tree = _snapshot(base), _pycache_kernels()
    root = os.geteuid() == 0
    env = dict(os.environ, FLEXKIN_CACHE_DIR=str(base), NUMBA_DEBUG_CACHE="1",
               PYTHONPATH=str(PKG.parent) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    try:
        if not root:  # a real read-only directory for this user?
            try:
                (base / "probe").touch()
            except OSError:
                pass
            else:
                pytest.skip("chmod does not make the directory read-only here")
        t = time.perf_counter()
        p = subprocess.run([sys.executable, "-m", "flexkin.cli", *COMMAND], capture_output=True, text=True,
                           env=env, timeout=600, preexec_fn=_drop_dac_capabilities if root else None)
        dt = time.perf_counter() - t
        if root and p.returncode != 0 and "prctl" in p.stderr:
            pytest.skip(f"cannot drop the DAC capabilities here: {p.stderr.strip()[-200:]}")
        assert p.returncode == 0, p.stderr[-2000:]
        out = p.stdout.splitlines()
        loaded = sum("[cache] data loaded" in ln for ln in out)
        saved = [ln for ln in out if "[cache] data saved" in ln or "[cache] index saved" in ln]
        assert loaded > 0 and not saved, (loaded, saved[:3])  # nothing compiled: every kernel was read
        err = [ln for ln in p.stderr.splitlines() if ln.strip()]
        assert len(err) == 1 and err[0].startswith("flexkin: warning: the kernel cache") and "not writable" in err[0], \
            p.stderr[-2000:]
        tmp_dir = err[0].split("temporary directory ")[1].split(" ")[0]
        assert not Path(tmp_dir).exists()  # removed at exit
        assert _snapshot(base) == before  # the read-only cache is untouched
        assert _pycache_kernels() == kernels_in_tree  # and nothing went to the package's __pycache__
        assert dt < 300, dt  # loading, not compiling (which takes minutes)
    finally:
        _writable_again(base)


def _entry(tmp_path, monkeypatch):
    monkeypatch.setenv("FLEXKIN_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(cache_mod, "_WARNED", set(), raising=False)
    d = cache_mod.cache_dir()
    return d, (lambda: {"a": np.arange(300_000, dtype=float)})


def test_failed_cache_write_leaves_no_temporary_file(tmp_path, monkeypatch):
    d, build = _entry(tmp_path, monkeypatch)

    def no_space(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(cache_mod.os, "replace", no_space)  # the write fails at the last OS call
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        a = cache_mod.cached_arrays("faulty", (1,), build)
        b = cache_mod.cached_arrays("faulty", (2,), build)
    assert np.array_equal(a["a"], b["a"]) and len(a["a"]) == 300_000  # the arrays are still returned
    msgs = [str(x.message) for x in w if issubclass(x.category, flexkin.FlexkinWarning)]
    assert len(msgs) == 1 and "No space left on device" in msgs[0] and str(d) in msgs[0]  # once per directory
    assert list(d.iterdir()) == []  # no temporary file left (was a 2.4 MB one per call)


def test_cache_write_failing_midway_leaves_no_temporary_file(tmp_path, monkeypatch):
    d, build = _entry(tmp_path, monkeypatch)
    real = np.savez

    def disk_full_midway(fh, **arrays):
        fh.write(b"\0" * 1_000_000)  # part of the file is on disk when the disk fills up
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(cache_mod.np, "savez", disk_full_midway)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cache_mod.cached_arrays("faulty", (3,), build)
    assert list(d.iterdir()) == []
    monkeypatch.setattr(cache_mod.np, "savez", real)
    cache_mod.cached_arrays("faulty", (3,), build)  # a later write works and is read back
    (entry,) = d.iterdir()
    assert entry.name.startswith("faulty-") and cache_mod.cached_arrays("faulty", (3,), lambda: 1 / 0)
