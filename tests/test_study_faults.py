"""Study failures a script can see (issue 27, item 4): every failure exits non-zero with a short
message, and a stopped study names the rows it keeps.

* rows that fail: exit 1 with one line (the first error), the table written; settings no
  design can use (``step = 1e-9``): exit 2 before any work, one line;
* a bad ``--scheduler``: exit 2 within ``--timeout`` with one line, no traceback (a refused
  port, a peer that is not a Dask scheduler, an unknown scheme);
* the Dask scheduler lost mid-study, or no worker left: exit 3 with one line naming the rows
  kept (real ``dask scheduler`` / ``dask worker`` processes on localhost);
* a real Ctrl-C (SIGINT to the study's process group, as a terminal sends it): exit 130, one
  line naming the rows kept, no tracebacks of the local cluster's workers.

The cluster tests start real processes and take tens of seconds each: they are marked slow.
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from flexkin.study import run_study
from flexkin.study.spec import StudyError
from test_study_support import TINY, _spawn, free_port, kill, wait_port, write_study

CLI = "import sys; from flexkin.study.cli import main; sys.exit(main(sys.argv[1:]))"
SIX = TINY.replace('"rod.length" = [1.0, 1.1]', '"rod.length" = [1.0, 1.05, 1.1]').replace(
    "orientations = [10, 20]", "orientations = [10, 15, 20]")


def study_cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", CLI, "study", *args], capture_output=True, text=True,
                          timeout=timeout)


def lines(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if ln.strip()]


# ---- rows that fail --------------------------------------------------------------------------
def test_failed_rows_exit_1_with_one_line(tmp_path, capsys):
    from flexkin.cli import main

    # the 1e4 m rods make the default grid (a quarter rod length around the legs) too large
    body = TINY.replace('"rod.length" = [1.0, 1.1]', '"rod.length" = [1.0, 1e4]').replace("orientations = [10, 20]",
                                                                                     "orientations = [10]")
    code = main(["study", str(write_study(tmp_path, body)), "--out", str(tmp_path / "out"), "--scheduler",
                 "synchronous", "--quiet", "--no-figures"])
    out, err = capsys.readouterr()
    assert code == 1, err
    (msg,) = lines(err)
    assert "1 of 2 row(s) failed" in msg and "design 1 at 10 deg" in msg and "too large" in msg
    assert (tmp_path / "out" / "results.csv").is_file()


def test_settings_no_design_can_use_exit_2_before_any_work(tmp_path, capsys):
    from flexkin.cli import main

    body = TINY.replace("step = 0.1", "step = 1e-9")
    t = time.perf_counter()
    code = main(["study", str(write_study(tmp_path, body)), "--out", str(tmp_path / "out"), "--quiet"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and time.perf_counter() - t < 30
    (msg,) = lines(err)
    assert "workspace.step" in msg and "too large" in msg and "Traceback" not in err
    assert not (tmp_path / "out" / "rows").exists()


# ---- a bad scheduler address -----------------------------------------------------------------
@contextlib.contextmanager
def not_a_scheduler():
    """A TCP server on localhost that accepts connections and answers garbage (as a proxy or
    another service would)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    stop = threading.Event()

    def serve() -> None:
        srv.settimeout(0.2)
        conns = []
        while not stop.is_set():
            try:
                c, _ = srv.accept()
            except OSError:
                continue
            with contextlib.suppress(OSError):
                c.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n" + b"\xff" * 64)
            conns.append(c)
        for c in conns:
            c.close()

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    try:
        yield f"tcp://127.0.0.1:{srv.getsockname()[1]}"
    finally:
        stop.set()
        th.join(2)
        srv.close()


def test_bad_scheduler_fails_within_timeout_without_traceback_in_process(tmp_path):
    """In-process (start-up excluded): the study gives up within ``timeout`` and leaves no
    half-built client behind (its garbage collection used to wait 2 x timeout and print a
    traceback)."""
    study = write_study(tmp_path, TINY)
    seen: list = []
    hook = sys.unraisablehook
    sys.unraisablehook = lambda u: seen.append(u)
    try:
        with not_a_scheduler() as addr:
            for address in (addr, f"tcp://127.0.0.1:{free_port()}", "foo://x"):
                t = time.perf_counter()
                with pytest.raises(StudyError) as e:
                    run_study(study, tmp_path / "out", scheduler=address, progress=False, timeout=2.0)
                gc.collect()
                dt = time.perf_counter() - t
                assert dt < 2.0 + 3.0, (address, dt)
                assert address in str(e.value) and "\n" not in str(e.value)
    finally:
        sys.unraisablehook = hook
    assert not seen, seen


def test_bad_scheduler_cli_one_line(tmp_path):
    study = write_study(tmp_path, TINY)
    with not_a_scheduler() as addr:
        p = study_cli(str(study), "--out", str(tmp_path / "out"), "--scheduler", addr, "--timeout", "2", "--quiet")
    assert p.returncode == 2, p.stderr
    (msg,) = lines(p.stderr)
    assert "Traceback" not in p.stderr and addr in msg and "no Dask scheduler answers" in msg


# ---- the cluster fails mid-study ---------------------------------------------------------------
@contextlib.contextmanager
def cluster(logdir: Path, n_workers: int = 1):
    """``dask scheduler`` and ``dask worker`` processes (no nanny) on localhost: yields
    ``(address, scheduler_process, worker_processes)``; all killed on exit."""
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    procs: list[subprocess.Popen] = []
    try:
        sched = _spawn([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
                        str(port), "--no-dashboard"], logdir / "scheduler.log")
        procs.append(sched)
        wait_port(port, 60)
        workers = []
        for k in range(n_workers):
            workers.append(_spawn([sys.executable, "-m", "distributed.cli.dask_worker", addr, "--nthreads", "1",
                                   "--no-dashboard", "--host", "127.0.0.1", "--no-nanny", "--local-directory",
                                   str(logdir)], logdir / f"worker{k}.log"))
            procs.append(workers[-1])
        from distributed import Client

        with Client(addr, timeout=60, set_as_default=False) as c:
            c.wait_for_workers(n_workers, timeout=60)
        yield addr, sched, workers
    finally:
        for p in reversed(procs):
            kill(p)


def _start_study(tmp_path: Path, *args: str) -> tuple[subprocess.Popen, Path]:
    out = tmp_path / "out"
    cmd = [sys.executable, "-c", CLI, "study", str(write_study(tmp_path, SIX)), "--out", str(out), "--quiet",
           "--no-figures", *args]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    rows = out / "rows"
    t_end = time.monotonic() + 240
    while time.monotonic() < t_end and proc.poll() is None:
        if rows.is_dir() and any(rows.glob("*.json")):
            return proc, rows
        time.sleep(0.05)
    kill(proc)
    pytest.fail(f"no row finished: {proc.stderr.read() if proc.stderr else ''}")


def _stopped_cleanly(proc: subprocess.Popen, rows: Path, code: int, fragment: str, limit: float) -> None:
    t = time.monotonic()
    try:
        out, err = proc.communicate(timeout=limit)
    except subprocess.TimeoutExpired:
        kill(proc)
        pytest.fail(f"the study did not stop within {limit} s")
    assert proc.returncode == code, err
    assert "Traceback" not in err, err[-3000:]
    (msg,) = lines(err)
    kept = sorted(rows.glob("*.json"))
    assert fragment in msg and f"{len(kept)} row(s) finished and kept" in msg and "design " in msg, msg
    assert "run the same command again" in msg
    assert time.monotonic() - t < limit


@pytest.mark.slow
def test_scheduler_lost_mid_study_exits_3_naming_the_rows(tmp_path):
    with cluster(tmp_path) as (addr, sched, _):
        proc, rows = _start_study(tmp_path, "--scheduler", addr)
        kill(sched)
        _stopped_cleanly(proc, rows, 3, "lost the connection to the Dask scheduler", 60)


@pytest.mark.slow
def test_no_worker_left_exits_3_after_the_worker_timeout(tmp_path):
    with cluster(tmp_path) as (addr, _, workers):
        proc, rows = _start_study(tmp_path, "--scheduler", addr, "--worker-timeout", "5")
        kill(workers[0])
        _stopped_cleanly(proc, rows, 3, "no Dask worker connected", 60)


@pytest.mark.slow
def test_ctrl_c_stops_quietly_and_names_the_rows_kept(tmp_path):
    proc, rows = _start_study(tmp_path, "--workers", "2")
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal's Ctrl-C does: the whole process group
    _stopped_cleanly(proc, rows, 130, "interrupted", 60)
    kept = len(list(rows.glob("*.json")))
    res = run_study(tmp_path / "study.toml", tmp_path / "out", scheduler="synchronous", progress=False,
                    figures=False)  # the re-run computes only the rest
    assert (res.n_reused, res.n_computed, res.n_failed) == (kept, 9 - kept, 0)
