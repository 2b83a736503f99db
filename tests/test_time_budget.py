"""Every solver takes a time budget and returns what it has, flagged incomplete, instead of hanging."""

from __future__ import annotations

import time

import numpy as np
import pytest

import flexkin
from flexkin import follow_path
from flexkin.solve.workspace import workspace


@pytest.fixture(scope="module")
def rfr(examples_dir):
    return flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")


def test_fk_time_budget(rfr):
    u = flexkin.ik(rfr, (0.05, 0.02, np.radians(20))).solutions[0].inputs
    t = time.perf_counter()
    r = flexkin.fk(rfr, u, time_budget=0.2)
    assert time.perf_counter() - t < 5.0
    assert r.complete is False and "time budget" in r.message
    assert all(s.residual <= 1e-10 for s in r.solutions)  # what it returns is still refined


def test_ik_time_budget(rfr):
    r = flexkin.ik(rfr, (0.05, 0.02, np.radians(20)), time_budget=1e-6)
    assert r.complete is False and r.message
    full = flexkin.ik(rfr, (0.05, 0.02, np.radians(20)), time_budget=60)
    assert full.complete and len(full) == 8


def test_path_and_workspace_time_budget(rfr):
    p = follow_path(rfr, (0, 0, np.radians(20)), (0.2, 0, np.radians(20)), steps=100_000, time_budget=0.5)
    assert not p.complete and "time budget" in p.message and 1 <= len(p.t) < 100_001
    w = workspace(rfr, np.radians(20), step=0.01, bounds=(-0.6, 0.6, -0.6, 0.6), all_aspects=False, time_budget=0.05)
    assert "time budget" in w.message


@pytest.mark.parametrize("bad", [0, -1, float("nan"), "soon"])
def test_bad_budget(rfr, bad):
    with pytest.raises(ValueError, match="time_budget"):
        flexkin.ik(rfr, (0, 0, 0), time_budget=bad)


def test_cli_fk_time_budget(examples_dir, capsys):
    """``flexkin fk --time-budget`` reaches flexkin.fk: a budget far below the search's needs ends
    early with ``complete = false`` in the JSON; a budget of 0 is a usage error naming the option."""
    import json

    from flexkin.cli import main

    path = examples_dir / "unit_3rfr.toml"
    u = np.degrees(flexkin.ik(flexkin.load_mechanism(path), (0.05, 0.02, np.radians(20))).solutions[0].inputs)
    t = time.perf_counter()
    code = main(["fk", str(path), "--inputs", *map(str, u), "--time-budget", "0.2", "--json"])
    out = capsys.readouterr().out
    assert code == 0 and time.perf_counter() - t < 10.0
    d = json.loads(out)
    assert d["complete"] is False and "time budget" in d["message"]
    # a bad budget is a usage error naming the option
    assert main(["fk", str(path), "--inputs", *map(str, u), "--time-budget", "0"]) == 2
    assert "--time-budget" in capsys.readouterr().err
