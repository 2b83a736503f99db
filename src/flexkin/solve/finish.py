"""From refined candidates to reported solutions (shared by IK and FK).

0. :func:`refine`: Newton from every candidate; with clamped legs, then a Newton deflated by the
   root it found from one start of each root (:func:`near_roots`), which finds the root's near
   neighbours;
1. keep converged candidates whose rods are in scope and of d-mode <= ``max_mode``; equilibria
   found with a pinned rod beyond its scope are counted in ``diag["out_of_scope"]``, and those
   with a rod near straight under tension beyond the seam chart's scope (``lambda L >
   LAMBDA_SCOPE``: where the search for rods down to taut stops) in
   ``diag["out_of_scope_taut"]``, for which the solvers say ``complete = False``
   (:data:`SCOPE_MESSAGE`);
2. canonical inputs and pose (angles wrapped into ``(-pi, pi]``);
3. one solution per equilibrium (:func:`distinct`);
4. stability, Jacobians (batched, :mod:`flexkin.analysis`);
5. :class:`~flexkin.results.Solution` objects sorted by (d-modes, energy, inputs, pose) and
   numbered from 1.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from ..analysis.jacobian import kinematic_jacobians
from ..analysis.stability import mechanism_stability
from ..analysis.verify import verify_solutions
from ..core.budget import Deadline, Rate, timed_slices
from ..core.jit import njit
from ..core.geometry2d import wrap_to_pi
from ..io.progress import Progress, substage
from ..results import Solution
from ..rod.atlas import in_scope
from ..rod.closed_form import mode_of, pinned_chart
from ..rod.elastica import taut_windows
from ..rod.kernels import CHART_LIB, CHART_ROT, CHART_SEAM, CHART_WRENCH, PHI, TH, clamped_mode
from ..rod.seam_atlas import seam_in_scope
from ..rod.slots import X as X_, Y as Y_
from ..rod.wrench_atlas import in_wrench_scope
from ..rod.state import RodState
from ..system import System
from .corrector import RESIDUAL_TOL
from .sliced import newton_within

__all__ = ["refine", "near_roots", "finish_solutions", "build_solutions", "distinct", "canonical", "rod_modes",
           "SCOPE_MESSAGE", "force_limit_message"]

#: why a result is incomplete when the search reached equilibria with a rod near straight under
#: tension beyond the numerical scope
SCOPE_MESSAGE = ("equilibria with a rod near straight under tension beyond the numerical scope (lambda L > 15.9, "
                 "a boundary layer too thin to confirm in double precision) were found and not reported: the "
                 "solution list is incomplete there")


def force_limit_message(lam: float) -> str:
    """Why a result is incomplete when a clamped leg's search reached its force limit
    ``lambda L = lam``."""
    return (f"the search for clamped rods reached its numerical force limit (lambda L = {lam:g}, a tip force of "
            f"{lam * lam:g} EI/L^2) and did not look beyond it: equilibria with a more heavily loaded clamped rod "
            "may be missing")


def canonical(system: System, X: NDArray) -> NDArray[np.float64]:
    """Angles of the unknowns in ``(-pi, pi]``: revolute inputs and the platform orientation."""
    X = np.array(X, dtype=float)
    lay = system.layout
    u = X[:, lay.inputs]
    u[:, system.angular] = wrap_to_pi(u[:, system.angular])
    X[:, lay.inputs] = u
    X[:, lay.pose.start + 2] = wrap_to_pi(X[:, lay.pose.start + 2])
    return X


#: a rod whose base moment (or, for a clamped tip, tip moment) is below this, relative to its
#: moment scale, has an inflection at that end to within the solver's resolution
BOUNDARY_RTOL = 1e-8


def rod_modes(system: System, X: NDArray, charts: NDArray, with_boundary: bool = False):
    """d-mode of every rod (n, 3) (SPEC §2), and with ``with_boundary`` also the ``mode_boundary``
    flags (n, 3): an inflection at an end of the rod to within :data:`BOUNDARY_RTOL`.

    A pinned rod's mode is the number of inflection points on (0, L] (its unified clamp
    amplitude, :func:`~flexkin.rod.closed_form.mode_of`); a base inflection does not count, so
    a rod on the boundary between two modes carries the lower label whichever side the solver
    came from.  A clamped rod's mode is the number of inflections strictly inside (its clamped
    tip is not an inflection).
    """
    n = len(X)
    modes = np.ones((n, 3), np.int64)
    boundary = np.zeros((n, 3), bool)
    for i in range(3):
        z = X[:, system.layout.rod[i]]
        pinned = charts[:, i] < CHART_WRENCH
        if np.any(pinned):
            v, ph = pinned_chart(z[pinned], charts[pinned, i])
            # phis at a base inflection is -pi/2 - j pi: snap to it within the resolution, so
            # that the label is a property of the configuration (the lower one), not of rounding
            j = np.round((-0.5 * np.pi - ph) / np.pi)
            on = (j >= 0) & (np.abs(ph - (-0.5 * np.pi - j * np.pi)) < BOUNDARY_RTOL)
            modes[pinned, i] = np.where(on, j + 1, mode_of(ph))
            boundary[pinned, i] = on
        for k in np.flatnonzero(~pinned):
            modes[k, i], boundary[k, i] = clamped_mode(int(charts[k, i]), np.ascontiguousarray(z[k], dtype=float),
                                                        BOUNDARY_RTOL)
    return (modes, boundary) if with_boundary else modes


def _in_scope(system: System, X: NDArray, charts: NDArray, modes: NDArray, max_mode: int, max_winding: int
              ) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """Solutions whose rods are all in the searched set, as three masks: the unified-chart pinned
    rods (``k' >= KPRIME_MIN / 2``, :mod:`flexkin.rod.atlas`), the seam-chart pinned rods (near
    straight under tension, ``lambda L <= LAMBDA_SCOPE``, :mod:`flexkin.rod.seam_atlas`: ``k'``
    goes to 0 there at any tension) and the clamped rods (d-mode and winding within SPEC §2's
    scope, :func:`~flexkin.rod.wrench_atlas.in_wrench_scope`)."""
    ok_u, ok_s, ok_c = (np.ones(len(X), bool) for _ in range(3))
    if len(X) == 0:
        return ok_u, ok_s, ok_c
    q, _ = system.unit_rods(X, charts)
    for i in range(3):
        z = X[:, system.layout.rod[i]]
        seam = charts[:, i] == CHART_SEAM
        clamped = charts[:, i] >= CHART_WRENCH
        unified = ~seam & ~clamped
        if np.any(unified):
            ok_u[unified] &= in_scope(z[unified, :1])
        if np.any(seam):
            ok_s[seam] &= seam_in_scope(q[seam, i, PHI])
        if np.any(clamped):
            ok_c[clamped] &= in_wrench_scope(q[clamped, i, TH], modes[clamped, i], max_mode, max_winding)
    return ok_u, ok_s, ok_c


#: a rod whose unit tip lies within this of (1, 0) is straight over its whole length (an
#: inextensible rod reaches its full length only when straight)
STRAIGHT_TOL = 1e-9


@njit
def _distinct(order, geo, rod, straight, fmag):
    """The compiled loops of :func:`distinct`: the first candidate (in ``order``) of every
    equilibrium, then the least loaded one of every continuum of straight rods."""
    chosen = np.empty(order.shape[0], np.int64)
    nc = 0
    for i in order:
        same = False
        for c in range(nc):
            k = chosen[c]
            d = 0.0
            for j in range(geo.shape[1]):
                d = max(d, abs(geo[k, j] - geo[i, j]))
            if d > 1e-6:
                continue
            d = 0.0
            for j in range(rod.shape[1]):
                d = max(d, abs(rod[k, j] - rod[i, j]))
            if d <= 1e-6:
                same = True
                break
        if not same:
            chosen[nc] = i
            nc += 1
    chosen = chosen[:nc]
    by_load = chosen[np.argsort(fmag[chosen], kind="mergesort")]
    keep = np.empty(nc, np.int64)
    nk = 0
    for a in by_load:
        merged = False
        for c in range(nk):
            b = keep[c]
            d = 0.0
            for j in range(geo.shape[1]):
                d = max(d, abs(geo[a, j] - geo[b, j]))
            if d > 1e-8:
                continue
            ok = True
            for r in range(3):
                d = 0.0
                for j in range(3):
                    d = max(d, abs(rod[a, 3 * r + j] - rod[b, 3 * r + j]))
                if d > 1e-6 and not (straight[a, r] and straight[b, r]):
                    ok = False
            if ok:
                merged = True
                break
        if not merged:
            keep[nk] = a
            nk += 1
    return chosen, keep[:nk]


def distinct(system: System, X: NDArray, charts: NDArray, residual: NDArray,
             diag: dict[str, Any] | None = None) -> NDArray[np.int64]:
    """Indices of one candidate per equilibrium (the smallest residual of each).

    Two candidates are one equilibrium only when their whole rod shapes agree: the pose, the
    inputs and every rod's tip force and base moment (which fix the shape by the closed form)
    agree to 1e-6 (scaled).  Equal end tangents are *not* enough -- the first and the second
    buckled shape of a pinned-pinned rod have equal inputs and tangents and forces 1 : 4.

    The one exception is a continuum: a rod that is straight over its whole length carries any
    axial force in the same configuration (a singular configuration).  Candidates that differ
    only in the axial forces of rods straight in both are merged; the least loaded is kept and
    ``diag["continuum"]`` counts the merged family.
    """
    if len(X) == 0:
        return np.zeros(0, np.int64)
    lay = system.layout
    w = system.rod_world(X, charts)
    q, _ = system.unit_rods(X, charts)
    sx = np.array([system.L_ref, system.L_ref, 1.0])
    su = system.input_scale()
    geo = np.concatenate([X[:, lay.pose] / sx, X[:, lay.inputs] / su], axis=1)
    rod = np.concatenate([w["force"] / system.F_ref,
                          w["base_moment"][..., None] / (system.F_ref * system.L_ref)], axis=2)  # (n, 3, 3)
    straight = (np.abs(q[..., X_] - 1.0) < STRAIGHT_TOL) & (np.abs(q[..., Y_]) < STRAIGHT_TOL)
    order = np.argsort(residual, kind="stable")
    fmag = np.sum(np.abs(w["force"].reshape(-1, 6)), axis=1)
    chosen, keep = _distinct(order, np.ascontiguousarray(geo), np.ascontiguousarray(rod.reshape(-1, 9)),
                             straight, fmag)
    chosen = list(chosen)
    keep = list(keep)
    if diag is not None and len(keep) < len(chosen):
        diag["continuum"] = len(chosen) - len(keep) + 1
    return np.array(sorted(keep), dtype=np.int64)


#: seconds to build one solution (stability, Jacobians, verification) before anything is measured
BUILD_COST = 3e-3


def finish_solutions(system: System, mech, X: NDArray, charts: NDArray, residual: NDArray, max_mode: int,
                     load: NDArray, diag: dict[str, Any] | None = None, fixed: str = "pose",
                     deadline: Deadline | None = None,
                     progress: Callable[[float, str], None] | None = None, margin: bool = False,
                     max_winding: int = 1) -> list[Solution]:
    """Reported solutions from refined candidates (module docstring); ``fixed`` is what the
    analysis held (``"pose"`` for IK, ``"inputs"`` for FK): its Newton matrix gives ``condition``;
    ``margin`` computes the stability margins now (else on first use); clamped rods with
    ``|winding| > max_winding`` are out of scope.
    With a ``deadline`` the solutions are built in slices while the time allows; those left
    unbuilt are dropped and the deadline is :attr:`~flexkin.core.budget.Deadline.hit`.
    ``progress(fraction, stage)`` is told how far the analysis has got."""
    X = canonical(system, X)
    modes = rod_modes(system, X, charts)
    ok = np.all(modes <= max_mode, axis=1) & np.all(np.isfinite(X), axis=1)
    ok_u, ok_s, ok_c = _in_scope(system, X[ok], charts[ok], modes[ok], max_mode, max_winding)
    if diag is not None and not np.all(ok_u & ok_s):  # equilibria the numerics cannot confirm: counted
        idx = np.flatnonzero(ok)
        for key, bad in (("out_of_scope", ~(ok_u & ok_s) & ok_c), ("out_of_scope_taut", ~ok_s & ok_c)):
            out = idx[bad]
            diag[key] = int(len(distinct(system, X[out], charts[out], residual[out]))) if len(out) else 0
    ok[ok] &= ok_u & ok_s & ok_c
    X, charts, residual, modes = X[ok], charts[ok], residual[ok], modes[ok]
    if len(X) == 0:
        return []
    idx = distinct(system, X, charts, residual, diag)
    dl = deadline if deadline is not None else Deadline()
    rate = Rate(BUILD_COST)
    sols = []
    n = len(idx)
    for lo, hi in timed_slices(n, dl, rate, first=1):  # one first: a solution can cost 0.3 s
        t = time.perf_counter()
        k = idx[lo:hi]
        sols += build_solutions(system, mech, X[k], charts[k], load, residual[k], modes[k], fixed,
                                substage(progress, lo / n, hi / n, ""), margin=margin)
        rate.add(hi - lo, time.perf_counter() - t)
    escale = system.F_ref * system.L_ref
    sols.sort(key=lambda s: (s.modes, round(s.energy / escale, 9), tuple(s.inputs), tuple(s.pose)))
    return [_with_id(s, k + 1) for k, s in enumerate(sols)]


def build_solutions(system: System, mech, X: NDArray, charts: NDArray, load: NDArray,
                    residual: NDArray | None = None, modes: NDArray | None = None,
                    fixed: str = "pose", progress: Callable[[float, str], None] | None = None,
                    margin: bool = False, stability: Any = None) -> list[Solution]:
    """:class:`~flexkin.results.Solution` objects (with stability, Jacobians and the independent
    check of :mod:`flexkin.analysis.verify`: ``verified``, ``condition``) for equilibria ``X``
    (n, n_unknowns) in ``charts`` (n, 3); residuals are recomputed when not given.  ``fixed``
    (``"pose"`` or ``"inputs"``) selects the Newton matrix whose condition is reported;
    ``margin`` computes the stability margins now (else on first use); ``stability`` (a
    :class:`~flexkin.analysis.stability.StabilityArrays`) if already computed."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    charts = np.atleast_2d(np.asarray(charts, dtype=np.int64))
    if len(X) == 0:
        return []
    if residual is None:
        residual = np.max(np.abs(system.residual(X, charts, load)), axis=1)
    modes_b, boundary = rod_modes(system, X, charts, with_boundary=True)
    if modes is None:
        modes = modes_b
    stab = _stability(system, X, charts, progress, margin) if stability is None else stability
    jac = kinematic_jacobians(system, X, charts, load)
    check = verify_solutions(system, X, charts, load, modes, boundary, fixed)
    q, _ = system.unit_rods(X, charts)
    lay = system.layout
    A, alpha, L = system.clamps(X[:, lay.inputs])
    n = len(X)
    coords = np.zeros((n, 3, 3))
    for i in range(3):
        zi = X[:, lay.rod[i]]
        coords[:, i, :zi.shape[1]] = zi
    dims = np.broadcast_to([lay.rod[i].stop - lay.rod[i].start for i in range(3)], (n, 3)).ravel()
    flat = RodState.many(q.reshape(n * 3, -1), charts.reshape(-1), coords.reshape(n * 3, 3), L.reshape(-1),
                         np.tile(system.EI, n), A.reshape(n * 3, 2), alpha.reshape(-1), modes.reshape(-1),
                         tuple(mech.legs[i].joint for _ in range(n) for i in range(3)), boundary.reshape(-1), dims)
    sols = []
    for j in range(n):
        rods = tuple(flat[3 * j:3 * j + 3])
        st = stab.item(j)
        sols.append(Solution(mech, tuple(float(v) for v in X[j, lay.pose]), tuple(float(v) for v in X[j, lay.inputs]),
                             tuple(int(v) for v in modes[j]),
                             rods, X[j].copy(), charts[j].copy(), float(residual[j]), st,
                             jac.item(j, system.L_ref), verified=bool(check.verified[j]),
                             condition=float(check.condition[j]), verify_error=float(check.error[j])))
    return sols


#: equilibria per batch of the stability analysis when progress is reported
PROGRESS_BATCH = 8


def _stability(system: System, X: NDArray, charts: NDArray, progress: Callable[[float, str], None] | None,
               margin: bool = False):
    """:func:`mechanism_stability`, in batches reporting ``progress`` when it is given (the
    stability of each equilibrium is computed on its own, so the batches change nothing)."""
    n = len(X)
    if progress is None or n <= PROGRESS_BATCH:
        out = mechanism_stability(system, X, charts, margin=margin)
    else:
        parts = []
        for k in range(0, n, PROGRESS_BATCH):
            progress(k / n, f"stability {k} of {n}")
            parts.append(mechanism_stability(system, X[k:k + PROGRESS_BATCH], charts[k:k + PROGRESS_BATCH],
                                             margin=margin))
        # the eigenvectors (kept for continuations, which do not report progress) are not joined
        out = type(parts[0])(**{f.name: np.concatenate([getattr(q, f.name) for q in parts])
                                for f in dataclasses.fields(parts[0]) if f.name != "pairs"})
    if progress is not None:
        progress(1.0, "Jacobians and verification")
    return out


def _with_id(s: Solution, k: int) -> Solution:
    """Number a solution just built (not yet shared): set in place, not copied."""
    object.__setattr__(s, "id", k)
    return s


def _taut_in_windows(system: System, X: NDArray, charts: NDArray) -> tuple[NDArray, NDArray]:
    """Candidates with every taut clamped rod of the wrench chart moved to its elastica window
    (:func:`~flexkin.rod.elastica.taut_windows`), where the Newton resolves it."""
    if not np.any(charts == CHART_WRENCH):
        return X, charts
    X = np.array(X, dtype=float)
    charts = np.array(charts, dtype=np.int64)
    for i in range(3):
        sl = system.layout.rod[i]
        if sl.stop - sl.start != 3:
            continue
        Z = np.ascontiguousarray(X[:, sl])
        ch = np.ascontiguousarray(charts[:, i])
        if taut_windows(ch, Z, CHART_WRENCH, CHART_LIB, CHART_ROT):
            X[:, sl], charts[:, i] = Z, ch
    return X, charts


def refine(system: System, mech, X: NDArray, charts: NDArray, load: NDArray, max_mode: int, held: str = "pose",
           diag: dict[str, Any] | None = None, deadline: Deadline | None = None,
           progress: Progress | None = None, margin: bool = False, max_winding: int = 1) -> list[Solution]:
    """Newton-refine candidates ``X`` and build the solutions: IK and FK share this finish.
    With clamped legs the near neighbours of every root are looked for too (:func:`near_roots`).

    Parameters
    ----------
    system : System
        The equation system of ``mech``.
    mech : Mechanism
        The mechanism.
    X : (n, n_unknowns) array
        Candidates.
    charts : (n, 3) int array
        Their rods' charts.
    load : (3,) array
        The load wrench.
    max_mode : int
        Largest d-mode reported.
    held : {"pose", "inputs"}
        What the Newton holds fixed: the pose (IK) or the inputs (FK).
    diag : dict, optional
        Diagnostics, told ``converged`` and what :func:`finish_solutions` counts.
    deadline : Deadline, optional
        What it leaves no time for is dropped and the deadline is hit.
    progress : callable, optional
        ``progress(fraction, stage)``.
    margin : bool
        Compute the stability margins now.
    max_winding : int
        Largest ``|winding|`` of a clamped rod reported (SPEC §2).

    Returns
    -------
    list of Solution
    """
    X, charts = _taut_in_windows(system, X, charts)
    res = newton_within(system, X, charts, load, held, deadline)
    good = res.residual <= RESIDUAL_TOL
    x, ch, resid = res.x[good], res.charts[good], res.residual[good]
    if np.any(system.clamped):  # the traced curves' chords (module docstring of near_roots)
        starts = _one_start_per_root(system, X, res.x, good, held)
        # a search for more roots: it leaves the budget's last share for building the solutions
        more = near_roots(system, X[starts], charts[starts], res.x[starts], load, held,
                          None if deadline is None else deadline.for_search())
        x, ch, resid = (np.concatenate([a, b]) for a, b in zip((x, ch, resid), more))
    if diag is not None:
        diag["converged"] = int(len(x))
    return finish_solutions(system, mech, x, ch, resid, max_mode, load, diag,
                            held, deadline=deadline, progress=progress, margin=margin, max_winding=max_winding)


def _one_start_per_root(system: System, X: NDArray, R: NDArray, good: NDArray, held: str) -> NDArray[np.int64]:
    """Indices of the converged candidates: for each distinct root ``R`` (to 1e-6 of the unknowns'
    scales), the start ``X`` nearest to it."""
    idx = np.flatnonzero(good)
    if len(idx) == 0:
        return idx
    cols = system.layout.columns(held)
    sc = system.unknown_scale()[cols]
    keys = np.round(R[idx][:, cols] / sc / 1e-6)
    _, group = np.unique(keys, axis=0, return_inverse=True)
    dist = np.max(np.abs(X[idx][:, cols] - R[idx][:, cols]) / sc, axis=1)
    order = np.lexsort((dist, group.ravel()))
    first = np.ones(len(order), bool)
    first[1:] = group.ravel()[order][1:] != group.ravel()[order][:-1]
    return idx[order[first]]


#: rounds of deflated Newton from each start that converged (:func:`near_roots`)
DEFLATION_ROUNDS = 2
#: iterations of one deflated Newton
DEFLATED_ITER = 25


def near_roots(system: System, X: NDArray, charts: NDArray, roots: NDArray, load: NDArray, held: str,
               deadline: Deadline | None = None) -> tuple[NDArray, NDArray, NDArray]:
    """Equilibria next to the ``roots`` that the Newton found from the starts ``X``: from each
    start, a Newton deflated by its root (:mod:`flexkin.solve.corrector`), then by the roots
    found so far, for :data:`DEFLATION_ROUNDS` rounds.

    A chord of the polylines (IK) or a lattice pose (FK) is one start, and Newton from it finds
    one root; two equilibria closer than the chords' spacing -- a near-fold pair, or the
    clusters of equilibria of taut rods with loops, whose positions along the rod change the
    energy only by ``exp(-lambda L)`` -- give one of them.  Deflation finds the other.

    :func:`refine` runs it for the mechanisms with clamped legs: their curves are traced with steps
    in the rods' coordinates, which grow to tens of EI/L^2 in the tip force of a taut rod (the
    unit 3-PF at (0, 0, 0) lost 6 equilibria in clusters without it), while a pinned leg's
    polylines are bisected to a relative force resolution (:mod:`flexkin.solve.pinned_curves`).
    Each deflated Newton stops after :data:`DEFLATED_ITER` iterations (the six equilibria it adds
    at the unit 3-PF's (0, 0, 0) take up to 15; 40 found nothing more on four clamped cases and
    cost half as much again).

    Parameters
    ----------
    system : System
        The equation system.
    X : (n, n_unknowns) array
        Starts (as given to the plain Newton).
    charts : (n, 3) int array
        Their rods' charts.
    roots : (n, n_unknowns) array
        The root the plain Newton found from each start.
    load : (3,) array
        The load wrench.
    held : {"pose", "inputs"}
        What the Newton holds fixed.
    deadline : Deadline, optional
        Looked at between rounds and slices; when it cuts the deflation short it is
        :attr:`~flexkin.core.budget.Deadline.hit` (the answer is then not complete).

    Returns
    -------
    x, charts, residual : arrays
        The converged roots found (n_unknowns columns), their charts and residuals; some may
        be roots found before (:func:`distinct` merges them).
    """
    n, nu = X.shape
    found_x, found_c, found_r = [np.zeros((0, nu))], [np.zeros((0, 3), np.int64)], [np.zeros(0)]
    if n == 0 or (deadline is not None and deadline.expired()):
        return found_x[0], found_c[0], found_r[0]
    D = np.zeros((n, DEFLATION_ROUNDS, nu))
    D[:, 0] = roots
    counts = np.ones(n, np.int64)
    todo = np.arange(n)
    for rnd in range(DEFLATION_ROUNDS):
        res = newton_within(system, X[todo], charts[todo], load, held, deadline, deflate=(D[todo], counts[todo]),
                            max_iter=DEFLATED_ITER)
        ok = res.residual <= RESIDUAL_TOL
        found_x.append(res.x[ok])
        found_c.append(res.charts[ok])
        found_r.append(res.residual[ok])
        todo = todo[:len(ok)][ok]
        if rnd + 1 == DEFLATION_ROUNDS or not len(todo) or (deadline is not None and deadline.expired()):
            break
        D[todo, counts[todo]] = res.x[ok]
        counts[todo] += 1
    return np.concatenate(found_x), np.concatenate(found_c), np.concatenate(found_r)
