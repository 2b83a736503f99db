"""The one batched Newton corrector on the mechanism's equation system (compiled).

IK, FK, continuation, paths and workspaces all refine candidates with :func:`newton`: a
damped Newton iteration on the square subsystem of the unknown columns ``cols`` (the other
columns held fixed: the pose for IK, the inputs for FK), with the analytic Jacobian of
:mod:`flexkin.system`, steps capped per column, halving line search on the residual's
infinity norm, and the rods' charts projected after every trial step
(:func:`flexkin.rod.kernels.project`).  Candidates that converge to one root are merged
after a few iterations so that the work of refining many starts of one root is not repeated.

**Deflation** (Farrell, Birkisson & Funke, SIAM J. Sci. Comput. 37 (2015) A2026, Eq. 2.4): a
candidate may be given roots it must not converge to again.  Newton then solves
``G(x) = M(x) F(x) = 0`` with ``M(x) = prod_r (1 / |x - r|^2 + 1)`` (distances in the solved
columns divided by their step caps), which has the roots of ``F`` except the deflated ones.  Its
Newton step is the plain one rescaled, ``d_G = d / (1 - grad(log M) . d)`` (Sherman-Morrison on
``J_G = M J + F grad(M)^T``), so it costs no more than a plain step; the line search is on
``M |F|``, convergence on ``|F|``.  From the start that led to one root, a deflated Newton finds
the root's near neighbours: the two equilibria of a near-fold pair, which one chord of the
geometric-condition curves cannot tell apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ..core.jit import njit
from numpy.typing import NDArray

from ..core.linalg import solve_into
from ..rod.kernels import CHART_WRENCH, NQ, project
from ..system import System, eval_one

__all__ = ["NewtonResult", "newton", "RESIDUAL_TOL"]

#: acceptance threshold on the scaled residual of a refined solution (IK, FK, continuation steps)
RESIDUAL_TOL = 1e-10


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of :func:`newton` for ``n`` candidates.

    Attributes
    ----------
    x : (n, n_unknowns) final iterates (all columns).
    charts : (n, 3) their rods' charts.
    residual : (n,) infinity norm of the scaled residual at ``x`` (``inf`` where undefined).
    converged : (n,) residual below the tolerance.
    iterations : (n,) iterations used.
    """

    x: NDArray[np.float64]
    charts: NDArray[np.int64]
    residual: NDArray[np.float64]
    converged: NDArray[np.bool_]
    iterations: NDArray[np.int64]


@njit(cache=True)
def _norm(r: np.ndarray) -> float:
    m = 0.0
    for v in r:
        a = abs(v)
        if not a <= 1e300:  # NaN or inf
            return np.inf
        if a > m:
            m = a
    return m


@njit(cache=True)
def _project_rods(x: np.ndarray, chart: np.ndarray, rod_col: np.ndarray) -> None:
    for i in range(3):
        c = chart[i]
        if c != CHART_WRENCH:
            project(c, x[rod_col[i]:rod_col[i] + (3 if c > CHART_WRENCH else 2)])


@njit(cache=True)
def _project_all(X: np.ndarray, charts: np.ndarray, rod_col: np.ndarray) -> None:
    for k in range(X.shape[0]):
        _project_rods(X[k], charts[k], rod_col)


@njit(cache=True)
def _deflation(x, roots, n_roots, cols, cap, grad) -> float:
    """The deflation factor ``M(x)`` of the first ``n_roots`` of ``roots`` (module docstring) and
    ``grad(log M)`` over the solved columns (into ``grad``)."""
    m = 1.0
    for c in range(cols.shape[0]):
        grad[c] = 0.0
    for j in range(n_roots):
        d2 = 0.0
        for c in range(cols.shape[0]):
            e = (x[cols[c]] - roots[j, cols[c]]) / cap[c]
            d2 += e * e
        if not d2 > 1e-300:
            return np.inf
        f = 1.0 / d2 + 1.0
        m *= f
        for c in range(cols.shape[0]):  # d log(1/d2 + 1) = -2 e / (d2^2 f) / cap
            grad[c] -= 2.0 * (x[cols[c]] - roots[j, cols[c]]) / (cap[c] * cap[c] * d2 * d2 * f)
    return m


@njit(cache=True)
def newton_kernel(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
                  X, charts, load, cols, cap, tol, max_iter, active, norm_out, iters_out,
                  roots, n_roots) -> None:
    """Damped Newton on the rows of ``X`` flagged ``active`` (in place), row ``k`` deflated by
    ``roots[k, :n_roots[k]]`` (full unknown vectors); see the module docstring."""
    n, nu = X.shape
    ne = nu - 3
    p = cols.shape[0]
    r = np.empty(ne)
    rt = np.empty(ne)
    J = np.empty((ne, nu))
    Jd = np.empty((0, 0))
    A = np.empty((p, p))
    b = np.empty(p)
    d = np.empty(p)
    work = np.empty((p, p + 1))
    xt = np.empty(nu)
    q = np.empty((3, NQ))
    g = np.empty((3, NQ, 3))
    grad = np.empty(p)
    gt = np.empty(p)
    for k in range(n):
        if not active[k]:
            continue
        x = X[k]
        ch = charts[k]
        nr = n_roots[k]
        eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, x, ch, load, r, J, True, q, g)
        nrm = _norm(r)
        mx = _deflation(x, roots[k], nr, cols, cap, grad) if nr else 1.0
        it = iters_out[k]
        while it < max_iter and nrm > tol:
            for a in range(p):  # the square subsystem (p == number of equations)
                b[a] = -r[a]
                for c in range(p):
                    A[a, c] = J[a, cols[c]]
            solve_into(A, b, d, work)
            if nr:  # the deflated step (module docstring)
                gd = 0.0
                for c in range(p):
                    gd += grad[c] * d[c]
                if 1.0 - gd != 0.0:
                    for c in range(p):
                        d[c] /= 1.0 - gd
            s = 1.0
            for c in range(p):
                if not np.isfinite(d[c]):
                    s = -1.0
                    break
                t = abs(d[c]) / cap[c]
                if t > s:
                    s = t
            it += 1
            if s < 0.0:
                break
            alpha = 1.0 / s
            improved = False
            for _ls in range(9):
                for c in range(nu):
                    xt[c] = x[c]
                for c in range(p):
                    xt[cols[c]] += alpha * d[c]
                _project_rods(xt, ch, rod_col)
                eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
                         xt, ch, load, rt, Jd, False, q, g)
                nt = _norm(rt)
                mt = _deflation(xt, roots[k], nr, cols, cap, gt) if nr else 1.0
                if mt * nt < mx * nrm:
                    for c in range(nu):
                        x[c] = xt[c]
                    nrm = nt
                    mx = mt
                    for c in range(p):
                        grad[c] = gt[c]
                    improved = True
                    break
                alpha *= 0.5
            if not improved:
                break
            if nrm > tol:
                eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
                         x, ch, load, r, J, True, q, g)
        norm_out[k] = nrm
        iters_out[k] = it


def newton(system: System, X: NDArray, charts: NDArray, load: NDArray, fixed: str, *, tol: float = 1e-13,
           max_iter: int = 40, cap: NDArray | None = None, merge_after: int | None = 4,
           merge_tol: float = 1e-6, deflate: tuple[NDArray, NDArray] | None = None) -> NewtonResult:
    """Refine candidates ``X`` (n, n_unknowns) with the columns of ``fixed`` (``"pose"`` or
    ``"inputs"``) held.

    Parameters
    ----------
    system : System
    X : ndarray (n, n_unknowns)
        Starting points (all columns; the fixed ones are kept).
    charts : ndarray (n, 3)
        The rods' charts (:mod:`flexkin.rod.kernels`).
    load : (3,)
        Load wrench ``(F_x, F_y, M_z)``.
    fixed : {"pose", "inputs"}
    tol : float
        Convergence threshold on the infinity norm of the scaled residual.
    max_iter : int
        Newton iterations per candidate.
    cap : ndarray, optional
        Largest step of each solved column (default: 0.2 for the chart variable ``v``, 0.5
        for chart angles, a fifth of the length scale for lengths, 0.3 rad for angles).
    merge_after : int or None
        After this many iterations, candidates whose iterates coincide to ``merge_tol`` are
        merged (all but one stop, reported unconverged).
    deflate : (roots, counts), optional
        Roots each candidate must not converge to again: ``roots`` (n, R, n_unknowns) and
        ``counts`` (n,), candidate ``k`` deflated by ``roots[k, :counts[k]]`` (module
        docstring).  Default: none.
    """
    lay = system.layout
    X = np.array(np.atleast_2d(X), dtype=float)
    charts = np.array(charts, dtype=np.int64).reshape(len(X), 3)
    cols = lay.columns(fixed)
    if cap is None:
        cap = default_cap(system, fixed)
    n = len(X)
    _project_all(X, charts, system.rod_col)  # start inside the charts
    norm = np.full(n, np.inf)
    iters = np.zeros(n, np.int64)
    active = np.ones(n, bool)
    if deflate is None:
        roots, counts = np.zeros((n, 0, lay.n_unknowns)), np.zeros(n, np.int64)
    else:
        roots = np.ascontiguousarray(deflate[0], dtype=float)
        counts = np.ascontiguousarray(deflate[1], dtype=np.int64)
    args = system.args() + (X, charts, np.asarray(load, dtype=float), cols, np.asarray(cap, dtype=float), tol)
    if merge_after is not None and n > 1:
        newton_kernel(*args, merge_after, active, norm, iters, roots, counts)
        pending = np.flatnonzero(norm > tol)
        if pending.size > 1:
            keys = np.round(X[pending][:, cols] / merge_tol)
            keys = np.where(np.isfinite(keys), keys, np.arange(len(pending))[:, None] + 1e18)
            _, first = np.unique(keys, axis=0, return_index=True)
            dup = np.ones(pending.size, bool)
            dup[first] = False
            active[:] = False
            active[pending[~dup]] = True
            norm[pending[dup]] = np.inf
        else:
            active[:] = False
            active[pending] = True
    newton_kernel(*args, max_iter, active, norm, iters, roots, counts)
    return NewtonResult(X, charts, norm, norm <= tol, iters)


def default_cap(system: System, fixed: str) -> NDArray[np.float64]:
    """Default step caps of the solved columns (see :func:`newton`)."""
    lay = system.layout
    cap = np.empty(lay.n_unknowns)
    for i, sl in enumerate(lay.rod):
        if sl.stop - sl.start == 2:
            cap[sl] = (0.2, 0.5)
        else:
            cap[sl] = 2.0  # dimensionless base wrench
    cap[lay.pose] = (0.1 * system.L_ref, 0.1 * system.L_ref, 0.3)
    cap[lay.inputs] = np.where(system.angular, 0.3, 0.2 * system.L_ref)
    return cap[lay.columns(fixed)]
