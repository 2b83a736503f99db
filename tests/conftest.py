"""Test configuration: headless matplotlib and the oracles' measurement report."""

from __future__ import annotations

import json
import os
import sys

import matplotlib
import pytest

matplotlib.use("Agg")

sys.path.insert(0, os.path.dirname(__file__))  # make tests/oracles.py importable


#: figures measured in the test processes of pytest-xdist, gathered by the controlling process
_FROM_WORKERS: dict[str, str] = {}


def pytest_sessionfinish(session, exitstatus):  # noqa: ARG001
    """In a pytest-xdist test process: hand the measured figures to the controlling process."""
    out = getattr(session.config, "workeroutput", None)
    if out is not None:
        from oracles import REPORT

        out["flexkin_report"] = json.dumps(REPORT)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):  # noqa: ARG001
    """pytest-xdist: a test process ended; keep its figures."""
    _FROM_WORKERS.update(json.loads(getattr(node, "workeroutput", {}).get("flexkin_report", "{}")))


def pytest_terminal_summary(terminalreporter, exitstatus, config):  # noqa: ARG001
    """Print the figures measured by the rod tests (max errors, completeness counts)."""
    try:
        from oracles import REPORT
    except ImportError:  # pragma: no cover
        return
    report = {**REPORT, **_FROM_WORKERS}
    if not report:
        return
    terminalreporter.section("flexkin rod measurements")
    for key in sorted(report):
        terminalreporter.write_line(f"{key}: {report[key]}")


import pathlib as _pathlib


@pytest.fixture(scope="session")
def examples_dir() -> _pathlib.Path:
    """The bundled ``examples/`` directory."""
    return _pathlib.Path(__file__).resolve().parents[1] / "examples"
