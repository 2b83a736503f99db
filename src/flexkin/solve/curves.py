"""Geometric-condition curves of the inverse kinematics (paper §4.1, Figs. 5, 7–9).

For a given platform pose each leg's attach point ``B_i`` is known, and the rods that can
reach it form a one-parameter family: a curve in the rod's parameter space.

* prismatic leg (Fig. 5): the tip height above the guide is fixed, ``y = h``;
* revolute leg (Fig. 8): the tip lies on a circle, ``x^2 + y^2 = r^2``;
* length leg (Fig. 9): on a unit rod the tip lies on the ray of angle ``beta``,
  ``y/x = tan(beta)``, and the solution is scaled by ``|AB|/|tip|``.

The curves are extracted as level sets on the dimensionless atlas (one grid for all
d-modes up to the maximum, see :mod:`flexkin.rod.atlas`) with contourpy's marching
squares.  Every vertex carries its chart coordinates, d-mode, actuator input and the
tip force it would exert in the world frame.  The tip evaluations (closed form) and the
snapping of the polylines onto the exact level set (Newton along the normal with the
analytic gradient of the tip, :func:`flexkin.rod.kernels.unified_eval`, and of the
condition, :func:`flexkin.solve.conditions.condition_eval`) are compiled.
"""

from __future__ import annotations

from dataclasses import dataclass

import math
from typing import Callable

import contourpy
import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d import rotate
from ..core.jit import njit
from ..rod.atlas import get_atlas
from ..rod.closed_form import kr_from_k, mode_of, to_paper
from ..rod.kernels import FX, FY, NQ, X, Y, unified_eval
from .conditions import condition_eval

__all__ = ["LegCurve", "leg_curves"]


@dataclass(frozen=True)
class LegCurve:
    """One leg's geometric-condition set: a list of polylines (branches).

    Each branch is a dict of equally long arrays: ``v``, ``ku = tanh v``, ``phis`` (unified chart),
    ``k``, ``psi``, ``kr``, ``mode`` (paper chart), ``input`` (SI), ``force`` (n, 2; world,
    on the rod tip) and ``length`` (free rod length).
    """

    leg: int
    actuation: str
    branches: tuple[dict[str, NDArray], ...]

    def __len__(self) -> int:
        return len(self.branches)


def leg_curves(mech, B: NDArray[np.float64], max_mode: int, *, theta: float = 0.0, force_tol: float = 0.05,
               passes: int = 8, progress: Callable[[float, str], None] | None = None) -> list[LegCurve]:
    """Geometric-condition curves of the legs for world attach points ``B`` (3, 2) and platform
    orientation ``theta`` (clamped legs: :func:`flexkin.solve.clamped_curves.clamped_leg_curve`).

    For a pinned leg:

    The marching-squares polylines are snapped onto the exact level set (Newton along the
    local normal, closed form) and refined by bisection wherever the rod force jumps by
    more than ``force_tol * (EI/L^2 + |n|)`` between vertices, so that the piecewise-linear
    curves in wrench space stay close to the true ones also where the force grows fast
    (rods near ``|k| = 1``).

    Parameters
    ----------
    mech : Mechanism
    B : (3, 2) world attach points at the imposed pose.
    max_mode : int
        Largest d-mode represented.
    force_tol : float
        Relative force resolution of the refined polylines.
    passes : int
        Maximum number of bisection passes.
    progress : callable, optional
        Called as ``progress(legs done / 3, "leg i")`` after each leg.
    """
    atlas = get_atlas(max_mode)
    out = []
    for i, leg in enumerate(mech.legs):
        if progress is not None and i:
            progress(i / 3, f"leg {i + 1}")
        if leg.platform_joint.carries_moment:
            from .clamped_curves import clamped_leg_curve

            out.append(clamped_leg_curve(mech, i, B[i], theta, max_mode))
            continue
        act = leg.actuator
        ls = act.level_set(B[i])
        f, mask_f = ls.g, ls.mask
        z = f(atlas.x, atlas.y)
        if mask_f is not None:
            z = np.ma.masked_where(~mask_f(atlas.x, atlas.y), z)
        gen = contourpy.contour_generator(x=atlas.PHIS, y=atlas.V, z=z, name="serial",
                                          line_type=contourpy.LineType.Separate)
        code, par = act.condition(B[i])
        branches = []
        for line in gen.lines(0.0):
            if len(line) < 2:
                continue
            zl = np.stack([line[:, 1], line[:, 0]], -1)
            t = _tips(zl)
            for _ in range(passes):  # only the new vertices are evaluated
                f_, L, _ = _forces(leg, B[i], t)
                fscale = leg.rod.EI / L ** 2
                jump = np.max(np.abs(np.diff(f_, axis=0)), axis=1)
                lim = force_tol * (np.minimum(fscale[:-1], fscale[1:]) + np.hypot(*f_[:-1].T))
                bad = np.flatnonzero(jump > lim)
                if bad.size == 0 or len(zl) > 20000:
                    break
                mid, tmid = _snap(code, par, 0.5 * (zl[bad] + zl[bad + 1]), zl[bad + 1] - zl[bad],
                                  max_shift=0.25 * np.hypot(*(zl[bad + 1] - zl[bad]).T))
                zl = np.insert(zl, bad + 1, mid, axis=0)
                t = np.insert(t, bad + 1, tmid, axis=0)
            if mask_f is not None:  # length legs: keep the ray, not its opposite
                keep = mask_f(t[:, 0], t[:, 1])
                if not np.all(keep):
                    for piece in np.split(np.arange(len(zl)), np.flatnonzero(np.diff(keep.astype(int))) + 1):
                        if keep[piece[0]] and len(piece) >= 2:
                            branches.append(_branch_data(leg, B[i], zl[piece], t[piece]))
                    continue
            branches.append(_branch_data(leg, B[i], zl, t))
        out.append(LegCurve(i, leg.actuation, tuple(branches)))
    return out


def _snap(code: int, par: NDArray[np.float64], z: NDArray[np.float64], direction: NDArray[np.float64],
          iters: int = 5, max_shift: NDArray[np.float64] | float = 0.1
          ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Move points ``z`` (n, 2) of chart ``(v, phis)`` onto the leg's level set (condition
    ``code``, ``par``, :meth:`~flexkin.mechanism.actuators.Actuator.condition`) along the
    normal of the local curve tangent ``direction`` (n, 2); returns the points and their unit
    tips (n, 4) as :func:`_tips`.

    Points that would move by more than ``max_shift`` (they would jump to another branch of
    the level set) or where the iteration does not settle keep their original position.
    """
    z = np.ascontiguousarray(z, dtype=float)
    out = np.empty_like(z)
    tips = np.empty((len(z), 4))
    shift = np.broadcast_to(np.asarray(max_shift, dtype=float), (len(z),)).copy()
    _snap_kernel(int(code), float(par[0]), float(par[1]), z, np.ascontiguousarray(direction, dtype=float),
                 iters, shift, out, tips)
    return out, tips


@njit(cache=True)
def _snap_kernel(code, p0, p1, z, direction, iters, max_shift, out, tips) -> None:
    """Newton along the normal of ``direction`` on ``g(tip(v, phis)) = 0`` with the analytic
    gradient; the step is capped at 0.05 per iteration (see :func:`_snap`)."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    for k in range(z.shape[0]):
        nx, ny = -direction[k, 1], direction[k, 0]
        h = max(math.hypot(nx, ny), 1e-300)
        nx /= h
        ny /= h
        t = 0.0
        for _ in range(iters):
            unified_eval(z[k, 0] + t * nx, z[k, 1] + t * ny, q, gr)
            g, gx, gy, _a, _ax, _ay, _ok = condition_eval(code, p0, p1, q[X], q[Y])
            dg = (gx * gr[X, 0] + gy * gr[Y, 0]) * nx + (gx * gr[X, 1] + gy * gr[Y, 1]) * ny
            step = g / dg
            if np.isfinite(step):
                t -= min(max(step, -0.05), 0.05)
                if abs(step) < 1e-15:
                    break
        px, py = z[k, 0] + t * nx, z[k, 1] + t * ny
        unified_eval(px, py, q, gr)
        g, gx, gy, _a, _ax, _ay, _ok = condition_eval(code, p0, p1, q[X], q[Y])
        dg = (gx * gr[X, 0] + gy * gr[Y, 0]) * nx + (gx * gr[X, 1] + gy * gr[Y, 1]) * ny
        settled = abs(g) <= 1e-9 * abs(dg) + 1e-13
        if not (settled and abs(t) < max_shift[k]):
            px, py = z[k, 0], z[k, 1]
            unified_eval(px, py, q, gr)
        out[k, 0], out[k, 1] = px, py
        tips[k, 0] = q[X]
        tips[k, 1] = q[Y]
        tips[k, 2] = q[FX]
        tips[k, 3] = q[FY]


@njit(cache=True)
def _tips_kernel(z, out) -> None:
    """Unit-rod tips ``out[:, 0:4] = x, y, f_x, f_y`` (local frame, force on the tip) at chart
    points ``z = (v, phis)`` (closed form, :func:`~flexkin.rod.kernels.unified_eval`)."""
    q = np.empty(NQ)
    gr = np.empty((NQ, 3))
    for k in range(z.shape[0]):
        unified_eval(z[k, 0], z[k, 1], q, gr)
        out[k, 0] = q[X]
        out[k, 1] = q[Y]
        out[k, 2] = q[FX]
        out[k, 3] = q[FY]


def _tips(z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit-rod tips (n, 4) = ``x, y, f_x, f_y`` at chart points ``z`` (n, 2)."""
    out = np.empty((len(z), 4))
    _tips_kernel(np.ascontiguousarray(z, dtype=float), out)
    return out


def _forces(leg, B, t) -> tuple[NDArray, NDArray, NDArray]:
    """World tip forces (n, 2), free lengths (n,) and inputs (n,) of the rods with unit tips
    ``t`` (:func:`_tips`) placed at ``B`` by the leg's actuator."""
    u, alpha, L = leg.actuator.from_tip(B, t[:, 0], t[:, 1])
    return rotate(t[:, 2:4], alpha) * (leg.rod.EI / L**2)[:, None], L, u


def _branch_data(leg, B, z, t) -> dict[str, NDArray]:
    v = np.ascontiguousarray(z[:, 0])
    phis = np.ascontiguousarray(z[:, 1])
    ku = np.tanh(v)
    force, L, u = _forces(leg, B, t)
    k, psi, q = to_paper(ku, phis)
    return {"v": v, "ku": ku, "phis": phis, "z": np.stack([v, phis], -1), "k": k, "psi": psi,
            "kr": kr_from_k(k, psi), "mode": mode_of(phis), "input": u, "force": force, "length": L,
            "tip_moment": np.zeros_like(v)}
