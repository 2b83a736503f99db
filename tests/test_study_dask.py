"""Design studies on real Dask clusters: a LocalCluster of 2 worker processes, a ``dask
scheduler`` + ``dask worker`` started here as subprocesses, and workers killed mid-study.
Every table must equal the single-process one (timings aside)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from flexkin.study import read_table, run_study
from flexkin.study.table import RowStore
from test_study_support import EXAMPLES, TINY, dask_processes, kill, reference_rows, strip, write_study

#: ``flexkin study`` in a subprocess (until the lead wires the command into ``flexkin``)
CLI = "import sys; from flexkin.study.cli import main; sys.exit(main(sys.argv[1:]))"
#: six rows (three designs) for the kill tests: enough that a kill lands mid-study
SIX = TINY.replace('"rod.length" = [1.0, 1.1]', '"rod.length" = [1.0, 1.05, 1.1]')


def test_local_cluster_two_workers_matches_synchronous(tmp_path):
    ref = reference_rows()
    res = run_study(write_study(tmp_path, TINY), tmp_path / "out", workers=2, progress=False, figures=False)
    assert res.scheduler == "local" and res.workers == 2
    assert (res.n_computed, res.n_failed) == (4, 0)
    assert strip(res.rows) == ref
    assert strip(read_table(tmp_path / "out")) == ref


def test_dask_scheduler_subprocesses_match_synchronous(tmp_path):
    """`flexkin study --scheduler tcp://...` (a subprocess, bounded in time) on a `dask scheduler`
    with two `dask worker` processes, all started here on free localhost ports."""
    ref = reference_rows()
    study = write_study(tmp_path, TINY)
    with dask_processes(tmp_path, n_workers=2) as (addr, _, _):
        done = subprocess.run([sys.executable, "-c", CLI, "study", str(study), "--out", str(tmp_path / "out"),
                               "--scheduler", addr, "--quiet", "--no-figures"],
                              capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    assert "4 computed" in done.stdout and "2 worker(s)" in done.stdout and addr in done.stdout
    assert strip(read_table(tmp_path / "out")) == ref


def test_worker_killed_mid_study_loses_nothing(tmp_path):
    """A worker process of the local cluster is killed after the first row: the rows it held are
    computed again elsewhere, the study completes, the table is the same."""
    import logging

    from distributed import Client, LocalCluster

    ref = reference_rows()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, Client(cluster, set_as_default=False) as client:
        pids = sorted(client.run(os.getpid).values())
        assert len(pids) == 2 and os.getpid() not in pids
        killed = []

        def on_row(row):
            if not killed:
                os.kill(pids[0], signal.SIGKILL)  # a worker process this test started (via LocalCluster)
                killed.append(row)

        res = run_study(write_study(tmp_path, TINY), tmp_path / "out", client=client, progress=False,
                        figures=False, on_row=on_row)
    assert killed
    assert (res.n_computed, res.n_failed) == (4, 0), [r["error"] for r in res.rows]
    assert strip(res.rows) == ref


def test_killed_study_and_worker_keep_finished_rows_and_rerun_completes(tmp_path):
    """The study (a `flexkin study` process on a `dask scheduler`) and its only worker are both killed
    as soon as a row is on disk: the finished rows stay, whole; a re-run computes only the rest."""
    study = write_study(tmp_path, SIX)
    out = tmp_path / "out"
    rows_dir = out / "rows"
    with dask_processes(tmp_path, nanny=False) as (addr, workers, _):
        cmd = [sys.executable, "-c", CLI, "study", str(study), "--out", str(out), "--scheduler", addr, "--quiet", "--no-figures"]
        log = open(tmp_path / "study.log", "wb")
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            t_end = time.monotonic() + 120
            while time.monotonic() < t_end and proc.poll() is None:
                if rows_dir.is_dir() and any(rows_dir.glob("*.json")):
                    break
                time.sleep(0.05)
            kill(workers[0])
            kill(proc)
        finally:
            kill(proc)
            log.close()
    finished = sorted(rows_dir.glob("*.json"))
    assert 1 <= len(finished) < 6, f"the kill should land mid-study; the study said: {(tmp_path / 'study.log').read_text()}"
    store = RowStore(out)
    for p in finished:  # every stored row is whole (atomic writes)
        row = store.get(p.stem)
        assert row is not None and row["error"] == "" and row["workspace_area"] > 0
    assert not (out / "results.parquet").exists()
    res = run_study(study, out, scheduler="synchronous", progress=False, figures=False)
    assert (res.n_reused, res.n_computed, res.n_failed) == (len(finished), 6 - len(finished), 0)
    ref_design = {1.0: 0, 1.1: 1}  # the reference study has no 1.05 design
    got = [r for r in strip(res.rows) if r["rod.length"] in ref_design]
    assert [dict(r, design=ref_design[r["rod.length"]]) for r in got] == reference_rows()


@pytest.mark.slow
def test_example_study_runs_in_under_two_minutes(tmp_path):
    """examples/study_3rfr.toml on a 2-worker local cluster, end to end, figures included."""
    t0 = time.perf_counter()
    res = run_study(EXAMPLES / "study_3rfr.toml", tmp_path / "out", workers=2, progress=False)
    wall = time.perf_counter() - t0
    assert wall < 120, wall
    assert (res.n_computed, res.n_failed, res.n_incomplete) == (18, 0, 0)
    assert len(res.figures) >= 15
    by = {(r["rod.length"], r["platform.scale"], r["theta_deg"]): r["workspace_area"] for r in res.rows}
    for s_ in (0.75, 1.0, 1.25):
        for th in (10.0, 20.0):
            areas = [by[(L, s_, th)] for L in (0.9, 1.0, 1.1)]
            assert areas == sorted(areas) and areas[0] > 0, areas  # longer rods reach further


@pytest.mark.slow
def test_minimal_study_form_runs_as_written(tmp_path):
    """The issue's minimal study (24 rows, default metrics and workspace settings but a 0.1 m
    step to keep it under a few minutes), on the default local cluster."""
    import shutil

    shutil.copy(EXAMPLES / "unit_3rfr.toml", tmp_path / "unit_3rfr.toml")
    body = ('mechanism = "unit_3rfr.toml"\norientations = [0, 20]\n[grid]\n"rod.length" = [0.9, 1.0, 1.1]\n'
            '"rod.EI" = {start = 0.5, stop = 2.0, num = 4}\n[workspace]\nstep = 0.1\n')
    res = run_study(write_study(tmp_path, body), tmp_path / "out", progress=False, figures=False)
    assert (res.n_computed, res.n_failed) == (24, 0)
    # unloaded kinematics do not depend on EI: every EI gives the same areas
    for L in (0.9, 1.0, 1.1):
        for th in (0.0, 20.0):
            areas = {r["workspace_area"] for r in res.rows if r["rod.length"] == L and r["theta_deg"] == th}
            assert len(areas) == 1, areas
