"""The deflated Newton of :mod:`flexkin.solve.corrector` (Farrell, Birkisson & Funke 2015).

* Its step is the Newton step of the deflated residual ``G = M F``, whose Jacobian is taken here by
  central finite differences (independent of the Sherman-Morrison form the kernel uses).
* It never returns a deflated root, and what it converges to is an equilibrium.
* From a start that led to one root it finds another.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import flexkin
from flexkin.solve.corrector import default_cap, newton
from flexkin.system import System

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
POSE = (0.01, 0.02, 0.05)


@pytest.fixture(scope="module")
def case():
    mech = flexkin.load_mechanism(EXAMPLES / "unit_3rfr.toml")
    res = flexkin.ik(mech, POSE)
    assert len(res.solutions) >= 4
    return mech, System.from_mechanism(mech), res


def _deflated_residual(system, x, charts, roots, cols, cap):
    """``G = M F`` with ``M = prod (1/|x - r|^2 + 1)`` (distances over ``cols`` divided by ``cap``)."""
    F = system.residual(x[None], charts[None], np.zeros(3))[0]
    M = 1.0
    for r in roots:
        e = (x[cols] - r[cols]) / cap
        M *= 1.0 / (e @ e) + 1.0
    return M * F


def test_deflated_step_is_the_newton_step_of_the_deflated_residual(case):
    """One kernel iteration from near a root moves along ``-J_G^-1 G`` (finite-difference ``J_G``);
    the line search may halve it, so the move is that step times a power of 1/2."""
    mech, system, res = case
    lay = system.layout
    cols = lay.columns("pose")
    cap = default_cap(system, "pose")
    a, b = res.solutions[0], res.solutions[1]
    x0 = a.x + 0.02 * (b.x - a.x)  # next to a root, deflating it: the step turns away from it
    charts = a.charts
    roots = a.x[None]
    out = newton(system, x0[None], charts[None], np.zeros(3), "pose", max_iter=1, merge_after=None,
                 deflate=(roots[None], np.array([1])))
    moved = (out.x[0] - x0)[cols]
    G0 = _deflated_residual(system, x0, charts, roots, cols, cap)
    JG = np.empty((len(cols), len(cols)))
    for c, col in enumerate(cols):
        h = 1e-6 * max(1.0, abs(x0[col]))
        xp, xm = x0.copy(), x0.copy()
        xp[col] += h
        xm[col] -= h
        JG[:, c] = (_deflated_residual(system, xp, charts, roots, cols, cap)
                    - _deflated_residual(system, xm, charts, roots, cols, cap)) / (2 * h)
    step = np.linalg.solve(JG, -G0)
    assert moved @ (a.x - x0)[cols] < 0  # away from the deflated root, where the plain step goes
    scale = max(1.0, np.max(np.abs(step) / cap))  # the kernel's cap on the step
    ratio = moved @ step / (step @ step) * scale
    assert np.linalg.norm(moved - (ratio / scale) * step) <= 1e-5 * np.linalg.norm(moved)
    assert np.isclose(np.log2(ratio), np.round(np.log2(ratio)), atol=1e-5) and ratio <= 1.0 + 1e-6


def test_deflated_newton_never_returns_a_deflated_root(case):
    """Starts next to every solution, each deflated by all of them: whatever converges is an
    equilibrium (residual below 1e-10) and none of the deflated ones."""
    mech, system, res = case
    X = np.array([s.x for s in res.solutions])
    C = np.array([s.charts for s in res.solutions])
    rng = np.random.default_rng(0)
    starts = X + 1e-3 * rng.standard_normal(X.shape) * system.unknown_scale()
    starts[:, system.layout.pose] = X[:, system.layout.pose]
    n = len(X)
    roots = np.broadcast_to(X, (n,) + X.shape).copy()
    out = newton(system, starts, C, np.zeros(3), "pose", merge_after=None,
                 deflate=(roots, np.full(n, n)))
    ok = out.residual <= 1e-10
    for x in out.x[ok]:
        assert np.min(np.max(np.abs(X - x) / system.unknown_scale(), axis=1)) > 1e-6
    assert np.all(np.max(np.abs(system.residual(out.x[ok], out.charts[ok], np.zeros(3))), axis=1) <= 1e-10)


def test_deflation_finds_a_second_root_from_one_start(case):
    """From a start that the plain Newton takes to a root, the deflated Newton reaches another
    equilibrium, for at least one of the starts between pairs of solutions."""
    mech, system, res = case
    sols = res.solutions
    found = 0
    for a in sols:
        for b in sols:
            if a is b or np.any(a.charts != b.charts):
                continue
            x0 = a.x + 0.25 * (b.x - a.x)
            plain = newton(system, x0[None], a.charts[None], np.zeros(3), "pose", merge_after=None)
            if not plain.residual[0] <= 1e-10:
                continue
            r = plain.x[0]
            out = newton(system, x0[None], a.charts[None], np.zeros(3), "pose", merge_after=None,
                         deflate=(r[None, None], np.array([1])))
            if out.residual[0] <= 1e-10:
                assert np.max(np.abs(out.x[0] - r) / system.unknown_scale()) > 1e-6
                found += 1
    assert found >= 1
