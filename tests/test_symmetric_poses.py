"""Symmetric poses, d-mode boundaries and near-boundary families (issue 12).

At a symmetric pose of a C3-symmetric mechanism some equilibria have every base moment zero:
pinned-pinned buckled rods.  The classical elastica fixes them independently of flexkin: a
pinned-pinned rod of length L whose chord is c has modulus k with c / L = 2 E(k)/K(k) - 1
(first buckled shape; the second is two scaled copies, same k, same end tangents, force x 4),
and its end tangents make the angle 2 arcsin(k) with the chord.

* unit 3-RFR at (0, 0, 0): each chord is 0.75 along the ray to the centre; the forces (along
  the chords, through the centre) balance for equal magnitudes, so every zero-moment family has
  8 sign choices per root k of |2E/K - 1| = 0.75, and both buckled members;
* unit 3-PFR: the chords must pass through the centre (moment balance) and meet the guide at
  the angle 2 arcsin(k); that fixes the symmetric orientations theta* by one scalar equation;
* near theta*, the base moments are small but not zero: every member continues to the
  perturbed pose (with the d-mode it reaches on that side of the boundary);
* completeness against the independent multi-start oracle at two symmetric poses.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

import flexkin
from flexkin.mechanism import symmetric_mechanism

import ik_oracle as O

R_BASE, R_PLATFORM, L = 1.0, 0.25, 1.0


def chord_ratio(k):
    m = k * k
    return 2.0 * ellipe(m) / ellipk(m) - 1.0


def zero_moment(sol, tol=1e-7):
    return max(abs(r.base_moment) for r in sol.rods) < tol


def forces(sol):
    return np.array([np.hypot(*r.tip_force) for r in sol.rods])


# ---------------------------------------------------------------------------------------------
# unit 3-RFR at (0, 0, 0)
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def rfr_centre():
    return flexkin.ik(symmetric_mechanism("revolute"), (0.0, 0.0, 0.0), max_mode=2)


def test_rfr_every_buckled_family_with_both_members(rfr_centre):
    c = (R_BASE - R_PLATFORM) / L
    ks = np.linspace(1e-6, 1 - 1e-12, 20001)
    f = np.abs(chord_ratio(ks)) - c
    n_roots = int(np.sum(np.sign(f[:-1]) != np.sign(f[1:])))
    assert n_roots == 2  # chord 0.75 ahead of the clamp, and behind it (a loop)
    fam = [s for s in rfr_centre.solutions if zero_moment(s)]
    by_mode = {m: [s for s in fam if s.modes == m] for m in ((1, 1, 1), (2, 2, 2))}
    assert len(by_mode[(1, 1, 1)]) == 8 * n_roots
    assert len(by_mode[(2, 2, 2)]) == 8 * n_roots
    assert len(fam) == 16 * n_roots  # no mixed families: the radial forces would not balance
    for s in by_mode[(1, 1, 1)]:
        partners = [t for t in by_mode[(2, 2, 2)] if np.allclose(t.inputs, s.inputs, atol=1e-8)]
        assert len(partners) == 1, s.inputs
        np.testing.assert_allclose(forces(partners[0]) / forces(s), 4.0, rtol=1e-6)
        # tangents 2 arcsin(k) off the chord, k from the classical chord relation
        k = abs(s.rods[0].k)
        assert abs(abs(chord_ratio(k)) - c) < 1e-7


def test_rfr_base_inflection_rods_flagged_and_labelled_by_convention(rfr_centre):
    """A base moment of zero is an inflection at the clamp: SPEC §2 does not count it, and the
    rod carries ``mode_boundary`` in the JSON."""
    fam = [s for s in rfr_centre.solutions if zero_moment(s)]
    assert fam
    for s in fam:
        d = s.to_dict()
        for rod, rd in zip(s.rods, d["rods"]):
            assert rod.mode_boundary and rd["mode_boundary"] is True
        # first buckled shape: one inflection (at the tip); second: one inside + the tip
        assert s.modes in ((1, 1, 1), (2, 2, 2))
    # and only those: a rod with a clearly non-zero base moment is not on a boundary
    rods = [r for s in rfr_centre.solutions for r in s.rods]
    assert all(r.mode_boundary == (abs(r.base_moment) < 1e-6) for r in rods)
    assert any(abs(r.base_moment) > 1e-2 for r in rods)


# ---------------------------------------------------------------------------------------------
# unit 3-PFR at its symmetric buckled orientations theta*
# ---------------------------------------------------------------------------------------------
def _pfr_mismatch(theta):
    """Chord through the centre from leg 1's guide (y = -1/2, tangent along +x) to the attach
    point at angle 210 deg + theta; the tangent-chord angle beta = 30 deg + theta = 2 arcsin k."""
    beta = math.radians(30.0) + theta
    k = math.sin(beta / 2)
    return 0.5 / math.sin(beta) - R_PLATFORM - L * chord_ratio(k)


def _pfr_thetas():
    th = np.linspace(-0.5, 2.5, 601)
    v = np.array([_pfr_mismatch(t) for t in th])
    return [brentq(_pfr_mismatch, th[i], th[i + 1], xtol=1e-15)
            for i in range(len(th) - 1) if np.sign(v[i]) != np.sign(v[i + 1]) and abs(v[i]) < 1]


PFR_THETAS = _pfr_thetas()


def test_pfr_symmetric_orientations_exist():
    assert len(PFR_THETAS) == 2


@pytest.mark.parametrize("theta", PFR_THETAS, ids=lambda t: f"theta*={math.degrees(t):.3f}deg")
def test_pfr_both_buckled_members(theta):
    res = flexkin.ik(symmetric_mechanism("prismatic"), (0.0, 0.0, theta), max_mode=2)
    fam = [s for s in res.solutions if zero_moment(s)]
    assert sorted(s.modes for s in fam) == [(1, 1, 1), (2, 2, 2)]
    a, b = sorted(fam, key=lambda s: s.modes)
    beta = math.radians(30.0) + theta
    # the guide point A = (-0.5 cot(beta), -0.5) on the chord through the centre; u = A_x - V_x
    u = -0.5 / math.tan(beta) + R_BASE * math.cos(math.radians(30.0))
    np.testing.assert_allclose(a.inputs, u, atol=1e-8)
    np.testing.assert_allclose(b.inputs, a.inputs, atol=1e-9)
    np.testing.assert_allclose(forces(b) / forces(a), 4.0, rtol=1e-6)


@pytest.mark.parametrize("delta", [1e-3, -1e-3, 1e-6, -1e-6])
@pytest.mark.parametrize("theta", PFR_THETAS, ids=lambda t: f"theta*={math.degrees(t):.3f}deg")
def test_pfr_near_boundary_families_found(theta, delta):
    """Off theta* the base moments are small but not zero (|m0| ~ delta): each buckled member
    continues, on one side with its base inflection moved inside the rod (one d-mode more).
    Searching up to d-mode 3, each must be found within O(delta), matched by inputs and forces."""
    mech = symmetric_mechanism("prismatic")
    fam = [s for s in flexkin.ik(mech, (0.0, 0.0, theta), max_mode=2).solutions if zero_moment(s)]
    near = flexkin.ik(mech, (0.0, 0.0, theta + delta), max_mode=3).solutions

    def key(s):
        return np.concatenate([s.inputs, forces(s) / np.max(forces(s))])

    K = np.array([key(s) for s in near])
    for s in fam:
        d = np.min(np.max(np.abs(K - key(s)), axis=1))
        assert d < 500 * abs(delta), (s.modes, d)
    small = [min(abs(r.base_moment) for r in s.rods) for s in near]
    assert 0 < min(small) < 200 * abs(delta)  # the family really sits next to the boundary


# ---------------------------------------------------------------------------------------------
# completeness against the independent oracle at symmetric poses
# ---------------------------------------------------------------------------------------------
ORACLE_QUICK = dict(n_starts=400, scan=(160, 320), max_triples=2000, seed=1)


@pytest.mark.parametrize("kind, theta", [("revolute", 0.0), ("prismatic", PFR_THETAS[0])],
                         ids=["3RFR-(0,0,0)", "3PFR-(0,0,theta*)"])
def test_completeness_at_symmetric_pose(kind, theta):
    mech = symmetric_mechanism(kind)
    pose = (0.0, 0.0, theta)
    flex = flexkin.ik(mech, pose, max_mode=2).solutions
    oracle = O.oracle_ik(mech, pose, load=(0.0, 0.0, 0.0), max_mode=2, **ORACLE_QUICK)
    assert oracle
    F = np.array([np.concatenate([s.inputs, np.ravel([r.tip_force for r in s.rods])]) for s in flex])
    scale = np.concatenate([np.ones(3), np.full(6, max(1.0, np.max(np.abs(F[:, 3:]))))])
    missed = []
    for o in oracle:
        if o.extreme:
            continue  # beyond flexkin's documented k' >= 1e-7 scope
        key = np.concatenate([o.inputs, np.ravel([r.tip_force for r in o.rods])])
        diff = F - key
        if kind == "revolute":  # input angles compared modulo 2 pi
            diff[:, :3] = np.angle(np.exp(1j * diff[:, :3]))
        if np.min(np.max(np.abs(diff) / scale, axis=1)) > 1e-5:
            missed.append((o.modes, o.inputs))
    assert not missed, f"flexkin misses {len(missed)} of {len(oracle)} oracle solutions: {missed[:5]}"
