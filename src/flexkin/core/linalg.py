"""Small dense linear algebra inside compiled loops (numba, ``cache=True``).

The Newton and continuation systems are 9x9 to 12x12: LU with partial pivoting written out
is several times faster there than a LAPACK call per candidate, and a numerically singular
matrix falls back to the minimum-norm least-squares solution (LAPACK ``gelsd`` through
``np.linalg.lstsq``), the behaviour the solvers rely on near chart poles and singularities.
"""

from __future__ import annotations

import numpy as np
from .jit import njit

__all__ = ["solve_into"]

#: relative pivot below which a matrix counts as singular
PIVOT_RTOL = 1e-13


@njit(cache=True)
def solve_into(A: np.ndarray, b: np.ndarray, x: np.ndarray, work: np.ndarray) -> bool:
    """Solve ``A x = b`` (``A`` (p, p), not modified); ``work`` is (p, p + 1) scratch.

    Returns ``True`` when LU with partial pivoting succeeded, ``False`` when the
    minimum-norm least-squares solution was used instead (singular or non-finite ``A``; then
    ``x`` may hold NaN if ``A`` was not finite).
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
    ok = scale > 0.0
    for k in range(p):
        if not ok:
            break
        piv = k
        best = abs(work[k, k])
        for i in range(k + 1, p):
            if abs(work[i, k]) > best:
                best = abs(work[i, k])
                piv = i
        if best <= PIVOT_RTOL * scale:
            ok = False
            break
        if piv != k:
            for j in range(k, p + 1):
                t = work[k, j]
                work[k, j] = work[piv, j]
                work[piv, j] = t
        inv = 1.0 / work[k, k]
        for i in range(k + 1, p):
            f = work[i, k] * inv
            if f != 0.0:
                for j in range(k + 1, p + 1):
                    work[i, j] -= f * work[k, j]
    if ok:
        for i in range(p - 1, -1, -1):
            s = work[i, p]
            for j in range(i + 1, p):
                s -= work[i, j] * x[j]
            x[i] = s / work[i, i]
        return True
    sol = np.linalg.lstsq(A.copy(), b.copy(), rcond=PIVOT_RTOL)[0]
    for i in range(p):
        x[i] = sol[i]
    return False
