"""One planar Cosserat rod (paper Eqs. 1–7 with extension, shear and a distributed load): shooting.

A rod is clamped at ``clamp`` with material angle ``clamp_angle`` (``th(0)``).  Shooting starts
from the clamp with the unknowns ``(n_x(0), n_y(0), m(0))`` — the force and moment exerted by
the rod ``(0, L]`` on its clamp end, i.e. the internal force and moment at ``s = 0`` in the
convention of SPEC §2 — and integrates

    x' = v_x cos th - v_y sin th,   y' = v_x sin th + v_y cos th,   th' = m / EI,
    v_x = 1 + tau (n_x cos th + n_y sin th) / EA,   v_y = tau (-n_x sin th + n_y cos th) / (kappa G A),
    n' = -tau f,   m' = -(x' n_y - y' n_x),

to the tip, where ``n(L)`` is the force ON the rod tip BY the platform and ``m(L)`` the
moment on the tip by the platform.  ``tau`` in [0, 1] multiplies the compliances and the
distributed load; ``tau = 0`` is exactly the Kirchhoff rod (paper Eq. 5).

Integration: fixed-step 8th-order Dormand–Prince Runge–Kutta, compiled with numba, together
with the variational equations, so the Jacobians of the tip state w.r.t. the clamp state
(position, angle, force, moment), the length and tau are analytic (exact derivatives of the
discrete map).  The step count (:func:`auto_steps`) bounds the global error of the tip state
by about ``tol`` (relative to L, default 1e-12); measured error ``~ 1e-6 (S/n)^8`` for
``n`` steps and the dimensionless scale ``S = L sqrt(kappa_0^2 + 4 R / EI)``.

Energies: ``energy`` is the elastic energy ``int m^2/(2EI) + tau (n_t^2/EA + n_s^2/(kappa G A))/2 ds``
(written with forces, which is the consistent form of ``(EA/2)(v_x-1)^2`` when the
compliance is scaled by tau, and stays regular at tau = 0); ``load_potential`` is
``-tau int f . p ds``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._kernels import shape_batch, shoot_batch

__all__ = ["ShootResult", "RodShape", "auto_steps", "shoot", "rod_shape"]

#: measured constant of the global error model ``err ~ _C_ERR (S / n)^8`` (see module doc)
_C_ERR = 1e-6
_SAFETY = 1.3
MIN_STEPS = 8
MAX_STEPS = 20000


@dataclass(frozen=True)
class ShootResult:
    """Tip state of a batch of rods (leading shape ``batch``), SPEC §2 conventions.

    The properties ``tip``, ``tip_angle``, ``tip_force`` and ``tip_moment`` are views of
    ``state``.

    Attributes
    ----------
    state : ndarray (..., 6)
        ``(x, y, th, n_x, n_y, m)`` at ``s = L``: tip position (m, world), material angle
        (rad), force on the tip by the platform (N, world) and moment on the tip (N m).
    energy : ndarray (...)
        Elastic energy of the rod (J; module docstring).
    load_potential : ndarray (...)
        Potential of the distributed load ``-tau int f . p ds`` (J).
    elongation : ndarray (...)
        ``int (v_x - 1) ds`` (m).
    d_start : ndarray (..., 6, 6) or None
        ``d state(L) / d state(0)``, columns ``(x0, y0, th0, n_x0, n_y0, m0)`` (in the SI
        units of the rows over those of the columns; ``None`` without ``jacobian=True``).
    d_length : ndarray (..., 6) or None
        ``d state(L) / d L`` (per m; ``None`` without ``jacobian=True``).
    d_tau : ndarray (..., 6) or None
        ``d state(L) / d tau`` (tau dimensionless; ``None`` without ``jacobian=True``).
    steps : ndarray (...) of int
        Runge–Kutta steps used.
    """

    state: NDArray[np.float64]
    energy: NDArray[np.float64]
    load_potential: NDArray[np.float64]
    elongation: NDArray[np.float64]
    d_start: NDArray[np.float64] | None
    d_length: NDArray[np.float64] | None
    d_tau: NDArray[np.float64] | None
    steps: NDArray[np.int64]

    @property
    def tip(self) -> NDArray[np.float64]:
        return self.state[..., 0:2]

    @property
    def tip_angle(self) -> NDArray[np.float64]:
        return self.state[..., 2]

    @property
    def tip_force(self) -> NDArray[np.float64]:
        return self.state[..., 3:5]

    @property
    def tip_moment(self) -> NDArray[np.float64]:
        return self.state[..., 5]


@dataclass(frozen=True)
class RodShape:
    """A rod sampled at ``n`` points uniformly spaced in the reference arc length.

    Every array has the batch's leading shape ``...`` (none for one rod), then ``n``.

    Attributes
    ----------
    s : ndarray (..., n)
        Reference (undeformed) arc length of the samples, from the clamp (m).
    points : ndarray (..., n, 2)
        Centre line, world frame (m).
    theta : ndarray (..., n)
        Material angle th: direction of the cross-section's axis d1 (the tangent when the rod
        is unsheared), world frame (rad).
    force : ndarray (..., n, 2)
        Internal force n(s), world frame (N): the force the part (s, L] exerts on [0, s].
    moment : ndarray (..., n)
        Internal (bending) moment m(s) (N m), counter-clockwise positive.
    axial_strain, shear_strain : ndarray (..., n)
        ``v_x - 1`` and ``v_y`` (dimensionless).
    energy : ndarray (..., n)
        Elastic energy from the clamp to ``s`` (J).
    load_potential : ndarray (..., n)
        Potential of the distributed load from the clamp to ``s`` (J).
    elongation : ndarray (..., n)
        ``int_0^s (v_x - 1) ds`` (m).
    """

    s: NDArray[np.float64]
    points: NDArray[np.float64]
    theta: NDArray[np.float64]
    force: NDArray[np.float64]
    moment: NDArray[np.float64]
    axial_strain: NDArray[np.float64]
    shear_strain: NDArray[np.float64]
    energy: NDArray[np.float64]
    load_potential: NDArray[np.float64]
    elongation: NDArray[np.float64]


# --------------------------------------------------------------------------------------
def auto_steps(length: ArrayLike, EI: ArrayLike, base_force: ArrayLike, base_moment: ArrayLike,
               line_load: ArrayLike = (0.0, 0.0), tol: float = 1e-12) -> NDArray[np.int64]:
    """Runge–Kutta step count for a global tip error of about ``tol * L``.

    Uses the scale ``S = L sqrt(kappa_0^2 + 4 R_max / EI)`` (``kappa_0 = |m0|/EI``,
    ``R_max = |n0| + |f| L``), which bounds the curvature of an elastica, and the measured
    error model ``1e-6 (S/n)^8`` of the 8th-order scheme, with a safety factor 1.3.

    Parameters
    ----------
    length, EI : array_like
        Free length (m) and bending stiffness (N m^2).
    base_force : (..., 2) array_like
        Internal force at the clamp (N).
    base_moment : array_like
        Moment at the clamp (N m).
    line_load : (..., 2) array_like
        Distributed load (N/m).
    tol : float
        Relative target error of the tip (> 0).

    Returns
    -------
    ndarray of int
        Step counts, clipped to ``[MIN_STEPS, MAX_STEPS]``.
    """
    if not tol > 0.0:
        raise ValueError(f"tol: must be > 0, got {tol!r}")
    L = np.asarray(length, dtype=float)
    EI = np.asarray(EI, dtype=float)
    n0 = np.asarray(base_force, dtype=float)
    f = np.asarray(line_load, dtype=float)
    R = np.hypot(n0[..., 0], n0[..., 1]) + np.hypot(f[..., 0], f[..., 1]) * L
    k0 = np.abs(np.asarray(base_moment, dtype=float)) / EI
    S = L * np.sqrt(k0 ** 2 + 4.0 * R / EI)
    n = np.ceil(_SAFETY * S * (_C_ERR / tol) ** 0.125)
    n = np.where(np.isfinite(n), n, MAX_STEPS)
    return np.clip(n, MIN_STEPS, MAX_STEPS).astype(np.int64)


def _pack(clamp, clamp_angle, length, EI, base_force, base_moment, axial_compliance, shear_compliance,
          line_load, tau, allow_negative_length=False):
    clamp = np.asarray(clamp, dtype=float)
    n0 = np.asarray(base_force, dtype=float)
    f = np.asarray(line_load, dtype=float)
    if clamp.shape[-1:] != (2,) or n0.shape[-1:] != (2,) or f.shape[-1:] != (2,):
        raise ValueError("clamp, base_force and line_load must have a last axis of length 2")
    scal = [np.asarray(a, dtype=float) for a in (clamp_angle, length, EI, base_moment, axial_compliance,
                                                   shear_compliance, tau)]
    shape = np.broadcast_shapes(clamp.shape[:-1], n0.shape[:-1], f.shape[:-1], *(a.shape for a in scal))
    alpha, L, EIa, m0, ce, cs, tau = (np.broadcast_to(a, shape).reshape(-1) for a in scal)
    A = np.broadcast_to(clamp, shape + (2,)).reshape(-1, 2)
    n0 = np.broadcast_to(n0, shape + (2,)).reshape(-1, 2)
    f = np.broadcast_to(f, shape + (2,)).reshape(-1, 2)
    for name, a in (("clamp", A), ("clamp_angle", alpha), ("base_force", n0), ("base_moment", m0),
                    ("line_load", f), ("tau", tau)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: must be finite")
    if not np.all(((L > 0) | (allow_negative_length & (L != 0))) & np.isfinite(L)):
        raise ValueError("length: must be finite and > 0")
    if not np.all((EIa > 0) & np.isfinite(EIa)):
        raise ValueError("EI: must be finite and > 0")
    if not np.all((ce >= 0) & np.isfinite(ce) & (cs >= 0) & np.isfinite(cs)):
        raise ValueError("axial_compliance / shear_compliance: must be finite and >= 0")
    y0 = np.ascontiguousarray(np.column_stack([A, alpha, n0, m0]))
    par = np.ascontiguousarray(np.column_stack([L, EIa, ce, cs, f, tau]))
    return shape, y0, par


def shoot(clamp: ArrayLike, clamp_angle: ArrayLike, length: ArrayLike, EI: ArrayLike,
          base_force: ArrayLike, base_moment: ArrayLike, *, axial_compliance: ArrayLike = 0.0,
          shear_compliance: ArrayLike = 0.0, line_load: ArrayLike = (0.0, 0.0), tau: ArrayLike = 1.0,
          steps: ArrayLike | None = None, tol: float = 1e-12, jacobian: bool = True,
          _allow_negative_length: bool = False) -> ShootResult:
    """Integrate a batch of rods from their clamps to their tips.

    Parameters
    ----------
    clamp : (..., 2) array_like
        Clamp point (m).
    clamp_angle : (...) array_like
        Material angle th(0) (rad).
    length : (...) array_like
        Free length L (m).
    EI : (...) array_like
        Bending stiffness (N m^2).
    base_force : (..., 2) array_like
        Internal force n(0) (N, world).
    base_moment : (...) array_like
        m(0) = EI th'(0) (N m).
    axial_compliance, shear_compliance : (...) array_like
        ``1/EA`` and ``1/(kappa G A)`` (1/N); 0 = rigid.
    line_load : (..., 2) array_like
        Distributed force per unit length f (N/m, world frame, dead load).
    tau : (...) array_like
        Homotopy parameter multiplying the compliances and ``line_load``.
    steps : (...) int, optional
        Runge–Kutta steps (default :func:`auto_steps` with ``tol``).
    tol : float
        Target error of the automatic step count.
    jacobian : bool
        Also integrate the variational equations.

    Returns
    -------
    ShootResult
        Arrays with the broadcast leading shape of the inputs.
    """
    shape, y0, par = _pack(clamp, clamp_angle, length, EI, base_force, base_moment, axial_compliance,
                           shear_compliance, line_load, tau, _allow_negative_length)
    if steps is None:
        ns = auto_steps(par[:, 0], par[:, 1], y0[:, 3:5], y0[:, 5], par[:, 4:6], tol)
    else:
        ns = np.broadcast_to(np.asarray(steps, dtype=np.int64), shape).reshape(-1)
        if np.any(ns < 1):
            raise ValueError("steps: must be >= 1")
    ns = np.ascontiguousarray(ns, dtype=np.int64)
    yL, W, Q = shoot_batch(y0, par, ns, bool(jacobian))
    d_start = d_length = d_tau = None
    if jacobian:
        d_start = np.zeros((yL.shape[0], 6, 6))
        d_start[:, 0, 0] = 1.0
        d_start[:, 1, 1] = 1.0
        d_start[:, :, 2:6] = W[:, :, 0:4]
        d_start = d_start.reshape(shape + (6, 6))
        d_length = W[:, :, 4].reshape(shape + (6,))
        d_tau = W[:, :, 5].reshape(shape + (6,))
    return ShootResult(state=yL.reshape(shape + (6,)), energy=Q[:, 0].reshape(shape),
                       load_potential=Q[:, 1].reshape(shape), elongation=Q[:, 2].reshape(shape),
                       d_start=d_start, d_length=d_length, d_tau=d_tau, steps=ns.reshape(shape))


def rod_shape(clamp: ArrayLike, clamp_angle: ArrayLike, length: ArrayLike, EI: ArrayLike,
              base_force: ArrayLike, base_moment: ArrayLike, *, axial_compliance: ArrayLike = 0.0,
              shear_compliance: ArrayLike = 0.0, line_load: ArrayLike = (0.0, 0.0), tau: ArrayLike = 1.0,
              n_points: int = 101, tol: float = 1e-12) -> RodShape:
    """The rods of :func:`shoot` sampled at ``n_points`` equally spaced reference arc lengths.

    The step count is a multiple of ``n_points - 1`` not below :func:`auto_steps`, the same for
    the whole batch, so the samples are exact Runge–Kutta nodes.

    Parameters
    ----------
    clamp, clamp_angle, length, EI, base_force, base_moment : array_like
        The rods, as in :func:`shoot`.
    axial_compliance, shear_compliance, line_load, tau : array_like
        The Cosserat terms and the homotopy parameter, as in :func:`shoot`.
    n_points : int
        Samples per rod (>= 2).
    tol : float
        Target error of the automatic step count.

    Returns
    -------
    RodShape
        Positions, angles, internal force and moment, strains and energies at the samples.
    """
    if int(n_points) < 2:
        raise ValueError(f"n_points: must be >= 2, got {n_points!r}")
    n_points = int(n_points)
    shape, y0, par = _pack(clamp, clamp_angle, length, EI, base_force, base_moment, axial_compliance,
                           shear_compliance, line_load, tau)
    need = int(np.max(auto_steps(par[:, 0], par[:, 1], y0[:, 3:5], y0[:, 5], par[:, 4:6], tol)))
    stride = max(1, math.ceil(need / (n_points - 1)))
    ns = np.full(y0.shape[0], stride * (n_points - 1), dtype=np.int64)
    out = shape_batch(y0, par, ns, stride)
    L, ce, cs, tau_ = par[:, 0:1], par[:, 2:3], par[:, 3:4], par[:, 6:7]
    th, nx, ny = out[..., 2], out[..., 3], out[..., 4]
    c, s = np.cos(th), np.sin(th)
    nt, nn = nx * c + ny * s, -nx * s + ny * c
    sig = np.linspace(0.0, 1.0, n_points)
    r = lambda a: a.reshape(shape + a.shape[1:])  # noqa: E731
    return RodShape(
        s=r(L * sig), points=r(out[..., 0:2]), theta=r(th), force=r(out[..., 3:5]), moment=r(out[..., 5]),
        axial_strain=r(tau_ * ce * nt), shear_strain=r(tau_ * cs * nn), energy=r(out[..., 6]),
        load_potential=r(out[..., 7]), elongation=r(out[..., 8]),
    )
