"""``flexkin study STUDY.toml --out DIR [--workers N | --scheduler ADDRESS]``.

Wiring into flexkin's command line (``flexkin/cli.py``)::

    from .study.cli import add_study_parser, run_study_command
    add_study_parser(sub)                      # sub = parser.add_subparsers(...)
    handler = {..., "study": run_study_command}[a.command]

:func:`run_study_command` prints the summary on stdout and returns the exit status, with one
line on stderr for each problem:

* 0: every row was computed (rows cut short by a time budget are reported, not failures);
* 1: the study ran to its end but some rows failed (their ``error`` column says why; the
  table is written);
* 2: bad input (a bad study file, workspace settings no design can use, a bad argument, an
  unwritable output directory, an unreachable or bad scheduler address) -- nothing computed;
* 3: the Dask cluster failed (the scheduler was lost, or no worker was left for
  ``--worker-timeout`` seconds): the finished rows are kept and named, a re-run computes the
  rest;
* 130: interrupted (Ctrl-C): the finished rows are kept and named.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, Sequence

from ..core import cli_args

__all__ = ["add_study_parser", "run_study_command", "main"]

EXIT_USAGE = 2
EXIT_FAILED_ROWS = 1
EXIT_CLUSTER = 3
EXIT_INTERRUPTED = 130


def add_study_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``study`` sub-command to ``subparsers`` (from ``parser.add_subparsers()``)."""
    p = subparsers.add_parser(
        "study", help="design study: sweep mechanism parameters and map workspaces, on Dask",
        description="Run a design study (docs/study.md): for every design of the study file's grid and every "
                    "orientation, map the workspace and compute the metrics; write DIR/results.parquet, "
                    "DIR/results.csv and figures. Rows finished by an earlier run into DIR are reused.")
    p.add_argument("study", metavar="STUDY.toml", help="study file (TOML)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (created; re-use it to resume)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", type=cli_args.integer_in(1, 4096), metavar="N",
                   help="worker processes of the local Dask cluster (default: the number of cores)")
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="address of a running Dask scheduler (tcp://HOST:PORT), or 'synchronous' to compute in "
                        "this process without Dask")
    p.add_argument("--timeout", type=cli_args.positive, default=10.0, metavar="S",
                   help="seconds to wait for the scheduler (default 10)")
    p.add_argument("--worker-timeout", type=cli_args.positive, default=60.0, metavar="S",
                   help="seconds to wait while no Dask worker is connected before giving up (default 60)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    p.add_argument("--no-figures", action="store_true", help="write the table only")
    p.add_argument("--retry-failed", action="store_true", help="compute again the stored rows that have an error")
    return p


def run_study_command(args: argparse.Namespace) -> int:
    """Run ``flexkin study`` for parsed ``args``; return the exit status."""
    from .run import StudyAborted, StudyInterrupted, run_study
    from .spec import StudyError

    try:
        res = run_study(args.study, args.out, workers=args.workers, scheduler=args.scheduler,
                        progress=not args.quiet, figures=not args.no_figures, retry_failed=args.retry_failed,
                        timeout=args.timeout, worker_timeout=getattr(args, "worker_timeout", 60.0))
    except StudyError as e:
        print(f"flexkin study: {e}", file=sys.stderr)
        return EXIT_USAGE
    except StudyAborted as e:
        print(f"flexkin study: {e.describe()}", file=sys.stderr)
        return EXIT_CLUSTER
    except StudyInterrupted as e:
        print(f"flexkin study: {e.describe()}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except KeyboardInterrupt:  # before any row was submitted, or a second Ctrl-C while stopping
        print(f"flexkin study: interrupted; the finished rows are kept in {args.out}/rows: run the same command "
              "again to compute the rest", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(res.summary())
    print(f"table: {res.parquet} and {res.csv}; {len(res.figures)} figure(s) in {res.out}")
    for m in res.messages:
        print(f"flexkin study: {m}", file=sys.stderr)
    if res.n_incomplete:
        print(f"flexkin study: {res.n_incomplete} row(s) were cut short by the time budget ('complete' is false)",
              file=sys.stderr)
    if res.n_failed:
        first = next(r for r in res.rows if r.get("error"))
        print(f"flexkin study: {res.n_failed} of {len(res.rows)} row(s) failed (first: design {first['design']} at "
              f"{first['theta_deg']:g} deg: {_cut(first['error'])}); see the 'error' column of {res.csv}",
              file=sys.stderr)
        return EXIT_FAILED_ROWS
    return 0


def _cut(text: str, n: int = 160) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= n else text[:n - 3] + "..."


def main(argv: Sequence[str] | None = None) -> int:
    """``flexkin study ...`` on its own (until the command is wired into ``flexkin``):
    ``python -c "import sys; from flexkin.study.cli import main; sys.exit(main())" study ...``."""
    import matplotlib

    matplotlib.use("Agg")
    parser = _OneLineParser(prog="flexkin")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_OneLineParser)
    add_study_parser(sub)
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse: one message line on stderr (or --help)
        return int(e.code) if isinstance(e.code, int) else EXIT_USAGE
    return run_study_command(args)


class _OneLineParser(argparse.ArgumentParser):
    """Argument errors as one line on stderr and exit status 2 (no usage block), as ``flexkin``."""

    def error(self, message: str) -> None:
        self.exit(EXIT_USAGE, f"{self.prog}: {' '.join(message.split())} (see '{self.prog} --help')\n")
