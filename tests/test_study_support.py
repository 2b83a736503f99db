"""Shared helpers of the design-study tests (no tests here).

A tiny study (2 designs x 2 orientations of the unit 3-RFR, 0.1 m grid, one aspect) is the
workload of every run; its synchronous (single-process) table is the reference that the Dask
runs must reproduce.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

TINY = f'''
name = "tiny"
mechanism = "{(EXAMPLES / 'unit_3rfr.toml').as_posix()}"
orientations = [10, 20]
[grid]
"rod.length" = [1.0, 1.1]
[workspace]
step = 0.1
all_aspects = false
'''

_REFERENCE: dict[str, list[dict]] = {}


def write_study(directory: Path, body: str, name: str = "study.toml") -> Path:
    p = Path(directory) / name
    p.write_text(body)
    return p


def strip(rows) -> list[dict]:
    """Rows without the timing column (the only one that differs between runs)."""
    return [{k: v for k, v in r.items() if k != "elapsed_s"} for r in rows]


def reference_rows() -> list[dict]:
    """The tiny study computed once, single-process (cached for the session)."""
    if "tiny" not in _REFERENCE:
        from flexkin.study import run_study

        d = Path(tempfile.mkdtemp(prefix="flexkin_study_ref_"))
        atexit.register(shutil.rmtree, d, True)
        res = run_study(write_study(d, TINY), d / "out", scheduler="synchronous", progress=False, figures=False)
        assert res.n_computed == 4 and res.n_failed == 0, res.rows
        _REFERENCE["tiny"] = strip(res.rows)
    return _REFERENCE["tiny"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_port(port: int, timeout: float) -> None:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        with socket.socket() as s:
            s.settimeout(0.5)
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.1)
    raise TimeoutError(f"nothing listens on port {port} after {timeout} s")


def _spawn(args: list[str], log: Path) -> subprocess.Popen:
    fh = open(log, "wb")
    return subprocess.Popen(args, stdout=fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                            start_new_session=True, env=dict(os.environ))


def kill(proc: subprocess.Popen, sig: int = signal.SIGKILL) -> None:
    """Kill a process this test started, and its process group (nanny children)."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, sig)
        with contextlib.suppress(ProcessLookupError):
            proc.kill()
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=10)


@contextlib.contextmanager
def dask_processes(logdir: Path, n_workers: int = 1, nanny: bool = True, timeout: float = 60.0):
    """A real ``dask scheduler`` and ``dask worker`` on localhost (free ports), as subprocesses;
    yields ``(address, worker_procs, start_worker)``; everything is killed on exit."""
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    procs: list[subprocess.Popen] = []
    workers: list[subprocess.Popen] = []

    def start_worker() -> subprocess.Popen:
        args = [sys.executable, "-m", "distributed.cli.dask_worker", addr, "--nthreads", "1", "--no-dashboard",
                "--host", "127.0.0.1", "--local-directory", str(logdir)]
        args += ["--nworkers", str(n_workers)] if nanny else ["--no-nanny"]
        w = _spawn(args, Path(logdir) / f"worker{len(workers)}.log")
        procs.append(w)
        workers.append(w)
        return w

    try:
        procs.append(_spawn([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                             "--port", str(port), "--no-dashboard"], Path(logdir) / "scheduler.log"))
        wait_port(port, timeout)
        start_worker()
        from distributed import Client

        with Client(addr, timeout=timeout, set_as_default=False) as c:
            c.wait_for_workers(n_workers if nanny else 1, timeout=timeout)
        yield addr, workers, start_worker
    finally:
        for p in reversed(procs):
            kill(p)
