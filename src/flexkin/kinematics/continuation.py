"""Continuation of IK solutions in the pose (paper §6): predictor–corrector on the one system.

One step moves ``n`` solutions at once from poses ``x0`` to poses ``x1``:

* **predictor**: the tangent of the solution branch from the implicit-function theorem,
  ``d(z, rho) = -A_IK^-1 G_x dx`` (:mod:`flexkin.kinematics.jacobian`);
* **corrector**: chord Newton with the predictor's matrix ``A_IK`` (one residual per
  iteration), then full Newton if the chord iteration is slow;
* **acceptance**: residual <= :data:`~flexkin.kinematics.ik.RESIDUAL_TOL` and a corrector
  displacement small against the predicted one (so that a step never jumps to another
  branch).  A step that fails is an answer, not an error: near an IK singularity (a fold of
  the branch, typically the workspace boundary) the steps fail however small they are.

d-mode changes of a rod need no special treatment: every d-mode is one strip of the unified
rod chart, so a rod changes mode continuously.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .ik import RESIDUAL_TOL
from .jacobian import system_derivatives
from ..rod.closed_form import SEAM_OFFSET, chart_to_seam, is_seam, seam_to_chart
from .system import REVOLUTE, MechArrays, project_zrod, residual, rod_world

__all__ = ["continue_ik", "unknown_scale"]


def unknown_scale(m: MechArrays) -> NDArray[np.float64]:
    """Scale of the IK unknowns ``(zrod, inputs)`` used for step norms."""
    return np.concatenate([np.ones(6), [1.0 if k == REVOLUTE else m.L_ref for k in m.kind]])


def _solve(A: NDArray, b: NDArray) -> tuple[NDArray, NDArray]:
    out = np.zeros_like(b)
    ok = np.isfinite(A).all(axis=(1, 2)) & np.isfinite(b).all(axis=1)
    if np.any(ok):
        ok_idx = np.flatnonzero(ok)
        c = np.linalg.cond(A[ok_idx])
        good = c < 1e13
        ok[ok_idx[~good]] = False
        if np.any(good):
            out[ok_idx[good]] = np.linalg.solve(A[ok_idx[good]], b[ok_idx[good]][..., None])[..., 0]
    return out, ok


def _A_ik(m: MechArrays, x: NDArray, pose: NDArray) -> tuple[NDArray, NDArray]:
    """``A_IK`` in the raw unknowns (zrod, inputs) and ``G_x`` in raw pose units."""
    Gz, Gx, Gu = system_derivatives(m, x[:, :6], pose, x[:, 6:])
    su = unknown_scale(m)[6:]
    sx = np.array([m.L_ref, m.L_ref, 1.0])
    return np.concatenate([Gz, Gu / su[None, None, :]], axis=2), Gx / sx[None, None, :]


def continue_ik(m: MechArrays, x: NDArray, pose0: NDArray, pose1: NDArray, load: NDArray,
                chord_iter: int = 6, newton_iter: int = 5) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Move IK solutions ``x = (zrod, inputs)`` (n, 9) from ``pose0`` to ``pose1`` (n, 3).

    Returns the new unknowns and a success flag per solution (failed rows are returned
    unchanged).
    """
    x = to_working_charts(np.atleast_2d(np.asarray(x, dtype=float)))
    pose0, pose1 = np.atleast_2d(pose0), np.atleast_2d(pose1)
    A, Gx = _A_ik(m, x, pose0)
    dx_pred, ok = _solve(A, -np.einsum("nij,nj->ni", Gx, pose1 - pose0))
    pred = x + dx_pred
    pred[:, :6] = project_zrod(pred[:, :6])
    y = pred.copy()

    def res(y_, p_):
        return residual(m, y_[:, :6], p_, y_[:, 6:], load)

    r = res(y, pose1)
    norm = np.max(np.abs(r), axis=1)
    norm[~np.isfinite(norm)] = np.inf
    chord = ok.copy()
    for _ in range(chord_iter):
        act = chord & (norm > RESIDUAL_TOL * 1e-2)
        if not np.any(act):
            break
        d, good = _solve(A[act], -r[act])
        ya = y[act] + d
        ya[:, :6] = project_zrod(ya[:, :6])
        ra = res(ya, pose1[act])
        na = np.max(np.abs(ra), axis=1)
        na[~np.isfinite(na)] = np.inf
        better = good & (na < norm[act])
        idx = np.flatnonzero(act)[better]
        y[idx], r[idx], norm[idx] = ya[better], ra[better], na[better]
        chord[np.flatnonzero(act)[~better]] = False
    for _ in range(newton_iter):  # full Newton for the slow ones
        act = ok & (norm > RESIDUAL_TOL * 1e-2)
        if not np.any(act):
            break
        Aa, _ = _A_ik(m, y[act], pose1[act])
        d, good = _solve(Aa, -r[act])
        ya = y[act] + d
        ya[:, :6] = project_zrod(ya[:, :6])
        ra = res(ya, pose1[act])
        na = np.max(np.abs(ra), axis=1)
        na[~np.isfinite(na)] = np.inf
        better = good & (na < norm[act])
        idx = np.flatnonzero(act)[better]
        y[idx], r[idx], norm[idx] = ya[better], ra[better], na[better]
        if np.all(~better):
            break
    # accept: converged, and the corrector stayed close to the prediction (same branch), in
    # physical terms (inputs and tip forces: the chart is very nonlinear near its seam)
    success = ok & (norm <= RESIDUAL_TOL) & _close(m, x, pred, y)
    out = np.where(success[:, None], y, x)
    seam = ~success & ok & np.any((np.abs(x[:, 0:6:2]) > SEAM_V) & ~is_seam(x[:, 1:6:2]), axis=1)
    if np.any(seam):
        idx = np.flatnonzero(seam)
        xs, okk = _across_seam(m, x[idx], pred[idx], pose1[idx], load, newton_iter + 4)
        out[idx[okk]] = xs[okk]
        success[idx[okk]] = True
    return out, success


#: a rod with |v| above this is near the seam of the chart (straight under tension, |k| -> 1)
SEAM_V = 4.0
#: rods switch to the seam chart above this |v| (and back below SEAM_OUT): hysteresis
SEAM_IN, SEAM_OUT = 3.0, 2.5


def to_working_charts(x: NDArray) -> NDArray:
    """Rods of IK unknowns ``x`` (n, >= 6) in the chart best for continuation.

    Mode-1 rods close to straight under tension (``|v| > SEAM_IN``, ``0 < phis < pi/2``) are
    moved to the seam chart (:func:`~flexkin.rod.closed_form.tip_seam`), where passing
    through the straight rod is regular; seam-chart rods far from it (``|v| < SEAM_OUT``) go
    back to the solvers' chart.
    """
    x = np.array(x, dtype=float)
    for i in range(3):
        z0, z1 = x[:, 2 * i], x[:, 2 * i + 1]
        seam = is_seam(z1)
        go = ~seam & (np.abs(z0) > SEAM_IN) & (z1 > 1e-6) & (z1 < 0.5 * np.pi - 1e-12)
        if np.any(go):
            ps, chi = chart_to_seam(z0[go], z1[go])
            x[go, 2 * i], x[go, 2 * i + 1] = ps, chi + SEAM_OFFSET
        if np.any(seam):
            v, ph = seam_to_chart(z0[seam], z1[seam] - SEAM_OFFSET)
            back = np.abs(v) < SEAM_OUT
            idx = np.flatnonzero(seam)[back]
            x[idx, 2 * i], x[idx, 2 * i + 1] = v[back], ph[back]
    return x


def _physical(m: MechArrays, x: NDArray) -> NDArray:
    """Chart-free part of IK unknowns: inputs (scaled) and world tip forces (in EI/L^2)."""
    _, force = rod_world(m, x[:, :6], x[:, 6:])
    return np.concatenate([x[:, 6:] / unknown_scale(m)[6:], force.reshape(-1, 6) / m.F_ref], axis=1)


def _close(m: MechArrays, x: NDArray, pred: NDArray, y: NDArray) -> NDArray[np.bool_]:
    """The corrected ``y`` is within half the predicted physical change of the prediction."""
    with np.errstate(invalid="ignore", over="ignore"):
        px, pp, py = _physical(m, x), _physical(m, pred), _physical(m, y)
        step = np.max(np.abs(pp - px), axis=1)
        corr = np.max(np.abs(py - pp), axis=1)
    return np.isfinite(corr) & (corr <= 0.5 * step + 1e-6)


def _across_seam(m: MechArrays, x: NDArray, pred: NDArray, pose1: NDArray, load: NDArray,
                 iters: int) -> tuple[NDArray, NDArray]:
    """Continue across the chart seam where a rod passes straight under tension.

    Such a rod has ``|k| -> 1`` and ``phis -> pi/2`` from one side and continues as its
    mirror image (``v -> -v``) on the other side.  Newton restarts from the prediction with
    those rods mirrored; the result is accepted when it converges and its inputs (the
    physical, chart-free part of the state) stay close to the predicted ones.
    """
    y = pred.copy()
    near = np.abs(x[:, 0:6:2]) > SEAM_V
    for i in range(3):
        y[near[:, i], 2 * i] = -x[near[:, i], 2 * i]
        y[near[:, i], 2 * i + 1] = x[near[:, i], 2 * i + 1]
    r = residual(m, y[:, :6], pose1, y[:, 6:], load)
    norm = np.max(np.abs(r), axis=1)
    norm[~np.isfinite(norm)] = np.inf
    ok = np.isfinite(norm)
    for _ in range(iters):
        act = ok & (norm > RESIDUAL_TOL * 1e-2)
        if not np.any(act):
            break
        Aa, _ = _A_ik(m, y[act], pose1[act])
        d, good = _solve(Aa, -r[act])
        ya = y[act] + d
        ya[:, :6] = project_zrod(ya[:, :6])
        ra = residual(m, ya[:, :6], pose1[act], ya[:, 6:], load)
        na = np.max(np.abs(ra), axis=1)
        na[~np.isfinite(na)] = np.inf
        better = good & (na < norm[act])
        idx = np.flatnonzero(act)[better]
        y[idx], r[idx], norm[idx] = ya[better], ra[better], na[better]
        if np.all(~better):
            break
    return y, ok & (norm <= RESIDUAL_TOL) & _close(m, x, pred, y)
