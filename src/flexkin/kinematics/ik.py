"""Full inverse kinematics: every equilibrium for a pose and a load (paper §4).

Procedure (paper §4.1–4.2, made global):

1. per leg, the geometric-condition curves on the atlas of all d-modes <= ``max_mode``
   (:mod:`flexkin.kinematics.curves`, Fig. 7);
2. every triple of curve points in platform equilibrium with the load (Eq. 15), found by
   subdivision over the three polylines in wrench space
   (:mod:`flexkin.kinematics.equilibrium`);
3. batch Newton on the full 9-equation system (:mod:`flexkin.kinematics.system`) to a
   scaled residual <= 1e-10, then de-duplication and sorting by (d-modes, energy).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..numerics import batch_newton
from ..rod.closed_form import mode_of
from .curves import leg_curves
from .equilibrium import equilibrium_triples
from .jacobian import kinematic_jacobians
from .results import KinematicsResult, Solution
from .stability import mechanism_stability
from ..rod.atlas import in_scope
from ..rod.closed_form import tip_any
from .system import REVOLUTE, MechArrays, clamp_arrays, platform_points, project_zrod, residual, rod_states, rod_world

__all__ = ["ik", "solve_ik", "RESIDUAL_TOL"]

#: acceptance threshold on the scaled residual of a refined solution
RESIDUAL_TOL = 1e-10


def _as_load(mech, load: ArrayLike | None) -> NDArray[np.float64]:
    return _as_triple(mech.load if load is None else load, "load (Fx, Fy, Mz)")


def _as_triple(value: ArrayLike, what: str) -> NDArray[np.float64]:
    """Three finite numbers, or a ValueError naming ``what``."""
    try:
        a = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be three finite numbers, got {value!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be three finite numbers, got {value!r}")
    return a


def project_unknowns(x: NDArray) -> NDArray:
    """Keep the rod-chart part (first 6 columns) of Newton iterates admissible."""
    x = x.copy()
    x[:, :6] = project_zrod(x[:, :6])
    return x


def _check_budget(budget: Any) -> float:
    """A positive finite number of seconds, or a ValueError."""
    try:
        b = float(budget)
    except (TypeError, ValueError):
        raise ValueError(f"time_budget must be a number of seconds > 0, got {budget!r}") from None
    if not (np.isfinite(b) and b > 0):
        raise ValueError(f"time_budget must be a number of seconds > 0, got {budget!r}")
    return b


def _check_mode(max_mode: Any) -> int:
    if isinstance(max_mode, bool) or not isinstance(max_mode, (int, np.integer)) or not 1 <= max_mode <= 6:
        raise ValueError(f"max_mode must be an integer between 1 and 6, got {max_mode!r}")
    return int(max_mode)


def finish_solutions(m: MechArrays, z: NDArray, res_norm: NDArray, pose: NDArray, inputs: NDArray,
                     max_mode: int, key_scale: NDArray, diag: dict[str, Any] | None = None) -> list[Solution]:
    """Filter converged candidates by d-mode, de-duplicate, build :class:`Solution` objects.

    Two candidates are the same equilibrium when their rods' tip forces and base moments,
    pose and inputs agree to 1e-6 (scaled); the one with the smaller residual is kept.
    Solutions are sorted by (d-modes, energy, inputs, pose).
    """
    modes = mode_of(z[:, 1::2])
    ok = np.all(modes <= max_mode, axis=1) & in_scope(z[:, 0::2])
    z, res_norm, pose, inputs = z[ok], res_norm[ok], pose[ok], inputs[ok].copy()
    # revolute inputs (clamp angles) are reported in (-pi, pi]
    rev = m.kind == REVOLUTE
    inputs[:, rev] = np.pi - np.mod(np.pi - inputs[:, rev], 2 * np.pi)
    if len(z) == 0:
        return []
    # identity of a solution: physical, chart-independent quantities, computed in one batch
    _, force = rod_world(m, z, inputs)
    _, _, L = clamp_arrays(m, inputs)
    t = tip_any(z[:, 0::2], z[:, 1::2])
    m0 = t.m0 * m.EI[None] / L
    keys = np.concatenate([force.reshape(-1, 6) / m.F_ref, m0 / (m.F_ref * m.L_ref),
                           pose / np.array([m.L_ref, m.L_ref, 1.0]), inputs / key_scale], axis=1)
    order = np.argsort(res_norm, kind="stable")
    chosen: list[int] = []
    for i in order:
        if not chosen or np.min(np.max(np.abs(keys[chosen] - keys[i]), axis=1)) > 1e-6:
            chosen.append(int(i))
    # a continuum: the same geometry (pose, inputs, rod tip angles) carrying different forces
    # happens only where straight rods take axial force freely (a singular configuration);
    # one representative, the least loaded, is kept
    geo = np.concatenate([pose / np.array([m.L_ref, m.L_ref, 1.0]), inputs / key_scale,
                          np.cos(t.theta), np.sin(t.theta)], axis=1)[chosen]
    fmag = np.sum(np.abs(force.reshape(-1, 6)), axis=1)[chosen]
    keep: list[int] = []
    for a in np.argsort(fmag, kind="stable"):
        if not keep or np.min(np.max(np.abs(geo[keep] - geo[a]), axis=1)) > 1e-8:
            keep.append(int(a))
    if diag is not None and len(keep) < len(chosen):
        diag["continuum"] = len(chosen) - len(keep) + 1
    chosen = [chosen[a] for a in sorted(keep)]
    idx = np.array(chosen)
    stab = mechanism_stability(m, z[idx], pose[idx], inputs[idx])
    jac = kinematic_jacobians(m, z[idx], pose[idx], inputs[idx])
    sols = []
    for j, i in enumerate(chosen):
        rs = rod_states(m, z[i], inputs[i])
        sols.append(Solution(pose=tuple(float(v) for v in pose[i]), inputs=tuple(float(v) for v in inputs[i]),
                             modes=tuple(r.mode for r in rs), rods=rs, residual=float(res_norm[i]),
                             zrod=tuple(float(v) for v in z[i]), stable=bool(stab.stable[j]),
                             stability_margin=float(stab.margin[j]), stability_index=int(stab.index[j]),
                             jacobian=jac.as_dict(j)))
    sols.sort(key=lambda s: (s.modes, round(s.energy / (m.F_ref * m.L_ref), 9), s.inputs, s.pose))
    return sols


def ik(mech, pose: ArrayLike, load: ArrayLike | None = None, max_mode: int = 2, *,
       stable_only: bool = False, time_budget: float | None = None) -> KinematicsResult:
    """All equilibria of ``mech`` at platform ``pose`` under ``load`` (paper §4).

    Parameters
    ----------
    mech : Mechanism
    pose : (x, y, theta)
        Platform pose, m and **radians**.
    load : (Fx, Fy, Mz), optional
        Load wrench on the platform at P; defaults to the mechanism file's ``[load]``.
    max_mode : int
        Largest d-mode of any rod (default 2, i.e. the 8 combinations of modes 1–2).
    stable_only : bool
        Keep only the stable equilibria (default: all, stable and unstable).
    time_budget : float, optional
        Seconds for the global search of step 2; when it runs out, the candidates found so
        far are refined and the result says ``complete = False``.

    Returns
    -------
    KinematicsResult
        ``problem == "ik"``; ``solutions`` (possibly empty, then ``message`` explains),
        ``curves`` holds the geometric-condition curves of step 1.
    """
    t0 = time.perf_counter()
    max_mode = _check_mode(max_mode)
    pose = _as_triple(pose, "pose (x, y, theta)")
    w = _as_load(mech, load)
    m = MechArrays.from_mechanism(mech)
    B = platform_points(m, pose[None])[0]
    curves = leg_curves(m, B, max_mode)
    diag: dict[str, Any] = {"branches": [len(c) for c in curves]}

    # ---- step 2: equilibrium triples on the polylines ------------------------------------
    wscale = m.wrench_scale()
    p0s, p1s, zs, us = [], [], [], []
    for i, c in enumerate(curves):
        arm = B[i] - pose[:2]
        P0, P1, Z0, Z1, U0, U1 = [], [], [], [], [], []
        for br in c.branches:
            f = br["force"]
            wr = np.stack([f[:, 0], f[:, 1], arm[0] * f[:, 1] - arm[1] * f[:, 0]], -1) / wscale
            z = np.stack([br["v"], br["phis"]], -1)
            P0.append(wr[:-1]); P1.append(wr[1:]); Z0.append(z[:-1]); Z1.append(z[1:])
            U0.append(br["input"][:-1]); U1.append(br["input"][1:])
        cat = (lambda L, d: np.concatenate(L) if L else np.zeros((0,) + d))
        p0s.append(cat(P0, (3,))); p1s.append(cat(P1, (3,)))
        zs.append((cat(Z0, (2,)), cat(Z1, (2,)))); us.append((cat(U0, ()), cat(U1, ())))
    target = w / wscale
    deadline = None if time_budget is None else t0 + _check_budget(time_budget)
    seg, s, complete = equilibrium_triples(p0s, p1s, target, deadline=deadline)
    diag["candidates"] = int(len(seg))
    diag["search_complete"] = complete
    if len(seg) == 0:
        msg = _empty_message(curves) if complete else \
            "search stopped early (time or node budget) before any candidate was found"
        return KinematicsResult("ik", mech, tuple(pose), tuple(w), max_mode, (), complete,
                                msg, time.perf_counter() - t0, diag, curves)
    zrod = np.empty((len(seg), 6))
    inputs = np.empty((len(seg), 3))
    for i in range(3):
        a, b = zs[i][0][seg[:, i]], zs[i][1][seg[:, i]]
        zrod[:, 2 * i:2 * i + 2] = a + s[:, i:i + 1] * (b - a)
        ua, ub = us[i][0][seg[:, i]], us[i][1][seg[:, i]]
        inputs[:, i] = ua + s[:, i] * (ub - ua)

    # ---- step 3: Newton on the full equations ------------------------------------------
    sols = refine_ik(m, pose, w, zrod, inputs, max_mode, diag)
    msg = "" if sols else "no equilibrium found: the geometric-condition curves admit no point of platform equilibrium"
    if diag.get("continuum"):
        msg = ("singular configuration: straight rods carry axial forces freely, a continuum of equilibria; "
               "the least loaded one is reported")
    if not complete:
        msg = "search stopped early (time or node budget): the solution list may be incomplete"
    res = KinematicsResult("ik", mech, tuple(float(v) for v in pose), tuple(float(v) for v in w), max_mode,
                           tuple(sols), complete, msg, time.perf_counter() - t0, diag, curves)
    return res.select(stable_only=True) if stable_only else res


def refine_ik(m: MechArrays, pose: NDArray, w: NDArray, zrod: NDArray, inputs: NDArray, max_mode: int,
              diag: dict[str, Any] | None = None) -> list[Solution]:
    """Newton-refine IK candidates (unknowns: rod charts and inputs) and build solutions."""
    n = len(zrod)
    P = np.broadcast_to(pose, (n, 3))

    def f(x: NDArray) -> NDArray:
        k = len(x)
        return residual(m, x[:, :6], np.broadcast_to(pose, (k, 3)), x[:, 6:], w)

    x0 = np.concatenate([zrod, inputs], axis=1)
    cap = np.array([0.2, 0.5] * 3 + [0.2 * m.L_ref if k != 1 else 0.3 for k in m.kind])
    res = batch_newton(f, x0, tol=1e-13, project=project_unknowns, max_step=cap, merge_after=4, merge_tol=1e-6)
    good = res.residual <= RESIDUAL_TOL
    if diag is not None:
        diag["converged"] = int(np.count_nonzero(good))
    x = res.z[good]
    key_scale = np.array([m.L_ref if k != 1 else 1.0 for k in m.kind])
    return finish_solutions(m, x[:, :6], res.residual[good], P[good], x[:, 6:], max_mode, key_scale, diag)


def _empty_message(curves) -> str:
    empty = [c.leg + 1 for c in curves if len(c) == 0]
    if empty:
        return f"pose unreachable: no rod of leg(s) {', '.join(map(str, empty))} can reach its platform point"
    return "no equilibrium found: the geometric-condition curves admit no point of platform equilibrium"


def solve_ik(*args: Any, **kwargs: Any) -> KinematicsResult:
    """Alias of :func:`ik`."""
    return ik(*args, **kwargs)
