"""flexkin's one small dense LU (flexkin.core.linalg) against numpy's LAPACK routines."""

from __future__ import annotations

import numpy as np
import pytest

from flexkin.core.linalg import det_sign, lu_solve, pivot_ratio, solve_into


@pytest.mark.parametrize("p", [1, 3, 9, 12, 40])
def test_solves_like_lapack(p):
    rng = np.random.default_rng(p)
    for _ in range(20):
        A = rng.normal(size=(p, p))
        b = rng.normal(size=p)
        want = np.linalg.solve(A, b)
        x = np.empty(p)
        assert solve_into(A, b, x, np.empty((p, p + 1)))
        tol = 1e-12 * np.linalg.cond(A) * max(1.0, np.max(np.abs(want)))
        assert np.max(np.abs(x - want)) < tol
        ok, x2, sign = lu_solve(A, b)
        assert ok and np.max(np.abs(x2 - want)) < tol
        assert sign == det_sign(A) == np.sign(np.linalg.det(A))
        s = np.linalg.svd(A, compute_uv=False)
        assert 0.0 < pivot_ratio(A) <= 1.0 and pivot_ratio(A) >= s[-1] / s[0] / p ** 2


def test_the_input_is_not_modified():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(6, 6))
    b = rng.normal(size=6)
    A0, b0 = A.copy(), b.copy()
    solve_into(A, b, np.empty(6), np.empty((6, 7)))
    lu_solve(A, b)
    det_sign(A)
    pivot_ratio(A)
    assert np.array_equal(A, A0) and np.array_equal(b, b0)


def test_singular_and_non_finite():
    A = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [1.0, 0.0, 1.0]])  # rank 2
    b = np.array([1.0, 2.0, 0.5])                                      # consistent
    x = np.empty(3)
    assert not solve_into(A, b, x, np.empty((3, 4)))   # falls back to least squares ...
    assert np.allclose(x, np.linalg.lstsq(A, b, rcond=None)[0])  # ... minimum norm
    Z = np.zeros((3, 3))
    assert not solve_into(Z, b, x, np.empty((3, 4))) and np.array_equal(x, np.zeros(3))
    assert det_sign(Z) == 0.0 and pivot_ratio(Z) == 0.0 and not lu_solve(Z, b)[0]
    N = np.eye(3)
    N[1, 2] = np.nan
    assert not solve_into(N, b, x, np.empty((3, 4))) and np.all(np.isnan(x))
    assert not lu_solve(N, b)[0]
