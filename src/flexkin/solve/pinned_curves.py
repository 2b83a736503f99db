"""Geometric-condition curves of a pinned leg (paper §4.1, Figs. 5, 7–9).

For a given platform pose each leg's attach point ``B_i`` is known, and the rods that can
reach it form a one-parameter family: a curve in the rod's parameter space.

* prismatic leg (Fig. 5): the tip height above the guide is fixed, ``y = h``;
* revolute leg (Fig. 8): the tip lies on a circle, ``x^2 + y^2 = r^2``;
* length leg (Fig. 9): on a unit rod the tip lies on the ray of angle ``beta``,
  ``y/x = tan(beta)``, and the solution is scaled by ``|AB|/|tip|``.

The curves are extracted as level sets on the dimensionless atlas (one grid for all
d-modes up to the maximum, see :mod:`flexkin.rod.atlas`) and, for the rods near straight under
tension that it cannot resolve, on the seam patch (:mod:`flexkin.rod.seam_atlas`), with
contourpy's marching squares.  Every vertex carries its chart and chart coordinates, d-mode,
actuator input and the tip force it would exert in the world frame.  The tip evaluations
(closed form) and the snapping of the polylines onto the exact level set (Newton along the
normal with the analytic gradient of the tip, :func:`flexkin.rod.kernels.eval_rod`, and of the
condition, :func:`flexkin.solve.conditions.condition_eval`) are compiled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import contourpy
import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d import rotate
from ..core.jit import njit
from ..rod.atlas import get_atlas
from ..mechanism.actuators import COND_CIRCLE
from ..rod.closed_form import kr_from_k, mode_of, seam_to_chart, to_paper
from ..rod.kernels import CHART_SEAM, CHART_UNIFIED, FX, FY, NQ, X, Y, eval_rod
from ..rod.seam_atlas import get_seam_atlas, unified_corner
from .conditions import condition_eval
from .leg_curve import LegCurve

__all__ = ["pinned_leg_curve"]


def pinned_leg_curve(mech, i: int, B: NDArray[np.float64], max_mode: int, *, force_tol: float = 0.05,
                     passes: int = 8) -> LegCurve:
    """Geometric-condition curve of pinned leg ``i`` for its world attach point ``B`` (2,).

    The level set is extracted on two sheets: the unified atlas (:mod:`flexkin.rod.atlas`)
    without its corner of rods near straight under tension, and the seam patch
    (:mod:`flexkin.rod.seam_atlas`) that covers that corner in the seam chart, overlapping the
    atlas in a band.  A revolute leg's condition ``|tip| = r`` is contoured in the regular form
    ``sign(k) sqrt(1 - |tip|) = +-sqrt(1 - r)`` (:func:`_level`): ``1 - |tip|`` vanishes
    quadratically on the straight rods (taut under tension, or compressed), so the plain form has
    a double root there and its level set near ``r = 1`` is a sliver no grid resolves; the regular
    form has simple roots down to ``r = 1`` (taut rods), where its level set is the straight rods.

    The marching-squares polylines are snapped onto the exact level set (Newton along the
    local normal, closed form) and refined by bisection wherever the rod force jumps by
    more than ``force_tol * (EI/L^2 + |n|)`` between vertices, so that the piecewise-linear
    curves in wrench space stay close to the true ones also where the force grows fast
    (rods near ``|k| = 1``).

    Parameters
    ----------
    mech : Mechanism
    i : int
        The leg.
    B : (2,) world attach point of the leg at the imposed pose.
    max_mode : int
        Largest d-mode represented.
    force_tol : float
        Relative force resolution of the refined polylines.
    passes : int
        Maximum number of bisection passes.

    Returns
    -------
    LegCurve
    """
    leg = mech.legs[i]
    act = leg.actuator
    ls = act.level_set(B)
    code, par = act.condition(B)
    branches = []
    for sh in _sheets(max_mode):
        z, levels = _field(code, par, ls, sh)
        if not levels:
            continue
        gen = contourpy.contour_generator(x=sh.z1, y=sh.z0, z=z, name="serial",
                                          line_type=contourpy.LineType.Separate)
        for level in levels:
            for line in gen.lines(level):
                if len(line) < 2:
                    continue
                zl = np.ascontiguousarray(np.stack([line[:, 1], line[:, 0]], -1))
                branches.extend(_polyline(leg, B, sh.chart, code, par, level, ls.mask, zl, force_tol, passes))
    return LegCurve(i, leg.actuation, tuple(branches))


#: a revolute leg's platform point at most this (relative to L) beyond full reach is taken as
#: exactly at full reach (rounding): the rods that reach it are the taut ones
TAUT_TOL = 1e-12


@dataclass(frozen=True)
class _Sheet:
    """A grid of pinned unit rods in one chart: coordinates ``z0``, ``z1`` (``(v, phis)`` or
    ``(psi_s, chi)``) and tips ``x``, ``y`` (all (n0, n1)), NaN at the nodes left to the other
    sheet (contourpy treats NaN as masked), and the regular form ``s`` of the circle condition,
    ``sign(k_u) sqrt(1 - |tip|)`` (see :func:`pinned_leg_curve`; the sign of ``k_u`` is the sign of
    ``z0`` in both charts)."""

    chart: int
    z0: NDArray[np.float64]
    z1: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    s: NDArray[np.float64]

    @classmethod
    def of(cls, chart: int, z0, z1, x, y, skip=None) -> "_Sheet":
        x, y = np.array(x, dtype=float), np.array(y, dtype=float)
        if skip is not None:
            x[skip] = np.nan
            y[skip] = np.nan
        s = np.sign(z0) * np.sqrt(np.maximum(1.0 - np.hypot(x, y), 0.0))
        s[np.isnan(x)] = np.nan
        for a in (x, y, s):
            a.setflags(write=False)
        return cls(chart, z0, z1, x, y, s)


@lru_cache(maxsize=4)
def _sheets(max_mode: int) -> tuple[_Sheet, _Sheet]:
    A = get_atlas(max_mode)
    S = get_seam_atlas()
    return (_Sheet.of(CHART_UNIFIED, A.V, A.PHIS, A.x, A.y, unified_corner(A)),
            _Sheet.of(CHART_SEAM, S.PSI, S.CHI, S.x, S.y))


def _field(code: int, par: NDArray[np.float64], ls, sh: _Sheet):
    """The function contoured on sheet ``sh`` and its levels (none: no rod of the sheet reaches)."""
    if code == COND_CIRCLE:
        r = float(par[0])
        if r > 1.0 + TAUT_TOL:  # beyond full reach
            return None, ()
        s0 = math.sqrt(max(1.0 - r, 0.0))
        return sh.s, ((s0, -s0) if s0 > 0.0 else (0.0,))
    z = ls.g(sh.x, sh.y)
    if ls.mask is not None:
        with np.errstate(invalid="ignore"):
            z = np.where(ls.mask(sh.x, sh.y), z, np.nan)
    return z, (0.0,)


def _polyline(leg, B, chart, code, par, level, mask_f, zl, force_tol, passes) -> list[dict[str, NDArray]]:
    """Branch data of one contour polyline ``zl`` (chart coordinates) after refinement."""
    t = _tips(chart, zl)
    for _ in range(passes):  # only the new vertices are evaluated
        f_, L, _ = _forces(leg, B, t)
        fscale = leg.rod.EI / L ** 2
        jump = np.max(np.abs(np.diff(f_, axis=0)), axis=1)
        lim = force_tol * (np.minimum(fscale[:-1], fscale[1:]) + np.hypot(*f_[:-1].T))
        bad = np.flatnonzero(jump > lim)
        if bad.size == 0 or len(zl) > 20000:
            break
        mid, tmid = _snap(chart, code, par, level, 0.5 * (zl[bad] + zl[bad + 1]), zl[bad + 1] - zl[bad],
                          max_shift=0.25 * np.hypot(*(zl[bad + 1] - zl[bad]).T))
        zl = np.insert(zl, bad + 1, mid, axis=0)
        t = np.insert(t, bad + 1, tmid, axis=0)
    if mask_f is not None:  # length legs: keep the ray, not its opposite
        keep = mask_f(t[:, 0], t[:, 1])
        if not np.all(keep):
            return [_branch_data(leg, B, zl[piece], t[piece], chart)
                    for piece in np.split(np.arange(len(zl)), np.flatnonzero(np.diff(keep.astype(int))) + 1)
                    if keep[piece[0]] and len(piece) >= 2]
    return [_branch_data(leg, B, zl, t, chart)]


@njit(cache=True)
def _level(code, p0, p1, level, z0, x, y):
    """``(g, g_x, g_y)``: the leg's condition at the unit tip ``(x, y)`` of a rod with first chart
    coordinate ``z0`` (its sign is the sign of ``k_u`` in both pinned charts), minus ``level``.

    A circle (revolute leg) in the regular form ``sign(z0) sqrt(1 - |tip|) - level`` (see
    :func:`leg_curves`); the gradient is NaN on the straight rods themselves, where the form's
    derivative is finite but not available from the tip alone."""
    if code == COND_CIRCLE:
        rho = math.hypot(x, y)
        d = 1.0 - rho
        sg = 1.0 if z0 > 0.0 else (-1.0 if z0 < 0.0 else 0.0)
        if not (d > 0.0 and rho > 0.0):
            return -level, math.nan, math.nan
        sq = math.sqrt(d)
        c = -sg / (2.0 * sq * rho)
        return sg * sq - level, c * x, c * y
    g, gx, gy, _a, _ax, _ay, _ok = condition_eval(code, p0, p1, x, y)
    return g, gx, gy


def _snap(chart: int, code: int, par: NDArray[np.float64], level: float, z: NDArray[np.float64],
          direction: NDArray[np.float64], iters: int = 5, max_shift: NDArray[np.float64] | float = 0.1
          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Move points ``z`` (n, 2) of chart ``chart`` onto the leg's level set (condition ``code``,
    ``par``, :meth:`~flexkin.mechanism.actuators.Actuator.condition`, at ``level`` of
    :func:`_level`) along the normal of the local curve tangent ``direction`` (n, 2); returns the
    points and their unit tips (n, 4) as :func:`_tips`.

    Points that would move by more than ``max_shift`` (they would jump to another branch of
    the level set) or where the iteration does not settle keep their original position.
    """
    z = np.ascontiguousarray(z, dtype=float)
    out = np.empty_like(z)
    tips = np.empty((len(z), 4))
    shift = np.broadcast_to(np.asarray(max_shift, dtype=float), (len(z),)).copy()
    _snap_kernel(int(chart), int(code), float(par[0]), float(par[1]), float(level), z,
                 np.ascontiguousarray(direction, dtype=float), iters, shift, out, tips)
    return out, tips


@njit(cache=True)
def _snap_kernel(chart, code, p0, p1, level, z, direction, iters, max_shift, out, tips) -> None:
    """Newton along the normal of ``direction`` on ``g(tip(z)) = level`` with the analytic
    gradient; the step is capped at 0.05 per iteration (see :func:`_snap`)."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    zz = np.empty(2)
    for k in range(z.shape[0]):
        nx, ny = -direction[k, 1], direction[k, 0]
        h = max(math.hypot(nx, ny), 1e-300)
        nx /= h
        ny /= h
        t = 0.0
        for _ in range(iters):
            zz[0], zz[1] = z[k, 0] + t * nx, z[k, 1] + t * ny
            eval_rod(chart, zz, q, gr)
            g, gx, gy = _level(code, p0, p1, level, zz[0], q[X], q[Y])
            dg = (gx * gr[X, 0] + gy * gr[Y, 0]) * nx + (gx * gr[X, 1] + gy * gr[Y, 1]) * ny
            step = g / dg
            if not np.isfinite(step):
                break
            t -= min(max(step, -0.05), 0.05)
            if abs(step) < 1e-12:  # quadratic convergence: the point is now exact to rounding
                break
        zz[0], zz[1] = z[k, 0] + t * nx, z[k, 1] + t * ny
        eval_rod(chart, zz, q, gr)
        g, gx, gy = _level(code, p0, p1, level, zz[0], q[X], q[Y])
        dg = (gx * gr[X, 0] + gy * gr[Y, 0]) * nx + (gx * gr[X, 1] + gy * gr[Y, 1]) * ny
        settled = abs(g) <= 1e-9 * abs(dg) + 1e-13
        if not (settled and abs(t) < max_shift[k]):
            zz[0], zz[1] = z[k, 0], z[k, 1]
            eval_rod(chart, zz, q, gr)
        out[k, 0], out[k, 1] = zz[0], zz[1]
        tips[k, 0] = q[X]
        tips[k, 1] = q[Y]
        tips[k, 2] = q[FX]
        tips[k, 3] = q[FY]


@njit(cache=True)
def _tips_kernel(chart, z, out) -> None:
    """Unit-rod tips ``out[:, 0:4] = x, y, f_x, f_y`` (local frame, force on the tip) at points
    ``z`` of chart ``chart`` (closed form, :func:`~flexkin.rod.kernels.eval_rod`)."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    for k in range(z.shape[0]):
        eval_rod(chart, z[k], q, gr)
        out[k, 0] = q[X]
        out[k, 1] = q[Y]
        out[k, 2] = q[FX]
        out[k, 3] = q[FY]


def _tips(chart: int, z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit-rod tips (n, 4) = ``x, y, f_x, f_y`` at points ``z`` (n, 2) of chart ``chart``."""
    out = np.empty((len(z), 4))
    _tips_kernel(int(chart), np.ascontiguousarray(z, dtype=float), out)
    return out


def _forces(leg, B, t) -> tuple[NDArray, NDArray, NDArray]:
    """World tip forces (n, 2), free lengths (n,) and inputs (n,) of the rods with unit tips
    ``t`` (:func:`_tips`) placed at ``B`` by the leg's actuator."""
    u, alpha, L = leg.actuator.from_tip(B, t[:, 0], t[:, 1])
    return rotate(t[:, 2:4], alpha) * (leg.rod.EI / L**2)[:, None], L, u


def _branch_data(leg, B, z, t, chart=CHART_UNIFIED) -> dict[str, NDArray]:
    z = np.ascontiguousarray(z, dtype=float)
    v, phis = (z[:, 0], z[:, 1]) if chart == CHART_UNIFIED else seam_to_chart(z[:, 0], z[:, 1])
    v = np.ascontiguousarray(v)
    phis = np.ascontiguousarray(phis)
    ku = np.tanh(v)
    force, L, u = _forces(leg, B, t)
    k, psi, q = to_paper(ku, phis)
    return {"v": v, "ku": ku, "phis": phis, "z": z.copy(), "k": k, "psi": psi,
            "kr": kr_from_k(k, psi), "mode": mode_of(phis), "input": u, "force": force, "length": L,
            "tip_moment": np.zeros_like(v), "chart": np.full(len(v), chart, dtype=np.int64)}
