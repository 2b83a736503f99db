"""Design studies that know feasibility (issue 27, item 8): the constrained workspace as a study
option, the feasible and strain-limited areas and the largest feasible disc as columns, and
seeds searched on the orientation slice when the seed pose has no stable equilibrium."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.study import run_study
from flexkin.study.evaluate import evaluate_design
from flexkin.study.spec import study_from_dict
from test_study_support import EXAMPLES, write_study

SPRING = Path(__file__).resolve().parents[1] / "docs" / "spring_steel_3rfr.toml"
WS = {"step": 0.01, "bounds": [-0.2, 0.2, -0.2, 0.2], "seed": [0.02, 0.01], "all_aspects": False}

RADIUS_STUDY = f'''
name = "spring steel: wire radius x strain limit"
mechanism = "{SPRING.as_posix()}"
orientations = [20]
[grid]
"rod.radius" = [0.8e-3, 1.0e-3]
"limits.max_strain" = [0.007, 0.009]
[workspace]
step = 0.01
bounds = [-0.2, 0.2, -0.2, 0.2]
seed = [0.02, 0.01]
all_aspects = false
'''


@pytest.fixture(scope="module")
def radius_rows(tmp_path_factory):
    d = tmp_path_factory.mktemp("radius_study")
    free = run_study(write_study(d, RADIUS_STUDY), d / "free", scheduler="synchronous", progress=False, figures=False)
    body = RADIUS_STUDY.replace("all_aspects = false", "all_aspects = false\nconstrained = true")
    held = run_study(write_study(d, body, "constrained.toml"), d / "held", scheduler="synchronous", progress=False,
                     figures=False)
    assert free.n_failed == 0 and held.n_failed == 0
    return free.rows, held.rows


def test_strain_limited_area_changes_with_the_wire_radius(radius_rows):
    """At zero load the kinematics do not depend on EI (so the stable region is the same for
    both radii), but the bending strain is radius x curvature: the thicker wire reaches its
    strain limit over less of the region."""
    free, _ = radius_rows
    by = {(r["rod.radius"], r["limits.max_strain"]): r for r in free}
    assert len({round(r["workspace_area"], 12) for r in free}) == 1           # correct physics
    for eps in (0.007, 0.009):
        thin, thick = by[(0.8e-3, eps)], by[(1.0e-3, eps)]
        assert thin["strain_limited_area"] > thick["strain_limited_area"] > 0
    for rad in (0.8e-3, 1.0e-3):
        assert by[(rad, 0.009)]["strain_limited_area"] > by[(rad, 0.007)]["strain_limited_area"]
    for r in free:
        assert r["constraints"] == "ranges;strain"
        assert 0 < r["feasible_area"] <= r["strain_limited_area"] <= r["workspace_area"]
        assert r["feasible_disc_radius"] > 0
    # the walkthrough's design (1 mm wire, strain limit 0.007): 278 stable cells, 50 of them feasible
    w = by[(1.0e-3, 0.007)]
    assert w["workspace_area"] == pytest.approx(278e-4) and w["feasible_area"] == pytest.approx(50e-4)


def test_the_feasible_disc_by_brute_force(radius_rows):
    """The disc of the row is all feasible cells of one aspect, and no larger disc about any
    grid point is (checked point by point on the map computed again)."""
    free, _ = radius_rows
    r = next(r for r in free if r["rod.radius"] == 1.0e-3 and r["limits.max_strain"] == 0.007)
    mech = flexkin.load_mechanism(SPRING)
    ws = flexkin.workspace(mech, math.radians(20), **WS)
    gx, gy = np.meshgrid(ws.x, ws.y)
    cx, cy, rad = r["feasible_disc_x"], r["feasible_disc_y"], r["feasible_disc_radius"]
    inside = np.hypot(gx - cx, gy - cy) < rad - 1e-9
    assert any(np.all(mp.feasible[inside]) for mp in ws.maps)
    h = ws.step
    best = 0.0
    for mp in ws.maps:
        pts = np.argwhere(mp.feasible)
        bad = np.argwhere(~mp.feasible)
        for j, i in pts:
            d_in = np.min(np.hypot(*(bad - (j, i)).T)) * h if len(bad) else np.inf
            d_edge = (min(i, j, len(ws.x) - 1 - i, len(ws.y) - 1 - j) + 1) * h
            best = max(best, min(d_in, d_edge))
    assert rad == pytest.approx(best)


def test_constrained_study_measures_the_feasible_region(radius_rows):
    free, held = radius_rows
    for f, c in zip(free, held):
        assert c["workspace_area"] == pytest.approx(c["feasible_area"])  # the wave stopped at infeasible cells
        assert 0 < c["feasible_area"] <= f["feasible_area"] + 1e-12
        assert c["feasible_disc_radius"] == pytest.approx(f["feasible_disc_radius"])


def _row(mech_file: Path, params: dict, theta: float, workspace: dict) -> dict:
    spec = study_from_dict({"mechanism": mech_file.as_posix(), "orientations": [theta],
                            "grid": {k: [v] for k, v in params.items()}, "workspace": workspace})
    return evaluate_design(spec.tasks()[0])


def test_a_design_without_a_stable_seed_pose_is_seeded_elsewhere():
    """The unit 3-RFR with L = 0.95 m at theta = 0 has no stable equilibrium at the legs'
    centroid (the seed pose): the study finds a pose of the slice with one, maps from there and
    says where; the IK there has stable solutions, at the seed pose none."""
    r = _row(EXAMPLES / "unit_3rfr.toml", {"rod.length": 0.95}, 0.0, {"step": 0.05})
    assert r["error"] == ""
    assert r["workspace_area"] > 0 and r["n_aspects"] >= 1
    assert "no stable IK solution at the seed pose" in r["note"] and "seeded at" in r["note"]
    assert (r["seed_x"], r["seed_y"]) != pytest.approx((0.0, 0.0), abs=0.03)
    import tomllib

    data = tomllib.loads((EXAMPLES / "unit_3rfr.toml").read_text())
    data["rod"]["length"] = 0.95
    mech = flexkin.mechanism_from_dict(data, source="L = 0.95")
    assert any(s.stable for s in flexkin.ik(mech, (r["seed_x"], r["seed_y"], 0.0)).solutions)
    off = _row(EXAMPLES / "unit_3rfr.toml", {"rod.length": 0.95}, 0.0, {"step": 0.05, "seed_search": False})
    assert off["workspace_area"] == 0 and off["note"] == "no stable IK solution at the seed pose"


def test_area_zero_only_when_no_sampled_pose_has_a_stable_equilibrium():
    """Rods of 0.3 m cannot span the 0.75 m from the pivots to the platform anywhere."""
    r = _row(EXAMPLES / "unit_3rfr.toml", {"rod.length": 0.3}, 0.0, {"step": 0.05})
    assert r["error"] == "" and r["workspace_area"] == 0 and r["feasible_disc_radius"] == 0
    import re

    m = re.search(r"no stable IK solution at the seed pose \(.*\) nor at any of the (\d+) other poses sampled",
                  r["note"])
    assert m and int(m.group(1)) >= 48, r["note"]
