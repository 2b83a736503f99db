"""The a-posteriori check of every reported solution (issue 12, :mod:`flexkin.analysis.verify`).

References, all independent of the closed form and of the module under test:

* scipy's ``solve_ivp`` (DOP853, rtol = atol = 1e-12, dense output) integrating the elastica in
  SI units and world coordinates, ``M' = F_x sin th - F_y cos th`` (SPEC §2: the force on the
  rod tip by the platform is the constant internal force; Eq. 8 then reads
  ``th'' = (R/EI) sin(th - psi)``);
* the inflection count of the integrated shape (dense output): 1 + the sign changes of the
  bending moment strictly inside the rod (SPEC §2; a base inflection does not count);
* finite differences for the condition number of the Newton matrix;
* corrupted solutions that must be flagged.

Rods under large tension (``lambda L = sqrt(R L^2 / EI)`` up to ~30 here) amplify any
perturbation by up to ``exp(lambda L)`` along the rod, so the reference, like the module,
integrates each rod in segments of ``lambda L <= 3`` whose tangent and moment restart from the
reported shape (:meth:`RodState.profile`) and checks that the segments join; the position (which
does not act back) is carried through from the clamp to the tip.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import flexkin
from flexkin.analysis.verify import RTOL, VERIFY_TOL, integrate_rod, newton_condition, verify_solutions
from flexkin.mechanism.builders import symmetric_mechanism
from flexkin.rod.state import RodState
from flexkin.solve.finish import build_solutions
from flexkin.system import System

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
DEG = math.pi / 180.0


# ---- the independent reference ---------------------------------------------------------------
def _rhs(EI: float, F: np.ndarray):
    def f(_s, y):
        return [math.cos(y[2]), math.sin(y[2]), y[3] / EI, F[0] * math.sin(y[2]) - F[1] * math.cos(y[2])]
    return f


def ode_check(rod: RodState, samples: int = 48) -> dict:
    """Integrate one rod (world frame, SI) with scipy from its clamp, restarting tangent and moment
    from the reported shape at the nodes of segments of ``lambda L <= 3``; returns the tip's
    position mismatch / L and the largest tangent and moment (/ (EI/L)) mismatch at the
    segments' ends, the inflection count on (0, L] (the sign changes of the moment strictly
    inside, moments below 1e-8 of the largest counting as zero, plus 1 for a pinned tip: a
    clamped tip is not an inflection, SPEC §2) and the tangent's total turning (rad)."""
    L, EI = rod.length, rod.EI
    F = np.array(rod.tip_force)
    lam = math.sqrt(np.hypot(*F) * L * L / EI)
    nseg = max(1, math.ceil(lam / 3.0))
    nodes = rod.profile(nseg + 1)
    start = np.array([[*rod.clamp, rod.clamp_angle, rod.base_moment]]
                     + [[nodes["x"][k], nodes["y"][k], nodes["theta"][k], nodes["moment"][k]] for k in range(1, nseg)])
    end = np.array([rod.tip[0], rod.tip[1], rod.tip_angle, rod.tip_moment])
    gap = np.zeros(3)
    ms, ths = [], []
    h = L / nseg
    y = start[0]
    for k in range(nseg):
        # (th, m) restarted from the reported shape, the position carried through (no feedback)
        sol = solve_ivp(_rhs(EI, F), (k * h, (k + 1) * h), np.r_[y[:2], start[k, 2:]], method="DOP853",
                        rtol=1e-12, atol=1e-12, dense_output=True)
        assert sol.success
        target = start[k + 1] if k + 1 < nseg else end
        y = sol.y[:, -1]
        gap = np.maximum(gap, [np.hypot(*(y[:2] - end[:2])) / L if k + 1 == nseg else 0.0,
                               abs((y[2] - target[2] + math.pi) % (2 * math.pi) - math.pi),
                               abs(y[3] - target[3]) * L / EI])
        yy = sol.sol(np.linspace(k * h, (k + 1) * h, samples + 1))
        ms.append(yy[3])
        ths.append(yy[2])
    m = np.concatenate(ms)
    eps = 1e-8 * np.max(np.abs(m))
    sig = np.sign(m[np.abs(m) > eps])
    count = (0 if rod.joint == "clamped" else 1) + int(np.sum(sig[1:] != sig[:-1]))
    th = np.concatenate(ths)
    return {"gap": gap, "count": count, "turning": float(np.ptp(th)), "lam": lam}


def label_ok(rod: RodState, c: dict) -> bool:
    """The d-mode of SPEC §2 equals the inflection count.  The count treats moments below 1e-8
    of the largest as zero, so a base inflection (a rod flagged ``mode_boundary``) does not
    count: such a rod must carry the lower label, like every other rod, exactly."""
    return rod.mode == c["count"]


# ---- mechanisms ------------------------------------------------------------------------------
def _welded(joints, pose):
    """The unit 3-PFR with rods welded to the platform at the tip tangents of a stable pinned
    solution (tip moments then vanish there: an equilibrium of the clamped mechanism)."""
    base = symmetric_mechanism("prismatic")
    res = flexkin.ik(base, (0.05, -0.02, 10 * DEG), max_mode=1)
    sol = next(s for s in res.solutions if s.stable and s.modes == (1, 1, 1))
    betas = [float(r.tip_angle - sol.pose[2]) for r in sol.rods]
    legs = tuple(dataclasses.replace(leg, joint=j, tip_angle=b) for leg, j, b in zip(base.legs, joints, betas))
    return dataclasses.replace(base, legs=legs, name="welded " + "/".join(joints))


def _mech(name: str):
    if name in ("prismatic", "revolute", "length"):
        return symmetric_mechanism(name)
    if name == "clamped":
        return _welded(("clamped",) * 3, None)
    if name == "half-clamped":
        return _welded(("pinned", "clamped", "pinned"), None)
    return flexkin.load_mechanism(EXAMPLES / f"{name}.toml")


CASES = [
    ("ik", "prismatic", (0.0, 0.0, 0.0)),
    ("ik", "revolute", (0.0, 0.0, 0.0)),            # taut rods with k' ~ 1e-4, mode boundaries
    ("ik", "revolute", (0.05, -0.02, 10 * DEG)),
    ("ik", "length", (0.03, 0.02, 0.1)),
    ("ik", "prototype_3pfr", (0.0, 0.0, 90 * DEG)),  # loops
    ("ik", "mixed_legs", (0.0, 0.0, 0.0)),          # loaded, three actuations, two rods
    ("ik", "clamped", (0.0, 0.03, -5 * DEG)),
    ("ik", "half-clamped", (0.0, 0.03, -5 * DEG)),
    ("ik", "half-clamped", (0.05, -0.02, 10 * DEG)),
    ("fk", "prototype_3pfr", (0.025, 0.025, 0.025)),
]
_RESULTS: dict = {}


def _solve(problem, name, given):
    key = (problem, name, given)
    if key not in _RESULTS:
        mech = _mech(name)
        _RESULTS[key] = (mech, (flexkin.ik if problem == "ik" else flexkin.fk)(mech, given))
    return _RESULTS[key]


def _id(case):
    return f"{case[0]}-{case[1]}-" + ",".join(f"{v:.3g}" for v in case[2])


# ---- 1. the compiled integrator against scipy -----------------------------------------------
@pytest.mark.parametrize("m0, force", [(1.2, (-5.0, 3.0)), (0.0, (-20.19, 0.0)), (-2.5, (30.0, -10.0)),
                                       (6.0, (-9.0, 4.0)), (0.3, (0.0, 0.0))])
def test_integrator_matches_solve_ivp(m0, force):
    ref = solve_ivp(_rhs(1.0, np.array(force)), (0.0, 1.0), [0.0, 0.0, 0.0, m0], method="DOP853",
                    rtol=1e-12, atol=1e-12, dense_output=True)
    for s in (0.37, 0.5, 1.0):
        got = integrate_rod(m0, force, s)
        want = ref.sol(s)
        assert np.max(np.abs(got - want)) <= 1e-9 * (1.0 + np.max(np.abs(want))), (s, got, want)


def test_integrator_bad_input():
    with pytest.raises(ValueError, match="s_end"):
        integrate_rod(1.0, (0.0, 0.0), 1.5)


def test_ode_convention_matches_closed_form():
    """The sign of M' (SPEC §2) against the closed form: a clamped-pinned rod shot by scipy from
    its clamp lands on the closed-form tip with zero moment."""
    for v, phis in [(0.4, 0.9), (1.1, -1.0), (0.8, -3.5), (-0.6, 0.2)]:
        rod = RodState.from_chart(v, phis, 0.8, 0.3, clamp=(0.1, -0.2), clamp_angle=0.4)
        sol = solve_ivp(_rhs(rod.EI, np.array(rod.tip_force)), (0.0, rod.length),
                        [*rod.clamp, rod.clamp_angle, rod.base_moment], method="DOP853", rtol=1e-12, atol=1e-12)
        y = sol.y[:, -1]
        assert np.hypot(y[0] - rod.tip[0], y[1] - rod.tip[1]) < 1e-9 * rod.length
        assert abs(y[2] - rod.tip_angle) < 1e-9
        assert abs(y[3]) < 1e-8 * rod.EI / rod.length


# ---- 2. every solution verified, labels = inflection counts ----------------------------------
@pytest.mark.parametrize("case", CASES, ids=_id)
def test_every_solution_verified_and_labelled(case):
    mech, res = _solve(*case)
    assert res.solutions
    bad, mislabelled = [], []
    for s in res.solutions:
        assert s.verified is True, (s.id, s.mode_label, s.verify_error)
        assert s.verify_error <= VERIFY_TOL
        assert s.condition is not None and 1.0 <= s.condition < np.inf
        d = s.to_dict()
        assert d["verified"] is True and d["condition"] == pytest.approx(s.condition)
        for i, rod in enumerate(s.rods):
            c = ode_check(rod)
            # the reference's own segments join (relative to what double precision allows)
            if np.max(c["gap"]) > 1e-8:
                bad.append((s.id, i, c["gap"]))
            if not label_ok(rod, c):
                mislabelled.append((s.id, s.mode_label, i, c["count"], rod.mode_boundary))
    assert not bad, bad[:5]
    assert not mislabelled, mislabelled[:5]


def test_hard_cases_are_present():
    """The cases above contain what makes the check hard: taut near-separatrix rods and
    mode-boundary rods (revolute at 0), loops and k' ~ 1e-6 (prototype at 90 deg), clamped
    tips carrying moments."""
    _, rev = _solve("ik", "revolute", (0.0, 0.0, 0.0))
    kp = [1.0 / math.cosh(r.v) for s in rev.solutions for r in s.rods]
    assert min(kp) < 1e-3
    assert any(r.mode_boundary for s in rev.solutions for r in s.rods)
    _, proto = _solve("ik", "prototype_3pfr", (0.0, 0.0, 90 * DEG))
    # rods looping round (the tangent turns by almost 2 pi) and rods with k' ~ 1e-6
    assert any(ode_check(r)["turning"] > 1.9 * math.pi for s in proto.solutions for r in s.rods)
    assert min(1.0 / math.cosh(r.v) for s in proto.solutions for r in s.rods) < 1e-5
    _, cl = _solve("ik", "clamped", (0.0, 0.03, -5 * DEG))
    assert any(abs(r.tip_moment) > 1e-6 for s in cl.solutions for r in s.rods)


def test_path_tracker_and_workspace_solutions_verified():
    """Paths, the tracker and workspaces report their solutions through the same builder."""
    from flexkin.solve.track import Tracker

    mech = symmetric_mechanism("revolute")
    start, end = (0.0, 0.0, 0.1), (0.06, -0.04, 0.1)
    path = flexkin.follow_path(mech, start, end, steps=6)
    sols = path.sample_solutions()
    assert len(sols) == 7 and all(s.verified and s.condition >= 1.0 for s in sols)
    assert any(1 in s.charts for s in sols)   # rods straight under tension: the seam chart
    step = Tracker(mech, sols[0]).move_to(sols[1].pose)
    assert step.reached and step.solution.verified and 1 in step.solution.charts
    step = Tracker(mech, sols[-1]).move_to(np.array(sols[0].inputs), kind="inputs")
    assert step.fraction > 0 and step.solution.verified
    ws = flexkin.workspace(mech, 0.1, step=0.1, bounds=(-0.3, 0.3, -0.3, 0.3), all_aspects=False)
    j, i = np.argwhere(ws.maps[0].reached)[0]
    assert ws.solution(mech, 0, int(j), int(i)).verified


# ---- 3. a corrupted solution is flagged, not dropped -----------------------------------------
@pytest.mark.parametrize("column", ["rod", "pose", "input"])
def test_corrupted_solution_flagged(column):
    mech, res = _solve("ik", "prototype_3pfr", (0.0, 0.0, 90 * DEG))
    system = System.from_mechanism(mech)
    lay = system.layout
    X = np.array([s.x for s in res.solutions[:12]])
    ch = np.array([s.charts for s in res.solutions[:12]])
    col = {"rod": lay.rod[1].start + 1, "pose": lay.pose.start, "input": lay.inputs.start + 2}[column]
    Xc = X.copy()
    Xc[:, col] += 1e-5 * system.unknown_scale()[col]
    sols = build_solutions(system, mech, Xc, ch, np.asarray(res.load))
    assert len(sols) == len(X)
    assert not any(s.verified for s in sols)
    assert all(s.verify_error > VERIFY_TOL for s in sols)
    assert all(s.to_dict()["verified"] is False for s in sols)
    assert all(s.verified for s in build_solutions(system, mech, X, ch, np.asarray(res.load)))


def test_wrong_label_flagged():
    mech, res = _solve("ik", "prototype_3pfr", (0.0, 0.0, 90 * DEG))
    system = System.from_mechanism(mech)
    X = np.array([s.x for s in res.solutions])
    ch = np.array([s.charts for s in res.solutions])
    modes = np.array([s.modes for s in res.solutions])
    v = verify_solutions(system, X, ch, np.asarray(res.load), modes)
    assert v.verified.all() and np.all(v.inflections == modes)
    wrong = modes.copy()
    wrong[:, 0] += 1
    v = verify_solutions(system, X, ch, np.asarray(res.load), wrong)
    assert not v.verified.any() and not v.modes_agree[:, 0].any()


def test_empty():
    system = System.from_mechanism(symmetric_mechanism("revolute"))
    n = system.layout.n_unknowns
    v = verify_solutions(system, np.zeros((0, n)), np.zeros((0, 3), np.int64), np.zeros(3), np.zeros((0, 3)))
    assert v.verified.shape == (0,) and v.inflections.shape == (0, 3)


# ---- 4. the condition number -----------------------------------------------------------------
@pytest.mark.parametrize("fixed", ["pose", "inputs"])
def test_condition_against_finite_differences(fixed):
    mech, res = _solve("ik", "revolute", (0.05, -0.02, 10 * DEG))
    system = System.from_mechanism(mech)
    lay = system.layout
    X = np.array([s.x for s in res.solutions])
    ch = np.array([s.charts for s in res.solutions])
    load = np.asarray(res.load)
    cond = newton_condition(system, X, ch, load, fixed)
    cols = system.layout.columns(fixed)
    scale = system.unknown_scale()
    for j in range(len(X)):
        A = np.empty((lay.n_equations, len(cols)))
        for k, c in enumerate(cols):
            h = 1e-6
            xp, xm = X[j].copy(), X[j].copy()
            xp[c] += h * scale[c]
            xm[c] -= h * scale[c]
            A[:, k] = (system.residual(xp[None], ch[j:j + 1], load)[0]
                       - system.residual(xm[None], ch[j:j + 1], load)[0]) / (2 * h)
        assert cond[j] == pytest.approx(np.linalg.cond(A), rel=1e-4)
    with pytest.raises(ValueError, match="fixed"):
        newton_condition(system, X, ch, load, "both")


# ---- 5. the prototype's IK (its cost is a row of benchmarks/bench.py) --------------------------
def test_every_prototype_ik_solution_verified():
    mech = flexkin.load_mechanism(EXAMPLES / "prototype_3pfr.toml")
    res = flexkin.ik(mech, (0.0, 0.0, math.pi / 2))
    assert len(res.solutions) >= 80 and all(s.verified for s in res.solutions)
    assert RTOL <= 1e-12


def test_fk_condition_is_the_fk_matrix():
    """An FK solution reports the condition of the FK Newton matrix (inputs held), an IK solution
    that of the IK matrix (pose held): the same equilibrium found both ways gives both."""
    mech, res = _solve("ik", "revolute", (0.05, -0.02, 10 * DEG))
    system = System.from_mechanism(mech)
    s = res.solutions[0]
    fk = flexkin.fk(mech, s.inputs, res.load)
    same = [f for f in fk.solutions if np.allclose(f.pose, s.pose, atol=1e-8)]
    assert len(same) == 1
    f = same[0]
    X, ch, load = np.array([f.x]), np.array([f.charts]), np.asarray(res.load)
    c_fk = newton_condition(system, X, ch, load, "inputs")[0]
    c_ik = newton_condition(system, X, ch, load, "pose")[0]
    assert f.condition == pytest.approx(c_fk, rel=1e-6)
    assert s.condition == pytest.approx(c_ik, rel=1e-3)
    assert abs(c_fk / c_ik - 1.0) > 1e-3  # the two matrices differ, so the test can tell them apart
