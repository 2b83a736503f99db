"""Independent test oracles for the clamped–pinned Kirchhoff rod (test-only code).

Nothing here imports flexkin: the rod is integrated directly from the paper's first-order
equations (Eqs. 5 and 7) with scipy, and the global single-rod inverse problem is solved by
ODE shooting from random starts.  These are the yardsticks the closed form (Eqs. 9–14) and
``flexkin.rod.solve_rod`` are measured against.

Conventions (SPEC §2): the rod is clamped at ``clamp`` with tangent angle ``clamp_angle``;
``n`` is the (constant) internal force, equal to the force applied ON the rod tip; the
bending moment is ``m = EI theta'`` and the tip moment vanishes at an equilibrium.

    x' = cos th,  y' = sin th,  th' = m/EI,  m' = n_x sin th - n_y cos th     (Eqs. 5, 7)

d-mode = number of inflection points on (0, L] = 1 + sign changes of m strictly inside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

__all__ = [
    "REPORT",
    "report",
    "RodODE",
    "integrate_rod",
    "count_inflections",
    "ShootingSolution",
    "shooting_multistart",
    "RTOL",
    "ATOL",
]

#: tolerances of the reference integration (DOP853); 1e-13 relative keeps the global error of
#: the tip quantities well below the 1e-9 relative agreement demanded of the closed form, also
#: for d-mode-3 rods under forces of several hundred EI/L^2.
RTOL = 1e-13
ATOL = 1e-14


#: measured figures collected by the tests, printed in pytest's terminal summary (conftest.py)
REPORT: dict[str, str] = {}


def report(key: str, text: str) -> None:
    """Record a measured figure under ``key`` (the last value recorded wins)."""
    REPORT[key] = text


@dataclass(frozen=True)
class RodODE:
    """Result of :func:`integrate_rod` (world frame, SI units).

    ``x, y, theta, m_tip`` are the tip values, ``energy`` = (1/2EI) int m^2 ds.  When
    ``n_eval`` (or ``s_eval``) is given, ``s, xs, ys, thetas, ms`` hold the sampled curve.
    """

    x: float
    y: float
    theta: float
    m_tip: float
    energy: float
    s: np.ndarray | None = None
    xs: np.ndarray | None = None
    ys: np.ndarray | None = None
    thetas: np.ndarray | None = None
    ms: np.ndarray | None = None


def _rhs(EI: float, nx: float, ny: float):
    def f(_s, z):
        _x, _y, th, m, _u = z
        c, s = np.cos(th), np.sin(th)
        return [c, s, m / EI, nx * s - ny * c, 0.5 * m * m / EI]

    return f


def integrate_rod(
    n_world,
    m0: float,
    clamp=(0.0, 0.0),
    clamp_angle: float = 0.0,
    L: float = 1.0,
    EI: float = 1.0,
    n_eval: int | None = None,
    s_eval=None,
    rtol: float = RTOL,
    atol: float = ATOL,
) -> RodODE:
    """Integrate Eqs. (5)/(7) from the clamp with internal force ``n_world`` and base moment ``m0``.

    The state is ``(x, y, theta, m, U)`` with ``U' = m^2/(2 EI)`` (bending energy).  The
    problem is integrated in dimensionless form (arc length / L, moment / (EI/L), force /
    (EI/L^2)) so that the tolerances mean the same thing for every L and EI.
    """
    nx, ny = (float(v) for v in n_world)
    L, EI = float(L), float(EI)
    cx, cy = (float(v) for v in clamp)
    # dimensionless problem
    fs = L * L / EI
    rhs = _rhs(1.0, nx * fs, ny * fs)
    z0 = [0.0, 0.0, float(clamp_angle), float(m0) * L / EI, 0.0]
    t_eval = None
    if s_eval is not None:
        t_eval = np.asarray(s_eval, dtype=float) / L
        t_eval = np.clip(t_eval, 0.0, 1.0)
    elif n_eval is not None:
        t_eval = np.linspace(0.0, 1.0, int(n_eval))
    sol = solve_ivp(rhs, (0.0, 1.0), z0, method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval)
    if not sol.success:  # pragma: no cover - the right-hand side is smooth and bounded
        raise RuntimeError(sol.message)
    if t_eval is None or t_eval[-1] == 1.0:
        zL = sol.y[:, -1]
    else:
        zL = _final(rhs, z0, rtol, atol)
    out = dict(
        x=cx + L * zL[0], y=cy + L * zL[1], theta=float(zL[2]), m_tip=float(zL[3]) * EI / L,
        energy=float(zL[4]) * EI / L,
    )
    if t_eval is not None:
        out.update(
            s=sol.t * L, xs=cx + L * sol.y[0], ys=cy + L * sol.y[1], thetas=sol.y[2].copy(),
            ms=sol.y[3] * EI / L,
        )
    return RodODE(**out)


def _final(rhs, z0, rtol, atol):
    sol = solve_ivp(rhs, (0.0, 1.0), z0, method="DOP853", rtol=rtol, atol=atol)
    return sol.y[:, -1]


def count_inflections(moments, rel_tol: float = 1e-9) -> int:
    """d-mode of a sampled rod: 1 + number of sign changes of the moment strictly inside.

    ``moments`` are samples along the whole rod, ``moments[0]`` at the clamp and
    ``moments[-1]`` at the tip.  The tip sample is ignored (the tip always counts); the clamp
    sample takes part unless it is a zero (a zero base moment is not an interior inflection,
    but a base moment of the other sign than the first interior sample puts an inflection
    strictly inside, however close to the clamp).  Samples smaller than ``rel_tol * max|m|``
    are treated as zeros and skipped.
    """
    m = np.asarray(moments, dtype=float)[:-1]
    scale = float(np.max(np.abs(moments))) if len(moments) else 0.0
    if scale == 0.0:
        return 1
    sig = np.sign(m[np.abs(m) > rel_tol * scale])
    return 1 + int(np.count_nonzero(sig[1:] != sig[:-1]))


# ----------------------------------------------------------------------------------------
# Global search for every equilibrium with the tip pinned at a point
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ShootingSolution:
    """One equilibrium found by :func:`shooting_multistart` (local clamp frame, SI units).

    ``kprime`` is the complementary modulus ``sqrt(1 - k^2) = |sin((theta_L - psi)/2)|``
    read off the tip angle (0 for a closed loop, 1 for the straight compressed column).
    """

    mode: int
    force: tuple[float, float]  # force on the rod tip, local frame (N)
    m0: float  # base moment (N m)
    energy: float
    residual: float  # dimensionless residual after polishing (formulation that found it)
    forward_residual: float  # max(|tip err|/L, |m(L)| L/EI) of a forward integration
    kprime: float
    found_by: str = ""
    hits: int = 0  # number of random starts whose Newton iteration converged to it

    @property
    def R(self) -> float:
        return float(np.hypot(*self.force))


# ---- forward shooting: unknowns (n_x, n_y, m0) from the clamp ----------------------------
def _rk4_forward(p: np.ndarray, n_steps: int):
    """Fixed-step RK4 for a batch of dimensionless rods (L = EI = 1) with sensitivities.

    ``p`` has shape (N, 3): ``(n_x, n_y, m0)``.  Returns the tip state ``(x, y, m)`` of
    shape (N, 3) and its Jacobian with respect to ``p``, shape (N, 3, 3), obtained from the
    variational equations integrated alongside (same RK4 scheme, hence consistent).
    """
    N = p.shape[0]
    nx, ny = p[:, 0], p[:, 1]
    # state rows: x, y, th, m ; sensitivities S[j, i] = d state_i / d p_j
    z = np.zeros((4, N))
    z[3] = p[:, 2]
    S = np.zeros((3, 4, N))
    S[2, 3] = 1.0  # d m(0) / d m0
    h = 1.0 / n_steps
    e_nx = np.zeros((3, N)); e_nx[0] = 1.0
    e_ny = np.zeros((3, N)); e_ny[1] = 1.0

    def f(z, S):
        c, s = np.cos(z[2]), np.sin(z[2])
        dz = np.stack([c, s, z[3], nx * s - ny * c])
        th_p = S[:, 2]
        a = nx * c + ny * s
        dS = np.stack([-s * th_p, c * th_p, S[:, 3], a * th_p + e_nx * s - e_ny * c], axis=1)
        return dz, dS

    for _ in range(n_steps):
        k1, l1 = f(z, S)
        k2, l2 = f(z + 0.5 * h * k1, S + 0.5 * h * l1)
        k3, l3 = f(z + 0.5 * h * k2, S + 0.5 * h * l2)
        k4, l4 = f(z + h * k3, S + h * l3)
        z = z + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        S = S + (h / 6.0) * (l1 + 2 * l2 + 2 * l3 + l4)
    out = np.stack([z[0], z[1], z[3]], axis=1)
    J = np.stack([S[:, 0], S[:, 1], S[:, 3]], axis=0)  # (3 out, 3 params, N)
    return out, np.moveaxis(J, -1, 0)


def _tight_forward_residual(p, target):
    r = integrate_rod((p[0], p[1]), p[2], L=1.0, EI=1.0)
    return np.array([r.x - target[0], r.y - target[1], r.m_tip])


def _forward_candidates(target, starts, n_steps, max_iter, R_cap):
    """Batch damped Newton of the forward shooting map; returns (n_x, n_y, m0) candidates."""
    p = starts.copy()
    n = len(p)
    active = np.ones(n, bool)
    goal = np.append(target, 0.0)
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        out, J = _rk4_forward(p[idx], n_steps)
        r = out - goal
        done = np.max(np.abs(r), axis=1) < 1e-11
        step = -_solve3(J, r)
        scale = np.maximum(np.hypot(p[idx, 0], p[idx, 1]), 1.0)
        lim = np.maximum(np.abs(step[:, :2]).max(axis=1) / (0.5 * scale + 2.0),
                         np.abs(step[:, 2]) / (0.5 * np.sqrt(scale) + 1.0))
        step = step / np.maximum(lim, 1.0)[:, None]
        bad = ~np.all(np.isfinite(step), axis=1)
        upd = ~done & ~bad
        p[idx[upd]] += step[upd]
        Rn = np.hypot(p[idx, 0], p[idx, 1])
        active[idx[done | bad | (Rn > R_cap)]] = False
    ok = np.isfinite(p).all(axis=1) & (np.hypot(p[:, 0], p[:, 1]) <= R_cap)
    p = p[ok]
    if len(p) == 0:
        return p
    out, _ = _rk4_forward(p, n_steps)
    return p[np.max(np.abs(out - goal), axis=1) < 1e-6]


# ---- backward shooting: unknowns (Lambda, t) from the pinned tip --------------------------
def _v_of_t(t):
    """Tip angle relative to the force, ``v = theta_L - psi`` in (0, 2 pi), from ``t`` in R.

    ``v = pi (1 + tanh t)``: logarithmic stretching near the loops ``v -> 0, 2 pi``
    (``k' = sin(v/2) ~ pi exp(-2|t|)``), so that near-loop equilibria have Newton basins of
    ordinary size.
    """
    return np.pi * (1.0 + np.tanh(t))


def _rk4_backward(q: np.ndarray, n_steps: int):
    """Tip map of the backward (tip-anchored) formulation for a batch ``q = (Lambda, t)``.

    With ``phi = theta - psi`` the rod obeys ``phi'' = Lambda^2 sin(phi)`` (L = EI = 1,
    ``Lambda^2 = R``), ``phi'(1) = 0`` (pinned tip) and ``phi(1) = v(t)``.  Integrating from
    the tip to the clamp gives ``phi(0)``, hence ``psi = -phi(0)`` (clamp tangent 0), and the
    clamp-to-tip chord in the force frame; rotating it by ``psi`` gives the tip in the clamp
    frame.  Returns ``tip (N, 2)``, ``dtip/dq (N, 2, 2)``, ``psi``, ``m0`` and the approximate
    d-mode (1 + sign changes of the moment along the discretised rod).
    """
    Lam, t = q[:, 0], q[:, 1]
    N = len(Lam)
    L2 = Lam * Lam
    z = np.zeros((4, N))  # phi, w = dphi/ds, X, Y (position relative to the tip, force frame)
    z[0] = _v_of_t(t)
    S = np.zeros((2, 4, N))  # sensitivities to (Lambda, t)
    S[1, 0] = np.pi / np.cosh(t) ** 2
    h = 1.0 / n_steps
    sel = np.zeros((2, N)); sel[0] = 1.0

    def f(z, S):
        c, s = np.cos(z[0]), np.sin(z[0])
        dz = np.stack([-z[1], -L2 * s, -c, -s])
        dphi = S[:, 0]
        dS = np.stack([-S[:, 1], -L2 * c * dphi - sel * (2.0 * Lam * s), s * dphi, -c * dphi],
                      axis=1)
        return dz, dS

    changes = np.zeros(N, np.int64)  # sign changes of the moment w along the rod
    last = np.zeros(N)
    for _ in range(n_steps):
        k1, l1 = f(z, S)
        k2, l2 = f(z + 0.5 * h * k1, S + 0.5 * h * l1)
        k3, l3 = f(z + 0.5 * h * k2, S + 0.5 * h * l2)
        k4, l4 = f(z + h * k3, S + h * l3)
        z = z + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
        S = S + (h / 6.0) * (l1 + 2 * l2 + 2 * l3 + l4)
        sg = np.sign(z[1])
        changes += (sg * last < 0)
        last = np.where(sg != 0, sg, last)
    psi = -z[0]
    c, s = np.cos(psi), np.sin(psi)
    X, Y = -z[2], -z[3]  # chord clamp -> tip, force frame
    tip = np.stack([c * X - s * Y, s * X + c * Y], axis=1)
    dpsi = -S[:, 0]  # (2, N)
    dX, dY = -S[:, 2], -S[:, 3]
    dtx = (-s * X - c * Y) * dpsi + c * dX - s * dY
    dty = (c * X - s * Y) * dpsi + s * dX + c * dY
    J = np.moveaxis(np.stack([dtx, dty], axis=0), -1, 0)  # (N, 2 out, 2 params)
    return tip, J, psi, z[1], 1 + changes


def _backward_tight(q, n_eval: int | None = None):
    """Tight (DOP853) backward integration; returns tip, psi, m0, energy, moments (s order)."""
    Lam, t = float(q[0]), float(q[1])
    L2 = Lam * Lam

    def f(_s, z):
        c, s = np.cos(z[0]), np.sin(z[0])
        return [-z[1], -L2 * s, -c, -s, 0.5 * z[1] * z[1]]

    t_eval = None if n_eval is None else np.linspace(0.0, 1.0, n_eval)
    sol = solve_ivp(f, (0.0, 1.0), [_v_of_t(t), 0.0, 0.0, 0.0, 0.0], method="DOP853",
                    rtol=RTOL, atol=ATOL, t_eval=t_eval)
    z = sol.y[:, -1]
    psi = -z[0]
    c, s = np.cos(psi), np.sin(psi)
    X, Y = -z[2], -z[3]
    tip = np.array([c * X - s * Y, s * X + c * Y])
    moments = sol.y[1][::-1] if n_eval is not None else None
    return tip, psi, z[1], z[4], moments


def _backward_candidates(target, starts, n_steps, max_iter, Lam_cap, Lam_keep, mode_keep):
    q = starts.copy()
    active = np.ones(len(q), bool)
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        tip, J, _, _, _ = _rk4_backward(q[idx], n_steps)
        r = tip - target
        done = np.max(np.abs(r), axis=1) < 1e-12
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            d0 = -(J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1]) / det
            d1 = -(-J[:, 1, 0] * r[:, 0] + J[:, 0, 0] * r[:, 1]) / det
        step = np.stack([d0, d1], axis=1)
        bad = ~np.all(np.isfinite(step), axis=1)
        step[bad] = 0.0
        lim = np.maximum(np.abs(step[:, 0]) / 2.0, np.abs(step[:, 1]) / 1.0)
        step = step / np.maximum(lim, 1.0)[:, None]
        upd = ~done & ~bad
        q[idx[upd]] += step[upd]
        q[idx, 0] = np.abs(q[idx, 0])  # Lambda -> -Lambda is the same rod
        active[idx[done | bad | (q[idx, 0] > Lam_cap) | (np.abs(q[idx, 1]) > 18.0)]] = False
    ok = np.isfinite(q).all(axis=1) & (q[:, 0] <= Lam_cap) & (np.abs(q[:, 1]) <= 18.0)
    q = q[ok]
    if len(q) == 0:
        return q
    tip, _, _, _, mode = _rk4_backward(q, n_steps)
    # keep converged ones that may be wanted (margins: the RK4 mode count may be off by one
    # for a zero of the moment right at the clamp)
    ok = (np.max(np.abs(tip - target), axis=1) < 1e-7) & (q[:, 0] <= Lam_keep) & (mode <= mode_keep)
    return q[ok]


def shooting_multistart(
    tip_local,
    L: float,
    EI: float,
    n_starts: int = 2000,
    max_mode: int = 2,
    rng: np.random.Generator | None = None,
    *,
    R_max: float = 400.0,
    method: str = "backward",
    n_steps: int = 200,
    max_iter: int = 40,
    t_max: float = 7.0,
    return_all_modes: bool = False,
) -> list[ShootingSolution]:
    """Every equilibrium with d-mode <= ``max_mode`` of a rod clamped at the origin (tangent
    +x) whose tip is pinned at ``tip_local``, by shooting from random starts.

    Everything is solved in dimensionless form (L = EI = 1, force in EI/L^2, moment in EI/L).
    Two independent shooting formulations are available (``method``: "backward", "forward"
    or "both"; solutions of both are merged):

    **forward** (the textbook one): unknowns ``(n_x, n_y, m0)``, equations ``x(L) = t_x``,
    ``y(L) = t_y``, ``m(L) = 0``, integrated from the clamp.  Starts: force magnitude
    ``R L^2/EI`` log-uniform in [0.01, R_max], direction uniform; base moment
    ``m0 L/EI = 2 sqrt(R L^2/EI) u``, ``u`` uniform in [-1, 1] -- the first integral
    ``m^2/(2EI) + R cos(theta - psi) = const`` with a zero tip moment gives
    ``m0^2 <= 2 EI R (1 - cos psi) <= 4 EI R``, so this interval holds every admissible base
    moment.  Caveat found while building this oracle: near-loop rods (k -> 1) make this map
    exponentially ill-conditioned (cond ~ 1e6 at k' ~ 6e-3, lambda L ~ 19) and their Newton
    basins tiny, so forward shooting alone misses such equilibria.

    **backward** (default): unknowns ``(Lambda, t)`` with ``Lambda = sqrt(R L^2/EI)`` and the
    tip angle relative to the force ``v = theta_L - psi = pi (1 + tanh t)``; the pendulum
    ``phi'' = Lambda^2 sin(phi)`` is integrated from the pinned tip (``phi' = 0``) to the
    clamp, which fixes ``psi = -phi(0)``; equations: tip x, y.  Every clamped-pinned
    equilibrium has such a representation (the tip moment vanishes, so the tip is a turning
    point of the pendulum), and the ``tanh`` stretching gives near-loop equilibria
    (``k' = sin(v/2) ~ pi exp(-2|t|)``) ordinary basins.  Starts: ``t`` uniform in
    [-t_max, t_max] (default 7: ``k'`` down to ~3e-6); ``Lambda`` for half of the starts
    uniform in (0, sqrt(R_max)], for the other half ``sqrt`` of a log-uniform ``R L^2/EI`` in
    [0.01, R_max] (uniform ``Lambda`` puts more starts at high forces, where basins are small).

    Both are refined by batch damped Newton on a fixed-step RK4 discretisation (Jacobians
    from variational equations), then every candidate is polished with
    ``scipy.optimize.least_squares`` on the tight DOP853 integration of its own formulation
    and kept when the residual is below 1e-10; the d-mode is counted on the tightly integrated
    moment, duplicates are merged, and solutions with ``R L^2/EI <= R_max`` and d-mode <=
    ``max_mode`` are returned sorted by (mode, R).  Each solution also carries the residual of
    a forward integration from the clamp with its ``(n, m0)`` (``forward_residual``).
    """
    if method not in ("backward", "forward", "both"):
        raise ValueError(method)
    rng = np.random.default_rng(0) if rng is None else rng
    target = np.asarray(tip_local, dtype=float).reshape(2) / L
    # entries: (n_x, n_y, m0), residual, method, backward parameters (Lambda, t) or None, hits
    found: list[tuple[np.ndarray, float, str, np.ndarray | None, int]] = []

    if method in ("backward", "both"):
        n1 = n_starts // 2
        Lam = np.concatenate([
            rng.uniform(0.0, np.sqrt(R_max), n1),
            np.sqrt(np.exp(rng.uniform(np.log(0.01), np.log(R_max), n_starts - n1))),
        ])
        t = rng.uniform(-t_max, t_max, n_starts)
        cand = _backward_candidates(target, np.stack([Lam, t], axis=1), n_steps, max_iter,
                                    1.5 * np.sqrt(R_max), 1.01 * np.sqrt(R_max),
                                    10**6 if return_all_modes else max_mode + 1)
        cand, hits = _dedupe(cand, 1e-5)
        for q0, nh in zip(cand, hits):
            ls = least_squares(lambda q: _backward_tight(q)[0] - target, q0, method="lm",
                               xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=100)
            rr = float(np.max(np.abs(ls.fun)))
            if rr < 1e-10:
                _, psi, m0, _, _ = _backward_tight(ls.x)
                R = ls.x[0] ** 2
                found.append((np.array([R * np.cos(psi), R * np.sin(psi), m0]), rr, "backward",
                              ls.x.copy(), int(nh)))

    if method in ("forward", "both"):
        R = np.exp(rng.uniform(np.log(0.01), np.log(R_max), n_starts))
        ang = rng.uniform(0.0, 2 * np.pi, n_starts)
        m0 = 2.0 * np.sqrt(R) * rng.uniform(-1.0, 1.0, n_starts)
        starts = np.stack([R * np.cos(ang), R * np.sin(ang), m0], axis=1)
        cand, hits = _dedupe(_forward_candidates(target, starts, n_steps, max_iter, 2.25 * R_max),
                             1e-6)
        for c, nh in zip(cand, hits):
            ls = least_squares(_tight_forward_residual, c, args=(target,), method="lm",
                               xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
            rr = float(np.max(np.abs(ls.fun)))
            if rr < 1e-10:
                found.append((ls.x, rr, "forward", None, int(nh)))

    # ---- merge duplicates (relative 1e-6 on (n, m0))
    keep: list[list] = []
    for x, rr, how, qb, nh in found:
        for k in keep:
            if np.max(np.abs(x - k[0])) <= 1e-6 * (1.0 + np.max(np.abs(k[0]))):
                if how not in k[2]:
                    k[2] += "+" + how
                if k[3] is None:
                    k[3] = qb
                k[4] += nh
                break
        else:
            keep.append([x, rr, how, qb, nh])
    result = []
    for x, rr, how, qb, nh in keep:
        Rd = float(np.hypot(x[0], x[1]))
        if Rd > R_max:
            continue
        # classify on the tight backward curve (well conditioned even for loops)
        if qb is None:
            qb = np.array([np.sqrt(Rd), _t_of_v(_tip_angle_rel(x))])
        v = float(_v_of_t(qb[1]))
        _, _, _, energy, moments = _backward_tight(qb, n_eval=4001)
        mode = count_inflections(moments)
        if mode > max_mode and not return_all_modes:
            continue
        fwd = integrate_rod((x[0], x[1]), x[2], L=1.0, EI=1.0)
        fres = max(abs(fwd.x - target[0]), abs(fwd.y - target[1]), abs(fwd.m_tip))
        result.append(ShootingSolution(
            mode=mode, force=(x[0] * EI / L**2, x[1] * EI / L**2), m0=x[2] * EI / L,
            energy=energy * EI / L, residual=rr, forward_residual=float(fres),
            kprime=float(abs(np.sin(v / 2.0))), found_by=how, hits=int(nh)))
    result.sort(key=lambda s: (s.mode, s.R))
    return result


def _tip_angle_rel(x) -> float:
    """``v = theta_L - psi`` in (0, 2 pi) of a dimensionless solution ``(n_x, n_y, m0)``.

    From the first integral ``m^2/2 + R cos(theta - psi) = R cos(v)`` at the clamp
    (``theta = 0``) only ``cos v`` follows, so ``v`` is read off a tight forward integration.
    Only used for solutions found by forward shooting alone, i.e. well-conditioned rods.
    """
    r = integrate_rod((x[0], x[1]), x[2], L=1.0, EI=1.0)
    psi = np.arctan2(x[1], x[0])
    return float(np.mod(r.theta - psi, 2 * np.pi))


def _t_of_v(v: float) -> float:
    return float(np.arctanh(np.clip(v / np.pi - 1.0, -1 + 1e-16, 1 - 1e-16)))


def _solve3(J: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched 3x3 solve by Cramer's rule (non-finite rows where singular; never raises)."""
    c0, c1, c2 = J[:, :, 0], J[:, :, 1], J[:, :, 2]
    det = np.einsum("ij,ij->i", c0, np.cross(c1, c2))
    with np.errstate(divide="ignore", invalid="ignore"):
        x0 = np.einsum("ij,ij->i", b, np.cross(c1, c2)) / det
        x1 = np.einsum("ij,ij->i", c0, np.cross(b, c2)) / det
        x2 = np.einsum("ij,ij->i", c0, np.cross(c1, b)) / det
    return np.stack([x0, x1, x2], axis=1)


def _dedupe(z: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Cluster rows closer than ``tol`` (relative, inf-norm); returns (representatives, counts)."""
    z = np.asarray(z, dtype=float)
    width = z.shape[1] if z.ndim == 2 else 3
    keep: list[np.ndarray] = []
    counts: list[int] = []
    for row in z.reshape(-1, width):
        for i, k in enumerate(keep):
            if np.max(np.abs(row - k)) <= tol * (1.0 + np.max(np.abs(k))):
                counts[i] += 1
                break
        else:
            keep.append(row)
            counts.append(1)
    return np.array(keep).reshape(-1, width), np.array(counts, dtype=np.int64)
