"""Pseudo-arclength continuation in tau, written as coroutines so many branches share one batch.

A branch is a generator that yields evaluation requests ``(zhat, tau, need_jacobian)`` and
receives ``(R, Jz, Jt)`` (scaled residual, Jacobian w.r.t. the unknowns and w.r.t. tau), or a
string instead of ``R``, which aborts the branch with that reason; it returns a
:class:`BranchEnd`.  :func:`run_batched` drives any number of such generators, evaluating all
pending requests of one round in a single batched call, so the compiled shooting kernel sees
every rod of every branch at once.  Nothing here knows about rods: the toy problems of the
tests drive the same code.

Algorithm (per branch): Newton at the start tau with tau fixed; then predictor–corrector on
``H(z, tau) = 0`` in the scaled variables ``y = (z, tau)``: tangent predictor ``y + ds t``
(``t`` the unit kernel vector of ``[H_z  H_tau]``, oriented along the previous one), Newton
corrector on ``H = 0, t . (y - y_pred) = 0``.  Step control: the first corrector update,
which scales like ``ds^2``, is steered to a quarter of ``max_correction`` (factor in
[1/4, 2]); a step whose first update exceeds ``max_correction`` or whose Newton iteration does
not contract is halved (this also keeps branches from jumping).  Convergence is declared on the
update size or, for ill-conditioned systems, on the residual reaching its rounding floor.

A turning point in tau (the tau-component of the tangent changes sign — where ``det H_z``
changes sign) is a fold: it is located by a few secant steps on the arclength and recorded with
the kernel direction there; the branch then continues with tau running back.  A branch ends
when it reaches or crosses its target tau (``target_up`` going up, ``target_down`` after a
fold), where it is polished by Newton with tau fixed, or fails (step underflow, too many steps,
or an abort by the evaluator).  A singular start (``H_z`` numerically singular, e.g. straight
rods at full reach, which carry axial self-stress freely) has no unique branch: the target is
then tried directly by damped Newton, and the result says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Generator

import numpy as np
from numpy.typing import NDArray

from ..core.linalg import det_sign, lu_solve, pivot_ratio

__all__ = ["ContinuationOptions", "BranchEnd", "Fold", "branch", "newton_fixed", "run_batched"]

Request = tuple[NDArray[np.float64], float, bool]
Reply = tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None]


@dataclass(frozen=True)
class ContinuationOptions:
    """Step control and tolerances of the pseudo-arclength continuation.

    All quantities are dimensionless, in the scaled units of :mod:`flexkin.cosserat.system`
    (unknowns O(1), tau in [0, 1]); update sizes and residuals are max-norms.

    Attributes
    ----------
    ds0 : float
        First arclength step along the curve in (z, tau).
    ds_max : float
        Largest arclength step.
    ds_min : float
        Smallest arclength step; the branch fails ("step size underflow") below it.
    max_steps : int
        Predictor–corrector steps per branch before it is declared stalled.
    corrector_tol : float
        Newton update size for convergence of the corrector on the curve.
    final_tol : float
        Newton update size for convergence with tau fixed (the start and the end of a branch).
    residual_bound : float
        Largest residual accepted together with an update below the tolerance (or at the
        noise floor).
    residual_tol : float
        Residual accepted as converged whatever the update (the rounding floor).
    noise_floor : float
        Update size treated as converged when Newton stagnates (the integration's noise).
    max_corrector_iter : int
        Newton iterations of the corrector per step.
    max_final_iter : int
        Newton iterations with tau fixed.
    max_correction : float
        Largest first corrector update (and largest final landing correction) accepted:
        guards against jumping to another branch; the step size aims at a quarter of it.
    contraction : float
        Required ratio of successive Newton updates; a slower decrease is stagnation.
    fold_refine : int
        Secant steps locating a fold (the zero of the tangent's tau component).
    """

    ds0: float = 1.0
    ds_max: float = 1.0
    ds_min: float = 1e-5
    max_steps: int = 150
    corrector_tol: float = 1e-9
    final_tol: float = 1e-10
    residual_bound: float = 1e-6
    residual_tol: float = 1e-11
    noise_floor: float = 1e-8
    max_corrector_iter: int = 6
    max_final_iter: int = 12
    max_correction: float = 0.1
    contraction: float = 0.5
    fold_refine: int = 4


@dataclass(frozen=True)
class Fold:
    """A turning point in tau: where it is and the kernel direction of H_z there."""

    tau: float
    z: NDArray[np.float64]
    null: NDArray[np.float64]


@dataclass
class BranchEnd:
    """How a branch ended."""

    status: str                                   # "reached", "returned", "failed"
    tau: float
    z: NDArray[np.float64] | None
    folds: list[Fold] = field(default_factory=list)
    det_changes: int = 0
    steps: int = 0
    evaluations: int = 0
    residual: float = 0.0
    note: str = ""


def _solve(A: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64] | None:
    ok, x, _ = lu_solve(np.ascontiguousarray(A), np.ascontiguousarray(b))
    return x if ok else None


def _tangent(Jz, Jt, prev):
    """Unit kernel vector of [Jz Jt] with positive component along ``prev``."""
    Aug = np.vstack([np.hstack([Jz, Jt[:, None]]), prev[None]])
    rhs = np.zeros(Aug.shape[0])
    rhs[-1] = 1.0
    t = _solve(Aug, rhs)
    if t is None or not np.all(np.isfinite(t)):
        _, _, vt = np.linalg.svd(np.hstack([Jz, Jt[:, None]]))
        t = vt[-1]
    t = t / np.linalg.norm(t)
    return t if t @ prev >= 0 else -t


class Abort(Exception):
    """Raised inside a branch when the evaluator answers with a reason (a string) instead of R."""


def _check(reply):
    if isinstance(reply[0], str):
        raise Abort(reply[0])
    return reply


class _Counter:
    def __init__(self) -> None:
        self.n = 0


def newton_fixed(z: NDArray[np.float64], tau: float, opts: ContinuationOptions, cnt: _Counter,
                 max_iter: int | None = None, tol: float | None = None,
                 damped: bool = False) -> Generator[Request, Reply, tuple]:
    """Newton on ``H(., tau) = 0``; returns ``(ok, z, R, Jz, Jt)``."""
    max_iter = opts.max_final_iter if max_iter is None else max_iter
    tol = opts.final_tol if tol is None else tol
    prev = np.inf
    z = z.copy()
    for _ in range(max_iter):
        R, Jz, Jt = _check((yield (z, tau, True)))
        cnt.n += 1
        if not np.all(np.isfinite(R)):
            return False, z, R, Jz, Jt
        if float(np.max(np.abs(R))) <= opts.residual_tol:      # at the rounding floor of the residual
            return True, z, R, Jz, Jt
        dz = _solve(Jz, -R)
        if dz is None:
            return False, z, R, Jz, Jt
        nd = float(np.max(np.abs(dz)))
        if nd <= tol and float(np.max(np.abs(R))) <= opts.residual_bound:
            z = z + dz
            return True, z, R, Jz, Jt
        if nd > opts.contraction * prev and prev < np.inf and not damped:
            # stagnation: at the noise floor of the integration this is convergence
            ok = nd <= opts.noise_floor and float(np.max(np.abs(R))) <= opts.residual_bound
            return ok, z, R, Jz, Jt
        if damped and nd > 0.5:
            dz *= 0.5 / nd
        prev = nd
        z = z + dz
    return False, z, R, Jz, Jt


def _corrector(yp, t, opts, cnt, tol):
    """Newton on [H(y); t.(y - yp)] = 0 from yp; returns (ok, y, R, Jz, Jt, first correction)."""
    y = yp.copy()
    prev = np.inf
    first = np.inf
    R = Jz = Jt = None
    for it in range(opts.max_corrector_iter):
        R, Jz, Jt = _check((yield (y[:-1], float(y[-1]), True)))
        cnt.n += 1
        if not np.all(np.isfinite(R)):
            return False, y, R, Jz, Jt, first
        if float(np.max(np.abs(R))) <= opts.residual_tol:   # at the rounding floor of the residual
            return True, y, R, Jz, Jt, (0.0 if it == 0 else first)
        Aug = np.vstack([np.hstack([Jz, Jt[:, None]]), t[None]])
        rhs = -np.concatenate([R, [t @ (y - yp)]])
        d = _solve(Aug, rhs)
        if d is None:
            return False, y, R, Jz, Jt, first
        nd = float(np.max(np.abs(d)))
        if it == 0:
            first = nd
            if nd > opts.max_correction:
                return False, y, R, Jz, Jt, first
        elif nd > opts.contraction * prev:
            ok = nd <= opts.noise_floor and float(np.max(np.abs(R))) <= opts.residual_bound
            return ok, y, R, Jz, Jt, first
        y = y + d
        prev = nd
        if nd <= tol and float(np.max(np.abs(R))) <= opts.residual_bound:
            R, Jz, Jt = _check((yield (y[:-1], float(y[-1]), True)))
            cnt.n += 1
            if not np.all(np.isfinite(R)):
                return False, y, R, Jz, Jt, first
            return True, y, R, Jz, Jt, first
    return False, y, R, Jz, Jt, first


def _step_factor(first: float, opts: ContinuationOptions) -> float:
    """Step-size factor from the first corrector update (which scales like ds^2)."""
    target = 0.25 * opts.max_correction
    if not np.isfinite(first):
        return 0.25
    if first <= 0.0:
        return 2.0
    return float(np.clip(np.sqrt(target / first), 0.25, 2.0))


def branch(z0: NDArray[np.float64], tau0: float, direction: int, opts: ContinuationOptions,
           target_up: float = 1.0, target_down: float = 0.0) -> Generator[Request, Reply, BranchEnd]:
    """Follow the solution curve through ``(z0, tau0)`` starting towards ``direction`` (+1/-1) in tau.

    Ends at ``target_up`` ("reached" if heading up) or ``target_down`` ("returned"), polished
    with tau fixed; "failed" when the steps underflow or the evaluator aborts the branch.
    """
    cnt = _Counter()
    state: dict = {"tau": tau0, "folds": []}
    try:
        return (yield from _branch(z0, tau0, direction, opts, target_up, target_down, cnt, state))
    except Abort as e:
        return BranchEnd("failed", float(state["tau"]), None, list(state["folds"]), evaluations=cnt.n,
                         note=str(e))


def _branch(z0, tau0, direction, opts, target_up, target_down, cnt, state):
    ok, z, R, Jz, Jt = yield from newton_fixed(z0, tau0, opts, cnt)
    if not ok:
        return BranchEnd("failed", tau0, None, evaluations=cnt.n, residual=float(np.max(np.abs(R))),
                         note=f"no convergence at the start (tau = {tau0:g})")
    n = z.size
    y = np.concatenate([z, [tau0]])
    e_tau = np.zeros(n + 1)
    e_tau[-1] = float(direction)
    t = _tangent(Jz, Jt, e_tau)
    sdet = det_sign(np.ascontiguousarray(Jz))
    note = ""
    if pivot_ratio(np.ascontiguousarray(Jz)) < 1e-9:
        sv = np.linalg.svd(Jz, compute_uv=False)
        if sv[-1] <= 1e-10 * sv[0]:
            # a singular start (e.g. straight rods at full reach, which take axial self-stress freely):
            # the curve through it is not unique; try the target directly by damped Newton
            note = f"singular start (cond(H_z) = {sv[0] / max(sv[-1], 1e-300):.2g} at tau = {tau0:g})"
            target = target_up if direction > 0 else target_down
            ok, zf, R, _, _ = yield from newton_fixed(z, target, opts, cnt, max_iter=40, damped=True)
            if ok:
                return BranchEnd("reached" if direction > 0 else "returned", target, zf, [], 0, 1, cnt.n,
                                 float(np.max(np.abs(R))),
                                 note + "; the refined solution was reached by Newton at tau = "
                                 f"{target:g} directly (its connection to the start is not followed)")
    ds = opts.ds0
    folds: list[Fold] = state["folds"]
    det_changes = 0
    step = -1
    for step in range(opts.max_steps):
        state["tau"] = float(y[-1])
        heading_up = t[-1] > 0
        target = target_up if heading_up else target_down
        dist = target - y[-1]
        # final step onto the target tau, when the tangent is not near a fold
        if abs(t[-1]) > 0.05 and ds * abs(t[-1]) >= abs(dist):
            yp = y + (dist / t[-1]) * t
            ok, zf, R, _, _ = yield from newton_fixed(yp[:-1], target, opts, cnt)
            if ok and float(np.max(np.abs(zf - yp[:-1]))) <= opts.max_correction:
                status = "reached" if heading_up else "returned"
                return BranchEnd(status, target, zf, folds, det_changes, step + 1, cnt.n,
                                 float(np.max(np.abs(R))), note)
            ds = 0.5 * min(ds, abs(dist / t[-1]))
            if ds < opts.ds_min:
                break
            continue
        yp = y + ds * t
        ok, yc, R, Jz, Jt, first = yield from _corrector(yp, t, opts, cnt, opts.corrector_tol)
        if not ok:
            ds *= min(0.5, _step_factor(first, opts))
            if ds < opts.ds_min:
                break
            continue
        # crossed a target tau: land on it by interpolation and Newton with tau fixed
        crossed = None
        if yc[-1] >= target_up and y[-1] < target_up:
            crossed = target_up
        elif yc[-1] <= target_down and y[-1] > target_down:
            crossed = target_down
        if crossed is not None:
            lam = (crossed - y[-1]) / (yc[-1] - y[-1])
            zi = y[:-1] + lam * (yc[:-1] - y[:-1])
            ok, zf, R, _, _ = yield from newton_fixed(zi, crossed, opts, cnt)
            if ok and float(np.max(np.abs(zf - zi))) <= opts.max_correction:
                status = "reached" if crossed == target_up else "returned"
                tn = _tangent(Jz, Jt, t)
                if (tn[-1] > 0) != (t[-1] > 0):
                    fold = yield from _locate_fold(y, t, yc, tn, opts, cnt)
                    folds.append(fold)
                return BranchEnd(status, crossed, zf, folds, det_changes, step + 1, cnt.n,
                                 float(np.max(np.abs(R))), note)
            ds *= 0.5
            if ds < opts.ds_min:
                break
            continue
        tn = _tangent(Jz, Jt, t)
        snew = det_sign(np.ascontiguousarray(Jz))
        if (tn[-1] > 0) != (t[-1] > 0):
            fold = yield from _locate_fold(y, t, yc, tn, opts, cnt)
            folds.append(fold)
        elif snew != sdet and snew != 0 and sdet != 0:
            det_changes += 1
        sdet = snew if snew != 0 else sdet
        y, t = yc, tn
        ds = min(ds * _step_factor(first, opts), opts.ds_max)
    why = "step size underflow" if ds < opts.ds_min else f"{opts.max_steps} steps without reaching the end"
    note = (note + "; " if note else "") + f"continuation stalled at tau = {float(y[-1]):.6g} ({why})"
    return BranchEnd("failed", float(y[-1]), y[:-1].copy(), folds, det_changes, step + 1, cnt.n, note=note)


def _locate_fold(ya, ta, yb, tb, opts, cnt):
    """Secant steps on the arclength for the zero of the tau-component of the tangent."""
    best = (abs(ta[-1]), ya, ta) if abs(ta[-1]) < abs(tb[-1]) else (abs(tb[-1]), yb, tb)
    for _ in range(opts.fold_refine):
        sa, sb = ta[-1], tb[-1]
        if sa == sb:
            break
        dist = float(np.linalg.norm(yb - ya))
        sig = dist * sa / (sa - sb)
        yp = ya + sig * ta
        ok, yc, R, Jz, Jt, _ = yield from _corrector(yp, ta, opts, cnt, opts.corrector_tol)
        if not ok:
            break
        tc = _tangent(Jz, Jt, ta)
        if abs(tc[-1]) < best[0]:
            best = (abs(tc[-1]), yc, tc)
        if (tc[-1] > 0) == (sa > 0):
            ya, ta = yc, tc
        else:
            yb, tb = yc, tc
    _, y, t = best
    null = t[:-1] / max(np.linalg.norm(t[:-1]), 1e-300)
    return Fold(tau=float(y[-1]), z=y[:-1].copy(), null=null)


def run_batched(gens: dict, evaluate: Callable[[list, list, NDArray[np.float64], bool], tuple]) -> dict:
    """Drive generators ``{key: gen}`` to completion; ``evaluate(keys, Z, tau, jac)`` -> (R, Jz, Jt).

    ``Z`` is a list of the requested unknown vectors (their lengths may differ); ``R``, ``Jz``,
    ``Jt`` are sequences indexed like ``keys``.

    Returns ``{key: return value}``.
    """
    out = {}
    pending = {}
    for k, g in gens.items():
        try:
            pending[k] = next(g)
        except StopIteration as e:
            out[k] = e.value
    while pending:
        keys = list(pending)
        Z = [pending[k][0] for k in keys]
        tau = np.array([pending[k][1] for k in keys], dtype=float)
        R, Jz, Jt = evaluate(keys, Z, tau, True)
        nxt = {}
        for j, k in enumerate(keys):
            try:
                nxt[k] = gens[k].send((R[j], Jz[j], Jt[j]))
            except StopIteration as e:
                out[k] = e.value
        pending = nxt
    return out
