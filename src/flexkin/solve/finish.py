"""From refined candidates to reported solutions (shared by IK and FK).

1. keep converged candidates whose rods are in scope and of d-mode <= ``max_mode``;
2. canonical inputs and pose (angles wrapped into ``(-pi, pi]``);
3. one solution per equilibrium (:func:`distinct`);
4. stability, Jacobians (batched, :mod:`flexkin.analysis`);
5. :class:`~flexkin.results.Solution` objects sorted by (d-modes, energy, inputs, pose) and
   numbered from 1.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..analysis.jacobian import kinematic_jacobians
from ..analysis.stability import mechanism_stability
from ..analysis.verify import verify_solutions
from ..core.jit import njit
from ..core.geometry2d import wrap_to_pi
from ..results import Solution
from ..rod.atlas import in_scope
from ..rod.closed_form import mode_of, standard_chart
from ..rod.kernels import CHART_WRENCH, TH
from ..rod.slots import X as X_, Y as Y_
from ..rod.wrench import wrench_mode
from ..rod.wrench_atlas import in_wrench_scope
from ..rod.state import RodState
from ..system import System

__all__ = ["finish_solutions", "build_solutions", "distinct", "canonical", "rod_modes"]


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
    came from.  A clamped rod's mode is 1 + the inflections strictly inside.
    """
    n = len(X)
    modes = np.ones((n, 3), np.int64)
    boundary = np.zeros((n, 3), bool)
    for i in range(3):
        z = X[:, system.layout.rod[i]]
        pinned = charts[:, i] != CHART_WRENCH
        if np.any(pinned):
            v, ph = standard_chart(z[pinned, 0], z[pinned, 1])
            # phis at a base inflection is -pi/2 - j pi: snap to it within the resolution, so
            # that the label is a property of the configuration (the lower one), not of rounding
            j = np.round((-0.5 * np.pi - ph) / np.pi)
            on = (j >= 0) & (np.abs(ph - (-0.5 * np.pi - j * np.pi)) < BOUNDARY_RTOL)
            modes[pinned, i] = np.where(on, j + 1, mode_of(ph))
            boundary[pinned, i] = on
        for k in np.flatnonzero(~pinned):
            modes[k, i], boundary[k, i] = wrench_mode(z[k, 0], z[k, 1], z[k, 2], BOUNDARY_RTOL)
    return (modes, boundary) if with_boundary else modes


def _in_scope(system: System, X: NDArray, charts: NDArray, modes: NDArray, max_mode: int) -> NDArray[np.bool_]:
    """Solutions whose rods are all in the searched set: pinned rods with ``k' >= KPRIME_MIN / 2``
    (:mod:`flexkin.rod.atlas`), clamped rods within the wrench atlas' scope
    (:func:`~flexkin.rod.wrench_atlas.in_wrench_scope`)."""
    ok = np.ones(len(X), bool)
    if len(X) == 0:
        return ok
    q, _ = system.unit_rods(X, charts)
    for i in range(3):
        z = X[:, system.layout.rod[i]]
        pinned = charts[:, i] != CHART_WRENCH
        if np.any(pinned):
            v, _ = standard_chart(z[pinned, 0], z[pinned, 1])
            ok[pinned] &= in_scope(v[:, None])
        if np.any(~pinned):
            ok[~pinned] &= in_wrench_scope(z[~pinned], q[~pinned, i, TH], modes[~pinned, i], max_mode)
    return ok


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


def finish_solutions(system: System, mech, X: NDArray, charts: NDArray, residual: NDArray, max_mode: int,
                     load: NDArray, diag: dict[str, Any] | None = None, fixed: str = "pose",
                     margin: bool = False) -> list[Solution]:
    """Reported solutions from refined candidates (module docstring); ``fixed`` is what the
    analysis held (``"pose"`` for IK, ``"inputs"`` for FK): its Newton matrix gives ``condition``;
    ``margin`` computes the stability margins now (else on first use)."""
    X = canonical(system, X)
    modes = rod_modes(system, X, charts)
    ok = np.all(modes <= max_mode, axis=1) & np.all(np.isfinite(X), axis=1)
    ok[ok] &= _in_scope(system, X[ok], charts[ok], modes[ok], max_mode)
    X, charts, residual, modes = X[ok], charts[ok], residual[ok], modes[ok]
    if len(X) == 0:
        return []
    idx = distinct(system, X, charts, residual, diag)
    sols = build_solutions(system, mech, X[idx], charts[idx], load, residual[idx], modes[idx], fixed, margin)
    escale = system.F_ref * system.L_ref
    sols.sort(key=lambda s: (s.modes, round(s.energy / escale, 9), tuple(s.inputs), tuple(s.pose)))
    return [_with_id(s, k + 1) for k, s in enumerate(sols)]


def build_solutions(system: System, mech, X: NDArray, charts: NDArray, load: NDArray,
                    residual: NDArray | None = None, modes: NDArray | None = None,
                    fixed: str = "pose", margin: bool = False, stability: Any = None) -> list[Solution]:
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
    stab = mechanism_stability(system, X, charts, margin=margin) if stability is None else stability
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


def _with_id(s: Solution, k: int) -> Solution:
    import dataclasses

    return dataclasses.replace(s, id=k)
