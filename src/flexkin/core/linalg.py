"""Small dense linear algebra inside compiled loops (numba, ``cache=True``): flexkin's one LU.

The Newton and continuation systems are 9x9 to 12x12 (and the Cosserat refinement's a few
tens): Gaussian elimination with partial pivoting written out is several times faster there
than a LAPACK call per candidate, and it runs without BLAS threads.  :func:`eliminate` is the
one factorisation; the right-hand side rides along as an extra column (the multipliers are not
kept).  On top of it:

* :func:`solve_into`: the solvers' solve, where a numerically singular matrix falls back to
  the minimum-norm least-squares solution (LAPACK ``gelsd`` through ``np.linalg.lstsq``), the
  behaviour the solvers rely on near chart poles and singularities;
* :func:`lu_solve`, :func:`det_sign`, :func:`pivot_ratio`: exact-zero pivots only, with the
  sign of the determinant and a cheap near-singularity indicator (the Cosserat continuation).
"""

from __future__ import annotations

import numpy as np
from .jit import njit

__all__ = ["eliminate", "back_substitute", "solve_into", "lu_solve", "det_sign", "pivot_ratio"]

#: relative pivot below which :func:`solve_into` counts a matrix as singular
PIVOT_RTOL = 1e-13


@njit(cache=True)
def eliminate(M: np.ndarray, p: int, tiny: float) -> float:
    """Reduce the leading ``p x p`` block of ``M`` (``p`` rows) to upper-triangular form in place,
    by Gaussian elimination with partial (row) pivoting; the further columns of ``M`` (e.g. a
    right-hand side) are transformed along.  Returns the sign of the row permutation (+1.0 or
    -1.0), or 0.0 when a pivot is at most ``tiny`` (``M`` is then only partly reduced).  The
    entries below the diagonal are left as they are (not zeroed)."""
    ncol = M.shape[1]
    sign = 1.0
    for k in range(p):
        piv = k
        best = abs(M[k, k])
        for i in range(k + 1, p):
            v = abs(M[i, k])
            if v > best:
                best = v
                piv = i
        if best <= tiny:
            return 0.0
        if piv != k:
            for j in range(k, ncol):
                t = M[k, j]
                M[k, j] = M[piv, j]
                M[piv, j] = t
            sign = -sign
        inv = 1.0 / M[k, k]
        for i in range(k + 1, p):
            f = M[i, k] * inv
            if f != 0.0:
                for j in range(k + 1, ncol):
                    M[i, j] -= f * M[k, j]
    return sign


@njit(cache=True)
def back_substitute(M: np.ndarray, p: int, x: np.ndarray) -> None:
    """``x`` from the upper-triangular ``M[:, :p]`` and the right-hand side ``M[:, p]`` left by
    :func:`eliminate`."""
    for i in range(p - 1, -1, -1):
        s = M[i, p]
        for j in range(i + 1, p):
            s -= M[i, j] * x[j]
        x[i] = s / M[i, i]


@njit(cache=True)
def solve_into(A: np.ndarray, b: np.ndarray, x: np.ndarray, work: np.ndarray) -> bool:
    """Solve ``A x = b`` (``A`` (p, p), not modified); ``work`` is (p, p + 1) scratch.

    Returns ``True`` when LU with partial pivoting succeeded, ``False`` when the
    minimum-norm least-squares solution was used instead (a pivot at most ``PIVOT_RTOL``
    times the largest entry, or non-finite ``A``; then ``x`` holds NaN if ``A`` was not finite).
    """
    p = A.shape[0]
    scale = 0.0
    finite = True
    for i in range(p):
        for j in range(p):
            a = A[i, j]
            work[i, j] = a
            if not np.isfinite(a):
                finite = False
            elif abs(a) > scale:
                scale = abs(a)
        work[i, p] = b[i]
    if not finite:
        x[:] = np.nan
        return False
    if scale > 0.0 and eliminate(work, p, PIVOT_RTOL * scale) != 0.0:
        back_substitute(work, p, x)
        return True
    sol = np.linalg.lstsq(A.copy(), b.copy(), rcond=PIVOT_RTOL)[0]
    for i in range(p):
        x[i] = sol[i]
    return False


@njit(cache=True)
def _diagonal_sign(M: np.ndarray, sign: float) -> float:
    for k in range(M.shape[0]):
        if M[k, k] < 0.0:
            sign = -sign
    return sign


@njit(cache=True)
def lu_solve(A: np.ndarray, b: np.ndarray):
    """Solve ``A x = b`` by LU with partial pivoting; returns ``(ok, x, sign of det A)``, with
    ``ok`` false for an exactly singular ``A`` (sign 0) or a non-finite ``x``."""
    n = A.shape[0]
    M = np.empty((n, n + 1))
    M[:, :n] = A
    M[:, n] = b
    x = np.empty(n)
    s = eliminate(M, n, 0.0)
    if s == 0.0:
        return False, x, 0.0
    back_substitute(M, n, x)
    sign = _diagonal_sign(M, s)
    for i in range(n):
        if not np.isfinite(x[i]):
            return False, x, sign
    return True, x, sign


@njit(cache=True)
def det_sign(A: np.ndarray) -> float:
    """Sign of ``det A`` (0.0 if exactly singular)."""
    M = A.copy()
    s = eliminate(M, A.shape[0], 0.0)
    return 0.0 if s == 0.0 else _diagonal_sign(M, s)


@njit(cache=True)
def pivot_ratio(A: np.ndarray) -> float:
    """``min |U_kk| / max |U_kk|`` of the pivoted LU: a cheap indicator of near-singularity."""
    M = A.copy()
    if eliminate(M, A.shape[0], 0.0) == 0.0:
        return 0.0
    lo = np.inf
    hi = 0.0
    for k in range(A.shape[0]):
        v = abs(M[k, k])
        lo = min(lo, v)
        hi = max(hi, v)
    return lo / hi
