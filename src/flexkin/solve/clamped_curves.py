"""Geometric-condition curves of the clamped legs (paper §4.1 with §8's tip condition), compiled.

For a clamped leg the rods that can be the leg's rod at a given pose satisfy two conditions on
the unit rod: the actuator's geometric condition on its tip (:mod:`flexkin.solve.conditions`)
and the tip angle ``alpha + theta(L) = theta_P + tip_angle``.  In the three-dimensional wrench
chart (:mod:`flexkin.rod.wrench`) they form curves, one-parameter families like a pinned leg's
curves of Fig. 7.  They are found by

1. **seeds**: the cells of the wrench atlas (:mod:`flexkin.rod.wrench_atlas`) whose corners
   bracket both conditions (the angle modulo 2 pi), each projected onto the curve by
   minimum-norm Newton;
2. **tracing**: predictor-corrector continuation along the tangent ``grad g1 x grad g2`` in
   both directions from a seed, until the curve leaves the searched set, closes on itself or
   the step budget ends; cells a traced curve passes through are not seeded again.

The output polylines carry everything the equilibrium search needs (wrench, input, chart
coordinates), like :func:`flexkin.solve.curves.leg_curves` does for pinned legs.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import types
from numba.typed import Dict
from numpy.typing import NDArray

from ..core.geometry2d import rotate
from ..core.geometry2d_kernels import wrap_angle
from ..core.jit import njit
from ..rod.elastica import SENS_WINDOW, SENS_WRENCH, reduce_window, tip_sensitivity, window_of
from ..rod.elliptic import complete
from ..rod.kernels import clamped_mode, eval_rod, project
from ..rod.orbit import modulus
from ..rod.slots import (
    CHART_LIB,
    CHART_ROT,
    CHART_WRENCH,
    EN,
    FX,
    FY,
    M0,
    ML,
    NQ,
    PHI,
    TH,
    X,
    Y,
)
from ..rod.wrench import wrench_eval
from ..rod.wrench_atlas import get_wrench_atlas, lambda_max, moment_extra, turning_max
from .conditions import condition_eval
from .leg_curve import LegCurve

__all__ = ["clamped_leg_curve", "segment_charts"]

TWO_PI = 2.0 * math.pi
#: turning (rad) traced beyond the winding scope, which is applied exactly to refined solutions
TURN_MARGIN = 0.5
MAX_POINTS = 4000
#: Newton iterations without a new smallest residual after which a projection onto the curve
#: gives up (on the unit 3-PF, a fifth of the elliptic-grid seeds never converged and took all
#: of their 30 iterations: a third of the curves' cost)
STALL = 4
#: the elliptic grids seed the rods from this fraction of the wrench atlas' ``lambda L`` range on
#: (:func:`_elliptic_seeds`; seeding every rod of the grids cost a third of the unit 3-PF's IK and
#: found no solution more on four test cases, even from 0.875 of the range on)
ELLIPTIC_FROM = 0.6
#: largest tracing step (in the chart's scaled coordinates, :func:`_metric`)
H_MAX = 0.05
#: ``lambda L`` at which a trace stops: the search's numerical force limit (a tip force of
#: 4096 EI/L^2; the elastica windows resolve taut rods far beyond it, the limit bounds the work
#: of tracing the curves' tails towards the straight rod under infinite tension)
LAMBDA_LIMIT = 64.0


#: chart switches traced at most from one seed in one direction
MAX_SWITCHES = 12
#: the traced-curve record's grid of base wrenches: lambda nodes, directions, base moments
N_VISIT = (128, 96, 97)


@njit
def _G(chart, z, code, p0, p1, tgt, q, gr, J):
    """Residual ``(g, angle)`` of the two conditions at ``z`` (chart ``chart``), its Jacobian
    ``J`` (2, 3) and whether the tip is admissible."""
    eval_rod(chart, z, q, gr)
    g, gx, gy, al, ax, ay, adm = condition_eval(code, p0, p1, q[X], q[Y])
    for c in range(3):
        J[0, c] = gx * gr[X, c] + gy * gr[Y, c]
        J[1, c] = gr[TH, c] + ax * gr[X, c] + ay * gr[Y, c]
    return g, wrap_angle(al + q[TH] - tgt), adm


@njit
def _correct(chart, z, code, p0, p1, tgt, q, gr, J, iters, tol) -> bool:
    """Minimum-norm Newton onto the curve (in place); True when it converged.  An iteration
    that has not reduced the residual below its best for :data:`STALL` iterations has stalled
    (cycling or diverging, as a seed far from the curve does) and gives up."""
    best = 1e300
    since = 0
    for _ in range(iters):
        g0, g1, adm = _G(chart, z, code, p0, p1, tgt, q, gr, J)
        if not (g0 == g0 and g1 == g1):
            return False
        r = max(abs(g0), abs(g1))
        if r < tol:
            return True
        if r < best:
            best, since = r, 0
        else:
            since += 1
            if since >= STALL:
                return False
        a = J[0, 0] * J[0, 0] + J[0, 1] * J[0, 1] + J[0, 2] * J[0, 2]
        b = J[0, 0] * J[1, 0] + J[0, 1] * J[1, 1] + J[0, 2] * J[1, 2]
        d = J[1, 0] * J[1, 0] + J[1, 1] * J[1, 1] + J[1, 2] * J[1, 2]
        det = a * d - b * b
        if not abs(det) > 1e-300:
            return False
        w0 = (d * g0 - b * g1) / det
        w1 = (-b * g0 + a * g1) / det
        for c in range(3):
            z[c] -= J[0, c] * w0 + J[1, c] * w1
        if chart != CHART_WRENCH:
            project(chart, z)
    g0, g1, adm = _G(chart, z, code, p0, p1, tgt, q, gr, J)
    return max(abs(g0), abs(g1)) < tol


@njit
def _metric(chart, z, q, mext) -> tuple:
    """Per-coordinate scales of the chart near ``z`` (the atlas' cell sizes grow with the load;
    an elastica window's times with ``lambda L``)."""
    if chart != CHART_WRENCH:
        sc = 1.0 + 0.1 * q[PHI]
        return sc, sc, sc
    R = math.hypot(z[0], z[1])
    lam = math.sqrt(R)
    sf = 1.0 + R
    sm = 1.0 + 2.0 * lam + mext
    return sf, sf, sm


@njit
def _rechart(chart, z, q, sens, znew) -> int:
    """The chart a trace at ``z`` (evaluated into ``q``; ``sens`` the wrench chart's tip
    sensitivity there, :func:`_sensitivity`) continues in (its coordinates into ``znew``): the
    rod's elastica window once ``sens`` passes :data:`SENS_WINDOW`, the wrench chart again below
    :data:`SENS_WRENCH`; ``chart`` if no change."""
    if chart == CHART_WRENCH:
        if sens <= SENS_WINDOW or not q[PHI] > 0.0:
            return chart
        rot, v, us, ue = window_of(z[0], z[1], z[2])
        if not v == v:
            return chart
        znew[0], znew[1], znew[2] = v, us, ue
        return CHART_ROT if rot else CHART_LIB
    if sens >= SENS_WRENCH:
        return chart
    znew[0], znew[1], znew[2] = q[FX], q[FY], q[M0]
    return CHART_WRENCH


@njit
def _cell(w, lam_nodes, npsi, nt, mext):
    """Atlas cell (i, j, k) containing the base wrench ``w`` (-1 if outside)."""
    R = math.hypot(w[0], w[1])
    lam = math.sqrt(R)
    nl = lam_nodes.shape[0]
    if lam >= lam_nodes[nl - 1]:
        return -1, -1, -1
    i = 0
    while i < nl - 2 and lam_nodes[i + 1] <= lam:
        i += 1
    psi = math.atan2(w[1], w[0])
    if psi < 0.0:
        psi += TWO_PI
    j = int(psi / (TWO_PI / npsi)) % npsi
    t = w[2] / (2.0 * lam + mext)
    k = int((t + 1.0) * 0.5 * (nt - 1))
    if k < 0 or k >= nt - 1:
        return -1, -1, -1
    return i, j, k


@njit
def _visit(w, lam_nodes, npsi, nt, mext, visited) -> None:
    """Mark the cell of the base wrench ``w`` as traced."""
    i, j, k = _cell(w, lam_nodes, npsi, nt, mext)
    if i < 0:
        return
    visited[i, j, k] = True


@njit
def _visit_segment(wa, wb, lam_nodes, npsi, nt, mext, visited) -> None:
    """Mark every cell the chord ``wa -> wb`` (base wrenches) passes through (subdivided where it
    jumps cells)."""
    ia, ja, ka = _cell(wa, lam_nodes, npsi, nt, mext)
    ib, jb, kb = _cell(wb, lam_nodes, npsi, nt, mext)
    dj = abs(ja - jb)
    dj = min(dj, npsi - dj)
    m = max(abs(ia - ib), dj, abs(ka - kb)) + 1
    if ia < 0 or ib < 0:
        m = 8
    m = min(m, 64)
    zc = np.empty(3)
    for r in range(m + 1):
        f = r / m
        zc[0] = wa[0] + f * (wb[0] - wa[0])
        zc[1] = wa[1] + f * (wb[1] - wa[1])
        zc[2] = wa[2] + f * (wb[2] - wa[2])
        _visit(zc, lam_nodes, npsi, nt, mext, visited)


#: cell sizes of the traced-window record: ``v``, ``u_s`` (reduced by whole periods), ``u_e - u_s``
WIN_CELL = (0.25, 0.25, 0.5)


@njit
def _wkey(chart, z) -> int:
    """Key of the cell of the elastica window ``z`` (chart ``chart``) in the traced-window record
    (a librating window of ``-v`` is the same rod shifted by half a period)."""
    v, us, ue = z[0], z[1], z[2]
    if chart == CHART_LIB and v < 0.0:
        k, kp = modulus(v)
        K = complete(k * k, kp * kp)[0]
        v, us, ue = -v, us + 2.0 * K, ue + 2.0 * K
    us, ue = reduce_window(chart == CHART_ROT, v, us, ue)
    iv = min(max(int(math.floor(v / WIN_CELL[0])), -1000), 1000) + 1000
    iu = min(max(int(math.floor(us / WIN_CELL[1])), -4000), 4000) + 4000
    il = min(max(int(math.floor((ue - us) / WIN_CELL[2])), -4000), 4000) + 4000
    return (((chart - CHART_LIB) * 2001 + iv) * 8001 + iu) * 8001 + il


@njit
def _mark(chart, za, zb, wa, wb, lam_nodes, npsi, nt, mext, visited, wvisited, windows) -> None:
    """Record the segment ``za -> zb`` (chart ``chart``; base wrenches ``wa``, ``wb``) as traced:
    the wrench-atlas cells of its base wrenches and, with ``windows`` (a rod near taut, where
    seeds are looked up by their windows, :func:`_trace_all`), the cells of its elastica windows."""
    _visit_segment(wa, wb, lam_nodes, npsi, nt, mext, visited)
    if not windows:
        return
    ya, yb = np.empty(3), np.empty(3)
    ch = chart
    if chart == CHART_WRENCH:
        ra, ya[0], ya[1], ya[2] = window_of(wa[0], wa[1], wa[2])
        rb, yb[0], yb[1], yb[2] = window_of(wb[0], wb[1], wb[2])
        if ra != rb or not (ya[0] == ya[0] and yb[0] == yb[0]):
            return
        ch = CHART_ROT if ra else CHART_LIB
    else:
        ya[:] = za
        yb[:] = zb
    m = 1
    for c in range(3):
        m = max(m, int(abs(yb[c] - ya[c]) / WIN_CELL[c]) + 1)
    m = min(m, 64)
    zc = np.empty(3)
    for r in range(m + 1):
        f = r / m
        for c in range(3):
            zc[c] = ya[c] + f * (yb[c] - ya[c])
        wvisited[_wkey(ch, zc)] = True


@njit
def _near_traced(w, lam_nodes, npsi, nt, mext, visited) -> bool:
    """Whether the wrench-atlas cell of the base wrench ``w`` or one of its 26 neighbours was
    traced (a curve passing close to a cell boundary may have marked the neighbour only)."""
    i, j, k = _cell(w, lam_nodes, npsi, nt, mext)
    if i < 0:
        return False
    ni, nk = visited.shape[0], visited.shape[2]
    for di in range(-1, 2):
        for dj in range(-1, 2):
            for dk in range(-1, 2):
                ii, kk = i + di, k + dk
                if 0 <= ii < ni and 0 <= kk < nk and visited[ii, (j + dj) % npsi, kk]:
                    return True
    return False


@njit
def _near_traced_window(chart, z, wvisited) -> bool:
    """Whether the cell of the elastica window ``z`` or one of its 26 neighbours was traced."""
    zc = np.empty(3)
    for di in range(-1, 2):
        for dj in range(-1, 2):
            for dk in range(-1, 2):
                zc[0] = z[0] + di * WIN_CELL[0]
                zc[1] = z[1] + dj * WIN_CELL[1]
                zc[2] = z[2] + dk * WIN_CELL[2]
                if _wkey(chart, zc) in wvisited:
                    return True
    return False


@njit
def _in_scope(chart, z, q, mode, max_mode, lam_max, turn_max) -> int:
    """0 if the rod ``z`` (chart ``chart``, evaluated into ``q``) is searched; 1 if its
    ``lambda L`` is beyond the search's numerical limit ``lam_max``; 2 if it is outside the scope
    (turning or d-mode).  ``mode`` is its d-mode when known, else negative (computed only when
    the cheaper tests pass)."""
    if q[PHI] > lam_max:
        return 1
    if abs(q[TH]) > turn_max + 1e-9:
        return 2
    if mode < 0:
        mode = clamped_mode(chart, z, 1e-9)[0]
    return 0 if mode <= max_mode else 2


#: columns of a traced point (:func:`_store`): the chart coordinates (0-2), then the unit rod's
#: tip, tip force, tip moment, energy and d-mode (what the equilibrium search needs of every point,
#: kept from the tracer's own evaluation: evaluating the points again cost a tenth of the IK)
_X, _Y, _FX, _FY, _ML, _EN, _MODE = 3, 4, 5, 6, 7, 8, 9
N_COLS = 10


@njit
def _store(out, n, chart, z, q) -> int:
    """Store the point ``z`` (chart ``chart``, evaluated into ``q``) in row ``n`` of ``out``;
    returns its d-mode."""
    mode = clamped_mode(chart, z, 1e-9)[0]
    out[n, 0], out[n, 1], out[n, 2] = z[0], z[1], z[2]
    out[n, _X], out[n, _Y], out[n, _FX], out[n, _FY] = q[X], q[Y], q[FX], q[FY]
    out[n, _ML], out[n, _EN], out[n, _MODE] = q[ML], q[EN], mode
    return mode


@njit
def _trace_one(chart, z0, direction, ref, code, p0, p1, tgt, max_mode, mext, lam_max, turn_max, out, n_out, visited,
               wvisited, lam_nodes, npsi, nt, limits, znext) -> tuple:
    """Trace from the point ``z0`` (chart ``chart``) on the curve, which is stored first, along
    ``direction`` (+1/-1) -- or, when ``ref`` is nonzero, along the tangent whose base-wrench
    change points like ``ref``; appends the points to ``out`` from ``n_out`` (stops at its end).
    Returns ``(n_out, next_chart)``: ``next_chart >= 0`` when the trace must continue in another
    chart from ``znext`` (then ``ref`` holds the last base-wrench step), -1 when it ended.  A
    trace that stops at the ``lambda L`` limit is counted in ``limits[0]``."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    qw = np.empty(NQ)
    gw = np.empty((NQ, 3))
    J = np.empty((2, 3))
    z = z0.copy()
    zp = np.empty(3)
    tprev = np.zeros(3)
    wa = np.empty(3)
    wb = np.empty(3)
    use_ref = ref[0] != 0.0 or ref[1] != 0.0 or ref[2] != 0.0
    h = 0.02
    steps = 0
    first = n_out
    _G(chart, z, code, p0, p1, tgt, q, gr, J)
    _store(out, n_out, chart, z, q)
    n_out += 1
    while n_out < out.shape[0]:
        # q, gr, J: evaluated at z (above, or by the corrector's last evaluation at the step)
        wa[0], wa[1], wa[2] = q[FX], q[FY], q[M0]
        t0 = J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1]
        t1 = J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2]
        t2 = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
        s0, s1, s2 = _metric(chart, z, q, mext)
        nt_ = math.sqrt((t0 / s0) ** 2 + (t1 / s1) ** 2 + (t2 / s2) ** 2)
        if not nt_ > 0.0:
            break
        t0, t1, t2 = t0 / nt_, t1 / nt_, t2 / nt_
        if steps == 0:
            if use_ref:
                dw = 0.0
                for c in range(3):
                    dw += ref[c] * (gr[FX + c if c < 2 else M0, 0] * t0 + gr[FX + c if c < 2 else M0, 1] * t1
                                    + gr[FX + c if c < 2 else M0, 2] * t2)
                sg = 1.0 if dw >= 0.0 else -1.0
            else:
                sg = direction
            t0, t1, t2 = sg * t0, sg * t1, sg * t2
        elif t0 * tprev[0] / s0 ** 2 + t1 * tprev[1] / s1 ** 2 + t2 * tprev[2] / s2 ** 2 < 0.0:
            t0, t1, t2 = -t0, -t1, -t2
        accepted = False
        while h > 1e-7:
            zp[0], zp[1], zp[2] = z[0] + h * t0, z[1] + h * t1, z[2] + h * t2
            pred0, pred1, pred2 = zp[0], zp[1], zp[2]
            if _correct(chart, zp, code, p0, p1, tgt, q, gr, J, 6, 1e-12):
                dev = math.sqrt(((zp[0] - pred0) / s0) ** 2 + ((zp[1] - pred1) / s1) ** 2
                                + ((zp[2] - pred2) / s2) ** 2)
                if dev < 0.3 * h:
                    accepted = True
                    break
            h *= 0.5
        if not accepted:
            break
        tprev[0], tprev[1], tprev[2] = t0, t1, t2
        # q, gr: the corrector's last evaluation, at zp
        wb[0], wb[1], wb[2] = q[FX], q[FY], q[M0]
        if chart == CHART_WRENCH:
            sens = tip_sensitivity(gr)
        else:
            wrench_eval(wb[0], wb[1], wb[2], qw, gw)
            sens = tip_sensitivity(gw)
        _mark(chart, z, zp, wa, wb, lam_nodes, npsi, nt, mext, visited, wvisited,
              chart != CHART_WRENCH or sens > SENS_WRENCH)
        z[0], z[1], z[2] = zp[0], zp[1], zp[2]
        steps += 1
        g, gx, gy, al, ax, ay, adm = condition_eval(code, p0, p1, q[X], q[Y])
        if not adm:
            break
        mode = _store(out, n_out, chart, z, q)
        where = _in_scope(chart, z, q, mode, max_mode, lam_max, turn_max)
        if where != 0:
            if where == 1:
                limits[0] += 1
            # the first point beyond the scope ends the polyline: its last segment covers the
            # stretch up to the boundary (a rod of the scope next to a d-mode boundary lies on it;
            # the solutions are held to the scope exactly after their refinement)
            n_out += 1
            break
        n_out += 1
        if steps > 8:  # closed loop: back at the start
            d = math.sqrt(((z[0] - z0[0]) / s0) ** 2 + ((z[1] - z0[1]) / s1) ** 2 + ((z[2] - z0[2]) / s2) ** 2)
            if d < 1.5 * h:
                if n_out == out.shape[0]:  # no room for the closing point
                    break
                out[n_out, :] = out[first, :]
                n_out += 1
                break
        nxt = _rechart(chart, z, q, sens, znext)
        if nxt != chart:
            for c in range(3):
                ref[c] = wb[c] - wa[c]
            return n_out, nxt
        h = min(h * 1.5, H_MAX)
    return n_out, -1


@njit
def _seeds(x, y, th, valid, code, p0, p1, tgt, pad) -> np.ndarray:
    """Cells whose corners bracket both conditions (the angle modulo 2 pi).  The conditions are
    evaluated once per node (a node is the corner of eight cells)."""
    nl, npsi, nt = x.shape
    G = np.zeros((nl, npsi, nt))  # (out-of-scope nodes: not evaluated, their cells not kept)
    A = np.zeros((nl, npsi, nt))
    for i in range(nl):
        for j in range(npsi):
            for k in range(nt):
                if valid[i, j, k]:
                    g, gx, gy, al, ax, ay, adm = condition_eval(code, p0, p1, x[i, j, k], y[i, j, k])
                    G[i, j, k] = g
                    A[i, j, k] = al + th[i, j, k] - tgt
    out = []
    for i in range(nl - 1):
        for j in range(npsi):
            jn = (j + 1) % npsi
            for k in range(nt - 1):
                if not valid[i, j, k]:
                    continue
                lo0 = lo1 = 1e300
                hi0 = hi1 = -1e300
                ok = True
                ref = A[i, j, k]
                for di in range(2):
                    for dj in range(2):
                        for dk in range(2):
                            jj = jn if dj else j
                            ii, kk = i + di, k + dk
                            if not valid[ii, jj, kk]:
                                ok = False
                            g = G[ii, jj, kk]
                            a = ref + wrap_angle(A[ii, jj, kk] - ref)
                            lo0, hi0 = min(lo0, g), max(hi0, g)
                            lo1, hi1 = min(lo1, a), max(hi1, a)
                if not ok:
                    continue
                e0 = pad * (hi0 - lo0) + 1e-12
                e1 = pad * (hi1 - lo1) + 1e-12
                if not (lo0 - e0 <= 0.0 <= hi0 + e0):
                    continue
                m = ref - wrap_angle(ref)  # the multiple of 2 pi nearest the cell
                if (lo1 - e1 <= m <= hi1 + e1) or (lo1 - e1 <= m + TWO_PI <= hi1 + e1) \
                        or (lo1 - e1 <= m - TWO_PI <= hi1 + e1):
                    out.append((i, j, k))
    res = np.empty((len(out), 3), np.int64)
    for r in range(len(out)):
        res[r, 0], res[r, 1], res[r, 2] = out[r]
    return res


@njit
def _trace_all(Z, charts, code, p0, p1, tgt, max_mode, mext, lam_max, turn_max, lam_nodes, npsi, nt, visited,
               wvisited, out, starts, line_chart, limits) -> int:
    """Project every seed ``Z[r]`` (chart ``charts[r]``) onto the curve and trace from it both
    ways unless an earlier trace passed through its cell (of the wrench atlas; for a taut rod, of
    the traced-window record ``wvisited``); a
    trace switches charts where the rod becomes taut or slack again (:func:`_rechart`), each
    piece its own polyline.  Polylines are stored consecutively in ``out`` with their start
    offsets in ``starts`` and their charts in ``line_chart``; returns their number."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    J = np.empty((2, 3))
    qw = np.empty(NQ)
    gw = np.empty((NQ, 3))
    w = np.empty(3)
    wz = np.empty(3)
    ref = np.zeros(3)
    znext = np.empty(3)
    n_out = 0
    n_lines = 0
    for r in range(Z.shape[0]):
        chart0 = charts[r]
        z = Z[r].copy()
        if not _correct(chart0, z, code, p0, p1, tgt, q, gr, J, 30, 1e-12):
            continue
        if _in_scope(chart0, z, q, -1, max_mode, lam_max, turn_max) != 0:
            continue
        w[0], w[1], w[2] = q[FX], q[FY], q[M0]
        # a taut rod is looked up in the traced-window record (the wrench atlas' cells cannot
        # tell such rods apart), any other in the wrench atlas' cells
        wrench_eval(w[0], w[1], w[2], qw, gw)
        taut = tip_sensitivity(gw) > SENS_WINDOW
        if taut:
            if chart0 == CHART_WRENCH:
                rot, wz[0], wz[1], wz[2] = window_of(w[0], w[1], w[2])
                wch = CHART_ROT if rot else CHART_LIB
            else:
                wz[:] = z
                wch = chart0
            key = _wkey(wch, wz)
            if _near_traced_window(wch, wz, wvisited):
                continue
        elif _near_traced(w, lam_nodes, npsi, nt, mext, visited):
            continue
        for direction in (-1.0, 1.0):
            chart = chart0
            zc = z.copy()
            ref[:] = 0.0
            for _ in range(MAX_SWITCHES):
                if n_out + MAX_POINTS > out.shape[0] or n_lines + 2 > line_chart.shape[0]:
                    break
                starts[n_lines] = n_out
                line_chart[n_lines] = chart
                n_out, nxt = _trace_one(chart, zc, direction, ref, code, p0, p1, tgt, max_mode, mext, lam_max,
                                        turn_max, out[:n_out + MAX_POINTS // 2], n_out, visited, wvisited, lam_nodes,
                                        npsi, nt, limits, znext)
                n_lines += 1
                if nxt < 0:
                    break
                chart = nxt
                zc = znext.copy()
        if taut:
            wvisited[key] = True
        else:
            _visit(w, lam_nodes, npsi, nt, mext, visited)
    starts[n_lines] = n_out
    return n_lines


@njit
def segment_charts(charts, Za, Zb, Wa, Wb, out_charts) -> None:
    """The chart each polyline segment ``Za -> Zb`` (n, 3; chart ``charts``) of a clamped curve
    is interpolated in (``out_charts``) and its ends there (``Wa``, ``Wb``): the IK's candidates
    are points on these chords.

    A segment is a chord of the curve.  In the wrench chart a near-taut rod's tip depends on
    the base moment like ``exp(lambda L)`` (tip sensitivity beyond :data:`SENS_WRENCH` at an
    end), so the chord's deviation from the curve in ``m0`` can exceed the rod's distance from
    the separatrix: a rod interpolated on it lies on the other side (librating instead of
    rotating, a different winding) and the Newton converges to a different equilibrium.  Such a
    segment, with both ends in elastica windows of one kind, is interpolated in its window
    coordinates (:mod:`flexkin.rod.elastica`), where a rotating window stays rotating and the
    chord follows the curve; every other segment in its own chart."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    for r in range(Za.shape[0]):
        out_charts[r] = charts[r]
        for c in range(3):
            Wa[r, c], Wb[r, c] = Za[r, c], Zb[r, c]
        if charts[r] != CHART_WRENCH:
            continue
        wrench_eval(Za[r, 0], Za[r, 1], Za[r, 2], q, gr)
        sens = tip_sensitivity(gr)
        wrench_eval(Zb[r, 0], Zb[r, 1], Zb[r, 2], q, gr)
        sens = max(sens, tip_sensitivity(gr))
        if not sens > SENS_WRENCH:
            continue
        ra, va, usa, uea = window_of(Za[r, 0], Za[r, 1], Za[r, 2])
        rb, vb, usb, ueb = window_of(Zb[r, 0], Zb[r, 1], Zb[r, 2])
        if ra != rb or not (va == va and vb == vb):
            continue
        # the same orbit's ends of a window are defined up to whole periods (4K libration, 2K
        # rotation): shift the second next to the first, and keep the segment only when its
        # window moves by less than a quarter period (else the chord in wrench space is kept)
        k, kp = modulus(vb)
        per = (2.0 if rb else 4.0) * complete(k * k, kp * kp)[0]
        sh = per * math.floor((usa - usb) / per + 0.5)
        usb += sh
        ueb += sh
        if abs(usb - usa) > 0.25 * per or abs(ueb - uea) > 0.25 * per or (uea - usa) * (ueb - usb) <= 0.0:
            continue
        Wa[r, 0], Wa[r, 1], Wa[r, 2] = va, usa, uea
        Wb[r, 0], Wb[r, 1], Wb[r, 2] = vb, usb, ueb
        out_charts[r] = CHART_ROT if ra else CHART_LIB


@lru_cache(maxsize=2)
def _elliptic_grids(max_mode: int, max_winding: int) -> tuple[tuple[NDArray[np.float64], ...], ...]:
    """Node coordinates and features of the libration and rotation grids of
    :mod:`flexkin.rod.free_atlas`: per grid ``(a, b, c, F)``."""
    from ..rod.free_atlas import (
        FEATURES,
        fill_libration,
        fill_rotation,
        libration_grid,
        rotation_grid,
    )

    out = []
    for grid, fill, arg in ((libration_grid, fill_libration, max_mode), (rotation_grid, fill_rotation, max_winding)):
        a, b, c = grid(arg)
        F = np.empty((len(a), len(b), len(c), FEATURES))
        fill(a, b, c, F)
        out.append((a, b, c, F))
    return tuple(out)


def _elliptic_seeds(max_mode: int, code: int, p0: float, p1: float, tgt: float, max_winding: int
                    ) -> tuple[NDArray, NDArray]:
    """Seeds near the separatrix, which the wrench atlas cannot resolve (its tip depends on the
    wrench with a condition number like ``exp(lambda L)``): nodes of the cells of the elliptic
    grids bracketing both conditions, as elastica windows (coordinates and chart), in the cells
    whose rods all have ``lambda L >= ELLIPTIC_FROM lambda_max(max_mode)``: below, the wrench
    atlas seeds the curves, and the traces continue them across the separatrix in the windows."""
    from ..rod.free_atlas import node_windows

    lam_min = ELLIPTIC_FROM * lambda_max(max_mode)

    Z, H = [], []
    for lib, (a, b, c, F) in zip((True, False), _elliptic_grids(max_mode, max_winding)):
        valid = (F[..., 10] <= max_mode) & np.all(np.isfinite(F), axis=-1) & (F[..., 9] >= lam_min)
        cells = _seeds(F[..., 0], F[..., 1], F[..., 4], valid, code, p0, p1, tgt, 0.25)
        if not len(cells):
            continue
        w = np.empty((len(cells), 3))
        node_windows(lib, a[cells[:, 0]], b[cells[:, 1]], c[cells[:, 2]], w)
        Z.append(w)
        H.append(np.full(len(w), CHART_LIB if lib else CHART_ROT, np.int64))
    if not Z:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    return np.concatenate(Z), np.concatenate(H)


def clamped_leg_curve(mech, i: int, B: NDArray[np.float64], theta: float, max_mode: int,
                      max_winding: int = 1, force_tol: float = 0.05) -> LegCurve:
    """Curves of clamped leg ``i`` (0-based) with its attach point at ``B`` (world) and the
    platform at orientation ``theta``: one branch dict per polyline (see
    :class:`~flexkin.solve.curves.LegCurve`; ``z`` holds the coordinates in the chart ``chart``:
    the wrench chart, or the elastica window of a taut rod), rods of d-mode ``<= max_mode`` and
    winding ``|w| <= max_winding`` (with a margin of turning).  ``limits`` counts the polylines
    stopped at the search's force limit :data:`LAMBDA_LIMIT`."""
    leg = mech.legs[i]
    atlas = get_wrench_atlas(max_mode, max_winding)
    mext = moment_extra(max_winding)
    code, par = leg.actuator.condition(B)
    tgt = float(theta + leg.tip_angle)
    cells = _seeds(atlas.x, atlas.y, atlas.th, atlas.valid, int(code), float(par[0]), float(par[1]), tgt, 0.25)
    Z = np.ascontiguousarray(atlas.wrench(cells[:, 0] + 0.5, cells[:, 1] + 0.5, cells[:, 2] + 0.5)) \
        if len(cells) else np.zeros((0, 3))
    Ze, He = _elliptic_seeds(max_mode, int(code), float(par[0]), float(par[1]), tgt, max_winding)
    Z = np.ascontiguousarray(np.concatenate([Z, Ze]))
    charts = np.concatenate([np.full(len(Z) - len(Ze), CHART_WRENCH, np.int64), He])
    wvisited = Dict.empty(key_type=types.int64, value_type=types.boolean)
    # the traced-curve record: cells of a polar grid of base wrenches like the atlas', up to the
    # search's force limit
    lam_v = LAMBDA_LIMIT * np.linspace(0.0, 1.0, N_VISIT[0]) ** 1.5
    visited = np.zeros((N_VISIT[0] - 1, N_VISIT[1], N_VISIT[2] - 1), bool)
    out = np.empty((40 * MAX_POINTS, N_COLS))
    n_max = 2 * MAX_SWITCHES * len(Z) + 2
    starts = np.zeros(n_max + 1, np.int64)
    line_chart = np.zeros(n_max, np.int64)
    limits = np.zeros(1, np.int64)
    n_lines = _trace_all(Z, charts, int(code), float(par[0]), float(par[1]), tgt, max_mode, mext, LAMBDA_LIMIT,
                         turning_max(max_winding) + TURN_MARGIN, lam_v, N_VISIT[1], N_VISIT[2], visited,
                         wvisited, out, starts, line_chart, limits)
    branches = []
    for a in range(n_lines):
        pts = out[starts[a]:starts[a + 1]]
        if len(pts) >= 2:
            branches.append(_thin(_branch_data(leg, B, pts, int(line_chart[a])), leg.rod.EI, force_tol))
    return LegCurve(i, leg.actuation, _distinct_stretches(branches, leg), limits=int(limits[0]))


#: a vertex lies on an earlier polyline when it is within this fraction of a segment's length of
#: it (a chord's sag is an eighth of its turning angle: 0.06 for the thinned segments' 0.5 rad)
ON_SEGMENT = 0.01
#: consecutive vertices on earlier polylines that make a traced-again stretch
RUN = 4
#: tip force (EI/L^2; lambda L ~ 14) beyond which a rod is kept on every polyline it was traced
#: on: the Newton on such rods converges only from starts closer than the chords' spacing (on the
#: unit 3-PF at (0, 0, 0), four equilibria at 390-450 EI/L^2 were lost without it)
TAUT_FORCE = 200.0


@njit
def _covered(P: np.ndarray, Q0: np.ndarray, Q1: np.ndarray, n_seg: int, rel: float) -> np.ndarray:
    """Whether each vertex ``P[j]`` lies within ``rel`` times a segment's length of one of the
    first ``n_seg`` segments ``Q0 -> Q1``."""
    out = np.zeros(P.shape[0], np.bool_)
    d = P.shape[1]
    for j in range(P.shape[0]):
        for s in range(n_seg):
            ab = 0.0
            ap = 0.0
            for c in range(d):
                e = Q1[s, c] - Q0[s, c]
                ab += e * e
                ap += e * (P[j, c] - Q0[s, c])
            t = min(max(ap / ab, 0.0), 1.0) if ab > 0.0 else 0.0
            r = 0.0
            for c in range(d):
                e = Q0[s, c] + t * (Q1[s, c] - Q0[s, c]) - P[j, c]
                r += e * e
            if r <= rel * rel * ab:
                out[j] = True
                break
    return out


def _distinct_stretches(branches: list[dict[str, NDArray]], leg) -> tuple[dict[str, NDArray], ...]:
    """The polylines without the stretches that trace an earlier polyline again.

    A seed beyond where an earlier trace of its curve ended (a chart switch, the force limit) is
    traced both ways, over the stretch the earlier trace covered too: every rod of a leg then lies
    on 2-3 polylines and the equilibrium search finds each solution 10-40 times.  A run of
    :data:`RUN` or more vertices within :data:`ON_SEGMENT` of a segment's length of earlier
    polylines (in input, tip force, tip moment, elastic energy and d-mode, scaled by the rod's length
    and stiffness: taut rods of different shapes share nearly the same tip wrench) is such a
    stretch: its inner vertices are dropped (its end vertices stay, so that the pieces
    overlap the earlier polyline by a segment), and a polyline so split becomes two.  Rods above
    :data:`TAUT_FORCE` stay on every polyline, and the elastica windows' polylines are kept before
    the wrench chart's."""
    if len(branches) < 2:
        return tuple(branches)
    L, EI = leg.rod.length, leg.rod.EI
    us = 1.0 if leg.actuator.angular else L

    def points(br: dict[str, NDArray]) -> NDArray:
        return np.column_stack([br["input"] / us, br["force"] * (br["length"] ** 2 / EI)[:, None],
                                br["tip_moment"] * br["length"] / EI, br["energy"] * br["length"] / EI,
                                10.0 * br["mode"]])

    n_all = sum(len(br["input"]) for br in branches)
    Q0, Q1 = np.empty((n_all, 6)), np.empty((n_all, 6))
    n_seg = 0
    kept: list[dict[str, NDArray]] = []
    # the elastica windows first: where a stretch was traced in both charts, Newton converges from
    # the window's chords (a rod near taut is ill-conditioned in its base wrench)
    for br in sorted(branches, key=lambda b: int(b["chart"][0]) == CHART_WRENCH):
        P = points(br)
        cov = _covered(P, Q0, Q1, n_seg, ON_SEGMENT) & (np.hypot(P[:, 1], P[:, 2]) <= TAUT_FORCE)
        drop = np.zeros(len(P), bool)
        j = 0
        while j < len(P):  # the inner vertices of runs of covered ones
            if not cov[j]:
                j += 1
                continue
            e = j
            while e < len(P) and cov[e]:
                e += 1
            if e - j >= RUN:
                drop[j + 1:e - 1] = True
                if j == 0:
                    drop[0] = True
                if e == len(P):
                    drop[e - 1] = True
            j = e
        cut = np.flatnonzero(np.diff(np.concatenate([[1], drop.view(np.int8), [1]])))
        for a, b in zip(cut[::2], cut[1::2]):  # the kept pieces [a, b)
            if b - a < 2:
                continue
            piece = {k: v[a:b] for k, v in br.items()}
            kept.append(piece)
            m = b - a - 1
            Q0[n_seg:n_seg + m], Q1[n_seg:n_seg + m] = P[a:b - 1], P[a + 1:b]
            n_seg += m
    return tuple(kept)


@njit
def _keep(f: np.ndarray, m: np.ndarray, fs: np.ndarray, ms: np.ndarray, tol: float) -> np.ndarray:
    """Vertices to keep: the ends, and every vertex where the force or the tip moment has moved
    by more than ``tol`` times its local scale since the last kept vertex."""
    n = f.shape[0]
    keep = np.zeros(n, np.bool_)
    keep[0] = True
    keep[n - 1] = True
    last = 0
    for j in range(1, n - 1):
        df = max(abs(f[j, 0] - f[last, 0]), abs(f[j, 1] - f[last, 1]))
        dm = abs(m[j] - m[last])
        if df > tol * (fs[j] + math.hypot(f[j, 0], f[j, 1])) or dm > tol * (ms[j] + abs(m[j])):
            keep[j] = True
            last = j
    return keep


def _thin(br: dict[str, NDArray], EI: float, tol: float) -> dict[str, NDArray]:
    """The branch with its vertices thinned to the wrench-space resolution ``tol`` (like the
    refinement of the pinned curves in :func:`flexkin.solve.curves.leg_curves`)."""
    L = br["length"]
    keep = _keep(np.ascontiguousarray(br["force"]), np.ascontiguousarray(br["tip_moment"]), EI / L**2, EI / L, tol)
    return {k: v[keep] for k, v in br.items()}


def _branch_data(leg, B: NDArray, pts: NDArray, chart: int) -> dict[str, NDArray]:
    """One polyline's branch dict from its traced points ``pts`` (rows of :func:`_store`)."""
    n = len(pts)
    u, alpha, L = leg.actuator.from_tip(B, pts[:, _X], pts[:, _Y])
    u, alpha, L = (np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in (u, alpha, L))
    EI = leg.rod.EI
    force = rotate(pts[:, [_FX, _FY]], alpha) * (EI / L**2)[:, None]
    return {"z": pts[:, :3].copy(), "chart": np.full(n, chart, dtype=np.int64), "input": np.array(u),
            "force": force, "tip_moment": EI / L * pts[:, _ML], "length": np.array(L),
            "mode": pts[:, _MODE].astype(np.int64), "energy": EI / L * pts[:, _EN]}
