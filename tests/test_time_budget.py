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


def test_ik_budget_is_looked_at_between_the_legs_curves(examples_dir):
    """A clamped mechanism's curves take most of its IK (about half a second per leg): the
    budget is looked at before each leg, so a budget of a fraction of that ends after at most
    one leg's curves (it overshot by all three before), incomplete."""
    from flexkin.solve.curves import leg_curves
    from flexkin.system import System

    mech = flexkin.load_mechanism(examples_dir / "unit_3pff.toml")
    pose = (0.0, 0.01, np.radians(21))
    flexkin.ik(mech, (0.0, 0.0, np.radians(20)), time_budget=0.05)  # loads the atlases (start-up)
    B = System.from_mechanism(mech).platform_points(np.array([pose]))[0]
    t = time.perf_counter()
    curves = leg_curves(mech, B, 2, theta=pose[2])
    all_legs = time.perf_counter() - t
    assert all(len(c) for c in curves)
    budget = 0.2 * all_legs
    r = flexkin.ik(mech, pose, time_budget=budget)
    assert r.complete is False and "time budget" in r.message
    assert r.elapsed < budget + 0.67 * all_legs  # at most one leg's curves past the budget (of three)


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
    mech = flexkin.load_mechanism(path)
    u_rad = flexkin.ik(mech, (0.05, 0.02, np.radians(20))).solutions[0].inputs
    u = np.degrees(u_rad)
    flexkin.fk(mech, u_rad, time_budget=0.2)  # compiles what FK needs (a fresh cache): not timed below
    t = time.perf_counter()
    code = main(["fk", str(path), "--inputs", *map(str, u), "--time-budget", "0.2", "--json"])
    out = capsys.readouterr().out
    assert code == 0 and time.perf_counter() - t < 10.0
    d = json.loads(out)
    assert d["complete"] is False and "time budget" in d["message"]
    # a bad budget is a usage error naming the option
    assert main(["fk", str(path), "--inputs", *map(str, u), "--time-budget", "0"]) == 2
    assert "--time-budget" in capsys.readouterr().err


# ---- issue 27, item 3: the budget covers the whole work ---------------------------------------
# Every budget test warms up first (start-up -- loading the compiled kernels and the cached
# atlases -- is not part of a budget) and then measures the wall time of the call.  The slack is
# generous for a shared, loaded 2-core machine (the work is sliced by measured wall-clock rates,
# so load lengthens slices, not their number); before the fix the same calls took 3-10x their
# budget (path 1 s -> 9.8 s, fk 1 s -> 8.5 s on this machine).
def _within(budget: float, elapsed: float) -> bool:
    return elapsed <= 1.5 * budget + 0.5


def _timed(f, *args, **kwargs):
    t = time.perf_counter()
    out = f(*args, **kwargs)
    return out, time.perf_counter() - t


def test_deadline_clock_and_slices():
    from flexkin.core.budget import Deadline, Rate, timed_slices

    free = Deadline()
    assert not free.limited and not free.expired(1e9) and not free.hit and free.remaining() == float("inf")
    assert list(timed_slices(10, free, Rate(1.0))) == [(0, 10)]
    d = Deadline(0.05)
    assert Deadline.of(d) is d and d.limited and not d.expired()
    assert d.expired(reserve=1.0) and d.hit  # the reserve does not fit: the run is cut short
    with pytest.raises(ValueError, match="time_budget"):
        Deadline(0)
    # slices: the first few units calibrate the rate, later slices fit the share of the budget
    d, rate, got = Deadline(2.0), Rate(1e-3), []
    for lo, hi in timed_slices(10_000, d, rate):
        got.append((lo, hi))
        rate.add(hi - lo, (hi - lo) * 1e-5)  # pretend 10 us per unit
    assert got[0] == (0, 4) and got[-1][1] == 10_000
    assert all(b - a <= int(d.slice_seconds() / 1e-5) + 1 for a, b in got[1:])
    # a deadline that passes stops the slices and is hit
    d = Deadline(0.02)
    n = 0
    for lo, hi in timed_slices(10**9, d, Rate(1e-3)):
        n += hi - lo
        time.sleep(0.005)
    assert d.hit and n < 10**9


def test_path_budget_covers_the_analysis_of_the_samples(rfr):
    follow_path(rfr, (0, 0, np.radians(20)), (0.2, 0, np.radians(20)), steps=10)  # warm
    for budget in (1.0, 2.0):
        p, dt = _timed(follow_path, rfr, (0, 0, np.radians(20)), (0.2, 0, np.radians(20)), steps=100_000,
                       time_budget=budget)
        assert _within(budget, dt), (budget, dt, len(p.t))
        assert p.complete is False and "time budget" in p.message
        assert len(p.t) == len(p.margin) == len(p.sing_ik) and np.all(np.isfinite(p.margin))


def test_path_budget_with_feasibility_and_never_complete_when_cut(rfr):
    p, dt = _timed(follow_path, rfr, (0, 0, np.radians(20)), (0.2, 0, np.radians(20)), steps=20_000,
                   time_budget=1.0, feasibility=True)
    assert _within(1.0, dt) and not p.complete and len(p.feasibility) == len(p.t) > 1
    # the verdicts are those check_feasibility gives for the samples
    from flexkin.analysis.feasibility import check_feasibility

    s = p.sample_solutions()[-1]
    assert check_feasibility(rfr, s).to_dict() == p.feasibility[-1].to_dict()
    d = p.to_dict(feasibility=True)
    assert d["complete"] is False and d["points"][-1]["feasibility"] == p.feasibility[-1].to_dict()
    # a path that fits its budget is complete
    q = follow_path(rfr, (0, 0, np.radians(20)), (0.05, 0, np.radians(20)), steps=5, time_budget=60)
    assert q.complete and len(q.t) == 6


def test_fk_budget_covers_refinement_and_analysis(rfr):
    u = flexkin.ik(rfr, (0.05, 0.02, np.radians(20))).solutions[0].inputs
    flexkin.fk(rfr, u, max_mode=3, time_budget=0.2)  # warm (the max_mode-3 atlas)
    for budget in (0.5, 2.0):
        r, dt = _timed(flexkin.fk, rfr, u, max_mode=3, time_budget=budget)
        assert _within(budget, dt), (budget, dt)
        assert r.complete is False and "time budget" in r.message and r.diagnostics.converged > 0
        assert all(s.residual <= 1e-10 and s.verified for s in r.solutions)


def test_ik_budget_covers_refinement_and_analysis(examples_dir):
    mech = flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")
    pose = (0.0, 0.0, np.radians(90))
    full, t_full = _timed(flexkin.ik, mech, pose)
    assert full.complete
    budget = max(0.3 * t_full, 0.05)
    r, dt = _timed(flexkin.ik, mech, pose, time_budget=budget)
    assert _within(budget, dt), (budget, dt, t_full)
    if not r.complete:  # cut short: a subset of the full list, each one refined and verified
        assert "time budget" in r.message and len(r) <= len(full)
        keys = {tuple(np.round(s.inputs, 6)) for s in full.solutions}
        assert all(tuple(np.round(s.inputs, 6)) in keys and s.verified for s in r.solutions)


def test_workspace_budget(rfr):
    workspace(rfr, np.radians(20), step=0.1, bounds=(-0.6, 0.6, -0.6, 0.6), all_aspects=False)  # warm
    w, dt = _timed(workspace, rfr, np.radians(20), step=0.004, bounds=(-0.6, 0.6, -0.6, 0.6), time_budget=1.0)
    assert _within(1.0, dt), dt
    assert w.complete is False and "time budget" in w.message and w.maps and w.maps[0].area_cells > 0
    full = workspace(rfr, np.radians(20), step=0.1, bounds=(-0.6, 0.6, -0.6, 0.6), all_aspects=False,
                     time_budget=60)
    assert full.complete and "time budget" not in full.message


@pytest.mark.parametrize("cmd", ["ik", "path", "workspace"])
def test_cli_time_budget_on_ik_path_workspace(examples_dir, capsys, cmd):
    """``--time-budget`` on ik, path and workspace: the command's computation keeps it (start-up
    excluded: the mechanism is solved once before) and the JSON says it is incomplete."""
    import json

    from flexkin.cli import main

    path = str(examples_dir / "unit_3rfr.toml")
    box = ["--bounds", "-0.6", "0.6", "-0.6", "0.6"]
    warm, args = {"ik": (["ik", path, "--pose", "0.05", "0.02", "20", "--max-mode", "4"],) * 2,
                  "path": (["path", path, "--from", "0", "0", "20", "--to", "0.2", "0", "20", "--steps", "5"],
                           ["path", path, "--from", "0", "0", "20", "--to", "0.2", "0", "20", "--steps", "100000"]),
                  "workspace": (["workspace", path, "--theta", "20", "--step", "0.1", *box, "--first-aspect"],
                                ["workspace", path, "--theta", "20", "--step", "0.004", *box])}[cmd]
    assert main(warm + ["--quiet"]) == 0  # start-up is not part of the budget
    capsys.readouterr()
    budget = 1.0 if cmd != "ik" else 0.02
    t = time.perf_counter()
    code = main(args + ["--time-budget", str(budget), "--json", "--quiet"])
    dt = time.perf_counter() - t
    out, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(out)
    complete = d["workspaces"][0]["complete"] if cmd == "workspace" else d["complete"]
    assert complete is False and "time budget" in err
    assert dt <= 1.5 * budget + 1.0, dt  # the CLI adds its output (JSON, table) to the budget
