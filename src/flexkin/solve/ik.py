"""Full inverse kinematics: every equilibrium for a pose and a load (paper §4).

Procedure (paper §4.1-4.2, made global):

1. per leg, the geometric-condition curves on the atlas of all d-modes <= ``max_mode``
   (:mod:`flexkin.solve.curves`, Fig. 7);
2. every triple of curve points in platform equilibrium with the load (Eq. 15), found by
   subdivision over the three polylines in wrench space (:mod:`flexkin.solve.equilibrium`);
3. the Newton corrector on the full equation system (:mod:`flexkin.solve.corrector`) to a
   scaled residual <= :data:`~flexkin.solve.corrector.RESIDUAL_TOL`, then one solution per equilibrium, stability and
   Jacobians (:mod:`flexkin.solve.finish`), sorted by (d-modes, energy).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.budget import Deadline
from ..core.validation import as_load, as_triple, check_max_mode, check_max_winding
from ..io.progress import Progress, substage
from ..results import IKDiagnostics, KinematicsResult
from ..system import System
from .clamped_curves import LAMBDA_LIMIT, segment_charts
from .curves import leg_curves
from .equilibrium import equilibrium_triples
from .finish import SCOPE_MESSAGE, force_limit_message, refine

__all__ = ["ik"]

#: seconds reserved per equilibrium-triple candidate for its refinement and analysis, while the
#: search runs under a time budget (a pinned IK candidate costs ~0.1 ms to refine, a solution
#: ~1-2 ms to build; candidates outnumber solutions)
CANDIDATE_COST = 3e-4


def ik(mech, pose: ArrayLike, load: ArrayLike | None = None, max_mode: int = 2, *, max_winding: int = 1,
       stable_only: bool = False, time_budget: float | Deadline | None = None,
       progress: Progress | None = None, margin: bool = False) -> KinematicsResult:
    """All equilibria of ``mech`` at platform ``pose`` under ``load`` (paper §4).

    Parameters
    ----------
    mech : Mechanism
        The mechanism.
    pose : (x, y, theta)
        Platform pose, m and **radians**.
    load : (Fx, Fy, Mz), optional
        Load wrench on the platform at P; defaults to the mechanism file's ``[load]``.
    max_mode : int
        Largest d-mode of any rod (default 2, i.e. the 8 combinations of modes 1-2 of pinned
        rods; a clamped rod's d-mode counts its inflections strictly inside, from 0).
    max_winding : int
        Largest ``|winding|`` of a clamped rod (SPEC §2; default 1).
    stable_only : bool
        Keep only the stable equilibria (default: all, stable and unstable).
    time_budget : float or Deadline, optional
        Seconds for the whole IK (start-up excluded; see :mod:`flexkin.core.budget`): the
        curves, the global search, the Newton refinement and the stability, Jacobians and
        verification of the solutions.  The search stops early enough for its candidates to
        be refined in time; when the time runs out the result holds what was finished and says
        ``complete = False``.  A :class:`~flexkin.core.budget.Deadline` shares a caller's clock.
    progress : callable, optional
        Called as ``progress(fraction, stage)`` as the work advances (``fraction`` from 0 to 1;
        :class:`flexkin.io.progress.ProgressBar` draws it).
    margin : bool
        Compute every solution's stability margin now (default: on first use -- the verdict
        and the index come from the closed form and need no margin).

    Returns
    -------
    KinematicsResult
        ``problem == "ik"``; ``solutions`` (possibly empty, then ``message`` explains),
        ``curves`` holds the geometric-condition curves of step 1.  ``complete`` is ``False``
        when the search stopped early, when it reached equilibria with a rod near straight
        under tension beyond the numerical scope (not reported), or when a clamped leg's curves
        reached the search's force limit (``message`` says so).
    """
    t0 = time.perf_counter()
    max_mode = check_max_mode(max_mode)
    max_winding = check_max_winding(max_winding)
    pose = as_triple(pose, "pose (x, y, theta)")
    w = as_load(mech, load)
    dl = Deadline.of(time_budget)
    system = System.from_mechanism(mech)
    B = system.platform_points(pose[None])[0]
    curves = leg_curves(mech, B, max_mode, max_winding=max_winding, theta=float(pose[2]),
                        progress=substage(progress, 0.0, 0.3, "geometric-condition curves"), deadline=dl)
    diag: dict[str, Any] = {"branches": tuple(len(c) for c in curves),
                            "force_limit": sum(c.limits for c in curves)}
    given = tuple(float(v) for v in pose)
    if dl.expired():
        diag["search_complete"] = False
        return KinematicsResult((), False, dl.message("stopped before the search for equilibria"),
                                time.perf_counter() - t0, IKDiagnostics(**diag), "ik", mech, given,
                                tuple(float(v) for v in w), max_mode, curves, max_winding=max_winding)

    # ---- step 2: equilibrium triples on the polylines (wrench space) -----------------------
    wscale = system.wrench_scale()
    lay = system.layout
    p0s, p1s, zs, us, cs = [], [], [], [], []
    default = system.default_charts(1)[0]
    for i, c in enumerate(curves):
        arm = B[i] - pose[:2]
        P0, P1, Z0, Z1, U0, U1, C = [], [], [], [], [], [], []
        for br in c.branches:
            f = br["force"]
            wr = np.stack([f[:, 0], f[:, 1], arm[0] * f[:, 1] - arm[1] * f[:, 0] + br["tip_moment"]], -1) / wscale
            z = br["z"]
            P0.append(wr[:-1]); P1.append(wr[1:]); Z0.append(z[:-1]); Z1.append(z[1:])
            U0.append(br["input"][:-1]); U1.append(br["input"][1:])
            C.append(br["chart"][:-1] if "chart" in br else np.full(len(z) - 1, default[i], dtype=np.int64))
        cat = (lambda L, d: np.concatenate(L) if L else np.zeros((0,) + d))
        dim = lay.rod[i].stop - lay.rod[i].start
        p0s.append(cat(P0, (3,))); p1s.append(cat(P1, (3,)))
        zs.append((cat(Z0, (dim,)), cat(Z1, (dim,)))); us.append((cat(U0, ()), cat(U1, ())))
        cs.append(np.concatenate(C) if C else np.zeros(0, np.int64))
    if progress is not None:
        progress(0.3, "platform equilibrium on the curves")
    seg, s, complete = equilibrium_triples(p0s, p1s, w / wscale, deadline=dl.for_search(), leaf_cost=CANDIDATE_COST)
    diag["candidates"] = int(len(seg))
    diag["search_complete"] = complete
    if len(seg) == 0:
        msg = _empty_message(curves) if complete else \
            (dl.message("the search stopped before any candidate was found") if dl.hit else
             "search stopped early (node budget) before any candidate was found")
        if complete and diag["force_limit"]:
            complete, msg = False, force_limit_message(LAMBDA_LIMIT)
        return KinematicsResult((), complete, msg, time.perf_counter() - t0, IKDiagnostics(**diag), "ik", mech,
                                tuple(float(v) for v in pose), tuple(float(v) for v in w), max_mode, curves,
                                max_winding=max_winding)
    X = np.zeros((len(seg), lay.n_unknowns))
    X[:, lay.pose] = pose
    charts = np.empty((len(seg), 3), np.int64)
    for i in range(3):
        za, zb, ci = zs[i][0], zs[i][1], cs[i]  # a rod in the chart of its branch
        if mech.legs[i].platform_joint.carries_moment and len(ci):  # a near-taut clamped rod: in its window
            za, zb, ci = np.empty_like(za), np.empty_like(zb), np.empty_like(ci)
            segment_charts(cs[i], zs[i][0], zs[i][1], za, zb, ci)
        a, b = za[seg[:, i]], zb[seg[:, i]]
        charts[:, i] = ci[seg[:, i]]
        X[:, lay.rod[i]] = a + s[:, i:i + 1] * (b - a)
        ua, ub = us[i][0][seg[:, i]], us[i][1][seg[:, i]]
        X[:, lay.inputs.start + i] = ua + s[:, i] * (ub - ua)

    # ---- step 3: Newton on the full equations ----------------------------------------------
    if progress is not None:
        progress(0.4, f"Newton on {len(X)} candidates")
    sols = refine(system, mech, X, charts, w, max_mode, "pose", diag, deadline=dl,
                  progress=substage(progress, 0.45, 1.0, "equilibria"), margin=margin, max_winding=max_winding)
    complete = complete and not dl.hit
    msg = "" if sols else "no equilibrium found: the geometric-condition curves admit no point of platform equilibrium"
    if diag.get("continuum"):
        msg = ("singular configuration: straight rods carry axial forces freely, a continuum of equilibria; "
               "the least loaded one is reported")
    if diag.get("out_of_scope_taut"):
        complete = False
        msg = SCOPE_MESSAGE
    if diag["force_limit"]:
        complete = False
        msg = force_limit_message(LAMBDA_LIMIT)
    if not diag["search_complete"] or dl.hit:
        msg = (dl.message("the solution list may be incomplete") if dl.hit else
               "search stopped early (node budget): the solution list may be incomplete")
    res = KinematicsResult(tuple(sols), complete, msg, time.perf_counter() - t0, IKDiagnostics(**diag), "ik", mech,
                           tuple(float(v) for v in pose), tuple(float(v) for v in w), max_mode, curves,
                           max_winding=max_winding)
    return res.select(stable_only=True) if stable_only else res


def _empty_message(curves) -> str:
    empty = [c.leg + 1 for c in curves if len(c) == 0]
    if empty:
        return f"pose unreachable: no rod of leg(s) {', '.join(map(str, empty))} can reach its platform point"
    return "no equilibrium found: the geometric-condition curves admit no point of platform equilibrium"
