"""Small dense linear algebra compiled with numba (no BLAS threads for the many tiny systems)."""

from __future__ import annotations

import numpy as np
from ..core.jit import njit

__all__ = ["lu_solve", "det_sign", "pivot_ratio"]


@njit(cache=True)
def _lu(A):
    n = A.shape[0]
    LU = A.copy()
    piv = np.arange(n)
    sign = 1.0
    for k in range(n):
        p = k
        big = abs(LU[k, k])
        for i in range(k + 1, n):
            v = abs(LU[i, k])
            if v > big:
                big = v
                p = i
        if big == 0.0:
            return LU, piv, 0.0
        if p != k:
            for j in range(n):
                t = LU[k, j]
                LU[k, j] = LU[p, j]
                LU[p, j] = t
            t2 = piv[k]
            piv[k] = piv[p]
            piv[p] = t2
            sign = -sign
        inv = 1.0 / LU[k, k]
        for i in range(k + 1, n):
            f = LU[i, k] * inv
            LU[i, k] = f
            if f != 0.0:
                for j in range(k + 1, n):
                    LU[i, j] -= f * LU[k, j]
    for k in range(n):
        if LU[k, k] < 0.0:
            sign = -sign
    return LU, piv, sign


@njit(cache=True)
def lu_solve(A, b):
    """Solve ``A x = b`` by LU with partial pivoting; returns ``(ok, x, sign of det A)``."""
    n = A.shape[0]
    LU, piv, sign = _lu(A)
    x = np.empty(n)
    if sign == 0.0:
        return False, x, 0.0
    for i in range(n):
        x[i] = b[piv[i]]
    for i in range(n):
        acc = x[i]
        for j in range(i):
            acc -= LU[i, j] * x[j]
        x[i] = acc
    for i in range(n - 1, -1, -1):
        acc = x[i]
        for j in range(i + 1, n):
            acc -= LU[i, j] * x[j]
        x[i] = acc / LU[i, i]
    for i in range(n):
        if not np.isfinite(x[i]):
            return False, x, sign
    return True, x, sign


@njit(cache=True)
def det_sign(A):
    """Sign of ``det A`` (0.0 if exactly singular)."""
    return _lu(A)[2]


@njit(cache=True)
def pivot_ratio(A):
    """``min |U_kk| / max |U_kk|`` of the pivoted LU: a cheap indicator of near-singularity."""
    LU, _, sign = _lu(A)
    if sign == 0.0:
        return 0.0
    lo = np.inf
    hi = 0.0
    for k in range(A.shape[0]):
        v = abs(LU[k, k])
        lo = min(lo, v)
        hi = max(hi, v)
    return lo / hi
