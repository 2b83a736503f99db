"""One equilibrium of one rod, placed in the world frame."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d import rotate
from .closed_form import mode_of, pinned_chart, standard_chart, to_paper
from .kernels import CHART_SEAM, CHART_UNIFIED, CHART_WRENCH, EN, FX, FY, M0, ML, NQ, TH, X, Y, eval_rods, profile_batch
from .wrench_atlas import winding

__all__ = ["RodState", "profiles", "centre_lines"]

#: kept for callers of the former helper; the one rotation is :func:`flexkin.core.geometry2d.rot2`


def _unified(chart: int, z0: float, z1: float) -> tuple[float, float]:
    """The solvers' chart ``(v, phis)`` of a pinned rod stored in ``chart``: pairs in the seam
    chart are converted whether raw (``(psi_s, chi)``, the continuation's unknowns) or
    offset-encoded (:func:`~flexkin.rod.closed_form.standard_chart`)."""
    v, ph = pinned_chart([z0, z1], [chart])
    return float(v[0]), float(ph[0])


@dataclass(frozen=True)
class RodState:
    """An equilibrium of one rod (clamped at its base; pinned or clamped at its tip).

    Attributes
    ----------
    mode : int
        d-mode q: the number of inflection points on (0, L] (SPEC §2).  A pinned tip counts,
        so a pinned rod's q is 1 + the sign changes of the bending moment strictly inside; a
        clamped tip does not, so a clamped rod's q is those sign changes alone (a C-shaped rod
        0, the buckled clamped-clamped arch 2).
    k, psi : float
        Paper parameters (Eqs. 9-13): ``k`` signed like the base moment (``|k| > 1`` for the
        non-inflectional rods a clamped tip allows), ``psi`` (rad) the direction of the tip
        force in the rod's local (clamp) frame.
    length, EI : float
        Free length (m) and bending stiffness (N m^2).
    clamp : tuple of 2 floats
        Clamp point, world frame (m).
    clamp_angle : float
        Tangent angle at the clamp, world frame (rad).
    tip : tuple of 2 floats
        Tip position, world frame (m).
    tip_angle : float
        Tangent angle at the tip, world frame (rad).
    tip_force : tuple of 2 floats
        Force applied on the rod tip by the platform, world frame (N).
    base_moment : float
        ``EI theta'(0)`` (N m), counter-clockwise positive.
    energy : float
        Bending energy (J).
    tip_moment : float
        ``EI theta'(L)``, the moment on the rod tip by the platform (N m; 0 if pinned).
    chart : int
        The chart the rod is known in (:mod:`flexkin.rod.kernels`: unified, seam or wrench).
    coords : tuple of float
        The rod's coordinates in that chart (2 for a pinned rod, 3 for the wrench chart;
        dimensionless, unit rod).
    joint : {"pinned", "clamped"}
        How the tip is joined to the platform.
    mode_boundary : bool
        The base moment vanishes to within the solver's resolution (an inflection at the
        clamp): the rod sits on the boundary between d-modes ``mode`` and ``mode + 1`` and
        carries the lower label (SPEC §2).
    extra : dict
        Free-form annotations a caller may attach; empty by default.  flexkin itself neither
        fills nor reads it, it takes no part in comparisons and is not written by
        :meth:`to_dict`.
    """

    mode: int
    k: float
    psi: float
    length: float
    EI: float
    clamp: tuple[float, float]
    clamp_angle: float
    tip: tuple[float, float]
    tip_angle: float
    tip_force: tuple[float, float]
    base_moment: float
    energy: float
    tip_moment: float = 0.0
    chart: int = CHART_UNIFIED
    coords: tuple[float, ...] = ()
    joint: str = "pinned"
    mode_boundary: bool = False
    extra: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    # ---- construction ------------------------------------------------------------------
    @classmethod
    def from_unit(cls, q: NDArray, chart: int, coords: NDArray, length: float, EI: float,
                  clamp: NDArray | tuple[float, float], clamp_angle: float, mode: int,
                  joint: str = "pinned", mode_boundary: bool = False) -> "RodState":
        """Place a unit rod's tip quantities ``q`` (NQ,) at a clamp, scaled to ``length``, ``EI``."""
        c = np.zeros(3)
        c[:len(coords)] = coords
        return cls.many(np.asarray(q)[None], np.array([chart]), c[None], np.array([length]), np.array([EI]),
                        np.asarray(clamp, dtype=float)[None], np.array([clamp_angle]), np.array([mode]),
                        (joint,), np.array([mode_boundary]), dims=(len(coords),))[0]

    @classmethod
    def many(cls, q: NDArray, charts: NDArray, coords: NDArray, length: NDArray, EI: NDArray, clamp: NDArray,
             clamp_angle: NDArray, modes: NDArray, joints, boundary: NDArray, dims=None) -> list["RodState"]:
        """:meth:`from_unit` for ``n`` rods at once (arrays with a leading ``n``; ``coords`` (n, 3)
        zero-padded, ``dims`` the number of chart coordinates of each, default from the chart)."""
        q = np.asarray(q, dtype=float)
        charts = np.asarray(charts, dtype=np.int64)
        c = np.asarray(clamp, dtype=float)
        al = np.asarray(clamp_angle, dtype=float)
        L = np.asarray(length, dtype=float)
        EI = np.asarray(EI, dtype=float)
        tip = c + L[:, None] * rotate(q[:, [X, Y]], al)
        f = (EI / L**2)[:, None] * rotate(q[:, [FX, FY]], al)
        R = np.hypot(q[:, FX], q[:, FY])
        psi = np.where(R > 0, np.mod(np.arctan2(q[:, FY], q[:, FX]), 2.0 * np.pi), np.pi)
        lam = np.sqrt(R)
        m0 = q[:, M0]
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.where(lam > 0, np.copysign(np.hypot(np.cos(0.5 * psi), m0 / (2.0 * lam)), np.where(m0 != 0, m0, 1.0)),
                         np.where(m0 != 0, np.copysign(np.inf, m0), 0.0))
        pinned = (charts == CHART_UNIFIED) | (charts == CHART_SEAM)
        if np.any(pinned):
            v, ph = pinned_chart(coords[pinned, :2], charts[pinned])
            k[pinned] = to_paper(np.tanh(v), ph)[0]
        if dims is None:
            dims = np.where(charts >= CHART_WRENCH, 3, 2)
        sc = EI / L
        return [cls(mode=int(modes[r]), k=float(k[r]), psi=float(psi[r]), length=float(L[r]), EI=float(EI[r]),
                    clamp=(float(c[r, 0]), float(c[r, 1])), clamp_angle=float(al[r]),
                    tip=(float(tip[r, 0]), float(tip[r, 1])), tip_angle=float(al[r] + q[r, TH]),
                    tip_force=(float(f[r, 0]), float(f[r, 1])), base_moment=float(sc[r] * m0[r]),
                    energy=float(sc[r] * q[r, EN]), tip_moment=float(sc[r] * q[r, ML]), chart=int(charts[r]),
                    coords=tuple(float(a) for a in coords[r, :int(dims[r])]), joint=joints[r],
                    mode_boundary=bool(boundary[r]))
                for r in range(len(q))]

    @classmethod
    def from_chart(cls, v: float, phis: float, length: float, EI: float,
                   clamp: NDArray[np.float64] | tuple[float, float] = (0.0, 0.0),
                   clamp_angle: float = 0.0) -> "RodState":
        """A pinned rod from its chart coordinates ``(v, phis)`` (``ku = tanh v``; pairs stored in
        the seam chart are converted, see :func:`~flexkin.rod.closed_form.tip_seam`)."""
        v, phis = (float(a) for a in standard_chart(v, phis))
        q = np.empty((1, NQ))
        g = np.empty((1, NQ, 3))
        eval_rods(np.array([CHART_UNIFIED]), np.array([[v, phis, 0.0]]), q, g)
        return cls.from_unit(q[0], CHART_UNIFIED, np.array([v, phis]), length, EI, clamp, clamp_angle,
                             int(mode_of(phis)))

    # ---- the unified chart's coordinates (pinned rods) -------------------------------------
    @property
    def v(self) -> float:
        """Solvers' chart variable ``v`` (``ku = tanh v``) of a pinned rod (NaN otherwise)."""
        if self.chart >= CHART_WRENCH:
            return float("nan")
        return _unified(self.chart, self.coords[0], self.coords[1])[0]

    @property
    def phis(self) -> float:
        """Unified clamp amplitude of a pinned rod (NaN otherwise)."""
        if self.chart >= CHART_WRENCH:
            return float("nan")
        return _unified(self.chart, self.coords[0], self.coords[1])[1]

    @property
    def ku(self) -> float:
        """Unified modulus ``tanh v`` of a pinned rod (NaN otherwise)."""
        return float(np.tanh(self.v))

    @property
    def winding(self) -> int | None:
        """Winding ``w`` of a rod clamped to the platform (SPEC §2): its total turning
        ``theta(L) - theta(0) = delta + 2 pi w`` with ``delta`` in ``(-pi, pi]``; ``None`` for a
        pinned tip."""
        if self.joint != "clamped":
            return None
        return int(winding(self.tip_angle - self.clamp_angle))

    @property
    def R(self) -> float:
        """Tip force magnitude (N)."""
        return float(np.hypot(*self.tip_force))

    # ---- shape -----------------------------------------------------------------------------
    def profile(self, n: int = 101) -> dict[str, NDArray[np.float64]]:
        """The rod sampled at ``n`` points uniformly in arc length: ``s`` (m), ``x``, ``y``
        (world, m), ``theta`` (rad, world), ``moment`` (N m)."""
        return {k: v[0] for k, v in profiles((self,), n).items()}

    def shape(self, n: int = 101) -> NDArray[np.float64]:
        """Deformed centre line in the world frame, shape ``(n, 2)``."""
        return centre_lines((self,), n)[0]

    def curvature(self, n: int = 201) -> NDArray[np.float64]:
        """Curvature ``theta'(s)`` at ``n`` points uniformly spaced in arc length (1/m)."""
        return self.profile(n)["moment"] / self.EI

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (SPEC §4: angles in degrees)."""
        return {
            "mode": self.mode,
            "k": self.k if np.isfinite(self.k) else None,
            "psi_deg": float(np.degrees(self.psi)),
            "tip_force": [self.tip_force[0], self.tip_force[1]],
            "base_moment": self.base_moment,
            "tip_moment": self.tip_moment,
            "energy": self.energy,
            "mode_boundary": self.mode_boundary,
            **({"winding": self.winding} if self.joint == "clamped" else {}),
        }


# ---------------------------------------------------------------------------------------------
def _unit_profiles(rods: Sequence[RodState], s: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(x, y, theta, m)`` of each rod's unit rod (local frame) at arc lengths ``s``: (m, n, 4)."""
    m = len(rods)
    out = np.empty((m, s.size, 4))
    if m == 0:
        return out
    ch = np.array([r.chart for r in rods], dtype=np.int64)
    z = np.zeros((m, 3))
    for i, r in enumerate(rods):
        z[i, :len(r.coords)] = r.coords
    seam = ch == CHART_SEAM
    if np.any(seam):  # profiles are evaluated in the unified chart (see _unified)
        z[seam, 0], z[seam, 1] = pinned_chart(z[seam, :2], ch[seam])
        ch[seam] = CHART_UNIFIED
    profile_batch(ch, z, s, out)
    return out


def profiles(rods: Sequence[RodState], n: int = 101) -> dict[str, NDArray[np.float64]]:
    """:meth:`RodState.profile` of many rods at once: ``s``, ``x``, ``y``, ``theta``, ``moment``,
    each of shape ``(len(rods), n)`` (the charts and placements batched, one compiled profile
    per rod).

    Parameters
    ----------
    rods : sequence of RodState
        The rods.
    n : int, optional
        Points per rod, uniform in arc length.

    Returns
    -------
    dict of ndarray
    """
    s = np.linspace(0.0, 1.0, n)
    u = _unit_profiles(rods, s)
    L = np.array([r.length for r in rods], dtype=float).reshape(-1, 1)
    a = np.array([r.clamp_angle for r in rods], dtype=float).reshape(-1, 1)
    c = np.array([r.clamp for r in rods], dtype=float).reshape(-1, 2)
    EI = np.array([r.EI for r in rods], dtype=float).reshape(-1, 1)
    r = rotate(u[..., :2], a)  # the unit rod turned by the clamp angle
    x = L * r[..., 0] + c[:, :1]
    y = L * r[..., 1] + c[:, 1:]
    return {"s": s[None, :] * L, "x": x, "y": y, "theta": u[..., 2] + a, "moment": u[..., 3] * EI / L}


def centre_lines(rods: Sequence[RodState], n: int = 101) -> NDArray[np.float64]:
    """:meth:`RodState.shape` of many rods at once: ``(len(rods), n, 2)`` (world, m).

    Parameters
    ----------
    rods : sequence of RodState
        The rods.
    n : int, optional
        Points per rod, uniform in arc length.

    Returns
    -------
    ndarray
    """
    p = profiles(rods, n)
    return np.stack([p["x"], p["y"]], -1)
