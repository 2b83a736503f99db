"""The one equation system of a planar PCM (paper Eqs. 15 and 17), assembled from its legs.

Every analysis (IK, FK, paths, workspaces, Jacobians, the Cosserat refinement's start) uses
this system; they differ only in which unknowns are held fixed.

Unknowns (named by :class:`Layout`), for ``n`` candidates at once, columns of ``X``:

* ``rod[i]``: the chart coordinates of rod ``i`` -- 2 for a pinned tip (``(v, phis)`` or the
  seam chart), 3 for a clamped tip (its dimensionless base wrench); which chart a row uses
  is given per rod by an integer array (:mod:`flexkin.rod.kernels`);
* ``pose``: ``(x, y, theta)`` of the platform (m, m, rad);
* ``inputs``: the actuator inputs (m, or rad for revolute legs).

Equations, all scaled to O(1), rows of the residual:

* ``tip[i]``: what leg ``i``'s joint imposes at ``B_i = P + Rot(theta) b_i``: the tip position
  ``(A_i + L_i Rot(alpha_i) tip_unit - B_i) / L_ref`` (2; the rigid-body closure, equivalent to
  Eq. 17 once the pose is eliminated) and, for a clamped tip, its angle
  ``wrap_angle(alpha_i + theta_unit - theta - tip_angle_i)`` (1, into ``(-pi, pi]``);
* ``force``, ``moment``: platform equilibrium (Eq. 15 with the sign of SPEC §2; the platform
  receives ``-n_i`` and ``-m_i(L)``): ``(sum n_i - F) / F_ref`` and
  ``(sum (B_i - P) x n_i + sum m_i(L) - M) / (F_ref L_ref)``.

The actuators enter through their affine clamp maps ``(A, alpha, L) = c0 + c1 u``
(:meth:`~flexkin.mechanism.actuators.Actuator.affine`), so the Jacobian with respect to the
inputs is exact; the rods' derivatives come from the closed form (:mod:`flexkin.rod.kernels`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from .core.jit import njit
from numpy.typing import NDArray

from .mechanism.joints import CLAMPED, JOINTS
from .rod.state import RodState
from .core.geometry2d import platform_points, rotate
from .core.geometry2d_kernels import wrap_angle
from .rod.kernels import (CHART_DIM, CHART_UNIFIED, CHART_WRENCH, EN, FX, FY, M0, ML, NQ, TH, X, Y, eval_rod,
                          eval_rods)

X_, Y_ = X, Y

__all__ = ["Layout", "System", "evaluate", "TWO_PI"]

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class Layout:
    """Named layout of a mechanism's unknowns (columns) and equations (rows).

    Attributes
    ----------
    rod : three slices
        Columns of each rod's chart coordinates.
    pose, inputs : slice
        Columns of the pose ``(x, y, theta)`` and of the three inputs.
    tip : three slices
        Rows of each leg's tip equations (2 for a pinned tip, 3 for a clamped one).
    force, moment : slice
        Rows of the platform's force balance (2) and moment balance (1).
    """

    rod: tuple[slice, slice, slice]
    pose: slice
    inputs: slice
    tip: tuple[slice, slice, slice]
    force: slice
    moment: slice

    @classmethod
    def for_joints(cls, clamped: tuple[bool, bool, bool]) -> "Layout":
        """The layout for legs whose tips are clamped (True) or pinned (False)."""
        col = row = 0
        rods, tips = [], []
        for c in clamped:
            d = 3 if c else 2
            rods.append(slice(col, col + d))
            col += d
            e = 3 if c else 2
            tips.append(slice(row, row + e))
            row += e
        return cls(tuple(rods), slice(col, col + 3), slice(col + 3, col + 6), tuple(tips),  # type: ignore[arg-type]
                   slice(row, row + 2), slice(row + 2, row + 3))

    @property
    def n_unknowns(self) -> int:
        """Number of columns (rods, pose, inputs)."""
        return self.inputs.stop

    @property
    def n_equations(self) -> int:
        """Number of rows (tip equations, force, moment)."""
        return self.moment.stop

    @property
    def n_rod(self) -> int:
        """Number of rod chart coordinates (all rods)."""
        return self.pose.start

    def columns(self, fixed: str) -> NDArray[np.int64]:
        """Columns solved for when ``"pose"`` (inverse kinematics) or ``"inputs"`` (forward
        kinematics) is held fixed."""
        keep = self.inputs if fixed == "pose" else self.pose
        return np.r_[np.arange(self.n_rod), np.arange(keep.start, keep.stop)].astype(np.int64)


@dataclass(frozen=True, eq=False)
class System:
    """A mechanism as the plain arrays the compiled kernels read (built once per analysis).

    Use :meth:`from_mechanism`; the arrays are read-only.
    """

    layout: Layout
    c0: NDArray[np.float64]        # (3, 4) affine clamp maps (A_x, A_y, alpha, L) = c0 + c1 u
    c1: NDArray[np.float64]        # (3, 4)
    EI: NDArray[np.float64]        # (3,)
    attach: NDArray[np.float64]    # (3, 2) b_i in the platform frame
    joint: NDArray[np.int64]       # (3,) joint codes
    tip_angle: NDArray[np.float64]  # (3,) clamped tips' tangent in the platform frame
    rod_col: NDArray[np.int64]     # (3,) first column of each rod
    tip_row: NDArray[np.int64]     # (3,) first row of each leg's tip equations
    angular: NDArray[np.bool_]     # (3,) angular inputs (revolute)
    L_ref: float
    EI_ref: float

    @classmethod
    def from_mechanism(cls, mech) -> "System":
        """Assemble the arrays from a :class:`~flexkin.mechanism.Mechanism`."""
        legs = mech.legs
        clamped = tuple(leg.platform_joint.code == CLAMPED for leg in legs)
        lay = Layout.for_joints(clamped)  # type: ignore[arg-type]
        aff = [leg.actuator.affine() for leg in legs]
        arr = {
            "c0": np.array([a[0] for a in aff]), "c1": np.array([a[1] for a in aff]),
            "EI": np.array([leg.rod.EI for leg in legs], dtype=float),
            "attach": np.array(mech.platform.attach, dtype=float),
            "joint": np.array([leg.platform_joint.code for leg in legs], dtype=np.int64),
            "tip_angle": np.array([leg.tip_angle for leg in legs], dtype=float),
            "rod_col": np.array([s.start for s in lay.rod], dtype=np.int64),
            "tip_row": np.array([s.start for s in lay.tip], dtype=np.int64),
            "angular": np.array([leg.actuator.angular for leg in legs]),
        }
        for a in arr.values():
            a.setflags(write=False)
        return cls(lay, L_ref=float(mech.length_scale), EI_ref=float(np.mean(arr["EI"])), **arr)

    # ---- scales -------------------------------------------------------------------------
    @property
    def F_ref(self) -> float:
        """Force scale ``EI_ref / L_ref**2`` (N)."""
        return self.EI_ref / self.L_ref**2

    @property
    def clamped(self) -> NDArray[np.bool_]:
        """Which tips are clamped."""
        return self.joint == CLAMPED

    def wrench_scale(self) -> NDArray[np.float64]:
        """Scales of ``(F_x, F_y, M_z)``."""
        return np.array([self.F_ref, self.F_ref, self.F_ref * self.L_ref])

    def input_scale(self) -> NDArray[np.float64]:
        """Scale of each input (``L_ref``, or 1 for angles)."""
        return np.where(self.angular, 1.0, self.L_ref)

    def unknown_scale(self) -> NDArray[np.float64]:
        """Scale of every column (1 for chart coordinates and angles, ``L_ref`` for lengths)."""
        s = np.ones(self.layout.n_unknowns)
        s[self.layout.pose][:2] = self.L_ref
        s[self.layout.inputs] = self.input_scale()
        return s

    def default_charts(self, n: int) -> NDArray[np.int64]:
        """Chart codes (n, 3): the unified chart for pinned rods, the wrench chart for clamped."""
        return np.broadcast_to(np.where(self.clamped, CHART_WRENCH, CHART_UNIFIED), (n, 3)).copy()

    # ---- geometry -----------------------------------------------------------------------
    def clamps(self, inputs: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """Clamp points ``A`` (n, 3, 2), tangent angles ``alpha`` (n, 3) and free lengths ``L`` (n, 3)
        for inputs (n, 3), through the legs' affine clamp maps."""
        u = np.atleast_2d(np.asarray(inputs, dtype=float))
        q = self.c0[None] + u[..., None] * self.c1[None]
        return q[..., :2], q[..., 2], q[..., 3]

    def platform_points(self, pose: NDArray) -> NDArray[np.float64]:
        """World attach points ``B_i`` (n, 3, 2) for poses (n, 3)."""
        return platform_points(self.attach, np.atleast_2d(pose))

    def rod_x(self, X: NDArray, i: int) -> NDArray[np.float64]:
        """Chart coordinates of rod ``i`` (n, 3), zero-padded for 2-coordinate charts."""
        X = np.atleast_2d(X)
        sl = self.layout.rod[i]
        out = np.zeros((len(X), 3))
        out[:, :sl.stop - sl.start] = X[:, sl]
        return out

    def unit_rods(self, X: NDArray, charts: NDArray) -> tuple[NDArray, NDArray]:
        """Unit-rod tip quantities (n, 3, NQ) and their chart gradients (n, 3, NQ, 3)."""
        X = np.atleast_2d(X)
        n = len(X)
        out = np.empty((n, 3, NQ))
        grad = np.empty((n, 3, NQ, 3))
        ch = np.asarray(charts, dtype=np.int64).reshape(n, 3)
        q, g = np.empty((n, NQ)), np.empty((n, NQ, 3))   # contiguous: the kernel's one signature
        for i in range(3):
            eval_rods(np.ascontiguousarray(ch[:, i]), self.rod_x(X, i), q, g)
            out[:, i], grad[:, i] = q, g
        return out, grad

    def rod_world(self, X: NDArray, charts: NDArray) -> dict[str, NDArray]:
        """World-frame rod quantities of candidates ``X``: ``tip`` (n, 3, 2), ``force`` on the
        tips (n, 3, 2), ``tip_angle``, ``base_moment``, ``tip_moment``, ``energy`` (n, 3)."""
        X = np.atleast_2d(X)
        q, _ = self.unit_rods(X, charts)
        A, al, L = self.clamps(X[:, self.layout.inputs])
        EI = self.EI[None]
        return {
            "tip": A + L[..., None] * rotate(q[..., [X_, Y_]], al),
            "force": (EI / L**2)[..., None] * rotate(q[..., [FX, FY]], al),
            "tip_angle": al + q[..., TH],
            "base_moment": EI / L * q[..., M0],
            "tip_moment": EI / L * q[..., ML],
            "energy": EI / L * q[..., EN],
        }

    def rods(self, X: NDArray, charts: NDArray, modes: NDArray | None = None) -> list[tuple[RodState, ...]]:
        """The rods of every row of ``X`` as :class:`~flexkin.rod.state.RodState` objects.

        Parameters
        ----------
        X : (n, n_unknowns) ndarray
            Equilibria (or candidates).
        charts : (n, 3) ndarray
            Their rods' charts.
        modes : (n, 3) ndarray, optional
            The rods' d-modes (e.g. :func:`flexkin.solve.finish.rod_modes`); 0 when not given
            (the shapes, curvatures and contacts do not need them).

        Returns
        -------
        list of tuple of 3 RodState
            One triple per row.
        """
        X = np.atleast_2d(X)
        charts = np.asarray(charts, dtype=np.int64).reshape(len(X), 3)
        modes = np.zeros((len(X), 3), np.int64) if modes is None else np.asarray(modes).reshape(len(X), 3)
        names = {cls.code: cls.name for cls in JOINTS.values()}
        q, _ = self.unit_rods(X, charts)
        lay = self.layout
        A, alpha, L = self.clamps(X[:, lay.inputs])
        return [tuple(RodState.from_unit(q[j, i], int(charts[j, i]), X[j, lay.rod[i]], L[j, i], self.EI[i],
                                         A[j, i], alpha[j, i], int(modes[j, i]), names[int(self.joint[i])])
                      for i in range(3))
                for j in range(len(X))]

    # ---- evaluation ---------------------------------------------------------------------
    def args(self) -> tuple:
        """The arrays in the order the kernels take them."""
        return (self.c0, self.c1, self.EI, self.attach, self.joint, self.tip_angle, self.rod_col, self.tip_row,
                self.L_ref, self.F_ref)

    def residual(self, X: NDArray, charts: NDArray, load: NDArray) -> NDArray[np.float64]:
        """Scaled residual, shape (n, n_equations)."""
        X = np.ascontiguousarray(np.atleast_2d(X), dtype=float)
        n = len(X)
        R = np.empty((n, self.layout.n_equations))
        J = np.empty((0, 0, 0))
        evaluate(*self.args(), X, np.ascontiguousarray(charts, dtype=np.int64), np.asarray(load, dtype=float),
                 R, J, False)
        return R

    def jacobian(self, X: NDArray, charts: NDArray, load: NDArray) -> tuple[NDArray, NDArray]:
        """Scaled residual (n, n_eq) and its Jacobian (n, n_eq, n_unknowns) in the raw unknowns."""
        X = np.ascontiguousarray(np.atleast_2d(X), dtype=float)
        n = len(X)
        lay = self.layout
        R = np.empty((n, lay.n_equations))
        J = np.empty((n, lay.n_equations, lay.n_unknowns))
        evaluate(*self.args(), X, np.ascontiguousarray(charts, dtype=np.int64), np.asarray(load, dtype=float),
                 R, J, True)
        return R, J


@njit(cache=True)
def eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
             x, chart, load, r, J, want_J, q, g) -> None:
    """Residual ``r`` (and, with ``want_J``, its Jacobian ``J``) of one candidate ``x``.

    ``q`` (3, NQ) and ``g`` (3, NQ, 3) are scratch arrays for the rods' unit quantities.
    """
    nu = x.shape[0]
    for i in range(3):
        col = rod_col[i]
        dim = 3 if chart[i] >= CHART_WRENCH else 2
        eval_rod(chart[i], x[col:col + dim], q[i], g[i])
    assemble(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, x, chart, load, r, J, want_J,
             q, g)
    _ = nu


@njit(cache=True)
def assemble(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
             x, chart, load, r, J, want_J, q, g) -> None:
    """The residual and Jacobian of candidate ``x`` from its rods' unit quantities ``q`` (3, NQ)
    and chart gradients ``g`` (3, NQ, 3) (evaluated by :func:`eval_one`, or cached by a search)."""
    nu = x.shape[0]
    ne = r.shape[0]
    ip = nu - 6   # first pose column
    iu = nu - 3   # first input column
    px, py, th = x[ip], x[ip + 1], x[ip + 2]
    cth, sth = math.cos(th), math.sin(th)
    fsum_x = 0.0
    fsum_y = 0.0
    msum = 0.0
    if want_J:
        J[:, :] = 0.0
    rf = ne - 3   # first force row
    inv_L = 1.0 / L_ref
    inv_F = 1.0 / F_ref
    inv_M = 1.0 / (F_ref * L_ref)
    for i in range(3):
        qi = q[i]
        gi = g[i]
        u = x[iu + i]
        Ax = c0[i, 0] + c1[i, 0] * u
        Ay = c0[i, 1] + c1[i, 1] * u
        al = c0[i, 2] + c1[i, 2] * u
        L = c0[i, 3] + c1[i, 3] * u
        dAx, dAy, dal, dL = c1[i, 0], c1[i, 1], c1[i, 2], c1[i, 3]
        col = rod_col[i]
        dim = 3 if chart[i] >= CHART_WRENCH else 2
        ca, sa = math.cos(al), math.sin(al)
        # rotated unit-rod tip and force (local -> world directions)
        rx = ca * qi[X] - sa * qi[Y]
        ry = sa * qi[X] + ca * qi[Y]
        tipx = Ax + L * rx
        tipy = Ay + L * ry
        sf = EI[i] / (L * L)
        wx = ca * qi[FX] - sa * qi[FY]
        wy = sa * qi[FX] + ca * qi[FY]
        fx = sf * wx
        fy = sf * wy
        sm = EI[i] / L
        mL = sm * qi[ML]
        bx = cth * attach[i, 0] - sth * attach[i, 1]
        by = sth * attach[i, 0] + cth * attach[i, 1]
        row = tip_row[i]
        r[row] = (tipx - px - bx) * inv_L
        r[row + 1] = (tipy - py - by) * inv_L
        clamped = joint[i] == CLAMPED
        if clamped:
            r[row + 2] = wrap_angle(al + qi[TH] - th - tip_angle[i])
        fsum_x += fx
        fsum_y += fy
        msum += bx * fy - by * fx + mL
        if want_J:
            for j in range(dim):
                gx = L * (ca * gi[X, j] - sa * gi[Y, j])
                gy = L * (sa * gi[X, j] + ca * gi[Y, j])
                J[row, col + j] = gx * inv_L
                J[row + 1, col + j] = gy * inv_L
                gfx = sf * (ca * gi[FX, j] - sa * gi[FY, j])
                gfy = sf * (sa * gi[FX, j] + ca * gi[FY, j])
                J[rf, col + j] = gfx * inv_F
                J[rf + 1, col + j] = gfy * inv_F
                J[rf + 2, col + j] = (bx * gfy - by * gfx + sm * gi[ML, j]) * inv_M
                if clamped:
                    J[row + 2, col + j] = gi[TH, j]
            # inputs: d/du of tip, force, moment through the affine clamp map
            dtx = dAx + dL * rx - L * dal * ry
            dty = dAy + dL * ry + L * dal * rx
            J[row, iu + i] = dtx * inv_L
            J[row + 1, iu + i] = dty * inv_L
            dsf = -2.0 * EI[i] * dL / (L * L * L)
            dfx = dsf * wx - sf * dal * wy
            dfy = dsf * wy + sf * dal * wx
            J[rf, iu + i] = dfx * inv_F
            J[rf + 1, iu + i] = dfy * inv_F
            dmL = -EI[i] * dL / (L * L) * qi[ML]
            J[rf + 2, iu + i] = (bx * dfy - by * dfx + dmL) * inv_M
            if clamped:
                J[row + 2, iu + i] = dal
                J[row + 2, ip + 2] = -1.0
            # pose
            J[row, ip] = -inv_L
            J[row + 1, ip + 1] = -inv_L
            J[row, ip + 2] = by * inv_L       # -dB_x/dtheta = +b_y'
            J[row + 1, ip + 2] = -bx * inv_L  # -dB_y/dtheta = -b_x'
            J[rf + 2, ip + 2] += -(bx * fx + by * fy) * inv_M
    r[rf] = (fsum_x - load[0]) * inv_F
    r[rf + 1] = (fsum_y - load[1]) * inv_F
    r[rf + 2] = (msum - load[2]) * inv_M


@njit(cache=True)
def evaluate(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
             X, charts, load, R, J, want_J) -> None:
    """:func:`eval_one` for every row of ``X``; non-finite rod evaluations give NaN rows."""
    q = np.empty((3, NQ))
    g = np.empty((3, NQ, 3))
    Jd = np.empty((0, 0))
    for k in range(X.shape[0]):
        if want_J:
            eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
                     X[k], charts[k], load, R[k], J[k], True, q, g)
        else:
            eval_one(c0, c1, EI, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref,
                     X[k], charts[k], load, R[k], Jd, False, q, g)


_ = CHART_DIM  # (re-exported for the layout's readers)
