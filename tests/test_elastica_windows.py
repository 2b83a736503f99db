"""Clamped rods as windows of elastica orbits (``flexkin.rod.elastica``) against independent checks.

* where both are well conditioned, a window evaluates to the same rod as the wrench chart
  (:func:`flexkin.rod.elastica.window_of` converts one into the other): tip, tip angle (the
  total turning, windings included), force, end moments, energy;
* the analytic derivatives with respect to ``(v, u_s, u_e)`` against central differences;
* taut rods (``lambda L`` from 12 to 60, the orbit passing close to the saddle, where shooting
  from the clamp loses ``exp(lambda L)``): the sampled window profile obeys the rod's ODE
  (Eqs. 5, 7) piece by piece (multiple shooting with DOP853 over 1/80 of the rod, each piece
  started from the profile), its end is the kernel's tip, and the tip moment and the energy
  agree with the profile's.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from flexkin.rod.elastica import window_of
from flexkin.rod.kernels import (CHART_LIB, CHART_ROT, CHART_WRENCH, EN, FX, FY, M0, ML, NQ, PHI, TH, X, Y,
                                 clamped_mode, clamped_peak, eval_rod, profile)


def evaluate(chart, z):
    q, g = np.empty(NQ), np.empty((NQ, 3))
    eval_rod(chart, np.asarray(z, float), q, g)
    return q, g


def random_wrenches(n, seed, lam_max=6.0):
    rng = np.random.default_rng(seed)
    lam = rng.uniform(0.3, lam_max, n)
    psi = rng.uniform(0.0, 2 * np.pi, n)
    m0 = rng.uniform(-1.0, 1.0, n) * (2 * lam + 6.0)
    return np.stack([lam**2 * np.cos(psi), lam**2 * np.sin(psi), m0], 1)


def window(z):
    rot, v, us, ue = window_of(*z)
    return (CHART_ROT if rot else CHART_LIB), np.array([v, us, ue])


def test_windows_are_the_wrench_charts_rods():
    for z in random_wrenches(400, 0):
        qw, _ = evaluate(CHART_WRENCH, z)
        chart, w = window(z)
        q, _ = evaluate(chart, w)
        for slot in (X, Y, TH, FX, FY, M0, ML, EN, PHI):
            assert q[slot] == pytest.approx(qw[slot], rel=1e-11, abs=1e-11), (slot, z, chart)
        assert clamped_mode(chart, w, 1e-9) == clamped_mode(CHART_WRENCH, z, 1e-9)


def test_window_derivatives_match_central_differences():
    for z in random_wrenches(150, 1):
        chart, w = window(z)
        q, g = evaluate(chart, w)
        for j in range(3):
            h = 1e-6 * (1.0 + abs(w[j]))
            wp, wm = w.copy(), w.copy()
            wp[j] += h
            wm[j] -= h
            fd = (evaluate(chart, wp)[0] - evaluate(chart, wm)[0]) / (2 * h)
            np.testing.assert_allclose(g[:, j], fd, rtol=1e-6, atol=1e-6 * (1 + np.abs(q).max()))


def rhs(R_vec):
    fx, fy = R_vec

    def f(s, y):
        return [math.cos(y[2]), math.sin(y[2]), y[3], fx * math.sin(y[2]) - fy * math.cos(y[2])]
    return f


TAUT = [  # (chart, v, u_s, u_e): orbits through the saddle, lambda L = u_e - u_s (libration)
    (CHART_LIB, 8.0, -2.0, 10.0),
    (CHART_LIB, 12.0, 1.0, 21.0),
    (CHART_LIB, 16.0, 2.5, 32.5),
    (CHART_LIB, 30.0, -5.0, 55.0),
    (CHART_ROT, 10.0, -3.0, 12.0),
    (CHART_ROT, 14.0, 1.0, -19.0),
]


@pytest.mark.parametrize("chart, v, us, ue", TAUT)
def test_taut_windows_obey_the_rod_equations(chart, v, us, ue):
    w = np.array([v, us, ue])
    q, _ = evaluate(chart, w)
    lam = q[PHI]
    assert lam > 11.0
    n = 80
    s = np.linspace(0.0, 1.0, n + 1)
    prof = np.empty((n + 1, 4))
    profile(chart, w, s, prof)
    assert np.all(np.isfinite(prof))
    f = rhs((q[FX], q[FY]))
    for j in range(n):
        sol = solve_ivp(f, (s[j], s[j + 1]), prof[j], method="DOP853", rtol=1e-12, atol=1e-12)
        end = sol.y[:, -1]
        scale = 1.0 + abs(prof[j + 1, 3])
        assert abs(end[0] - prof[j + 1, 0]) < 1e-8 and abs(end[1] - prof[j + 1, 1]) < 1e-8, (j, end, prof[j + 1])
        assert abs(end[2] - prof[j + 1, 2]) < 1e-8 and abs(end[3] - prof[j + 1, 3]) < 1e-8 * scale, j
    # the profile's ends are the kernel's clamp and tip
    assert prof[0, :3] == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    assert prof[-1, 0] == pytest.approx(q[X], abs=1e-10) and prof[-1, 1] == pytest.approx(q[Y], abs=1e-10)
    assert prof[-1, 2] == pytest.approx(q[TH], abs=1e-10)
    assert prof[0, 3] == pytest.approx(q[M0], rel=1e-9, abs=1e-9)
    assert prof[-1, 3] == pytest.approx(q[ML], rel=1e-9, abs=1e-9)
    # energy: (1/2) int m^2 (a fine trapezoid of the profile)
    sf = np.linspace(0.0, 1.0, 20001)
    pf = np.empty((len(sf), 4))
    profile(chart, w, sf, pf)
    assert q[EN] == pytest.approx(0.5 * np.trapezoid(pf[:, 3] ** 2, sf), rel=1e-6)
    # the closed-form peak curvature is the profile's
    assert clamped_peak(chart, w) == pytest.approx(np.max(np.abs(pf[:, 3])), rel=1e-6)
    # a taut rod is nearly straight along its force: the tip is within O(1/lambda) of full reach
    assert math.hypot(q[X], q[Y]) > 1.0 - 8.0 / lam


def test_taut_windows_moves_only_taut_rods_and_keeps_them():
    """``taut_windows`` (the refinement's re-charting) moves a wrench-chart rod to its window only
    when its tip sensitivity to the base moment passes ``SENS_WINDOW``, and the window is the same
    rod."""
    from flexkin.rod.elastica import SENS_WINDOW, taut_windows, tip_sensitivity

    rng = np.random.default_rng(4)
    taut = []
    for _ in range(100):  # librating windows across a top, in their base wrench
        v, us = rng.uniform(4.0, 9.0), rng.uniform(-1.0, 1.0)
        q, _ = evaluate(CHART_LIB, [v, us, us + rng.uniform(6.0, 14.0)])
        taut.append([q[FX], q[FY], q[M0]])
    Z = np.concatenate([random_wrenches(100, 3), np.array(taut)])
    charts = np.full(len(Z), CHART_WRENCH, np.int64)
    Z0 = Z.copy()
    moved = taut_windows(charts, Z, CHART_WRENCH, CHART_LIB, CHART_ROT)
    sens = np.array([tip_sensitivity(evaluate(CHART_WRENCH, z)[1]) for z in Z0])
    assert moved == np.count_nonzero(charts != CHART_WRENCH) > 0
    np.testing.assert_array_equal(charts != CHART_WRENCH, sens > SENS_WINDOW)
    for c, z, z0 in zip(charts, Z, Z0):
        if c == CHART_WRENCH:
            np.testing.assert_array_equal(z, z0)
            continue
        q, _ = evaluate(c, z)
        qw, gw = evaluate(CHART_WRENCH, z0)
        # the wrench chart's own tip is only good to its sensitivity times the rounding of m0
        tol = 1e-12 * (1.0 + tip_sensitivity(gw)) * (1.0 + abs(z0[2]))
        assert abs(q[X] - qw[X]) < tol and abs(q[Y] - qw[Y]) < tol and abs(q[TH] - qw[TH]) < tol
        assert q[FX] == pytest.approx(z0[0], rel=1e-12, abs=1e-12) and q[M0] == pytest.approx(z0[2], rel=1e-9, abs=1e-9)
