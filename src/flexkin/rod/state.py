"""One equilibrium of one rod, placed in the world frame."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .closed_form import HALF_PI, mode_of, rod_shape, standard_chart, tip_any, tip_chart, to_paper

__all__ = ["RodState", "project_chart", "rot"]

#: bound on the chart variable v (ku = tanh v, k' = sech v ~ 2 exp(-|v|))
_V_MAX = 40.0


def rot(angle: float | NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrix (or stack of matrices) for ``angle`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def project_chart(v: NDArray[np.float64], phis: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Map iterates back into the chart ``phis < pi/2`` (``ku = tanh v``).

    A step across ``phis = pi/2`` passes through the unloaded straight rod, where the
    chart is polar (``sqrt(R) ~ pi/2 - phis``, ``psi = 2 arccos(ku)``); it is continued on
    the other side, i.e. with the force reversed: ``phis -> pi - phis`` and ``psi -> psi +/- pi``,
    which is ``a -> a -/+ pi/2`` for the angle ``a = arcsin(ku)`` (the Gudermannian of v).
    """
    v = np.asarray(v, dtype=float).copy()
    phis = np.asarray(phis, dtype=float).copy()
    over = phis > HALF_PI - 1e-12
    if np.any(over):
        phis[over] = np.minimum(np.pi - phis[over], HALF_PI - 1e-12)
        a = np.arctan(np.sinh(np.clip(v[over], -700.0, 700.0)))  # Gudermannian: ku = sin(a)
        a = np.where(a >= 0, a - HALF_PI, a + HALF_PI)
        v[over] = np.arcsinh(np.tan(a))
    np.clip(v, -_V_MAX, _V_MAX, out=v)
    return v, phis


@dataclass(frozen=True)
class RodState:
    """An equilibrium of one clamped–pinned rod.

    Attributes
    ----------
    mode : int
        d-mode q (number of inflection points on (0, L], SPEC §2).
    k, psi : float
        Paper parameters (Eqs. 9–13): ``k`` signed like the base moment, ``psi`` (rad) the
        direction of the tip force in the rod's local (clamp) frame.
    ku, phis : float
        Unified-chart coordinates (see :mod:`flexkin.rod.closed_form`); ``v`` with
        ``ku = tanh v`` is the solvers' variable.
    length, EI : float
        Free length (m) and bending stiffness (N m^2).
    clamp, clamp_angle : clamp point (world, m) and tangent angle (rad).
    tip, tip_angle : tip position (world, m) and tangent angle at the tip (rad).
    tip_force : force applied on the rod tip by the platform, world frame (N).
    base_moment : ``EI theta'(0)`` (N m), counter-clockwise positive.
    energy : bending energy (J).
    """

    mode: int
    k: float
    psi: float
    ku: float
    phis: float
    v: float
    length: float
    EI: float
    clamp: tuple[float, float]
    clamp_angle: float
    tip: tuple[float, float]
    tip_angle: float
    tip_force: tuple[float, float]
    base_moment: float
    energy: float
    extra: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_chart(cls, v: float, phis: float, length: float, EI: float,
                   clamp: NDArray[np.float64] | tuple[float, float] = (0.0, 0.0),
                   clamp_angle: float = 0.0) -> "RodState":
        """Build the state from chart coordinates ``(v, phis)`` (``ku = tanh v``) and the clamp
        (pairs stored in the seam chart are converted, see :func:`~flexkin.rod.closed_form.tip_seam`)."""
        tu = tip_any(v, phis)
        v, phis = (float(a) for a in standard_chart(v, phis))
        ku = float(np.tanh(v))
        t = _Scaled(tu, length, EI)
        k, psi, q = to_paper(ku, phis)
        Rm = rot(clamp_angle)
        c = np.asarray(clamp, dtype=float)
        tip = c + Rm @ np.array([float(t.x), float(t.y)])
        f = Rm @ np.array([float(t.fx), float(t.fy)])
        return cls(
            mode=int(q), k=float(k), psi=float(psi), ku=ku, phis=float(phis), v=float(v),
            length=float(length), EI=float(EI), clamp=(float(c[0]), float(c[1])),
            clamp_angle=float(clamp_angle), tip=(float(tip[0]), float(tip[1])),
            tip_angle=float(clamp_angle + t.theta), tip_force=(float(f[0]), float(f[1])),
            base_moment=float(t.m0), energy=float(t.energy),
        )

    @property
    def R(self) -> float:
        """Tip force magnitude (N)."""
        return float(np.hypot(*self.tip_force))

    def shape(self, n: int = 101) -> NDArray[np.float64]:
        """Deformed centre line in the world frame, shape ``(n, 2)``."""
        _, x, y, _, _ = rod_shape(self.ku, self.phis, self.length, self.EI, n, kprime=1.0 / np.cosh(self.v))
        pts = np.stack([x, y], -1) @ rot(self.clamp_angle).T
        return pts + np.asarray(self.clamp)

    def curvature(self, n: int = 201) -> NDArray[np.float64]:
        """Curvature ``theta'(s)`` at ``n`` points uniformly spaced in arc length (1/m)."""
        _, _, _, _, m = rod_shape(self.ku, self.phis, self.length, self.EI, n, kprime=1.0 / np.cosh(self.v))
        return m / self.EI

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (SPEC §4: angles in degrees)."""
        return {
            "mode": self.mode,
            "k": self.k,
            "psi_deg": float(np.degrees(self.psi)),
            "tip_force": [self.tip_force[0], self.tip_force[1]],
            "base_moment": self.base_moment,
            "energy": self.energy,
        }


class _Scaled:
    """Tip quantities of a unit rod scaled to length ``L`` and stiffness ``EI``."""

    def __init__(self, t, L: float, EI: float) -> None:
        self.x, self.y, self.theta = t.x * L, t.y * L, t.theta
        self.fx, self.fy = t.fx * EI / L**2, t.fy * EI / L**2
        self.m0, self.energy = t.m0 * EI / L, t.energy * EI / L


def _mode_ok(phis: NDArray[np.float64], max_mode: int) -> NDArray[np.bool_]:
    return mode_of(phis) <= max_mode
