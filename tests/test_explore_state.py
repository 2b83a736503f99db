"""The explorer's logic without a browser (flexkin.explore.state / scene / export / jobs / cli).

Paths and poses are fixed here; which solution crosses what on them is asked of the library
(``flexkin.ik``, ``flexkin.follow_path``), never hard-coded.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.explore import export
from flexkin.explore.jobs import Worker, WorkspaceJob, overlay
from flexkin.explore.scene import LEG_COLORS, ShapeCache, scene
from flexkin.explore.state import (ExplorerState, SolveOutcome, input_bounds, match_solution, pose_bounds,
                                   solution_distance)
from flexkin.plot.style import mode_color

ROOT = Path(__file__).resolve().parents[1]
PROTO = ROOT / "examples" / "prototype_3pfr.toml"
TH = math.radians(90.0)
P0 = (0.0, 0.3, TH)            # start pose
P_MODE = (0.15, 0.3, TH)       # a drag from P0 to here crosses a d-mode change on some branch
P_END = (0.0, 0.42, TH)        # a drag from P0 to here ends some branch (IK singularity)
P_NONE = (0.0, 1.1, TH)        # no equilibrium (rods too short)


@pytest.fixture(scope="module")
def mech():
    return flexkin.load_mechanism(PROTO)


@pytest.fixture(scope="module")
def ik0(mech):
    return flexkin.ik(mech, P0)


def fresh(mech, ik0) -> ExplorerState:
    """A state at P0 with the (cached) full IK applied."""
    st = ExplorerState(mech, P0)
    assert st.apply(SolveOutcome(st.request(), ik0))
    return st


def drag(st: ExplorerState, a, b, n: int):
    """Move in n equal steps from a to b (as a drag does); returns the outcomes."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return [st.move(a + (b - a) * k / n) for k in range(1, n + 1)]


def kinds(st: ExplorerState) -> list[str]:
    return [e.kind for e in st.log]


@pytest.fixture(scope="module")
def mode_change_id(mech, ik0):
    """Id (at P0) of a stable solution whose branch crosses a d-mode change on P0 -> P_MODE."""
    for s in ik0.solutions:
        if s.stable:
            p = flexkin.follow_path(mech, P0, P_MODE, steps=30, solution=s)
            if p.complete and any(e.kind == "mode_change" for e in p.events):
                return s.id
    pytest.fail("no branch with a d-mode change on the test path (the library changed?)")


# ---------------------------------------------------------------------------------------------
def test_refresh_lists_what_ik_returns(mech, ik0):
    st = ExplorerState(mech, P0)
    assert st.stale and st.status().startswith("Solving IK")
    out = st.refresh()
    assert out.result is not None and not st.stale
    assert [s.id for s in st.solutions] == [s.id for s in ik0.solutions]
    assert [s.modes for s in st.solutions] == [s.modes for s in ik0.solutions]
    np.testing.assert_allclose([s.inputs for s in st.solutions], [s.inputs for s in ik0.solutions], atol=1e-9)
    n = len(ik0.solutions)
    ns = sum(s.stable is True for s in ik0.solutions)
    assert st.status() == f"{n} equilibria at this pose, {ns} stable"
    rows = st.rows()
    assert rows["id"] == [s.id for s in ik0.solutions]
    assert rows["u1"][0] == pytest.approx(ik0.solutions[0].inputs_display()[0])
    assert set(rows["stable"]) <= {"stable", "unstable", "undecided"}
    assert all(f == "..." for f in rows["feasible"])  # filled in later, in the background
    sc = scene(st, ShapeCache())
    drawn = len(sc["rods_solid"]["xs"]) + len(sc["rods_dashed"]["xs"]) + len(sc["rods_selected"]["xs"])
    assert drawn == 3 * n
    assert len(sc["rods_solid"]["xs"]) == 3 * ns
    # every listed solution's rods are drawn where the library puts them
    s = ik0.solutions[-1]
    i = sc["rods_dashed"]["sid"].index(s.id) if s.stable is not True else sc["rods_solid"]["sid"].index(s.id)
    lay = sc["rods_dashed"] if s.stable is not True else sc["rods_solid"]
    np.testing.assert_allclose(np.c_[lay["xs"][i], lay["ys"][i]], s.rods[0].shape(40), atol=1e-12)
    assert lay["color"][i] == mode_color(s.mode_label)


def test_feasibility_filled_in_and_filter(mech, ik0):
    st = fresh(mech, ik0)
    from flexkin.explore.state import feasibility_of

    feas = feasibility_of(mech, st.solutions)
    assert st.apply_feasibility(st.serial, feas)
    rows = st.rows()
    ref = ik0.feasibility()
    assert rows["feasible"] == ["yes" if f.feasible else "no: " + "; ".join(f.reasons) for f in ref]
    st.set_show("feasible")
    assert {s.id for s, _ in st.visible()} == {s.id for s, f in zip(ik0.solutions, ref) if f.feasible}
    st.set_show("stable")
    assert {s.id for s, _ in st.visible()} == {s.id for s in ik0.solutions if s.stable is True}
    assert not st.apply_feasibility(st.serial - 1, feas)  # feasibility of an older solve is ignored


def test_tracking_follows_the_selected_branch_through_a_mode_change(mech, ik0, mode_change_id):
    st = fresh(mech, ik0)
    st.select(mode_change_id)
    start = st.selected
    outs = drag(st, P0, P_MODE, 30)
    assert all(o.tracked and o.reached and not o.needs_solve for o in outs)
    assert st.result.solutions is ik0.solutions, "tracking must not re-solve"
    assert "mode_change" in kinds(st)
    ev = next(e for e in st.log if e.kind == "mode_change")
    assert ev.solution_id == mode_change_id and f"{start.mode_label} ->" in ev.detail
    assert st.selected.modes != start.modes
    assert st.selected.pose == pytest.approx(P_MODE, abs=1e-12)
    # only the tracked equilibrium is drawn and listed while dragging
    sc = scene(st, ShapeCache())
    assert len(sc["rods_selected"]["xs"]) == 3 and not sc["rods_solid"]["xs"] and not sc["rods_dashed"]["xs"]
    assert sc["rods_selected"]["color"] == list(LEG_COLORS)
    assert st.rows()["id"] == [mode_change_id]
    assert st.status().startswith(f"Tracking #{mode_change_id}")
    # the tracked point is a real equilibrium: the full IK there contains it ...
    ik1 = flexkin.ik(mech, P_MODE)
    m, d = match_solution(st.selected, ik1.solutions, mech)
    assert m is not None and d < 1e-6
    # ... and on release the list is refreshed and the selection moves to that solution
    tracked = st.selected
    out = st.refresh()
    assert [s.id for s in st.solutions] == [s.id for s in ik1.solutions]
    assert st.selected_id == m.id and st.selected.modes == tracked.modes
    assert solution_distance(st.selected, tracked, mech) < 1e-6
    assert not st.notice and out.error == ""


def test_match_solution(mech, ik0):
    sols = list(ik0.solutions)
    rng = np.random.default_rng(1)
    for k in rng.choice(len(sols), size=5, replace=False):
        ref = sols[k]
        shuffled = [sols[i] for i in rng.permutation(len(sols))]
        m, d = match_solution(ref, shuffled, mech)
        assert m is ref and d == 0.0
    # distinct equilibria are far apart; a solution of another pose matches none
    d = [solution_distance(a, b, mech) for i, a in enumerate(sols) for b in sols[i + 1:]]
    assert min(d) > 1e-3
    other = flexkin.ik(mech, (0.01, 0.3, TH)).solutions
    assert match_solution(other[0], sols, mech)[0] is None
    assert match_solution(sols[0], [], mech) == (None, math.inf)


def test_branch_end_is_reported_and_the_remaining_solutions_offered(mech, ik0):
    ending = None
    for s in ik0.solutions:
        if s.stable:
            p = flexkin.follow_path(mech, P0, P_END, steps=40, solution=s)
            if not p.complete:
                ending = s
                break
    assert ending is not None, "no branch ends on the test path (the library changed?)"
    st = fresh(mech, ik0)
    st.select(ending.id)
    outs = drag(st, P0, P_END, 40)
    last = next(i for i, o in enumerate(outs) if not o.reached)
    assert outs[last].needs_solve and "branch_end" in [e.kind for e in outs[last].entries]
    assert st.selected is None and st.selected_id is None
    assert "ended" in st.notice and f"#{ending.id}" in st.notice
    assert st.visible() and st.visible()[0][0].id == ending.id  # the end of the branch stays drawn
    # the app then solves where the user is; the notice offers what remains
    where = tuple(st.pose)
    st.refresh()
    ikw = flexkin.ik(mech, where)
    assert len(st.solutions) == len(ikw.solutions)
    assert f"{len(ikw.solutions)} solution(s) remain" in st.notice
    # later moves without a selection ask for full solves, not tracking
    o = st.move(P0)
    assert not o.tracked and o.needs_solve


def test_no_equilibrium_here_and_the_app_goes_on(mech, ik0):
    st = fresh(mech, ik0)
    st.select(ik0.solutions[0].id)
    st.move(P_NONE)  # the branch cannot get there...
    st.refresh()
    assert st.solutions == ()
    assert st.status().startswith("No equilibrium here")
    assert "no_solution" in kinds(st)
    sc = scene(st, ShapeCache())
    assert not sc["rods_solid"]["xs"] and not sc["rods_selected"]["xs"] and sc["handle"]["px"] == [0.0]
    assert json.loads(export.solutions_json(st))["solutions"] == []
    assert export.rods_csv(st).strip() == ",".join(export.CSV_COLUMNS)
    assert export.figure_bytes(st, "png")[:8] == b"\x89PNG\r\n\x1a\n"
    # ... and the explorer keeps working
    st.move(P0)
    st.refresh()
    assert len(st.solutions) == len(ik0.solutions)


def test_fk_mode_lists_all_poses_and_tracks_inputs(mech, ik0):
    st = fresh(mech, ik0)
    sel = next(s for s in ik0.solutions if s.stable)
    st.select(sel.id)
    st.set_mode("fk")
    assert st.mode == "fk" and st.stale
    np.testing.assert_allclose(st.inputs, sel.inputs)
    out = st.refresh()
    fk = out.result
    assert fk.problem == "fk" and len(st.solutions) == len(fk.solutions) >= 1
    for s in st.solutions:  # all at the given inputs, at different poses
        np.testing.assert_allclose(s.inputs, sel.inputs, atol=1e-9)
    assert st.selected is not None and st.selected.pose == pytest.approx(P0, abs=1e-7)
    assert st.selected_id in [s.id for s in fk.solutions]
    sc = scene(st, ShapeCache())
    assert len(sc["platforms"]["xs"]) == len(fk.solutions) - 1  # each other pose gets its platform
    assert sc["handle"]["px"] == [pytest.approx(P0[0], abs=1e-7)]
    assert st.status().endswith("stable") and "these inputs" in st.status()
    # sliding an input tracks the selected pose
    u = np.array(st.inputs) + np.array([0.004, 0.0, 0.0])
    o = st.move(u)
    assert o.tracked and o.reached
    np.testing.assert_allclose(st.selected.inputs, u, atol=1e-9)
    assert abs(st.selected.pose[0] - P0[0]) > 1e-5  # the platform moved
    # and back to IK at the pose reached
    moved = st.selected.pose
    st.set_mode("ik")
    assert tuple(st.pose) == pytest.approx(moved)


def test_load_change_keeps_the_nearest_equilibrium(mech, ik0):
    st = fresh(mech, ik0)
    sel = next(s for s in ik0.solutions if s.stable)
    st.select(sel.id)
    st.set_load((0.0, -0.05, 0.0))
    assert st.stale
    st.refresh()
    assert st.result.load == (0.0, -0.05, 0.0)
    assert st.selected is not None and "not_found" not in kinds(st)
    assert solution_distance(st.selected, sel, mech) < 0.2
    with pytest.raises(ValueError):
        st.set_load((0.0, math.nan, 0.0))


def test_exports(mech, ik0, tmp_path):
    st = fresh(mech, ik0)
    st.select(ik0.solutions[1].id)
    d = json.loads(export.solutions_json(st))
    assert d == json.loads(json.dumps(ik0.to_dict(feasibility=True)))
    assert [s["id"] for s in d["solutions"]] == [s.id for s in ik0.solutions]
    assert d["pose"] == pytest.approx([0.0, 0.3, 90.0])
    assert "feasible" in d["solutions"][0]
    text = export.rods_csv(st)
    rows = list(csv.reader(io.StringIO(text)))
    assert tuple(rows[0]) == export.CSV_COLUMNS == ("solution", "leg", "s", "x", "y", "theta_deg", "moment")
    n = export.CSV_POINTS
    assert len(rows) - 1 == len(ik0.solutions) * 3 * n
    body = np.array(rows[1:], dtype=float)
    s = ik0.solutions[1]
    blk = body[(body[:, 0] == s.id) & (body[:, 1] == 3)]
    prof = s.rods[2].profile(n)
    np.testing.assert_allclose(blk[:, 2], prof["s"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(blk[:, 3:5], np.c_[prof["x"], prof["y"]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(blk[:, 5], np.degrees(prof["theta"]), rtol=1e-15)
    np.testing.assert_allclose(blk[:, 6], prof["moment"], rtol=1e-15)
    png, ctype = export.export(st, "figure.png")
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and ctype == "image/png"
    svg, _ = export.export(st, "figure.svg")
    assert b"<svg" in svg[:500]
    (tmp_path / "f.png").write_bytes(png)
    with pytest.raises(KeyError):
        export.export(st, "secrets.txt")


def test_pick_and_select(mech, ik0):
    st = fresh(mech, ik0)
    s = ik0.solutions[4]
    mid = s.rods[1].shape(60)[30]
    sid = st.pick(mid[0], mid[1], 1e-4)
    assert sid is not None
    # the picked solution has a rod through that point
    picked = st.solution_by_id(sid)
    assert min(np.hypot(*(r.shape(400) - mid).T).min() for r in picked.rods) < 1e-3
    assert st.pick(5.0, 5.0, 1e-3) is None
    st.select(sid)
    assert st.rows()["selected"].count(True) == 1
    with pytest.raises(ValueError):
        st.select(10_000)


def test_bounds(mech):
    x0, x1, y0, y1 = pose_bounds(mech, P0)
    assert x0 < -0.789 < 0.784 < x1 and y0 < -0.45 < 0.908 < y1
    lo, hi = input_bounds(mech, 0)
    assert lo < 0.0 < 1.5 < hi
    assert input_bounds(mech, 0, 5.0)[1] > 5.0


def test_out_of_date_solve_is_not_applied(mech, ik0):
    st = ExplorerState(mech, P0)
    req = st.request()
    st.move((0.01, 0.3, TH))  # the user moved on meanwhile (no selection)
    assert not st.apply(SolveOutcome(req, ik0))
    assert st.stale and st.solutions == ()
    # ... but what it found is drawn meanwhile, at its own pose
    assert len(st.visible()) == len(ik0.solutions)
    assert "showing the" in st.status()


# ---------------------------------------------------------------------------------------------
def test_worker_runs_the_latest_request_and_cancels_outdated_work():
    w = Worker()
    ran, done = [], []
    gate = threading.Event()

    def slow(tag):
        def fn(cancelled):
            ran.append(tag)
            gate.wait(5)
            return tag
        return fn

    def cancellable(cancelled):
        t0 = time.time()
        while not cancelled():
            if time.time() - t0 > 5:
                return "not cancelled"
            time.sleep(0.005)
        from flexkin.explore.jobs import Cancelled

        raise Cancelled

    try:
        w.submit("solve", slow("a"), done.append)
        time.sleep(0.1)
        w.submit("solve", slow("b"), done.append)
        w.submit("solve", slow("c"), done.append)  # replaces b, which never runs
        gate.set()
        t0 = time.time()
        while len(done) < 2 and time.time() - t0 < 5:
            time.sleep(0.01)
        assert ran == ["a", "c"] and done == ["a", "c"]
        w.submit("feasibility", cancellable, done.append)
        time.sleep(0.1)
        gate.clear()
        w.submit("solve", slow("d"), done.append)  # a new solve outdates the running feasibility
        gate.set()
        t0 = time.time()
        while not w.idle and time.time() - t0 < 5:
            time.sleep(0.01)
        assert done == ["a", "c", "d"]
    finally:
        w.stop()
        w.join(5)


def test_workspace_job_overlay_and_cancel(mech, ik0):
    sel = next(s for s in ik0.solutions if s.stable)
    job = WorkspaceJob(mech, sel, step=0.05, time_budget=60).run()
    assert job.done and not job.error and job.steps > 0
    ws = job.result
    ov = overlay(ws)
    img = ov["image"][0]
    assert img.dtype == np.uint32 and img.shape == (len(ws.y), len(ws.x))
    assert ov["cells"] == int(ws.maps[0].reached.sum()) > 0
    rgba = img.view(np.uint8).reshape(*img.shape, 4)
    assert (rgba[..., 3] > 0).sum() >= ov["cells"]
    assert ov["x"][0] < ws.x[0] and ov["dw"][0] > ws.x[-1] - ws.x[0]
    assert export.figure_bytes(fresh(mech, ik0), "png", workspace=ws)[:4] == b"\x89PNG"
    # cancellation: the progress callback stops the computation
    calls = []
    job2 = WorkspaceJob(mech, sel, step=0.02, time_budget=60, on_progress=lambda j: (calls.append(1), j.cancel()),
                        on_done=lambda j: calls.append("done"))
    job2.run()
    assert "done" not in calls and job2.result is None and not job2.done


# ---------------------------------------------------------------------------------------------
def test_cli_bad_file_exits_2_before_any_server(tmp_path, capsys, monkeypatch):
    from flexkin.explore import cli

    def no_server(*a, **k):  # pragma: no cover - must not be reached
        raise AssertionError("a server was started for a bad file")

    monkeypatch.setattr("flexkin.explore.server.serve", no_server, raising=False)
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\n[rod]\nlength = -1.0\nEI = 1.0\n')
    with pytest.raises(flexkin.MechanismError) as ei:
        flexkin.load_mechanism(bad)
    assert cli.main([str(bad), "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == str(ei.value)
    assert cli.main([str(tmp_path / "missing.toml"), "--no-browser"]) == 2
    assert "missing.toml" in capsys.readouterr().err
    assert cli.main([str(PROTO), "--port", "70000"]) == 2
    assert "--port" in capsys.readouterr().err


def test_cli_parser_wiring():
    import argparse

    from flexkin.explore.cli import add_explore_parser

    parser = argparse.ArgumentParser(prog="flexkin")
    sub = parser.add_subparsers(dest="command", required=True)
    add_explore_parser(sub)
    a = parser.parse_args(["explore", "m.toml", "--port", "0", "--no-browser", "--pose", "0", "0.3", "90"])
    assert (a.command, a.mechanism, a.port, a.no_browser, a.pose) == ("explore", "m.toml", 0, True, [0.0, 0.3, 90.0])
    a = parser.parse_args(["explore", "m.toml"])
    assert a.port is None and not a.no_browser and a.max_mode == 2


def test_responsiveness_bench_smoke():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from explore_responsiveness import responsiveness

    r = responsiveness(PROTO, moves=6, refreshes=1)
    assert r["track"]["n"] == 6 and r["refresh"]["n"] == 1 and r["n_solutions"] > 0
    assert r["track"]["median_ms"] > 0 and set(r["met"]) == {"track", "refresh"}


def test_prismatic_guide_follows_the_input_offset(mech):
    """The guide of a prismatic leg spans the clamp positions of its input range: with an input
    zero offset (``[[leg]] offset``, e.g. from ``flexkin calibrate``) the slider sits at
    ``origin + (u + offset) direction``, so the guide moves with it."""
    import dataclasses

    from flexkin.explore.scene import base_layers

    legs = tuple(dataclasses.replace(leg, offset=0.05 * (k + 1)) if leg.actuation == "prismatic" else leg
                 for k, leg in enumerate(mech.legs))
    moved = dataclasses.replace(mech, legs=legs)
    guides = base_layers(moved)["guides"]
    for i, leg in enumerate(moved.legs):
        if leg.actuation != "prismatic":
            continue
        lo, hi = input_bounds(moved, i)
        ends = np.array([guides["xs"][i], guides["ys"][i]]).T
        for u in (lo, hi):
            clamp = np.asarray(leg.clamp(u)[0], dtype=float)
            assert np.min(np.hypot(*(ends - clamp).T)) < 1e-12
