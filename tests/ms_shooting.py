"""Multiple shooting for rods and mechanisms (test-only; used by ik_oracle and fk_oracle).

Why: single shooting from the clamp amplifies errors like ``exp(Lambda L)`` for a rod that runs
near the saddle of the pendulum ``phi'' = Lambda^2 sin(phi)`` -- a taut rod (nearly straight
under high tension, bent only in boundary layers at its ends, ``|k - 1|`` exponentially small),
or a loop between two taut tails.  Clamped rods are often like that.  Here every rod is cut into
``K`` equal segments; the states at the interior nodes are extra unknowns and continuity at the
nodes extra equations, so every integration is short (amplification ``exp(Lambda L / K)``).

Scaled unknowns of rod i (as in ``ik_oracle._System``): ``q_i = (n_x / F_ref, n_y / F_ref,
m0 / (F_ref L_ref))``, then the K - 1 interior nodes ``(x / L_ref, y / L_ref, theta, m / (F_ref
L_ref))``.  Rows of rod i: continuity at the K - 1 nodes (4 each, same scaling), tip at ``B_i``
(2, / L_ref) and the tip condition (pinned: ``m(L) L / EI = 0``; clamped:
``wrap(theta(L) - theta_P - tip_angle) = 0``).

* :func:`rod_block`: residual rows of one rod and their derivatives (rod unknowns, the leg input,
  the pose), plus its tip moment and derivatives (for the moment balance);
* :class:`MSSystem`: the 12 K mechanism equations (rods + platform equilibrium ``sum n_i = F``,
  ``sum (B_i - P) x n_i + sum_clamped m_i(L) = M_z``) for IK (pose fixed, inputs unknown) or FK
  (inputs fixed, pose unknown); K = 1 is exactly ``ik_oracle``'s 12-equation system;
* :class:`LegMS`: one leg of an IK problem (rod unknowns + its input; 4 K - 1 equations): its
  solution curve, traced by pseudo-arclength continuation in ``ik_oracle``.

Segments are unit rods of ``clamped_chart.rk4_rods`` (RK4 + variational equations, steps per rod
from its force and moment) scaled to the segment length ``L / K``, or, for tight residuals,
``ik_oracle.integrate_batch`` (DOP853, rtol 1e-13).
"""

from __future__ import annotations

import numpy as np
from clamped_chart import rk4_rods, steps_for
from ik_oracle import Geom, _wrap, integrate_batch

__all__ = ["LegMS", "MSSystem", "RodFK", "rod_block", "solve_batch"]


def _segments(g: Geom, i, K, Xr, A, al, L, n_min, per_lambda, var, tight=False):
    """Integrate the K segments of rod i.  Returns start states (sxy (M, K, 2), sth, sm), end
    states (exy, eth, em), Z (4, M, K) unit-rod ends, S (4, 4, M, K) sensitivities, interior sign
    changes (M, K), ell (M,) and the unit-rod parameters (ax, ay, mt) (M, K)."""
    Fs, Ms = g.F_ref, g.F_ref * g.L_ref
    M = len(Xr)
    EI = g.EI[i]
    n = Xr[:, 0:2] * Fs
    ell = L / K
    sxy = np.empty((M, K, 2)); sth = np.empty((M, K)); sm = np.empty((M, K))
    sxy[:, 0] = A
    sth[:, 0] = al
    sm[:, 0] = Xr[:, 2] * Ms
    for j in range(1, K):
        b = 3 + 4 * (j - 1)
        sxy[:, j, 0] = Xr[:, b] * g.L_ref
        sxy[:, j, 1] = Xr[:, b + 1] * g.L_ref
        sth[:, j] = Xr[:, b + 2]
        sm[:, j] = Xr[:, b + 3] * Ms
    ax = np.repeat(n[:, 0] * ell**2 / EI, K)
    ay = np.repeat(n[:, 1] * ell**2 / EI, K)
    mt = (sm * (ell[:, None] / EI)).ravel()
    th0 = sth.ravel()
    if tight:
        y = integrate_batch(ax, ay, mt, th0, n_eval=2)[..., -1]
        Z, S, ch = y, None, np.zeros(len(ax), np.int64)
    else:
        Z, S, ch = rk4_rods(ax, ay, mt, th0, steps_for(ax, ay, mt, n_min=n_min, per_lambda=per_lambda), var=var)
    Z = Z.reshape(4, M, K)
    exy = sxy + ell[:, None, None] * np.stack([Z[0], Z[1]], -1)
    eth, em = Z[2], Z[3] * EI / ell[:, None]
    return (sxy, sth, sm), (exy, eth, em), Z, (None if S is None else S.reshape(4, 4, M, K)), ch.reshape(M, K), ell, \
        (ax.reshape(M, K), ay.reshape(M, K), mt.reshape(M, K))


def rod_block(g: Geom, i: int, K: int, Xr, A, al, L, dclamp, B, tip_th, jac=True, n_min=16, per_lambda=8.0,
              tight=False):
    """Rows of rod i (see the module docstring) for the rod unknowns ``Xr`` (M, 3 + 4 (K - 1)).

    ``A`` (M, 2), ``al`` (M,), ``L`` (M,): the clamp point, angle and length; ``dclamp`` =
    (dA/dv (M, 2), dal/dv (M,), dL/dv (M,)) their derivatives with respect to the leg's (scaled)
    input v; ``B`` (M, 2) the tip target and ``tip_th`` (M,) the clamped tip tangent.

    Returns a dict: ``R`` (M, 4K-1); with ``jac``: ``Jr`` (M, 4K-1, nr) w.r.t. the rod unknowns,
    ``Jv`` (M, 4K-1) w.r.t. the input, ``JB`` (M, 4K-1, 2) w.r.t. B, ``Jt`` (M, 4K-1) w.r.t.
    tip_th; always ``mL`` (M,) the tip moment / (F_ref L_ref), with ``jac`` its derivatives
    ``dmL_dr`` (M, nr), ``dmL_dv`` (M,); ``changes`` (M,) interior sign changes of the moment
    (inside the segments and at the nodes), ``turning`` (M,), ``end`` (exy, eth, em) of the
    last segment."""
    Fs, Ms = g.F_ref, g.F_ref * g.L_ref
    M = len(Xr)
    EI = g.EI[i]
    nr = 3 + 4 * (K - 1)
    cl = bool(g.clamped[i])
    (sxy, sth, sm), (exy, eth, em), Z, S, ch, ell, (ax, ay, mt) = _segments(
        g, i, K, Xr, A, al, L, n_min, per_lambda, jac, tight)
    nrow = 4 * K - 1
    R = np.empty((M, nrow))
    for j in range(K - 1):
        b = 3 + 4 * j
        r0 = 4 * j
        R[:, r0] = exy[:, j, 0] / g.L_ref - Xr[:, b]
        R[:, r0 + 1] = exy[:, j, 1] / g.L_ref - Xr[:, b + 1]
        R[:, r0 + 2] = eth[:, j] - Xr[:, b + 2]
        R[:, r0 + 3] = em[:, j] / Ms - Xr[:, b + 3]
    rt = 4 * (K - 1)
    R[:, rt] = (exy[:, -1, 0] - B[:, 0]) / g.L_ref
    R[:, rt + 1] = (exy[:, -1, 1] - B[:, 1]) / g.L_ref
    R[:, rt + 2] = _wrap(eth[:, -1] - tip_th) if cl else em[:, -1] * L / EI
    sg = np.sign(sm)
    node_changes = np.sum(np.sign(em[:, :-1]) * sg[:, 1:] < 0, axis=1) if K > 1 else 0
    out = {"R": R, "mL": em[:, -1] / Ms, "changes": ch.sum(axis=1) + node_changes, "turning": eth[:, -1] - al,
           "end": (exy[:, -1], eth[:, -1], em[:, -1])}
    if not jac:
        return out
    # end-state derivatives (physical) of segment j w.r.t. n_x, n_y, m_start, th_start, ell
    e2, e1 = ell**2 / EI, ell / EI
    d = {}
    for key, p, fac in (("nx", 0, e2), ("ny", 1, e2), ("m", 2, e1)):
        f = fac[:, None]
        d[key] = (ell[:, None] * S[p, 0] * f, ell[:, None] * S[p, 1] * f, S[p, 2] * f, S[p, 3] * f * (EI / ell[:, None]))
    d["th"] = (ell[:, None] * S[3, 0], ell[:, None] * S[3, 1], S[3, 2], S[3, 3] * (EI / ell[:, None]))
    dp = (2 * ax / ell[:, None], 2 * ay / ell[:, None], mt / ell[:, None])
    dX = [sum(S[p, st] * dp[p] for p in range(3)) for st in range(4)]
    d["ell"] = (Z[0] + ell[:, None] * dX[0], Z[1] + ell[:, None] * dX[1], dX[2],
                dX[3] * EI / ell[:, None] - Z[3] * EI / ell[:, None] ** 2)
    dA, dal, dL = dclamp
    Jr = np.zeros((M, nrow, nr))
    Jv = np.zeros((M, nrow))
    for j in range(K):
        if j < K - 1:
            spec = [(4 * j, 0, 1 / g.L_ref), (4 * j + 1, 1, 1 / g.L_ref), (4 * j + 2, 2, 1.0), (4 * j + 3, 3, 1 / Ms)]
        else:
            spec = [(rt, 0, 1 / g.L_ref), (rt + 1, 1, 1 / g.L_ref), (rt + 2, 2, 1.0) if cl else (rt + 2, 3, L / EI)]
        for r_, st, sc in spec:
            Jr[:, r_, 0] += d["nx"][st][:, j] * Fs * sc
            Jr[:, r_, 1] += d["ny"][st][:, j] * Fs * sc
            if j == 0:
                Jr[:, r_, 2] += d["m"][st][:, j] * Ms * sc
                # the clamp (input) moves the start of segment 0
                if st in (0, 1):
                    Jv[:, r_] += dA[:, st] * sc
                Jv[:, r_] += d["th"][st][:, j] * dal * sc
            else:
                b = 3 + 4 * (j - 1)
                if st in (0, 1):
                    Jr[:, r_, b + st] += g.L_ref * sc
                Jr[:, r_, b + 2] += d["th"][st][:, j] * sc
                Jr[:, r_, b + 3] += d["m"][st][:, j] * Ms * sc
            Jv[:, r_] += d["ell"][st][:, j] * (dL / K) * sc
            if j == K - 1 and st == 3 and not cl:
                Jv[:, r_] += em[:, -1] / EI * dL  # the row m L / EI depends on L explicitly
        if j < K - 1:
            b = 3 + 4 * j
            for t in range(4):
                Jr[:, 4 * j + t, b + t] -= 1.0
    JB = np.zeros((M, nrow, 2))
    JB[:, rt, 0] = -1.0 / g.L_ref
    JB[:, rt + 1, 1] = -1.0 / g.L_ref
    Jt = np.zeros((M, nrow))
    if cl:
        Jt[:, rt + 2] = -1.0
    # tip moment derivatives (scaled by 1/Ms)
    j = K - 1
    dmL = np.zeros((M, nr))
    dmL[:, 0] = d["nx"][3][:, j] * Fs / Ms
    dmL[:, 1] = d["ny"][3][:, j] * Fs / Ms
    dmL_dv = d["ell"][3][:, j] * (dL / K) / Ms
    if K == 1:
        dmL[:, 2] = d["m"][3][:, j]
        dmL_dv = dmL_dv + d["th"][3][:, j] * dal / Ms
    else:
        b = 3 + 4 * (j - 1)
        dmL[:, b + 2] = d["th"][3][:, j] / Ms
        dmL[:, b + 3] = d["m"][3][:, j]
    out.update({"Jr": Jr, "Jv": Jv, "JB": JB, "Jt": Jt, "dmL_dr": dmL, "dmL_dv": dmL_dv})
    return out


def _clamp_derivs(g: Geom, i, us, M):
    """d(A, alpha, L)/d(scaled input) of leg i."""
    k = g.kind[i]
    dA = np.zeros((M, 2)); dal = np.zeros(M); dL = np.zeros(M)
    if k == "prismatic":
        dA[:] = np.array([np.cos(g.angle[i]), np.sin(g.angle[i])]) * us
    elif k == "revolute":
        dal[:] = us
    else:
        dL[:] = us
    return dA, dal, dL


def expand_rod(g: Geom, i, K, q, A, al, L, n_min=64):
    """Rod unknowns (M, 3 + 4 (K - 1)) from q (M, 3): nodes by integrating from the clamp."""
    M = len(q)
    Xr = np.zeros((M, 3 + 4 * (K - 1)))
    Xr[:, :3] = q
    if K == 1:
        return Xr
    Fs, Ms = g.F_ref, g.F_ref * g.L_ref
    EI = g.EI[i]
    n = q[:, :2] * Fs
    m = q[:, 2] * Ms
    ell = L / K
    xy, th = np.array(A, float), np.array(al, float)
    for j in range(1, K):
        ax, ay, mt = n[:, 0] * ell**2 / EI, n[:, 1] * ell**2 / EI, m * ell / EI
        Z, _S, _ = rk4_rods(ax, ay, mt, th, steps_for(ax, ay, mt, n_min=n_min), var=False)
        xy = xy + ell[:, None] * Z[:2].T
        th = Z[2]
        m = Z[3] * EI / ell
        b = 3 + 4 * (j - 1)
        Xr[:, b] = xy[:, 0] / g.L_ref
        Xr[:, b + 1] = xy[:, 1] / g.L_ref
        Xr[:, b + 2] = th
        Xr[:, b + 3] = m / Ms
    return Xr


class LegMS:
    """Leg i of an IK problem (pose fixed) in multiple-shooting form: unknowns x = (rod unknowns,
    scaled input) (M, 4 K), 4 K - 1 equations; see :func:`rod_block`."""

    def __init__(self, g: Geom, i: int, pose, K: int = 4, n_min=16, per_lambda=8.0):
        self.g, self.i, self.K = g, i, int(K)
        self.nr = 3 + 4 * (self.K - 1)
        self.pose = np.asarray(pose, float)
        c, s = np.cos(self.pose[2]), np.sin(self.pose[2])
        b = g.attach[i]
        self.arm = np.array([c * b[0] - s * b[1], s * b[0] + c * b[1]])
        self.B = self.pose[:2] + self.arm
        self.tip_th = float(self.pose[2] + g.tip_angle[i])
        self.us = g.u_scale()[i]
        self.n_min, self.per_lambda = n_min, per_lambda

    def clamp(self, v):
        A, al, L = self.g.clamp(self.i, np.asarray(v, float) * self.us)
        M = len(np.atleast_1d(v))
        return np.asarray(A, float).reshape(M, 2), np.asarray(al, float).reshape(M), np.asarray(L, float).reshape(M)

    def expand(self, q, v):
        A, al, L = self.clamp(v)
        return np.column_stack([expand_rod(self.g, self.i, self.K, q, A, al, L), v])

    def eval(self, x, jac=True, tight=False):
        x = np.atleast_2d(x)
        M = len(x)
        A, al, L = self.clamp(x[:, -1])
        out = rod_block(self.g, self.i, self.K, x[:, :-1], A, al, L, _clamp_derivs(self.g, self.i, self.us, M),
                        np.broadcast_to(self.B, (M, 2)), np.full(M, self.tip_th), jac=jac, n_min=self.n_min,
                        per_lambda=self.per_lambda, tight=tight)
        out["L"] = L
        if jac:
            out["J"] = np.concatenate([out["Jr"], out["Jv"][..., None]], axis=2)  # (M, 4K-1, 4K)
        return out

    def wrench(self, x, out):
        """Scaled platform wrench W (M, 3) and its derivative dW/dx (M, 3, 4K)."""
        g = self.g
        q = x[:, :3]
        M = len(x)
        cl = bool(g.clamped[self.i])
        W = np.column_stack([q[:, 0], q[:, 1], (self.arm[0] * q[:, 1] - self.arm[1] * q[:, 0]) / g.L_ref
                             + (out["mL"] if cl else 0.0)])
        dW = np.zeros((M, 3, x.shape[1]))
        dW[:, 0, 0] = 1.0
        dW[:, 1, 1] = 1.0
        dW[:, 2, 0] = -self.arm[1] / g.L_ref
        dW[:, 2, 1] = self.arm[0] / g.L_ref
        if cl:
            dW[:, 2, :-1] += out["dmL_dr"]
            dW[:, 2, -1] += out["dmL_dv"]
        return W, dW


class RodFK:
    """Rod i of an FK problem (inputs fixed, so its clamp is fixed) in multiple-shooting form, as a
    function of the platform pose: unknowns Xr (M, 4 K - 1) (see :func:`rod_block`)."""

    def __init__(self, g: Geom, i: int, inputs, K: int = 4, n_min=16, per_lambda=8.0):
        self.g, self.i, self.K = g, i, int(K)
        self.nr = 3 + 4 * (self.K - 1)
        A, al, L = g.clamp(i, np.asarray(float(np.asarray(inputs, float).reshape(3)[i])))
        self.A, self.al, self.L = np.asarray(A, float).reshape(2), float(al), float(L)
        self.n_min, self.per_lambda = n_min, per_lambda

    def arm(self, pose):
        b = self.g.attach[self.i]
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        return np.stack([c * b[0] - s * b[1], s * b[0] + c * b[1]], -1)

    def expand(self, q):
        M = len(q)
        return expand_rod(self.g, self.i, self.K, q, np.broadcast_to(self.A, (M, 2)), np.full(M, self.al),
                          np.full(M, self.L))

    def eval(self, Xr, pose, jac=True, tight=False):
        """:func:`rod_block` at the poses (M, 3) (physical); with ``jac`` also ``Jp`` (M, 4K-1, 3):
        the derivative of the rows w.r.t. the physical pose."""
        Xr = np.atleast_2d(Xr)
        pose = np.atleast_2d(pose)
        M = len(Xr)
        arm = self.arm(pose)
        B = pose[:, :2] + arm
        z0 = np.zeros(M)
        out = rod_block(self.g, self.i, self.K, Xr, np.broadcast_to(self.A, (M, 2)), np.full(M, self.al),
                        np.full(M, self.L), (np.zeros((M, 2)), z0, z0), B, pose[:, 2] + self.g.tip_angle[self.i],
                        jac=jac, n_min=self.n_min, per_lambda=self.per_lambda, tight=tight)
        out["arm"] = arm
        if jac:
            JB = out["JB"]
            Jp = np.empty(JB.shape[:2] + (3,))
            Jp[:, :, 0] = JB[:, :, 0]
            Jp[:, :, 1] = JB[:, :, 1]
            Jp[:, :, 2] = -JB[:, :, 0] * arm[:, 1:2] + JB[:, :, 1] * arm[:, 0:1] + out["Jt"]
            out["Jp"] = Jp
        return out

    def wrench(self, Xr, out):
        """Scaled platform wrench W (M, 3), dW/dXr (M, 3, nr) and the explicit dW/dpose (M, 3, 3)."""
        g = self.g
        Fs, Ms = g.F_ref, g.F_ref * g.L_ref
        arm = out["arm"]
        M = len(Xr)
        cl = bool(g.clamped[self.i])
        n = Xr[:, :2] * Fs
        W = np.column_stack([Xr[:, 0], Xr[:, 1], (arm[:, 0] * n[:, 1] - arm[:, 1] * n[:, 0]) / Ms
                             + (out["mL"] if cl else 0.0)])
        dW = np.zeros((M, 3, Xr.shape[1]))
        dW[:, 0, 0] = 1.0
        dW[:, 1, 1] = 1.0
        dW[:, 2, 0] = -arm[:, 1] / g.L_ref
        dW[:, 2, 1] = arm[:, 0] / g.L_ref
        if cl and "dmL_dr" in out:
            dW[:, 2] += out["dmL_dr"]
        dWp = np.zeros((M, 3, 3))
        dWp[:, 2, 2] = (-arm[:, 1] * n[:, 1] - arm[:, 0] * n[:, 0]) / Ms
        return W, dW, dWp


class MSSystem:
    """Multiple-shooting form of the IK (``problem="ik"``, ``fixed`` = pose) or FK
    (``problem="fk"``, ``fixed`` = inputs) equations; see the module docstring.  Unknowns: the
    three rods' unknowns then the 3 platform unknowns (IK: ``u / u_scale``; FK: ``x / L_ref,
    y / L_ref, theta``); rows: the rods' rows then the equilibrium (3)."""

    def __init__(self, g: Geom, problem: str, fixed, load, K: int = 4, n_min: int = 16, per_lambda: float = 8.0):
        self.g = g
        self.problem = problem
        self.fixed = np.asarray(fixed, float).reshape(3)
        self.load = np.asarray(load, float).reshape(3)
        self.K = int(K)
        self.n_min, self.per_lambda = int(n_min), float(per_lambda)
        self.cl = g.clamped
        self.us = g.u_scale()
        self.nr = 3 + 4 * (self.K - 1)
        self.n = 3 * self.nr + 3
        self.ps = np.array([g.L_ref, g.L_ref, 1.0])

    def platform(self, X):
        """Physical pose (N, 3) and inputs (N, 3)."""
        P = X[:, 3 * self.nr:]
        N = len(X)
        if self.problem == "ik":
            return np.broadcast_to(self.fixed, (N, 3)).copy(), P * self.us
        return P * self.ps, np.broadcast_to(self.fixed, (N, 3)).copy()

    def clamps(self, u):
        N = len(u)
        A = np.empty((N, 3, 2)); al = np.empty((N, 3)); L = np.empty((N, 3))
        for i in range(3):
            a, b, c = self.g.clamp(i, u[:, i])
            A[:, i], al[:, i], L[:, i] = a, b, c
        return A, al, L

    def expand(self, z):
        """Multiple-shooting unknowns (N, n) from 12-unknown vectors z (N, 12)."""
        z = np.atleast_2d(np.asarray(z, float))
        X = np.zeros((len(z), self.n))
        X[:, 3 * self.nr:] = z[:, 9:12]
        _pose, u = self.platform(X)
        A, al, L = self.clamps(u)
        for i in range(3):
            X[:, i * self.nr:(i + 1) * self.nr] = expand_rod(self.g, i, self.K, z[:, 3 * i:3 * i + 3], A[:, i],
                                                              al[:, i], L[:, i])
        return X

    def reduce(self, X):
        X = np.atleast_2d(X)
        z = np.empty((len(X), 12))
        for i in range(3):
            z[:, 3 * i:3 * i + 3] = X[:, i * self.nr:i * self.nr + 3]
        z[:, 9:12] = X[:, 3 * self.nr:]
        return z

    def eval(self, X, jac=True, tight=False):
        """Residual (N, n), Jacobian (N, n, n) (None unless ``jac``), d-mode estimates - 1 (interior
        sign changes, N, 3), turning (N, 3), tip moments / (F_ref L_ref) (N, 3)."""
        g, K = self.g, self.K
        X = np.atleast_2d(X)
        N = len(X)
        Fs, Ms = g.F_ref, g.F_ref * g.L_ref
        R = np.zeros((N, self.n))
        J = np.zeros((N, self.n, self.n)) if jac else None
        pose, u = self.platform(X)
        A, al, L = self.clamps(u)
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        b = g.attach
        arm = np.stack([c[:, None] * b[None, :, 0] - s[:, None] * b[None, :, 1],
                        s[:, None] * b[None, :, 0] + c[:, None] * b[None, :, 1]], -1)
        B = pose[:, None, :2] + arm
        pc = 3 * self.nr
        nrow = 4 * K - 1
        eqr = 3 * nrow
        changes = np.zeros((N, 3), np.int64)
        turning = np.zeros((N, 3))
        mLs = np.zeros((N, 3))
        for i in range(3):
            o = i * self.nr
            ro = i * nrow
            Xr = X[:, o:o + self.nr]
            dcl = _clamp_derivs(g, i, self.us[i], N) if self.problem == "ik" else (np.zeros((N, 2)), np.zeros(N),
                                                                                   np.zeros(N))
            tip_th = pose[:, 2] + g.tip_angle[i]
            blk = rod_block(g, i, K, Xr, A[:, i], al[:, i], L[:, i], dcl, B[:, i], tip_th, jac=jac, n_min=self.n_min,
                            per_lambda=self.per_lambda, tight=tight)
            R[:, ro:ro + nrow] = blk["R"]
            changes[:, i] = blk["changes"]
            turning[:, i] = blk["turning"]
            mLs[:, i] = blk["mL"]
            n = Xr[:, :2] * Fs
            R[:, eqr] += Xr[:, 0]
            R[:, eqr + 1] += Xr[:, 1]
            R[:, eqr + 2] += (arm[:, i, 0] * n[:, 1] - arm[:, i, 1] * n[:, 0]) / Ms
            if self.cl[i]:
                R[:, eqr + 2] += blk["mL"]
            if not jac:
                continue
            J[:, ro:ro + nrow, o:o + self.nr] = blk["Jr"]
            if self.problem == "ik":
                J[:, ro:ro + nrow, pc + i] = blk["Jv"]
            else:
                # B = P + arm(theta), tip_th = theta + tip_angle; pose scaled (x/L_ref, y/L_ref, theta)
                JB = blk["JB"]
                J[:, ro:ro + nrow, pc] += JB[:, :, 0] * g.L_ref
                J[:, ro:ro + nrow, pc + 1] += JB[:, :, 1] * g.L_ref
                J[:, ro:ro + nrow, pc + 2] += JB[:, :, 0] * (-arm[:, i, 1:2]) + JB[:, :, 1] * arm[:, i, 0:1]
                J[:, ro:ro + nrow, pc + 2] += blk["Jt"]
            J[:, eqr, o] += 1.0
            J[:, eqr + 1, o + 1] += 1.0
            J[:, eqr + 2, o] += -arm[:, i, 1] / g.L_ref
            J[:, eqr + 2, o + 1] += arm[:, i, 0] / g.L_ref
            if self.problem == "fk":
                J[:, eqr + 2, pc + 2] += (-arm[:, i, 1] * n[:, 1] - arm[:, i, 0] * n[:, 0]) / Ms
            if self.cl[i]:
                J[:, eqr + 2, o:o + self.nr] += blk["dmL_dr"]
                if self.problem == "ik":
                    J[:, eqr + 2, pc + i] += blk["dmL_dv"]
        R[:, eqr] -= self.load[0] / Fs
        R[:, eqr + 1] -= self.load[1] / Fs
        R[:, eqr + 2] -= self.load[2] / Ms
        return R, J, changes, turning, mLs

    def newton(self, X, n_iter=30, tol=1e-10, blow=5e3):
        """Damped batch Newton.  Returns X, residual inf-norm, d-modes (N, 3), turning (N, 3)."""
        g = self.g
        X = np.array(X, float)
        N = len(X)
        active = np.ones(N, bool)
        for _ in range(n_iter):
            idx = np.flatnonzero(active)
            if not idx.size:
                break
            R, J, *_ = self.eval(X[idx])
            rn = np.max(np.abs(R), axis=1)
            done = rn < tol
            step = solve_batch(J, -R)
            bad = ~np.all(np.isfinite(step), axis=1)
            step[bad] = 0.0
            lim = np.max(np.abs(step[:, 3 * self.nr:]), axis=1) / 0.3
            Lr = self.clamps(self.platform(X[idx])[1])[2]
            Rmax = np.zeros(len(idx))
            for i in range(3):
                o = i * self.nr
                fs = g.F_ref * Lr[:, i] ** 2 / g.EI[i]
                Rd = np.hypot(X[idx, o], X[idx, o + 1]) * fs
                Rmax = np.maximum(Rmax, Rd)
                lim = np.maximum(lim, np.hypot(step[:, o], step[:, o + 1]) * fs / (0.5 * Rd + 3.0))
                if self.K > 1:
                    th_cols = o + 3 + 4 * np.arange(self.K - 1) + 2
                    lim = np.maximum(lim, np.max(np.abs(step[:, th_cols]), axis=1) / 0.5)
            step *= (1.0 / np.maximum(lim, 1.0))[:, None]
            upd = ~done & ~bad
            X[idx[upd]] += step[upd]
            blown = (Rmax > blow) | ~np.all(np.isfinite(X[idx]), axis=1)
            active[idx[done | bad | blown]] = False
        R, _, ch, turn, _ = self.eval(X, jac=False)
        return X, np.max(np.abs(R), axis=1), ch + 1, turn

    def polish(self, X, n_iter=6, tol=1e-12):
        """Quasi-Newton with the tight residual (DOP853 segments) and the RK4 Jacobian (many steps).
        Returns the best iterate and its tight residual (inf-norm)."""
        X = np.atleast_2d(np.array(X, float))
        best = X.copy()
        best_r = np.full(len(X), np.inf)
        fine = MSSystem(self.g, self.problem, self.fixed, self.load, self.K, n_min=256, per_lambda=32.0)
        active = np.ones(len(X), bool)
        for _ in range(n_iter + 1):
            idx = np.flatnonzero(active)
            if not idx.size:
                break
            R = self.eval(X[idx], jac=False, tight=True)[0]
            rn = np.max(np.abs(R), axis=1)
            better = rn < best_r[idx]
            best_r[idx[better]] = rn[better]
            best[idx[better]] = X[idx[better]]
            go = rn >= tol
            active[idx[~go]] = False
            idx, R = idx[go], R[go]
            if not idx.size:
                break
            J = fine.eval(X[idx])[1]
            step = solve_batch(J, -R)
            fin = np.all(np.isfinite(step), axis=1)
            X[idx[fin]] += step[fin]
            active[idx[~fin]] = False
        return best, best_r


def solve_batch(J, B):
    """Batched ``J x = B`` for ``B`` (M, n) or (M, n, k); a singular system gives NaN."""
    vec = B.ndim == J.ndim - 1
    Bm = B[..., None] if vec else B
    with np.errstate(all="ignore"):
        try:
            X = np.linalg.solve(J, Bm)
        except np.linalg.LinAlgError:
            X = np.full(Bm.shape, np.nan)
            for k in range(len(Bm)):
                try:
                    X[k] = np.linalg.solve(J[k], Bm[k])
                except np.linalg.LinAlgError:
                    pass
    return X[..., 0] if vec else X
