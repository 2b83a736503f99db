"""Full forward kinematics: every equilibrium pose for given inputs and load (paper §5).

With the inputs fixed every clamp is known, and the unknowns are the six rod parameters
(paper: rigid-body closure Eq. 17 plus equilibrium Eq. 15, six equations).  Instead of
the paper's sampled global optimisation, a branch-and-bound over the product of the
three rods' atlases finds every solution region:

* each rod's atlas is a binary tree of cells with bounds of the tip position and tip
  force (:mod:`flexkin.rod.atlas_tree`), mapped to the world frame by the rod's clamp;
* a triple of nodes survives only if interval arithmetic on its boxes admits
  the three platform side lengths ``|B_i - B_j| = d_ij``, the signed area of the
  platform triangle (which rejects the mirror image), the force balance
  ``sum n_i = F`` and the moment balance about ``B_1``;
* the largest node of every surviving triple is split until all three are single cells,
  whose centres (pose fitted to the three tips) start a batch Newton on the full
  9-equation system with the inputs held fixed.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.geometry2d import fit_pose as _fit_pose
from ..core.geometry2d import rot2
from ..core.validation import as_triple, check_budget, check_max_mode
from ..results import FKDiagnostics, KinematicsResult, Solution
from ..rod.atlas_tree import get_atlas_tree
from ..system import System
from .corrector import newton
from .finish import finish_solutions
from .fk_search import fk_starts
from .ik import RESIDUAL_TOL, as_load

__all__ = ["fk"]


def _imul(alo, ahi, blo, bhi):
    """Interval product."""
    p = np.stack([alo * blo, alo * bhi, ahi * blo, ahi * bhi])
    return p.min(0), p.max(0)


def _icross(a_c, a_h, b_c, b_h):
    """Interval of the 2-D cross product of two boxes given by centre and half-width."""
    x1 = _imul(a_c[..., 0] - a_h[..., 0], a_c[..., 0] + a_h[..., 0], b_c[..., 1] - b_h[..., 1], b_c[..., 1] + b_h[..., 1])
    x2 = _imul(a_c[..., 1] - a_h[..., 1], a_c[..., 1] + a_h[..., 1], b_c[..., 0] - b_h[..., 0], b_c[..., 0] + b_h[..., 0])
    return x1[0] - x2[1], x1[1] - x2[0]


def _dist_ok(c, h, d, tol):
    near = np.hypot(*np.moveaxis(np.maximum(np.abs(c) - h, 0.0), -1, 0))
    far = np.hypot(*np.moveaxis(np.abs(c) + h, -1, 0))
    return (near <= d + tol) & (far >= d - tol)


def fk_candidates(m: System, inputs: NDArray, w: NDArray, max_mode: int,
                  max_nodes: int = 20_000_000, chunk: int = 200_000, stride: int = 1,
                  eps_tip: float = 0.01, eps_force: float = 0.05, fallback: int = 20_000,
                  deadline: float | None = None) -> tuple[NDArray[np.float64], bool]:
    """Starting points (n, 9) = (zrod, pose) for the FK Newton, from the atlas B&B.

    Returns the starts and whether the search completed within ``max_nodes`` node
    triples.  Near singular configurations (e.g. all rods' lines of action through one
    point, where the moment balance stops pruning) the search can exceed its budget; it
    then also returns the centres of up to ``fallback`` unresolved node triples
    (deterministic subsample) and reports ``complete = False``.
    """
    tree = get_atlas_tree(max_mode, stride)
    A, alpha, L = m.clamps(inputs[None])
    A, alpha, L = A[0], alpha[0], L[0]
    cen_t, half_t, cen_f, half_f = [], [], [], []
    for i in range(3):
        R = rot2(alpha[i])
        Ra = np.abs(R)
        lo, hi = tree.lo, tree.hi
        ct, ht = 0.5 * (lo[:, :2] + hi[:, :2]), 0.5 * (hi[:, :2] - lo[:, :2])
        cf, hf = 0.5 * (lo[:, 2:] + hi[:, 2:]), 0.5 * (hi[:, 2:] - lo[:, 2:])
        fs = m.EI[i] / L[i] ** 2
        cen_t.append(A[i] + L[i] * ct @ R.T)
        half_t.append(L[i] * ht @ Ra.T)
        cen_f.append(fs * cf @ R.T)
        half_f.append(fs * hf @ Ra.T)
    b = m.attach
    d12, d13, d23 = (float(np.hypot(*(b[j] - b[i]))) for i, j in ((0, 1), (0, 2), (1, 2)))
    e1, e2 = b[1] - b[0], b[2] - b[0]
    area = float(e1[0] * e2[1] - e1[1] * e2[0])  # signed: rejects the mirror-image platform
    tol_len = 1e-9 * m.L_ref
    Fres = float(np.hypot(w[0], w[1]))
    mom_slack = float(np.hypot(*b[0])) * Fres
    # a node is resolved once its tip and force boxes are small in physical terms (Newton's
    # basin is far larger); this stops the refinement near the chart's polar point (the
    # unloaded straight rod), where many cells map onto almost the same rod
    size_t = np.max(np.stack(half_t), axis=-1) / (eps_tip * m.L_ref)  # (3, n_nodes)
    fmag = np.hypot(*np.moveaxis(np.stack(cen_f), -1, 0))
    size_f = np.max(np.stack(half_f), axis=-1) / (eps_force * (m.F_ref + fmag))
    size = np.maximum(size_t, size_f)
    size = np.where(tree.is_leaf[None] | (size < 1.0), -1.0, size)
    leaves = []
    stack = [np.zeros((1, 3), dtype=np.int64)]
    evaluated = 0
    while stack:  # depth-first over chunks keeps the working set bounded
        active = stack.pop()
        evaluated += len(active)
        if evaluated > max_nodes or (deadline is not None and time.perf_counter() > deadline):
            stack.append(active)
            break
        n = [active[:, i] for i in range(3)]
        c = [cen_t[i][n[i]] for i in range(3)]
        h = [half_t[i][n[i]] for i in range(3)]
        ok = _dist_ok(c[1] - c[0], h[0] + h[1], d12, tol_len)
        ok &= _dist_ok(c[2] - c[0], h[0] + h[2], d13, tol_len)
        ok &= _dist_ok(c[2] - c[1], h[1] + h[2], d23, tol_len)
        alo, ahi = _icross(c[1] - c[0], h[0] + h[1], c[2] - c[0], h[0] + h[2])
        ok &= (alo <= area + tol_len**2) & (ahi >= area - tol_len**2)
        fc = sum(cen_f[i][n[i]] for i in range(3))
        fh = sum(half_f[i][n[i]] for i in range(3))
        ok &= np.all(np.abs(fc - w[:2]) <= fh + 1e-12 * m.F_ref, axis=1)
        m2 = _icross(c[1] - c[0], h[0] + h[1], cen_f[1][n[1]], half_f[1][n[1]])
        m3 = _icross(c[2] - c[0], h[0] + h[2], cen_f[2][n[2]], half_f[2][n[2]])
        ok &= (m2[0] + m3[0] <= w[2] + mom_slack + 1e-12) & (m2[1] + m3[1] >= w[2] - mom_slack - 1e-12)
        active = active[ok]
        if not len(active):
            continue
        sz = np.stack([size[i][active[:, i]] for i in range(3)], 1)
        done = np.all(sz < 0, axis=1)
        if np.any(done):
            leaves.append(active[done])
        active, sz = active[~done], sz[~done]
        if not len(active):
            continue
        j = np.argmax(sz, axis=1)
        rows = np.arange(len(active))
        kids = tree.child[active[rows, j]]
        left, right = active.copy(), active.copy()
        left[rows, j] = kids[:, 0]
        right[rows, j] = kids[:, 1]
        nxt = np.concatenate([left, right])
        for k in range(0, len(nxt), chunk):
            stack.append(nxt[k:k + chunk])
    complete = not stack
    starts = [np.zeros((0, 9))]
    if leaves:
        starts.append(_linearised_starts(m, tree, np.concatenate(leaves), A, alpha, L, w))
    timed_out = deadline is not None and time.perf_counter() > deadline
    if stack and not timed_out:  # out of time: only what was resolved
        rest = np.concatenate(stack)
        if len(rest) > fallback:
            rest = rest[np.random.default_rng(0).choice(len(rest), fallback, replace=False)]
        zrod = np.concatenate([tree.center[rest[:, i]] for i in range(3)], axis=1)
        Xr = np.zeros((len(zrod), m.layout.n_unknowns))
        Xr[:, :6] = zrod
        Xr[:, m.layout.inputs] = inputs
        tips = m.rod_world(Xr, m.default_charts(len(Xr)))["tip"]
        starts.append(np.concatenate([zrod, fit_pose(m, tips)], axis=1))
    return np.concatenate(starts), complete


def _linearised_starts(m: System, tree, lv: NDArray[np.int64], A, alpha, L, w: NDArray,
                       reach: float = 1.0) -> NDArray[np.float64]:
    """One linearised Newton step per leaf triple; keep those whose step stays near the cells.

    Each leaf cell carries the bilinear model of its unit-rod tip and force; mapped to the
    world frame these give, with the pose linearised about the fit of the three tips, a
    9x9 linear system for the chart corrections and the pose.  A triple is kept when the
    corrections stay within ``reach`` cell half-widths beyond the cell (a solution inside
    the cell has a step of at most one half-width).  Returns starts (n, 9).
    """
    n = len(lv)
    if n == 0:
        return np.zeros((0, 9))
    out = []
    for lo in range(0, n, 200_000):
        sl = lv[lo:lo + 200_000]
        k = len(sl)
        zc = np.concatenate([tree.center[sl[:, i]] for i in range(3)], axis=1)
        tip = np.empty((k, 3, 2))
        frc = np.empty((k, 3, 2))
        Jt = np.empty((k, 3, 2, 2))
        Jf = np.empty((k, 3, 2, 2))
        for i in range(3):
            R = rot2(alpha[i])
            fs = m.EI[i] / L[i] ** 2
            val, grd = tree.value[sl[:, i]], tree.grad[sl[:, i]]
            tip[:, i] = A[i] + L[i] * val[:, :2] @ R.T
            frc[:, i] = fs * val[:, 2:] @ R.T
            Jt[:, i] = L[i] * np.einsum("ab,nbc->nac", R, grd[:, :2, :])
            Jf[:, i] = fs * np.einsum("ab,nbc->nac", R, grd[:, 2:, :])
        pose0 = fit_pose(m, tip)
        th = pose0[:, 2]
        ct, st = np.cos(th), np.sin(th)
        b = m.attach
        Rb = np.stack([ct[:, None] * b[None, :, 0] - st[:, None] * b[None, :, 1],
                       st[:, None] * b[None, :, 0] + ct[:, None] * b[None, :, 1]], -1)  # (k, 3, 2)
        dRb = np.stack([-Rb[..., 1], Rb[..., 0]], -1)  # d(Rot(th) b)/dth
        M = np.zeros((k, 9, 9))
        r = np.zeros((k, 9))
        for i in range(3):
            rows = slice(2 * i, 2 * i + 2)
            M[:, rows, 2 * i:2 * i + 2] = Jt[:, i]
            M[:, rows, 6:8] = -np.eye(2)
            M[:, rows, 8] = -dRb[:, i]
            r[:, rows] = tip[:, i] - pose0[:, None, :2][:, 0] - Rb[:, i]
            M[:, 6:8, 2 * i:2 * i + 2] = Jf[:, i]
            # moment: (Rb_i) x f_i
            M[:, 8, 2 * i:2 * i + 2] = Rb[:, i, 0:1] * Jf[:, i, 1] - Rb[:, i, 1:2] * Jf[:, i, 0]
            M[:, 8, 8] += dRb[:, i, 0] * frc[:, i, 1] - dRb[:, i, 1] * frc[:, i, 0]
        r[:, 6:8] = frc.sum(1) - w[:2]
        r[:, 8] = np.sum(Rb[..., 0] * frc[..., 1] - Rb[..., 1] * frc[..., 0], axis=1) - w[2]
        # scale rows and columns for conditioning
        rs = np.array([1.0 / m.L_ref] * 6 + [1.0 / m.F_ref] * 2 + [1.0 / (m.F_ref * m.L_ref)])
        Ms = M * rs[None, :, None]
        with np.errstate(all="ignore"):
            step = -_solve_batch(Ms, r * rs)
        step = np.where(np.isfinite(step), step, np.inf)
        half = np.concatenate([tree.half[sl[:, i]] for i in range(3)], axis=1)
        keep = np.all(np.abs(step[:, :6]) <= (1.0 + reach) * half, axis=1)
        x = np.concatenate([zc + step[:, :6], pose0 + step[:, 6:]], axis=1)
        out.append(x[keep])
    return np.concatenate(out)


def fit_pose(m: System, tips: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least-squares rigid pose placing the attach points ``b_i`` on ``tips`` (n, 3, 2)."""
    return _fit_pose(m.attach, tips)


def _solve_batch(J: NDArray[np.float64], b: NDArray[np.float64], rcond: float = 1e-13) -> NDArray[np.float64]:
    """Batched ``J x = b``; singular or non-finite systems get the minimum-norm least-squares
    solution from a batched truncated SVD (no Python loop)."""
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


def fk(mech, inputs: ArrayLike, load: ArrayLike | None = None, max_mode: int = 2, *, stride: int = 4,
       stable_only: bool = False, time_budget: float | None = None) -> KinematicsResult:
    """All equilibrium poses of ``mech`` for actuator ``inputs`` under ``load`` (paper §5).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    inputs : (u1, u2, u3)
        Actuator inputs in SI units: m for prismatic and length legs, **radians** for
        revolute legs.
    load : (Fx, Fy, Mz), optional
        Load wrench on the platform at P; defaults to the mechanism file's ``[load]``.
    max_mode : int
        Largest d-mode of any rod (default 2).
    stride : int
        Coarsening of the atlas cells used by the search (1 = finest, slowest).
    stable_only : bool
        Keep only the stable equilibria (default: all, stable and unstable).
    time_budget : float, optional
        Seconds for the global search; when it runs out, the candidates found so far are
        refined and the result says ``complete = False``.

    Returns
    -------
    KinematicsResult
        ``problem == "fk"``; ``solutions`` possibly empty, then ``message`` explains.
    """
    t0 = time.perf_counter()
    max_mode = check_max_mode(max_mode)
    u = as_triple(inputs, "inputs")
    w = as_load(mech, load)
    for i, leg in enumerate(mech.legs):
        leg.actuator.check_input(float(u[i]), i)
    deadline = None if time_budget is None else t0 + check_budget(time_budget)
    system = System.from_mechanism(mech)
    given, wl = tuple(float(v) for v in u), tuple(float(v) for v in w)
    diag: dict[str, Any] = {}
    msg = _assembly_obstruction(system, u)
    if msg:
        return KinematicsResult((), True, msg, time.perf_counter() - t0, FKDiagnostics(), "fk", mech, given, wl,
                                max_mode)
    X, complete, nodes = fk_starts(system, mech, u, w, max_mode, stride=stride, deadline=deadline)
    diag["candidates"] = int(len(X))
    diag["search_complete"] = complete
    diag["nodes"] = int(nodes)
    sols = refine_fk(system, mech, X, system.default_charts(len(X)), w, max_mode, diag)
    msg = "" if sols else "no equilibrium pose found for these inputs and load"
    if diag.get("continuum"):
        msg = ("singular configuration: straight rods carry axial forces freely, a continuum of equilibria; "
               "the least loaded one is reported")
    if not complete:
        why = ("time budget exhausted" if deadline is not None and time.perf_counter() > deadline
               else "search budget exhausted near a singular configuration")
        msg = f"{why}: the solution list may be incomplete" + ("" if sols else "; " + msg)
    res = KinematicsResult(tuple(sols), complete, msg, time.perf_counter() - t0, FKDiagnostics(**diag), "fk", mech,
                           given, wl, max_mode)
    return res.select(stable_only=True) if stable_only else res


def refine_fk(system: System, mech, X: NDArray, charts: NDArray, load: NDArray, max_mode: int,
              diag: dict[str, Any] | None = None) -> list[Solution]:
    """Newton-refine FK candidates ``X`` (inputs held) and build the solutions."""
    res = newton(system, X, charts, load, "inputs")
    good = res.residual <= RESIDUAL_TOL
    if diag is not None:
        diag["converged"] = int(np.count_nonzero(good))
    return finish_solutions(system, mech, res.x[good], res.charts[good], res.residual[good], max_mode, load, diag)


def _assembly_obstruction(m: System, u: NDArray) -> str:
    """A one-line reason when the rods cannot reach a common platform, else ``""``."""
    A, _, L = m.clamps(u[None])
    A, L = A[0], L[0]
    b = m.attach
    for i in range(3):
        for j in range(i + 1, 3):
            gap = float(np.hypot(*(A[j] - A[i])))
            reach = L[i] + L[j] + float(np.hypot(*(b[j] - b[i])))
            if gap > reach:
                return (f"cannot assemble: clamps {i + 1} and {j + 1} are {gap:.6g} m apart, more than the rods "
                        f"and the platform side can span ({reach:.6g} m)")
    return ""
