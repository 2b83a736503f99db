"""Tests of the full inverse kinematics ``flexkin.ik`` (paper §4) against independent yardsticks.

* the paper's Table 2 (prototype, unloaded);
* every reported solution re-integrated from its clamp with an independent ODE integration
  (``tests/ik_oracle.py``): tips on the platform points, platform equilibrium (SPEC §2 sign),
  d-modes equal to the inflection counts;
* completeness against an independent multi-start shooting solver (``ik_oracle.oracle_ik``):
  no solution with all d-modes <= 2 that the oracle finds may be missing from flexkin's list
  (solutions with an extreme rod, |k| > 1 - 1e-7, are documented out of scope and only
  reported);
* continuity in the load (guards the sign of Eq. 15), the direct sign of the tip forces,
  unreachable poses, argument checking and the SPEC §4 JSON.

The counts per d-mode combination (flexkin vs oracle) and the verification maxima are printed
and, when ``tests/oracles.py`` provides its ``REPORT`` registry, recorded there so that the
terminal summary shows them.  The big completeness study is ``@pytest.mark.slow``.
"""

from __future__ import annotations

import functools
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.mechanism.builders import symmetric_mechanism

sys.path.insert(0, os.path.dirname(__file__))
import ik_oracle as O

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
MAX_MODE = 2
EXTREME_K = 1.0 - 1e-7  # |k| beyond this: out of scope (flexkin's atlas stops at k' = 1e-7)

try:  # the colleague's measurement registry, printed by conftest's terminal summary
    from oracles import REPORT  # type: ignore
except ImportError:  # pragma: no cover
    REPORT = {}


def record(key: str, value) -> None:
    REPORT[f"ik: {key}"] = value
    print(f"[ik] {key}: {value}")


# --------------------------------------------------------------------------------------
# mechanisms, poses and cached flexkin results
# --------------------------------------------------------------------------------------
@functools.cache
def mech(name: str):
    if name == "prototype":
        return flexkin.load_mechanism(str(EXAMPLES / "prototype_3pfr.toml"))
    if name == "mixed":
        return flexkin.load_mechanism(str(EXAMPLES / "mixed_legs.toml"))
    return symmetric_mechanism({"P": "prismatic", "R": "revolute", "L": "length"}[name])


def pose_rad(p):
    return (float(p[0]), float(p[1]), math.radians(p[2]))


def load_of(name, load):
    return tuple(mech(name).load) if load is None else tuple(float(v) for v in load)


@functools.cache
def flex(name: str, pose_deg: tuple, load: tuple | None = None, max_mode: int = MAX_MODE):
    return flexkin.ik(mech(name), pose_rad(pose_deg), load=load, max_mode=max_mode)


def case_id(c):
    name, p, load = c
    s = f"{name}-({p[0]:g},{p[1]:g},{p[2]:g}deg)"
    return s + ("" if load is None else f"-load{tuple(load)}")


MIXED_LOAD2 = (0.03, 0.02, -0.001)
# (mechanism, pose (m, m, deg), load or None for the mechanism's own [load])
CASES = [
    ("prototype", (0.0, 0.0, 60.0), None),
    ("prototype", (0.0, 0.0, 90.0), None),
    ("prototype", (0.0, 0.0, 120.0), None),
    ("P", (0.05, -0.03, 15.0), None),
    ("P", (-0.1, 0.05, 35.0), None),
    ("R", (0.05, 0.02, 20.0), None),
    ("R", (0.0, 0.05, 0.0), None),
    ("R", (0.2, 0.0, 0.0), None),
    ("L", (0.05, 0.02, 20.0), None),
    ("L", (-0.05, 0.08, 35.0), None),
    ("mixed", (0.02, -0.01, 15.0), None),  # the file's load (0, -0.05 N, 0.002 N m)
    ("mixed", (-0.02, 0.03, -20.0), MIXED_LOAD2),
]


# ======================================================================================
# 1. Paper Table 2
# ======================================================================================
@pytest.mark.parametrize("theta_deg, rho", [(60.0, -0.007), (90.0, 0.025), (120.0, 0.058)])
def test_table2_prototype(theta_deg, rho):
    res = flex("prototype", (0.0, 0.0, theta_deg))
    hits = [s for s in res.solutions
            if s.modes == (1, 1, 1) and all(abs(u - rho) <= 1e-3 for u in s.inputs)]
    assert hits, (f"no mode-111 solution with rho1=rho2=rho3={rho} m (+-1 mm) at theta={theta_deg} deg; "
                  f"mode-111 inputs: {[tuple(round(u, 4) for u in s.inputs) for s in res.solutions if s.modes == (1, 1, 1)]}")
    # the three inputs of the Table-2 solution are equal (C3 symmetry of the prototype)
    s = hits[0]
    assert max(s.inputs) - min(s.inputs) < 1e-6


# ======================================================================================
# 2. Every reported solution verified by an independent integration
# ======================================================================================
@pytest.mark.parametrize("case", CASES, ids=case_id)
def test_every_solution_verified(case):
    name, p, load = case
    m = mech(name)
    res = flex(name, p, load)
    L_ref = O.Geom.of(m).L_ref
    w = load_of(name, load)
    assert res.solutions, "expected solutions at this pose"
    checks = O.verify_many(m, res.solutions, w, pose_rad(p))
    bad = []
    amb = 0
    for s, v in zip(res.solutions, checks):
        problems = []
        if v["tip_error"] > 1e-8 * L_ref:
            problems.append(f"tip error {v['tip_error']:.2e} m")
        # forward integration from the clamp amplifies rounding like 1/k'^2 for rods near
        # |k| = 1 (tight loops, taut rods): the attainable tip-moment check scales with it
        kp = min(np.sqrt(max(1.0 - r.k * r.k, 1e-300)) for r in s.rods)
        if v["tip_moment"] > 1e-6 * max(1.0, (1e-4 / kp) ** 2):
            problems.append(f"tip moment {v['tip_moment']:.2e} EI/L (k' = {kp:.1e})")
        if v["eq_force"] > 1e-8 or v["eq_moment"] > 1e-8:
            problems.append(f"equilibrium {v['eq_force']:.2e}/{v['eq_moment']:.2e}")
        if v["clamp_error"] > 1e-12 * max(L_ref, 1.0):
            problems.append(f"clamp differs from SPEC §2 by {v['clamp_error']:.2e}")
        for q_rep, q_ode, a in zip(s.modes, v["modes"], v["mode_ambiguous"]):
            # a boundary case (zero moment at the clamp, vanishing slope at the tip, tangency)
            # may be labelled with either neighbouring mode
            if a:
                amb += 1
            if (q_rep != q_ode and not a) or abs(q_rep - q_ode) > 2:
                problems.append(f"mode {s.modes} reported, inflections {v['modes']}")
                break
        if any(q > MAX_MODE for q in s.modes):
            problems.append(f"mode {s.modes} above max_mode")
        if not np.allclose(s.pose, pose_rad(p), rtol=0, atol=1e-14):
            problems.append("pose differs from the requested pose")
        if problems:
            bad.append((s.mode_label, tuple(round(u, 6) for u in s.inputs), problems))
    record(f"verify {case_id(case)}",
           f"{len(res.solutions)} solutions, max tip err {max(c['tip_error'] for c in checks):.1e} m, "
           f"max tip moment {max(c['tip_moment'] for c in checks):.1e}, "
           f"max eq {max(max(c['eq_force'], c['eq_moment']) for c in checks):.1e}, ambiguous-mode rods {amb}")
    assert not bad, f"{len(bad)} of {len(res.solutions)} solutions fail verification: {bad[:5]}"


def test_verification_detects_errors():
    """The verifier itself must fail on a corrupted solution (guards the yardstick)."""
    m = mech("P")
    res = flex("P", (0.05, -0.03, 15.0), None)
    s = res.solutions[0]

    class Fake:
        pose = s.pose
        inputs = (s.inputs[0] + 1e-6, s.inputs[1], s.inputs[2])
        rods = s.rods

    v_ok = O.verify_solution(m, s, (0, 0, 0))
    v_bad = O.verify_solution(m, Fake(), (0, 0, 0))
    assert v_ok["tip_error"] < 1e-9
    assert v_bad["tip_error"] > 5e-7
    v_load = O.verify_solution(m, s, (1e-3, 0, 0))
    assert v_load["eq_force"] > 1e-8


# ======================================================================================
# 3. Completeness against the independent multi-start shooting oracle
# ======================================================================================
@functools.cache
def _oracle(name, p, load, budget):
    m = mech(name)
    st: dict = {}
    sols = O.oracle_ik(m, pose_rad(p), load=load_of(name, load), max_mode=MAX_MODE, stats=st,
                       **dict(BUDGETS[budget]))
    return sols, st


def compare_with_oracle(name, p, load, budget):
    m = mech(name)
    res = flex(name, p, load)
    sols, st = _oracle(name, p, load, budget)
    F_ref = O.Geom.of(m).F_ref
    flex_forces = [[r.tip_force for r in s.rods] for s in res.solutions]
    missed, missed_extreme = [], []
    for s in sols:
        if any(O.match(ff, s.forces, F_ref) for ff in flex_forces):
            continue
        (missed_extreme if s.extreme else missed).append(s)
    flex_found = sum(1 for ff in flex_forces if any(O.match(ff, s.forces, F_ref) for s in sols))
    info = {
        "flexkin": res.by_modes(),
        "oracle": O.by_modes(sols),
        "flexkin_total": len(res.solutions),
        "oracle_total": len(sols),
        "flexkin_found_by_oracle": flex_found,
        "missed": [_describe(s) for s in missed],
        "missed_extreme": [_describe(s) for s in missed_extreme],
        "oracle_stats": st,
    }
    record(f"completeness {case_id((name, p, load))}", info)
    return info, missed


def _describe(s):
    return {"modes": s.mode_label, "inputs": [round(float(u), 9) for u in s.inputs],
            "tip_forces": [[round(float(f), 9) for f in r.tip_force] for r in s.rods],
            "base_moments": [round(r.base_moment, 9) for r in s.rods],
            "R_dimless": [round(r.R_dimless, 3) for r in s.rods],
            "1-|k|": [float(f"{1 - abs(r.k):.2e}") for r in s.rods]}


BUDGETS = {
    "quick": (("n_starts", 400), ("scan", (160, 320)), ("max_triples", 2000), ("seed", 1)),
    "full": (("n_starts", 3000), ("scan", (300, 600)), ("max_triples", 12000), ("s_max", 6.0), ("seed", 7)),
}

COMPLETE_DEFAULT = [
    pytest.param(("P", (0.05, -0.03, 15.0), None), id="P-(0.05,-0.03,15deg)"),
    pytest.param(("R", (0.0, 0.05, 0.0), None), id="R-(0,0.05,0deg)"),
    pytest.param(("L", (0.05, 0.02, 20.0), None), id="L-(0.05,0.02,20deg)"),
    pytest.param(("mixed", (0.02, -0.01, 15.0), None), id="mixed-fileload-(0.02,-0.01,15deg)"),
    pytest.param(("prototype", (0.0, 0.0, 90.0), None), id="prototype-(0,0,90deg)"),
]

COMPLETE_SLOW = [
    pytest.param(c, id=case_id(c)) for c in [
        ("P", (0.05, -0.03, 15.0), None),
        ("P", (-0.1, 0.05, 35.0), None),
        ("R", (0.0, 0.05, 0.0), None),
        ("R", (0.2, 0.0, 0.0), None),
        ("L", (0.05, 0.02, 20.0), None),
        ("L", (-0.05, 0.08, 35.0), None),
        ("mixed", (0.02, -0.01, 15.0), None),
        ("mixed", (-0.02, 0.03, -20.0), MIXED_LOAD2),
    ]
] + [pytest.param(("prototype", (0.0, 0.0, 90.0), None), id="prototype-(0,0,90deg)")]


@pytest.mark.parametrize("case", COMPLETE_DEFAULT)
def test_completeness_quick(case):
    info, missed = compare_with_oracle(*case, "quick")
    assert info["oracle_total"] > 0
    assert not missed, (f"flexkin misses {len(missed)} non-extreme solution(s) found by the oracle: "
                        f"{info['missed']}")


@pytest.mark.slow
@pytest.mark.parametrize("case", COMPLETE_SLOW)
def test_completeness_full(case):
    info, missed = compare_with_oracle(*case, "full")
    assert info["oracle_total"] > 0
    assert not missed, (f"flexkin misses {len(missed)} non-extreme solution(s) found by the oracle: "
                        f"{info['missed']}")


def test_oracle_finds_flexkin_solutions():
    """Guard on the yardstick: the quick oracle must recover most of flexkin's (verified)
    solutions on a rich case, otherwise 'no miss' would mean little."""
    name, p, load = "P", (0.05, -0.03, 15.0), None
    res = flex(name, p, load)
    sols, _ = _oracle(name, p, load, "quick")
    F_ref = O.Geom.of(mech(name)).F_ref
    non_extreme = [s for s in res.solutions if all(abs(r.k) <= EXTREME_K for r in s.rods)]
    found = sum(1 for s in non_extreme if any(O.match([r.tip_force for r in s.rods], o.forces, F_ref) for o in sols))
    record("oracle recall (quick) on P-(0.05,-0.03,15deg)", f"{found}/{len(non_extreme)} non-extreme flexkin solutions")
    assert found >= 0.8 * len(non_extreme)


@pytest.mark.parametrize("theta", [60.0, 90.0, 120.0])
def test_c3_symmetry_of_the_solution_set(theta):
    """A C3-symmetric mechanism at a pose (0, 0, theta), unloaded, has a C3-symmetric solution set:
    rotating a solution by 120 deg and relabelling the legs gives a solution.  Cheap, independent
    completeness check on the prototype (all non-extreme images must be listed)."""
    name, p = "prototype", (0.0, 0.0, theta)
    res = flex(name, p, None)
    F_ref = O.Geom.of(mech(name)).F_ref
    c, s_ = math.cos(2 * math.pi / 3), math.sin(2 * math.pi / 3)
    Rm = np.array([[c, -s_], [s_, c]])
    forces = [np.array([r.tip_force for r in s.rods]) for s in res.solutions]
    missing = []
    for s, F in zip(res.solutions, forces):
        if any(abs(r.k) > EXTREME_K for r in s.rods):
            continue
        img = np.roll(F @ Rm.T, 1, axis=0)
        if not any(O.match(G, img, F_ref) for G in forces):
            missing.append((s.mode_label, np.round(F, 6).tolist()))
    assert not missing, f"{len(missing)} solutions whose C3 image is not listed: {missing[:4]}"


# ======================================================================================
# 4. Load continuity (sign of Eq. 15) and the direct sign of the tip forces
# ======================================================================================
def _z(m, s, pose, load):
    return O.solution_z(m, s, pose, load)


CONT_CASES = [
    pytest.param(("mixed", (0.02, -0.01, 15.0), None), id="mixed-fileload"),
    pytest.param(("P", (0.05, -0.03, 15.0), (0.5, -0.3, 0.05)), id="P-load(0.5,-0.3,0.05)"),
]


@pytest.mark.parametrize("case", CONT_CASES)
def test_load_perturbation_continuity(case):
    """IK at L0 and at L0 (1 + eps): every solution has a partner at the other load, displaced
    as predicted by the oracle's tangent (first order, J^-1 dr/dload with the oracle's own
    Jacobian), and the inputs move in the predicted direction.  Solutions with an extreme rod
    (|k| > 1 - 1e-7, out of scope) and near-singular ones (cond J > 1e8) are exempt."""
    name, p, load = case
    m = mech(name)
    pose = pose_rad(p)
    L0 = np.array(load_of(name, load))
    eps = 1e-3
    L1 = L0 * (1 + eps)
    r0 = flex(name, p, tuple(L0))
    r1 = flex(name, p, tuple(L1))
    assert len(r0.solutions) > 0
    g = O.Geom.of(m)
    z0 = np.array([_z(m, s, pose, L0) for s in r0.solutions])
    z1 = np.array([_z(m, s, pose, L1) for s in r1.solutions])
    du, df, conds = O.tangents_many(m, r0.solutions, pose, L0, L1 - L0)
    pred = np.concatenate([df.reshape(-1, 6), du], axis=1)
    ext0 = [any(abs(r.k) > EXTREME_K for r in s.rods) for s in r0.solutions]
    ext1 = [any(abs(r.k) > EXTREME_K for r in s.rods) for s in r1.solutions]
    # compare forces (scaled by EI/L^2) and inputs (scaled) between the loads
    def feat(z):
        return np.concatenate([z[:, [0, 1, 3, 4, 6, 7]], z[:, 9:12]], axis=1)

    f0, f1 = feat(z0), feat(z1)
    us = g.u_scale()
    predf = np.concatenate([pred[:, :6] / g.F_ref, pred[:, 6:] / us], axis=1)
    unmatched0, unmatched1, direction_bad = [], [], []
    used = set()
    for a in range(len(f0)):
        want = f0[a] + predf[a]
        d = np.max(np.abs(f1 - want), axis=1) if len(f1) else np.array([np.inf])
        b = int(np.argmin(d))
        tol = 0.05 * np.max(np.abs(predf[a])) + 1e-7
        if d[b] <= tol:
            used.add(b)
            du_act = f1[b, 6:] - f0[a, 6:]
            du_pred = predf[a, 6:]
            if np.linalg.norm(du_pred) > 1e-9 and np.dot(du_act, du_pred) <= 0:
                direction_bad.append(a)
        elif conds[a] < 1e8 and not ext0[a]:
            unmatched0.append((r0.solutions[a].mode_label, float(d[b]), float(tol)))
    for b in range(len(f1)):
        if b not in used and not ext1[b]:
            d = np.max(np.abs(f0 - f1[b]), axis=1)
            if d.min() > 1e-2:  # no nearby solution at L0 at all
                unmatched1.append(r1.solutions[b].mode_label)
    record(f"load continuity {case_id((name, p, load))}",
           f"{len(r0.solutions)} -> {len(r1.solutions)} solutions ({sum(ext0)} / {sum(ext1)} with an extreme rod), "
           f"eps={eps}, max cond(J)={max(conds):.1e}")
    assert not unmatched0, f"solutions at L0 without a predicted partner at L0(1+eps): {unmatched0[:5]}"
    assert not unmatched1, f"solutions at L0(1+eps) without a partner at L0: {unmatched1[:5]}"
    assert not direction_bad, f"inputs move against the tangent prediction for {len(direction_bad)} solutions"


def _continuation_study(name, p, load, n_steps, n_sub):
    """Double the load in steps; the oracle continues every flexkin solution of each step to the
    next load; flexkin's list at the next load must contain every continued solution (all modes
    <= 2, no extreme rod).  Every flexkin solution at the next load must continue back to a
    flexkin solution at the previous load, or be born at a fold (backward continuation fails)."""
    m = mech(name)
    pose = pose_rad(p)
    L0 = np.array(load_of(name, load))
    g = O.Geom.of(m)
    loads = [L0 * (1 + k / n_steps) for k in range(n_steps + 1)]
    lost, unexplained, born = [], [], 0
    counts = []
    for k in range(n_steps):
        ra = flex(name, p, tuple(loads[k]))
        rb = flex(name, p, tuple(loads[k + 1]))
        counts.append(len(ra.solutions))
        Fa = [[r.tip_force for r in s.rods] for s in ra.solutions]
        Fb = [[r.tip_force for r in s.rods] for s in rb.solutions]
        Za = np.array([_z(m, s, pose, loads[k]) for s in ra.solutions]).reshape(-1, 12)
        fwd = O.continue_many(m, Za, pose, loads[k], loads[k + 1], n_sub=n_sub)
        for s, c in zip(ra.solutions, fwd):
            if c is None or any(q > MAX_MODE for q in c.modes) or c.extreme:
                continue
            if not any(O.match(fb, c.forces, g.F_ref) for fb in Fb):
                lost.append((k, s.mode_label, _describe(c)))
        matched_b = [any(c is not None and O.match(fb, c.forces, g.F_ref) for c in fwd) for fb in Fb]
        todo = [j for j, ok in enumerate(matched_b) if not ok]
        if todo:
            Zb = np.array([_z(m, rb.solutions[j], pose, loads[k + 1]) for j in todo])
            back = O.continue_many(m, Zb, pose, loads[k + 1], loads[k], n_sub=n_sub)
            for j, c in zip(todo, back):
                sb = rb.solutions[j]
                if c is None:
                    born += 1
                elif any(O.match(fa, c.forces, g.F_ref) for fa in Fa):
                    pass  # matched backwards (forward continuation went elsewhere)
                elif any(q > MAX_MODE for q in c.modes) or c.extreme or any(abs(r.k) > EXTREME_K for r in sb.rods):
                    pass  # came from an out-of-scope rod
                else:
                    unexplained.append((k, sb.mode_label, _describe(c)))
    counts.append(len(flex(name, p, tuple(loads[-1])).solutions))
    record(f"load doubling {case_id((name, p, load))}",
           f"solution counts along the path {counts}, born at folds {born}")
    return lost, unexplained


def test_load_doubling_continuation():
    lost, unexplained = _continuation_study("mixed", (0.02, -0.01, 15.0), None, n_steps=5, n_sub=3)
    assert not lost, f"flexkin loses continued solutions: {lost[:3]}"
    assert not unexplained, f"flexkin solutions not continuable to a listed solution: {unexplained[:3]}"


@pytest.mark.slow
def test_load_doubling_continuation_prismatic():
    lost, unexplained = _continuation_study("P", (0.05, -0.03, 15.0), (0.5, -0.3, 0.05), n_steps=10, n_sub=2)
    assert not lost, f"flexkin loses continued solutions: {lost[:3]}"
    assert not unexplained, f"flexkin solutions not continuable to a listed solution: {unexplained[:3]}"


@pytest.mark.parametrize("kind, f", [("P", 0.05), ("P", -0.08), ("R", 0.05)])
def test_tip_force_sign_centred_pose(kind, f):
    """At the centred pose of a C3-symmetric mechanism under a small load F = (f, 0): the tip
    forces on the rods sum to +F (SPEC §2: sum n_i = F) and their moments about P to zero."""
    res = flex(kind, (0.0, 0.0, 0.0), (f, 0.0, 0.0))
    assert res.solutions
    for s in res.solutions:
        n = np.array([r.tip_force for r in s.rods])
        assert np.allclose(n.sum(axis=0), [f, 0.0], atol=1e-9), (s.mode_label, n.sum(axis=0))
        B = np.array([r.tip for r in s.rods])
        arm = B - np.array(s.pose[:2])
        assert abs(np.sum(arm[:, 0] * n[:, 1] - arm[:, 1] * n[:, 0])) < 1e-9


# ======================================================================================
# 5. Unreachable poses and bad arguments
# ======================================================================================
@pytest.mark.parametrize("name", ["P", "R", "mixed"])
def test_unreachable_pose(name):
    """A pose far outside the reach of the fixed-length legs: no solution, a message, no exception.
    (A pure length-actuated mechanism reaches every pose with a long enough rod, so it is not used.)"""
    res = flexkin.ik(mech(name), (5.0, 5.0, 0.0))
    assert len(res.solutions) == 0
    assert isinstance(res.message, str) and res.message.strip()
    assert res.to_dict()["solutions"] == []


@pytest.mark.parametrize("bad", [
    {"pose": (0.0, 0.0)},
    {"pose": (0.0, float("nan"), 0.0)},
    {"pose": (0.0, 0.0, float("inf"))},
    {"pose": (0.0, 0.0, 0.1), "max_mode": 0},
    {"pose": (0.0, 0.0, 0.1), "load": (0.0, float("nan"), 0.0)},
    {"pose": (0.0, 0.0, 0.1), "load": (1.0, 2.0)},
])
def test_bad_arguments(bad):
    kw = dict(bad)
    pose = kw.pop("pose")
    with pytest.raises(ValueError):
        flexkin.ik(mech("P"), pose, **kw)


# ======================================================================================
# 6. JSON (SPEC §4)
# ======================================================================================
@pytest.mark.parametrize("name, p, load", [("R", (0.05, 0.02, 20.0), None),
                                           ("mixed", (0.02, -0.01, 15.0), None)])
def test_to_dict_json(name, p, load):
    res = flex(name, p, load)
    d = res.to_dict()
    for key in ("problem", "mechanism", "load", "max_mode", "solutions"):
        assert key in d
    assert d["problem"] == "ik"
    assert d["mechanism"] == mech(name).name
    assert d["max_mode"] == MAX_MODE
    assert np.allclose(d["load"], load_of(name, load))
    assert len(d["solutions"]) == len(res.solutions) > 0
    kinds = [leg.actuation for leg in mech(name).legs]
    for s, sd in zip(res.solutions, d["solutions"]):
        for key in ("pose", "inputs", "modes", "stable", "residual", "rods", "jacobian"):
            assert key in sd, key
        assert np.allclose(sd["pose"], [s.pose[0], s.pose[1], math.degrees(s.pose[2])])
        assert math.isclose(sd["pose"][2], p[2], abs_tol=1e-9)  # degrees
        want = [math.degrees(u) if k == "revolute" else u for u, k in zip(s.inputs, kinds)]
        assert np.allclose(sd["inputs"], want)
        assert sd["modes"] == list(s.modes)
        assert len(sd["rods"]) == 3
        for r, rd in zip(s.rods, sd["rods"]):
            for key in ("k", "psi_deg", "tip_force", "base_moment", "energy"):
                assert key in rd, key
            assert math.isclose(rd["psi_deg"], math.degrees(r.psi), rel_tol=1e-12, abs_tol=1e-12)
            assert np.allclose(rd["tip_force"], r.tip_force)
    text = json.dumps(d)
    assert json.loads(text) == d
