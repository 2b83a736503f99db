"""Feasibility checks (paper §4, last step): collisions, loops, strain, actuator strokes.

Every verdict is compared with something computed another way:

* crossings of two rods: matplotlib's ``Path.intersects_path`` (agg's C++ segment test) on
  centre lines sampled at a different density;
* self-intersections (loops): a Cramer's-rule parametric intersection of every pair of
  non-adjacent segments (numpy, different density), and a pure-Python loop for one rod;
* rod inside the platform: barycentric point-in-triangle test on densely sampled points;
* bending strain: the rod re-integrated from its clamp with the reported tip force and base
  moment (``tests/ik_oracle.integrate_rod``, DOP853, independent of flexkin's closed form),
  and finite differences of the sampled tangent angle;
* strokes: the leg ranges compared by hand.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from scipy.spatial import cKDTree

import flexkin
from flexkin.analysis.feasibility import (
    TIP_EXCLUSION_FRACTION,
    Feasibility,
    check_feasibility,
    check_solutions,
    inputs_out_of_range,
    rod_max_curvature,
)
from flexkin.core.polyline import polyline_crossings, polyline_platform, segment_distances, self_crossings

sys.path.insert(0, os.path.dirname(__file__))
import ik_oracle as O

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
POSE90 = (0.0, 0.0, math.radians(90.0))
ORACLE_N = 301  # oracle sampling density, different from the checks' default 200


@functools.cache
def mech(name: str):
    return flexkin.load_mechanism(str(EXAMPLES / f"{name}.toml"))


@functools.cache
def ik90(name: str):
    return flexkin.ik(mech(name), POSE90)


@functools.cache
def feas90(name: str) -> tuple[Feasibility, ...]:
    return check_solutions(mech(name), ik90(name).solutions)


# --------------------------------------------------------------------------------------
# independent oracles
# --------------------------------------------------------------------------------------
def oracle_rods_cross(P: np.ndarray, Q: np.ndarray) -> bool:
    return bool(MplPath(P).intersects_path(MplPath(Q), filled=False))


def oracle_self_crossings(P: np.ndarray) -> int:
    """Pairs of segments i < j - 1 meeting at parameters strictly inside both (Cramer's rule)."""
    a, d = P[:-1], np.diff(P, axis=0)
    i, j = np.triu_indices(len(d), k=2)
    r, s, w = d[i], d[j], a[j] - a[i]
    den = r[:, 0] * (-s[:, 1]) - r[:, 1] * (-s[:, 0])
    ok = np.abs(den) > 1e-300
    t = (w[:, 0] * (-s[:, 1]) - w[:, 1] * (-s[:, 0])) / np.where(ok, den, 1.0)
    u = (r[:, 0] * w[:, 1] - r[:, 1] * w[:, 0]) / np.where(ok, den, 1.0)
    return int(np.count_nonzero(ok & (t > 0) & (t < 1) & (u > 0) & (u < 1)))


def python_self_crossings(P) -> int:
    """The same count by a plain Python double loop (slow; one rod only)."""
    pts = [tuple(map(float, p)) for p in P]
    count = 0
    for i in range(len(pts) - 1):
        (x1, y1), (x2, y2) = pts[i], pts[i + 1]
        for j in range(i + 2, len(pts) - 1):
            (x3, y3), (x4, y4) = pts[j], pts[j + 1]
            den = (x2 - x1) * (y4 - y3) - (y2 - y1) * (x4 - x3)
            if den == 0.0:
                continue
            t = ((x3 - x1) * (y4 - y3) - (y3 - y1) * (x4 - x3)) / den
            u = ((x3 - x1) * (y2 - y1) - (y3 - y1) * (x2 - x1)) / den
            if 0.0 < t < 1.0 and 0.0 < u < 1.0:
                count += 1
    return count


def oracle_inside_platform_points(p: np.ndarray, B: np.ndarray) -> bool:
    T = np.array([[B[1, 0] - B[0, 0], B[2, 0] - B[0, 0]], [B[1, 1] - B[0, 1], B[2, 1] - B[0, 1]]])
    l1, l2 = np.linalg.solve(T, p - B[0])
    return bool(l1 > 1e-9 and l2 > 1e-9 and 1.0 - l1 - l2 > 1e-9)


def oracle_inside_platform(rod, B: np.ndarray, exclusion: float, n: int = 2001) -> bool:
    """Any sampled point of the rod (without its last ``exclusion`` of arc) strictly inside B."""
    P = rod.shape(n)
    s = np.linspace(0.0, rod.length, n)
    P = P[s <= rod.length - exclusion]
    T = np.array([[B[1, 0] - B[0, 0], B[2, 0] - B[0, 0]], [B[1, 1] - B[0, 1], B[2, 1] - B[0, 1]]])
    lam = np.linalg.solve(T, (P - B[0]).T)  # barycentric (l1, l2); l0 = 1 - l1 - l2
    l0 = 1.0 - lam[0] - lam[1]
    return bool(np.any((lam[0] > 1e-9) & (lam[1] > 1e-9) & (l0 > 1e-9)))


def ode_max_strain(rod, radius: float) -> float:
    """Peak |m|/EI * r of the rod re-integrated from its clamp (independent of the closed form)."""
    ode = O.integrate_rod(rod.tip_force, rod.base_moment, rod.clamp, rod.clamp_angle, rod.length, rod.EI,
                          n_eval=20001)
    assert np.hypot(*(ode.tip - np.asarray(rod.tip))) < 1e-7 * rod.length  # it is the same rod
    return float(np.max(np.abs(ode.ms))) / rod.EI * radius


def fd_max_curvature(rod, n: int = 4001) -> float:
    """Peak curvature by finite differences of the sampled tangent angle.

    The chord angles sit at the mid-points s = (j + 1/2) h, so their differences are the
    curvature at s = (j + 1) h, O(h^2); the two end values are extrapolated linearly.
    """
    P = rod.shape(n)
    th = np.unwrap(np.arctan2(*np.diff(P, axis=0).T[::-1]))
    k = np.diff(th) / (rod.length / (n - 1))
    ends = [2 * k[0] - k[1], 2 * k[-1] - k[-2]]
    return float(np.max(np.abs(np.r_[k, ends])))


# --------------------------------------------------------------------------------------
# geometry primitives on hand-made cases
# --------------------------------------------------------------------------------------
def test_primitives_known_answers():
    X1, X2 = np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([[0.0, 1.0], [1.0, 0.0]])
    assert polyline_crossings(X1, X2) == (1, 0.0)
    n, d = polyline_crossings(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0.0, 2.0], [3.0, 2.0]]))
    assert n == 0 and d == pytest.approx(2.0)
    # T-contact: no proper crossing, counted through `touch`
    T = np.array([[0.5, 0.0], [0.5, 1.0]])
    base = np.array([[0.0, 0.0], [1.0, 0.0]])
    assert polyline_crossings(base, T) == (1, 0.0)  # distance exactly 0 is a touch
    lifted = T + [0.0, 1e-14]
    n, d = polyline_crossings(base, lifted)
    assert n == 0 and d == pytest.approx(1e-14, rel=1e-3)
    assert polyline_crossings(base, lifted, touch=1e-12) == (1, d)
    # a straight (collinear) polyline never crosses itself
    line = np.stack([np.linspace(0, 1, 50), np.zeros(50)], -1)
    n, d = self_crossings(line)
    assert n == 0 and d == pytest.approx(1.0 / 49 * 1.0, rel=1e-12)  # segments two apart: one segment between
    # a figure-eight style loop: one crossing
    t = np.linspace(0, 2 * np.pi, 400)[:-5]  # open lemniscate of Gerono, through 0 at pi/2, 3 pi/2
    loop = np.stack([np.cos(t), np.sin(t) * np.cos(t)], -1)
    assert self_crossings(loop)[0] == oracle_self_crossings(loop) == 1
    # a 350 degree arc of radius 1: no crossing; its two ends are 2 sin(5 deg) apart
    a = np.radians(np.linspace(0.0, 350.0, 351))
    arc = np.stack([np.cos(a), np.sin(a)], -1)
    n, d = self_crossings(arc, min_gap=175)
    assert n == 0 and d == pytest.approx(2 * math.sin(math.radians(5.0)), rel=1e-3)


def test_blocked_prefilter_equals_brute_force():
    rng = np.random.default_rng(7)
    for _ in range(60):
        P = np.cumsum(rng.normal(size=(int(rng.integers(3, 70)), 2)), 0)
        Q = np.cumsum(rng.normal(size=(int(rng.integers(3, 70)), 2)), 0) + rng.normal(size=2) * 4
        dist, cross = segment_distances(P, Q)
        n, d = polyline_crossings(P, Q)
        assert n == np.count_nonzero(cross) and d == pytest.approx(dist.min(), abs=1e-13)
        assert oracle_rods_cross(P, Q) == (n > 0)
        gap = int(rng.integers(2, 6))
        dist, cross = segment_distances(P, P)
        i, j = np.triu_indices(len(P) - 1, k=gap)
        n, d = self_crossings(P, min_gap=gap)
        assert n == np.count_nonzero(cross[i, j])
        assert d == (pytest.approx(dist[i, j].min(), abs=1e-13) if i.size else math.inf)
        if gap == 2:
            assert n == oracle_self_crossings(P)


def test_polyline_platform():
    T = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert polyline_platform(np.array([[0.2, 0.2]]), T) == (True, 0.0)
    # passes through the interior between two samples (no sample inside)
    assert polyline_platform(np.array([[-1.0, 0.3], [2.0, 0.3]]), T)[0]
    # ends exactly on a vertex, coming from outside: not a crossing
    inside, d = polyline_platform(np.array([[2.0, -1.0], [1.0, 0.0]]), T, tol=1e-12)
    assert not inside and d == 0.0
    inside, d = polyline_platform(np.array([[2.0, 2.0], [3.0, 3.0]]), T)
    assert not inside and d == pytest.approx(math.hypot(1.5, 1.5))


# --------------------------------------------------------------------------------------
# loops (d-mode 2)
# --------------------------------------------------------------------------------------
def test_mode2_rod_loop_detected_and_verified():
    """solve_rod at tip (0.2, 0.3): one mode-2 rod loops, another mode-2 rod does not."""
    sols = flexkin.solve_rod((0.2, 0.3), 1.0, 1.0, max_mode=2).solutions
    mode2 = [s for s in sols if s.mode == 2]
    counts = [self_crossings(s.shape(200))[0] for s in mode2]
    oracle = [oracle_self_crossings(s.shape(ORACLE_N)) for s in mode2]
    assert counts == oracle
    assert 1 in counts and 0 in counts  # both a looping and a loop-free mode-2 rod
    looping = mode2[counts.index(1)]
    assert python_self_crossings(looping.shape(120)) == 1


def test_self_intersections_of_all_ik_rods_match_oracle():
    """unit 3-PFR at (0, 0, 90 deg): every rod of every IK solution, flexkin vs Cramer oracle."""
    res, feas = ik90("unit_3pfr"), feas90("unit_3pfr")
    n_loops = 0
    for sol, f in zip(res.solutions, feas):
        for i, rod in enumerate(sol.rods):
            loops = oracle_self_crossings(rod.shape(ORACLE_N)) > 0
            assert ((i + 1) in f.self_intersecting) == loops, (sol.mode_label, sol.inputs, i)
            assert (f"rod {i + 1} self-intersects" in f.reasons) == loops
            n_loops += loops
    assert n_loops > 50  # the paper's remark: mode-2 rods loop a lot


def test_mechanism_loop_with_radius_is_intersection_not_contact():
    m = mech("prototype_3pfr")
    for sol, f in zip(ik90("prototype_3pfr").solutions, feas90("prototype_3pfr")):
        for i in f.self_intersecting:
            assert f"rod {i} self-intersects" in f.reasons
            assert oracle_self_crossings(sol.rods[i - 1].shape(ORACLE_N)) > 0
    assert m.legs[0].rod.radius == pytest.approx(1.5e-3)


# --------------------------------------------------------------------------------------
# rod-rod crossings
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["unit_3pfr", "prototype_3pfr", "mixed_legs"])
def test_rod_crossings_match_matplotlib(name):
    pairs = ((0, 1), (0, 2), (1, 2))
    n_cross = 0
    for sol, f in zip(ik90(name).solutions, feas90(name)):
        shapes = [rod.shape(ORACLE_N) for rod in sol.rods]
        for (i, j), d in zip(pairs, f.rod_distances):
            crosses = oracle_rods_cross(shapes[i], shapes[j])
            assert (f"rods {i + 1} and {j + 1} intersect" in f.reasons) == crosses
            assert (d == 0.0) == crosses
            n_cross += crosses
            if not crosses:  # the reported distance is the polyline distance (~ dense points)
                dense = cKDTree(sol.rods[i].shape(1000)).query(sol.rods[j].shape(1000))[0].min()
                assert d == pytest.approx(dense, abs=1e-3 * sol.rods[i].length)
        assert f.min_rod_distance == min(f.rod_distances)
    assert n_cross > 0


def test_crossing_solution_of_unit_mechanism():
    """The unit 3-PFR IK has mode-111 solutions whose rods cross (paper Fig. 10 style)."""
    hits = [(s, f) for s, f in zip(ik90("unit_3pfr").solutions, feas90("unit_3pfr"))
            if s.modes == (1, 1, 1) and f.rod_collisions]
    assert len(hits) >= 3  # a C3-symmetric triple
    for s, f in hits:
        i, j = f.rod_collisions[0]
        assert oracle_rods_cross(s.rods[i - 1].shape(ORACLE_N), s.rods[j - 1].shape(ORACLE_N))
        assert not f.feasible and f.min_rod_distance == 0.0


def test_capsule_threshold_uses_radii_and_clearance():
    m = mech("prototype_3pfr")
    sol = clean_solution()
    f = check_feasibility(m, sol)
    d, need = f.min_rod_distance, 2 * 1.5e-3
    assert d > need
    near = check_feasibility(m, sol, clearance=d - need + 1e-9)
    far = check_feasibility(m, sol, clearance=d - need - 1e-9)
    assert near.rod_collisions and not far.rod_collisions
    assert any(r.startswith("rods ") and "collide: distance" in r for r in near.reasons)


# --------------------------------------------------------------------------------------
# rod-platform
# --------------------------------------------------------------------------------------
def test_platform_crossings_match_barycentric_oracle():
    m = mech("unit_3pfr")  # no radius: zero thickness, exemption = 5% of the shortest edge
    n_hits = 0
    for sol, f in zip(ik90("unit_3pfr").solutions, feas90("unit_3pfr")):
        B = m.platform.world(np.array(sol.pose))
        edge = min(np.hypot(*(B[k] - B[k - 1])) for k in range(3))
        for i, rod in enumerate(sol.rods):
            inside = oracle_inside_platform(rod, B, TIP_EXCLUSION_FRACTION * edge)
            assert ((i + 1) in f.platform_collisions) == inside, (sol.mode_label, sol.inputs, i)
            assert (f"rod {i + 1} crosses the platform" in f.reasons) == inside
            n_hits += inside
    assert n_hits > 0


def test_tip_exclusion_length():
    """A rod that reaches its pin through the platform: exempting its tail from just before its
    first inside point (measured densely, independently) clears it; a bit less does not."""
    m = mech("unit_3pfr")
    n = 4001
    for sol, f in zip(ik90("unit_3pfr").solutions, feas90("unit_3pfr")):
        if not f.platform_collisions:
            continue
        i = f.platform_collisions[0] - 1
        rod = sol.rods[i]
        B = m.platform.world(np.array(sol.pose))
        inside = np.array([oracle_inside_platform_points(p, B) for p in rod.shape(n)[:-1]])
        first = int(np.argmax(inside))
        if inside[first:].all():  # inside from `first` up to the pin
            break
    else:
        pytest.fail("no rod enters the platform and stays inside up to its pin")
    s_in = rod.length * first / (n - 1)
    h = rod.length / 199  # the checks' sampling step
    cleared = check_feasibility(m, sol, tip_exclusion=rod.length - s_in + 2 * h)
    kept = check_feasibility(m, sol, tip_exclusion=rod.length - s_in - 2 * h)
    assert (i + 1) not in cleared.platform_collisions
    assert (i + 1) in kept.platform_collisions


def test_rod_ending_on_platform_boundary_is_fine():
    """The clean prototype solution: the rods reach the corners from outside; even without any
    exemption (tip_exclusion=0, zero clearance) the tips on the boundary are not collisions."""
    m = mech("prototype_3pfr")
    sol = clean_solution()
    bare = dataclasses.replace(m, legs=tuple(dataclasses.replace(leg, rod=dataclasses.replace(leg.rod, radius=None))
                                             for leg in m.legs))
    f = check_feasibility(bare, sol, tip_exclusion=0.0)
    assert f.platform_collisions == () and f.feasible
    assert all(d < 1e-9 for d in f.platform_distances)  # the tip itself is on the triangle


# --------------------------------------------------------------------------------------
# strain
# --------------------------------------------------------------------------------------
def test_max_curvature_closed_form_against_ode_and_fd():
    rods = [rod for sol in ik90("prototype_3pfr").solutions[::3] for rod in sol.rods]  # C3 triples
    interior = [r for r in rods if r.phis <= 0.0]
    at_base = [r for r in rods if r.phis > 0.0]
    assert interior and at_base  # both branches of the closed form are exercised
    for rod in rods:  # all rods: finite differences of the tangent angle (O(h^2))
        k = rod_max_curvature(rod)
        assert k == pytest.approx(fd_max_curvature(rod), rel=1e-5)
        assert k >= np.max(np.abs(rod.curvature(201))) * (1 - 1e-12)
    for rod in (max(interior, key=lambda r: r.energy), at_base[0]):  # ODE, tight
        assert rod_max_curvature(rod) * 1.5e-3 == pytest.approx(ode_max_strain(rod, 1.5e-3), rel=1e-6)
    for rod in at_base:  # peak at the clamp: |m0| / EI
        assert rod_max_curvature(rod) == pytest.approx(abs(rod.base_moment) / rod.EI, rel=1e-12)


def test_max_curvature_of_clamped_rods_against_ode():
    """Clamped-tip rods (wrench chart): the first-integral peak equals the peak of the rod
    re-integrated from its clamp (scipy ODE, 20001 points), interior peaks and end peaks alike;
    it is finite, so a strain limit is enforced on them (it was NaN)."""
    from flexkin.rod.kernels import CHART_WRENCH

    m = mech("mixed_clamped")
    sols = flexkin.ik(m, (0.02, -0.05, np.radians(5.73))).solutions
    rods = [r for s in sols for r in s.rods if r.chart == CHART_WRENCH]
    assert len(rods) >= 20
    interior = 0
    for rod in rods:
        k = rod_max_curvature(rod)
        ends = max(abs(rod.base_moment), abs(rod.tip_moment)) / rod.EI
        interior += k > ends * (1 + 1e-6)
        assert np.isfinite(k)
        assert k == pytest.approx(ode_max_strain(rod, 1.0), rel=1e-6)
    assert interior > 0  # the interior branch is exercised
    radius = 0.2 / max(rod_max_curvature(r) for r in sols[0].rods)  # rod peaks at strain 0.2
    f = check_feasibility(m, sols[0], max_strain=0.1)
    assert all(s is None for s in f.strains)  # no radius in the file: skipped, not judged
    legs = tuple(dataclasses.replace(leg, rod=dataclasses.replace(leg.rod, radius=radius)) for leg in m.legs)
    f = check_feasibility(dataclasses.replace(m, legs=legs), sols[0], max_strain=0.1)
    assert f.max_strain == pytest.approx(0.2, rel=1e-9) and not f.feasible
    assert any(r.startswith("strain") for r in f.reasons)


def test_strain_just_above_and_below_the_limit():
    m = mech("prototype_3pfr")
    sol = max(ik90("prototype_3pfr").solutions, key=lambda s: s.energy)
    f = check_feasibility(m, sol)
    assert f.strain_limit is None and any(s.startswith("strain") for s in f.skipped)
    worst = int(np.argmax(f.strains))
    oracle = ode_max_strain(sol.rods[worst], m.legs[worst].rod.radius)
    assert f.max_strain == pytest.approx(oracle, rel=1e-6)
    # the limit given as an argument
    above = check_feasibility(m, sol, max_strain=0.999 * f.max_strain)
    below = check_feasibility(m, sol, max_strain=1.001 * f.max_strain)
    tag = f"on rod {worst + 1}"
    assert any(r.startswith("strain ") and r.endswith(tag) for r in above.reasons)
    assert not any(r.startswith("strain ") for r in below.reasons)
    # the limit from the mechanism ([limits] max_strain), and the argument overriding it
    limited = dataclasses.replace(m, max_strain=0.999 * f.max_strain)
    assert any(r.startswith("strain ") for r in check_feasibility(limited, sol).reasons)
    assert not any(r.startswith("strain ")
                   for r in check_feasibility(limited, sol, max_strain=1.001 * f.max_strain).reasons)
    assert check_feasibility(limited, sol).strain_limit == pytest.approx(0.999 * f.max_strain)


def test_strain_without_radius_is_skipped_not_judged():
    m = mech("unit_3pfr")  # EI only, no radius
    sol = ik90("unit_3pfr").solutions[0]
    f = check_feasibility(m, sol, max_strain=1e-9)
    assert f.max_strain is None and f.strains == (None, None, None)
    assert not any(r.startswith("strain") for r in f.reasons)
    assert sum("has no radius" in s for s in f.skipped) == 3
    assert all(k > 0 for k in f.max_curvatures)


def test_mechanism_file_limit_is_used():
    m = mech("mixed_legs")  # [limits] max_strain = 0.04
    assert m.max_strain == 0.04
    for sol, f in zip(ik90("mixed_legs").solutions, feas90("mixed_legs")):
        over = [i for i, s in enumerate(f.strains) if s > 0.04]
        assert [r for r in f.reasons if r.startswith("strain")] == [
            f"strain {f.strains[i]:.6g} > 0.04 on rod {i + 1}" for i in over]


# --------------------------------------------------------------------------------------
# actuator strokes
# --------------------------------------------------------------------------------------
def test_inputs_outside_range():
    assert all(leg.range == (-0.5, 1.0) for leg in mech("unit_3pfr").legs)
    for sol, f in zip(ik90("unit_3pfr").solutions, feas90("unit_3pfr")):
        expected = tuple(i + 1 for i, u in enumerate(sol.inputs) if not -0.5 <= u <= 1.0)
        assert f.inputs_out_of_range == expected
        for i in expected:
            assert f"input {i} = {sol.inputs[i - 1]:.6g} m outside range [-0.5, 1]" in f.reasons
    assert any(f.inputs_out_of_range for f in feas90("unit_3pfr"))


def test_revolute_range_in_degrees():
    m = mech("mixed_legs")
    sol = ik90("mixed_legs").solutions[0]
    phi = math.degrees(sol.inputs[1])
    legs = list(m.legs)
    legs[1] = dataclasses.replace(legs[1], range=(math.radians(phi + 1.0), math.radians(phi + 50.0)))
    narrow = dataclasses.replace(m, legs=tuple(legs))
    out = inputs_out_of_range(narrow, sol.inputs)
    assert out == [(2, f"input 2 = {phi:.6g} deg outside range [{phi + 1:.6g}, {phi + 50:.6g}]")]
    f = check_feasibility(narrow, sol)
    assert f.inputs_out_of_range == (2,) and out[0][1] in f.reasons
    assert inputs_out_of_range(m, sol.inputs) == []


# --------------------------------------------------------------------------------------
# a clean solution, the result object, arguments
# --------------------------------------------------------------------------------------
def clean_solution():
    """Prototype, pose (0, 0, 90 deg): the stable mode-111 solution with rho ~ 0.025 m (Table 2)."""
    (sol,) = [s for s in ik90("prototype_3pfr").solutions
              if s.modes == (1, 1, 1) and np.allclose(s.inputs, 0.025, atol=2e-3)]
    return sol


def test_clean_solution_is_feasible():
    m = mech("prototype_3pfr")
    sol = clean_solution()
    f = check_feasibility(m, sol, max_strain=0.04)
    assert f.feasible and f.reasons == () and f.skipped == ()
    assert f.rod_collisions == f.self_intersecting == f.platform_collisions == f.inputs_out_of_range == ()
    shapes = [r.shape(ORACLE_N) for r in sol.rods]
    assert not any(oracle_rods_cross(shapes[i], shapes[j]) for i, j in ((0, 1), (0, 2), (1, 2)))
    assert not any(oracle_self_crossings(P) for P in shapes)
    assert f.min_rod_distance > 0.05  # the rods are far apart
    assert 0 < f.max_strain < 0.04
    assert f.max_strain == pytest.approx(max(ode_max_strain(r, 1.5e-3) for r in sol.rods), rel=1e-6)


def test_to_dict_is_json_ready():
    f = feas90("unit_3pfr")[1]
    d = json.loads(json.dumps(f.to_dict()))
    assert d["feasible"] is False and d["reasons"] == list(f.reasons)
    assert set(d["rod_distances"]) == {"1-2", "1-3", "2-3"}
    assert d["rod_collisions"] == [list(p) for p in f.rod_collisions]
    assert d["strains"] == [None, None, None] and d["max_strain"] is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.feasible = True  # type: ignore[misc]


def test_bad_arguments():
    m, sol = mech("unit_3pfr"), ik90("unit_3pfr").solutions[0]
    for kw in ({"n_samples": 2}, {"n_samples": 10.0}, {"clearance": -1e-3}, {"max_strain": 0.0},
               {"max_strain": float("nan")}, {"tip_exclusion": -1.0}):
        with pytest.raises(ValueError):
            check_feasibility(m, sol, **kw)


def test_all_solutions_quickly_with_fewer_samples():
    """Vectorised checks: the 100 IK solutions of the unit mechanism at two densities agree."""
    res = ik90("unit_3pfr")
    coarse = check_solutions(mech("unit_3pfr"), res.solutions, n_samples=120)
    for a, b in zip(coarse, feas90("unit_3pfr")):
        assert a.self_intersecting == b.self_intersecting
        assert a.rod_collisions == b.rod_collisions
        assert a.inputs_out_of_range == b.inputs_out_of_range
