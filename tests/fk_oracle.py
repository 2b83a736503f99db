"""Independent multi-start shooting oracle for the forward kinematics of planar PCMs (test-only).

Independence.  Nothing here calls flexkin's solvers: only the plain geometry of a
:class:`flexkin.Mechanism` is read (through :class:`ik_oracle.Geom`, which rebuilds every clamp
from SPEC §2 by hand), and the rods are integrated with the integrators of ``tests/ik_oracle.py``
(batched RK4 with variational equations, batched DOP853) and with the long-double Taylor-series
integrator here (:func:`taylor_ld`).

Equations.  Each rod obeys the paper's first-order equations (Eqs. 5 and 7),

    x' = cos th,  y' = sin th,  th' = m/EI,  m' = n_x sin th - n_y cos th,

with ``n`` the (constant) internal force = the force ON the rod tip BY the platform (SPEC §2).
The 12 FK equations for the 12 unknowns (per rod ``n_i`` and ``m0_i``, and the pose) are: tip i
at ``B_i = P + Rot(theta) b_i`` (6), zero tip moment (3), and the platform equilibrium
``sum n_i = F``, ``sum (B_i - P) x n_i = M_z`` (3; the platform receives ``-n_i``).

Unknowns actually iterated ("tip-anchored chart").  Per rod ``(Lambda, t, psi)``: ``Lambda^2 =
R L^2/EI`` (dimensionless tip force), ``psi`` its world direction, ``v = theta_L - psi =
pi (1 + tanh t)`` the tip angle relative to the force (so ``k' = |sin(v/2)|``; the tanh
stretching gives taut rods, ``k' -> 0``, room), then the pose ``(x / L_ref, y / L_ref, theta)``.
Each rod is integrated from its pinned tip (at ``B_i``, tangent ``theta_L``, zero moment) back
to ``s = 0``; the residual is its arrival at the clamp point ``A_i`` (2) with the clamp tangent
``alpha_i`` (1), plus the equilibrium (3).  This is the same two-point boundary value problem as
above, shot from the other end: shooting from the clamp amplifies errors like ``1/k'^2`` for taut
rods (the tip then sits near the saddle of the pendulum ``phi'' = Lambda^2 sin phi``), shooting from
the tip does not -- except for rods of d-mode >= 2 with a small k', which pass near the saddle
*inside*; :func:`shoot_from_tip` handles those by the symmetry of the elastica.  (The reversed
rod, ``sigma = L - s``, ``th~ = th + pi``, ``m~ = -m``, ``n~ = -n``, obeys the same equations.)

Starts (all fed to one damped batch Newton on the 12 equations, RK4 + variational Jacobian):

* **pose-grid starts**: every unit clamped-pinned rod is a point ``(Lambda, t)`` of a scanned
  chart grid; with the inputs fixed each clamp is fixed, so the scan of rod i is a fixed sheet of
  (tip, force) triangles in the world.  On a jittered grid of poses (the reach region times a
  theta grid) every triangle of every rod containing ``B_i`` is found; for every triple of such
  rods the platform wrench balance is linearised in the pose (through the triangles' tip
  stiffness) and the triple is a start when the predicted pose correction is within ``s_max``
  grid steps (one start per cluster of equal predictions);
* **anchor starts** (taut rods): a rod whose tip is nearly at full reach exists only in a thin
  shell of poses, which a pose grid straddles.  So poses are also built rod-first: a random
  scanned state of rod j with extension ``|B_j - A_j| >= ext_min L_j`` fixes ``B_j``, a theta
  grid completes the pose, and the same triple search runs on these poses;
* **random chart starts**: a pose uniform in the reach region (theta uniform) and, per rod, one of
  its scanned rods pinned at ``B_i`` chosen at random;
* **random forward starts** (textbook, as in ``ik_oracle``): a pose uniform in the reach region,
  per rod a random dimensionless force ``R L^2/EI`` (log-uniform), direction and base moment
  (within the first-integral bound), Newton-projected from the clamp (pose frozen) onto "tip at
  ``B_i``, zero tip moment".

Converged candidates are de-duplicated, refined with an 800-step RK4 and polished with the
tight residual.  Every returned solution is **verified** (:func:`verify_fk`): the 12 equations hold
to ``VERIFY_TOL`` (scaled), every rod integrated from its pinned tip to its clamp by
:func:`shoot_from_tip` -- a long-double Taylor series, split at the rod's inflection points by the
reflection symmetry of the elastica, so that rods near the separatrix stay well conditioned
(checked against a 30-digit mpmath integration in the tests); the one-piece DOP853 integration
is kept as a cross-check.  The d-mode of each rod is 1 + the number of
inflection points strictly inside it.  A rod with ``k' < EXTREME_KPRIME = 5e-7`` is **extreme**:
flexkin drops such rods (documented out of scope); extreme solutions are returned with the flag
and only reported by the tests.

Coverage limits (documented, not hidden): the chart scan reaches ``Lambda <= Lambda_max`` (default
40, i.e. R L^2/EI <= 1600) and Newton gives up beyond ``1.5 Lambda_max``; rods are searched with
d-mode <= max_mode + 1.

Rods CLAMPED to the platform (``leg.joint == "clamped"``, tip tangent ``theta + leg.tip_angle``;
tip moment m(L) in the moment balance): mechanisms with a clamped leg are solved by
``fk_clamped.fk_clamped`` (exact rods at the nodes of a pose lattice, seeded from the canonical
chart of clamped rods and flood-filled over the lattice, linearised triples, Newton in the pose
with the rods slaved, multiple-shooting refinement; search box R L^2/EI <= 450, clamped
|turning| <= max_turn + 0.5) and verified by :func:`_verify_mixed` (clamped rods shot from both
ends).  The pinned-only path is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from clamped_chart import bucket_hits, bucket_spans, rk4_step
from ik_oracle import (
    Geom,
    _rk4_unit,
    _safe_solve,
    integrate_batch,
)
from scipy.special import expit

__all__ = [
    "EXTREME_KPRIME",
    "VERIFY_TOL",
    "FKOracleRod",
    "FKOracleSolution",
    "FKSystem",
    "TipSystem",
    "by_modes",
    "fk_multistart",
    "oracle_fk",
    "pose_match",
    "shoot_from_tip",
    "taylor_ld",
    "verify_fk",
    "verify_solutions",
]

#: rods with k' = sqrt(1 - k^2) below this are out of flexkin's scope (it drops them)
EXTREME_KPRIME = 5e-7
#: the 12 scaled equations (shot from the pinned tips, DOP853) must hold to this for a solution
#: without extreme rods to be accepted
VERIFY_TOL = 1e-9


# ======================================================================================
# the 12 FK equations shot from the clamps (used by the verification and the forward starts)
# ======================================================================================
class FKSystem:
    """Geometry for fixed inputs and the 12 FK equations shot from the clamps.

    Scaled unknowns: ``n / F_ref``, ``m0 / (F_ref L_ref)`` per rod, then ``x / L_ref``,
    ``y / L_ref``, ``theta``.  Scaled equations: tip error / L_ref, tip moment L/EI, force error
    / F_ref, moment error / (F_ref L_ref).
    """

    def __init__(self, mech_or_geom, inputs, load):
        g = mech_or_geom if isinstance(mech_or_geom, Geom) else Geom.of(mech_or_geom)
        self.g = g
        self.inputs = np.asarray(inputs, float).reshape(3)
        self.load = np.asarray(load, float).reshape(3)
        A, al, L = [], [], []
        for i in range(3):
            a, b, c = g.clamp(i, np.asarray(self.inputs[i]))
            A.append(np.asarray(a, float)); al.append(float(b)); L.append(float(c))
        self.A = np.array(A)     # (3, 2)
        self.al = np.array(al)   # (3,)
        self.L = np.array(L)     # (3,)
        self.ps = np.array([g.L_ref, g.L_ref, 1.0])

    # ---- conversions -------------------------------------------------------------------
    def physical(self, z):
        g = self.g
        n = z[:, 0:9].reshape(-1, 3, 3).copy()
        n[..., :2] *= g.F_ref
        n[..., 2] *= g.F_ref * g.L_ref
        pose = z[:, 9:12] * self.ps
        return n, pose

    def to_z(self, forces, moments, pose):
        """Scaled unknowns from SI forces (N, 3, 2), base moments (N, 3), poses (N, 3)."""
        g = self.g
        f = np.asarray(forces, float).reshape(-1, 3, 2)
        z = np.empty((len(f), 12))
        z[:, 0:9:3] = f[..., 0] / g.F_ref
        z[:, 1:9:3] = f[..., 1] / g.F_ref
        z[:, 2:9:3] = np.asarray(moments, float).reshape(-1, 3) / (g.F_ref * g.L_ref)
        z[:, 9:12] = np.asarray(pose, float).reshape(-1, 3) / self.ps
        return z

    def platform_points(self, pose):
        """B_i (N, 3, 2) for poses (N, 3)."""
        b = self.g.attach
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        arm = np.stack([c[:, None] * b[None, :, 0] - s[:, None] * b[None, :, 1],
                        s[:, None] * b[None, :, 0] + c[:, None] * b[None, :, 1]], -1)
        return pose[:, None, :2] + arm, arm

    def unit_params(self, n):
        """Dimensionless (ax, ay, mt) (N, 3) of SI forces/moments n (N, 3, 3)."""
        EI, L = self.g.EI[None], self.L[None]
        return n[..., 0] * L**2 / EI, n[..., 1] * L**2 / EI, n[..., 2] * L / EI

    # ---- residual --------------------------------------------------------------------------
    def tight_residual(self, z):
        """Residual (N, 12) with every rod integrated by DOP853 (batched, rtol 1e-13)."""
        g = self.g
        z = np.atleast_2d(z)
        N = len(z)
        n, pose = self.physical(z)
        ax, ay, mt = self.unit_params(n)
        y = integrate_batch(ax, ay, mt, np.broadcast_to(self.al[None], (N, 3)))[..., -1].reshape(4, N, 3)
        B, arm = self.platform_points(pose)
        tip = self.A[None] + self.L[None, :, None] * np.stack([y[0], y[1]], -1)
        r = np.empty((N, 12))
        rr = np.empty((N, 3, 3))
        rr[..., :2] = (tip - B) / g.L_ref
        rr[..., 2] = y[3]
        r[:, :9] = rr.reshape(N, 9)
        r[:, 9:11] = (n[..., :2].sum(axis=1) - self.load[:2]) / g.F_ref
        mom = np.sum(arm[..., 0] * n[..., 1] - arm[..., 1] * n[..., 0], axis=1)
        r[:, 11] = (mom - self.load[2]) / (g.F_ref * g.L_ref)
        return r


def _solve(J, r):
    with np.errstate(all="ignore"):
        try:
            return np.linalg.solve(J, r[..., None])[..., 0]
        except np.linalg.LinAlgError:
            return np.stack([_safe_solve(Jk, rk) for Jk, rk in zip(J, r)])


# ======================================================================================
# the same equations in tip-anchored chart form (the search runs on these)
# ======================================================================================
def _v_of_t(t):
    """Tip angle relative to the force, v = pi (1 + tanh t) = 2 pi expit(2 t) (no cancellation)."""
    return 2.0 * np.pi * expit(2.0 * t)


def _dv_dt(t):
    e = expit(2.0 * t)
    return 4.0 * np.pi * e * (1.0 - e)


def _t_of_v(v):
    v = np.clip(v, 1e-300, 2 * np.pi - 1e-15)
    return 0.5 * (np.log(v) - np.log(2 * np.pi - v))


_LD = np.longdouble
_PI_LD = np.arccos(_LD(-1))


def _chart_ld(lam, t, psi):
    """Reversed-rod data of chart points in long double, in the frame of the reversed rod's force
    (direction ``psi~ = psi + pi``, magnitude ``Lambda^2``): the angle ``phi0`` of the tangent at the
    pinned end relative to the force, taken in (-pi, pi] so that it is small, with full relative
    precision, near the saddle (taut rods: ``v`` near 0 or 2 pi), ``k'`` and ``K(k)`` (by the AGM,
    ``K = pi / (2 AGM(1, k'))``).  Returns (psi~, phi0, k', K)."""
    lam, t, psi = (np.asarray(a, float).astype(_LD) for a in (lam, t, psi))
    small = _LD(1) / (_LD(1) + np.exp(2 * np.abs(t)))  # min(expit(2t), expit(-2t)): v / 2 pi or 1 - v / 2 pi
    phi0 = np.where(t <= 0, 2 * _PI_LD * small, -2 * _PI_LD * small)  # v, or v - 2 pi
    kp = np.sin(_PI_LD * small)
    a, b = np.ones_like(kp), kp.copy()
    for _ in range(80):
        a, b = (a + b) / 2, np.sqrt(a * b)
        if np.all(np.abs(a - b) <= _LD(4e-19) * a):
            break
    return psi + _PI_LD, phi0, kp, _PI_LD / (2 * a)


def taylor_ld(ax, ay, z, D, order=16, h_rate=0.2):
    """Unit rods (force (ax, ay)) integrated from the states ``z`` (4, M) = (x, y, theta, m) over the
    arc lengths ``D`` (M,) >= 0 by a fixed-step Taylor-series method of order ``order`` in long
    double (64-bit mantissa), the coefficients by the usual recurrences for sin/cos (``s' = c theta'``,
    ``c' = -s theta'``).  Steps ``h <= h_rate / (2 Lambda + |m| + 1)``, well inside the radius of
    convergence (~ pi / (2 Lambda)).  Returns the end states (4, M) in long double."""
    ax, ay, D = (np.asarray(a).astype(_LD) for a in (ax, ay, D))
    z = np.array(z, dtype=_LD)
    M = z.shape[1]
    lam = np.sqrt(np.hypot(ax.astype(float), ay.astype(float)))
    rate = 2 * lam + np.abs(z[3].astype(float)) + 1.0
    n = max(1, int(np.ceil(np.max(D.astype(float) * rate, initial=0.0) / h_rate)))
    h = D / n
    inv = [_LD(1) / (k + 1) for k in range(order)]
    jj = np.arange(1, order + 1, dtype=_LD)[:, None]
    X, Y, T, Mm, S, C = (np.empty((order + 1, M), _LD) for _ in range(6))
    for _ in range(n):
        T[0], Mm[0] = z[2], z[3]
        S[0], C[0] = np.sin(z[2]), np.cos(z[2])
        for k in range(order):
            X[k + 1] = C[k] * inv[k]
            Y[k + 1] = S[k] * inv[k]
            T[k + 1] = Mm[k] * inv[k]
            Mm[k + 1] = (ax * S[k] - ay * C[k]) * inv[k]
            w = jj[:k + 1] * T[1:k + 2]
            S[k + 1] = (w * C[k::-1]).sum(0) * inv[k]
            C[k + 1] = -(w * S[k::-1]).sum(0) * inv[k]
        for comp, arr in enumerate((X, Y, T, Mm)):
            acc = arr[order]
            for k in range(order - 1, 0, -1):
                acc = acc * h + arr[k]
            z[comp] = z[comp] + acc * h
    return z


def shoot_from_tip(lam, t, psi, max_half_waves=8):
    """Reversed unit rods of chart points ``(Lambda, t, psi)`` integrated from the pinned tip (moment
    zero) over unit arc length, accurately also near the separatrix (``k' -> 0``).

    In the frame of the force the angle ``phi`` of the tangent relative to the force obeys the
    pendulum ``phi'' = Lambda^2 sin phi``, and a pinned end is a turning point (``phi' = 0``): the rod
    is a libration about ``phi = pi`` between the turning points ``v`` and ``2 pi - v`` (the rod's
    inflection points, moment zero, all on the force line), which recur every half-period
    ``H = 2 K(k) / Lambda`` (``k = cos(v/2)``), with the curvature extrema half-way, at ``phi = pi``.
    Near the separatrix the turning points sit next to the saddle ``phi = 0``: integrating towards
    one amplifies errors like ``1/k'`` (``1/k'^2`` across a d-mode >= 2 rod), integrating away from
    one does not.  The elastica is symmetric under the reflection across the normal at a curvature
    extremum (reversibility: ``phi(s_c + s) - pi = pi - phi(s_c - s)``), which in the force frame is
    the line ``x = x_c``; so every full half-wave is obtained by integrating from an inflection point
    ``(x_s, y_s, phi_s)`` over the quarter period ``Q = K / Lambda`` to ``x_c`` and jumping to the
    next inflection point ``(2 x_c - x_s, y_s, -phi_s)`` (angle taken mod 2 pi); only the last,
    partial half-wave is integrated to the end.  The integration is in long double
    (:func:`taylor_ld`) with ``phi`` kept small near the saddle, so ``v`` keeps its relative
    precision.

    Returns (z (4, M) float64 end states (x, y, theta, m) in the world orientation, number of
    inflection points strictly inside the rod, boundary flag: the far end lies within 1e-7 H of an
    inflection point, i.e. its moment nearly vanishes and the count is a boundary case).
    """
    lam = np.abs(np.asarray(lam, float).ravel())
    psi_f, phi0, _kp, K = _chart_ld(lam, np.asarray(t, float).ravel(), np.asarray(psi, float).ravel())
    M = len(lam)
    lam_ld = lam.astype(_LD)
    a = lam_ld * lam_ld
    zero = np.zeros(M, _LD)
    pos = lam > 0
    Q = np.where(pos, K / np.where(pos, lam_ld, _LD(1)), _LD(np.inf))
    H = 2 * Q
    fin = np.isfinite(H)
    n_in = np.where(fin, np.floor(_LD(1) / np.where(fin, H, _LD(1))), 0).astype(np.int64)
    n_in = np.minimum(n_in, max_half_waves)
    rem = np.where(fin, _LD(1) - n_in * np.where(fin, H, _LD(0)), _LD(1))
    z = np.stack([zero, zero, phi0, zero])  # force frame: (x, y, phi, m)
    for j in range(int(n_in.max(initial=0))):
        act = n_in > j
        zc = taylor_ld(a, zero, z, np.where(act, Q, _LD(0)))  # curvature extremum, phi = +-pi
        new = np.stack([2 * zc[0] - z[0], z[1], -z[2], zero])
        z = np.where(act[None], new, z)
    z = taylor_ld(a, zero, z, rem)
    c, s = np.cos(psi_f), np.sin(psi_f)
    out = np.stack([c * z[0] - s * z[1], s * z[0] + c * z[1], z[2] + psi_f, z[3]]).astype(float)
    frac = np.where(fin, rem / np.where(fin, H, _LD(1)), _LD(0.5)).astype(float)
    boundary = (frac < 1e-7) | (frac > 1 - 1e-7)
    return out, n_in, boundary


class TipSystem:
    """The FK equations with each rod integrated backwards from its pinned tip, in chart form.

    Unknowns per rod ``(Lambda, t, psi)``: ``Lambda^2 = R L^2/EI`` (dimensionless tip force),
    ``psi`` its world direction, ``t`` the tip angle relative to the force through
    ``v = pi (1 + tanh t)`` (so ``theta_L = psi + v`` and ``|k| = |cos(v/2)|``; the tanh stretching
    makes ``t ~ log k'`` near ``|k| = 1``, which keeps Newton's basins of taut rods and rods near
    the separatrix wide), then the pose ``(x / L_ref, y / L_ref, theta)``.  Each rod starts at
    ``B_i(pose)`` with tangent ``theta_L`` and zero moment and is integrated to ``s = 0``; the
    equations are arrival at the clamp point ``A_i`` (2, / L_ref) with the clamp angle ``alpha_i``
    (1, modulo 2 pi), and the platform equilibrium (3).  This is the prescribed system (tip at
    B_i, zero tip moment, equilibrium) with the two-point boundary value problem shot from the
    other end: taut rods of d-mode 1 are well-conditioned this way, while shooting from the clamp
    amplifies errors like 1/k'^2 (rods of d-mode >= 2 near the separatrix are ill-conditioned
    either way).

    Backward integration uses the reversed rod: with ``sigma = 1 - s/L``, ``theta~ = theta + pi``,
    ``m~ = -m`` and the force negated, the reversed rod obeys the same equations, so the
    integrators of ``ik_oracle`` are reused unchanged.
    """

    def __init__(self, fsys: FKSystem):
        self.f = fsys
        self.g = fsys.g
        self.fs = fsys.g.EI / fsys.L**2  # force scale per rod

    def rods(self, y):
        """n (N, 3, 2) SI, pose, B, arm, reversed-rod parameters (ax', ay', th0') (N, 3)."""
        f = self.f
        lam, t, psi = y[:, 0:9:3], y[:, 1:9:3], y[:, 2:9:3]
        Rd = lam * lam
        c, s = np.cos(psi), np.sin(psi)
        n = np.stack([Rd * c, Rd * s], -1) * self.fs[None, :, None]
        pose = y[:, 9:12] * f.ps
        B, arm = f.platform_points(pose)
        th0 = psi + _v_of_t(t) + np.pi
        return n, pose, B, arm, -Rd * c, -Rd * s, th0

    def _residual(self, y, X, Yc, TH, n, pose, B, arm):
        g, f = self.g, self.f
        N = len(y)
        clamp = B + f.L[None, :, None] * np.stack([X, Yc], -1)
        r = np.empty((N, 12))
        rr = np.empty((N, 3, 3))
        rr[..., :2] = (clamp - f.A[None]) / g.L_ref
        rr[..., 2] = _wrap(TH - np.pi - f.al[None])
        r[:, 0:9] = rr.reshape(N, 9)
        r[:, 9:11] = (n.sum(axis=1) - f.load[:2]) / g.F_ref
        mom = np.sum(arm[..., 0] * n[..., 1] - arm[..., 1] * n[..., 0], axis=1)
        r[:, 11] = (mom - f.load[2]) / (g.F_ref * g.L_ref)
        return r

    def eval(self, y, n_steps=128, jac=True):
        g, f = self.g, self.f
        N = len(y)
        n, pose, B, arm, axr, ayr, th0 = self.rods(y)
        Z, S, ch = _rk4_unit(axr.ravel(), ayr.ravel(), np.zeros(3 * N), th0.ravel(), n_steps)
        Z = Z.reshape(4, N, 3)
        S = S.reshape(4, 4, N, 3)
        ch = ch.reshape(N, 3)
        r = self._residual(y, Z[0], Z[1], Z[2], n, pose, B, arm)
        if not jac:
            return r, ch
        lam, t, psi = y[:, 0:9:3], y[:, 1:9:3], y[:, 2:9:3]
        c, s = np.cos(psi), np.sin(psi)
        # d(ax', ay', th0')/d(lam, t, psi)
        dax = (-2 * lam * c, 0.0 * lam, lam * lam * s)
        day = (-2 * lam * s, 0.0 * lam, -lam * lam * c)
        dth = (0.0 * lam, _dv_dt(t), 1.0 + 0.0 * lam)
        J = np.zeros((N, 12, 12))
        for i in range(3):
            Li = f.L[i]
            osc = np.array([Li / g.L_ref, Li / g.L_ref, 1.0])[:, None]
            Sx = S[0, :3, :, i] * osc  # d(x, y, th)/d ax'  (3, N)
            Sy = S[1, :3, :, i] * osc
            St = S[3, :3, :, i] * osc
            for c_ in range(3):
                col = Sx * dax[c_][:, i] + Sy * day[c_][:, i] + St * dth[c_][:, i]
                J[:, 3 * i:3 * i + 3, 3 * i + c_] = col.T
            J[:, 3 * i, 9] = 1.0
            J[:, 3 * i + 1, 10] = 1.0
            J[:, 3 * i, 11] = -arm[:, i, 1] / g.L_ref
            J[:, 3 * i + 1, 11] = arm[:, i, 0] / g.L_ref
            # equilibrium rows: dn/dlam = 2 lam fs (c, s), dn/dpsi = lam^2 fs (-s, c)
            k = self.fs[i] / g.F_ref
            dn_dl = 2 * lam[:, i, None] * k * np.stack([c[:, i], s[:, i]], -1)
            dn_dp = lam[:, i, None] ** 2 * k * np.stack([-s[:, i], c[:, i]], -1)
            J[:, 9:11, 3 * i] = dn_dl
            J[:, 9:11, 3 * i + 2] = dn_dp
            ax_, ay_ = arm[:, i, 0] / g.L_ref, arm[:, i, 1] / g.L_ref
            J[:, 11, 3 * i] = ax_ * dn_dl[:, 1] - ay_ * dn_dl[:, 0]
            J[:, 11, 3 * i + 2] = ax_ * dn_dp[:, 1] - ay_ * dn_dp[:, 0]
        J[:, 11, 11] = -np.sum(arm[..., 0] * n[..., 0] + arm[..., 1] * n[..., 1], axis=1) / (g.F_ref * g.L_ref)
        return r, J, ch

    def tight(self, y):
        """The residual (N, 12) with every reversed rod integrated by :func:`shoot_from_tip` (long
        double Taylor series, split at the inflection points: accurate to ~1e-13 also near the
        separatrix); also the reversed rods' states at the clamp (4, N, 3), the d-modes (1 +
        inflection points strictly inside) and the boundary flags of the counts (N, 3)."""
        y = np.atleast_2d(y)
        N = len(y)
        n, pose, B, arm, *_ = self.rods(y)
        Z, n_in, bnd = shoot_from_tip(y[:, 0:9:3], y[:, 1:9:3], y[:, 2:9:3])
        Z = Z.reshape(4, N, 3)
        r = self._residual(y, Z[0], Z[1], Z[2], n, pose, B, arm)
        return r, Z, (1 + n_in).reshape(N, 3), bnd.reshape(N, 3)

    def plain(self, y):
        """The residual with every reversed rod integrated in one piece by DOP853 in double precision
        (``ik_oracle.integrate_batch``, rtol 1e-13): fast, but ill-conditioned like 1/k'^2 for
        d-mode >= 2 rods near the separatrix."""
        y = np.atleast_2d(y)
        N = len(y)
        n, pose, B, arm, axr, ayr, th0 = self.rods(y)
        Yb = integrate_batch(axr, ayr, np.zeros((N, 3)), th0, n_eval=2).reshape(4, N, 3, 2)
        return self._residual(y, Yb[0, ..., -1], Yb[1, ..., -1], Yb[2, ..., -1], n, pose, B, arm)

    def tight_jacobian(self, y, r0=None):
        """Jacobian of :meth:`tight`'s residual: the rod rows by forward differences (each rod
        depends only on its own chart point, so three perturbed evaluations suffice), the pose
        columns and the equilibrium rows exactly (as in :meth:`eval`)."""
        y = np.atleast_2d(y)
        if r0 is None:
            r0 = self.tight(y)[0]
        J = self.eval(y, n_steps=8)[1]  # exact pose columns and equilibrium rows; rod blocks replaced
        for c in range(3):
            h = 1e-7 * (1.0 + np.abs(y[:, c:9:3]))
            yp = y.copy()
            yp[:, c:9:3] += h
            rp = self.tight(yp)[0]
            for i in range(3):
                J[:, 3 * i:3 * i + 3, 3 * i + c] = (rp[:, 3 * i:3 * i + 3] - r0[:, 3 * i:3 * i + 3]) / h[:, i, None]
        return J


def chart_y(sys: FKSystem, forces, tip_angles, poses):
    """Tip-anchored chart unknowns from SI forces (N, 3, 2), world tip angles (N, 3), poses (N, 3)."""
    g = sys.g
    f = np.asarray(forces, float).reshape(-1, 3, 2)
    y = np.empty((len(f), 12))
    R = np.hypot(f[..., 0], f[..., 1])
    psi = np.arctan2(f[..., 1], f[..., 0])
    v = np.mod(np.asarray(tip_angles, float).reshape(-1, 3) - psi, 2 * np.pi)
    y[:, 0:9:3] = np.sqrt(R * sys.L[None] ** 2 / g.EI[None])
    y[:, 1:9:3] = _t_of_v(v)
    y[:, 2:9:3] = psi
    y[:, 9:12] = np.asarray(poses, float).reshape(-1, 3) / sys.ps
    return y


def tip_newton(ts: TipSystem, y, n_iter=30, n_steps=128, tol=1e-10, lam_blow=60.0):
    """Damped batch Newton on the tip-anchored equations.  Returns y, residual inf-norm,
    RK4 d-mode estimates and the size of the last Newton step (inf-norm)."""
    y = y.copy()
    N = len(y)
    active = np.ones(N, bool)
    last = np.full(N, np.inf)
    for it in range(n_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        r, J, _ = ts.eval(y[idx], n_steps)
        rn = np.max(np.abs(r), axis=1)
        done = rn < tol
        # give up on starts that are clearly not converging (saves most of the work)
        hopeless = ((it >= 8) & (rn > 1e-2)) | ((it >= 14) & (rn > 1e-5))
        active[idx[hopeless]] = False
        keep = ~hopeless
        idx, r, J, rn, done = idx[keep], r[keep], J[keep], rn[keep], done[keep]
        if idx.size == 0:
            break
        step = -_solve(J, r)
        bad = ~np.all(np.isfinite(step), axis=1)
        step[bad] = 0.0
        lam = np.abs(y[idx, 0:9:3])
        lim = np.max(np.abs(step[:, 0:9:3]) / (0.3 * lam + 0.5), axis=1)
        lim = np.maximum(lim, np.max(np.abs(step[:, 1:9:3]), axis=1) / 1.0)
        lim = np.maximum(lim, np.max(np.abs(step[:, 2:9:3]), axis=1) / 0.5)
        lim = np.maximum(lim, np.max(np.abs(step[:, 9:11]) / 0.1, axis=1))  # 0.1 L_ref
        lim = np.maximum(lim, np.abs(step[:, 11]) / 0.3)  # 0.3 rad
        fac = 1.0 / np.maximum(lim, 1.0)
        step *= fac[:, None]
        upd = ~done & ~bad
        y[idx[upd]] += step[upd]
        last[idx] = np.where(done, 0.0, np.max(np.abs(step), axis=1))
        blown = (np.max(lam, axis=1) > lam_blow) | (np.max(np.abs(y[idx, 1:9:3]), axis=1) > 18.0)
        active[idx[done | bad | blown]] = False
    y[:, 0:9:3] = np.abs(y[:, 0:9:3])
    r, ch = ts.eval(y, n_steps, jac=False)
    return y, np.max(np.abs(r), axis=1), ch + 1, last


def tip_polish(ts: TipSystem, Y, n_fast=4, n_tight=4, tol=1e-13):
    """Polish converged candidates: ``n_fast`` Newton iterations on the fast residual
    (:meth:`TipSystem.plain`) with the 800-step RK4 Jacobian, then ``n_tight`` Newton iterations on
    the tight residual (:meth:`TipSystem.tight`) with its Jacobian (:meth:`TipSystem.tight_jacobian`)
    for the candidates whose tight residual is above ``tol``.  Returns the best iterate and its
    tight residual."""
    Y = np.atleast_2d(Y).copy()
    active = np.ones(len(Y), bool)
    for _ in range(n_fast):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        r = ts.plain(Y[idx])
        go = np.max(np.abs(r), axis=1) >= tol
        active[idx[~go]] = False
        idx, r = idx[go], r[go]
        if idx.size == 0:
            break
        step = _solve(ts.eval(Y[idx], n_steps=800)[1], r)
        fin = np.all(np.isfinite(step), axis=1)
        Y[idx[fin]] -= step[fin]
        active[idx[~fin]] = False
    r = ts.tight(Y)[0]
    best_r = np.max(np.abs(r), axis=1)
    best_y = Y.copy()
    idx = np.flatnonzero(best_r > tol)
    Z, rz = Y[idx].copy(), r[idx]
    for _ in range(n_tight):
        if not idx.size:
            break
        step = _solve(ts.tight_jacobian(Z, rz), rz)
        fin = np.all(np.isfinite(step), axis=1)
        Z[fin] -= step[fin]
        rz = ts.tight(Z)[0]
        rn = np.max(np.abs(rz), axis=1)
        better = rn < best_r[idx]
        best_r[idx[better]] = rn[better]
        best_y[idx[better]] = Z[better]
        go = (rn >= tol) & fin
        idx, Z, rz = idx[go], Z[go], rz[go]
    return best_y, best_r


# ======================================================================================
# solutions
# ======================================================================================
def _kprime_of_t(t):
    """k' = |sin(v/2)| with v = 2 pi expit(2 t), without cancellation at either end (v -> 0, 2 pi)."""
    t = np.asarray(t, float)
    return np.sin(np.pi * np.minimum(expit(2.0 * t), expit(-2.0 * t)))


@dataclass(frozen=True)
class FKOracleRod:
    tip_force: np.ndarray  # (2,) on the rod tip, world (N)
    base_moment: float  # EI theta'(0) (N m)
    tip_angle: float  # theta_L, world (rad)
    clamp: np.ndarray
    clamp_angle: float
    length: float
    EI: float
    mode: int  # 1 + inflection points strictly inside the rod (verify_fk)
    mode_ambiguous: bool  # the clamp is (nearly) at an inflection point: boundary case of the count
    kprime: float  # k' = |sin((theta_L - psi) / 2)|, from the chart without cancellation (clamped: see fk_clamped)
    R_dimless: float  # R L^2/EI
    tip_moment: float = 0.0  # m(L), the moment ON the rod tip BY the platform (N m); 0 for a pinned tip
    turning: float = float("nan")  # theta(L) - theta(0) (rad), continuous
    joint: str = "pinned"
    k_value: float = float("nan")  # clamped rods: k from the first integral (> 1: non-inflectional)

    @property
    def k(self) -> float:
        """|k| = |cos((theta_L - psi) / 2)| (pinned); the first-integral k of a clamped rod."""
        if np.isfinite(self.k_value):
            return float(self.k_value)
        return float(np.sqrt(max(0.0, 1.0 - self.kprime**2)))

    @property
    def extreme(self) -> bool:
        return bool(self.kprime < EXTREME_KPRIME)


@dataclass(frozen=True)
class FKOracleSolution:
    pose: np.ndarray  # (x, y, theta) m, m, rad; theta in (-pi, pi]
    inputs: np.ndarray
    rods: tuple[FKOracleRod, FKOracleRod, FKOracleRod]
    residual: float  # verify_fk "tip_shot" (scaled inf-norm of the 12 equations)
    check: dict = field(repr=False)  # the full verify_fk dict
    y: np.ndarray = field(repr=False)  # chart unknowns

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
    def min_kprime(self) -> float:
        return float(min(r.kprime for r in self.rods))

    @property
    def extreme(self) -> bool:
        return any(r.extreme for r in self.rods)


def _wrap(th):
    return np.angle(np.exp(1j * np.asarray(th, float)))


# ======================================================================================
# verification of a solution (oracle's own or a flexkin solution): the 12 equations
# ======================================================================================
def verify_fk(mech, inputs, load, poses, forces, tip_angles, base_moments=None, tip_moments=None):
    """Check candidate FK solutions on the 12 equations with a tight integration (DOP853, rtol =
    atol = 1e-13, batched, dimensionless).

    Inputs (SI, rad for revolute legs) and the load are shared; per solution: ``poses`` (N, 3),
    ``forces`` (N, 3, 2) (force ON each rod tip BY the platform), ``tip_angles`` (N, 3) world tip
    tangents, optionally the reported ``base_moments`` (N, 3).  The clamps are rebuilt from the
    inputs by SPEC §2 (``ik_oracle.Geom``) and ``B_i = P + Rot(theta) b_i``.

    Each rod is integrated from its pinned tip at ``B_i`` (tangent ``theta_L``, zero moment: these
    two equations hold by construction) back to its clamp by :func:`shoot_from_tip` (well
    conditioned also for rods near the separatrix).  Returns one dict per solution:

    * ``clamp_error``: max |arrival - A_i| / L_ref; ``clamp_angle_error``: max |theta(0) - alpha_i|
      (rad, mod 2 pi) -- together the "tip at B_i with zero moment" equations of the rods;
    * ``eq_force`` = |sum n_i - F| / F_ref, ``eq_moment`` = |sum (B_i - P) x n_i - M| / (F_ref L_ref);
    * ``tip_shot``: the max of the four above (the scaled inf-norm of the 12 equations);
    * ``plain_shot``: the same with every rod integrated in one piece (cross-check; ill-conditioned
      like 1/k'^2 for d-mode >= 2 rods near the separatrix);
    * ``base_moment_error``: max |m0 (integrated) - m0 (reported)| L/EI (NaN if not reported);
    * ``forward_tip_error`` (/ L_ref) and ``forward_tip_moment`` (L/EI): the equations shot the other
      way, from the clamp with the reported (else the integrated) base moment; ill-conditioned like
      1/k'^2 for taut rods, so only meaningful where ``kprime`` is not small;
    * ``modes`` (1 + inflection points strictly inside each rod), ``mode_ambiguous`` (the clamp is
      within 1e-7 half-wave of an inflection point), ``kprime`` (per rod), ``base_moments`` (N m);
    * ``verified``: ``tip_shot <= VERIFY_TOL``.

    (A solution given by tip angles and forces in double precision defines ``v = theta_L - psi``
    only to ~1e-15 absolutely, i.e. to ~1e-15 / k' relatively near the separatrix; the residual
    inherits that floor, which stays below VERIFY_TOL for in-scope rods, k' >= 5e-7.)

    Mechanisms with CLAMPED legs (tip tangent theta_P + tip_angle, tip moment ``m(L)`` applied ON
    the rod BY the platform): see :func:`_verify_mixed`; ``base_moments`` are then required and
    ``tip_moments`` (N, 3) are used when given (else derived by integrating from the clamp).
    """
    g = Geom.of(mech)
    if g.any_clamped:
        return _verify_mixed(g, inputs, load, poses, forces, tip_angles, base_moments, tip_moments)
    sys = FKSystem(g, inputs, np.asarray(load, float).reshape(3))
    poses = np.asarray(poses, float).reshape(-1, 3)
    N = len(poses)
    if N == 0:
        return []
    y = chart_y(sys, np.asarray(forces, float).reshape(N, 3, 2), np.asarray(tip_angles, float).reshape(N, 3), poses)
    return _verify_chart(sys, y, base_moments)


def _verify_chart(sys: FKSystem, y, base_moments=None):
    """:func:`verify_fk` on chart unknowns ``y`` (N, 12) (the oracle's own solutions are checked
    here directly, without the round trip through tip angles in double precision)."""
    g = sys.g
    ts = TipSystem(sys)
    y = np.atleast_2d(y)
    N = len(y)
    n, poses, *_ = ts.rods(y)
    forces = n
    r, Z, modes, bnd = ts.tight(y)
    rp = ts.plain(y)
    m0 = -Z[3] * g.EI[None] / sys.L[None]  # reversed rod: m~ = -m
    m0_rep = None if base_moments is None else np.asarray(base_moments, float).reshape(N, 3)
    fr = sys.tight_residual(sys.to_z(forces, m0 if m0_rep is None else m0_rep, poses))
    out = []
    for j in range(N):
        rr = r[j, :9].reshape(3, 3)
        d = {
            "clamp_error": float(np.max(np.abs(rr[:, :2]))),
            "clamp_angle_error": float(np.max(np.abs(rr[:, 2]))),
            "eq_force": float(np.max(np.abs(r[j, 9:11]))),
            "eq_moment": float(abs(r[j, 11])),
            "plain_shot": float(np.max(np.abs(rp[j]))),
            "base_moment_error": (float("nan") if m0_rep is None else
                                  float(np.max(np.abs(m0[j] - m0_rep[j]) * sys.L / g.EI))),
            "forward_tip_error": float(np.max(np.abs(fr[j, :9].reshape(3, 3)[:, :2]))),
            "forward_tip_moment": float(np.max(np.abs(fr[j, :9].reshape(3, 3)[:, 2]))),
            "modes": tuple(int(q) for q in modes[j]),
            "mode_ambiguous": tuple(bool(b) for b in bnd[j]),
            "kprime": tuple(float(k) for k in _kprime_of_t(y[j, 1:9:3])),
            "base_moments": tuple(float(v) for v in m0[j]),
        }
        d["tip_shot"] = max(d["clamp_error"], d["clamp_angle_error"], d["eq_force"], d["eq_moment"])
        d["verified"] = bool(d["tip_shot"] <= VERIFY_TOL)
        out.append(d)
    return out


def verify_solutions(mech, inputs, load, sols):
    """:func:`verify_fk` for solution objects with ``pose`` and ``rods`` (each rod with
    ``tip_force``, ``tip_angle`` and ``base_moment``; for clamped legs ``tip_moment`` is used when
    the rods report it), e.g. flexkin's."""
    sols = list(sols)
    if not sols:
        return []
    tm = None
    if Geom.of(mech).any_clamped and all(getattr(r, "tip_moment", None) is not None for s in sols for r in s.rods):
        tm = [[r.tip_moment for r in s.rods] for s in sols]
    return verify_fk(mech, inputs, load, [s.pose for s in sols],
                     [[r.tip_force for r in s.rods] for s in sols],
                     [[r.tip_angle for r in s.rods] for s in sols],
                     [[r.base_moment for r in s.rods] for s in sols], tip_moments=tm)


def _verify_mixed(g: Geom, inputs, load, poses, forces, tip_angles, base_moments, tip_moments=None, n_eval=1001):
    """:func:`verify_fk` for mechanisms with clamped legs.

    Pinned rods: as in :func:`verify_fk` (shot from the pinned tip by :func:`shoot_from_tip`).
    Clamped rods (need the reported base moment m0; the tip moment m(L) is the reported one, else
    the one integrated from the clamp): shot from BOTH ends -- from the clamp with (n, m0) and from
    the tip at B_i with the reported tip tangent and m(L) -- each over half the rod by DOP853 (rtol
    1e-13); the mismatch at mid-length enters ``clamp_error`` (position / L_ref),
    ``clamp_angle_error`` (mod 2 pi) and ``moment_mismatch`` (in units of the rod's moment scale
    (1 + sqrt(R L^2/EI)) EI/L, the first-integral bound of its moment).  Two-sided shooting stays well
    conditioned for taut rods (one-sided shooting amplifies errors like exp(Lambda)).  Also
    ``tip_angle_error`` = max |wrap(theta_L - theta_P - tip_angle)| over clamped rods (their tip
    condition).  The moment balance is ``sum (B_i - P) x n_i + sum_clamped m_i(L) = M_z``.
    ``tip_shot`` is the max of these and the equilibrium errors; ``plain_shot`` the same equations
    shot in one piece from the clamps (ill-conditioned for taut rods); per rod ``modes`` (1 + sign
    changes of the moment strictly inside), ``mode_ambiguous``, ``kprime`` (clamped: from the first
    integral, k' = sqrt|1 - k^2| for k <= 1, sqrt(1 - 1/k^2) beyond), ``base_moments``,
    ``tip_moments``, ``turnings``."""
    from ik_oracle import _mode_ambiguous, count_inflections, elastica_k

    sys = FKSystem(g, inputs, np.asarray(load, float).reshape(3))
    poses = np.asarray(poses, float).reshape(-1, 3)
    N = len(poses)
    if N == 0:
        return []
    f = np.asarray(forces, float).reshape(N, 3, 2)
    ta = np.asarray(tip_angles, float).reshape(N, 3)
    cl = g.clamped
    if base_moments is None and np.any(cl):
        raise ValueError("verify_fk: base moments are required for clamped legs")
    m0 = np.zeros((N, 3)) if base_moments is None else np.asarray(base_moments, float).reshape(N, 3)
    EI, L = g.EI[None], sys.L[None]
    ax, ay = f[..., 0] * L**2 / EI, f[..., 1] * L**2 / EI
    mt = m0 * L / EI
    al = np.broadcast_to(sys.al[None], (N, 3))
    Bp, arm = sys.platform_points(poses)
    # one-piece forward shots (plain; also the tip moments if not reported)
    yp = integrate_batch(ax, ay, mt, al, n_eval=2).reshape(4, N, 3, 2)[..., -1]
    mL = yp[3] * EI / L if tip_moments is None else np.asarray(tip_moments, float).reshape(N, 3)
    mL = np.where(cl[None], mL, 0.0)
    clamp_err = np.zeros((N, 3)); ang_err = np.zeros((N, 3)); mom_mis = np.zeros((N, 3))
    tip_ang = np.zeros((N, 3))
    modes = np.ones((N, 3), np.int64); amb = np.zeros((N, 3), bool); kprime = np.ones((N, 3))
    m0_out = m0.copy(); turn = np.zeros((N, 3))
    pin = np.flatnonzero(~cl)
    if len(pin):
        y = chart_y(sys, f, ta, poses)
        lam, t, psi = y[:, 3 * pin], y[:, 3 * pin + 1], y[:, 3 * pin + 2]
        Z, n_in, bnd = shoot_from_tip(lam, t, psi)
        Z = Z.reshape(4, N, len(pin))
        clamp = Bp[:, pin] + sys.L[None, pin, None] * np.stack([Z[0], Z[1]], -1)
        clamp_err[:, pin] = np.max(np.abs(clamp - sys.A[None, pin]), axis=-1) / g.L_ref
        ang_err[:, pin] = np.abs(_wrap(Z[2] - np.pi - sys.al[None, pin]))
        modes[:, pin] = 1 + n_in.reshape(N, len(pin))
        amb[:, pin] = bnd.reshape(N, len(pin))
        kprime[:, pin] = _kprime_of_t(t)
        m0_out[:, pin] = -Z[3] * g.EI[None, pin] / sys.L[None, pin]
        turn[:, pin] = ta[:, pin] - sys.al[None, pin]
    for i in np.flatnonzero(cl):
        Li, EIi = sys.L[i], g.EI[i]
        yf = integrate_batch(ax[:, i] / 4, ay[:, i] / 4, mt[:, i] / 2, al[:, i], n_eval=n_eval)
        yb = integrate_batch(-ax[:, i] / 4, -ay[:, i] / 4, -mL[:, i] * Li / EIi / 2, ta[:, i] + np.pi, n_eval=n_eval)
        pf = sys.A[i][None] + 0.5 * Li * yf[:2, :, -1].T
        pb = Bp[:, i] + 0.5 * Li * yb[:2, :, -1].T
        clamp_err[:, i] = np.max(np.abs(pf - pb), axis=1) / g.L_ref
        ang_err[:, i] = np.abs(_wrap(yf[2, :, -1] - (yb[2, :, -1] - np.pi)))
        # (moment mismatch in units of the rod's moment scale (1 + sqrt(R L^2/EI)) EI/L)
        mom_mis[:, i] = np.abs(2 * yf[3, :, -1] + 2 * yb[3, :, -1]) / (1.0 + np.hypot(ax[:, i], ay[:, i]) ** 0.5)
        tip_ang[:, i] = np.abs(_wrap(ta[:, i] - poses[:, 2] - g.tip_angle[i]))
        turn[:, i] = (yf[2, :, -1] - al[:, i]) + (ta[:, i] - (yb[2, :, -1] - np.pi))
        ms_f = yf[3] * 2 * EIi / Li  # (N, n_eval) physical moments, clamp -> mid
        ms_b = (-yb[3] * 2 * EIi / Li)[:, ::-1]  # mid -> tip
        for j in range(N):
            ms = np.concatenate([ms_f[j], ms_b[j, 1:]])
            modes[j, i] = count_inflections(ms)
            amb[j, i] = _mode_ambiguous(ms, clamped=True)
            kk = elastica_k(ax[j, i], ay[j, i], ta[j, i], mL[j, i] * Li / EIi)
            kprime[j, i] = np.sqrt(abs(1 - kk * kk)) if kk <= 1 else np.sqrt(1 - 1 / (kk * kk))
    # equilibrium
    Fsum = f.sum(axis=1) - sys.load[None, :2]
    Msum = np.sum(arm[..., 0] * f[..., 1] - arm[..., 1] * f[..., 0], axis=1) + mL.sum(axis=1) - sys.load[2]
    eqf = np.max(np.abs(Fsum), axis=1) / g.F_ref
    eqm = np.abs(Msum) / (g.F_ref * g.L_ref)
    # plain one-piece shots from the clamps
    tipp = sys.A[None] + sys.L[None, :, None] * np.stack([yp[0], yp[1]], -1)
    tip_err_p = np.max(np.abs(tipp - Bp), axis=-1) / g.L_ref
    cond_p = np.where(cl[None], np.abs(_wrap(yp[2] - poses[:, 2:3] - g.tip_angle[None])), np.abs(yp[3]))
    Mp = np.sum(arm[..., 0] * f[..., 1] - arm[..., 1] * f[..., 0], axis=1) + np.sum(
        np.where(cl[None], yp[3] * EI / L, 0.0), axis=1) - sys.load[2]
    out = []
    for j in range(N):
        d = {
            "clamp_error": float(np.max(clamp_err[j])),
            "clamp_angle_error": float(np.max(ang_err[j])),
            "moment_mismatch": float(np.max(mom_mis[j])),
            "tip_angle_error": float(np.max(tip_ang[j])),
            "eq_force": float(eqf[j]),
            "eq_moment": float(eqm[j]),
            "plain_shot": float(max(np.max(tip_err_p[j]), np.max(cond_p[j]), eqf[j],
                                    abs(Mp[j]) / (g.F_ref * g.L_ref))),
            "base_moment_error": (float(np.max(np.where(cl, 0.0, np.abs(m0_out[j] - m0[j]) * sys.L / g.EI)))
                                  if base_moments is not None else float("nan")),
            "forward_tip_error": float(np.max(tip_err_p[j])),
            "forward_tip_moment": float(np.max(np.where(cl, 0.0, np.abs(yp[3, j])))),
            "modes": tuple(int(q) for q in modes[j]),
            "mode_ambiguous": tuple(bool(b) for b in amb[j]),
            "kprime": tuple(float(k) for k in kprime[j]),
            "base_moments": tuple(float(v) for v in m0_out[j]),
            "tip_moments": tuple(float(v) for v in mL[j]),
            "turnings": tuple(float(v) for v in turn[j]),
        }
        d["tip_shot"] = max(d["clamp_error"], d["clamp_angle_error"], d["moment_mismatch"], d["tip_angle_error"],
                            d["eq_force"], d["eq_moment"])
        d["verified"] = bool(d["tip_shot"] <= VERIFY_TOL)
        out.append(d)
    return out


def _build(sys: FKSystem, ts: TipSystem, Y) -> list[FKOracleSolution]:
    """Solutions from polished chart unknowns, each checked by :func:`_verify_chart` (residual of
    the 12 equations, d-modes, base moments)."""
    Y = np.atleast_2d(Y)
    N = len(Y)
    if N == 0:
        return []
    f, g = sys, sys.g
    n, pose, *_ = ts.rods(Y)
    tip_angles = Y[:, 2:9:3] + _v_of_t(Y[:, 1:9:3])
    checks = _verify_chart(sys, Y)
    out = []
    for j in range(N):
        c = checks[j]
        rods = []
        for i in range(3):
            rods.append(FKOracleRod(tip_force=n[j, i].copy(), base_moment=c["base_moments"][i],
                                    tip_angle=float(tip_angles[j, i]), clamp=f.A[i].copy(),
                                    clamp_angle=float(f.al[i]), length=float(f.L[i]), EI=float(g.EI[i]),
                                    mode=c["modes"][i], mode_ambiguous=c["mode_ambiguous"][i],
                                    kprime=c["kprime"][i], R_dimless=float(Y[j, 3 * i] ** 2)))
        p = pose[j].copy()
        p[2] = float(_wrap(p[2]))
        out.append(FKOracleSolution(pose=p, inputs=f.inputs.copy(), rods=tuple(rods), residual=c["tip_shot"],
                                    check=c, y=Y[j].copy()))
    return out


def _key(y):
    """Identity of a solution: dimensionless forces R L^2/EI (cartesian), tanh t and the pose
    (theta wrapped)."""
    y = np.atleast_2d(np.array(y, float))
    lam, t, psi = y[:, 0:9:3], y[:, 1:9:3], y[:, 2:9:3]
    R = lam * lam
    return np.column_stack([R * np.cos(psi), R * np.sin(psi), np.tanh(t), y[:, 9:11], _wrap(y[:, 11])])


# ======================================================================================
# pose sampling in the reach region
# ======================================================================================
def _in_reach(sys: FKSystem, pose, slack=1.0):
    B, _ = sys.platform_points(pose)
    d = np.hypot(*np.moveaxis(B - sys.A[None], -1, 0))
    return np.all(d <= slack * sys.L[None], axis=1)


def _reach_box(sys: FKSystem, th):
    """Bounding box of the intersection of the discs |P + Rot(th) b_i - A_i| <= L_i (per theta)."""
    b = sys.g.attach
    c, s = np.cos(th), np.sin(th)
    lo = np.full((len(th), 2), -np.inf)
    hi = np.full((len(th), 2), np.inf)
    for i in range(3):
        cx = sys.A[i, 0] - (c * b[i, 0] - s * b[i, 1])
        cy = sys.A[i, 1] - (s * b[i, 0] + c * b[i, 1])
        lo = np.maximum(lo, np.stack([cx - sys.L[i], cy - sys.L[i]], -1))
        hi = np.minimum(hi, np.stack([cx + sys.L[i], cy + sys.L[i]], -1))
    return lo, hi


def sample_poses(sys: FKSystem, n, rng):
    """``n`` poses uniform in the reach region (theta uniform), by rejection."""
    out = []
    got = 0
    for _ in range(200):
        m = max(4 * (n - got), 1000)
        th = rng.uniform(-np.pi, np.pi, m)
        lo, hi = _reach_box(sys, th)
        ok = np.all(hi > lo, axis=1)
        th, lo, hi = th[ok], lo[ok], hi[ok]
        P = lo + (hi - lo) * rng.uniform(size=(len(th), 2))
        pose = np.column_stack([P, th])
        # uniform in the region for each theta would weight theta by its box area; accept with
        # probability box_area / max_box_area so that the pose density is uniform in (x, y, theta)
        area = np.prod(hi - lo, axis=1)
        keep = _in_reach(sys, pose) & (rng.uniform(size=len(th)) <= area / max(area.max(), 1e-300))
        out.append(pose[keep])
        got += int(np.count_nonzero(keep))
        if got >= n:
            break
    P = np.concatenate(out) if out else np.zeros((0, 3))
    return P[:n]


def pose_grid(sys: FKSystem, h_xy, n_theta, rng, jitter=True):
    """A jittered grid of poses in the reach region: spacing ``h_xy * L_ref`` in x, y and
    ``2 pi / n_theta`` in theta.  Returns poses (M, 3)."""
    g = sys.g
    h = h_xy * g.L_ref
    ht = 2 * np.pi / n_theta
    th = -np.pi + ht * (np.arange(n_theta) + (rng.uniform() if jitter else 0.5))
    lo, hi = _reach_box(sys, th)
    out = []
    off = rng.uniform(size=2) if jitter else np.full(2, 0.5)
    for j in range(n_theta):
        if np.any(hi[j] <= lo[j]):
            continue
        xs = np.arange(np.floor(lo[j, 0] / h), np.ceil(hi[j, 0] / h) + 1) * h + off[0] * h
        ys = np.arange(np.floor(lo[j, 1] / h), np.ceil(hi[j, 1] / h) + 1) * h + off[1] * h
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        pose = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, th[j])])
        out.append(pose[_in_reach(sys, pose)])
    return np.concatenate(out) if out else np.zeros((0, 3))


# ======================================================================================
# family 1: random starts (uniform poses in the reach region, random rods pinned at B_i)
# ======================================================================================
def random_chart_starts(sys: FKSystem, sheets, n, rng):
    """``n`` textbook multi-start points: a pose uniform in the reach region (theta uniform) and,
    for every rod, one of the rods of its sheet pinned at ``B_i`` chosen uniformly at random
    (tip-anchored seeding: every rod of the start already has its tip at ``B_i`` and zero tip
    moment, up to the chart interpolation; only the platform equilibrium is off)."""
    out = []
    got = 0
    for _ in range(20):
        pose = sample_poses(sys, 2 * (n - got) + 100, rng)
        B, _ = sys.platform_points(pose)
        M = len(pose)
        picks = []
        ok = np.ones(M, bool)
        for i in range(3):
            qi, tr, a, b = sheets[i].locate(B[:, i])
            cnt = np.bincount(qi, minlength=M)
            ok &= cnt > 0
            first = np.cumsum(cnt) - cnt
            order = np.argsort(qi, kind="stable")
            choice = first + np.floor(rng.uniform(size=M) * np.maximum(cnt, 1)).astype(np.int64)
            choice = np.minimum(choice, max(len(qi) - 1, 0))
            picks.append((order, tr, a, b, choice))
        idx = np.flatnonzero(ok)
        if len(idx):
            y = np.empty((len(idx), 12))
            for i, (order, tr, a, b, choice) in enumerate(picks):
                j = order[choice[idx]]
                _, cc, _, _ = sheets[i].affine(tr[j], a[j], b[j])
                y[:, 3 * i:3 * i + 3] = cc
            y[:, 9:12] = pose[idx] / sys.ps
            out.append(y)
            got += len(idx)
        if got >= n:
            break
    Y = np.concatenate(out) if out else np.zeros((0, 12))
    return Y[:n]


# ======================================================================================
# family 1b: random starts of ik_oracle's kind (random forces and base moments, projected)
# ======================================================================================
def random_forward_starts(sys: FKSystem, n, rng, R_range=(0.05, 300.0)):
    """``n`` random starts as in ``ik_oracle``: a pose uniform in the reach region, per rod a
    dimensionless force ``R L^2/EI`` log-uniform in ``R_range``, a uniform direction and a base
    moment ``m0 L/EI`` uniform within the first-integral bound ``+-2 sqrt(R L^2/EI)``; each rod is
    then Newton-projected (pose frozen, shooting from the clamp) onto "tip at B_i, zero tip
    moment".  Returns the chart unknowns of the starts whose three rods converged.  (Shooting from
    the clamp is well-conditioned for lightly loaded, nearly straight rods, where the chart of
    the tip-anchored family is most nonlinear.)"""
    g = sys.g
    pose = sample_poses(sys, n, rng)
    n = len(pose)
    p = np.empty((n, 3, 3))  # dimensionless (ax, ay, mt)
    for i in range(3):
        Rd = np.exp(rng.uniform(np.log(R_range[0]), np.log(R_range[1]), n))
        ang = rng.uniform(0.0, 2 * np.pi, n)
        p[:, i, 0] = Rd * np.cos(ang)
        p[:, i, 1] = Rd * np.sin(ang)
        p[:, i, 2] = 2.0 * np.sqrt(Rd) * rng.uniform(-1.0, 1.0, n)
    p = p.reshape(-1, 3)
    th0 = np.broadcast_to(sys.al[None], (n, 3)).ravel()
    B, _ = sys.platform_points(pose)
    tgt = ((B - sys.A[None]) / sys.L[None, :, None]).reshape(-1, 2)
    ok = np.zeros(len(p), bool)
    active = np.ones(len(p), bool)
    n_iter, n_steps = 15, 64
    for it in range(n_iter + 1):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        Z, S, _ = _rk4_unit(p[idx, 0], p[idx, 1], p[idx, 2], th0[idx], n_steps)
        r = np.stack([Z[0] - tgt[idx, 0], Z[1] - tgt[idx, 1], Z[3]], 1)
        done = np.max(np.abs(r), axis=1) < 1e-8
        ok[idx[done]] = True
        if it == n_iter:
            break
        J = np.moveaxis(np.stack([S[0:3, 0], S[0:3, 1], S[0:3, 3]], 1), -1, 0).transpose(0, 2, 1)
        with np.errstate(all="ignore"):
            det = np.linalg.det(J)
            good = np.isfinite(det) & (np.abs(det) > 1e-14)
        step = np.zeros_like(r)
        if np.any(good):
            step[good] = -np.linalg.solve(J[good], r[good][..., None])[..., 0]
        Rd = np.hypot(p[idx, 0], p[idx, 1])
        lim = np.maximum(np.hypot(step[:, 0], step[:, 1]) / (0.5 * Rd + 3.0),
                         np.abs(step[:, 2]) / (0.5 * np.sqrt(Rd) + 1.0))
        step *= (1.0 / np.maximum(lim, 1.0))[:, None]
        upd = ~done & good
        p[idx[upd]] += step[upd]
        active[idx[done | ~good | (Rd > 3e3)]] = False
    Z, _, _ = _rk4_unit(p[:, 0], p[:, 1], p[:, 2], th0, n_steps)
    keep = ok.reshape(n, 3).all(axis=1)
    EI, L = g.EI[None], sys.L[None]
    pr = p.reshape(n, 3, 3)
    forces = np.stack([pr[..., 0], pr[..., 1]], -1) * (EI / L**2)[..., None]
    y = chart_y(sys, forces, Z[2].reshape(n, 3), pose)
    return y[keep]


# ======================================================================================
# family 2: pose grid x triangulated tip-anchored chart of every rod
# ======================================================================================
_SCAN: dict = {}


def _chart_modes(lam, t):
    """d-mode of the unit rods of the chart, without integration: from the pinned tip (a turning
    point of the pendulum ``phi'' = Lambda^2 sin phi``, moment zero) the moment vanishes again every
    half-period ``2 K(k) / Lambda`` of arc length (``k = |cos(v/2)|``), so the number of zeros
    strictly inside the unit rod is ``ceil(Lambda / 2K) - 1`` and the d-mode ``ceil(Lambda / 2K)``.
    Used only to label the scan (seeding); every solution's d-mode is counted on its tight
    integration."""
    from scipy.special import ellipkm1

    kp = _kprime_of_t(t)
    K = ellipkm1(kp * kp)  # K(m) at m = k^2 = 1 - k'^2, accurate for k' -> 0
    return np.maximum(np.ceil(lam / (2.0 * K)), 1).astype(np.int64)


def _chart_points(lam, t, n_steps=256):
    """Unit clamped-pinned rods of chart points (Lambda, t), integrated from the pinned tip (force
    along +x), in the clamp frame: returns tip (M, 2), psi (force direction), w0 (dimensionless base
    moment).

    Same symmetries as :func:`shoot_from_tip` (force frame, angle ``phi`` relative to the force):
    every half-wave between inflection points advances ``x`` by the same ``2 x_c`` (``x_c`` at the
    quarter period ``Q = K / Lambda``) and is the mirror image (``y, phi, m -> -y, -phi, -m``) of
    the previous one, and the second half of a half-wave is the reflection of its first half across
    ``x = x_c``.  So the whole rod follows from two integrations that only move *away* from the
    saddle (well conditioned): from the tip to ``Q`` and to the matching point of the last partial
    half-wave, by fixed-step RK4 (``n_steps``, i.e. ``h Lambda <= K / n_steps``) in double
    precision -- ample for seeding.
    """
    from scipy.special import ellipkm1

    lam = np.asarray(lam, float).ravel()
    t = np.asarray(t, float).ravel()
    small = expit(-2.0 * np.abs(t))
    phi0 = np.where(t <= 0, 2 * np.pi * small, -2 * np.pi * small)  # v in (-pi, pi]
    K = ellipkm1(np.sin(np.pi * small) ** 2)
    Q = K / lam
    H = 2 * Q
    n = np.floor(1.0 / H)
    rem = 1.0 - n * H
    second = rem > Q  # the end lies in the second half of its half-wave: reflect
    tau = np.where(second, H - rem, rem)
    a = lam * lam

    def depart(D):
        """RK4 from (0, 0, phi0, 0) over arc lengths D (force frame, m' = Lambda^2 sin phi)."""
        z = np.stack([np.zeros_like(lam), np.zeros_like(lam), phi0, np.zeros_like(lam)])
        h = D / n_steps

        def f(z):
            return np.stack([np.cos(z[2]), np.sin(z[2]), z[3], a * np.sin(z[2])])

        for _ in range(n_steps):
            z = rk4_step(f, z, h)
        return z

    zc = depart(np.where(second | (n > 0), Q, 0.0))
    zs = depart(tau)
    xc = zc[0]
    phic = np.pi * np.sign(phi0)
    x = np.where(second, 2 * xc - zs[0], zs[0])
    y = zs[1]
    phi = np.where(second, 2 * phic - zs[2], zs[2])
    m = zs[3]
    sgn = np.where(n % 2 == 1, -1.0, 1.0)  # mirror for odd numbers of full half-waves
    x = n * 2 * xc + x
    y, phi, m = sgn * y, sgn * phi, sgn * m
    # reversed rod (force along -x, i.e. the rod's own tip force along +x): the clamp end has the
    # tangent phi + pi and the moment m; the rod's clamp angle is phi, its base moment -m
    c, s_ = np.cos(-phi), np.sin(-phi)
    tip = np.stack([c * x - s_ * y, s_ * x + c * y], -1)
    return tip, -phi, -m


def chart_scan(lam_max=40.0, n_lam=320, n_t=480, n_steps=256, mode_cap=4):
    """Unit clamped-pinned rods on a (Lambda, t) grid of the tip-anchored chart (cached).

    Returns lam (n_lam,), t (n_t,), tip (n_lam, n_t, 2) in the clamp frame (clamp tangent = x),
    psi (force direction in the clamp frame), w0 (dimensionless base moment), d-mode (exact, from
    :func:`_chart_modes`).  Lambda is spaced uniformly in sqrt(Lambda), t uniformly in [-8, 8]
    (k' down to ~1e-7).  Points of d-mode <= ``mode_cap`` are integrated (:func:`_chart_points`),
    the others are NaN.
    """
    key = (lam_max, n_lam, n_t, n_steps, mode_cap)
    if key not in _SCAN:
        lam = np.linspace(np.sqrt(1e-3), np.sqrt(lam_max), n_lam) ** 2
        t = np.linspace(-8.0, 8.0, n_t)
        tip = np.full((n_lam, n_t, 2), np.nan)
        psi = np.full((n_lam, n_t), np.nan)
        w0 = np.full((n_lam, n_t), np.nan)
        LL, TT = np.meshgrid(lam, t, indexing="ij")
        mode = _chart_modes(LL, TT)
        todo = np.flatnonzero((mode <= mode_cap).ravel())
        tp, ps, w = _chart_points(LL.ravel()[todo], TT.ravel()[todo], n_steps)
        tip.reshape(-1, 2)[todo] = tp
        psi.reshape(-1)[todo] = ps
        w0.reshape(-1)[todo] = w
        _SCAN[key] = (lam, t, tip, psi, w0, mode)
    return _SCAN[key]


class _Sheet:
    """Rod i's chart scan placed at its (fixed) clamp: triangles of (tip, force, tip angle)
    in the world, bucketed for point location (a hierarchy of bucket sizes ``bucket * ratio^l`` so
    that large triangles occupy few buckets)."""

    def __init__(self, sys: FKSystem, i: int, scan, max_mode: int, bucket: float, cap: int = 16,
                 n_levels: int = 8, ratio: float = 2.0):
        g = sys.g
        lam, t, tip, psi, _w0, mode = scan
        self.W0 = np.asarray(_w0, float).ravel()  # dimensionless base moment per vertex (seeding only)
        L, EI, al, A = sys.L[i], g.EI[i], sys.al[i], sys.A[i]
        c, s = np.cos(al), np.sin(al)
        P = A + L * np.stack([c * tip[..., 0] - s * tip[..., 1], s * tip[..., 0] + c * tip[..., 1]], -1)
        R = (lam**2)[:, None] * EI / L**2
        F = np.stack([R * np.cos(psi + al), R * np.sin(psi + al)], -1)
        C = np.stack([np.broadcast_to(lam[:, None], mode.shape), np.broadcast_to(t[None, :], mode.shape),
                      psi + al], -1)  # chart unknowns (Lambda, t, world force direction)
        nl, nt = mode.shape
        a, b = np.meshgrid(np.arange(nl - 1), np.arange(nt - 1), indexing="ij")
        a, b = a.ravel(), b.ravel()
        v00 = a * nt + b
        v10 = (a + 1) * nt + b
        v11 = (a + 1) * nt + b + 1
        v01 = a * nt + b + 1
        tri = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
        md = mode.ravel()[tri]
        keep = (np.min(md, axis=1) <= max_mode) & (np.max(md, axis=1) <= max_mode + 1)
        Pf = P.reshape(-1, 2)
        keep &= np.all(np.isfinite(Pf[tri]).reshape(len(tri), -1), axis=1)
        tri = tri[keep]
        self.P, self.F, self.C = Pf, F.reshape(-1, 2), C.reshape(-1, 3)
        self.mode = mode.ravel()  # per vertex
        self.ext = np.hypot(*(Pf - A).T) / L  # per vertex: |tip - clamp| / L
        self.tri = tri
        V = Pf[tri]  # (T, 3, 2)
        lo, hi = V.min(1), V.max(1)
        self.origin = lo.min(0) - bucket
        self.levels = []
        todo = np.arange(len(tri))
        for lev in range(n_levels):
            h = bucket * ratio**lev
            fits, rep, k, blo, bhi, span = bucket_spans(lo[todo], hi[todo], self.origin, h, cap, lev == n_levels - 1)
            sy = span[rep, 1]
            nby = int(bhi[:, 1].max()) + 2 if len(bhi) else 1
            bid = (blo[rep, 0] + k // sy) * nby + blo[rep, 1] + k % sy
            order = np.argsort(bid, kind="stable")
            self.levels.append((h, nby, bid[order], todo[rep[order]]))
            todo = todo[~fits]
            if not len(todo):
                break

    def locate(self, Q):
        """Triangles containing the points Q (M, 2): returns (query index, triangle, a, b)
        with the barycentric coordinates relative to vertex 0."""
        QI, TR = [], []
        for h, nby, bid, btri in self.levels:
            q = np.floor((Q - self.origin) / h).astype(np.int64)
            ok = (q[:, 0] >= 0) & (q[:, 1] >= 0) & (q[:, 1] < nby)
            qi, tr = bucket_hits(q[:, 0] * nby + q[:, 1], ok, bid, btri)
            QI.append(qi)
            TR.append(tr)
        qi, tr = np.concatenate(QI), np.concatenate(TR)
        V = self.P[self.tri[tr]]
        e1, e2 = V[:, 1] - V[:, 0], V[:, 2] - V[:, 0]
        d = Q[qi] - V[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        with np.errstate(all="ignore"):
            a = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
            b = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
        inside = (a >= 0) & (b >= 0) & (a + b < 1) & np.isfinite(a) & np.isfinite(b) & (det != 0)
        return qi[inside], tr[inside], a[inside], b[inside]

    def affine(self, tr, a, b):
        """Force, chart unknowns, d force / d tip (2x2) and d chart / d tip (3x2) at the located points."""
        T = self.tri[tr]
        V, F, C = self.P[T], self.F[T], self.C[T]
        w = np.stack([1 - a - b, a, b], 1)
        f = np.einsum("nk,nkc->nc", w, F)
        c = np.einsum("nk,nkc->nc", w, C)
        DV = np.stack([V[:, 1] - V[:, 0], V[:, 2] - V[:, 0]], -1)  # (n, 2 coords, 2 params)
        DF = np.stack([F[:, 1] - F[:, 0], F[:, 2] - F[:, 0]], -1)
        DC = np.stack([C[:, 1] - C[:, 0], C[:, 2] - C[:, 0]], -1)  # (n, 3 chart, 2 params)
        with np.errstate(all="ignore"):
            inv = np.linalg.inv(DV)
        return f, c, DF @ inv, DC @ inv


def _solve3(A, b):
    """Batched 3x3 solve by Cramer's rule (inf where singular)."""
    c0, c1, c2 = A[:, :, 0], A[:, :, 1], A[:, :, 2]
    det = np.einsum("ij,ij->i", c0, np.cross(c1, c2))
    with np.errstate(all="ignore"):
        x0 = np.einsum("ij,ij->i", b, np.cross(c1, c2)) / det
        x1 = np.einsum("ij,ij->i", c0, np.cross(b, c2)) / det
        x2 = np.einsum("ij,ij->i", c0, np.cross(c1, b)) / det
    return np.column_stack([x0, x1, x2])


def _located(sys: FKSystem, sheet, i, B, arm):
    """Rods of ``sheet`` (rod i) pinned at the points ``B`` (M, 2) (platform arms ``arm`` (M, 2)):
    query index, scaled platform wrench w (n, 3), its derivative with respect to the scaled pose
    Jw (n, 3, 3), chart unknowns cc (n, 3), d chart / d tip G (n, 3, 2), d B_i / d scaled pose
    dB (n, 2, 3).  Sorted by query index."""
    g = sys.g
    qi, tr, a, b = sheet.locate(B)
    order = np.argsort(qi, kind="stable")
    qi, tr, a, b = qi[order], tr[order], a[order], b[order]
    f, cc, K, G = sheet.affine(tr, a, b)
    ok = np.all(np.isfinite(K.reshape(len(K), -1)), axis=1) & np.all(np.isfinite(G.reshape(len(G), -1)), axis=1)
    qi, f, cc, K, G = qi[ok], f[ok], cc[ok], K[ok], G[ok]
    ar = arm[qi]
    perp = np.stack([-ar[:, 1], ar[:, 0]], -1)
    dB = np.zeros((len(qi), 2, 3))
    dB[:, 0, 0] = g.L_ref
    dB[:, 1, 1] = g.L_ref
    dB[:, :, 2] = perp
    df = K @ dB  # (n, 2, 3)
    w = np.column_stack([f[:, 0] / g.F_ref, f[:, 1] / g.F_ref,
                         (ar[:, 0] * f[:, 1] - ar[:, 1] * f[:, 0]) / (g.F_ref * g.L_ref)])
    Jw = np.empty((len(qi), 3, 3))
    Jw[:, :2] = df / g.F_ref
    Jw[:, 2] = (ar[:, 0, None] * df[:, 1] - ar[:, 1, None] * df[:, 0]) / (g.F_ref * g.L_ref)
    Jw[:, 2, 2] += (perp[:, 0] * f[:, 1] - perp[:, 1] * f[:, 0]) / (g.F_ref * g.L_ref)
    return qi, w, Jw, cc, G, dB


def _cluster(Z, sc, h_xy, h_th, cluster, keep_per, max_starts):
    """The best ``keep_per`` starts (smallest score) of every cluster of equal predicted solutions
    (cells of ``cluster = (pose cells in grid steps, Lambda, t, psi)``), best first."""
    if not len(Z):
        return Z
    cp, cl, ct, cps = cluster
    key = np.round(np.column_stack([Z[:, 9:11] / (cp * h_xy), _wrap(Z[:, 11]) / (cp * h_th),
                                    Z[:, 0:9:3] / cl, Z[:, 1:9:3] / ct, _wrap(Z[:, 2:9:3]) / cps]))
    order = np.argsort(sc, kind="stable")
    _, inv = np.unique(key[order], axis=0, return_inverse=True)
    inv = np.asarray(inv).ravel()
    o2 = np.argsort(inv, kind="stable")  # stable: within a cluster, best score first
    starts_ = np.r_[0, np.flatnonzero(np.diff(inv[o2])) + 1]
    rank = np.empty(len(o2), np.int64)
    rank[o2] = np.arange(len(o2)) - np.repeat(starts_, np.diff(np.r_[starts_, len(o2)]))
    chosen = order[np.flatnonzero(rank < keep_per)]  # in score order
    return Z[chosen][:max_starts]


def _combos(cnts, npz, chunk):
    """All combinations, pose by pose, of one located rod per listed rod (``cnts``: per rod the
    number of located rods at each of the ``npz`` poses), in chunks of about ``chunk``: yields
    (pose index J, list per rod of indices into that rod's located arrays, sorted by pose)."""
    first = [np.cumsum(c) - c for c in cnts]
    tot = np.prod(np.stack(cnts), axis=0)
    bounds = np.searchsorted(np.cumsum(tot), np.arange(chunk, int(tot.sum()) + chunk, chunk))
    lo_p = 0
    for hi_p in np.unique(np.r_[bounds + 1, npz]):
        hi_p = int(min(hi_p, npz))
        if hi_p <= lo_p:
            continue
        pidx = np.arange(lo_p, hi_p)
        tt = tot[pidx]
        J = np.repeat(pidx, tt)
        k = np.arange(len(J)) - np.repeat(np.cumsum(tt) - tt, tt)
        lo_p = hi_p
        if not len(J):
            continue
        sel = []
        div = tot[J].copy()
        for c, f0 in zip(cnts, first):  # mixed-radix digits of k, first rod most significant
            div = div // c[J]
            sel.append(f0[J] + (k // div) % c[J])
        yield J, sel


def _grid_starts(sys: FKSystem, poses, sheets, s_max, h_xy, h_th, cluster=(1.0, 2.0, 1.0, 0.25), keep_per=1,
                 max_starts=200000, pose_chunk=4000, tri_chunk=1_000_000):
    """Starts (chart unknowns y) from the triples of located rods at every grid pose whose
    linearised pose correction is within ``s_max`` grid steps.

    For each located rod the platform wrench it exerts and its derivative with respect to the
    pose (through the tip stiffness of its triangle) are computed once; a triple's wrench balance
    ``W(p0) + Jw dp = load`` then costs a sum and a 3x3 solve.  Kept triples are clustered by
    their predicted solution (:func:`_cluster`).  Returns (starts, number of triples)."""
    g = sys.g
    load = np.array([sys.load[0] / g.F_ref, sys.load[1] / g.F_ref, sys.load[2] / (g.F_ref * g.L_ref)])
    sc_ = np.array([h_xy, h_xy, h_th])
    scores, Ys = [], []
    n_triples = 0
    for c0 in range(0, len(poses), pose_chunk):
        pz = poses[c0:c0 + pose_chunk]
        npz = len(pz)
        B, arm = sys.platform_points(pz)
        hits = [_located(sys, sheets[i], i, B[:, i], arm[:, i]) for i in range(3)]
        cnts = [np.bincount(h[0], minlength=npz) for h in hits]
        n_triples += int(np.sum(cnts[0] * cnts[1] * cnts[2]))
        for J, sel in _combos(cnts, npz, tri_chunk):
            W = hits[0][1][sel[0]] + hits[1][1][sel[1]] + hits[2][1][sel[2]] - load
            Jw = hits[0][2][sel[0]] + hits[1][2][sel[1]] + hits[2][2][sel[2]]
            dp = -_solve3(Jw, W)
            score = np.max(np.abs(dp) / sc_, axis=1)
            kp = np.flatnonzero(np.isfinite(score) & (score <= s_max))
            if not len(kp):
                continue
            dpk = dp[kp]
            y = np.empty((len(kp), 12))
            for i in range(3):
                s_i = sel[i][kp]
                dBi = np.einsum("nac,nc->na", hits[i][5][s_i], dpk)
                y[:, 3 * i:3 * i + 3] = hits[i][3][s_i] + np.einsum("nab,nb->na", hits[i][4][s_i], dBi)
            y[:, 0:9:3] = np.abs(y[:, 0:9:3])
            y[:, 9:12] = pz[J[kp]] / sys.ps + dpk
            scores.append(score[kp])
            Ys.append(y)
    if not Ys:
        return np.zeros((0, 12)), n_triples
    return _cluster(np.concatenate(Ys), np.concatenate(scores), h_xy, h_th, cluster, keep_per, max_starts), n_triples


# ======================================================================================
# family 3: anchored taut rods
# ======================================================================================
def anchor_states(sys: FKSystem, sheet, j, ext_min, max_mode, rng, n_max):
    """Scanned states (vertices) of rod j nearly at full reach (``|tip - A_j| >= ext_min L_j``,
    d-mode <= max_mode), stratified along the reach circle: one random vertex per cell of
    (polar angle of the tip about the clamp in steps of 0.01 rad, d-mode, side t > 0 / t < 0),
    at most ``n_max`` (random subset)."""
    ok = (sheet.ext >= ext_min) & (sheet.mode <= max_mode) & np.all(np.isfinite(sheet.P), axis=1)
    cand = np.flatnonzero(ok)
    if not len(cand):
        return cand
    d = sheet.P[cand] - sys.A[j]
    phi = np.floor(np.arctan2(d[:, 1], d[:, 0]) / 0.01).astype(np.int64)
    key = np.column_stack([phi, sheet.mode[cand], sheet.C[cand, 1] > 0])
    perm = rng.permutation(len(cand))
    _, first = np.unique(key[perm], axis=0, return_index=True)
    pick = cand[perm[first]]
    if len(pick) > n_max:
        pick = rng.choice(pick, n_max, replace=False)
    return np.sort(pick)


def _anchor_starts(sys: FKSystem, sheets, j, verts, n_theta, s_max, h_xy, h_th, rng, lam_max=40.0,
                   cluster=(1.0, 2.0, 1.0, 0.25), keep_per=1, max_starts=200000, chunk=4000,
                   tri_chunk=1_000_000):
    """Starts with rod j taut: its tip is put at a scanned taut state (``verts``), the platform
    angle runs over a grid of ``n_theta`` values (random offset per state), so ``B_j`` is exactly
    on rod j's thin reach shell where a pose grid would straddle it.  The other two rods are
    located at their ``B_i``.  A taut rod behaves like a string: it supplies a force of free
    magnitude ``T`` along its current direction while its tip can only slide along the shell; so
    the wrench balance is linearised in (slide delta of B_j, dtheta, T) and a pair is kept when
    |delta| <= s_max h_xy L_ref, |dtheta| <= s_max h_th and 0 < T L^2/EI <= lam_max^2.  Rod j of
    the start keeps the state's (t, psi) with Lambda from T.  Returns (starts, pairs, poses)."""
    g = sys.g
    sh = sheets[j]
    others = [i for i in range(3) if i != j]
    load = np.array([sys.load[0] / g.F_ref, sys.load[1] / g.F_ref, sys.load[2] / (g.F_ref * g.L_ref)])
    b = g.attach
    Bv = sh.P[verts]
    Cv = sh.C[verts]
    e_all = np.stack([np.cos(Cv[:, 2]), np.sin(Cv[:, 2])], -1)  # force direction of the state
    chord = (Bv - sys.A[j]) / np.hypot(*(Bv - sys.A[j]).T)[:, None]
    tau_all = np.stack([-chord[:, 1], chord[:, 0]], -1)  # slide direction on the shell
    T0_all = np.hypot(*sh.F[verts].T) / g.F_ref
    th = (2 * np.pi / n_theta) * (np.arange(n_theta)[None, :] + rng.uniform(size=(len(verts), 1))) - np.pi
    th = th.ravel()
    vi = np.repeat(np.arange(len(verts)), n_theta)
    c, s = np.cos(th), np.sin(th)
    armj = np.stack([c * b[j, 0] - s * b[j, 1], s * b[j, 0] + c * b[j, 1]], -1)
    poses = np.column_stack([Bv[vi] - armj, th])
    keep = _in_reach(sys, poses)
    poses, vi, armj = poses[keep], vi[keep], armj[keep]
    scores, Ys = [], []
    n_pairs = 0
    fs_j = g.EI[j] / sys.L[j] ** 2 / g.F_ref  # scaled force per unit Lambda^2
    for c0 in range(0, len(poses), chunk):
        pz, vz, az = poses[c0:c0 + chunk], vi[c0:c0 + chunk], armj[c0:c0 + chunk]
        npz = len(pz)
        B, arm = sys.platform_points(pz)
        hits = [_located(sys, sheets[i], i, B[:, i], arm[:, i]) for i in others]
        cnts = [np.bincount(h[0], minlength=npz) for h in hits]
        n_pairs += int(np.sum(cnts[0] * cnts[1]))
        for J, sel in _combos(cnts, npz, tri_chunk):
            n = len(J)
            e, tau, T0 = e_all[vz[J]], tau_all[vz[J]], T0_all[vz[J]]
            aj = az[J]
            perp = np.stack([-aj[:, 1], aj[:, 0]], -1)
            # scaled pose change for (delta, dtheta): dP = delta L_ref tau - dtheta perp(arm_j)
            Mq = np.zeros((n, 3, 2))
            Mq[:, 0:2, 0] = tau
            Mq[:, 0:2, 1] = -perp / g.L_ref
            Mq[:, 2, 1] = 1.0
            W = hits[0][1][sel[0]] + hits[1][1][sel[1]] - load
            Jw = hits[0][2][sel[0]] + hits[1][2][sel[1]]
            A3 = np.empty((n, 3, 3))
            A3[:, :, 0:2] = Jw @ Mq
            A3[:, 2, 1] += T0 * (perp[:, 0] * e[:, 1] - perp[:, 1] * e[:, 0]) / g.L_ref
            A3[:, 0, 2] = e[:, 0]
            A3[:, 1, 2] = e[:, 1]
            A3[:, 2, 2] = (aj[:, 0] * e[:, 1] - aj[:, 1] * e[:, 0]) / g.L_ref
            q = -_solve3(A3, W)
            T = q[:, 2]
            score = np.maximum(np.abs(q[:, 0]) / h_xy, np.abs(q[:, 1]) / h_th)
            kp = np.flatnonzero(np.isfinite(score) & (score <= s_max) & (T > 0) & (T <= lam_max**2 * fs_j))
            if not len(kp):
                continue
            dp = np.einsum("nab,nb->na", Mq[kp], q[kp, :2])
            y = np.empty((len(kp), 12))
            for r, i in enumerate(others):
                s_i = sel[r][kp]
                dBi = np.einsum("nac,nc->na", hits[r][5][s_i], dp)
                y[:, 3 * i:3 * i + 3] = hits[r][3][s_i] + np.einsum("nab,nb->na", hits[r][4][s_i], dBi)
            y[:, 3 * j] = np.sqrt(T[kp] / fs_j)
            y[:, 3 * j + 1] = Cv[vz[J[kp]], 1]
            y[:, 3 * j + 2] = Cv[vz[J[kp]], 2]
            y[:, 0:9:3] = np.abs(y[:, 0:9:3])
            y[:, 9:12] = pz[J[kp]] / sys.ps + dp
            scores.append(score[kp])
            Ys.append(y)
    if not Ys:
        return np.zeros((0, 12)), n_pairs, len(poses)
    Z = _cluster(np.concatenate(Ys), np.concatenate(scores), h_xy, h_th, cluster, keep_per, max_starts)
    return Z, n_pairs, len(poses)


# ======================================================================================
# driver
# ======================================================================================
def _near_key(y):
    """Normalised coordinates for "this start will converge to that known solution":
    pose (x, y in L_ref; cos/sin theta), per rod Lambda (cos psi, sin psi) / 10 and t / 10."""
    y = np.atleast_2d(y)
    lam, t, psi = y[:, 0:9:3], y[:, 1:9:3], y[:, 2:9:3]
    return np.column_stack([y[:, 9:11], np.cos(y[:, 11]), np.sin(y[:, 11]),
                            0.1 * lam * np.cos(psi), 0.1 * lam * np.sin(psi), 0.1 * t])


def _dedupe(keys, tol, order=None):
    """Greedy de-duplication (inf-norm, relative to 1 + |key|); returns the kept indices."""
    keys = np.atleast_2d(keys)
    order = np.arange(len(keys)) if order is None else order
    chosen: list[int] = []
    for i in order:
        if chosen:
            K = keys[chosen]
            if np.min(np.max(np.abs(K - keys[i]) / (1.0 + np.abs(K)), axis=1)) <= tol:
                continue
        chosen.append(int(i))
    return chosen


def _steps_for(y):
    """RK4 steps for a start: about 8 per unit of the largest Lambda (h Lambda <= 1/8)."""
    lam = np.max(np.abs(y[:, 0:9:3]), axis=1)
    return np.clip(64 * np.ceil(8.0 * lam / 64.0), 128, 768).astype(np.int64)


def fk_multistart(mech, inputs, load=None, max_mode=2, *, n_random=1500, n_forward=1500, grid=(0.04, 72),
                  min_grid_poses=2000, max_grid_poses=20000, anchors=(400, 72, 0.97), s_max=2.0, keep_per=1,
                  scan=(40.0, 320, 480), seed=0, chunk=1000, near=1e-3, return_all=False, stats=None,
                  max_turn=None, clamped_grid=(0.08, 36), ms_segments=4):
    """All FK equilibria with every d-mode <= ``max_mode`` found by multi-start shooting.

    ``inputs`` SI (rad for revolute legs); ``load`` (Fx, Fy, Mz), default the mechanism's.

    Starts (see the module docstring):

    * ``grid = (h_xy, n_theta)``: pose grid, spacing ``h_xy L_ref`` (refined in x, y until the
      reach region holds ``min_grid_poses`` poses, coarsened when it holds more than
      ``max_grid_poses``, e.g. very long rods) and ``n_theta`` orientations; ``None`` to skip;
    * ``anchors = (states per rod, n_theta, ext_min)``: anchored taut rods
      (:func:`_anchor_starts`); ``None`` to skip;
    * both search triples within ``s_max`` grid steps (``keep_per`` starts per cluster);
    * ``n_random`` random chart starts, ``n_forward`` random forward starts.

    ``scan = (Lambda_max, n_Lambda, n_t)`` is the chart grid (Newton gives up beyond 1.5
    Lambda_max).  Starts run in chunks of ``chunk``; a start within ``near`` (normalised,
    :func:`_near_key`) of an already converged solution is skipped (0 to run all).  Deterministic
    for a given ``seed``.

    Returns a list of :class:`FKOracleSolution` sorted by (modes, pose), every one verified by
    :func:`verify_fk` (``residual <= VERIFY_TOL``; 1e-6 for extreme solutions, reported only); all
    d-modes ``<= max_mode`` unless ``return_all``.  ``stats`` (dict) receives the counts of starts,
    Newton runs, CPU seconds, and ``rejected``: candidates with d-modes <= max_mode and no extreme
    rod whose verified residual stayed between VERIFY_TOL and 1e-6 (expected: none).

    Mechanisms with CLAMPED legs are solved by ``fk_clamped.fk_clamped`` (exact rods located at
    the poses of a ``clamped_grid = (h_xy, n_theta)`` grid plus ``n_random`` random poses,
    linearised triples, Newton in the pose with the rods slaved, multiple-shooting refinement with
    ``ms_segments`` segments per rod); only solutions whose clamped rods turn by at most
    ``max_turn`` (default 2 pi max_mode) are kept, and every rod reports its ``tip_moment`` and
    ``turning``.
    """
    import time

    from scipy.spatial import cKDTree

    t_start = time.process_time()
    g = Geom.of(mech)
    load = np.asarray(mech.load if load is None else load, float)
    if g.any_clamped:
        from fk_clamped import fk_clamped

        return fk_clamped(mech, inputs, load, max_mode=max_mode, max_turn=max_turn, K=ms_segments,
                          grid=clamped_grid, n_random=n_random, s_max=s_max, seed=seed, return_all=return_all,
                          stats=stats)
    sys = FKSystem(g, inputs, load)
    ts = TipSystem(sys)
    rng = np.random.default_rng(seed)
    info: dict = {}
    parts = []
    sc = chart_scan(*scan)
    lam_blow = 1.5 * scan[0]  # Newton gives up on a start whose largest Lambda exceeds this
    sheets = [_Sheet(sys, i, sc, max_mode, 0.01 * g.L_ref) for i in range(3)]
    h_xy, n_th = grid if grid else (0.04, 72)
    if grid:
        poses = pose_grid(sys, h_xy, n_th, rng)
        if min_grid_poses and 0 < len(poses) < min_grid_poses:  # small reach region: refine x, y
            h_xy *= max(np.sqrt(len(poses) / min_grid_poses), 0.25)
            poses = pose_grid(sys, h_xy, n_th, rng)
        elif max_grid_poses and len(poses) > max_grid_poses:  # huge reach region: coarsen x, y
            h_xy *= np.sqrt(len(poses) / max_grid_poses)
            poses = pose_grid(sys, h_xy, n_th, rng)
        info["grid_poses"] = len(poses)
        yg, n_tr = _grid_starts(sys, poses, sheets, s_max, h_xy, 2 * np.pi / n_th, keep_per=keep_per)
        info["grid_triples"] = int(n_tr)
        info["grid_starts"] = len(yg)
        parts.append(yg)
    if anchors:
        n_anc, n_tha, ext_min = anchors
        ya_all, n_pairs, n_poses = [], 0, 0
        for j in range(3):
            verts = anchor_states(sys, sheets[j], j, ext_min, max_mode, rng, n_anc)
            ya, n_pr, n_ps = _anchor_starts(sys, sheets, j, verts, n_tha, s_max, h_xy, 2 * np.pi / n_tha, rng,
                                            lam_max=scan[0], keep_per=keep_per)
            ya_all.append(ya)
            n_pairs += n_pr
            n_poses += n_ps
        info["anchor_poses"] = n_poses
        info["anchor_pairs"] = n_pairs
        ya = np.concatenate(ya_all)
        info["anchor_starts"] = len(ya)
        parts.append(ya)
    if n_forward:
        yf = random_forward_starts(sys, n_forward, rng)
        info["forward_starts"] = len(yf)
        parts.append(yf)
    if n_random:
        yr = random_chart_starts(sys, sheets, n_random, rng)
        info["random_starts"] = len(yr)
        parts.append(yr)
    starts = np.concatenate(parts) if parts else np.zeros((0, 12))
    info["starts"] = len(starts)
    info["cpu_seeding"] = round(time.process_time() - t_start, 1)
    found = np.zeros((0, 12))
    n_run = n_conv = 0
    for c0 in range(0, len(starts), chunk):
        S = starts[c0:c0 + chunk]
        if len(found) and near > 0:
            d, _ = cKDTree(_near_key(found)).query(_near_key(S), k=1, p=np.inf)
            S = S[d > near]
        if not len(S):
            continue
        steps = _steps_for(S)
        for ns in np.unique(steps):
            y, rn, modes, _ = tip_newton(ts, S[steps == ns], n_iter=25, n_steps=int(ns), tol=1e-9, lam_blow=lam_blow)
            n_run += len(y)
            ok = (rn < 1e-8) & np.all(modes <= max_mode + 1, axis=1)
            n_conv += int(np.count_nonzero(ok))
            if np.any(ok):
                F_ = np.concatenate([found, y[ok]])
                found = F_[_dedupe(_key(F_), 1e-6)]
    info["newton_runs"] = n_run
    info["converged"] = n_conv
    info["cpu_newton"] = round(time.process_time() - t_start - info["cpu_seeding"], 1)
    out = []
    rejected = []
    Y = found
    if len(Y):
        Y, rn, _, _ = tip_newton(ts, Y, n_iter=10, n_steps=800, tol=1e-11, lam_blow=lam_blow)
        Y = Y[rn < 1e-5]  # (loose: RK4 near the separatrix; the polish and verification decide)
        Y = Y[_dedupe(_key(Y), 1e-6)]
        Yp, _ = tip_polish(ts, Y)
        for s in _build(sys, ts, Yp):
            # extreme rods (k' < 5e-7, out of scope, reported only): a looser residual, since the
            # chart itself (v = theta_L - psi near 0 or 2 pi) loses digits there
            ok = s.residual <= (1e-6 if s.extreme else VERIFY_TOL)
            if not ok:
                if not s.extreme and s.residual <= 1e-6 and max(s.modes) <= max_mode:
                    rejected.append((s.mode_label, s.pose.tolist(), s.residual))
                continue
            if return_all or all(q <= max_mode for q in s.modes):
                out.append(s)
        keys = _key(np.array([s.y for s in out]).reshape(-1, 12))
        out = [out[i] for i in _dedupe(keys, 1e-7)]
    out.sort(key=lambda s: (s.modes, tuple(np.round(s.pose, 9))))
    info["unique"] = len(out)
    info["rejected"] = rejected
    info["cpu_total"] = round(time.process_time() - t_start, 1)
    if stats is not None:
        stats.update(info)
    return out


oracle_fk = fk_multistart  # the previous name


def by_modes(sols) -> dict[str, int]:
    out: dict[str, int] = {}
    for s in sols:
        out[s.mode_label] = out.get(s.mode_label, 0) + 1
    return dict(sorted(out.items()))


def pose_match(p, q, tol_xy=1e-6, tol_th=1e-5) -> bool:
    """Whether two poses agree: |dx|, |dy| <= tol_xy (m) and |dtheta| (mod 2 pi) <= tol_th (rad)."""
    p = np.asarray(p, float)
    q = np.asarray(q, float)
    return bool(max(abs(p[0] - q[0]), abs(p[1] - q[1])) <= tol_xy and abs(float(_wrap(p[2] - q[2]))) <= tol_th)
