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
"""

from __future__ import annotations

import json
import math
import os
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

from .evaluate import METRICS, DesignTask, evaluate_design
from .spec import StudyError, StudySpec, load_study, study_from_dict
from .table import RowStore, _atomic_write, rows_to_arrow, table_columns, write_table

__all__ = ["run_study", "StudyResult", "SYNCHRONOUS", "CONNECT_TIMEOUT", "default_workers"]

#: ``scheduler`` value that runs the study in the calling process, without Dask.
SYNCHRONOUS = "synchronous"
#: Seconds to wait for a scheduler given by address before giving up.
CONNECT_TIMEOUT = 10.0


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


def _connect(scheduler: str, timeout: float):
    """A client of the scheduler at ``scheduler``, or a StudyError within ``timeout`` seconds."""
    import gc
    import socket

    from distributed import Client
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, loc = parse_address(scheduler)
        host_port = parse_host_port(loc) if scheme == "tcp" else None
    except (ValueError, TypeError) as e:
        raise StudyError(f"bad Dask scheduler address {scheduler!r} ({' '.join(str(e).split())}); "
                         "expected tcp://HOST:PORT") from None
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
    # the handshake can hang on a peer that accepts but does not answer: build the client in a
    # daemon thread and give up at the deadline
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
    e = box.get("error")
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
              timeout: float = CONNECT_TIMEOUT, on_row: Callable[[dict[str, Any]], None] | None = None
              ) -> StudyResult:
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

    Returns
    -------
    StudyResult

    Raises
    ------
    StudyError
        Bad study file or arguments, unwritable ``out``, unreachable scheduler.
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
    if not (isinstance(timeout, (int, float)) and math.isfinite(timeout) and timeout > 0):
        raise StudyError(f"timeout: expected a number of seconds > 0, got {timeout!r}")
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
    try:
        if todo and scheduler == SYNCHRONOUS:
            for t in todo:
                finish(t, evaluate_design(t), True)
        elif todo:
            mode, n_workers = _run_dask(todo, finish, workers, scheduler, client, timeout)
        elif client is not None:
            mode = "client"
        elif scheduler is not None:
            mode = scheduler
        else:
            mode = "local"
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


def _run_dask(todo: list[DesignTask], finish: Callable[[DesignTask, dict[str, Any], bool], None],
              workers: int | None, scheduler: str | None, client: Any, timeout: float) -> tuple[str, int]:
    """Compute ``todo`` on Dask; call ``finish`` for each row as it completes."""
    import logging

    from distributed import Client, LocalCluster, as_completed

    cluster = None
    own_client = client is None
    if client is not None:
        mode = "client"
    elif scheduler is not None:
        client = _connect(scheduler, timeout)
        mode = scheduler
    else:
        try:
            cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
        except Exception as e:
            raise StudyError(f"cannot start a local Dask cluster ({_one_line(e)}); a script that runs a study "
                             "must guard it with `if __name__ == \"__main__\":`") from None
        client = Client(cluster, set_as_default=False)
        mode = "local"
    futures: dict[str, tuple[Any, DesignTask]] = {}
    try:
        if mode != "local":
            _check_workers(client)
        n_workers = len(client.nthreads())
        for t in todo:
            fut = client.submit(evaluate_design, t, key=f"flexkin-study-{t.key}", pure=False, retries=0)
            futures[fut.key] = (fut, t)
        for fut in as_completed([f for f, _ in futures.values()], loop=client.loop):
            _, t = futures.pop(fut.key)
            try:
                row = fut.result()
            except Exception as e:  # the worker died (KilledWorker), lost data, cancelled...
                finish(t, _error_row(t, _one_line(e)), False)  # not stored: a re-run tries again
            else:
                finish(t, row, True)
            fut.release()
    except BaseException:
        for fut, _ in futures.values():
            fut.cancel()
        raise
    finally:
        if own_client:
            client.close()
        if cluster is not None:
            cluster.close()
    return mode, max(n_workers, 1)
