"""flexkin's one ODE stepper (flexkin.core.dop853) against scipy's public DOP853.

The compiled step functions are called from Python here, with a Python right-hand side, and
drive Hairer's step-size control exactly as :func:`scipy.integrate.solve_ivp` does: the
accepted steps and the states must then be those of ``solve_ivp(method="DOP853")`` with the
same first step and tolerances.  That checks every coefficient of the table (``A``, ``B``, ``C``
through a time component, ``E3``, ``E5``) and the stepper's arithmetic, against scipy's public
interface only.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from flexkin.core import dop853 as d


def forced_pendulum(t, y):
    """th'' = -sin th - 0.1 th' + 0.3 cos(1.3 t): smooth, non-autonomous."""
    return np.array([y[1], -math.sin(y[0]) - 0.1 * y[1] + 0.3 * math.cos(1.3 * t)])


def _autonomous(u, out):
    """The same with the time as a third state (t' = 1), as the compiled stepper takes it."""
    out[:2] = forced_pendulum(u[2], u[:2])
    out[2] = 1.0


def flexkin_dop853(y0, t_end, first_step, rtol, atol, max_step=np.inf):
    """Accepted times and states of an integration by flexkin's compiled step functions."""
    n = 3
    u = np.array([*y0, 0.0])
    K = np.zeros((d.STAGES, n))
    ut = np.empty(n)
    un = np.empty(n)
    ts, ys = [0.0], [u[:2].copy()]
    t, h_abs = 0.0, first_step
    _autonomous(u, K[0])
    while t < t_end:   # scipy's step loop (time kept apart, as scipy does: t_new = t + h)
        h_abs = min(h_abs, max_step)
        rejected = False
        while True:
            t_new = min(t + h_abs, t_end)
            h = t_new - t
            for s in range(1, d.STAGES):
                d.stage_state(s, u, h, K, ut, n)
                _autonomous(ut, K[s])
            d.advance(u, h, K, un, n)
            # scipy's error scale covers the pendulum's two states; the time component's
            # estimate is exactly zero (t' = 1 is integrated exactly), so it adds nothing
            err = d.error_norm(u[:2], un[:2], h, K[:, :2].copy(), rtol, atol, 2)
            fac = d.step_factor(err, rejected)
            h_abs = h * fac
            if err < 1.0:
                break
            rejected = True
        t = t_new
        u[:2] = un[:2]
        u[2] = t
        _autonomous(u, K[0])
        ts.append(t)
        ys.append(u[:2].copy())
    return np.array(ts), np.array(ys)


def test_table_order_conditions():
    assert d.A.shape == (d.STAGES, d.STAGES) and np.all(np.triu(d.A) == 0.0)
    assert np.allclose(d.A.sum(1), d.C, atol=1e-14)
    for k in range(8):  # quadrature conditions of an 8th-order method: b . c^k = 1/(k+1)
        assert abs(d.B @ d.C**k - 1.0 / (k + 1)) < 1e-13
    # the error estimators are differences of two consistent methods
    assert abs(d.E5.sum()) < 1e-13 and abs(d.E3.sum()) < 1e-13


def test_fixed_steps_equal_scipy():
    """With loose tolerances every step is accepted at max_step: the 8th-order propagation
    (A, B, C) alone, step by step."""
    h, y0, t_end = 0.25, (0.3, 0.0), 5.0
    ref = solve_ivp(forced_pendulum, (0.0, t_end), y0, method="DOP853", first_step=h, max_step=h, rtol=1.0,
                    atol=1e6)
    ts, ys = flexkin_dop853(y0, t_end, h, 1.0, 1e6, max_step=h)
    assert len(ts) == len(ref.t) == 21
    assert np.allclose(ts, ref.t, rtol=0, atol=1e-14)
    assert np.max(np.abs(ys - ref.y.T)) < 1e-13


@pytest.mark.parametrize("tol", [1e-5, 1e-8, 1e-11])
def test_adaptive_steps_equal_scipy(tol):
    """Same first step and tolerances: the same accepted steps (the error estimators E3, E5 and
    the step-size control) and the same states.

    The error estimate is a small difference of O(1) stage sums, so rounding alone moves a step
    size by up to ~1e-6 relative when the error norm is far below 1; a wrong estimator
    coefficient changes the error norm by a large factor (the same cancellation), and so the
    steps by far more."""
    y0, t_end, h0 = (2.5, 0.4), 20.0, 0.01
    ref = solve_ivp(forced_pendulum, (0.0, t_end), y0, method="DOP853", first_step=h0, rtol=tol, atol=tol,
                    dense_output=True)
    ts, ys = flexkin_dop853(y0, t_end, h0, tol, tol)
    assert ref.status == 0 and len(ts) == len(ref.t) > 10
    assert np.allclose(ts, ref.t, rtol=1e-6, atol=0)
    # the states at our (nearly the same) times, from scipy's own interpolant
    assert np.max(np.abs(ys - ref.sol(ts).T)) < 1e-12
