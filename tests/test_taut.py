"""Pinned rods near taut, down to taut (issue 27, item 1).

Set-up (the issue's): the unit 3-RFR of ``examples/unit_3rfr.toml`` at x = 0.0855..., theta = 20 deg,
at the y where leg 3's platform point is ``d`` short of the rod length from its joint: the rods
that reach it are within about ``sqrt(d)`` of straight (taut under tension, or compressed).
Before the fix ``ik`` found 6, 4, 2 and 0 of the 8 equilibria at d = 1e-6, 1e-7, 1e-9 and 0 and
said ``complete``.

Yardsticks, none of them the global search:

* the geometry: ``|B_3 - V_3| = L - d`` from the pose alone;
* continuation (:func:`flexkin.follow_path`, in the seam chart where a rod is near straight
  under tension) of every IK solution at d = 1e-4 down the decades to d = 1e-12: the IK at each
  decade must contain every followed solution, and nothing else;
* at d = 0 (exactly taut) the followed pairs (a rod and its mirror image about the straight rod)
  meet: each pair is one reported equilibrium, with leg 3's rod straight along the chord;
* re-integration of every reported rod by solve_ivp (``tests/ik_oracle.py``);
* forward kinematics at the inputs of near-taut and taut IK solutions returns their poses.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.rod.kernels import CHART_SEAM
from flexkin.solve.curves import leg_curves
from flexkin.system import System

sys.path.insert(0, os.path.dirname(__file__))
import ik_oracle as O  # noqa: E402

MECH = flexkin.load_mechanism(Path(__file__).resolve().parents[1] / "examples" / "unit_3rfr.toml")
X0, TH = 0.08550503583141718, math.radians(20.0)
V3 = np.array(MECH.legs[2].origin, float)
B3 = np.array(MECH.platform.attach[2], float)
L = MECH.legs[2].rod.length
DECADES = [10.0 ** -k for k in range(4, 13)]


def y_short(d: float) -> float:
    """The y at which leg 3's platform point is ``d`` short of taut (the lower of the two)."""
    c, s = math.cos(TH), math.sin(TH)
    b = np.array([c * B3[0] - s * B3[1], s * B3[0] + c * B3[1]])
    dx = X0 + b[0] - V3[0]
    return float(V3[1] - b[1] - math.sqrt((L - d) ** 2 - dx * dx))


def pose(d: float) -> tuple[float, float, float]:
    return (X0, y_short(d), TH)


def wrap(a):
    return np.angle(np.exp(1j * np.asarray(a)))


@pytest.fixture(scope="module")
def walk():
    """Every IK solution at d = 1e-4 followed down the decades (continuation, one path per decade)."""
    sols = list(flexkin.ik(MECH, pose(DECADES[0])).solutions)
    assert len(sols) == 8
    out = {DECADES[0]: sols}
    for d0, d1 in zip(DECADES[:-1], DECADES[1:]):
        nxt = []
        for s in sols:
            p = flexkin.follow_path(MECH, pose(d0), pose(d1), steps=4, solution=s)
            assert p.complete, (d1, s.modes, p.events)
            nxt.append(p.sample_solutions()[-1])
        out[d1] = sols = nxt
    return out


def test_set_up_geometry():
    sy = System.from_mechanism(MECH)
    for d in DECADES + [0.0]:
        B = sy.platform_points(np.array([pose(d)]))[0, 2]
        assert abs(np.hypot(*(B - V3)) - (L - d)) < 1e-15


@pytest.mark.parametrize("d", DECADES[1:], ids=lambda d: f"d={d:.0e}")
def test_ik_finds_every_followed_solution(walk, d):
    res = flexkin.ik(MECH, pose(d))
    assert res.complete
    assert len(res.solutions) == len(walk[d]) == 8
    U = np.array([s.inputs for s in res.solutions])
    F = np.array([np.ravel([r.tip_force for r in s.rods]) for s in res.solutions])
    for s in walk[d]:
        du = np.max(np.abs(wrap(U - np.array(s.inputs))), axis=1)
        j = int(np.argmin(du))
        assert du[j] < 1e-7, (d, s.modes, du[j])
        np.testing.assert_allclose(F[j], np.ravel([r.tip_force for r in s.rods]), rtol=1e-6, atol=1e-6)
        assert res.solutions[j].modes == s.modes
    # the near-taut rods in tension are solved in the seam chart, where they are regular
    assert sum(int(s.charts[2]) == CHART_SEAM for s in res.solutions) == 6


def test_ik_exactly_taut(walk):
    """At d = 0 each followed pair (rod 3 and its mirror image) becomes one equilibrium with rod 3
    straight along the chord, pulled (three pairs) or pushed (one pair) along it."""
    res = flexkin.ik(MECH, pose(0.0))
    assert res.complete and len(res.solutions) == 4
    U = np.array([s.inputs for s in res.solutions])
    hits = []
    for s in walk[DECADES[-1]]:
        du = np.max(np.abs(wrap(U - np.array(s.inputs))), axis=1)
        j = int(np.argmin(du))
        assert du[j] < 2e-5, du[j]  # the pair is sqrt(1e-12) apart; taut is a double root (fold)
        hits.append(j)
    assert sorted(set(hits)) == [0, 1, 2, 3] and all(hits.count(j) == 2 for j in range(4))
    for s in res.solutions:
        rod = s.rods[2]
        chord = (np.array(rod.tip) - np.array(rod.clamp)) / L
        assert abs(np.hypot(*chord) - 1.0) < 1e-12
        assert abs(wrap(rod.clamp_angle - math.atan2(chord[1], chord[0]))) < 1e-5  # straight along it
        f = np.array(rod.tip_force)
        assert abs(chord[0] * f[1] - chord[1] * f[0]) < 1e-5 * np.hypot(*f)  # force along the rod
        assert abs(rod.base_moment) < 1e-5 * max(1.0, np.hypot(*f))
    tension = sorted(float(np.dot(s.rods[2].tip_force, np.array(s.rods[2].tip) - V3)) > 0 for s in res.solutions)
    assert tension == [False, True, True, True]


@pytest.mark.parametrize("d", [1e-12, 0.0], ids=["d=1e-12", "taut"])
def test_near_taut_solutions_verified_by_ode(d):
    res = flexkin.ik(MECH, pose(d))
    assert res.solutions
    for s, v in zip(res.solutions, O.verify_many(MECH, res.solutions, (0.0, 0.0, 0.0), pose=pose(d))):
        assert v["tip_error"] < 1e-9 and v["tip_moment"] < 1e-7, v
        assert v["eq_force"] < 1e-9 and v["eq_moment"] < 1e-9, v
        assert tuple(v["modes"]) == s.modes
        assert s.verified


@pytest.mark.parametrize("d, k", [(1e-12, 5), (0.0, 1)], ids=["1e-12", "taut"])
def test_fk_returns_near_taut_solutions(d, k):
    """The pinned FK branch-and-bound covers the rods near taut (the seam patch of its tree)."""
    sol = flexkin.ik(MECH, pose(d)).solutions[k]
    res = flexkin.fk(MECH, sol.inputs)
    assert res.complete
    dp = [np.max(np.abs(np.array(s.pose) - np.array(sol.pose))) for s in res.solutions]
    assert min(dp) < 1e-7, (sol.modes, min(dp))


def test_taut_leg_curve_is_the_straight_rods():
    """For a revolute leg whose platform point is exactly at full reach, the geometric-condition
    curve in the seam chart is the straight rod under tension (psi_s = 0) of every tension, with
    its force along the chord (the regular form of the condition has a simple root there)."""
    sy = System.from_mechanism(MECH)
    B = sy.platform_points(np.array([pose(0.0)]))[0]
    curve = leg_curves(MECH, B, 2, theta=TH)[2]
    seam = [br for br in curve.branches if br["chart"][0] == CHART_SEAM]
    assert seam
    chord = (B[2] - V3) / L
    for br in seam:
        f = br["force"]
        # (below R ~ 1e-2 EI/L^2 every rod is straight to rounding, whatever its force direction)
        loaded = np.hypot(*f.T) > 1e-2
        assert np.max(np.abs(br["z"][loaded, 0]), initial=0.0) < 1e-12  # psi_s = 0
        fl = f[loaded]
        assert np.max(np.abs(chord[0] * fl[:, 1] - chord[1] * fl[:, 0]), initial=0.0) < 1e-9 * max(1.0, np.max(f))
        assert np.all(fl @ chord > 0)
    tensions = np.concatenate([br["force"] @ chord for br in seam])
    assert tensions.min() < 1e-3 and tensions.max() > 200.0  # from unloaded to the scope's end


def test_scope_limit_of_taut_rods_makes_the_result_incomplete(monkeypatch):
    """Where the taut search stops (lambda L beyond the seam chart's scope) the result says
    complete = False and why, instead of dropping the equilibria silently.  The scope is lowered
    below the tension of rod 3 in two of the equilibria for the test."""
    import flexkin.rod.seam_atlas as SA

    full = flexkin.ik(MECH, pose(1e-6))
    phis = sorted(math.sqrt(np.hypot(*s.rods[2].tip_force) * L**2 / MECH.legs[2].rod.EI)
                  for s in full.solutions if int(s.charts[2]) == CHART_SEAM)
    assert len(phis) == 6
    monkeypatch.setattr(SA, "LAMBDA_SCOPE", 0.5 * (phis[3] + phis[4]))
    res = flexkin.ik(MECH, pose(1e-6))
    assert not res.complete and "beyond the numerical scope" in res.message
    assert res.diagnostics.out_of_scope_taut == 2 and len(res.solutions) == 6
