"""Single-rod inverse problem: every equilibrium of a rod whose tip is pinned at a point.

Given the clamp (point and tangent angle), the rod (L, EI) and the tip point, the two
tip equations ``L (x, y)(ku, phis) = tip_local`` are solved globally:

1. every triangle of the atlas grid (two per cell) whose image under the unit-rod tip
   map contains the target (barycentric test with a small tolerance) yields a start;
2. batch damped Newton on the closed form refines every start to machine precision;
3. converged roots are de-duplicated and sorted by (d-mode, energy).

This is the paper's Fig. 19 experiment (clamp on a linear actuator, tip on a dynamometer)
and the building block of the kinematics.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.jit import njit

from ..core.geometry2d import rot2
from ..core.validation import check_max_mode, check_positive
from ..rod.atlas import get_atlas, in_scope
from ..rod.closed_form import mode_of
from ..rod.kernels import NQ, X, Y, project, unified_eval
from ..results import Result
from ..rod.state import RodState

__all__ = ["RodInverseResult", "solve_rod", "atlas_starts", "refine_rod", "ACCEPT_TOL"]

#: acceptance threshold on the unit-rod tip residual (fraction of the rod length)
ACCEPT_TOL = 1e-11


@dataclass(frozen=True)
class RodInverseResult(Result):
    """All equilibria of one rod whose tip is held (pinned, or clamped with ``tip_angle``).

    Attributes
    ----------
    solutions : tuple of RodState, sorted by (mode, energy).
    residuals : tuple of float, tip-position error of each solution (m).
    tip, clamp, clamp_angle, length, EI, max_mode : the problem data (SI, rad).
    tip_angle : float or None
        The imposed tip tangent (rad, world) of a clamped tip; ``None`` for a pinned tip.
    complete, message, elapsed, diagnostics : see :class:`~flexkin.results.Result`.
    """

    residuals: tuple[float, ...] = ()
    tip: tuple[float, float] = (0.0, 0.0)
    clamp: tuple[float, float] = (0.0, 0.0)
    clamp_angle: float = 0.0
    length: float = 1.0
    EI: float = 1.0
    max_mode: int = 2
    tip_angle: float | None = None

    def plot(self, path: str | None = None, **kwargs: Any):
        """The equilibria drawn over each other (like the paper's Fig. 19 set-up)."""
        from ..plot.rod import plot_rod_solutions

        return plot_rod_solutions(self, path, **kwargs)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (SPEC §4, ``flexkin rod``)."""
        return {
            "problem": "rod",
            "length": self.length,
            "EI": self.EI,
            "tip": list(self.tip),
            "tip_angle_deg": None if self.tip_angle is None else float(np.degrees(self.tip_angle)),
            "joint": "pinned" if self.tip_angle is None else "clamped",
            "clamp": list(self.clamp),
            "clamp_angle_deg": float(np.degrees(self.clamp_angle)),
            "complete": self.complete,
            "message": self.message,
            "max_mode": self.max_mode,
            "solutions": [
                dict(s.to_dict(), residual=r) for s, r in zip(self.solutions, self.residuals)
            ],
        }


def atlas_starts(target: NDArray[np.float64], max_mode: int, tol: float = 0.02) -> NDArray[np.float64]:
    """Starting points ``(v, phis)`` from atlas triangles whose image contains ``target``.

    ``target`` is the unit-rod tip ``(x, y)`` in the local frame.
    """
    A = get_atlas(max_mode)
    P = np.stack([A.x, A.y], -1)  # (nk, nphi, 2)
    p00, p10, p01, p11 = P[:-1, :-1], P[1:, :-1], P[:-1, 1:], P[1:, 1:]
    KU, PH = A.V, A.PHIS
    c00 = np.stack([KU[:-1, :-1], PH[:-1, :-1]], -1)
    c10 = np.stack([KU[1:, :-1], PH[1:, :-1]], -1)
    c01 = np.stack([KU[:-1, 1:], PH[:-1, 1:]], -1)
    c11 = np.stack([KU[1:, 1:], PH[1:, 1:]], -1)
    starts = []
    for (a, b, c), (ca, cb, cc) in (((p00, p10, p11), (c00, c10, c11)), ((p00, p11, p01), (c00, c11, c01))):
        e1, e2, d = b - a, c - a, target - a
        det = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (d[..., 0] * e2[..., 1] - d[..., 1] * e2[..., 0]) / det
            v = (e1[..., 0] * d[..., 1] - e1[..., 1] * d[..., 0]) / det
            inside = (u >= -tol) & (v >= -tol) & (u + v <= 1 + tol) & np.isfinite(u) & np.isfinite(v)
        if np.any(inside):
            uu, vv = np.clip(u[inside], 0, 1), np.clip(v[inside], 0, 1)
            s = uu + vv
            big = s > 1
            uu = np.divide(uu, s, out=uu.copy(), where=big)
            vv = np.divide(vv, s, out=vv.copy(), where=big)
            starts.append(ca[inside] + uu[:, None] * (cb[inside] - ca[inside]) + vv[:, None] * (cc[inside] - ca[inside]))
    if not starts:
        return np.zeros((0, 2))
    return np.concatenate(starts)


@dataclass(frozen=True)
class RodNewton:
    """Outcome of :func:`refine_rod`: iterates ``z`` (n, 2), residual norms, convergence flags."""

    z: NDArray[np.float64]
    residual: NDArray[np.float64]
    converged: NDArray[np.bool_]


@njit(cache=True)
def _rod_newton(Z: np.ndarray, tx: float, ty: float, tol: float, max_iter: int, res: np.ndarray) -> None:
    """Damped Newton on ``tip(z) = (tx, ty)`` for unit pinned rods, in place (2x2, analytic Jacobian)."""
    q = np.empty(NQ)
    g = np.empty((NQ, 3))
    zt = np.empty(3)
    for k in range(Z.shape[0]):
        z = Z[k]
        project(0, z)
        unified_eval(z[0], z[1], q, g)
        rx, ry = q[X] - tx, q[Y] - ty
        nrm = max(abs(rx), abs(ry))
        for _ in range(max_iter):
            if not nrm > tol:
                break
            a, b, c, d = g[X, 0], g[X, 1], g[Y, 0], g[Y, 1]
            det = a * d - b * c
            if not abs(det) > 1e-300:
                break
            dz0 = -(d * rx - b * ry) / det
            dz1 = -(-c * rx + a * ry) / det
            s = max(abs(dz0) / 0.2, abs(dz1) / 0.5, 1.0)
            alpha = 1.0 / s
            improved = False
            for _ls in range(9):
                zt[0] = z[0] + alpha * dz0
                zt[1] = z[1] + alpha * dz1
                project(0, zt)
                unified_eval(zt[0], zt[1], q, g)
                nx, ny = q[X] - tx, q[Y] - ty
                nt = max(abs(nx), abs(ny))
                if nt < nrm:
                    z[0], z[1] = zt[0], zt[1]
                    rx, ry, nrm = nx, ny, nt
                    improved = True
                    break
                alpha *= 0.5
            if not improved:
                break
        res[k] = nrm if nrm == nrm else np.inf


def refine_rod(z0: NDArray[np.float64], target: NDArray[np.float64]) -> RodNewton:
    """Newton on the unit-rod tip equations from starts ``z0`` (n, 2) in the ``(v, phis)`` chart.

    ``target`` is the unit-rod tip in the local frame.  Near ``|k| = 1`` the closed form's
    rounding noise is a few 1e-13 L: roots that stalled there are accepted
    (:data:`ACCEPT_TOL` is still far below the 1e-10 m contract for any L <= 10 m).
    """
    z0 = np.atleast_2d(np.asarray(z0, dtype=float))
    Z = np.zeros((len(z0), 3))
    Z[:, :2] = z0[:, :2]
    res = np.full(len(Z), np.inf)
    _rod_newton(Z, float(target[0]), float(target[1]), 1e-13, 40, res)
    return RodNewton(Z[:, :2], res, res <= ACCEPT_TOL)


def unique_rows(z: NDArray[np.float64], tol: float) -> NDArray[np.int64]:
    """Indices of the first occurrence of each cluster of rows closer than ``tol`` (inf-norm)."""
    keep: list[int] = []
    for i in range(len(z)):
        if all(np.max(np.abs(z[i] - z[j])) > tol for j in keep):
            keep.append(i)
    return np.asarray(keep, dtype=np.int64)


def solve_rod(
    tip: ArrayLike,
    length: float,
    EI: float,
    *,
    clamp: ArrayLike = (0.0, 0.0),
    clamp_angle: float = 0.0,
    tip_angle: float | None = None,
    max_mode: int = 2,
) -> RodInverseResult:
    """All equilibria with d-mode <= ``max_mode`` of a rod whose tip is held at ``tip``:
    pinned (``tip_angle=None``), or clamped with the tangent ``tip_angle``.

    Parameters
    ----------
    tip : (2,) array_like
        Tip point, world frame (m).
    length, EI : float
        Rod length (m, > 0) and bending stiffness (N m^2, > 0).
    clamp : (2,) array_like
        Clamp point (m).
    clamp_angle : float
        Clamp tangent angle (rad).
    tip_angle : float, optional
        Tip tangent angle (rad, world frame) of a clamped tip; ``None`` for a pinned tip.
    max_mode : int
        Largest d-mode searched (>= 1).

    Returns
    -------
    RodInverseResult
        ``solutions`` may be empty (then ``message`` says why); never raises for an
        unreachable tip.
    """
    from ..mechanism.model import LENGTH_LIMITS, STIFFNESS_LIMITS

    t0 = time.perf_counter()
    tip = np.asarray(tip, dtype=float).reshape(2)
    clamp = np.asarray(clamp, dtype=float).reshape(2)
    length = check_positive(length, "length", LENGTH_LIMITS)
    EI = check_positive(EI, "EI", STIFFNESS_LIMITS)
    max_mode = check_max_mode(max_mode)
    if not (np.all(np.isfinite(tip)) and np.all(np.isfinite(clamp)) and np.isfinite(clamp_angle)):
        raise ValueError("tip, clamp and clamp_angle must be finite numbers")
    if tip_angle is not None and not np.isfinite(tip_angle):
        raise ValueError(f"tip_angle must be a finite number (rad) or None, got {tip_angle!r}")
    local = rot2(-clamp_angle) @ (tip - clamp) / length
    base = dict(tip=(float(tip[0]), float(tip[1])), clamp=(float(clamp[0]), float(clamp[1])),
                clamp_angle=float(clamp_angle), length=float(length), EI=float(EI), max_mode=int(max_mode),
                tip_angle=None if tip_angle is None else float(tip_angle))
    dist = float(np.hypot(*local))
    if dist > 1.0 + 1e-12:
        return RodInverseResult(message=f"tip is {dist * length:.6g} m from the clamp, beyond the rod length "
                                        f"{length:.6g} m", elapsed=time.perf_counter() - t0, **base)
    if tip_angle is not None:
        return _solve_clamped(local, float(tip_angle) - clamp_angle, t0, base)
    if dist >= 1.0 - 1e-12 and abs(float(np.arctan2(local[1], local[0]))) < 1e-9:
        # at full reach along the clamp axis only the straight rod fits, and being
        # inextensible it carries any axial force: a continuum; the unloaded one is reported
        st = RodState.from_chart(0.0, np.pi / 2, length, EI, clamp, clamp_angle)
        return RodInverseResult(solutions=(st,), residuals=(float(np.hypot(*(np.array(st.tip) - tip))),),
                                message="tip at full reach on the clamp axis: the straight rod carries any axial "
                                        "force; the unloaded one is reported",
                                elapsed=time.perf_counter() - t0, **base)
    starts = atlas_starts(local, max_mode)
    res = refine_rod(starts, local)
    ok = res.converged & (mode_of(res.z[:, 1]) <= max_mode) & in_scope(res.z[:, :1])
    z = res.z[ok]
    order = np.lexsort((z[:, 1], z[:, 0]))
    z = z[order][unique_rows(z[order], 1e-7)]
    states = [RodState.from_chart(k, p, length, EI, clamp, clamp_angle) for k, p in z]
    # one equilibrium may have several chart points (the unloaded straight rod is the pole of
    # the chart): keep one per physical state (tip force and base moment)
    fs, ms = EI / length**2, EI / length
    phys = np.array([[st.tip_force[0] / fs, st.tip_force[1] / fs, st.base_moment / ms] for st in states]).reshape(-1, 3)
    states = [states[i] for i in unique_rows(phys, 1e-7)]
    return _result(states, tip, t0, base, {"starts": int(len(starts)), "converged": int(np.count_nonzero(res.converged))})


def _result(states: list[RodState], tip: NDArray, t0: float, base: dict, diag: dict) -> RodInverseResult:
    resid = [float(np.hypot(s.tip[0] - tip[0], s.tip[1] - tip[1])) for s in states]
    pairs = sorted(zip(states, resid), key=lambda sr: (sr[0].mode, sr[0].energy, sr[0].k))
    what = "reaches the tip point" if base["tip_angle"] is None else "reaches the tip point with that tangent"
    msg = "" if pairs else f"no equilibrium with d-mode <= {base['max_mode']} {what}"
    return RodInverseResult(solutions=tuple(p[0] for p in pairs), residuals=tuple(p[1] for p in pairs), message=msg,
                            elapsed=time.perf_counter() - t0, diagnostics=diag, **base)


def _solve_clamped(local: NDArray, local_angle: float, t0: float, base: dict) -> RodInverseResult:
    """A rod clamped at both ends: every root in the wrench chart (:mod:`flexkin.rod.clamped`)."""
    from ..rod.clamped import clamped_rod_roots
    from ..rod.kernels import CHART_WRENCH, eval_rods
    from ..rod.wrench import wrench_mode

    Z, diag = clamped_rod_roots(float(local[0]), float(local[1]), local_angle, base["max_mode"])
    q = np.empty((len(Z), NQ))
    g = np.empty((len(Z), NQ, 3))
    eval_rods(np.full(len(Z), CHART_WRENCH, dtype=np.int64), np.ascontiguousarray(Z), q, g)
    states = []
    for z, qq in zip(Z, q):
        mode, boundary = wrench_mode(z[0], z[1], z[2], 1e-8)
        states.append(RodState.from_unit(qq, CHART_WRENCH, z, base["length"], base["EI"], base["clamp"],
                                         base["clamp_angle"], mode, "clamped", boundary))
    return _result(states, np.array(base["tip"]), t0, base, diag)
