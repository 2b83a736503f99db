"""Study throughput on 1 and 2 workers and the per-row overhead of the scheduling (docs/study.md).

    python benchmarks/study_scaling.py [--repeat 3] [--json out.json]

Two workloads, each run synchronously (this process, no Dask) and on a local Dask cluster of 1
and 2 worker processes, interleaved, into fresh output directories, without figures:

* ``example``: examples/study_3rfr.toml (18 rows of 0.3-1.5 s);
* ``cheap``: 120 rows of the unit 3-RFR on a 0.5 m grid (a few ms of computing each), where
  almost all the time is the per-row overhead;
* ``one``: the first of those rows alone: the fixed cost of a run (cluster start-up, the
  workers' imports and kernel loading).

Per run: the wall time of ``run_study`` (cluster start-up and shutdown included) and its rows
per second; the start-up (from the call to the first completed row, minus that row's own
time: cluster start, workers importing flexkin and loading the compiled kernels); the steady
rate (rows per second between the first and the last completed row, from ``on_row`` time
stamps); the rows' own ``elapsed_s`` (sum and median); and the overhead per row: the steady
interval between rows times the number of workers, minus the median ``elapsed_s``.  The
1-minute load average before and after each run is printed: on a shared machine it decides
what 2 workers can gain.  The CPU time of every process of a run (this one, which holds the
local cluster's scheduler, and the worker processes, counted once they have exited) does not
depend on the load: ``(cpu(cheap) - cpu(one)) - (cpu_sync(cheap) - cpu_sync(one))``, over the
119 extra rows, is the CPU that Dask spends per row.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHEAP = f'''
name = "cheap rows"
mechanism = "{(ROOT / 'examples' / 'unit_3rfr.toml').as_posix()}"
orientations = [20]
[grid]
"rod.length" = {{start = 0.9, stop = 1.1, num = 120}}
[workspace]
step = 0.5
all_aspects = false
seed_search = false
'''


def run(study: Path, mode: str) -> dict:
    from flexkin.study import run_study

    out = Path(tempfile.mkdtemp(prefix="flexkin_bench_study_"))
    stamps: list[float] = []
    kw = {"scheduler": "synchronous"} if mode == "sync" else {"workers": int(mode)}
    load0 = os.getloadavg()[0]
    o0 = os.times()
    t0, c0 = time.perf_counter(), time.process_time()
    first: list[float] = []

    def on_row(row: dict) -> None:
        stamps.append(time.perf_counter())
        if not first:
            first.append(float(row.get("elapsed_s") or 0.0))

    res = run_study(study, out, progress=False, figures=False, on_row=on_row, **kw)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    o1 = os.times()
    children = (o1.children_user - o0.children_user) + (o1.children_system - o0.children_system)
    load1 = os.getloadavg()[0]
    shutil.rmtree(out, ignore_errors=True)
    n = len(stamps)
    steady = (n - 1) / (stamps[-1] - stamps[0]) if n > 1 and stamps[-1] > stamps[0] else float("nan")
    rows = [r for r in res.rows if r.get("elapsed_s") is not None]
    med_row = statistics.median(r["elapsed_s"] for r in rows)
    workers = 1 if mode == "sync" else int(mode)
    return {"mode": mode, "rows": n, "failed": res.n_failed, "wall_s": wall, "process_cpu_s": cpu,
            "workers_cpu_s": children, "total_cpu_s": cpu + children,
            "rows_per_s": n / wall, "startup_s": stamps[0] - t0 - first[0] if n else None,
            "steady_rows_per_s": steady, "sum_row_s": sum(r["elapsed_s"] for r in rows), "median_row_s": med_row,
            "overhead_per_row_s": workers / steady - med_row if steady == steady else None,
            "load_before": load0, "load_after": load1}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", metavar="FILE")
    ap.add_argument("--only", choices=("example", "cheap", "one"))
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="flexkin_bench_studies_"))
    (tmp / "cheap.toml").write_text(CHEAP)
    (tmp / "one.toml").write_text(CHEAP.replace("{start = 0.9, stop = 1.1, num = 120}", "[0.9]"))
    studies = {"example": ROOT / "examples" / "study_3rfr.toml", "cheap": tmp / "cheap.toml", "one": tmp / "one.toml"}
    if a.only:
        studies = {a.only: studies[a.only]}
    from flexkin.study import run_study

    for s in studies.values():  # warm-up: kernels loaded, Dask imported
        d = Path(tempfile.mkdtemp())
        run_study(s, d, scheduler="synchronous", progress=False, figures=False)
        shutil.rmtree(d, ignore_errors=True)
    results = []
    for k in range(a.repeat):
        for name, s in studies.items():
            for mode in ("sync", "1", "2"):
                r = run(s, mode)
                r["workload"], r["repeat"] = name, k
                results.append(r)
                print(f"{name:8s} {mode:>4s}: {r['rows']} rows, wall {r['wall_s']:.2f} s ({r['rows_per_s']:.2f} rows/s), "
                      f"start-up {r['startup_s']:.2f} s, steady {r['steady_rows_per_s']:.2f} rows/s, rows' own time "
                      f"{r['sum_row_s']:.2f} s (median {1e3 * r['median_row_s']:.1f} ms), overhead/row "
                      f"{1e3 * (r['overhead_per_row_s'] or float('nan')):.1f} ms, CPU {r['total_cpu_s']:.2f} s (workers "
                      f"{r['workers_cpu_s']:.2f} s), load {r['load_before']:.1f}->{r['load_after']:.1f}", flush=True)
    if len(studies) == 3:
        for k in range(a.repeat):
            cpu = {(r["workload"], r["mode"]): r["total_cpu_s"] for r in results if r["repeat"] == k}
            sync = (cpu[("cheap", "sync")] - cpu[("one", "sync")])
            for mode in ("1", "2"):
                extra = (cpu[("cheap", mode)] - cpu[("one", mode)]) - sync
                print(f"repeat {k}: {mode} worker(s): Dask CPU per row {1e3 * extra / 119:.1f} ms; fixed CPU of a run "
                      f"{cpu[('one', mode)] - cpu[('one', 'sync')]:.2f} s")
    if a.json:
        Path(a.json).write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
