"""Independent multi-start shooting oracle for the inverse kinematics of planar PCMs (test-only).

Nothing here calls flexkin's solvers: only the geometry of a :class:`flexkin.Mechanism`
(leg actuation, origin, guide angle, rod length and EI, platform attach points) is read,
and the clamp of each leg is rebuilt from SPEC §2 by hand.  Each rod obeys the first-order
equations of the paper (Eqs. 5 and 7), integrated from its clamp:

    x' = cos th,  y' = sin th,  th' = m/EI,  m' = n_x sin th - n_y cos th

with ``n`` the (constant) internal force = the force ON the rod tip BY the platform.

Unknowns (12): per rod ``(n_x, n_y, m0)`` in the world frame, and the three inputs ``u``.
Equations (12): tip i at ``B_i`` (6), zero tip moment (3), platform equilibrium (3):
``sum n_i = F`` and ``sum (B_i - P) x n_i = M_z`` (the platform receives ``-n_i``).

Method (see :func:`oracle_ik`): two families of starts for a damped batch Newton on the 12
equations, discretised by fixed-step RK4 whose Jacobian comes from the variational equations
integrated alongside (many starts at once, numpy-vectorised):

* random starts, as a textbook multi-start: per rod a dimensionless force ``R L^2/EI``
  log-uniform, uniform direction, base moment inside the first-integral bound
  ``|m0| L/EI <= 2 sqrt(R L^2/EI)``, inputs in a reachable range; each rod is first projected
  (inputs frozen) onto "tip at B_i, zero tip moment";
* "triple" starts: every unit clamped-pinned rod is a point ``(Lambda, t)`` of a tip-anchored
  chart (``Lambda^2`` = dimensionless force, ``v = pi (1 + tanh t)`` = tip angle relative to
  the force; integrated by RK4 from the pinned tip).  A grid scan of that chart, with each
  leg's geometric condition (paper §4.1) evaluated on it, samples every leg's set of reachable
  rods; triples of samples whose wrenches nearly balance the load (linearised along the
  sampled curves) are the starts.  This is the paper's idea, but on an independent chart,
  with an independent integrator, used only to seed the shooting.

Converged candidates are de-duplicated, refined with a finer RK4 and polished with the
residual evaluated by ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-13); the d-mode of each
rod is counted on the tightly integrated moment (1 + sign changes strictly inside the rod).
A solution whose rods have |k| > 1 - 1e-7 (``|k| = |cos((theta_L - psi)/2)|``: near-loops and
taut rods in tension) is flagged ``extreme``.

Also here: :func:`verify_solution` / :func:`verify_many` (re-integration of reported
solutions), :func:`tangents_many` (first-order load sensitivity) and :func:`continue_many`
(predictor-corrector continuation in the load), all on the same independent equations.

Rods CLAMPED to the platform (``getattr(leg, "joint", "pinned") == "clamped"``, tip tangent
``theta_P + getattr(leg, "tip_angle", 0.0)``): the third equation of such a rod is its tip angle
(modulo 2 pi) instead of a zero tip moment, and its tip moment ``m(L)`` (the moment ON the rod
BY the platform) enters the platform's moment balance, ``sum (B_i - P) x n_i + sum m_i(L) =
M_z``.  Mechanisms with a clamped leg are solved by ``leg_curves`` (every leg's solution curve
traced by pseudo-arclength continuation from seeds of the canonical chart of clamped rods in
``clamped_chart``, triples of curve points, Newton along the curves) in the multiple-shooting
form of ``ms_shooting`` (well conditioned for taut rods), plus this module's random starts; every
rod reports ``tip_moment``, ``turning`` = theta(L) - theta(0) and its d-mode (1 + sign changes of
the moment strictly inside the rod); solutions are returned for every clamped rod with
``|turning| <= max_turn`` (default 2 pi max_mode).  The pinned-only path is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

__all__ = [
    "Geom",
    "OracleRod",
    "OracleSolution",
    "continue_many",
    "continue_solution",
    "count_inflections",
    "integrate_rod",
    "match",
    "oracle_ik",
    "oracle_solution_from",
    "tangent_inputs",
    "tangents_many",
    "verify_many",
    "verify_solution",
]

RTOL = 1e-12
ATOL = 1e-13


# ======================================================================================
# geometry (SPEC §2, rebuilt by hand from the mechanism's plain fields)
# ======================================================================================
@dataclass(frozen=True)
class Geom:
    kind: tuple[str, str, str]
    origin: np.ndarray  # (3, 2)
    angle: np.ndarray  # (3,)
    length: np.ndarray  # (3,) NaN for length legs
    EI: np.ndarray  # (3,)
    attach: np.ndarray  # (3, 2)
    L_ref: float
    F_ref: float
    #: platform joint per leg: "pinned" (zero tip moment) or "clamped" (tip tangent theta_P + tip_angle)
    joint: tuple[str, str, str] = ("pinned", "pinned", "pinned")
    #: tip tangent of clamped legs in the platform frame (rad); unused for pinned legs
    tip_angle: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def clamped(self) -> np.ndarray:
        """(3,) bool: which legs are welded to the platform."""
        return np.array([j == "clamped" for j in self.joint])

    @property
    def any_clamped(self) -> bool:
        return bool(np.any(self.clamped))

    @classmethod
    def of(cls, mech) -> Geom:
        """Plain fields only: ``leg.actuation``, ``leg.origin``, ``leg.angle``, ``leg.rod.length``,
        ``leg.rod.EI``, ``getattr(leg, "joint", "pinned")``, ``getattr(leg, "tip_angle", 0.0)`` (rad)
        and ``mech.platform.attach``."""
        joint = tuple(str(getattr(leg, "joint", "pinned") or "pinned") for leg in mech.legs)
        for j in joint:
            if j not in ("pinned", "clamped"):
                raise ValueError(f"unknown platform joint {j!r}")
        tip_angle = np.array([float(getattr(leg, "tip_angle", 0.0) or 0.0) if jt == "clamped" else 0.0
                              for leg, jt in zip(mech.legs, joint)], float)
        kind = tuple(leg.actuation for leg in mech.legs)
        origin = np.array([leg.origin for leg in mech.legs], float)
        angle = np.array([leg.angle for leg in mech.legs], float)
        length = np.array([np.nan if k == "length" else leg.rod.length for k, leg in zip(kind, mech.legs)], float)
        EI = np.array([leg.rod.EI for leg in mech.legs], float)
        attach = np.array(mech.platform.attach, float)
        fixed = length[np.isfinite(length)]
        c = origin.mean(axis=0)
        L_ref = float(np.mean([length[i] if np.isfinite(length[i]) else np.hypot(*(origin[i] - c))
                               for i in range(3)]))
        if fixed.size:
            L_ref = float(np.mean(fixed)) if fixed.size == 3 else L_ref
        return cls(kind, origin, angle, length, EI, attach, L_ref, float(np.mean(EI)) / L_ref**2, joint, tip_angle)

    def u_scale(self) -> np.ndarray:
        return np.array([1.0 if k == "revolute" else self.L_ref for k in self.kind])

    def clamp(self, i: int, u):
        """Clamp point A (..., 2), tangent angle alpha, free length L of leg i for input(s) u."""
        u = np.asarray(u, float)
        e = np.array([np.cos(self.angle[i]), np.sin(self.angle[i])])
        k = self.kind[i]
        if k == "prismatic":
            return self.origin[i] + u[..., None] * e, np.full(u.shape, self.angle[i]), np.full(u.shape, self.length[i])
        if k == "revolute":
            return np.broadcast_to(self.origin[i], u.shape + (2,)).copy(), u.copy(), np.full(u.shape, self.length[i])
        return np.broadcast_to(self.origin[i], u.shape + (2,)).copy(), np.full(u.shape, self.angle[i]), u.copy()

    def platform_points(self, pose) -> np.ndarray:
        x, y, th = (float(v) for v in pose)
        c, s = np.cos(th), np.sin(th)
        b = self.attach
        return np.stack([x + c * b[:, 0] - s * b[:, 1], y + s * b[:, 0] + c * b[:, 1]], -1)


def _wrap(th):
    """Angle(s) wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(th, float)))


# ======================================================================================
# batch RK4 of unit rods with sensitivities to (ax, ay, m0~, th0)
# ======================================================================================
def _rk4_unit(ax, ay, mt, th0, n_steps):
    """Unit rods (L = EI = 1) with dimensionless force (ax, ay), base moment mt, clamp angle th0.

    Returns ``z`` (4, M): tip (x, y, th, m); ``S`` (4 params, 4 states, M); ``changes`` (M,)
    sign changes of the moment at the RK4 nodes strictly inside the rod.
    """
    M = ax.shape[0]
    z = np.zeros((4, M))
    z[2] = th0
    z[3] = mt
    S = np.zeros((4, 4, M))
    S[2, 3] = 1.0  # dm/dmt
    S[3, 2] = 1.0  # dth/dth0
    h = 1.0 / n_steps
    ex = np.zeros((4, M)); ex[0] = 1.0
    ey = np.zeros((4, M)); ey[1] = 1.0

    def f(z, S):
        c, s = np.cos(z[2]), np.sin(z[2])
        dz = np.stack([c, s, z[3], ax * s - ay * c])
        dth = S[:, 2]
        a = ax * c + ay * s
        dS = np.stack([-s * dth, c * dth, S[:, 3], a * dth + ex * s - ey * c], axis=1)
        return dz, dS

    changes = np.zeros(M, np.int64)
    last = np.sign(mt)
    for j in range(n_steps):
        k1, l1 = f(z, S)
        k2, l2 = f(z + 0.5 * h * k1, S + 0.5 * h * l1)
        k3, l3 = f(z + 0.5 * h * k2, S + 0.5 * h * l2)
        k4, l4 = f(z + h * k3, S + h * l3)
        z = z + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        S = S + (h / 6.0) * (l1 + 2 * l2 + 2 * l3 + l4)
        if j < n_steps - 1:
            sg = np.sign(z[3])
            changes += (sg * last < 0)
            last = np.where(sg != 0, sg, last)
    return z, S, changes


# ======================================================================================
# the 12-equation system
# ======================================================================================
class _System:
    """Residual and Jacobian of the 12 equations for a batch of scaled unknowns.

    Scaled unknowns: ``n / F_ref``, ``m0 / (F_ref L_ref)``, ``u / u_scale``.
    Scaled equations: tip error / L_ref, tip condition (pinned: tip moment L/EI; clamped: tip
    angle error ``wrap(theta(L) - theta_P - tip_angle)`` in rad), force error / F_ref, moment error
    / (F_ref L_ref) with the moment ``sum (B_i - P) x n_i + sum_clamped m_i(L)``.
    """

    def __init__(self, g: Geom, pose, load):
        self.g = g
        self.pose = np.asarray(pose, float)
        self.load = np.asarray(load, float)
        self.B = g.platform_points(pose)
        self.arm = self.B - self.pose[:2]
        self.us = g.u_scale()
        self.cl = g.clamped  # (3,) bool
        self.any_cl = bool(np.any(self.cl))
        self.tip_th = float(self.pose[2]) + g.tip_angle  # world tip tangent of clamped legs (mod 2 pi)

    def physical(self, z):
        g = self.g
        n = z[:, 0:9].reshape(-1, 3, 3).copy()
        n[..., :2] *= g.F_ref
        n[..., 2] *= g.F_ref * g.L_ref
        u = z[:, 9:12] * self.us
        return n, u

    def rk4(self, ax, ay, mt, th0, n_steps):
        """Batch RK4 of unit rods: ``n_steps`` steps for all (pinned-only mechanisms, unchanged), or,
        when a leg is clamped, at least ``n_steps`` and more for rods of large force or moment
        (:func:`clamped_chart.steps_for`, numba kernel)."""
        if not self.any_cl:
            return _rk4_unit(ax, ay, mt, th0, n_steps)
        from clamped_chart import rk4_rods, steps_for

        return rk4_rods(ax, ay, mt, th0, steps_for(ax, ay, mt, n_min=n_steps))

    def rod_params(self, z):
        """Per rod arrays: A (N,3,2), alpha, L, ax, ay, mt (N,3)."""
        n, u = self.physical(z)
        N = len(z)
        A = np.empty((N, 3, 2)); al = np.empty((N, 3)); L = np.empty((N, 3))
        for i in range(3):
            A[:, i], al[:, i], L[:, i] = self.g.clamp(i, u[:, i])
        EI = self.g.EI[None]
        ax = n[..., 0] * L**2 / EI
        ay = n[..., 1] * L**2 / EI
        mt = n[..., 2] * L / EI
        return n, u, A, al, L, ax, ay, mt

    def eval(self, z, n_steps=200, jac=True):
        g = self.g
        N = len(z)
        n, _u, A, al, L, ax, ay, mt = self.rod_params(z)
        Z, S, ch = self.rk4(ax.ravel(), ay.ravel(), mt.ravel(), al.ravel(), n_steps)
        Z = Z.reshape(4, N, 3)
        S = S.reshape(4, 4, N, 3)
        ch = ch.reshape(N, 3)
        r = self._assemble(n, A, L, Z[0], Z[1], Z[2], Z[3])
        if not jac:
            return r, ch
        Jm = np.zeros((N, 12, 12))
        EI = g.EI[None]
        # d(out)/d(ax, ay, mt, th0) with out = (x, y, m) of the unit rod (x, y, theta if clamped)
        third = np.where(self.cl[None, None, :], S[:, 2], S[:, 3]) if self.any_cl else S[:, 3]
        d_out = np.stack([S[:, 0], S[:, 1], third], axis=1)  # (4 params, 3 outs, N, 3)
        for i in range(3):
            Li = L[:, i]
            rows = slice(3 * i, 3 * i + 3)
            outscale = np.stack([Li / g.L_ref, Li / g.L_ref, np.ones(N)], 0)  # tip in L_ref, moment as is
            dp_dnx = g.F_ref * Li**2 / EI[0, i]
            dp_dm0 = g.F_ref * g.L_ref * Li / EI[0, i]
            Jm[:, rows, 3 * i + 0] = (d_out[0, :, :, i] * outscale * dp_dnx).T
            Jm[:, rows, 3 * i + 1] = (d_out[1, :, :, i] * outscale * dp_dnx).T
            Jm[:, rows, 3 * i + 2] = (d_out[2, :, :, i] * outscale * dp_dm0).T
            k = g.kind[i]
            us = self.us[i]
            if k == "prismatic":
                e = np.array([np.cos(g.angle[i]), np.sin(g.angle[i])])
                Jm[:, 3 * i, 9 + i] = e[0] * us / g.L_ref
                Jm[:, 3 * i + 1, 9 + i] = e[1] * us / g.L_ref
            elif k == "revolute":
                Jm[:, rows, 9 + i] = (d_out[3, :, :, i] * outscale).T * us
            else:  # length: L = u; tip = A + L X(p(L)); p = (ax, ay, mt) depend on L
                dp = [2 * ax[:, i] / Li, 2 * ay[:, i] / Li, mt[:, i] / Li]
                dX = sum(d_out[j, :, :, i] * dp[j] for j in range(3))  # (3 outs, N)
                col = np.empty((3, N))
                col[0] = (Z[0, :, i] + Li * dX[0]) / g.L_ref
                col[1] = (Z[1, :, i] + Li * dX[1]) / g.L_ref
                col[2] = dX[2]
                Jm[:, rows, 9 + i] = col.T * us
            Jm[:, 9, 3 * i] = 1.0
            Jm[:, 10, 3 * i + 1] = 1.0
            Jm[:, 11, 3 * i] = -self.arm[i, 1] / g.L_ref
            Jm[:, 11, 3 * i + 1] = self.arm[i, 0] / g.L_ref
            if self.cl[i]:
                # the tip moment m(L) = Z3 EI / L enters the moment balance
                cm = EI[0, i] / Li / (g.F_ref * g.L_ref)
                S3 = S[:, 3, :, i]  # d Z3 / d(ax, ay, mt, th0)  (4, N)
                Jm[:, 11, 3 * i] += S3[0] * dp_dnx * cm
                Jm[:, 11, 3 * i + 1] += S3[1] * dp_dnx * cm
                Jm[:, 11, 3 * i + 2] += S3[2] * dp_dm0 * cm
                if k == "revolute":
                    Jm[:, 11, 9 + i] += S3[3] * cm * us
                elif k == "length":
                    dZ3 = S3[0] * dp[0] + S3[1] * dp[1] + S3[2] * dp[2]
                    Jm[:, 11, 9 + i] += (dZ3 * cm - Z[3, :, i] * cm / Li) * us
        return r, Jm, ch

    def _assemble(self, n, A, L, X, Y, TH, M):
        """Residual (N, 12) from the unit rods' tip states X, Y, TH, M (N, 3)."""
        g = self.g
        N = len(n)
        r = np.empty((N, 12))
        tip = A + L[..., None] * np.stack([X, Y], -1)
        rr = np.empty((N, 3, 3))
        rr[..., :2] = (tip - self.B[None]) / g.L_ref
        rr[..., 2] = np.where(self.cl[None], _wrap(TH - self.tip_th[None]), M) if self.any_cl else M
        r[:, 0:9] = rr.reshape(N, 9)
        r[:, 9:11] = (n[..., :2].sum(axis=1) - self.load[:2]) / g.F_ref
        mom = np.sum(self.arm[None, :, 0] * n[..., 1] - self.arm[None, :, 1] * n[..., 0], axis=1)
        if self.any_cl:
            mom = mom + np.sum(np.where(self.cl[None], M * g.EI[None] / L, 0.0), axis=1)
        r[:, 11] = (mom - self.load[2]) / (g.F_ref * g.L_ref)
        return r


def _newton(sys: _System, z, n_iter=40, n_steps=200, tol=1e-10):
    """Damped batch Newton; returns final z, residual inf-norm and RK4 mode estimates."""
    z = z.copy()
    N = len(z)
    active = np.ones(N, bool)
    res = np.full(N, np.inf)
    for _ in range(n_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        r, J, _ = sys.eval(z[idx], n_steps)
        rn = np.max(np.abs(r), axis=1)
        res[idx] = rn
        done = rn < tol
        try:
            step = -np.linalg.solve(J, r[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = np.stack([_safe_solve(Jk, rk) for Jk, rk in zip(J, r)])
        bad = ~np.all(np.isfinite(step), axis=1)
        step[bad] = 0.0
        # damping: relative to the current dimensionless rod forces
        _, _, _, _, L, ax, ay, _mt = sys.rod_params(z[idx])
        Rd = np.hypot(ax, ay)  # (n, 3)
        Fs = sys.g.F_ref * L**2 / sys.g.EI[None]  # scaled-unknown -> dimensionless factor
        dR = np.hypot(step[:, 0:9:3], step[:, 1:9:3]) * Fs
        lim = np.max(dR / (0.5 * Rd + 3.0), axis=1)
        lim = np.maximum(lim, np.max(np.abs(step[:, 9:12]) / 0.3, axis=1))
        step *= (1.0 / np.maximum(lim, 1.0))[:, None]
        upd = ~done & ~bad
        z[idx[upd]] += step[upd]
        blown = np.max(Rd, axis=1) > 5e3
        if np.any([k == "length" for k in sys.g.kind]):
            Lk = z[idx][:, 9:12] * sys.us
            for i, k in enumerate(sys.g.kind):
                if k == "length":
                    blown |= Lk[:, i] <= 1e-3 * sys.g.L_ref
        active[idx[done | bad | blown]] = False
    r, ch = sys.eval(z, n_steps, jac=False)
    return z, np.max(np.abs(r), axis=1), ch + 1


def _safe_solve(J, r):
    try:
        return np.linalg.solve(J, r)
    except np.linalg.LinAlgError:
        return np.full_like(r, np.nan)


# ======================================================================================
# tight integration (solve_ivp DOP853) of one rod, and the d-mode count
# ======================================================================================
@dataclass(frozen=True)
class RodODE:
    tip: np.ndarray
    theta: float
    m_tip: float
    s: np.ndarray
    ms: np.ndarray
    energy: float


def integrate_rod(n, m0, clamp, clamp_angle, L, EI, n_eval=2001, rtol=RTOL, atol=ATOL) -> RodODE:
    """Integrate Eqs. (5)/(7) from the clamp (dimensionless internally); SI in and out."""
    ax, ay = float(n[0]) * L * L / EI, float(n[1]) * L * L / EI

    def f(_s, z):
        c, s = np.cos(z[2]), np.sin(z[2])
        return [c, s, z[3], ax * s - ay * c, 0.5 * z[3] * z[3]]

    t_eval = np.linspace(0.0, 1.0, n_eval)
    sol = solve_ivp(f, (0.0, 1.0), [0.0, 0.0, float(clamp_angle), float(m0) * L / EI, 0.0], method="DOP853",
                    rtol=rtol, atol=atol, t_eval=t_eval)
    y = sol.y
    tip = np.asarray(clamp, float) + L * y[:2, -1]
    return RodODE(tip=tip, theta=float(y[2, -1]), m_tip=float(y[3, -1]) * EI / L, s=sol.t * L,
                  ms=y[3] * EI / L, energy=float(y[4, -1]) * EI / L)


def integrate_batch(ax, ay, mt, th0, n_eval=2, rtol=1e-13, atol=1e-13):
    """Tight DOP853 integration of many unit rods at once (L = EI = 1).

    ``ax, ay`` dimensionless force, ``mt`` dimensionless base moment, ``th0`` clamp angle.
    Returns ``y`` of shape (4, M, n_eval): x, y, theta, m at ``linspace(0, 1, n_eval)``.
    (One error norm for the whole batch: the tolerance is set one decade tighter than the
    per-rod reference to compensate.)
    """
    ax, ay, mt, th0 = (np.asarray(a, float).ravel() for a in (ax, ay, mt, th0))
    M = len(ax)

    def f(_s, z):
        z = z.reshape(4, M)
        c, s = np.cos(z[2]), np.sin(z[2])
        return np.concatenate([c, s, z[3], ax * s - ay * c])

    z0 = np.concatenate([np.zeros(M), np.zeros(M), th0, mt])
    sol = solve_ivp(f, (0.0, 1.0), z0, method="DOP853", rtol=rtol, atol=atol,
                    t_eval=np.linspace(0.0, 1.0, n_eval))
    return sol.y.reshape(4, M, n_eval)


def count_inflections(ms, rel_tol=1e-9) -> int:
    """1 + number of sign changes of the moment strictly inside the rod (samples incl. ends).

    The clamp sample takes part when it is not a zero (``> rel_tol * max|m|``): a base moment
    whose sign differs from the first interior sample's puts a zero strictly inside, however
    close to the clamp (next to a d-mode boundary the first inflection can lie before the first
    interior sample); a vanishing base moment (an inflection at the clamp) does not count.  The
    tip sample never does (the pinned tip always counts, the 1)."""
    ms = np.asarray(ms, float)
    scale = float(np.max(np.abs(ms)))
    if scale == 0.0:
        return 1
    m = ms[:-1]
    sg = np.sign(m[np.abs(m) > rel_tol * scale])
    return 1 + int(np.count_nonzero(sg[1:] != sg[:-1]))


def _mode_ambiguous(ms, rel=1e-6, clamped=False) -> bool:
    """Whether the d-mode of a sampled rod is a boundary case: a zero of the moment at the clamp
    (the rod sits between modes q and q + 1), a nearly vanishing moment slope at the pinned tip
    (for a clamped tip: a nearly vanishing tip moment, an inflection at the tip), or an interior
    near-tangency of the moment to zero (a near-zero sample whose neighbours have the same sign).
    Clean interior zero crossings are not ambiguous."""
    ms = np.asarray(ms, float)
    scale = float(np.max(np.abs(ms)))
    if scale == 0.0:
        return True
    tiny = rel * scale
    if abs(ms[0]) < tiny or abs(ms[-2]) < tiny:
        return True
    if clamped and abs(ms[-1]) < tiny:
        return True
    j = np.flatnonzero(np.abs(ms[1:-2]) < tiny) + 1
    return bool(np.any(np.sign(ms[j - 1]) * np.sign(ms[j + 1]) > 0))


# ======================================================================================
# polish with the tight integrator
# ======================================================================================
def _tight_residual(sys: _System, z):
    """Residual (N, 12) with every rod integrated by DOP853 (batched)."""
    z = np.atleast_2d(z)
    N = len(z)
    n, _u, A, al, L, ax, ay, mt = sys.rod_params(z)
    y = integrate_batch(ax, ay, mt, al)[..., -1].reshape(4, N, 3)
    return sys._assemble(n, A, L, y[0], y[1], y[2], y[3])


def _polish(sys: _System, Z, n_iter=6, tol=1e-11):
    """Quasi-Newton on a batch: residual from DOP853, Jacobian from a fine RK4 (800 steps)."""
    Z = np.atleast_2d(Z).copy()
    best_r = np.full(len(Z), np.inf)
    best_z = Z.copy()
    active = np.ones(len(Z), bool)
    for _ in range(n_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        r = _tight_residual(sys, Z[idx])
        rn = np.max(np.abs(r), axis=1)
        better = rn < best_r[idx]
        best_r[idx[better]] = rn[better]
        best_z[idx[better]] = Z[idx[better]]
        go = rn >= tol
        active[idx[~go]] = False
        idx, r = idx[go], r[go]
        if idx.size == 0:
            break
        _, J, _ = sys.eval(Z[idx], n_steps=800)
        with np.errstate(all="ignore"):
            step = np.stack([_safe_solve(Jk, rk) for Jk, rk in zip(J, r)])
        fin = np.all(np.isfinite(step), axis=1)
        Z[idx[fin]] -= step[fin]
        active[idx[~fin]] = False
    return best_z, best_r


# ======================================================================================
# solutions
# ======================================================================================
@dataclass(frozen=True)
class OracleRod:
    tip_force: np.ndarray  # (2,) on the rod tip, world
    base_moment: float
    clamp: np.ndarray
    clamp_angle: float
    length: float
    EI: float
    mode: int  # 1 + sign changes of the moment strictly inside (0, L) (pinned and clamped tips)
    mode_ambiguous: bool
    k: float  # elastica modulus from the first integral (pinned tip: |cos((theta_L - psi)/2)|; > 1: orbiting)
    R_dimless: float  # R L^2/EI
    tip_moment: float = 0.0  # m(L) = moment ON the rod tip BY the platform (N m); 0 for a pinned tip
    turning: float = float("nan")  # theta(L) - theta(0) (rad), continuous
    tip_angle: float = float("nan")  # theta(L), world, continuous (rad)
    joint: str = "pinned"

    @property
    def extreme(self) -> bool:
        """Near the separatrix (|k| within 1e-7 of 1): the rods flexkin treats as out of scope."""
        return bool(abs(abs(self.k) - 1.0) < 1e-7)


@dataclass(frozen=True)
class OracleSolution:
    inputs: np.ndarray  # SI (rad for revolute)
    rods: tuple[OracleRod, OracleRod, OracleRod]
    residual: float
    z: np.ndarray = field(repr=False)
    pose: np.ndarray | None = None  # the IK pose (x, y, theta) (m, m, rad)

    @property
    def modes(self) -> tuple[int, int, int]:
        return tuple(r.mode for r in self.rods)

    @property
    def mode_label(self) -> str:
        return "".join(str(q) for q in self.modes)

    @property
    def forces(self) -> np.ndarray:
        return np.array([r.tip_force for r in self.rods])

    @property
    def extreme(self) -> bool:
        return any(r.extreme for r in self.rods)

    @property
    def turnings(self) -> tuple[float, float, float]:
        return tuple(r.turning for r in self.rods)

    @property
    def tip_moments(self) -> np.ndarray:
        return np.array([r.tip_moment for r in self.rods])


def _build_many(sys: _System, Z, res) -> list[OracleSolution]:
    """Solutions from polished unknowns: modes counted on a tight, densely sampled integration."""
    Z = np.atleast_2d(Z)
    N = len(Z)
    if N == 0:
        return []
    n, u, A, al, L, ax, ay, mt = sys.rod_params(Z)
    y = integrate_batch(ax, ay, mt, al, n_eval=4001).reshape(4, N, 3, 4001)
    out = []
    for j in range(N):
        rods = []
        for i in range(3):
            ms = y[3, j, i]
            cl = bool(sys.cl[i])
            if cl:
                kk = elastica_k(ax[j, i], ay[j, i], y[2, j, i, -1], y[3, j, i, -1])
            else:
                psi = np.arctan2(n[j, i, 1], n[j, i, 0])
                kk = abs(np.cos(0.5 * (y[2, j, i, -1] - psi)))
            rods.append(OracleRod(tip_force=n[j, i, :2].copy(), base_moment=float(n[j, i, 2]),
                                  clamp=A[j, i].copy(), clamp_angle=float(al[j, i]), length=float(L[j, i]),
                                  EI=float(sys.g.EI[i]), mode=count_inflections(ms),
                                  mode_ambiguous=_mode_ambiguous(ms, clamped=cl), k=float(kk),
                                  R_dimless=float(np.hypot(ax[j, i], ay[j, i])),
                                  tip_moment=float(ms[-1] * sys.g.EI[i] / L[j, i]) if cl else 0.0,
                                  turning=float(y[2, j, i, -1] - al[j, i]), tip_angle=float(y[2, j, i, -1]),
                                  joint=sys.g.joint[i]))
        out.append(OracleSolution(inputs=u[j].copy(), rods=tuple(rods), residual=float(res[j]), z=Z[j].copy(),
                                  pose=sys.pose.copy()))
    return out


def elastica_k(ax, ay, theta, m):
    """Modulus k of a unit rod's elastica from the first integral at any point (theta, m):
    ``m^2/2 + R cos(theta - psi) = C`` and ``k^2 = (C + R) / (2 R) = m^2 / (4 R) + cos^2((theta - psi)/2)``
    (``k < 1``: inflectional; ``k > 1``: non-inflectional, the tangent turns monotonically; inf if
    the force vanishes and m does not)."""
    R = float(np.hypot(ax, ay))
    psi = float(np.arctan2(ay, ax))
    c2 = np.cos(0.5 * (float(theta) - psi)) ** 2
    if R == 0.0:
        return float("inf") if m != 0 else 0.0
    return float(np.sqrt(float(m) ** 2 / (4.0 * R) + c2))


def _key(sys: _System, z):
    """Identity of a solution: scaled forces, base moments and inputs (revolute wrapped)."""
    k = np.array(z, float).copy()
    for i, kind in enumerate(sys.g.kind):
        if kind == "revolute":
            k[..., 9 + i] = np.angle(np.exp(1j * k[..., 9 + i]))
    return k


def _dedupe_rows(keys, tol):
    chosen = []
    for i, kr in enumerate(keys):
        if all(np.max(np.abs(kr - keys[j]) / (1.0 + np.abs(keys[j]))) > tol for j in chosen):
            chosen.append(i)
    return chosen


def _clamped_m0(Rd, rng, max_turn):
    """Dimensionless base moments ``m0 L/EI`` for random starts of clamped rods: half inside the
    first-integral bound ``|m0| <= 2 sqrt(R)`` (inflectional rods), half beyond it up to
    ``2 sqrt(R) + max_turn`` (non-inflectional, "orbiting" rods, whose tangent turns by about
    ``m0`` when the force is small), both signs."""
    n = len(Rd)
    b = 2.0 * np.sqrt(Rd)
    orb = rng.uniform(size=n) < 0.5
    mag = np.where(orb, b + rng.uniform(0.0, 1.0, n) * (max_turn + 1.0), b * rng.uniform(0.0, 1.0, n))
    return np.where(rng.uniform(size=n) < 0.5, -mag, mag)


def _random_starts(sys: _System, n, rng, R_range=(0.05, 300.0), max_turn=4 * np.pi):
    g = sys.g
    z = np.empty((n, 12))
    u = np.empty((n, 3))
    for i in range(3):
        d = sys.B[i] - g.origin[i]
        k = g.kind[i]
        if k == "prismatic":
            e = np.array([np.cos(g.angle[i]), np.sin(g.angle[i])])
            proj = float(d @ e)
            u[:, i] = proj + g.length[i] * rng.uniform(-1.0, 1.0, n)
        elif k == "revolute":
            u[:, i] = rng.uniform(-np.pi, np.pi, n)
        else:
            r = float(np.hypot(*d))
            u[:, i] = r * rng.uniform(1.0, 3.0, n)
    for i in range(3):
        L = u[:, i] if g.kind[i] == "length" else np.full(n, g.length[i])
        Rd = np.exp(rng.uniform(np.log(R_range[0]), np.log(R_range[1]), n))
        ang = rng.uniform(0.0, 2 * np.pi, n)
        m0d = 2.0 * np.sqrt(Rd) * rng.uniform(-1.0, 1.0, n)
        if sys.cl[i]:
            m0d = _clamped_m0(Rd, rng, max_turn)
        R = Rd * g.EI[i] / L**2
        z[:, 3 * i] = R * np.cos(ang) / g.F_ref
        z[:, 3 * i + 1] = R * np.sin(ang) / g.F_ref
        z[:, 3 * i + 2] = m0d * g.EI[i] / L / (g.F_ref * g.L_ref)
    z[:, 9:12] = u / sys.us
    return z


def _phase_a(sys: _System, z, n_iter=15, n_steps=64):
    """Per-rod Newton with the inputs frozen: bring every tip to B_i with zero tip moment.

    Returns the updated scaled unknowns and a mask of starts whose three rods all converged.
    """
    g = sys.g
    N = len(z)
    _n, _u, A, al, L, ax, ay, mt = sys.rod_params(z)
    p = np.stack([ax.ravel(), ay.ravel(), mt.ravel()], 1)
    th0 = al.ravel()
    tgt = ((sys.B[None] - A) / L[..., None]).reshape(-1, 2)
    clm = np.tile(sys.cl, N)  # clamped rod? (flattened like p)
    tth = np.tile(sys.tip_th, N)
    ok = np.zeros(len(p), bool)
    active = np.ones(len(p), bool)
    for it in range(n_iter + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        Z, S, _ = _rk4_unit(p[idx, 0], p[idx, 1], p[idx, 2], th0[idx], n_steps)
        c_ = clm[idx]
        r = np.stack([Z[0] - tgt[idx, 0], Z[1] - tgt[idx, 1], np.where(c_, _wrap(Z[2] - tth[idx]), Z[3])], 1)
        done = np.max(np.abs(r), axis=1) < 1e-8
        ok[idx[done]] = True
        if it == n_iter:
            break
        J = np.stack([S[0:3, 0], S[0:3, 1], np.where(c_[None], S[0:3, 2], S[0:3, 3])], 1)  # (params, outs, M)
        J = np.moveaxis(J, -1, 0).transpose(0, 2, 1)  # (M, outs, params)
        with np.errstate(all="ignore"):
            det = np.linalg.det(J)
            good = np.isfinite(det) & (np.abs(det) > 1e-14)
        step = np.zeros_like(r)
        if np.any(good):
            step[good] = -np.linalg.solve(J[good], r[good][..., None])[..., 0]
        Rd = np.hypot(p[idx, 0], p[idx, 1])
        lim = np.maximum(np.hypot(step[:, 0], step[:, 1]) / (0.5 * Rd + 3.0),
                         np.abs(step[:, 2]) / (0.5 * np.sqrt(Rd) + 1.0 + np.where(c_, 0.25 * np.abs(p[idx, 2]), 0.0)))
        step *= (1.0 / np.maximum(lim, 1.0))[:, None]
        upd = ~done & good
        p[idx[upd]] += step[upd]
        active[idx[done | ~good | (Rd > 3e3)]] = False
    ax, ay, mt = (p[:, j].reshape(N, 3) for j in range(3))
    zz = z.copy()
    EI = g.EI[None]
    zz[:, 0:9:3] = ax * EI / L**2 / g.F_ref
    zz[:, 1:9:3] = ay * EI / L**2 / g.F_ref
    zz[:, 2:9:3] = mt * EI / L / (g.F_ref * g.L_ref)
    return zz, ok.reshape(N, 3).all(axis=1)


def _rk4_backward_plain(Lam, t, n_steps):
    """Unit rods integrated by RK4 from the pinned tip to the clamp (clamp tangent = local x axis).

    With ``phi = theta - psi`` the rod obeys ``phi'' = Lam^2 sin(phi)``, ``phi'(1) = 0`` (zero
    tip moment), ``phi(1) = v = pi (1 + tanh t)`` (``v`` the tip angle relative to the force; the
    tanh stretching gives near-loop and taut rods, ``v -> 0, 2 pi``, room on the chart).
    Integrating in ``sigma = 1 - s`` gives ``phi(0)``, hence ``psi = -phi(0)`` (clamp angle 0),
    the base moment ``phi'(0)`` and the chord.  Returns the tip in the clamp frame (M, 2), psi,
    the dimensionless base moment and the d-mode estimate (1 + sign changes of the moment).
    """
    L2 = Lam * Lam
    phi = np.pi * (1.0 + np.tanh(t))
    w = np.zeros_like(phi)
    X = np.zeros_like(phi)
    Y = np.zeros_like(phi)
    h = 1.0 / n_steps
    changes = np.zeros(phi.shape, np.int64)
    last = np.zeros(phi.shape)
    for j in range(n_steps):
        # z' = (-w, -L2 sin phi, -cos phi, -sin phi)
        s1, c1 = np.sin(phi), np.cos(phi)
        k1p, k1w, k1x, k1y = -w, -L2 * s1, -c1, -s1
        p2 = phi + 0.5 * h * k1p; w2 = w + 0.5 * h * k1w
        s2, c2 = np.sin(p2), np.cos(p2)
        k2p, k2w, k2x, k2y = -w2, -L2 * s2, -c2, -s2
        p3 = phi + 0.5 * h * k2p; w3 = w + 0.5 * h * k2w
        s3, c3 = np.sin(p3), np.cos(p3)
        k3p, k3w, k3x, k3y = -w3, -L2 * s3, -c3, -s3
        p4 = phi + h * k3p; w4 = w + h * k3w
        s4, c4 = np.sin(p4), np.cos(p4)
        k4p, k4w, k4x, k4y = -w4, -L2 * s4, -c4, -s4
        phi = phi + (h / 6.0) * (k1p + 2 * k2p + 2 * k3p + k4p)
        w = w + (h / 6.0) * (k1w + 2 * k2w + 2 * k3w + k4w)
        X = X + (h / 6.0) * (k1x + 2 * k2x + 2 * k3x + k4x)
        Y = Y + (h / 6.0) * (k1y + 2 * k2y + 2 * k3y + k4y)
        if j < n_steps - 1:
            sg = np.sign(w)
            changes += (sg * last < 0)
            last = np.where(sg != 0, sg, last)
    psi = -phi
    c, s = np.cos(psi), np.sin(psi)
    Xc, Yc = -X, -Y
    tip = np.stack([c * Xc - s * Yc, s * Xc + c * Yc], -1)
    return tip, psi, w, 1 + changes


_SCAN_CACHE: dict = {}


def _scan(lam_max: float, n_lam: int = 240, n_t: int = 480, n_steps: int = 64):
    """Every unit clamped-pinned rod on a (Lambda, t) grid (tip-anchored chart, cached)."""
    key = (round(lam_max, 9), n_lam, n_t, n_steps)
    if key not in _SCAN_CACHE:
        lam = np.linspace(1e-3, lam_max, n_lam)
        t = np.linspace(-8.0, 8.0, n_t)
        LL, TT = np.meshgrid(lam, t, indexing="ij")
        tip, psi, w0, mode = _rk4_backward_plain(LL.ravel(), TT.ravel(), n_steps)
        _SCAN_CACHE[key] = (lam, t, tip.reshape(n_lam, n_t, 2), psi.reshape(n_lam, n_t),
                            w0.reshape(n_lam, n_t), mode.reshape(n_lam, n_t))
    return _SCAN_CACHE[key]


def _chart_to_leg(sys: _System, i: int, lam, t, n_steps=96):
    """Unit rods of the tip-anchored chart placed on leg i.

    Returns the leg's geometric-condition value ``C`` (zero on the leg's curve), the input u,
    the world tip force n (M, 2), the base moment m0 and the d-mode estimate (all SI).
    """
    g = sys.g
    tp, ps, w, md = _rk4_backward_plain(lam, t, n_steps)
    X, Y = tp[:, 0], tp[:, 1]
    d = sys.B[i] - g.origin[i]
    k = g.kind[i]
    if k == "prismatic":
        e = np.array([np.cos(g.angle[i]), np.sin(g.angle[i])])
        h = float(-e[1] * d[0] + e[0] * d[1])
        C = Y - h / g.length[i]
        L = np.full(len(lam), g.length[i])
        al = np.full(len(lam), g.angle[i])
        u = float(d @ e) - L * X
    elif k == "revolute":
        C = np.hypot(X, Y) - float(np.hypot(*d)) / g.length[i]
        L = np.full(len(lam), g.length[i])
        u = np.angle(np.exp(1j * (np.arctan2(d[1], d[0]) - np.arctan2(Y, X))))
        al = u
    else:
        beta = np.arctan2(d[1], d[0]) - g.angle[i]
        C = X * np.sin(beta) - Y * np.cos(beta)
        C = np.where(X * np.cos(beta) + Y * np.sin(beta) > 1e-3, C, np.nan)
        L = float(np.hypot(*d)) / np.maximum(np.hypot(X, Y), 1e-12)
        al = np.full(len(lam), g.angle[i])
        u = L
    Rd = lam**2
    n = np.stack([Rd * np.cos(ps + al), Rd * np.sin(ps + al)], 1) * (g.EI[i] / L**2)[:, None]
    m0 = w * g.EI[i] / L
    return C, u, n, m0, md


def _wrench(sys: _System, i: int, n):
    g = sys.g
    return np.column_stack([n[:, 0] / g.F_ref, n[:, 1] / g.F_ref,
                            (sys.arm[i, 0] * n[:, 1] - sys.arm[i, 1] * n[:, 0]) / (g.F_ref * g.L_ref)])


def _leg_samples(sys: _System, i: int, R_range, max_mode, n_lam=160, n_t=320):
    """Points of leg i's geometric-condition set (the rods from the leg's clamp that can be
    pinned at B_i, for some input), sampled by shooting on the tip-anchored chart.

    Every unit rod is ``(Lambda, t)``: ``Lambda^2`` the dimensionless tip force and
    ``v = pi (1 + tanh t)`` the tip angle relative to the force; integrating the pendulum
    ``phi'' = Lambda^2 sin(phi)`` from the pinned tip (zero moment) to the clamp gives the tip in
    the clamp frame.  On a grid of the chart the leg's geometric condition (prismatic: tip height
    above the guide; revolute: chord length; length leg: chord direction, paper §4.1) is evaluated,
    its zero crossings along both grid directions are interpolated and re-integrated, and each
    yields the leg input.  For every sample the wrench change per grid cell along the curve is
    estimated by finite differences (its "spacing").

    Returns a dict of arrays: u, n (M, 2) world tip force, m0, w (M, 3) scaled wrench, sp
    (spacing), cell (M, 2) chart cell indices.
    """
    lam_max = float(np.sqrt(1.35 * R_range[1]))
    lam, t, tip, _psi, _w0, mode = _scan(lam_max, n_lam, n_t)
    dl, dt = lam[1] - lam[0], t[1] - t[0]
    C, *_ = _chart_to_leg_grid(sys, i, tip)
    valid = np.isfinite(C) & (mode <= max_mode)
    Cz = np.where(np.isfinite(C), C, 0.0)
    pts = []
    for ax in (0, 1):
        sl0 = (slice(None, -1), slice(None)) if ax == 0 else (slice(None), slice(None, -1))
        sl1 = (slice(1, None), slice(None)) if ax == 0 else (slice(None), slice(1, None))
        C0, C1 = Cz[sl0], Cz[sl1]
        cross = (np.sign(C0) != np.sign(C1)) & valid[sl0] & valid[sl1]
        ii, jj = np.nonzero(cross)
        s_ = C0[ii, jj] / (C0[ii, jj] - C1[ii, jj])
        if ax == 0:
            pts.append(np.column_stack([lam[ii] + s_ * dl, t[jj]]))
        else:
            pts.append(np.column_stack([lam[ii], t[jj] + s_ * dt]))
    P = np.concatenate(pts)
    keys = ("u", "n", "m0", "w", "sp", "T", "cell")
    if len(P) == 0:
        return {k: np.zeros((0,) + sh) for k, sh in zip(keys, ((), (2,), (), (3,), (), (3,), (2,)))}
    smp = _sample_at(sys, i, P, dl, dt, 1.0, max_mode)
    parts = [smp]
    out = {k: np.concatenate([p_[k] for p_ in parts]) for k in keys}
    _, first = np.unique(np.round(np.column_stack([out["u"] / sys.us[i], out["w"]]), 7), axis=0, return_index=True)
    out = {k: v[np.sort(first)] for k, v in out.items()}
    return out


def _sample_at(sys: _System, i: int, P, dl, dt, step, max_mode):
    """Leg-i samples at chart points P (M, 2) with along-curve tangents for a sample step of
    ``step`` grid cells (scalar or per point)."""
    g = sys.g
    m = len(P)
    step = np.broadcast_to(np.asarray(step, float), (m,)).copy()
    LAM = np.concatenate([P[:, 0], P[:, 0] + 0.25 * step * dl, P[:, 0]])
    TT = np.concatenate([P[:, 1], P[:, 1], P[:, 1] + 0.25 * step * dt])
    Cc, u, n, m0, md = _chart_to_leg(sys, i, LAM, TT)
    W = _wrench(sys, i, n)
    f = 4.0  # finite differences over a quarter step -> change per step
    gC = np.stack([(Cc[m:2 * m] - Cc[:m]) * f, (Cc[2 * m:] - Cc[:m]) * f], 1)
    gW = [(W[m:2 * m] - W[:m]) * f, (W[2 * m:] - W[:m]) * f]
    nrm = np.hypot(gC[:, 0], gC[:, 1]) + 1e-300
    tau = np.stack([-gC[:, 1], gC[:, 0]], 1) / nrm[:, None]  # unit tangent in (step-scaled) cell units
    Tv = gW[0] * tau[:, :1] + gW[1] * tau[:, 1:]
    sp = np.linalg.norm(Tv, axis=1)
    sp = np.where(np.isfinite(sp), sp, 0.0) + 1e-9
    keep = (md[:m] <= max_mode) & np.isfinite(Cc[:m]) & np.all(np.isfinite(Tv), axis=1)
    if g.kind[i] == "length":
        keep &= u[:m] > 0
    sel = np.flatnonzero(keep)
    return {"u": u[:m][sel], "n": n[:m][sel], "m0": m0[:m][sel], "w": W[:m][sel], "sp": sp[sel], "T": Tv[sel],
            "cell": np.column_stack([np.floor(P[sel, 0] / dl), np.floor((P[sel, 1] + 8.0) / dt)]),
            "P": P[sel], "tau": tau[sel], "step": step[sel]}


def _chart_to_leg_grid(sys: _System, i: int, tip):
    """The geometric-condition value on the scan grid (NaN where a length leg's ray is wrong)."""
    g = sys.g
    X, Y = tip[..., 0], tip[..., 1]
    d = sys.B[i] - g.origin[i]
    k = g.kind[i]
    if k == "prismatic":
        e = np.array([np.cos(g.angle[i]), np.sin(g.angle[i])])
        return (Y - float(-e[1] * d[0] + e[0] * d[1]) / g.length[i],)
    if k == "revolute":
        return (np.hypot(X, Y) - float(np.hypot(*d)) / g.length[i],)
    beta = np.arctan2(d[1], d[0]) - g.angle[i]
    C = X * np.sin(beta) - Y * np.cos(beta)
    return (np.where(X * np.cos(beta) + Y * np.sin(beta) > 1e-3, C, np.nan),)


def _triple_starts(sys: _System, samples, max_cands, k_near=4, s_max=1.0, close_frac=0.0, return_s=False):
    """Candidate triples of leg samples nearly in platform equilibrium, one per cluster.

    Each sample carries its scaled wrench ``W`` and the wrench change per chart cell along its
    curve ``T`` (tangent).  For every pair of samples of legs 1 and 2 the wrench leg 3 would need
    is looked up in a KD-tree of leg 3's samples (``k_near`` nearest); the triple is linearised,
    ``sum_i W_i + s_i T_i = load``, and kept when every ``|s_i| <= s_max`` (the solution lies
    within about a cell of the three samples) or the mismatch is below half the summed spacing.
    Candidates whose samples fall in the same coarse chart cells (3 x 3 grid cells per leg) are
    clustered and only the best of each cluster is kept.  Returns index triples (M, 3), best first.
    """
    from scipy.spatial import cKDTree

    g = sys.g
    W = [s_["w"] for s_ in samples]
    Sp = [s_["sp"] for s_ in samples]
    T = [s_["T"] for s_ in samples]
    if any(len(w) == 0 for w in W):
        return np.zeros((0, 3), int)
    target = np.array([sys.load[0] / g.F_ref, sys.load[1] / g.F_ref, sys.load[2] / (g.F_ref * g.L_ref)])
    tree3 = cKDTree(W[2])
    bound = 2.0 * s_max * (np.max(Sp[0]) + np.max(Sp[1]) + np.max(Sp[2]))
    k_near = min(k_near, len(W[2]))
    picks = []
    n1 = len(W[0])
    chunk = max(1, 250000 // max(len(W[1]), 1))
    for a in range(0, n1, chunk):
        j1 = np.arange(a, min(n1, a + chunk))
        J1, J2 = np.meshgrid(j1, np.arange(len(W[1])), indexing="ij")
        J1, J2 = J1.ravel(), J2.ravel()
        need = target - W[0][J1] - W[1][J2]
        d, j3 = tree3.query(need, k=k_near, distance_upper_bound=bound, workers=-1)
        d, j3 = d.reshape(len(J1), -1), j3.reshape(len(J1), -1)
        for c in range(d.shape[1]):
            fin = np.isfinite(d[:, c])
            if not fin.any():
                continue
            A1, A2, A3, dd = J1[fin], J2[fin], j3[fin, c], d[fin, c]
            rhs = need[fin] - W[2][A3]
            c0, c1, c2 = T[0][A1], T[1][A2], T[2][A3]
            det = np.einsum("ij,ij->i", c0, np.cross(c1, c2))
            with np.errstate(divide="ignore", invalid="ignore"):
                s0 = np.einsum("ij,ij->i", rhs, np.cross(c1, c2)) / det
                s1 = np.einsum("ij,ij->i", c0, np.cross(rhs, c2)) / det
                s2 = np.einsum("ij,ij->i", c0, np.cross(c1, rhs)) / det
            sm = np.max(np.abs(np.stack([s0, s1, s2], 1)), axis=1)
            sm = np.where(np.isfinite(sm), sm, np.inf)
            rel = dd / (Sp[0][A1] + Sp[1][A2] + Sp[2][A3])
            score = np.minimum(sm, rel / close_frac) if close_frac > 0 else sm
            sel = score <= s_max
            picks.append(np.column_stack([A1[sel], A2[sel], A3[sel], score[sel], s0[sel], s1[sel], s2[sel]]))
    if not picks:
        return (np.zeros((0, 3), int), np.zeros((0, 3))) if return_s else np.zeros((0, 3), int)
    P = np.concatenate(picks)
    if len(P) > max_cands:
        P = P[np.argpartition(P[:, 3], max_cands)[:max_cands]]
    P = P[np.argsort(P[:, 3], kind="stable")]
    Pi = P[:, :3].astype(int)
    cells = np.column_stack([samples[i]["cell"][Pi[:, i]] // 3 for i in range(3)])
    _, first = np.unique(cells, axis=0, return_index=True)
    first = np.sort(first)
    if return_s:
        return Pi[first], P[first, 4:7]
    return Pi[first]


def _triple_z(sys: _System, samples, P, s=None):
    """Starts from index triples ``P``; with the linear coefficients ``s`` (M, 3) the samples that
    carry their tangent (``dz``: change of (q, u) per sample step, clamped legs) are moved along it."""
    g = sys.g
    z = np.empty((len(P), 12))
    for i in range(3):
        j = P[:, i]
        n, m0, u = samples[i]["n"][j], samples[i]["m0"][j], samples[i]["u"][j]
        z[:, 3 * i] = n[:, 0] / g.F_ref
        z[:, 3 * i + 1] = n[:, 1] / g.F_ref
        z[:, 3 * i + 2] = m0 / (g.F_ref * g.L_ref)
        z[:, 9 + i] = u / sys.us[i]
        if s is not None and "dz" in samples[i]:
            dz = samples[i]["dz"][j] * np.clip(s[:, i], -2.0, 2.0)[:, None]
            z[:, 3 * i:3 * i + 3] += dz[:, :3]
            z[:, 9 + i] += dz[:, 3]
    return z


def oracle_ik(mech, pose, load=None, max_mode=2, n_starts=2000, seed=0, batch=2000, n_steps=64,
              R_range=(0.05, 300.0), return_all=False, extra_starts=None, scan=(240, 480),
              max_triples=6000, s_max=5.0, k_near=2, stats=None, max_turn=None, ms_segments=4):
    """All IK equilibria with every d-mode <= ``max_mode`` found by multi-start shooting.

    Two families of starts for a damped batch Newton on the 12 equations (RK4, ``n_steps``):

    * ``n_starts`` random starts: per rod a dimensionless force ``R L^2/EI`` log-uniform in
      ``R_range``, uniform direction, base moment ``m0 L/EI`` uniform within the first-integral
      bound ``+-2 sqrt(R L^2/EI)``, inputs uniform in a reachable range; each rod is first
      Newton-projected (inputs frozen) onto "tip at B_i, zero tip moment";
    * "triple" starts: each leg's geometric-condition set is sampled by shooting on a
      ``scan`` grid of the tip-anchored chart (:func:`_leg_samples`), and triples of samples
      nearly in platform equilibrium (linearised mismatch within ``s_max`` sample steps, the
      ``k_near`` nearest leg-3 samples per pair, one per cluster; at most ``max_triples``)
      are used as starts.

    Converged candidates are de-duplicated, refined with a fine RK4 (400 steps) and polished
    with DOP853 (rtol 1e-13); the d-mode of each rod is counted on the tight integration.
    Returns a list of :class:`OracleSolution` sorted by (modes, inputs).  ``extra_starts``
    (SI: list of (forces (3, 2), base moments (3,), inputs (3,))) are appended.

    Clamped legs (``leg.joint == "clamped"``, tip tangent ``theta + leg.tip_angle``): the tip
    condition of such a rod is its tip angle (mod 2 pi) instead of a zero tip moment, and its tip
    moment enters the platform's moment balance.  Every configuration is a distinct solution (rods
    whose tangents turn by an extra 2 pi are different states ``(n, m0)``); each rod reports its
    ``tip_moment``, ``turning`` = theta(L) - theta(0) and d-mode (1 + interior sign changes of the
    moment).  A clamped rod may be non-inflectional (tangent turning monotonically, ``k > 1``), so
    its d-mode does not bound its turning: solutions are kept when every clamped rod has
    ``|turning| <= max_turn`` (default ``2 pi max_mode``; all if ``return_all``), and the random
    starts of clamped rods include base moments beyond the inflectional bound, up to
    ``2 sqrt(R L^2/EI) + max_turn`` (:func:`_clamped_m0`).  Instead of the triple starts, such a
    mechanism is solved by tracing every leg's solution curve (``leg_curves.solve_clamped``:
    chart-seeded pseudo-arclength continuation, triples of curve points, Newton along the curves,
    at most ``max_triples`` starts) and every candidate is refined, polished and built in the
    multiple-shooting form of ``ms_shooting`` (``ms_segments`` segments per rod), which stays well
    conditioned for taut rods (nearly straight under high tension, ``|k - 1|`` exponentially small).
    """
    g = Geom.of(mech)
    load = np.asarray(mech.load if load is None else load, float)
    sys = _System(g, pose, load)
    rng = np.random.default_rng(seed)
    max_turn = 2 * np.pi * max_mode if max_turn is None else float(max_turn)
    turn_cap = max_turn + np.pi  # candidates (before polishing) may exceed the bound a little
    parts = []
    info = {}
    if n_starts:
        starts = _random_starts(sys, n_starts, rng, R_range, max_turn)
        starts, ok = _phase_a(sys, starts)
        parts.append(starts[ok])
        info["random_after_projection"] = int(np.count_nonzero(ok))
    if extra_starts:
        parts.append(np.array([to_z(sys, f, m, u) for f, m, u in extra_starts]))
    starts = np.concatenate(parts) if parts else np.zeros((0, 12))
    found = []
    n_conv = 0
    for b0 in range(0, len(starts), batch):
        z, rn, modes = _newton(sys, starts[b0:b0 + batch], n_iter=20, n_steps=n_steps, tol=1e-9)
        ok = (rn < 1e-9) & np.all(modes <= max_mode + 1, axis=1)
        if sys.any_cl and np.any(ok):
            ok[ok] &= _turn_ok(sys, z[ok], turn_cap, n_steps)
        n_conv += int(np.count_nonzero(rn < 1e-9))
        found.extend(z[ok])
    if found:
        F_ = np.array(found)
        found = list(F_[_dedupe_rows(_key(sys, F_), 1e-6)])
    if sys.any_cl:
        from leg_curves import solve_clamped

        info["converged"] = n_conv
        out = solve_clamped(sys, found, R_range, max_mode, max_turn, return_all, max_triples, s_max, k_near, info,
                            K=ms_segments)
        info["unique"] = len(out)
        if stats is not None:
            stats.update(info)
        return out
    if max_triples:
        samples = [_leg_samples(sys, i, R_range, max_mode, *scan) for i in range(3)]
        info["leg_samples"] = [len(s_["u"]) for s_ in samples]
        P = _triple_starts(sys, samples, 400000, k_near=k_near, s_max=s_max)
        info["triple_clusters"] = len(P)
        P = P[:max_triples]
        for b0 in range(0, len(P), batch):
            z, rn, modes = _newton(sys, _triple_z(sys, samples, P[b0:b0 + batch]), n_iter=15, n_steps=n_steps,
                                   tol=1e-9)
            ok = (rn < 1e-9) & np.all(modes <= max_mode + 1, axis=1)
            n_conv += int(np.count_nonzero(rn < 1e-9))
            found.extend(z[ok])
        info["triples_used"] = len(P)
    Z = np.array(found).reshape(-1, 12)
    info["converged"] = n_conv
    out = []
    if len(Z):
        Z = Z[_dedupe_rows(_key(sys, Z), 1e-6)]
        Z, rn, _ = _newton(sys, Z, n_iter=8, n_steps=400, tol=1e-10)
        Z = Z[rn < 1e-8]
        Z = Z[_dedupe_rows(_key(sys, Z), 1e-6)]
        Zp, rn = _polish(sys, Z)
        good = rn <= 1e-9
        for s in _build_many(sys, Zp[good], rn[good]):
            if return_all or (all(q <= max_mode for q in s.modes)
                              and all(abs(r.turning) <= max_turn for r in s.rods if r.joint == "clamped")):
                out.append(s)
        keys = np.array([_key(sys, s.z) for s in out]).reshape(-1, 12)
        out = [out[i] for i in _dedupe_rows(keys, 1e-7)]
    out.sort(key=lambda s: (s.modes, tuple(np.round(s.inputs, 9))))
    info["unique"] = len(out)
    if stats is not None:
        stats.update(info)
    return out


def _turn_ok(sys: _System, z, cap, n_steps=64):
    """Mask of candidates whose clamped rods all turn by at most ``cap`` (RK4 estimate)."""
    _n, _u, _A, al, _L, ax, ay, mt = sys.rod_params(z)
    Z, _S, _ = _rk4_unit(ax.ravel(), ay.ravel(), mt.ravel(), al.ravel(), n_steps)
    turn = np.abs(Z[2].reshape(-1, 3) - al)
    return np.all(~sys.cl[None] | (turn <= cap), axis=1)


def to_z(sys_or_mech, forces, moments, inputs, pose=None, load=None):
    """Scaled unknown vector from SI forces (3, 2), base moments (3,) and inputs (3,)."""
    sys = sys_or_mech if isinstance(sys_or_mech, _System) else _System(Geom.of(sys_or_mech), pose, load)
    g = sys.g
    z = np.empty(12)
    f = np.asarray(forces, float).reshape(3, 2)
    z[0:9:3] = f[:, 0] / g.F_ref
    z[1:9:3] = f[:, 1] / g.F_ref
    z[2:9:3] = np.asarray(moments, float) / (g.F_ref * g.L_ref)
    z[9:12] = np.asarray(inputs, float) / sys.us
    return z


def by_modes(sols) -> dict[str, int]:
    out: dict[str, int] = {}
    for s in sols:
        out[s.mode_label] = out.get(s.mode_label, 0) + 1
    return dict(sorted(out.items()))


# ======================================================================================
# verification of a reported solution, continuation, tangent predictions
# ======================================================================================
def verify_solution(mech, sol, load=None, pose=None) -> dict:
    """Re-integrate every rod of ``sol`` from its clamp with its reported tip force and base moment.

    ``sol`` needs ``pose``, ``inputs`` and ``rods`` (each with ``tip_force`` and ``base_moment``;
    rods of clamped legs may report ``tip_moment``).  The clamp is rebuilt from the inputs by SPEC
    §2 (not taken from the solution).  Each rod is integrated with solve_ivp (DOP853, rtol = atol =
    1e-13, dimensionless).

    Returns a dict: ``tip_error`` (max distance tip - B_i, m), ``tip_moment`` (max |m(L)| L/EI over
    the PINNED rods, their tip condition; 0 if none), ``tip_angle_error`` (max |theta(L) - theta_P
    - tip_angle| (mod 2 pi, rad) over the CLAMPED rods, their tip condition; 0 if none),
    ``eq_force`` / ``eq_moment`` (equilibrium errors relative to the largest force term |n_i|,
    |F|, resp. the largest moment-term magnitude |B_i - P| |n_i|, |m_i(L)|, |M|; the moment
    balance is ``sum (B_i - P) x n_i + sum_clamped m_i(L) = M_z`` with the reported tip moments, or
    the integrated ones when not reported), ``eq_abs`` (absolute errors scaled by EI/L^2 and EI/L),
    ``modes`` (1 + sign changes of the moment strictly inside each rod), ``mode_ambiguous`` (per
    rod: a zero of the moment at the clamp, at a clamped tip, or a near-tangency, where the count is
    a boundary case), ``clamp_error`` (reported clamp / clamp angle / length vs SPEC §2, when the
    rods report them), per rod ``tip_moments`` (integrated m(L), N m) and ``turnings`` (theta(L) -
    theta(0)), ``tip_moment_error`` (max |reported - integrated tip moment| L/EI over clamped rods
    that report one; 0 if none) and ``midpoint_mismatch``: clamped rods reporting a tip moment are
    also shot from BOTH ends (from the clamp with (n, m0), from the tip at B_i with tangent theta_P +
    tip_angle and the reported tip moment, each over half the rod) and compared at mid-length
    (max of |dx|/L, |dtheta| mod 2 pi, |dm| L/EI / (1 + sqrt(R L^2/EI))): well conditioned also for taut rods, whose
    one-sided residuals are amplified like exp(Lambda) (NaN if no rod qualifies).
    """
    return verify_many(mech, [sol], load, pose)[0]


def verify_many(mech, sols, load=None, pose=None) -> list[dict]:
    """:func:`verify_solution` for many solutions with one batched integration (the batch error
    norm is compensated by the tolerance 1e-13, a decade below the single-rod reference)."""
    g = Geom.of(mech)
    load = np.asarray(mech.load if load is None else load, float)
    sols = list(sols)
    if not sols:
        return []
    N = len(sols)
    cl = g.clamped
    ax, ay, mt, th0 = (np.empty((N, 3)) for _ in range(4))
    A_all, L_all = np.empty((N, 3, 2)), np.empty((N, 3))
    clamp_err = np.zeros(N)
    rep_mL = np.full((N, 3), np.nan)
    for j, sol in enumerate(sols):
        for i, rod in enumerate(sol.rods):
            A, al, L = g.clamp(i, np.asarray(sol.inputs[i], float))
            A, al, L = np.asarray(A, float), float(al), float(L)
            for attr, want in (("clamp", A), ("clamp_angle", al), ("length", L)):
                if hasattr(rod, attr):
                    have = np.asarray(getattr(rod, attr), float)
                    d = float(np.max(np.abs(have - want)))
                    if attr == "clamp_angle":
                        d = abs(float(np.angle(np.exp(1j * (float(have) - want)))))
                    clamp_err[j] = max(clamp_err[j], d)
            n = np.asarray(rod.tip_force, float)
            ax[j, i], ay[j, i] = n[0] * L * L / g.EI[i], n[1] * L * L / g.EI[i]
            mt[j, i] = float(rod.base_moment) * L / g.EI[i]
            th0[j, i] = al
            A_all[j, i], L_all[j, i] = A, L
            if cl[i] and getattr(rod, "tip_moment", None) is not None:
                rep_mL[j, i] = float(rod.tip_moment)
    y = integrate_batch(ax, ay, mt, th0, n_eval=2001).reshape(4, N, 3, 2001)
    mid = _midpoint_mismatch(g, sols, pose, ax, ay, mt, th0, A_all, L_all, rep_mL) if np.any(
        np.isfinite(rep_mL)) else np.full(N, np.nan)
    out = []
    for j, sol in enumerate(sols):
        ps = np.asarray(sol.pose if pose is None else pose, float)
        B = g.platform_points(ps)
        arm = B - ps[:2]
        tip = A_all[j] + L_all[j][:, None] * np.stack([y[0, j, :, -1], y[1, j, :, -1]], -1)
        mL_int = y[3, j, :, -1] * g.EI / L_all[j]  # integrated tip moments (N m)
        F = np.zeros(2)
        Mz = 0.0
        fterms = [float(np.hypot(*load[:2]))]
        mterms = [abs(float(load[2]))]
        for rod, i in zip(sol.rods, range(3)):
            n = np.asarray(rod.tip_force, float)
            F += n
            t = arm[i, 0] * n[1] - arm[i, 1] * n[0]
            Mz += t
            fterms.append(float(np.hypot(*n)))
            mterms.append(float(np.hypot(*arm[i])) * float(np.hypot(*n)))  # |arm| |n| bounds |arm x n|
            if cl[i]:
                m_i = rep_mL[j, i] if np.isfinite(rep_mL[j, i]) else mL_int[i]
                Mz += m_i
                mterms.append(abs(float(m_i)))
        ef = float(np.hypot(*(F - load[:2])))
        em = abs(Mz - load[2])
        tip_m = [abs(y[3, j, i, -1]) for i in range(3) if not cl[i]]
        tip_a = [abs(float(_wrap(y[2, j, i, -1] - ps[2] - g.tip_angle[i]))) for i in range(3) if cl[i]]
        mle = [abs(rep_mL[j, i] - mL_int[i]) * L_all[j, i] / g.EI[i] for i in range(3)
               if cl[i] and np.isfinite(rep_mL[j, i])]
        out.append({
            "tip_error": float(np.max(np.hypot(*(tip - B).T))),
            "tip_moment": float(max(tip_m)) if tip_m else 0.0,
            "tip_angle_error": float(max(tip_a)) if tip_a else 0.0,
            "eq_force": ef / max(max(fterms), 1e-300),
            "eq_moment": em / max(max(mterms), 1e-300),
            "eq_abs": max(ef / g.F_ref, em / (g.F_ref * g.L_ref)),
            "modes": tuple(count_inflections(y[3, j, i]) for i in range(3)),
            "mode_ambiguous": tuple(_mode_ambiguous(y[3, j, i], clamped=bool(cl[i])) for i in range(3)),
            "clamp_error": float(clamp_err[j]),
            "tip_moments": tuple(float(v) for v in mL_int),
            "turnings": tuple(float(y[2, j, i, -1] - th0[j, i]) for i in range(3)),
            "tip_moment_error": float(max(mle)) if mle else 0.0,
            "midpoint_mismatch": float(mid[j]),
        })
    return out


def _midpoint_mismatch(g: Geom, sols, pose, ax, ay, mt, th0, A_all, L_all, rep_mL):
    """Two-sided shooting of the clamped rods that report a tip moment (see :func:`verify_solution`):
    max over those rods of the scaled state mismatch at mid-length (NaN for solutions without one)."""
    N = len(sols)
    jj, ii = np.nonzero(np.isfinite(rep_mL))
    # forward half from the clamp: a unit rod of length L/2 (force scaled by 1/4, moment by 1/2)
    yf = integrate_batch(ax[jj, ii] / 4, ay[jj, ii] / 4, mt[jj, ii] / 2, th0[jj, ii])[..., -1]
    # backward half from the tip: the reversed rod (force -n, tangent + pi, moment -m)
    Bt = np.empty((len(jj), 2))
    tht = np.empty(len(jj))
    for k, (j, i) in enumerate(zip(jj, ii)):
        ps = np.asarray(sols[j].pose if pose is None else pose, float)
        Bt[k] = g.platform_points(ps)[i]
        tht[k] = ps[2] + g.tip_angle[i]
    Lh = L_all[jj, ii]
    mLd = rep_mL[jj, ii] * Lh / g.EI[ii]
    yb = integrate_batch(-ax[jj, ii] / 4, -ay[jj, ii] / 4, -mLd / 2, tht + np.pi)[..., -1]
    pf = A_all[jj, ii] + 0.5 * Lh[:, None] * yf[:2].T
    pb = Bt + 0.5 * Lh[:, None] * yb[:2].T
    dpos = np.hypot(*(pf - pb).T) / Lh
    dth = np.abs(_wrap(yf[2] - (yb[2] - np.pi)))
    # dimensionless m L/EI (unit-half moment x 2), in units of the rod's moment scale 1 + sqrt(R L^2/EI)
    dm = np.abs(yf[3] * 2 - (-yb[3] * 2)) / (1.0 + np.hypot(ax[jj, ii], ay[jj, ii]) ** 0.5)
    mis = np.maximum(np.maximum(dpos, dth), dm)
    out = np.full(N, np.nan)
    for k, j in enumerate(jj):
        out[j] = mis[k] if not np.isfinite(out[j]) else max(out[j], mis[k])
    return out


def solution_z(mech, sol, pose, load):
    """Scaled unknowns of a flexkin-like solution (tip forces, base moments, inputs)."""
    f = np.array([r.tip_force for r in sol.rods], float)
    m = np.array([r.base_moment for r in sol.rods], float)
    return to_z(mech, f, m, np.asarray(sol.inputs, float), pose=pose, load=load)


def tangent_inputs(mech, sol, pose, load, dload):
    """First-order prediction of the change of (forces, moments, inputs) for a load change ``dload``.

    Uses the oracle's own Jacobian (fine RK4 with variational equations) at the solution:
    ``dz = -J^{-1} dr/dload * dload``.  Returns (d_inputs SI (3,), d_forces (3, 2), cond(J)).
    """
    g = Geom.of(mech)
    sys = _System(g, pose, np.asarray(load, float))
    z = solution_z(mech, sol, pose, load)
    _, J, _ = sys.eval(z[None], n_steps=1500)
    rhs = np.zeros(12)
    d = np.asarray(dload, float)
    rhs[9:11] = d[:2] / g.F_ref
    rhs[11] = d[2] / (g.F_ref * g.L_ref)
    dz = np.linalg.solve(J[0], rhs)  # r(z, load) = ... - load: dr/dload = -I on the equilibrium rows
    du = dz[9:12] * sys.us
    df = np.stack([dz[0:9:3], dz[1:9:3]], -1) * g.F_ref
    return du, df, float(np.linalg.cond(J[0]))


def tangents_many(mech, sols, pose, load, dload, n_steps=1000):
    """:func:`tangent_inputs` for many solutions at once: returns (du (N, 3) SI, dforces (N, 3, 2),
    cond(J) (N,))."""
    g = Geom.of(mech)
    sys = _System(g, pose, np.asarray(load, float))
    Z = np.array([solution_z(mech, s_, pose, load) for s_ in sols]).reshape(-1, 12)
    _, J, _ = sys.eval(Z, n_steps=n_steps)
    rhs = np.zeros(12)
    d = np.asarray(dload, float)
    rhs[9:11] = d[:2] / g.F_ref
    rhs[11] = d[2] / (g.F_ref * g.L_ref)
    dz = np.stack([_safe_solve(Jk, rhs) for Jk in J]).reshape(-1, 12)
    du = dz[:, 9:12] * sys.us
    df = np.stack([dz[:, 0:9:3], dz[:, 1:9:3]], -1) * g.F_ref
    conds = np.array([np.linalg.cond(Jk) for Jk in J])
    return du, df, conds


def continue_many(mech, Z, pose, load0, load1, n_sub=2):
    """Predictor-corrector continuation of many solutions (scaled unknowns ``Z``, (N, 12)) from
    ``load0`` to ``load1`` in ``n_sub`` equal load steps (tangent predictor from the oracle's
    Jacobian, Newton corrector, DOP853 polish).  Returns a list with an :class:`OracleSolution`
    or ``None`` (corrector failed) per input."""
    g = Geom.of(mech)
    Z = np.atleast_2d(np.array(Z, float)).copy()
    N = len(Z)
    alive = np.ones(N, bool)
    l0, l1 = np.asarray(load0, float), np.asarray(load1, float)
    for j in range(1, n_sub + 1):
        la = l0 + (l1 - l0) * (j - 1) / n_sub
        lb = l0 + (l1 - l0) * j / n_sub
        idx = np.flatnonzero(alive)
        if idx.size == 0:
            break
        sa = _System(g, pose, la)
        _, J, _ = sa.eval(Z[idx], n_steps=400)
        rhs = np.zeros(12)
        rhs[9:11] = (lb - la)[:2] / g.F_ref
        rhs[11] = (lb - la)[2] / (g.F_ref * g.L_ref)
        dz = np.stack([_safe_solve(Jk, rhs) for Jk in J])
        fin = np.all(np.isfinite(dz), axis=1)
        alive[idx[~fin]] = False
        Z[idx[fin]] += dz[fin]
        idx = np.flatnonzero(alive)
        sb = _System(g, pose, lb)
        zz, rn, _ = _newton(sb, Z[idx], n_iter=20, n_steps=400, tol=1e-10)
        Z[idx] = zz
        alive[idx[rn > 1e-8]] = False
    out: list = [None] * N
    idx = np.flatnonzero(alive)
    if idx.size:
        sb = _System(g, pose, l1)
        zp, rn = _polish(sb, Z[idx])
        good = rn <= 1e-9
        for k, s_ in zip(idx[good], _build_many(sb, zp[good], rn[good])):
            out[k] = s_
    return out


def continue_solution(mech, sol_z, pose, load0, load1, n_sub=1):
    """:func:`continue_many` for one solution."""
    return continue_many(mech, np.asarray(sol_z)[None], pose, load0, load1, n_sub)[0]


def oracle_solution_from(mech, sol, pose, load):
    """Polish a flexkin-like solution on the oracle's own equations (None if that fails)."""
    g = Geom.of(mech)
    sys = _System(g, pose, np.asarray(load, float))
    zp, rn = _polish(sys, solution_z(mech, sol, pose, load)[None])
    if rn[0] > 1e-9:
        return None
    return _build_many(sys, zp, rn)[0]


def match(flex_forces, oracle_forces, F_ref, rtol=1e-6):
    """Whether two sets of three tip forces agree within ``rtol`` (relative to max(|n|, EI/L^2))."""
    a = np.asarray(flex_forces, float).reshape(3, 2)
    b = np.asarray(oracle_forces, float).reshape(3, 2)
    scale = max(float(np.max(np.abs(b))), F_ref)
    return float(np.max(np.abs(a - b))) <= rtol * scale
