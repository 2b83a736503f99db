"""Test configuration: headless matplotlib and the oracles' measurement report."""

from __future__ import annotations

import os
import sys

import matplotlib

matplotlib.use("Agg")

sys.path.insert(0, os.path.dirname(__file__))  # make tests/oracles.py importable


def pytest_terminal_summary(terminalreporter, exitstatus, config):  # noqa: ARG001
    """Print the figures measured by the rod tests (max errors, completeness counts)."""
    try:
        from oracles import REPORT
    except ImportError:  # pragma: no cover
        return
    if not REPORT:
        return
    terminalreporter.section("flexkin rod measurements")
    for key in sorted(REPORT):
        terminalreporter.write_line(f"{key}: {REPORT[key]}")


import pathlib as _pathlib

import pytest as _pytest


@_pytest.fixture(scope="session")
def examples_dir() -> _pathlib.Path:
    """The bundled ``examples/`` directory."""
    return _pathlib.Path(__file__).resolve().parents[1] / "examples"
