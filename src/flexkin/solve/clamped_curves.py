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
from numpy.typing import NDArray

from ..core.jit import njit
from ..core.geometry2d import rotate
from ..core.geometry2d_kernels import wrap_angle
from ..rod.slots import EN, FX, FY, ML, NQ, TH, X, Y
from ..rod.wrench import wrench_eval, wrench_mode
from ..rod.wrench_atlas import get_wrench_atlas, lambda_max, moment_extra, turning_max
from .conditions import condition_eval
from .leg_curve import LegCurve

__all__ = ["clamped_leg_curve"]

TWO_PI = 2.0 * math.pi
#: turning (rad) traced beyond the winding scope, which is applied exactly to refined solutions
TURN_MARGIN = 0.5
MAX_POINTS = 4000


@njit
def _G(z, code, p0, p1, tgt, q, gr, J):
    """Residual ``(g, angle)`` of the two conditions at ``z``, its Jacobian ``J`` (2, 3) and
    whether the tip is admissible."""
    wrench_eval(z[0], z[1], z[2], q, gr)
    g, gx, gy, al, ax, ay, adm = condition_eval(code, p0, p1, q[X], q[Y])
    for c in range(3):
        J[0, c] = gx * gr[X, c] + gy * gr[Y, c]
        J[1, c] = gr[TH, c] + ax * gr[X, c] + ay * gr[Y, c]
    return g, wrap_angle(al + q[TH] - tgt), adm


@njit
def _correct(z, code, p0, p1, tgt, q, gr, J, iters, tol) -> bool:
    """Minimum-norm Newton onto the curve (in place); True when it converged."""
    for _ in range(iters):
        g0, g1, adm = _G(z, code, p0, p1, tgt, q, gr, J)
        if not (g0 == g0 and g1 == g1):
            return False
        if max(abs(g0), abs(g1)) < tol:
            return True
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
    g0, g1, adm = _G(z, code, p0, p1, tgt, q, gr, J)
    return max(abs(g0), abs(g1)) < tol


@njit
def _metric(z, mext) -> tuple:
    """Per-coordinate scales of the chart near ``z`` (the atlas' cell sizes grow with the load)."""
    R = math.hypot(z[0], z[1])
    lam = math.sqrt(R)
    sf = 1.0 + R
    sm = 1.0 + 2.0 * lam + mext
    return sf, sf, sm


@njit
def _cell(z, lam_nodes, npsi, nt, mext):
    """Atlas cell (i, j, k) containing ``z`` (-1 if outside)."""
    R = math.hypot(z[0], z[1])
    lam = math.sqrt(R)
    nl = lam_nodes.shape[0]
    if lam >= lam_nodes[nl - 1]:
        return -1, -1, -1
    i = 0
    while i < nl - 2 and lam_nodes[i + 1] <= lam:
        i += 1
    psi = math.atan2(z[1], z[0])
    if psi < 0.0:
        psi += TWO_PI
    j = int(psi / (TWO_PI / npsi)) % npsi
    t = z[2] / (2.0 * lam + mext)
    k = int((t + 1.0) * 0.5 * (nt - 1))
    if k < 0 or k >= nt - 1:
        return -1, -1, -1
    return i, j, k


@njit
def _visit(z, lam_nodes, npsi, nt, mext, visited) -> None:
    """Mark the cell of ``z`` as traced."""
    i, j, k = _cell(z, lam_nodes, npsi, nt, mext)
    if i < 0:
        return
    visited[i, j, k] = True


@njit
def _visit_segment(za, zb, lam_nodes, npsi, nt, mext, visited) -> None:
    """Mark every cell the chord ``za -> zb`` passes through (subdivided where it jumps cells)."""
    ia, ja, ka = _cell(za, lam_nodes, npsi, nt, mext)
    ib, jb, kb = _cell(zb, lam_nodes, npsi, nt, mext)
    dj = abs(ja - jb)
    dj = min(dj, npsi - dj)
    m = max(abs(ia - ib), dj, abs(ka - kb)) + 1
    if ia < 0 or ib < 0:
        m = 8
    m = min(m, 64)
    zc = np.empty(3)
    for r in range(m + 1):
        f = r / m
        zc[0] = za[0] + f * (zb[0] - za[0])
        zc[1] = za[1] + f * (zb[1] - za[1])
        zc[2] = za[2] + f * (zb[2] - za[2])
        _visit(zc, lam_nodes, npsi, nt, mext, visited)


@njit
def _in_scope(z, q, max_mode, lam_max, turn_max) -> int:
    """0 if the rod ``z`` is searched; 1 if its ``lambda L`` is beyond the search's numerical
    limit ``lam_max``; 2 if it is outside the scope (tangent turning or d-mode)."""
    if math.sqrt(math.hypot(z[0], z[1])) > lam_max * 1.02:
        return 1
    if abs(q[TH]) > turn_max + 1e-9:
        return 2
    return 0 if wrench_mode(z[0], z[1], z[2], 1e-9)[0] <= max_mode else 2


@njit
def _trace_one(z0, direction, code, p0, p1, tgt, max_mode, mext, lam_max, turn_max, out, n_out, visited,
               lam_nodes, npsi, nt, limits) -> int:
    """Trace from the point ``z0`` on the curve along ``direction`` (+1/-1); appends points to
    ``out`` from ``n_out``; returns the new count (stops at MAX_POINTS total).  A trace that
    stops at the ``lambda L`` limit is counted in ``limits[0]``."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    J = np.empty((2, 3))
    z = z0.copy()
    zp = np.empty(3)
    tprev = np.zeros(3)
    h = 0.02
    steps = 0
    while n_out < out.shape[0]:
        _G(z, code, p0, p1, tgt, q, gr, J)
        t0 = J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1]
        t1 = J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2]
        t2 = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
        s0, s1, s2 = _metric(z, mext)
        nt_ = math.sqrt((t0 / s0) ** 2 + (t1 / s1) ** 2 + (t2 / s2) ** 2)
        if not nt_ > 0.0:
            break
        t0, t1, t2 = t0 / nt_, t1 / nt_, t2 / nt_
        if steps == 0:
            t0, t1, t2 = direction * t0, direction * t1, direction * t2
        elif t0 * tprev[0] / s0 ** 2 + t1 * tprev[1] / s1 ** 2 + t2 * tprev[2] / s2 ** 2 < 0.0:
            t0, t1, t2 = -t0, -t1, -t2
        accepted = False
        while h > 1e-7:
            zp[0], zp[1], zp[2] = z[0] + h * t0, z[1] + h * t1, z[2] + h * t2
            pred0, pred1, pred2 = zp[0], zp[1], zp[2]
            if _correct(zp, code, p0, p1, tgt, q, gr, J, 6, 1e-12):
                dev = math.sqrt(((zp[0] - pred0) / s0) ** 2 + ((zp[1] - pred1) / s1) ** 2
                                + ((zp[2] - pred2) / s2) ** 2)
                if dev < 0.3 * h:
                    accepted = True
                    break
            h *= 0.5
        if not accepted:
            break
        tprev[0], tprev[1], tprev[2] = t0, t1, t2
        _visit_segment(z, zp, lam_nodes, npsi, nt, mext, visited)
        z[0], z[1], z[2] = zp[0], zp[1], zp[2]
        steps += 1
        wrench_eval(z[0], z[1], z[2], q, gr)
        g, gx, gy, al, ax, ay, adm = condition_eval(code, p0, p1, q[X], q[Y])
        if not adm:
            break
        where = _in_scope(z, q, max_mode, lam_max, turn_max)
        if where != 0:
            if where == 1:
                limits[0] += 1
            break
        out[n_out, 0], out[n_out, 1], out[n_out, 2] = z[0], z[1], z[2]
        n_out += 1
        _visit(z, lam_nodes, npsi, nt, mext, visited)
        if steps > 8:  # closed loop: back at the start
            d = math.sqrt(((z[0] - z0[0]) / s0) ** 2 + ((z[1] - z0[1]) / s1) ** 2 + ((z[2] - z0[2]) / s2) ** 2)
            if d < 1.5 * h:
                out[n_out, 0], out[n_out, 1], out[n_out, 2] = z0[0], z0[1], z0[2]
                n_out += 1
                break
        h = min(h * 1.5, 0.05)
    return n_out


@njit
def _seeds(x, y, th, valid, code, p0, p1, tgt, pad) -> np.ndarray:
    """Cells whose corners bracket both conditions (the angle modulo 2 pi)."""
    nl, npsi, nt = x.shape
    out = []
    for i in range(nl - 1):
        for j in range(npsi):
            jn = (j + 1) % npsi
            for k in range(nt - 1):
                lo0 = lo1 = 1e300
                hi0 = hi1 = -1e300
                ok = True
                ref = 0.0
                first = True
                for di in range(2):
                    for dj in range(2):
                        for dk in range(2):
                            jj = jn if dj else j
                            ii, kk = i + di, k + dk
                            if not valid[ii, jj, kk]:
                                ok = False
                            g, gx, gy, al, ax, ay, adm = condition_eval(code, p0, p1, x[ii, jj, kk], y[ii, jj, kk])
                            a = al + th[ii, jj, kk] - tgt
                            if first:
                                ref = a
                                first = False
                            a = ref + wrap_angle(a - ref)
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
def _trace_all(Z, code, p0, p1, tgt, max_mode, mext, lam_max, turn_max, lam_nodes, npsi, nt, visited, cells,
               out, starts, limits) -> int:
    """Project every seed ``Z[r]`` (in cell ``cells[r]``) onto the curve and trace from it unless
    an earlier trace passed through its cell; polylines are stored consecutively in ``out``
    with their start offsets in ``starts``; returns the number of polylines."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    J = np.empty((2, 3))
    n_out = 0
    n_lines = 0
    back = np.empty((MAX_POINTS, 3))
    for r in range(Z.shape[0]):
        if visited[cells[r, 0], cells[r, 1], cells[r, 2]]:
            continue
        z = Z[r].copy()
        if not _correct(z, code, p0, p1, tgt, q, gr, J, 30, 1e-12):
            continue
        wrench_eval(z[0], z[1], z[2], q, gr)
        if _in_scope(z, q, max_mode, lam_max, turn_max) != 0:
            continue
        i, j, k = _cell(z, lam_nodes, npsi, nt, mext)
        if i >= 0 and visited[i, j, k]:
            continue
        if n_out + 2 * MAX_POINTS // 4 > out.shape[0]:
            break
        nb = _trace_one(z, -1.0, code, p0, p1, tgt, max_mode, mext, lam_max, turn_max, back, 0, visited, lam_nodes,
                        npsi, nt, limits)
        starts[n_lines] = n_out
        for a in range(nb - 1, -1, -1):
            out[n_out] = back[a]
            n_out += 1
        out[n_out] = z
        n_out += 1
        lim = min(out.shape[0], n_out + MAX_POINTS // 2)
        n_out = _trace_one(z, 1.0, code, p0, p1, tgt, max_mode, mext, lam_max, turn_max, out[:lim], n_out, visited,
                           lam_nodes, npsi, nt, limits)
        n_lines += 1
        _visit(z, lam_nodes, npsi, nt, mext, visited)
    starts[n_lines] = n_out
    return n_lines


@lru_cache(maxsize=2)
def _elliptic_grids(max_mode: int, max_winding: int) -> tuple[NDArray[np.float64], ...]:
    """Features of the libration and rotation grids of :mod:`flexkin.rod.free_atlas`."""
    from ..rod.free_atlas import FEATURES, fill_libration, fill_rotation, libration_grid, rotation_grid

    out = []
    for grid, fill, arg in ((libration_grid, fill_libration, max_mode), (rotation_grid, fill_rotation, max_winding)):
        a, b, c = grid(arg)
        F = np.empty((len(a), len(b), len(c), FEATURES))
        fill(a, b, c, F)
        out.append(F)
    return tuple(out)


def _elliptic_seeds(max_mode: int, max_winding: int, code: int, p0: float, p1: float, tgt: float, atlas
                    ) -> tuple[NDArray, NDArray]:
    """Seeds near the separatrix, which the wrench atlas cannot resolve (its tip depends on the
    wrench with a condition number like ``1/k'^2``): cells of the elliptic grids bracketing both
    conditions, as wrench-chart points and their wrench-atlas cells."""
    Z, C = [], []
    mext = moment_extra(max_winding)
    for F in _elliptic_grids(max_mode, max_winding):
        valid = (F[..., 9] <= lambda_max(max_mode)) & (F[..., 10] <= max_mode) & np.all(np.isfinite(F), axis=-1)
        cells = _seeds(F[..., 0], F[..., 1], F[..., 4], valid, code, p0, p1, tgt, 0.25)
        for i, j, k in cells:
            z = np.ascontiguousarray(F[i, j, k, 6:9])
            ci = _cell(z, atlas.lam, len(atlas.psi), len(atlas.t), mext)
            if ci[0] >= 0:
                Z.append(z)
                C.append(ci)
    return np.array(Z, float).reshape(-1, 3), np.array(C, np.int64).reshape(-1, 3)


def clamped_leg_curve(mech, i: int, B: NDArray[np.float64], theta: float, max_mode: int,
                      max_winding: int = 1, force_tol: float = 0.05) -> LegCurve:
    """Curves of clamped leg ``i`` (0-based) with its attach point at ``B`` (world) and the
    platform at orientation ``theta``: one branch dict per polyline (see
    :class:`~flexkin.solve.curves.LegCurve`; ``z`` holds the wrench-chart coordinates), rods of
    d-mode ``<= max_mode`` and winding ``|w| <= max_winding`` (with a margin of turning).
    ``limits`` counts the polylines stopped at the grid's force limit
    (:func:`~flexkin.rod.wrench_atlas.lambda_max`)."""
    leg = mech.legs[i]
    atlas = get_wrench_atlas(max_mode, max_winding)
    mext = moment_extra(max_winding)
    code, par = leg.actuator.condition(B)
    tgt = float(theta + leg.tip_angle)
    cells = _seeds(atlas.x, atlas.y, atlas.th, atlas.valid, int(code), float(par[0]), float(par[1]), tgt, 0.25)
    Z = np.ascontiguousarray(atlas.wrench(cells[:, 0] + 0.5, cells[:, 1] + 0.5, cells[:, 2] + 0.5)) \
        if len(cells) else np.zeros((0, 3))
    Ze, Ce = _elliptic_seeds(max_mode, max_winding, int(code), float(par[0]), float(par[1]), tgt, atlas)
    Z, cells = np.ascontiguousarray(np.concatenate([Z, Ze])), np.ascontiguousarray(np.concatenate([cells, Ce]))
    visited = np.zeros((len(atlas.lam) - 1, len(atlas.psi), len(atlas.t) - 1), bool)
    out = np.empty((40 * MAX_POINTS, 3))
    starts = np.zeros(len(Z) + 2, np.int64)
    limits = np.zeros(1, np.int64)
    n_lines = _trace_all(Z, int(code), float(par[0]), float(par[1]), tgt, max_mode, mext, lambda_max(max_mode),
                         turning_max(max_winding) + TURN_MARGIN, atlas.lam, len(atlas.psi), len(atlas.t), visited,
                         cells, out, starts, limits)
    branches = []
    for a in range(n_lines):
        zl = out[starts[a]:starts[a + 1]]
        if len(zl) >= 2:
            branches.append(_thin(_branch_data(leg, B, zl), leg.rod.EI, force_tol))
    return LegCurve(i, leg.actuation, tuple(branches), limits=int(limits[0]))


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


def _branch_data(leg, B: NDArray, zl: NDArray) -> dict[str, NDArray]:
    from ..rod.kernels import CHART_WRENCH, eval_rods

    q = np.empty((len(zl), NQ))
    g = np.empty((len(zl), NQ, 3))
    eval_rods(np.full(len(zl), CHART_WRENCH, dtype=np.int64), np.ascontiguousarray(zl), q, g)
    u, alpha, L = leg.actuator.from_tip(B, q[:, X], q[:, Y])
    u, alpha, L = (np.broadcast_to(np.asarray(v, dtype=float), (len(zl),)) for v in (u, alpha, L))
    EI = leg.rod.EI
    force = rotate(q[:, [FX, FY]], alpha) * (EI / L**2)[:, None]
    modes = np.array([wrench_mode(z[0], z[1], z[2], 1e-9)[0] for z in zl])
    return {"z": zl.copy(), "input": np.array(u), "force": force, "tip_moment": EI / L * q[:, ML],
            "length": np.array(L), "mode": modes, "energy": EI / L * q[:, EN]}
