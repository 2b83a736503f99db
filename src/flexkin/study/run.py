"""Running a study on Dask: :func:`run_study`.

Every (design, orientation) is one Dask task running
:func:`flexkin.study.evaluate.evaluate_design`.  By default the tasks run on a
:class:`distributed.LocalCluster` of worker processes on this machine (one thread each, as many
as cores); ``scheduler="tcp://HOST:PORT"`` submits them to an existing cluster instead (a
``dask scheduler`` with its ``dask worker`` processes, or a dask-jobqueue cluster on Slurm/PBS),
``client=`` uses a :class:`distributed.Client` you already hold, and
``scheduler="synchronous"`` runs them one after the other in this process (no Dask; for
debugging and profiling).

The client writes each row to ``DIR/rows/`` as soon as it completes, so a killed worker or
a killed study loses only the rows in flight; a re-run with the same ``DIR`` computes only
the missing rows.  The table is assembled at the end, in row order (design, then orientation),
so it does not depend on the number of workers or on the completion order.

When the cluster fails -- the connection to the scheduler is lost, or no worker is left for
``worker_timeout`` seconds -- the study stops with :class:`StudyAborted`; on Ctrl-C with
:class:`StudyInterrupted`.  Both name the rows finished (kept in ``DIR/rows``: a re-run
computes the rest); no table is written.  The local cluster's worker processes ignore Ctrl-C
(the study stops them), so an interrupt prints nothing of theirs.
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

from .evaluate import METRICS, DesignTask, evaluate_design
from .spec import StudyError, StudySpec, load_study, study_from_dict
from .table import RowStore, _atomic_write, rows_to_arrow, table_columns, write_table

__all__ = ["run_study", "StudyResult", "StudyAborted", "StudyInterrupted", "SYNCHRONOUS", "CONNECT_TIMEOUT",
           "WORKER_TIMEOUT", "default_workers"]

#: ``scheduler`` value that runs the study in the calling process, without Dask.
SYNCHRONOUS = "synchronous"
#: Seconds to wait for a scheduler given by address before giving up.
CONNECT_TIMEOUT = 10.0
#: Seconds the study waits while no Dask worker is connected before giving up.
WORKER_TIMEOUT = 60.0
#: Seconds between two looks at the cluster while no row completes.
_POLL = 0.5


def _row_label(task: DesignTask) -> str:
    params = ", ".join(f"{k} = {v:g}" for k, v in task.params)
    return f"design {task.design} ({params}) at {task.theta_deg:g} deg"


def _rows_named(tasks: list[DesignTask], limit: int = 8) -> str:
    names = [_row_label(t) for t in tasks[:limit]]
    more = f" and {len(tasks) - limit} more" if len(tasks) > limit else ""
    return "; ".join(names) + more


class _Stopped:
    """What a stopped study leaves: the rows finished by this run (kept in ``out/rows``)."""

    def _setup(self, reason: str, finished: list[DesignTask], remaining: int, out: Path) -> None:
        self.reason = reason
        self.finished = tuple(finished)
        self.remaining = int(remaining)
        self.out = out

    def describe(self) -> str:
        """One line: why, which rows are kept, how to resume."""
        kept = (f"{len(self.finished)} row(s) finished and kept in {self.out / 'rows'}: {_rows_named(list(self.finished))}"
                if self.finished else f"no row finished in this run (rows are kept in {self.out / 'rows'})")
        return (f"{self.reason}; {kept}; {self.remaining} row(s) not computed: run the same command again to "
                "compute them")


class StudyAborted(RuntimeError, _Stopped):
    """The study could not finish: the Dask scheduler was lost, or no worker was left.

    Attributes
    ----------
    reason : str
    finished : tuple of DesignTask
        The rows finished by this run (stored in ``out/rows``; a re-run reuses them).
    remaining : int
        Rows not computed.
    out : Path
    """

    def __init__(self, reason: str, finished: list[DesignTask], remaining: int, out: Path) -> None:
        self._setup(reason, finished, remaining, out)
        super().__init__(self.describe())


class StudyInterrupted(KeyboardInterrupt, _Stopped):
    """The study was interrupted (Ctrl-C); attributes as :class:`StudyAborted`."""

    def __init__(self, finished: list[DesignTask], remaining: int, out: Path) -> None:
        self._setup("interrupted", finished, remaining, out)
        super().__init__(self.describe())


class _ClusterLost(Exception):
    """Internal: the Dask cluster cannot compute the study any more (message: why)."""


@dataclass(frozen=True)
class StudyResult:
    """What :func:`run_study` did.

    Attributes
    ----------
    spec : StudySpec
    out : Path
        The output directory.
    parquet, csv : Path
        The table (``results.parquet``, ``results.csv``).
    figures : tuple of Path
    rows : tuple of dict
        The table's rows, in row order.
    columns : tuple of (name, type)
    n_computed, n_reused : int
        Rows computed by this run / taken from ``DIR/rows`` (finished by an earlier run).
    n_failed : int
        Rows with an ``error``.
    n_incomplete : int
        Rows cut short by the time budget (``complete`` false, no error).
    elapsed : float
        Seconds, for the whole run (cluster start-up included).
    compute_s : float
        Sum of ``elapsed_s`` of the rows computed by this run.
    scheduler : str
        ``"synchronous"``, ``"local"``, ``"client"`` or the scheduler address.
    workers : int
        Workers at the start of the computation (1 for synchronous, 0 when every row was reused).
    messages : tuple of str
        Things the user should know (e.g. a figure that could not be drawn).
    """

    spec: StudySpec = field(repr=False)
    out: Path
    parquet: Path
    csv: Path
    figures: tuple[Path, ...]
    rows: tuple[dict[str, Any], ...] = field(repr=False)
    columns: tuple[tuple[str, str], ...] = field(repr=False)
    n_computed: int
    n_reused: int
    n_failed: int
    n_incomplete: int
    elapsed: float
    compute_s: float
    scheduler: str
    workers: int
    messages: tuple[str, ...] = ()

    def table(self):
        """The table as a :class:`pyarrow.Table`."""
        return rows_to_arrow(self.rows, self.columns)

    def summary(self) -> str:
        """One line: rows, reuse, failures, time, where the table is."""
        s = (f"{self.spec.name}: {len(self.rows)} rows ({self.spec.n_designs} designs x "
             f"{len(self.spec.orientations)} orientations): {self.n_computed} computed, {self.n_reused} reused")
        if self.n_failed:
            s += f", {self.n_failed} failed"
        if self.n_incomplete:
            s += f", {self.n_incomplete} incomplete"
        where = f" on {self.workers} worker(s) ({self.scheduler})" if self.n_computed else ""
        return s + f"; {self.elapsed:.1f} s{where}; table {self.parquet}"


def _error_row(task: DesignTask, message: str) -> dict[str, Any]:
    row: dict[str, Any] = {"design": task.design}
    row.update(dict(task.params))
    row["theta_deg"] = task.theta_deg
    row.update({m: None for m in task.metrics})
    row.update({"complete": False, "error": message, "note": "", "elapsed_s": None})
    return row


def _one_line(e: BaseException) -> str:
    msg = " ".join(str(e).split())
    return f"{type(e).__name__}: {msg}" if msg else type(e).__name__


def _spec(spec_or_path: StudySpec | str | os.PathLike[str] | Mapping[str, Any]) -> StudySpec:
    if isinstance(spec_or_path, StudySpec):
        return spec_or_path
    if isinstance(spec_or_path, Mapping):
        return study_from_dict(spec_or_path)
    return load_study(spec_or_path)


def _out_dir(out: str | os.PathLike[str]) -> Path:
    try:
        p = Path(os.fspath(out))
    except TypeError:
        raise StudyError(f"out: expected a directory path, got {out!r}") from None
    if not str(p):
        raise StudyError("out: empty directory name")
    if p.exists() and not p.is_dir():
        raise StudyError(f"{p}: exists and is not a directory")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise StudyError(f"{p}: cannot create the output directory ({e.strerror or e})") from None
    if not os.access(p, os.W_OK):
        raise StudyError(f"{p}: the output directory is not writable")
    return p


def _ask_identity(address: str, timeout: float) -> dict[str, Any]:
    """The identity a Dask server at ``address`` gives (raises on anything else: no answer within
    ``timeout``, a peer that does not speak Dask's protocol)."""
    import asyncio

    from distributed.comm import connect

    async def ask() -> Any:
        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["reply"] = asyncio.run(asyncio.wait_for(ask(), timeout))
        except BaseException as e:  # noqa: BLE001 - reported by the caller
            box["error"] = e

    th = threading.Thread(target=run, name="flexkin-study-probe", daemon=True)
    th.start()
    th.join(timeout + 0.5)
    if "reply" in box:
        return box["reply"] if isinstance(box["reply"], dict) else {"reply": box["reply"]}
    raise box.get("error") or TimeoutError(f"no answer within {timeout:g} s")


def _disarm(e: BaseException | None) -> None:
    """A Client whose construction failed is left half-built inside the exception's traceback;
    at garbage collection it would wait for its own close (seconds) and print a traceback: mark
    it closed first."""
    import traceback

    from distributed import Client

    if e is None:
        return
    for frame, _ in traceback.walk_tb(e.__traceback__):
        obj = frame.f_locals.get("self")
        if isinstance(obj, Client):
            obj.status = "closed"
            try:
                obj._loop_runner.stop()
            except Exception:  # noqa: BLE001 - best effort
                pass
    e.__traceback__ = None


def _parse_address(scheduler: str) -> tuple[str, tuple[str, int] | None]:
    """The scheme of a scheduler address and, for TCP, its host and port (StudyError if bad)."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import backends

    try:
        scheme, loc = parse_address(scheduler)
        if scheme not in backends:
            raise ValueError(f"unknown scheme {scheme!r}; known: {', '.join(sorted(backends))}")
        return scheme, (parse_host_port(loc) if scheme == "tcp" else None)
    except (ValueError, TypeError) as e:
        raise StudyError(f"bad Dask scheduler address {scheduler!r} ({' '.join(str(e).split())}); "
                         "expected tcp://HOST:PORT") from None


def _connect(scheduler: str, timeout: float):
    """A client of the scheduler at ``scheduler``, or a StudyError within ``timeout`` seconds."""
    import gc
    import socket

    from distributed import Client

    _, host_port = _parse_address(scheduler)
    deadline = time.monotonic() + timeout
    if host_port is not None:  # a plain TCP probe first: a clear error, and no half-open client
        last: Exception | None = None
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise StudyError(f"cannot connect to the Dask scheduler at {scheduler!r} within {timeout:g} s "
                                 f"({_one_line(last) if last else 'timed out'})")
            try:
                socket.create_connection(host_port, timeout=min(left, 2.0)).close()
                break
            except OSError as e:
                last = e
                time.sleep(min(0.2, max(deadline - time.monotonic(), 0.0)))
    # something listens: is it a Dask scheduler?  (a peer that accepts but does not speak Dask
    # would make the client hang or fail half-built)
    try:
        ident = _ask_identity(scheduler, max(deadline - time.monotonic(), 0.1))
    except BaseException as e:  # noqa: BLE001 - any failure means: no scheduler there
        raise StudyError(f"no Dask scheduler answers at {scheduler!r} within {timeout:g} s ({_one_line(e)})") from None
    if "Scheduler" not in str(ident.get("type", "")):
        raise StudyError(f"the Dask server at {scheduler!r} is not a scheduler (it says type "
                         f"{str(ident.get('type'))[:40]!r})")
    # build the client in a daemon thread and give up at the deadline
    box: dict[str, Any] = {}

    def build() -> None:
        try:
            box["client"] = Client(scheduler, timeout=max(deadline - time.monotonic(), 1.0), set_as_default=False)
        except Exception as e:  # noqa: BLE001 - reported below
            box["error"] = e

    th = threading.Thread(target=build, name="flexkin-study-connect", daemon=True)
    th.start()
    th.join(max(deadline - time.monotonic(), 0.0) + 1.0)
    if "client" in box:
        return box["client"]
    e = box.pop("error", None)
    _disarm(e)
    hook = sys.unraisablehook
    sys.unraisablehook = lambda *_: None  # a half-built client's __del__ would print a traceback
    try:
        gc.collect()
    finally:
        sys.unraisablehook = hook
    if isinstance(e, ValueError):
        raise StudyError(f"bad Dask scheduler address {scheduler!r} ({' '.join(str(e).split())})") from None
    why = _one_line(e) if e is not None else "no answer from the scheduler"
    raise StudyError(f"cannot connect to the Dask scheduler at {scheduler!r} within {timeout:g} s ({why})")


def _check_workers(client: Any) -> None:
    """Every worker connected now must be able to import flexkin."""
    import importlib.util

    try:
        found = client.run(importlib.util.find_spec, "flexkin", on_error="return")
    except Exception:  # pragma: no cover - the check is a courtesy, the rows report failures anyway
        return
    for addr, spec in sorted(found.items()):
        if spec is None or isinstance(spec, BaseException):
            why = _one_line(spec) if isinstance(spec, BaseException) else "no module named 'flexkin'"
            raise StudyError(f"Dask worker {addr} cannot import flexkin ({why}); install flexkin in the "
                             "workers' Python environment")


def run_study(spec_or_path: StudySpec | str | os.PathLike[str] | Mapping[str, Any], out: str | os.PathLike[str],
              workers: int | None = None, scheduler: str | None = None, progress: bool = True, *,
              client: Any = None, figures: bool = True, retry_failed: bool = False,
              timeout: float = CONNECT_TIMEOUT, on_row: Callable[[dict[str, Any]], None] | None = None,
              worker_timeout: float = WORKER_TIMEOUT) -> StudyResult:
    """Run a design study and write its table and figures into ``out``.

    Parameters
    ----------
    spec_or_path : StudySpec, path or dict
        A validated study, a study file, or a parsed study file (paths relative to the
        current directory).
    out : path
        Output directory (created).  Rows finished by an earlier run into the same directory
        are reused.
    workers : int, optional
        Worker processes of the local cluster (default: the number of cores).
    scheduler : str, optional
        ``"tcp://HOST:PORT"`` (any address a :class:`distributed.Client` accepts) of a running
        Dask scheduler, or ``"synchronous"`` to compute in this process without Dask.
    progress : bool
        A progress bar on stderr counting completed rows (only when stderr is a terminal).
    client : distributed.Client, optional
        Use this client (e.g. of a dask-jobqueue cluster); it is left open.
    figures : bool
        Write the figures (default true).
    retry_failed : bool
        Compute again the stored rows that have an ``error``.
    timeout : float
        Seconds to wait when connecting to ``scheduler``.
    on_row : callable, optional
        Called in this process with each row as it completes (after it is stored).
    worker_timeout : float
        Seconds to wait while no Dask worker is connected (none started, all lost) before
        giving up with :class:`StudyAborted`.

    Returns
    -------
    StudyResult

    Raises
    ------
    StudyError
        Bad study file or arguments, unwritable ``out``, unreachable scheduler.
    StudyAborted
        The cluster failed (scheduler lost, no worker left); the finished rows are kept.
    StudyInterrupted
        Ctrl-C (a :class:`KeyboardInterrupt`); the finished rows are kept.
    """
    t_start = time.perf_counter()
    spec = _spec(spec_or_path)
    n_given = sum(x is not None for x in (workers, scheduler, client))
    if n_given > 1:
        raise StudyError("give at most one of workers, scheduler and client")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 4096):
        raise StudyError(f"workers: expected an integer from 1 to 4096, got {workers!r}")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise StudyError(f"scheduler: expected an address such as tcp://host:8786, got {scheduler!r}")
    for name, v in (("timeout", timeout), ("worker_timeout", worker_timeout)):
        if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise StudyError(f"{name}: expected a number of seconds > 0, got {v!r}")
    if scheduler is not None and scheduler != SYNCHRONOUS:
        _parse_address(scheduler)  # a bad address fails before any work
    outp = _out_dir(out)
    tasks = spec.tasks()
    _atomic_write(outp / "study.json", json.dumps(spec.to_dict(), indent=2, allow_nan=False).encode())
    store = RowStore(outp)
    done: dict[str, dict[str, Any]] = {}
    for t in tasks:
        row = store.get(t.key)
        if row is not None and not (retry_failed and row.get("error")):
            done[t.key] = row
    todo = list({t.key: t for t in tasks if t.key not in done}.values())  # identical rows: computed once
    reused = len(done)
    computed: dict[str, dict[str, Any]] = {}

    bar = None
    if progress and sys.stderr is not None and sys.stderr.isatty() and todo:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(todo) + reused, initial=reused, desc=f"study {spec.name}", unit="row", file=sys.stderr,
                   dynamic_ncols=True, leave=False, mininterval=0, miniters=1)  # every row is drawn

    def finish(task: DesignTask, row: dict[str, Any], keep: bool) -> None:
        if keep:
            store.put(task.key, row)
        computed[task.key] = row
        if bar is not None:
            bar.update(1)
        if on_row is not None:
            on_row(row)

    mode, n_workers = SYNCHRONOUS, (1 if todo else 0)
    by_key = {t.key: t for t in todo}

    def kept() -> list[DesignTask]:
        return [by_key[k] for k, r in computed.items() if k in by_key and not r.get("error")]

    try:
        if todo and scheduler == SYNCHRONOUS:
            for t in todo:
                finish(t, evaluate_design(t), True)
        elif todo:
            mode, n_workers = _run_dask(todo, finish, workers, scheduler, client, timeout, worker_timeout)
        elif client is not None:
            mode = "client"
        elif scheduler is not None:
            mode = scheduler
        else:
            mode = "local"
    except _ClusterLost as e:
        done_ok = kept()
        raise StudyAborted(str(e), done_ok, len(todo) - len(done_ok), outp) from None
    except KeyboardInterrupt:
        done_ok = kept()
        raise StudyInterrupted(done_ok, len(todo) - len(done_ok), outp) from None
    finally:
        if bar is not None:
            bar.close()

    rows = []
    for t in tasks:
        src = done.get(t.key) or computed[t.key]
        row = dict(src)
        row["design"] = t.design  # the stored row may come from a study with another grid
        row.update(dict(t.params))
        row["theta_deg"] = t.theta_deg
        rows.append(row)
    columns = table_columns(spec.keys, {m: METRICS[m].dtype for m in spec.metrics})
    pq_path, csv_path = write_table(rows, columns, outp)
    figs: list[Path] = []
    messages: list[str] = []
    if figures:
        from .figures import study_figures

        try:
            figs, msgs = study_figures(rows, spec, outp)
            messages.extend(msgs)
        except Exception as e:  # the table is written; a figure problem must not lose the study
            messages.append(f"figures not written: {_one_line(e)}")
    new = list(computed.values())
    return StudyResult(
        spec=spec, out=outp, parquet=pq_path, csv=csv_path, figures=tuple(figs), rows=tuple(rows),
        columns=tuple(columns), n_computed=len(new), n_reused=reused,
        n_failed=sum(1 for r in rows if r.get("error")),
        n_incomplete=sum(1 for r in rows if not r.get("error") and not r.get("complete")),
        elapsed=time.perf_counter() - t_start,
        compute_s=float(sum(r.get("elapsed_s") or 0.0 for r in new)), scheduler=mode, workers=n_workers,
        messages=tuple(messages))


def default_workers() -> int:
    """Worker processes of the default local cluster: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


class _QuietDask:
    """Dask's own log messages (reconnection attempts, tracebacks of a lost connection) silenced
    while a study runs: the study reports what happened itself, in one line."""

    _NAMES = ("distributed", "tornado", "asyncio")

    def __enter__(self) -> _QuietDask:
        import logging

        names = [n for n in list(logging.root.manager.loggerDict)
                 if any(n == p or n.startswith(p + ".") for p in self._NAMES)]
        self._levels = {n: logging.getLogger(n).level for n in set(names) | set(self._NAMES)}
        for n in self._levels:
            logging.getLogger(n).setLevel(logging.CRITICAL + 1)
        return self

    def __exit__(self, *exc: Any) -> None:
        import logging

        for n, lv in self._levels.items():
            logging.getLogger(n).setLevel(lv)


def _connected_workers(client: Any) -> int | None:
    """Workers connected to the scheduler now (None if the scheduler does not answer)."""
    try:
        return len(client.sync(client.scheduler.ncores, callback_timeout=5.0))
    except Exception:  # noqa: BLE001 - a scheduler that does not answer
        return None


def _run_dask(todo: list[DesignTask], finish: Callable[[DesignTask, dict[str, Any], bool], None],
              workers: int | None, scheduler: str | None, client: Any, timeout: float,
              worker_timeout: float = WORKER_TIMEOUT) -> tuple[str, int]:
    """Compute ``todo`` on Dask; call ``finish`` for each row as it completes.  Raises
    ``_ClusterLost`` when the scheduler is lost or no worker is left for ``worker_timeout``."""
    import logging

    from distributed import Client, LocalCluster, as_completed

    cluster = None
    own_client = client is None
    quiet = _QuietDask().__enter__()
    try:
        if client is not None:
            mode = "client"
        elif scheduler is not None:
            client = _connect(scheduler, timeout)
            mode = scheduler
        else:
            # the worker processes ignore Ctrl-C (the study stops them): those started now inherit
            # the ignored signal from the start, those a nanny restarts set it in their preload
            main = threading.current_thread() is threading.main_thread()
            old = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
            try:
                cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=logging.CRITICAL,
                                       # no dashboard; the scheduler's small HTTP server on a free
                                       # local port (its default 8787 may be taken: a warning)
                                       scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                       preload=["flexkin.study.worker_setup"])
            except Exception as e:
                raise StudyError(f"cannot start a local Dask cluster ({_one_line(e)}); a script that runs a study "
                                 "must guard it with `if __name__ == \"__main__\":`") from None
            finally:
                if main:
                    signal.signal(signal.SIGINT, old)
            client = Client(cluster, set_as_default=False)
            mode = "local"
    except BaseException:
        quiet.__exit__(None, None, None)
        raise
    where = "the Dask scheduler" + (f" at {scheduler}" if scheduler else "")
    futures: dict[str, tuple[Any, DesignTask]] = {}
    try:
        if mode != "local":
            _check_workers(client)
        n_workers = len(client.nthreads())
        for t in todo:
            fut = client.submit(evaluate_design, t, key=f"flexkin-study-{t.key}", pure=False, retries=0)
            futures[fut.key] = (fut, t)
        ac = as_completed([f for f, _ in futures.values()], loop=client.loop)
        idle_since: float | None = None
        last_look = time.monotonic()
        while not ac.is_empty():
            batch = ac.next_batch(block=False)
            for fut in batch:
                _, t = futures.pop(fut.key)
                if client.status != "running":
                    futures[fut.key] = (fut, t)
                    break
                try:
                    row = fut.result()
                except Exception as e:  # the worker died (KilledWorker), lost data, cancelled...
                    if client.status != "running":
                        futures[fut.key] = (fut, t)
                        break
                    finish(t, _error_row(t, _one_line(e)), False)  # not stored: a re-run tries again
                else:
                    finish(t, row, True)
                fut.release()
            if client.status != "running":
                raise _ClusterLost(f"lost the connection to {where}")
            if batch:
                idle_since, last_look = None, time.monotonic()
                continue
            time.sleep(_POLL)
            if time.monotonic() - last_look < 2 * _POLL:
                continue
            last_look = time.monotonic()
            n = _connected_workers(client)
            if n is None or client.status != "running":
                raise _ClusterLost(f"lost the connection to {where}")
            if n > 0:
                idle_since = None
            elif idle_since is None:
                idle_since = time.monotonic()
            elif time.monotonic() - idle_since > worker_timeout:
                raise _ClusterLost(f"no Dask worker connected to {where} for {worker_timeout:g} s "
                                   "(start workers, or give --worker-timeout more time)")
    except BaseException:
        for fut, _ in futures.values():
            try:
                fut.cancel()
            except Exception:  # noqa: BLE001 - the scheduler may be gone
                pass
        raise
    finally:
        try:
            if own_client:
                client.close(timeout=5)
            if cluster is not None:
                cluster.close(timeout=10)
        except BaseException:  # noqa: BLE001 - closing a lost or interrupted cluster: nothing more to do
            pass
        quiet.__exit__(None, None, None)
    return mode, max(n_workers, 1)
