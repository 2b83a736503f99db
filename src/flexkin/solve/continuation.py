"""Continuation of IK solutions in the pose (paper §6): predictor-corrector on the one system.

One step moves ``n`` solutions at once from their poses to target poses (compiled, one
loop over the candidates):

* **predictor**: the tangent of the solution branch from the implicit-function theorem,
  ``d(z, rho) = -A_IK^-1 G_x dx`` (:mod:`flexkin.analysis.jacobian`);
* **corrector**: chord Newton with the predictor's matrix ``A_IK`` (one residual per
  iteration), then full Newton if the chord iteration stalls;
* **acceptance**: residual <= :data:`~flexkin.solve.corrector.RESIDUAL_TOL` and a corrector
  displacement small against the predicted one, in physical terms (inputs and tip forces),
  so that a step never jumps to another branch.  A step that fails is an answer, not an
  error: near an IK singularity (a fold of the branch, typically the workspace boundary)
  the steps fail however small they are.

d-mode changes of a rod need no special treatment: every d-mode is one strip of the unified
rod chart, so a rod changes mode continuously.  Pinned rods close to straight under tension
(``|k| -> 1``, the seam of the unified chart) are moved to the seam chart
(:func:`to_working_charts`), where passing through the straight rod is regular.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from ..core.jit import njit
from numpy.typing import NDArray

from ..core.linalg import solve_into
from ..rod.closed_form import chart_to_seam, seam_to_chart
from ..rod.kernels import CHART_SEAM, CHART_UNIFIED, CHART_WRENCH, FX, FY, ML, NQ, eval_rod, project
from ..system import System, eval_one
from .corrector import _norm, _project_rods
from .corrector import RESIDUAL_TOL

__all__ = ["continue_ik", "to_working_charts", "SEAM_V", "SEAM_IN", "SEAM_OUT"]

#: a rod with |v| above this is near the seam of the chart (straight under tension, |k| -> 1)
SEAM_V = 4.0
#: rods switch to the seam chart above this |v| (and back below SEAM_OUT): hysteresis
SEAM_IN, SEAM_OUT = 3.0, 2.5


@njit(cache=True)
def _physical(c0, c1, EI, rod_col, L_ref, F_ref, x, chart, su, out, q, g) -> None:
    """Chart-free state of unknowns: inputs (scaled), world tip forces (in EI/L^2), tip moments
    (in EI/L) and the pose (in L_ref, rad), into ``out`` (15,)."""
    nu = x.shape[0]
    iu = nu - 3
    out[12] = x[nu - 6] / L_ref
    out[13] = x[nu - 5] / L_ref
    out[14] = x[nu - 4]
    for i in range(3):
        u = x[iu + i]
        al = c0[i, 2] + c1[i, 2] * u
        L = c0[i, 3] + c1[i, 3] * u
        col = rod_col[i]
        dim = 3 if chart[i] >= CHART_WRENCH else 2
        eval_rod(chart[i], x[col:col + dim], q[i], g[i])
        sf = EI[i] / (L * L) / F_ref
        ca, sa = math.cos(al), math.sin(al)
        out[i] = u / su[i]
        out[3 + 2 * i] = sf * (ca * q[i, FX] - sa * q[i, FY])
        out[4 + 2 * i] = sf * (sa * q[i, FX] + ca * q[i, FY])
        out[9 + i] = EI[i] / L * q[i, ML] / (F_ref * L_ref)


@njit(cache=True)
def continue_kernel(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
                    X, charts, P1, load, cols, pcols, su, tol, chord_iter, newton_iter, ok) -> None:
    """One continuation step of every row of ``X``: the parameter columns ``pcols`` (the pose
    for IK, the inputs for FK) move to ``P1`` and the unknown columns ``cols`` follow (in place
    where it succeeds; see the module docstring)."""
    n, nu = X.shape
    ne = nu - 3
    p = cols.shape[0]
    r = np.empty(ne)
    J = np.empty((ne, nu))
    Jd = np.empty((0, 0))
    A = np.empty((p, p))
    b = np.empty(p)
    d = np.empty(p)
    work = np.empty((p, p + 1))
    y = np.empty(nu)
    yt = np.empty(nu)
    q = np.empty((3, NQ))
    g = np.empty((3, NQ, 3))
    ph0 = np.empty(15)
    php = np.empty(15)
    phy = np.empty(15)
    for k in range(n):
        x = X[k]
        ch = charts[k]
        ok[k] = False
        eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, x, ch, load, r, J, True, q, g)
        for a in range(p):
            b[a] = 0.0
            for c in range(3):
                b[a] -= J[a, pcols[c]] * (P1[k, c] - x[pcols[c]])
            for c in range(p):
                A[a, c] = J[a, cols[c]]
        if not solve_into(A, b, d, work):
            continue
        fin = True
        for c in range(p):
            if not np.isfinite(d[c]):
                fin = False
        if not fin:
            continue
        for c in range(nu):
            y[c] = x[c]
        for c in range(3):
            y[pcols[c]] = P1[k, c]
        for c in range(p):
            y[cols[c]] += d[c]
        _project_rods(y, ch, rod_col)
        _physical(c0, c1, EI, rod_col, L_ref, F_ref, x, ch, su, ph0, q, g)
        _physical(c0, c1, EI, rod_col, L_ref, F_ref, y, ch, su, php, q, g)
        eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, y, ch, load, r, Jd, False, q, g)
        nrm = _norm(r)
        # chord iterations with the predictor's matrix
        for _ in range(chord_iter):
            if nrm <= 1e-2 * tol:
                break
            for a in range(p):
                b[a] = -r[a]
            solve_into(A, b, d, work)
            for c in range(nu):
                yt[c] = y[c]
            for c in range(p):
                yt[cols[c]] += d[c]
            _project_rods(yt, ch, rod_col)
            eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, yt, ch, load, r, Jd,
                     False, q, g)
            nt = _norm(r)
            if not nt < nrm:
                break
            for c in range(nu):
                y[c] = yt[c]
            nrm = nt
        # full Newton for the slow ones
        for _ in range(newton_iter):
            eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, y, ch, load, r, J, True,
                     q, g)
            nrm = _norm(r)
            if nrm <= 1e-2 * tol:
                break
            for a in range(p):
                b[a] = -r[a]
                for c in range(p):
                    A[a, c] = J[a, cols[c]]
            solve_into(A, b, d, work)
            for c in range(nu):
                yt[c] = y[c]
            for c in range(p):
                yt[cols[c]] += d[c]
            _project_rods(yt, ch, rod_col)
            eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, yt, ch, load, r, Jd,
                     False, q, g)
            nt = _norm(r)
            if not nt < nrm:
                break
            for c in range(nu):
                y[c] = yt[c]
            nrm = nt
        if not nrm <= tol:
            continue
        # same branch: the corrector stayed within half the predicted physical change
        _physical(c0, c1, EI, rod_col, L_ref, F_ref, y, ch, su, phy, q, g)
        step = 0.0
        corr = 0.0
        for c in range(15):
            step = max(step, abs(php[c] - ph0[c]))
            corr = max(corr, abs(phy[c] - php[c]))
        if not corr <= 0.5 * step + 1e-6:
            continue
        for c in range(nu):
            x[c] = y[c]
        ok[k] = True


def to_working_charts(system: System, X: NDArray, charts: NDArray) -> tuple[NDArray, NDArray]:
    """Pinned rods in the chart best for continuation.

    Mode-1 rods close to straight under tension (``|v| > SEAM_IN``, ``0 < phis < pi/2``) are
    moved to the seam chart (:func:`~flexkin.rod.kernels.seam_eval`), where passing through
    the straight rod is regular; seam-chart rods far from it (``|v| < SEAM_OUT``) go back to
    the unified chart.
    """
    X = np.array(X, dtype=float)
    charts = np.array(charts, dtype=np.int64)
    if not _switch_needed(X, charts, system.rod_col):
        return X, charts
    for i in range(3):
        c = system.layout.rod[i].start
        z0, z1 = X[:, c], X[:, c + 1]
        uni = charts[:, i] == CHART_UNIFIED
        go = uni & (np.abs(z0) > SEAM_IN) & (z1 > 1e-6) & (z1 < 0.5 * np.pi - 1e-12)
        if np.any(go):
            ps, chi = chart_to_seam(z0[go], z1[go])
            X[go, c], X[go, c + 1] = ps, chi
            charts[go, i] = CHART_SEAM
        seam = charts[:, i] == CHART_SEAM
        seam[go] = False
        if np.any(seam):
            v, ph = seam_to_chart(z0[seam], z1[seam])
            back = np.abs(v) < SEAM_OUT
            idx = np.flatnonzero(seam)[back]
            X[idx, c], X[idx, c + 1] = v[back], ph[back]
            charts[idx, i] = CHART_UNIFIED
    return X, charts


#: ``k'`` at ``|v| = SEAM_OUT``: a seam-chart rod with a larger ``k'`` goes back to the unified chart
_KP_OUT = 1.0 / math.cosh(SEAM_OUT)


@njit(cache=True)
def _switch_needed(X, charts, rod_col) -> bool:
    """Whether :func:`to_working_charts` moves any rod (the common case is none): a unified
    rod beyond ``SEAM_IN``, or a seam rod whose ``k'`` (:func:`~flexkin.rod.closed_form.seam_to_chart`)
    is above that of ``|v| = SEAM_OUT``."""
    for k in range(X.shape[0]):
        for i in range(3):
            z0 = X[k, rod_col[i]]
            z1 = X[k, rod_col[i] + 1]
            if charts[k, i] == CHART_UNIFIED:
                if abs(z0) > SEAM_IN and z1 > 1e-6 and z1 < 0.5 * np.pi - 1e-12:
                    return True
            elif charts[k, i] == CHART_SEAM:
                h = 0.5 * abs(z0)
                sc, cc, ch = math.sin(z1), math.cos(z1), math.cos(h)
                kp = math.sin(h) * cc / math.sqrt(cc * cc + ch * ch * sc * sc)
                if kp >= _KP_OUT * (1.0 - 1e-12):
                    return True
    return False


@lru_cache(maxsize=64)
def _columns(system: System, fixed: str) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Solved columns, parameter columns and input scales of a system (cached per system)."""
    lay = system.layout
    sl = lay.pose if fixed == "pose" else lay.inputs
    return lay.columns(fixed), np.arange(sl.start, sl.stop, dtype=np.int64), system.input_scale()


def continue_ik(system: System, X: NDArray, charts: NDArray, pose1: NDArray, load: NDArray,
                chord_iter: int = 6, newton_iter: int = 5, fixed: str = "pose"
                ) -> tuple[NDArray, NDArray, NDArray[np.bool_]]:
    """Move solutions ``X`` (n, n_unknowns) to new values ``pose1`` (n, 3) of the columns held
    fixed (``fixed="pose"``: IK solutions to new poses; ``"inputs"``: FK solutions to new inputs).

    Returns the new unknowns, their charts and a success flag per solution (failed rows are
    returned unchanged).  Where a rod near straight under tension fails, the step is retried
    across the seam with the rod's mirror image.
    """
    X, charts = to_working_charts(system, X if np.ndim(X) == 2 else np.atleast_2d(X), charts)
    P1 = np.ascontiguousarray(pose1 if np.ndim(pose1) == 2 else np.atleast_2d(pose1), dtype=float)
    load = np.asarray(load, dtype=float)
    ok = np.zeros(len(X), bool)
    cols, pcols, su = _columns(system, fixed)
    X0 = X.copy()
    continue_kernel(*system.args(), X, charts, P1, load, cols, pcols, su, RESIDUAL_TOL, chord_iter, newton_iter, ok)
    if np.count_nonzero(ok) == len(ok):  # (ndarray.all costs ~5 us on the single-step path)
        return X, charts, ok
    near = ~ok & _near_seam(system, X0, charts)
    if np.any(near):
        idx = np.flatnonzero(near)
        Xs, cs = X0[idx].copy(), charts[idx].copy()
        for i in range(3):
            c = system.layout.rod[i].start
            flip = (cs[:, i] == CHART_UNIFIED) & (np.abs(Xs[:, c]) > SEAM_V)
            Xs[flip, c] = -Xs[flip, c]
        oks = np.zeros(len(idx), bool)
        continue_kernel(*system.args(), Xs, cs, P1[idx], load, cols, pcols, su, RESIDUAL_TOL, 0, newton_iter + 4,
                        oks)
        X[idx[oks]] = Xs[oks]
        ok[idx[oks]] = True
    X[~ok] = X0[~ok]
    return X, charts, ok


def _near_seam(system: System, X: NDArray, charts: NDArray) -> NDArray[np.bool_]:
    """Rows with a unified-chart rod close to the seam (``|v| > SEAM_V``)."""
    out = np.zeros(len(X), bool)
    for i in range(3):
        c = system.layout.rod[i].start
        out |= (charts[:, i] == CHART_UNIFIED) & (np.abs(X[:, c]) > SEAM_V)
    return out


_ = (CHART_WRENCH, project)
