"""Batch damped Newton with finite-difference Jacobians (shared by every solver).

One Newton implementation serves the single-rod problem, the inverse and forward
kinematics and the path/workspace continuation: each of them supplies a vectorised
residual ``f(Z) -> (n, p)`` for ``n`` independent candidates with ``p`` unknowns and
``p`` equations, and an optional ``project(Z)`` that maps iterates back into the chart.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["NewtonResult", "batch_newton", "fd_jacobian", "solve_batch"]

Residual = Callable[[NDArray[np.float64]], NDArray[np.float64]]


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of :func:`batch_newton` for ``n`` candidates.

    Attributes
    ----------
    z : (n, p) final iterates.
    residual : (n,) infinity norm of the residual at ``z``.
    converged : (n,) bool, residual below the tolerance.
    iterations : (n,) iterations used.
    """

    z: NDArray[np.float64]
    residual: NDArray[np.float64]
    converged: NDArray[np.bool_]
    iterations: NDArray[np.int64]


def fd_jacobian(f: Residual, z: NDArray[np.float64], step: NDArray[np.float64] | float = 1e-7) -> NDArray[np.float64]:
    """Central-difference Jacobian of a batch residual, shape ``(n, p_out, p_in)``.

    All ``2 p`` perturbed copies are evaluated in one call of ``f``.
    """
    z = np.atleast_2d(np.asarray(z, dtype=float))
    n, p = z.shape
    h = np.broadcast_to(np.asarray(step, dtype=float), (p,)) * np.maximum(1.0, np.abs(z))
    eye = np.eye(p)
    zz = np.concatenate([z[:, None, :] + h[..., None] * eye, z[:, None, :] - h[..., None] * eye], axis=1)
    # h has shape (n, p); h[..., None] * eye -> (n, p, p)
    vals = f(zz.reshape(n * 2 * p, p)).reshape(n, 2 * p, -1)
    diff = (vals[:, :p, :] - vals[:, p:, :]) / (2.0 * h[:, :, None])
    return np.swapaxes(diff, 1, 2)


def batch_newton(
    f: Residual,
    z0: NDArray[np.float64],
    *,
    tol: float = 1e-12,
    max_iter: int = 40,
    project: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
    max_step: NDArray[np.float64] | float | None = None,
    fd_step: float = 1e-7,
    merge_after: int | None = None,
    merge_tol: float = 1e-7,
) -> NewtonResult:
    """Solve ``f(z) = 0`` for many starting points at once.

    Damped Newton: the full step is tried first and halved (up to 8 times) until the
    residual norm decreases; ``max_step`` caps each component of a step; ``project`` maps
    iterates back into the admissible chart.  Non-finite residuals count as failures.

    Parameters
    ----------
    f : callable
        Vectorised residual, ``(m, p) -> (m, p)``; must return non-finite values (not
        raise) where it is undefined.
    z0 : (n, p) array
        Starting points.
    tol : float
        Convergence threshold on the infinity norm of the (scaled) residual.
    merge_after : int, optional
        From this iteration on, active candidates whose iterates coincide to ``merge_tol``
        (they converge to the same root) are merged: all but one are dropped and reported
        as not converged.  Saves the work of refining many starts of one root.
    """
    z = np.array(np.atleast_2d(z0), dtype=float)
    if project is not None:
        z = project(z)
    n, p = z.shape
    if n == 0:
        return NewtonResult(z, np.zeros(0), np.zeros(0, bool), np.zeros(0, np.int64))
    r = f(z)
    norm = _norm(r)
    iters = np.zeros(n, np.int64)
    active = norm > tol
    for it in range(max_iter):
        if merge_after is not None and it >= merge_after:
            idx = np.flatnonzero(active)
            if idx.size > 1:
                keys = np.round(z[idx] / merge_tol).astype(np.int64)
                _, first = np.unique(keys, axis=0, return_index=True)
                dup = np.ones(idx.size, bool)
                dup[first] = False
                active[idx[dup]] = False
                norm[idx[dup]] = np.inf
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        za, ra = z[idx], r[idx]
        J = fd_jacobian(f, za, fd_step)
        ok = np.all(np.isfinite(J), axis=(1, 2))
        step = np.zeros_like(za)
        if np.any(ok):
            step[ok] = _lstsq_batch(J[ok], -ra[ok])
        if max_step is not None:
            cap = np.broadcast_to(np.asarray(max_step, dtype=float), (p,))
            scale = np.max(np.abs(step) / cap, axis=1)
            step = step / np.maximum(scale, 1.0)[:, None]
        alpha = np.ones(idx.size)
        best_z, best_r, best_norm = za.copy(), ra.copy(), norm[idx].copy()
        pending = ok.copy()
        for _ls in range(9):
            if not np.any(pending):
                break
            cand = za[pending] + alpha[pending, None] * step[pending]
            if project is not None:
                cand = project(cand)
            rc = f(cand)
            nc = _norm(rc)
            better = nc < best_norm[pending]
            sel = np.flatnonzero(pending)[better]
            best_z[sel], best_r[sel], best_norm[sel] = cand[better], rc[better], nc[better]
            pending[np.flatnonzero(pending)[better]] = False
            alpha[pending] *= 0.5
        improved = best_norm < norm[idx]
        z[idx], r[idx], norm[idx] = best_z, best_r, best_norm
        iters[idx] += 1
        # stop candidates that converged, stalled, or failed to evaluate
        active[idx] = improved & (best_norm > tol) & ok
    return NewtonResult(z, norm, norm <= tol, iters)


def _norm(r: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.max(np.abs(r), axis=-1)
    return np.where(np.isfinite(out), out, np.inf)


def _lstsq_batch(J: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Solve ``J x = b`` per candidate; minimum-norm least squares where singular."""
    return solve_batch(J, b)


def solve_batch(J: NDArray[np.float64], b: NDArray[np.float64], rcond: float = 1e-13) -> NDArray[np.float64]:
    """Batched ``J x = b`` (J: (n, p, p)); falls back to a batched truncated SVD.

    Never loops in Python: singular or non-finite systems get the minimum-norm
    least-squares solution (rows of NaN/inf matrices give NaN).
    """
    try:
        x = np.linalg.solve(J, b[..., None])[..., 0]
        if np.all(np.isfinite(x)):
            return x
    except np.linalg.LinAlgError:
        pass
    finite = np.all(np.isfinite(J), axis=(1, 2)) & np.all(np.isfinite(b), axis=1)
    x = np.full(b.shape, np.nan)
    if np.any(finite):
        U, S, Vt = np.linalg.svd(J[finite])
        cut = S > rcond * S[:, :1]
        inv = np.where(cut, 1.0 / np.where(cut, S, 1.0), 0.0)
        c = np.einsum("nji,nj->ni", U, b[finite]) * inv
        x[finite] = np.einsum("nji,nj->ni", Vt, c)
    return x
