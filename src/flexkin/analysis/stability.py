"""Stability of an equilibrium with the actuators locked (paper §4.3), exactly.

The total potential of the mechanism is

    V = sum_i (EI_i/2) int_0^{L_i} theta_i'(s)^2 ds  -  F . P  -  M theta_P,

on the configurations with every rod clamped (actuators locked) and every rod tip pinned to
its platform point ``B_i = P + Rot(theta_P) b_i``.  An equilibrium is stable when the second
variation of V is positive definite on the admissible perturbations.  Its index (number of
unstable directions) is computed exactly, by inertia additivity (Haynsworth) twice:

1. **each rod with its tip pinned** (the platform held still).  Let ``Q`` be the rod's second
   variation with its tip force ``n`` treated as a dead load,
   ``Q[eta] = int EI eta'^2 + (n . t) eta^2 ds`` on ``eta(0) = 0``, and ``C`` the map to the
   tip displacement.  The bordered matrix ``[[Q, C^T], [C, 0]]`` gives
   ``index(Q on ker C) = index(Q) - neg(C Q^-1 C^T)``, where ``index(Q)`` follows from
   Sturm's oscillation theorem (Pruefer angle of the Jacobi field ``u'' = (n . t) u``,
   :func:`free_index`) and ``C Q^-1 C^T = dp/dn`` is the rod's tip compliance along its
   family of equilibria, from the closed form (:func:`rod_compliance`).
2. **the platform**, moving the rod tips: the reduced Hessian of
   ``V(q) = sum_i U_i(p_i(q)) - F.P - M theta`` over the pose ``q``, where ``U_i(p)`` is the
   rod's equilibrium energy with its tip at ``p``, ``grad U_i = n_i`` (the force on the tip)
   and ``hess U_i = K_i = dn_i/dp_i`` (the tip stiffness):

       H = sum_i J_i^T K_i J_i  -  diag(0, 0, sum_i n_i . (B_i - P)),   J_i = [I, perp(B_i - P)].

The Morse index of the equilibrium is the sum of the rods' pinned indices and the number of
negative eigenvalues of H; the equilibrium is stable when it is 0.  The same steps give the
classical cantilever (free tip, dead load) and column (tip on a slider) results
(:func:`rod_stability`).  Counting the zeros of ``det [dm; dr]`` over the Jacobi fields
(conjugate points) is *not* enough for these isoperimetric problems: zeros can be crossed in
either direction (Manning, Rogers & Maddocks 1998), which the inertia formula handles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ..core.jit import njit
from numpy.typing import ArrayLike, NDArray

from ..core.geometry2d import rot2
from ..rod.closed_form import standard_chart, tangent_angles, tip_any, tip_chart
from ..rod.state import RodState
from ..system import System

__all__ = ["free_index", "rod_pinned_index", "rod_compliance", "rod_tip_stiffness", "reduced_hessian",
           "mechanism_stability",
           "rod_stability", "RodStability", "JACOBI_STEPS"]

#: RK4 steps along a unit rod for the Jacobi field (theta sampled at twice this rate)
JACOBI_STEPS = 256


@njit(cache=True)
def _pruefer_kernel_h(theta: NDArray, force: NDArray, h: float, out_angle: NDArray) -> None:
    n, ns = theta.shape
    N = (ns - 1) // 2
    for r in range(n):
        fx, fy = force[r, 0], force[r, 1]
        u, du, ang = 0.0, 1.0, 0.0
        for j in range(N):
            q0 = fx * np.cos(theta[r, 2 * j]) + fy * np.sin(theta[r, 2 * j])
            qm = fx * np.cos(theta[r, 2 * j + 1]) + fy * np.sin(theta[r, 2 * j + 1])
            q1 = fx * np.cos(theta[r, 2 * j + 2]) + fy * np.sin(theta[r, 2 * j + 2])
            k1u, k1d = du, q0 * u
            k2u, k2d = du + 0.5 * h * k1d, qm * (u + 0.5 * h * k1u)
            k3u, k3d = du + 0.5 * h * k2d, qm * (u + 0.5 * h * k2u)
            k4u, k4d = du + h * k3d, q1 * (u + h * k3u)
            u += h / 6.0 * (k1u + 2.0 * k2u + 2.0 * k3u + k4u)
            du += h / 6.0 * (k1d + 2.0 * k2d + 2.0 * k3d + k4d)
            nrm = np.sqrt(u * u + du * du)
            u /= nrm
            du /= nrm
            a = np.arctan2(u, du)
            a += 2.0 * np.pi * np.round((ang - a) / (2.0 * np.pi))
            ang = a
        out_angle[r] = ang


def free_index(theta: NDArray[np.float64], force: NDArray[np.float64]) -> NDArray[np.int64]:
    """Index of the second variation of clamped unit rods under their tip force as a dead load.

    ``Q[eta] = int eta'^2 + q eta^2 ds``, ``q = n . t`` (``eta(0) = 0``, natural end): by
    Sturm's oscillation theorem in Pruefer form (``u'' = q u``, ``u(0) = 0``, ``u'(0) = 1``,
    ``u = r sin(a)``, ``u' = r cos(a)``), the number of negative eigenvalues is the number of
    ``k >= 0`` with ``a(1) > pi/2 + k pi``.  (Counting the zeros of ``u'`` instead would be
    wrong: where ``q > 0`` they are crossed backwards.)

    Parameters
    ----------
    theta : ndarray, shape (n, 2 N + 1)
        Tangent angle at ``s = linspace(0, 1, 2 N + 1)``.
    force : ndarray, shape (n, 2)
        Tip force (unit rod, same frame as ``theta``).
    """
    theta = np.ascontiguousarray(theta, dtype=float)
    f = np.ascontiguousarray(force, dtype=float)
    ang = np.zeros(theta.shape[0])
    if theta.shape[0]:
        _pruefer_kernel_h(theta, f, 1.0 / ((theta.shape[1] - 1) // 2), ang)
    return np.maximum(0, np.floor((ang - 0.5 * np.pi) / np.pi).astype(np.int64) + 1)


def rod_compliance(v: ArrayLike, phis: ArrayLike, step: float = 1e-6) -> NDArray[np.float64]:
    """Tip compliance ``dp/dn`` of unit rods with zero tip moment, local frame, (n, 2, 2).

    The inverse of the tip stiffness (:func:`rod_tip_stiffness`), but finite also for a
    straight rod (whose axial compliance is 0).
    """
    Jp, Jf = _chart_jacobians(v, phis, step)
    return Jp @ np.linalg.pinv(Jf)


def _chart_jacobians(v: ArrayLike, phis: ArrayLike, step: float) -> tuple[NDArray, NDArray]:
    v = np.atleast_1d(np.asarray(v, dtype=float))
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    cols_p, cols_f = [], []
    for dv, dp in ((step, 0.0), (0.0, step)):
        a, b = tip_any(v + dv, phis + dp), tip_any(v - dv, phis - dp)
        cols_p.append(np.stack([a.x - b.x, a.y - b.y], -1) / (2 * step))
        cols_f.append(np.stack([a.fx - b.fx, a.fy - b.fy], -1) / (2 * step))
    return np.stack(cols_p, -1), np.stack(cols_f, -1)


def _neg_count(A: NDArray[np.float64]) -> NDArray[np.int64]:
    """Number of clearly negative eigenvalues of symmetric parts (zeros are not counted)."""
    ev = np.linalg.eigvalsh(0.5 * (A + np.swapaxes(A, -1, -2)))
    tol = 1e-9 * np.max(np.abs(ev), axis=-1, keepdims=True)
    return np.sum(ev < -tol, axis=-1)


def _theta_nodes(v: NDArray, phis: NDArray, steps: int) -> NDArray[np.float64]:
    v, phis = standard_chart(v, phis)
    return tangent_angles(v, phis, np.linspace(0.0, 1.0, 2 * steps + 1))


def rod_pinned_index(v: ArrayLike, phis: ArrayLike, steps: int = JACOBI_STEPS) -> NDArray[np.int64]:
    """Index (unstable directions) of clamped unit rods with their tip pinned (chart coordinates).

    With ``Q`` the second variation under the tip force as a dead load and ``C`` the map to
    the tip displacement, the bordered-matrix inertia (Haynsworth) gives
    ``index(Q on ker C) = index(Q) - neg(C Q^-1 C^T)``, and ``C Q^-1 C^T`` is the rod's tip
    compliance ``dp/dn`` along its equilibrium family (:func:`rod_compliance`).  A zero
    eigenvalue of the compliance (a straight rod: its axial constraint is vacuous to first
    order) is not counted.
    """
    v = np.atleast_1d(np.asarray(v, dtype=float))
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    theta = _theta_nodes(v, phis, steps)
    t = tip_any(v, phis)
    free = free_index(theta, np.stack([t.fx, t.fy], -1))
    return free - _neg_count(rod_compliance(v, phis))


def rod_tip_stiffness(v: ArrayLike, phis: ArrayLike, step: float = 1e-6) -> NDArray[np.float64]:
    """Tip stiffness ``K = dn/dp`` of unit rods, local frame, shape (n, 2, 2).

    ``K`` is the Hessian of the rod's equilibrium energy as a function of its tip position
    (``grad U = n``), so it is symmetric; computed as ``(dn/dz) (dp/dz)^-1`` on the chart
    ``z = (v, phis)`` by central differences of the closed form (Eqs. 9, 12, 13).  Where the
    chart is degenerate (the unloaded straight rod, the pole of the chart) the derivative is
    taken at a point 1e-6 away, inside the loaded rods.
    """
    v = np.atleast_1d(np.asarray(v, dtype=float)).copy()
    phis = np.atleast_1d(np.asarray(phis, dtype=float)).copy()
    Jp, Jf = _chart_jacobians(v, phis, step)
    det = np.linalg.det(Jp)
    bad = ~(np.abs(det) > 1e-12 * np.sum(Jp**2, axis=(1, 2)))
    if np.any(bad):
        phis[bad] -= 1e-6
        v[bad] += 1e-6
        Jp[bad], Jf[bad] = _chart_jacobians(v[bad], phis[bad], step)
    return Jf @ np.linalg.pinv(Jp)


def reduced_hessian(system: System, X: NDArray, charts: NDArray) -> NDArray[np.float64]:
    """Reduced Hessian ``H`` (n, 3, 3) of the potential over the pose (module docstring).

    Dimensionless: translations in units of ``L_ref``, energy in ``EI_ref / L_ref``.
    """
    X = np.atleast_2d(X)
    n = len(X)
    lay = system.layout
    _, alpha, L = system.clamps(X[:, lay.inputs])
    w = system.rod_world(X, charts)
    force = w["force"]
    arm = system.platform_points(X[:, lay.pose]) - X[:, None, lay.pose][..., :2]
    H = np.zeros((n, 3, 3))
    for i in range(3):
        z = _pinned_coords(system, X, charts, i)
        Kl = rod_tip_stiffness(z[:, 0], z[:, 1]) * (system.EI[i] / L[:, i] ** 3)[:, None, None]
        Rm = rot2(alpha[:, i])
        K = Rm @ Kl @ np.swapaxes(Rm, 1, 2)
        J = np.zeros((n, 2, 3))
        J[:, 0, 0] = J[:, 1, 1] = 1.0
        J[:, 0, 2] = -arm[:, i, 1]
        J[:, 1, 2] = arm[:, i, 0]
        H += np.swapaxes(J, 1, 2) @ K @ J
        H[:, 2, 2] -= np.sum(force[:, i] * arm[:, i], axis=1)
    S = np.array([system.L_ref, system.L_ref, 1.0])
    return H * S[None, :, None] * S[None, None, :] / (system.F_ref * system.L_ref)


def _pinned_coords(system: System, X: NDArray, charts: NDArray, i: int) -> NDArray[np.float64]:
    """Rod ``i``'s coordinates in the unified chart ``(v, phis)`` (seam-chart rods converted)."""
    from ..rod.closed_form import seam_to_chart

    z = np.array(X[:, system.layout.rod[i]][:, :2], dtype=float)
    seam = np.asarray(charts)[:, i] == 1
    if np.any(seam):
        v, ph = seam_to_chart(z[seam, 0], z[seam, 1])
        z[seam, 0], z[seam, 1] = v, ph
    return z


@dataclass(frozen=True)
class StabilityArrays:
    """Stability of ``n`` equilibria (arrays; see :func:`mechanism_stability`)."""

    stable: NDArray[np.bool_]         # (n,)
    index: NDArray[np.int64]          # (n,) number of unstable directions (Morse index)
    margin: NDArray[np.float64]       # (n,) see mechanism_stability
    rod_index: NDArray[np.int64]      # (n, 3) index of each rod with its tip pinned
    hessian: NDArray[np.float64]      # (n, 3, 3) reduced Hessian (dimensionless)


def mechanism_stability(system: System, X: NDArray, charts: NDArray,
                        steps: int = JACOBI_STEPS) -> StabilityArrays:
    """Stability of equilibria of the mechanism with the actuators locked.

    Parameters
    ----------
    system : System
    X : ndarray (n, n_unknowns)
        Refined equilibria (the load enters through the rods' tip forces).
    charts : ndarray (n, 3)
    steps : int
        RK4 steps of the Jacobi fields along each rod.

    Returns
    -------
    StabilityArrays
        ``index`` = sum of the rods' pinned indices + negative eigenvalues of the reduced
        Hessian; ``stable`` iff ``index == 0``.  ``margin`` is the smallest eigenvalue of the
        dimensionless reduced Hessian when every rod is stable with its tip pinned (it
        crosses zero where the platform loses stability, at an FK singularity); when ``k``
        rods buckle on their own it is ``-k``.  So ``margin > 0`` iff stable.
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    n = len(X)
    zrod = np.concatenate([_pinned_coords(system, X, charts, i) for i in range(3)], axis=1)
    cnt = rod_pinned_index(zrod[:, 0::2].ravel(), zrod[:, 1::2].ravel(), steps).reshape(n, 3)
    H = reduced_hessian(system, X, charts)
    H = 0.5 * (H + np.swapaxes(H, 1, 2))
    finite = np.all(np.isfinite(H), axis=(1, 2))
    ev = np.full((n, 3), -np.inf)
    if np.any(finite):
        ev[finite] = np.linalg.eigvalsh(H[finite])
    index = cnt.sum(1) + np.sum(ev < 0.0, axis=1)
    rods_ok = cnt.sum(1) == 0
    margin = np.where(rods_ok, ev[:, 0], -cnt.sum(1).astype(float))
    margin = np.where(np.isfinite(margin), margin, -1.0)
    return StabilityArrays(index == 0, index.astype(np.int64), margin, cnt, H)


# ---- a single rod: the classical cases -----------------------------------------------------------


@dataclass(frozen=True)
class RodStability:
    """Stability of one clamped rod under a tip condition (see :func:`rod_stability`).

    Attributes
    ----------
    stable : bool
    index : int
        Number of unstable directions.
    first_conjugate : float or None
        For ``tip="free"``: arc length (m) where the Jacobi field first reaches its first
        focal point (``u' = 0``, forward), ``inf`` if none on (0, L); ``None`` otherwise.
    tip : str
        ``"pinned"``, ``"slider"`` or ``"free"``.
    """

    stable: bool
    index: int
    first_conjugate: float | None
    tip: str


def rod_stability(rod: RodState, tip: str = "pinned", slider_angle: float | None = None,
                  steps: int = JACOBI_STEPS) -> RodStability:
    """Stability of one rod clamped at its base, with its tip force treated as

    * ``"pinned"``: a reaction, the tip held at a fixed point (rotation free);
    * ``"slider"``: a dead load along a line of angle ``slider_angle`` (rad, world frame) on
      which the tip slides, plus the lateral reaction (rotation free);
    * ``"free"``: a dead load on a free tip (the cantilever).

    The rod must be an equilibrium of that problem (zero tip moment, as every
    :class:`RodState` is; for ``"slider"`` and ``"free"`` the tip force must be the dead
    load).  Index of the free problem by Sturm–Pruefer (:func:`free_index`), then the
    constrained ones by the bordered-matrix inertia with the tip compliance.
    """
    if tip not in ("pinned", "slider", "free"):
        raise ValueError(f"tip must be 'pinned', 'slider' or 'free', got {tip!r}")
    if tip == "slider" and slider_angle is None:
        raise ValueError("tip='slider' needs slider_angle (rad)")
    v, ph = np.array([rod.v]), np.array([rod.phis])
    theta = _theta_nodes(v, ph, steps)
    t = tip_chart(rod.v, rod.phis)
    f = np.array([[float(t.fx), float(t.fy)]])
    index = int(free_index(theta, f)[0])
    first: float | None = None
    if tip == "free":
        first = _first_focal(theta[0], f[0]) * rod.length
    else:
        Cp = rod_compliance(v, ph)[0]
        if tip == "slider":
            a = float(slider_angle) - rod.clamp_angle  # local frame
            g = np.array([-np.sin(a), np.cos(a)])
            Cp = np.array([[g @ Cp @ g]])
        index -= int(_neg_count(Cp[None])[0])
    return RodStability(index == 0, index, first, tip)


def _first_focal(theta: NDArray, f: NDArray) -> float:
    """First s where the Pruefer angle of the free Jacobi field reaches pi/2 (inf if never)."""
    ns = theta.shape[0]
    N = (ns - 1) // 2
    best = np.inf
    lo, hi = 0, N
    # bisection on the number of steps: the angle at s is that of the truncated rod
    ang_end = _angle_at(theta, f, N)
    if ang_end <= 0.5 * np.pi:
        return best
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _angle_at(theta, f, mid) > 0.5 * np.pi:
            hi = mid
        else:
            lo = mid
    a0, a1 = _angle_at(theta, f, lo), _angle_at(theta, f, hi)
    return (lo + (0.5 * np.pi - a0) / (a1 - a0)) / N


def _angle_at(theta: NDArray, f: NDArray, k: int) -> float:
    if k == 0:
        return 0.0
    out = np.zeros(1)
    # theta rescaled: the first k steps of the grid, as a rod of "length" k/N (h unchanged)
    sub = np.ascontiguousarray(theta[None, : 2 * k + 1])
    N = (theta.shape[0] - 1) // 2
    _pruefer_kernel_h(sub, np.ascontiguousarray(f[None]), 1.0 / N, out)
    return float(out[0])
