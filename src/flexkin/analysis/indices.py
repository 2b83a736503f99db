"""Kinematic performance indices of equilibria (paper §4.4 and §6: "evaluated pose by pose to
get kinematic performance indices to assess manipulability or to do an optimal design").

Per equilibrium (:func:`performance_indices` over solutions, :func:`index_arrays` over
arrays of equilibria, e.g. every cell of a workspace map):

**Output stiffness** ``K`` (3x3) with the actuators locked: the change of the load wrench
``W = (F_x, F_y, M_z)`` at P that holds the platform displaced by ``dq = (dx, dy, dtheta)``,
``dW = K dq``.  It is the Hessian of the potential reduced to the pose, computed by
:func:`flexkin.analysis.stability.output_stiffness` from the equation system's Jacobian
(rods re-solved with pose and inputs fixed).  Units: ``K[:2, :2]`` N/m, ``K[:2, 2]`` N/rad,
``K[2, :2]`` N (N m/m), ``K[2, 2]`` N m/rad.  Positive definite at a stable equilibrium.

**Compliance** ``C = K^-1``: ``dq = C dW`` (m/N, m/(N m), rad/N, rad/(N m)); ``None`` where
``K`` is singular (an FK singularity).  Two scalar summaries:

* ``force_stiffness = 1 / lambda_max(C[:2, :2])`` (N/m): the stiffness against a force at P in
  its weakest direction, the platform free to turn (the Schur complement of ``K[2, 2]``);
* ``moment_stiffness = 1 / C[2, 2]`` (N m/rad): the stiffness against a moment, the platform
  free to translate.

**Homogenised kinematic Jacobian.**  With a characteristic length ``L_c`` (default: the
mechanism's length scale, the mean rod length, :attr:`Mechanism.length_scale`), positions and
prismatic/length inputs are measured in ``L_c``, angles (platform orientation and revolute
inputs) in radians::

    J_h = diag(1/L_c, 1/L_c, 1) J_IK diag(s_1, s_2, s_3),   s_k = L_c (prismatic, length) or 1 (revolute),

with ``J_IK = d(x, y, theta)/d(rho)`` of Eq. (16) in SI units.  An angular rate ``theta'``
counts as the speed ``L_c theta'`` of a point at distance ``L_c`` from P.

**Velocity ellipsoid** (paper §4.4, ref. [23]): the image under ``J_h`` of the unit ball of
homogenised input rates ``|(rho'_k / s_k)| <= 1``.  Its semi-axes are the singular values
``sigma_1 >= sigma_2 >= sigma_3`` of ``J_h`` (dimensionless), its axes the left singular
vectors (columns of ``U``, in ``(x'/L_c, y'/L_c, theta')``).  ``manipulability = |det J_h| =
sigma_1 sigma_2 sigma_3``.

**Velocity ellipse** of P: the image of the same input ball in ``(x', y')``, under
``J_t = J_IK[:2] diag(s)`` (m/s for a unit homogenised input rate: an actuator speed ``L_c``/s,
or 1 rad/s for a revolute input).  Its semi-axes are the two singular values of ``J_t`` (m/s),
``angle`` the direction of the major axis (rad, from X, in ``(-pi/2, pi/2]``).

**Condition number** ``cond = sigma_1 / sigma_3`` of ``J_h``: dimensionally homogeneous through
``L_c``; ``cond(J_h) = cond(J_h^-1)``, so the same for the FK Jacobian.  ``None`` (infinite) at
an IK singularity (``J_IK`` singular), and where ``J_IK`` does not exist (FK singularity).

**Peak bending strain** of rod i: ``max_s |theta_i'(s)| * c_i`` with ``c_i`` the outer fibre
distance, the rod's ``radius`` (m) when the mechanism gives it, else ``None`` (the convention of
:mod:`flexkin.analysis.feasibility`).  The peak curvature ``max |theta'|`` (1/m) is exact, for pinned and
clamped tips (:func:`~flexkin.analysis.feasibility.rod_max_curvature`).

**Distance to the nearest singularity** is not a property of one equilibrium but of the branch
it lies on: :func:`~flexkin.solve.workspace_map.singularity_distance_map` over a workspace map (the distance in the plane
from each reached cell to the nearest IK/FK singularity found by the map) and
:func:`singularity_distance_along_path` along a path (the arc length to the nearest sign change
of ``det A_IK`` or ``det A_FK``).  Both are ``NaN`` (``None`` in JSON) where a singularity
could lie closer than the nearest one known (beyond the grid's edge, an unresolved cell or a
path's end).  A single solution's ``singularity_distance`` is ``None``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.jsonable import finite_or_none
from ..system import System

__all__ = ["Indices", "IndexArrays", "index_arrays", "performance_indices", "peak_curvature",
           "singularity_distance_along_path", "INDEX_UNITS"]

#: Units of every entry of :meth:`Indices.to_dict` (also in the JSON, under ``"units"``).
INDEX_UNITS: dict[str, str] = {
    "stiffness": "rows (Fx [N], Fy [N], Mz [N m]) per columns (x [m], y [m], theta [rad]): "
                 "N/m, N/rad; N, N m/rad",
    "compliance": "rows (x [m], y [m], theta [rad]) per columns (Fx [N], Fy [N], Mz [N m]): "
                  "m/N, m/(N m); rad/N, rad/(N m)",
    "force_stiffness": "N/m",
    "moment_stiffness": "N m/rad",
    "characteristic_length": "m",
    "velocity_ellipsoid": "dimensionless: (x'/L_c, y'/L_c, theta') per unit homogenised input rate",
    "velocity_ellipse": "m/s per unit homogenised input rate (L_c/s or 1 rad/s); angle in deg from X",
    "manipulability": "dimensionless (|det J_h|)",
    "condition_number": "dimensionless (cond J_h)",
    "peak_curvature": "1/m",
    "peak_strain": "dimensionless (radius * peak curvature)",
    "singularity_distance": "m",
}

#: condition number beyond which K counts as singular (no compliance)
_SINGULAR_K = 1e14


@dataclass(frozen=True, eq=False)
class IndexArrays:
    """Indices of ``n`` equilibria as arrays (see the module docstring; ``NaN`` where undefined).

    Attributes
    ----------
    stiffness, compliance : (n, 3, 3)
        ``K`` (N/m, N/rad, N, N m/rad) and ``C = K^-1``.
    force_stiffness, moment_stiffness : (n,)
        ``1 / lambda_max(C[:2, :2])`` (N/m) and ``1 / C[2, 2]`` (N m/rad).
    ellipsoid_axes : (n, 3)
        Singular values of ``J_h``, decreasing.
    ellipsoid_dirs : (n, 3, 3)
        Their directions, as columns.
    ellipse_axes : (n, 2)
        Semi-axes of the velocity ellipse of P (m/s), major first.
    ellipse_angle : (n,)
        Direction of the major axis (rad, in ``(-pi/2, pi/2]``).
    manipulability, cond : (n,)
        ``|det J_h|`` and ``sigma_1 / sigma_3`` (``inf`` at an IK singularity).
    curvature : (n, 3)
        Peak curvature of each rod (1/m).
    strain : (n, 3)
        Peak bending strain of each rod (``NaN`` without a radius).
    length : float
        The characteristic length ``L_c`` (m).
    """

    stiffness: NDArray[np.float64]
    compliance: NDArray[np.float64]
    force_stiffness: NDArray[np.float64]
    moment_stiffness: NDArray[np.float64]
    ellipsoid_axes: NDArray[np.float64]
    ellipsoid_dirs: NDArray[np.float64]
    ellipse_axes: NDArray[np.float64]
    ellipse_angle: NDArray[np.float64]
    manipulability: NDArray[np.float64]
    cond: NDArray[np.float64]
    curvature: NDArray[np.float64]
    strain: NDArray[np.float64]
    length: float

    def __len__(self) -> int:
        return len(self.cond)

    @property
    def max_strain(self) -> NDArray[np.float64]:
        """Largest peak strain over the rods with a radius (n,), ``NaN`` where none has one."""
        s = self.strain
        known = np.isfinite(s)
        return np.where(known.any(axis=1), np.max(np.where(known, s, -np.inf), axis=1), np.nan)

    def item(self, i: int) -> "Indices":
        """The :class:`Indices` of equilibrium ``i``.

        Parameters
        ----------
        i : int
            Index of the equilibrium in the arrays.

        Returns
        -------
        Indices
        """
        return Indices(self.stiffness[i].copy(), self.compliance[i].copy(), float(self.force_stiffness[i]),
                       float(self.moment_stiffness[i]), self.ellipsoid_axes[i].copy(), self.ellipsoid_dirs[i].copy(),
                       self.ellipse_axes[i].copy(), float(self.ellipse_angle[i]), float(self.manipulability[i]),
                       float(self.cond[i]), self.curvature[i].copy(), self.strain[i].copy(), self.length)


@dataclass(frozen=True, eq=False)
class Indices:
    """Performance indices of one equilibrium (see the module docstring for formulas and units).

    Attributes
    ----------
    stiffness, compliance : (3, 3) ndarray
        Output stiffness ``K`` with the actuators locked and ``C = K^-1`` (``NaN`` if singular).
    force_stiffness, moment_stiffness : float
        N/m and N m/rad.
    ellipsoid_axes, ellipsoid_dirs : ndarray
        Velocity ellipsoid of ``J_h``: semi-axes (3,) and directions (3, 3) as columns.
    ellipse_axes : (2,) ndarray
        Velocity ellipse of P: semi-axes (m/s per unit homogenised input rate).
    ellipse_angle : float
        Major-axis direction (rad).
    manipulability, cond : float
        ``|det J_h|`` and the homogeneous condition number.
    curvature, strain : (3,) ndarray
        Peak curvature (1/m) and peak bending strain (``NaN`` without radius) of each rod.
    length : float
        The characteristic length ``L_c`` (m).
    """

    stiffness: NDArray[np.float64]
    compliance: NDArray[np.float64]
    force_stiffness: float
    moment_stiffness: float
    ellipsoid_axes: NDArray[np.float64]
    ellipsoid_dirs: NDArray[np.float64]
    ellipse_axes: NDArray[np.float64]
    ellipse_angle: float
    manipulability: float
    cond: float
    curvature: NDArray[np.float64]
    strain: NDArray[np.float64]
    length: float

    @property
    def max_strain(self) -> float | None:
        """The largest peak strain over the rods with a radius, ``None`` if none has one."""
        known = [float(s) for s in self.strain if np.isfinite(s)]
        return max(known) if known else None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: ``None`` for every undefined value, angles in degrees, a ``units`` map.

        Returns
        -------
        dict
        """
        def mat(a: NDArray) -> list[list[float]] | None:
            return a.tolist() if np.all(np.isfinite(a)) else None

        def vec(a: NDArray) -> list[float | None]:
            return [finite_or_none(v) for v in a]

        ok_j = bool(np.all(np.isfinite(self.ellipsoid_axes)))
        ok_e = bool(np.all(np.isfinite(self.ellipse_axes)))
        return {
            "stiffness": mat(self.stiffness),
            "compliance": mat(self.compliance),
            "force_stiffness": finite_or_none(self.force_stiffness),
            "moment_stiffness": finite_or_none(self.moment_stiffness),
            "characteristic_length": float(self.length),
            "velocity_ellipsoid": {"semi_axes": self.ellipsoid_axes.tolist(), "axes": self.ellipsoid_dirs.tolist()}
            if ok_j else None,
            "velocity_ellipse": {"semi_axes": self.ellipse_axes.tolist(),
                                 "angle_deg": float(np.degrees(self.ellipse_angle))} if ok_e else None,
            "manipulability": finite_or_none(self.manipulability),
            "condition_number": finite_or_none(self.cond),
            "peak_curvature": vec(self.curvature),
            "peak_strain": vec(self.strain),
            "max_strain": self.max_strain,
            "singularity_distance": None,
            "units": dict(INDEX_UNITS),
        }


# ---------------------------------------------------------------------------------------------
def _stiffness(system: System, X: NDArray, charts: NDArray) -> NDArray[np.float64]:
    """:func:`output_stiffness` of every row, ``NaN`` rows where its linear system is singular.

    The equations' derivatives do not depend on the load (it enters the residual as a
    constant, :mod:`flexkin.system`), so a zero load is passed."""
    from .stability import output_stiffness

    w = np.zeros(3)
    try:
        return output_stiffness(system, X, charts, w)
    except np.linalg.LinAlgError:
        out = np.full((len(X), 3, 3), np.nan)
        for k in range(len(X)):
            try:
                out[k] = output_stiffness(system, X[k:k + 1], charts[k:k + 1], w)[0]
            except np.linalg.LinAlgError:
                pass
        return out


def peak_curvature(rods: Sequence[Any]) -> NDArray[np.float64]:
    """Peak curvature ``max_s |theta'(s)|`` (1/m) of each rod.

    Parameters
    ----------
    rods : sequence of RodState
        Rods of one or more equilibria.

    Returns
    -------
    ndarray
        One value per rod.
    """
    from .feasibility import rod_max_curvature

    return np.array([rod_max_curvature(r) for r in rods], dtype=float)


def _check_length(length: float | None, default: float) -> float:
    if length is None:
        return float(default)
    Lc = float(length)
    if not (math.isfinite(Lc) and Lc > 0.0):
        raise ValueError(f"characteristic_length must be a finite number > 0 (m), got {length!r}")
    return Lc


def index_arrays(mech: Any, X: ArrayLike, charts: ArrayLike, *, rods: Sequence[Sequence[Any]] | None = None,
                 characteristic_length: float | None = None, system: System | None = None) -> IndexArrays:
    """Performance indices of ``n`` equilibria of ``mech`` given as arrays.

    Parameters
    ----------
    mech : Mechanism
        The mechanism (rod radii for the strains, the default characteristic length).
    X : (n, n_unknowns) array_like
        The equilibria's unknowns (:class:`flexkin.system.Layout`), e.g. ``Solution.x``.
    charts : (n, 3) array_like
        The rods' charts.
    rods : sequence of n triples of RodState, optional
        The rods, when already built (else they are built from ``X``).
    characteristic_length : float, optional
        ``L_c`` (m) of the homogenised Jacobian; default ``mech.length_scale``.
    system : System, optional
        The mechanism's equation system, when already built.

    Returns
    -------
    IndexArrays

    Raises
    ------
    ValueError
        For a non-positive or non-finite ``characteristic_length`` or mismatched shapes.
    """
    from .jacobian import kinematic_jacobians

    m = System.from_mechanism(mech) if system is None else system
    Lc = _check_length(characteristic_length, mech.length_scale)
    X = np.atleast_2d(np.asarray(X, dtype=float))
    charts = np.atleast_2d(np.asarray(charts, dtype=np.int64))
    n = len(X)
    if X.shape != (n, m.layout.n_unknowns) or charts.shape != (n, 3):
        raise ValueError(f"X must have shape (n, {m.layout.n_unknowns}) and charts (n, 3), "
                         f"got {X.shape} and {charts.shape}")
    # stiffness and compliance
    K = _stiffness(m, X, charts) if n else np.zeros((0, 3, 3))
    C = np.full_like(K, np.nan)
    finite = np.all(np.isfinite(K), axis=(1, 2))
    with np.errstate(all="ignore"):
        S = np.array([m.L_ref, m.L_ref, 1.0])
        Kh = K / (m.F_ref * m.L_ref) * S[None, :, None] * S[None, None, :]   # dimensionless for conditioning
        ok = finite.copy()
        ok[finite] = np.linalg.cond(Kh[finite]) < _SINGULAR_K
    if np.any(ok):
        C[ok] = np.linalg.inv(K[ok])
    fstiff = np.full(n, np.nan)
    mstiff = np.full(n, np.nan)
    if np.any(ok):
        lam = np.linalg.eigvalsh(0.5 * (C[ok, :2, :2] + np.swapaxes(C[ok, :2, :2], 1, 2)))[:, -1]
        fstiff[ok] = np.where(lam > 0, 1.0 / np.where(lam > 0, lam, 1.0), np.nan)
        crr = C[ok, 2, 2]
        mstiff[ok] = np.where(crr > 0, 1.0 / np.where(crr > 0, crr, 1.0), np.nan)
    # the homogenised Jacobian J_h and its velocity ellipsoid / ellipse
    jac = kinematic_jacobians(m, X, charts, np.zeros(3)) if n else None
    su = m.input_scale()                                     # J_IK of the system: L_ref units
    sc = np.where(m.angular, 1.0, Lc)                        # homogenised input scales s_k
    ax3 = np.full((n, 3), np.nan)
    dirs = np.full((n, 3, 3), np.nan)
    ax2 = np.full((n, 2), np.nan)
    ang = np.full(n, np.nan)
    manip = np.full(n, np.nan)
    cond = np.full(n, np.nan)
    if n:
        J = jac.J_IK
        has = np.all(np.isfinite(J), axis=(1, 2))
        # physical J_IK = diag(L_ref, L_ref, 1) J diag(1/su); then J_h = diag(1/Lc, 1/Lc, 1) J_phys diag(sc)
        Jphys = J[has] * S[None, :, None] / su[None, None, :]
        Jh = Jphys * (1.0 / np.array([Lc, Lc, 1.0]))[None, :, None] * sc[None, None, :]
        if np.any(has):
            U, sv, _ = np.linalg.svd(Jh)
            ax3[has], dirs[has] = sv, U
            manip[has] = np.prod(sv, axis=1)
            with np.errstate(divide="ignore"):
                cond[has] = np.where(sv[:, 2] > 0, sv[:, 0] / np.where(sv[:, 2] > 0, sv[:, 2], 1.0), np.inf)
            Jt = Jphys[:, :2, :] * sc[None, None, :]
            Ut, st, _ = np.linalg.svd(Jt)
            ax2[has] = st
            a = np.arctan2(Ut[:, 1, 0], Ut[:, 0, 0])
            ang[has] = np.where(a > 0.5 * np.pi, a - np.pi, np.where(a <= -0.5 * np.pi, a + np.pi, a))
    # peak curvature and strain
    rods_ = m.rods(X, charts) if rods is None else rods
    curv = np.array([peak_curvature(r) for r in rods_], dtype=float).reshape(n, 3)
    radius = np.array([np.nan if leg.rod.radius is None else float(leg.rod.radius) for leg in mech.legs])
    strain = curv * radius[None, :]
    return IndexArrays(K, C, fstiff, mstiff, ax3, dirs, ax2, ang, manip, cond, curv, strain, Lc)


def performance_indices(solutions: Sequence[Any], characteristic_length: float | None = None
                        ) -> tuple[Indices, ...]:
    """Performance indices of equilibria (batched per mechanism).

    Parameters
    ----------
    solutions : sequence of Solution
        Equilibria, e.g. a :class:`~flexkin.results.KinematicsResult`; each knows its mechanism.
    characteristic_length : float, optional
        ``L_c`` (m) of the homogenised Jacobian; default: each mechanism's ``length_scale``.

    Returns
    -------
    tuple of Indices
        In the order of ``solutions``.
    """
    sols = list(solutions)
    out: list[Indices | None] = [None] * len(sols)
    groups: dict[int, list[int]] = {}
    for k, s in enumerate(sols):
        groups.setdefault(id(s.mechanism), []).append(k)
    for ks in groups.values():
        mech = sols[ks[0]].mechanism
        arr = index_arrays(mech, np.array([sols[k].x for k in ks]), np.array([sols[k].charts for k in ks]),
                           rods=[sols[k].rods for k in ks], characteristic_length=characteristic_length)
        for j, k in enumerate(ks):
            out[k] = arr.item(j)
    return tuple(out)  # type: ignore[arg-type]


def singularity_distance_along_path(poses: ArrayLike, sing_ik: ArrayLike, sing_fk: ArrayLike,
                                    characteristic_length: float) -> NDArray[np.float64]:
    """Arc length along a path from every point to the nearest IK or FK singularity on it.

    A singularity is a sign change of ``det A_IK`` or ``det A_FK`` between two consecutive
    points, placed by linear interpolation of the determinant.  Arc length is measured in the
    homogeneous pose metric ``ds^2 = dx^2 + dy^2 + (L_c dtheta)^2`` (m).  A point whose nearer
    path end is closer than every singularity found gets ``NaN`` (one may lie beyond the end).

    Parameters
    ----------
    poses : (n, 3) array_like
        The path's poses ``(x, y, theta)`` (m, m, rad), e.g. ``PathResult.poses``.
    sing_ik, sing_fk : (n,) array_like
        The singularity measures (``PathResult.sing_ik``, ``sing_fk``,
        :mod:`flexkin.analysis.jacobian`), or any functions that change sign at the singularities.
    characteristic_length : float
        ``L_c`` (m) weighting the orientation.

    Returns
    -------
    ndarray (n,)
        Distances (m), ``NaN`` where unknown.
    """
    P = np.atleast_2d(np.asarray(poses, dtype=float))
    Lc = _check_length(characteristic_length, 1.0)
    n = len(P)
    out = np.full(n, np.nan)
    if n < 2:
        return out
    d = np.diff(P, axis=0) * np.array([1.0, 1.0, Lc])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.hypot(d[:, 0], d[:, 1]), d[:, 2]))])
    cross: list[float] = []
    for g in (np.asarray(sing_ik, dtype=float), np.asarray(sing_fk, dtype=float)):
        for k in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0):
            t = g[k] / (g[k] - g[k + 1])
            cross.append(s[k] + t * (s[k + 1] - s[k]))
    if not cross:
        return out
    c = np.array(cross)
    d_s = np.min(np.abs(s[:, None] - c[None, :]), axis=1)
    d_end = np.minimum(s, s[-1] - s)
    known = d_s <= d_end
    out[known] = d_s[known]
    return out
