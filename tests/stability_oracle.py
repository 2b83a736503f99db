"""Independent stability oracle for planar Kirchhoff rods and parallel continuum mechanisms (test-only).

Nothing here calls a flexkin solver or flexkin's stability code.  The only thing read from a
:class:`flexkin.Mechanism` is its plain geometry, through ``ik_oracle.Geom`` (clamps rebuilt
by hand from SPEC §2).  The method is a *direct discretisation* of the total potential, a
different route from the library's exact (Jacobi conjugate-point + reduced Hessian) test.

Discretisation
--------------
Each rod (length L, stiffness EI, clamp C, clamp angle alpha) is cut into N equal segments of
length h = L/N with piecewise-constant tangent angles theta_j (j = 1..N) -- theta_j is the
angle at the segment midpoint s_j = (j - 1/2) h.  Then

    tip      r = C + h sum_j (cos theta_j, sin theta_j)                     (midpoint rule)
    energy   E = EI/(2h) [ 2 (theta_1 - alpha)^2 + sum_{j>=2} (theta_j - theta_{j-1})^2 ]

The clamp term is the half-cell difference (theta_1 - alpha)/(h/2) over the length h/2 (a
ghost-point Dirichlet condition); the pinned tip is a natural (Neumann) end with no term.  A
CLAMPED tip (rod welded to the platform, or a single rod whose tip tangent is prescribed) gets the
same half-cell Dirichlet term at the tip,

    E_tip = EI/(2h) * 2 (theta_tip - theta_N)^2,   theta_tip = theta_p + beta_i  (mechanism)
                                                   or a fixed angle           (single rod),

with beta_i = tip_angle_i + 2 pi k_i (k_i from the continuous solution: rods whose tangent turns
by an extra 2 pi are other configurations).  So the perturbation obeys eta_i(L) = delta theta_p,
the tip moment is m_i(L) = 2 EI (theta_tip - theta_N)/h (the moment ON the rod tip BY the
platform) and the platform's rotational equilibrium gets -sum_i m_i(L).
Both ends are second-order: eigenvalues, tip forces and poses converge like h^2, which is
checked (N and 2N) and used for a Richardson extrapolation of the smallest eigenvalue.

Problem
-------
Unknowns z = (all theta_{i,j}, rigid coordinates q), multipliers lambda.  Potential

    V = sum_i E_i - sum_i F_i . r_i + U(q)           (F_i: dead loads on rod tips, if any)

with affine-in-tip constraints  g = sum_i G_i r_i + c(q) = 0.  Lagrangian W = V - lambda . g,
so that the total force on the tip of rod i is n_i = F_i + G_i^T lambda (SPEC §2 sign: the
force ON the rod tip).  Cases:

* mechanism: q = pose (x, y, theta_p), U = -F.P - M theta_p, g_i = r_i - P - Rot(theta_p) b_i
  (lambda_i = n_i, the rod tip forces); clamped legs add their tip terms E_tip (coupling their
  last angle to theta_p);
* single rod, tip ``free`` under a dead load (no constraint), on a straight ``slider`` (one
  constraint d.(r - r0) = 0, d normal to the line; dead load, tip rotation free), or
  ``pinned`` at a point (two constraints, the tip force is a reaction).

The DISCRETE equilibrium is solved first (Newton on the KKT system, started from the given
continuous solution sampled at the segment midpoints), so that the Hessian is evaluated at a
true discrete critical point with the discrete multipliers.  The stability problem is the
generalized eigenproblem of the Hessian H of W on the null space Z of the constraint Jacobian A

    Z^T H Z v = mu Z^T D Z v,   D = diag(h/L_ref on angles; 1/L_ref^2 on x, y; 1 on theta_p)

Default solver (O(N)): H is block tridiagonal, so the KKT matrix [[H - sigma D, -A^T], [-A, 0]]
is factorised by banded elimination of the rods plus a Schur complement on (q, lambda); its
inertia minus m is the number of eigenvalues below sigma (index at sigma = 0; the smallest
eigenvalues by bisection in sigma).  ``method="dense"`` instead forms Z^T H Z explicitly
(scipy null_space + eigh), which the tests use to cross-check the banded path.
mu is reported dimensionless, in units of EI_ref/L_ref (H is divided by that; L_ref, EI_ref
are the mean rod length and stiffness).
With this mass the continuous limit of mu is the Rayleigh quotient of the second variation
over int(delta theta^2) ds / L: e.g. for a straight cantilever under an axial compressive
dead load p EI/L^2, mu_k = ((2k-1) pi/2)^2 - p exactly.  Stable <=> mu_min > 0 (index 0).
"""

from __future__ import annotations

import math
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import eigh, null_space, solve_banded
from scipy.optimize import brentq

sys.path.insert(0, os.path.dirname(__file__))

__all__ = [
    "ContinuousRod",
    "DiscreteEquilibrium",
    "RodSpec",
    "StabilityResult",
    "Tip",
    "cantilever_elastica",
    "critical_load",
    "mechanism_rods",
    "mechanism_stability",
    "sample_rod",
    "single_rod_equilibria",
    "single_rod_stability",
    "solution_stability",
]

DEFAULT_N = 200


# ======================================================================================
# input data
# ======================================================================================
@dataclass(frozen=True)
class RodSpec:
    """One rod: clamp point (m), clamp tangent angle (rad), free length (m), EI (N m^2); for a
    mechanism leg also its platform joint ("pinned" | "clamped") and, if clamped, its tip tangent
    in the platform frame (rad)."""

    clamp: tuple[float, float]
    clamp_angle: float
    length: float
    EI: float
    joint: str = "pinned"
    tip_angle: float = 0.0


@dataclass(frozen=True)
class Tip:
    """Boundary condition of a single rod's tip (world frame, SI).

    kind: ``"free"`` (dead ``load`` only), ``"slider"`` (tip on the line through ``point``
    with unit ``direction``; ``load`` dead; rotation free) or ``"pinned"`` (tip at ``point``;
    ``load`` is normally zero, the pin reaction is a multiplier).
    """

    kind: str
    load: tuple[float, float] = (0.0, 0.0)
    point: tuple[float, float] | None = None
    direction: tuple[float, float] | None = None
    angle: float | None = None  # prescribed tip tangent (world, rad): a clamped tip; None: rotation free

    @staticmethod
    def free(load) -> Tip:
        return Tip("free", (float(load[0]), float(load[1])))

    @staticmethod
    def slider(point, direction, load=(0.0, 0.0)) -> Tip:
        d = np.asarray(direction, float)
        d = d / np.linalg.norm(d)
        return Tip("slider", (float(load[0]), float(load[1])), (float(point[0]), float(point[1])),
                   (float(d[0]), float(d[1])))

    @staticmethod
    def pinned(point, load=(0.0, 0.0)) -> Tip:
        return Tip("pinned", (float(load[0]), float(load[1])), (float(point[0]), float(point[1])))

    @staticmethod
    def clamped(point, angle, load=(0.0, 0.0)) -> Tip:
        """Tip at ``point`` with its tangent prescribed (``angle``, world, rad): a clamped-clamped rod."""
        return Tip("pinned", (float(load[0]), float(load[1])), (float(point[0]), float(point[1])), None, float(angle))

    @staticmethod
    def guided(point, direction, angle, load=(0.0, 0.0)) -> Tip:
        """Tip on the line through ``point`` along ``direction`` with its tangent prescribed
        (``angle``): e.g. a clamped-clamped column loaded axially (the tip slides along the axis)."""
        t = Tip.slider(point, direction, load)
        return Tip("slider", t.load, t.point, t.direction, float(angle))

    # constraint rows G (m, 2) and constant part c0 (m,): g = G r + c0
    def rows(self) -> tuple[np.ndarray, np.ndarray]:
        if self.kind == "free":
            return np.zeros((0, 2)), np.zeros(0)
        if self.kind == "slider":
            t = np.asarray(self.direction, float)
            d = np.array([-t[1], t[0]])
            return d[None, :], np.array([-d @ np.asarray(self.point, float)])
        if self.kind == "pinned":
            return np.eye(2), -np.asarray(self.point, float)
        raise ValueError(f"unknown tip kind {self.kind!r}")


@dataclass(frozen=True)
class ContinuousRod:
    """A continuous equilibrium of one rod: total tip force n (N, on the rod tip) and m0 (N m)."""

    tip_force: tuple[float, float]
    base_moment: float
    mode: int = 0
    tip: tuple[float, float] | None = None
    tip_angle: float | None = None
    tip_moment: float | None = None  # residual m(L) (N m)


# ======================================================================================
# results
# ======================================================================================
@dataclass
class DiscreteEquilibrium:
    N: int
    thetas: list[np.ndarray]  # per rod, angles at segment midpoints
    q: np.ndarray  # rigid coordinates (pose for a mechanism; empty for one rod)
    lam: np.ndarray  # multipliers
    tip_forces: np.ndarray  # (R, 2) total force on each rod tip (dead + reaction)
    tips: np.ndarray  # (R, 2)
    residual: float  # scaled KKT residual (inf norm)
    iterations: int
    converged: bool
    base_moments: np.ndarray  # (R,) discrete EI theta'(0) = 2 EI (theta_1 - alpha)/h
    tip_moments: np.ndarray | None = None  # (R,) clamped tips: 2 EI (theta_tip - theta_N)/h; 0 otherwise


@dataclass
class StabilityResult:
    """Verdict of the oracle.

    ``stable``: index == 0 at both resolutions and min_eig > 0.  ``index``: number of negative
    eigenvalues of the constrained second variation at the finest N.  ``min_eig``: smallest
    eigenvalue, Richardson-extrapolated from N/2 and N (dimensionless, units EI_ref/L_ref).
    ``N``: finest resolution (segments per rod).
    """

    stable: bool
    index: int
    min_eig: float
    N: int
    min_eig_coarse: float = math.nan  # at N/2
    min_eig_fine: float = math.nan  # at N
    index_coarse: int = -1
    eigs: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)  # lowest few at N
    converged: bool = True  # indices agree at N/2 and N and the eigenvalue change is small
    equilibrium: DiscreteEquilibrium | None = field(default=None, repr=False)
    equilibrium_coarse: DiscreteEquilibrium | None = field(default=None, repr=False)


# ======================================================================================
# continuous rod by ODE (independent of flexkin), sampled at the segment midpoints
# ======================================================================================
def _ode(n, EI):
    nx, ny = float(n[0]), float(n[1])

    def f(_s, z):
        c, s = math.cos(z[2]), math.sin(z[2])
        return [c, s, z[3] / EI, nx * s - ny * c]

    return f


def sample_rod(rod: RodSpec, tip_force, base_moment, N: int, rtol=1e-12, atol=1e-13):
    """Integrate x' = cos th, y' = sin th, th' = m/EI, m' = n_x sin th - n_y cos th from the clamp.

    Returns (theta at the N segment midpoints, tip (2,), tip angle, tip moment).
    """
    L = rod.length
    s_mid = (np.arange(N) + 0.5) * (L / N)
    t_eval = np.concatenate([s_mid, [L]])
    z0 = [rod.clamp[0], rod.clamp[1], rod.clamp_angle, float(base_moment)]
    sol = solve_ivp(_ode(tip_force, rod.EI), (0.0, L), z0, method="DOP853", rtol=rtol,
                    atol=atol * max(1.0, abs(base_moment), L), t_eval=t_eval)
    y = sol.y
    return y[2, :N].copy(), y[:2, -1].copy(), float(y[2, -1]), float(y[3, -1])


# ======================================================================================
# the discrete problem
# ======================================================================================
class _Problem:
    """Rods + rigid coordinates + affine-in-tip constraints (see module docstring).

    The Hessian of W is block diagonal: one symmetric tridiagonal block per rod and a small
    block for q; the constraint Jacobian has m (<= 6) rows.  All linear algebra exploits that:
    the KKT matrix [[H - sigma D, -A^T], [-A, 0]] is factorised by eliminating the rod blocks
    (banded LU) and a Schur complement on the border (q, lambda), in O(N).  Its inertia is
    inertia(T) + inertia(Schur) (Haynsworth), and the number of constrained eigenvalues below
    sigma is n_neg(KKT) - m; this count gives the index (sigma = 0) and, by bisection, the
    smallest eigenvalues.  A dense null-space path (:meth:`spectrum_dense`) is kept to
    cross-check it.
    """

    def __init__(self, rods: Sequence[RodSpec], Ns: Sequence[int], dead: np.ndarray, G: np.ndarray,
                 nq: int, c, dc, hc, U, gU, hU, q_mass: np.ndarray, L_ref: float, EI_ref: float,
                 q_res_scale=None, q_step_scale=None, tip_targets=None, tip_q: int | None = None):
        """``tip_targets``: per rod None (tip rotation free) or the constant c_i of a clamped tip
        theta_tip = c_i (+ q[tip_q] when ``tip_q`` is given: the platform rotation)."""
        self.tip_targets = [None] * len(rods) if tip_targets is None else list(tip_targets)
        self.tip_q = tip_q
        self.rods = list(rods)
        self.Ns = [int(n) for n in Ns]
        self.h = np.array([r.length / n for r, n in zip(self.rods, self.Ns)])
        self.off = np.concatenate([[0], np.cumsum(self.Ns)]).astype(int)
        self.nt = int(self.off[-1])
        self.nq = nq
        self.n = self.nt + nq
        self.dead = np.asarray(dead, float).reshape(len(self.rods), 2)
        self.G = np.asarray(G, float)  # (R, m, 2)
        self.m = self.G.shape[1]
        self.c, self.dc, self.hc, self.U, self.gU, self.hU = c, dc, hc, U, gU, hU
        self.q_mass = np.asarray(q_mass, float)
        self.L_ref, self.EI_ref = float(L_ref), float(EI_ref)
        self.e_scale = self.EI_ref / self.L_ref  # eigenvalues are reported in units of EI_ref/L_ref
        self.q_res_scale = np.ones(nq) if q_res_scale is None else np.asarray(q_res_scale, float)
        self.q_step_scale = np.ones(nq) if q_step_scale is None else np.asarray(q_step_scale, float)

    # ---- pieces ------------------------------------------------------------------------
    def split(self, z):
        return [z[self.off[i]:self.off[i + 1]] for i in range(len(self.rods))], z[self.nt:]

    def pack(self, thetas, q):
        return np.concatenate([np.concatenate(thetas), np.asarray(q, float)])

    def tips(self, z):
        th, _ = self.split(z)
        return np.array([np.asarray(r.clamp) + h * np.array([np.cos(t).sum(), np.sin(t).sum()])
                         for r, h, t in zip(self.rods, self.h, th)])

    def tip_forces(self, lam):
        return self.dead + np.einsum("imk,m->ik", self.G, lam)

    def constraint(self, z):
        _, q = self.split(z)
        return np.einsum("imk,ik->m", self.G, self.tips(z)) + self.c(q)

    def tip_theta(self, i, q):
        """Prescribed tip tangent of rod i (None if its tip rotation is free)."""
        c = self.tip_targets[i]
        if c is None:
            return None
        return float(c) + (float(q[self.tip_q]) if self.tip_q is not None else 0.0)

    def potential(self, z):
        """V = sum E_i - sum F_i . r_i + U(q) (J)."""
        th, q = self.split(z)
        V = 0.0
        for i, (rod, h, t) in enumerate(zip(self.rods, self.h, th)):
            V += rod.EI / (2.0 * h) * (2.0 * (t[0] - rod.clamp_angle) ** 2 + float(np.sum(np.diff(t) ** 2)))
            tt = self.tip_theta(i, q)
            if tt is not None:
                V += rod.EI / (2.0 * h) * 2.0 * (tt - t[-1]) ** 2
        V -= float(np.sum(self.dead * self.tips(z)))
        return V + (float(self.U(q)) if self.nq else 0.0)

    def tip_moments(self, z):
        """Discrete tip moments 2 EI (theta_tip - theta_N)/h (0 for free tip rotation)."""
        th, q = self.split(z)
        out = np.zeros(len(self.rods))
        for i, (rod, h, t) in enumerate(zip(self.rods, self.h, th)):
            tt = self.tip_theta(i, q)
            if tt is not None:
                out[i] = 2.0 * rod.EI * (tt - t[-1]) / h
        return out

    def couplings(self):
        """Per rod the Hessian block (N_i, nq) coupling its angles to q (clamped tips tied to q)."""
        out = []
        for i, (rod, h, n) in enumerate(zip(self.rods, self.h, self.Ns)):
            C = np.zeros((n, self.nq))
            if self.tip_targets[i] is not None and self.tip_q is not None:
                C[-1, self.tip_q] = -2.0 * rod.EI / h
            out.append(C)
        return out

    def jac_rods(self, z):
        """Per rod A_i (m, N_i) = G_i d r_i / d theta_i; and A_q (m, nq)."""
        th, q = self.split(z)
        A = [self.G[i] @ (h * np.stack([-np.sin(t), np.cos(t)])) for i, (h, t) in enumerate(zip(self.h, th))]
        Aq = self.dc(q) if self.nq else np.zeros((self.m, 0))
        return A, Aq

    def jac(self, z):
        A, Aq = self.jac_rods(z)
        return np.concatenate(A + [Aq], axis=1)

    def grad(self, z, lam):
        """Gradient of the Lagrangian W = V - lam . g with respect to z."""
        th, q = self.split(z)
        n_tip = self.tip_forces(lam)
        g = np.zeros(self.n)
        gq_tip = np.zeros(self.nq)
        for i, (rod, h, t) in enumerate(zip(self.rods, self.h, th)):
            k = rod.EI / h
            d = np.diff(t)
            gi = np.zeros(len(t))
            gi[0] += 2.0 * k * (t[0] - rod.clamp_angle)
            gi[1:] += k * d
            gi[:-1] -= k * d
            tt = self.tip_theta(i, q)
            if tt is not None:
                gi[-1] += 2.0 * k * (t[-1] - tt)
                if self.tip_q is not None:
                    gq_tip[self.tip_q] -= 2.0 * k * (t[-1] - tt)
            gi -= h * (-n_tip[i, 0] * np.sin(t) + n_tip[i, 1] * np.cos(t))
            g[self.off[i]:self.off[i + 1]] = gi
        if self.nq:
            g[self.nt:] = self.gU(q) - self.dc(q).T @ lam + gq_tip
        return g

    def rod_blocks(self, z, lam, sigma=0.0):
        """Tridiagonal (diag, off) of H_i - sigma e_scale D_i for every rod."""
        th, _ = self.split(z)
        n_tip = self.tip_forces(lam)
        out = []
        for i, (rod, h, t) in enumerate(zip(self.rods, self.h, th)):
            N = len(t)
            k = rod.EI / h
            diag = np.full(N, 2.0 * k)
            diag[0] = 3.0 * k if N > 1 else 2.0 * k
            if N > 1:
                diag[-1] = k
            if self.tip_targets[i] is not None:
                diag[-1] += 2.0 * k  # half-cell Dirichlet term at a clamped tip
            diag += h * (n_tip[i, 0] * np.cos(t) + n_tip[i, 1] * np.sin(t))
            diag -= sigma * self.e_scale * h / self.L_ref
            out.append((diag, np.full(N - 1, -k)))
        return out

    def q_block(self, z, lam, sigma=0.0):
        _, q = self.split(z)
        if not self.nq:
            return np.zeros((0, 0))
        H = self.hU(q) - self.hc(q, lam) - sigma * self.e_scale * np.diag(self.q_mass)
        if self.tip_q is not None:
            for i, (rod, h) in enumerate(zip(self.rods, self.h)):
                if self.tip_targets[i] is not None:
                    H[self.tip_q, self.tip_q] += 2.0 * rod.EI / h
        return H

    def mass_diag(self):
        D = np.empty(self.n)
        for i, h in enumerate(self.h):
            D[self.off[i]:self.off[i + 1]] = h / self.L_ref
        D[self.nt:] = self.q_mass
        return D

    def hess_dense(self, z, lam):
        H = np.zeros((self.n, self.n))
        for i, (d, e) in enumerate(self.rod_blocks(z, lam)):
            sl = slice(self.off[i], self.off[i + 1])
            H[sl, sl] = np.diag(d) + np.diag(e, 1) + np.diag(e, -1)
        H[self.nt:, self.nt:] = self.q_block(z, lam)
        for i, C in enumerate(self.couplings()):
            sl = slice(self.off[i], self.off[i + 1])
            H[sl, self.nt:] = C
            H[self.nt:, sl] = C.T
        return H

    # ---- structured KKT factorisation ----------------------------------------------------
    def kkt(self, z, lam, sigma=0.0) -> _KKT:
        A, Aq = self.jac_rods(z)
        return _KKT(self.rod_blocks(z, lam, sigma), A, Aq, self.q_block(z, lam, sigma), self.couplings())

    def count_below(self, z, lam, sigma) -> int:
        """Number of constrained eigenvalues (units e_scale) below sigma."""
        return self.kkt(z, lam, sigma).n_neg - self.m

    def lowest(self, z, lam, k=1, rtol=1e-11):
        """The k smallest constrained eigenvalues by bisection on :meth:`count_below`."""
        lo = -1.0
        while self.count_below(z, lam, lo) > 0:
            lo *= 4.0
        hi = 1.0
        while self.count_below(z, lam, hi) < k:
            hi *= 4.0
        out = []
        for j in range(1, k + 1):
            a, b = lo, hi
            while b - a > rtol * max(1.0, abs(a), abs(b)):
                mid = 0.5 * (a + b)
                if self.count_below(z, lam, mid) >= j:
                    b = mid
                else:
                    a = mid
            out.append(0.5 * (a + b))
            lo = a
        return np.array(out)

    def spectrum_dense(self, z, lam):
        """All constrained eigenvalues, dense: Z = null(A), eig(Z^T H Z, Z^T D Z) (validation)."""
        H = self.hess_dense(z, lam) / self.e_scale
        D = self.mass_diag()
        if self.m:
            Z = null_space(self.jac(z))
            Hr = Z.T @ H @ Z
            Mr = Z.T @ (D[:, None] * Z)
        else:
            Hr, Mr = H, np.diag(D)
        return eigh(0.5 * (Hr + Hr.T), 0.5 * (Mr + Mr.T), eigvals_only=True)

    def scales(self):
        """Scale of each KKT residual: angles -> h EI/L^2, q -> wrench, constraints -> L."""
        fs = self.EI_ref / self.L_ref**2
        s = np.empty(self.n + self.m)
        for i, h in enumerate(self.h):
            s[self.off[i]:self.off[i + 1]] = h * fs
        s[self.nt:self.n] = self.q_res_scale
        s[self.n:] = self.L_ref
        return s

    # ---- Newton on the KKT system --------------------------------------------------------
    def lsq_multipliers(self, z):
        if self.m == 0:
            return np.zeros(0)
        g = self.grad(z, np.zeros(self.m))
        return np.linalg.lstsq(self.jac(z).T, g, rcond=None)[0]

    def newton(self, z0, lam0=None, tol=1e-11, max_iter=60, max_dtheta=0.3) -> DiscreteEquilibrium:
        z = np.array(z0, float)
        lam = self.lsq_multipliers(z) if lam0 is None else np.array(lam0, float)
        sc = self.scales()
        # attainable accuracy: the angle residual is a second difference EI (theta_j+1 - 2 theta_j
        # + theta_j-1)/h scaled by h EI/L^2, i.e. rounding is amplified like N^2
        tol = max(tol, 50.0 * np.finfo(float).eps * max(self.Ns) ** 2)
        res, it, converged, small = math.inf, 0, False, 0
        for it in range(max_iter + 1):
            g = self.grad(z, lam)
            cst = self.constraint(z)
            F = np.concatenate([g, cst])
            res = float(np.max(np.abs(F / sc))) if F.size else 0.0
            if res < tol or (small >= 2 and res < 1e3 * tol):
                converged = True
                break
            if it == max_iter:
                break
            # [[H, -A^T], [-A, 0]] [dz; dlam] = [-g; cst]
            dz, dlam = self.kkt(z, lam).solve(-g, cst)
            dth = float(np.max(np.abs(dz[:self.nt]))) if self.nt else 0.0
            if self.nq:
                dth = max(dth, float(np.max(np.abs(dz[self.nt:] / self.q_step_scale))))
            fac = min(1.0, max_dtheta / dth) if dth > 0 else 1.0
            small = small + 1 if dth < 1e-12 else 0
            z += fac * dz
            lam += fac * dlam
        th, q = self.split(z)
        base = np.array([2.0 * r.EI * (t[0] - r.clamp_angle) / h for r, h, t in zip(self.rods, self.h, th)])
        return DiscreteEquilibrium(N=self.Ns[0], thetas=[t.copy() for t in th], q=q.copy(), lam=lam.copy(),
                                   tip_forces=self.tip_forces(lam), tips=self.tips(z), residual=res,
                                   iterations=it, converged=converged, base_moments=base,
                                   tip_moments=self.tip_moments(z))


def _tridiag_neg(d, e) -> int:
    """Negative eigenvalues of the symmetric tridiagonal (d, e): signs of the LDL^T pivots."""
    neg = 0
    piv = 1.0
    tiny = 1e-300
    for j in range(len(d)):
        piv = d[j] - (e[j - 1] * e[j - 1] / piv if j else 0.0)
        if piv == 0.0:
            piv = -tiny if j else tiny
        if piv < 0.0:
            neg += 1
    return neg


class _KKT:
    """Factorisation of [[T, C], [C^T, K_bb]] with T = blockdiag(tridiagonal rod blocks).

    Unknown order (theta_rods, q, lambda); C_i = [H_iq, -A_i^T] couples rod i to q (through a
    clamped tip tied to the platform rotation; else zero) and lambda; K_bb = [[H_qq, -A_q^T],
    [-A_q, 0]].
    """

    def __init__(self, blocks, A, Aq, Hqq, couplings=None):
        self.blocks = blocks
        self.A = A
        nq = Hqq.shape[0]
        m = Aq.shape[0]
        self.nq, self.m = nq, m
        nb = nq + m
        Kbb = np.zeros((nb, nb))
        Kbb[:nq, :nq] = Hqq
        Kbb[:nq, nq:] = -Aq.T
        Kbb[nq:, :nq] = -Aq
        self.n_neg = 0
        self.X = []  # T_i^{-1} C_i
        self.ab = []
        self.C = []
        S = Kbb.copy()
        if couplings is None:
            couplings = [np.zeros((len(d), nq)) for d, _ in blocks]
        for (d, e), Ai, Hiq in zip(blocks, A, couplings):
            N = len(d)
            ab = np.zeros((3, N))
            ab[0, 1:] = e
            ab[1] = d
            ab[2, :-1] = e
            self.ab.append(ab)
            self.n_neg += _tridiag_neg(d, e)
            Ci = np.zeros((N, nb))
            Ci[:, :nq] = Hiq
            Ci[:, nq:] = -Ai.T
            self.C.append(Ci)
            Xi = solve_banded((1, 1), ab, Ci) if nb else np.zeros((N, 0))
            self.X.append(Xi)
            S -= Ci.T @ Xi
        self.S = 0.5 * (S + S.T)
        if nb:
            self.n_neg += int(np.sum(np.linalg.eigvalsh(self.S) < 0.0))

    def solve(self, r_z, r_lam):
        """Solve [[H, -A^T], [-A, 0]] [dz; dlam] = [r_z; r_lam]."""
        nq, m = self.nq, self.m
        nt = sum(len(d) for d, _ in self.blocks)
        r_t = r_z[:nt]
        rb = np.concatenate([r_z[nt:], r_lam])
        Y = []
        o = 0
        for ab, Ci in zip(self.ab, self.C):
            N = ab.shape[1]
            yi = solve_banded((1, 1), ab, r_t[o:o + N])
            Y.append(yi)
            rb = rb - Ci.T @ yi
            o += N
        xb = np.linalg.solve(self.S, rb) if nq + m else np.zeros(0)
        xt = np.concatenate([yi - Xi @ xb for yi, Xi in zip(Y, self.X)])
        return np.concatenate([xt, xb[:nq]]), xb[nq:]


def _evaluate(build: Callable[[int], tuple[_Problem, np.ndarray, np.ndarray | None]], N: int,
              n_low: int = 1, method: str = "banded", rel_change: float = 0.05) -> StabilityResult:
    """Solve the discrete equilibrium and the spectrum at N/2 and N; Richardson on mu_min.

    method ``"banded"`` (default): index from the KKT inertia, lowest eigenvalues by
    bisection; ``"dense"``: full null-space generalized eigenproblem (for cross-checks).
    """
    out = []
    for n in (N // 2, N):
        prob, z0, lam0 = build(n)
        eq = prob.newton(z0, lam0)
        z = prob.pack(eq.thetas, eq.q)
        if method == "dense":
            w = prob.spectrum_dense(z, eq.lam)
            idx = int(np.sum(w < 0.0))
            w = w[:max(n_low, 1)]
        else:
            idx = prob.count_below(z, eq.lam, 0.0)
            w = prob.lowest(z, eq.lam, max(n_low, 1))
        out.append((eq, w, idx))
    (eq_c, w_c, idx_c), (eq_f, w_f, idx_f) = out
    mc, mf = float(w_c[0]), float(w_f[0])
    ext = (4.0 * mf - mc) / 3.0
    conv = (idx_c == idx_f and eq_c.converged and eq_f.converged
            and abs(mf - mc) <= rel_change * max(abs(mf), 1e-3))
    stable = idx_f == 0 and idx_c == 0 and ext > 0.0
    return StabilityResult(stable=stable, index=idx_f, min_eig=ext, N=N, min_eig_coarse=mc, min_eig_fine=mf,
                           index_coarse=idx_c, eigs=np.asarray(w_f).copy(), converged=conv, equilibrium=eq_f,
                           equilibrium_coarse=eq_c)


# ======================================================================================
# mechanism
# ======================================================================================
def _rot(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def _mechanism_problem(rods: Sequence[RodSpec], attach, load, N: int, tip_targets=None) -> _Problem:
    """``tip_targets``: per rod None (pinned) or beta_i (clamped: theta_tip = theta_p + beta_i)."""
    b = np.asarray(attach, float).reshape(3, 2)
    F = np.asarray(load, float).reshape(3)
    R = len(rods)
    G = np.zeros((R, 2 * R, 2))
    for i in range(R):
        G[i, 2 * i:2 * i + 2] = np.eye(2)

    def arms(q):
        return (_rot(q[2]) @ b.T).T  # (3, 2) a_i = Rot b_i

    def c(q):
        a = arms(q)
        return -(q[:2][None, :] + a).ravel()

    def dc(q):
        a = arms(q)
        J = np.zeros((2 * R, 3))
        for i in range(R):
            J[2 * i:2 * i + 2, :2] = -np.eye(2)
            J[2 * i, 2] = a[i, 1]  # -d(Rot b)/dtheta = -(-a_y, a_x)
            J[2 * i + 1, 2] = -a[i, 0]
        return J

    def hc(q, lam):
        a = arms(q)
        Hq = np.zeros((3, 3))
        Hq[2, 2] = float(np.sum(lam.reshape(R, 2) * a))  # sum lam_k d2 c_k: d2(-Rot b) = +a
        return Hq

    def U(q):
        return -F[0] * q[0] - F[1] * q[1] - F[2] * q[2]

    def gU(q):
        return -F

    def hU(q):
        return np.zeros((3, 3))

    L_ref = float(np.mean([r.length for r in rods]))
    EI_ref = float(np.mean([r.EI for r in rods]))
    fs = EI_ref / L_ref**2
    return _Problem(rods, [N] * R, np.zeros((R, 2)), G, 3, c, dc, hc, U, gU, hU,
                    q_mass=np.array([1.0 / L_ref**2, 1.0 / L_ref**2, 1.0]), L_ref=L_ref, EI_ref=EI_ref,
                    q_res_scale=np.array([fs, fs, fs * L_ref]), q_step_scale=np.array([L_ref, L_ref, 1.0]),
                    tip_targets=tip_targets, tip_q=2)


def mechanism_stability(rods: Sequence[RodSpec], attach, pose, load, tip_forces, base_moments,
                        N: int = 2 * DEFAULT_N, n_low: int = 1, method: str = "banded") -> StabilityResult:
    """Stability of a mechanism equilibrium with the actuators locked.

    rods: three :class:`RodSpec` (clamps as locked by the actuators; ``joint``/``tip_angle`` for
    rods welded to the platform); attach: (3, 2) b_i in the platform frame; pose (x, y, theta rad);
    load (F_x, F_y, M_z) at P; tip_forces (3, 2) force ON each rod tip (world, N); base_moments (3,)
    EI theta'(0) (N m).  The continuous solution (pose, n_i, m0_i) is sampled at the segment
    midpoints and Newton-solved as a DISCRETE equilibrium (pose free) at N/2 and N segments per rod;
    see :class:`StabilityResult`.  A clamped rod's tip tangent is tied to the platform rotation,
    theta_i(L) = theta_p + tip_angle_i + 2 pi k_i, the integer k_i taken from the continuous
    solution (its integrated tip tangent): the perturbations obey eta_i(L) = delta theta_p.
    """
    tip_forces = np.asarray(tip_forces, float).reshape(3, 2)
    base_moments = np.asarray(base_moments, float).reshape(3)
    pose = np.asarray(pose, float).reshape(3)
    targets = []
    for i, r in enumerate(rods):
        if getattr(r, "joint", "pinned") == "clamped":
            thL = sample_rod(r, tip_forces[i], base_moments[i], 8)[2]
            k = round((thL - pose[2] - r.tip_angle) / (2 * math.pi))
            targets.append(float(r.tip_angle + 2 * math.pi * k))
        else:
            targets.append(None)

    def build(n):
        prob = _mechanism_problem(rods, attach, load, n, tip_targets=targets)
        th = [sample_rod(r, tip_forces[i], base_moments[i], n)[0] for i, r in enumerate(rods)]
        return prob, prob.pack(th, pose), tip_forces.ravel().copy()

    return _evaluate(build, N, n_low=n_low, method=method)


def mechanism_rods(mech, inputs) -> list[RodSpec]:
    """Clamps of a flexkin Mechanism for actuator inputs (SI), rebuilt by ``ik_oracle.Geom``."""
    from ik_oracle import Geom

    g = Geom.of(mech)
    rods = []
    for i in range(3):
        A, al, L = g.clamp(i, np.asarray(float(inputs[i])))
        rods.append(RodSpec((float(A[0]), float(A[1])), float(al), float(L), float(g.EI[i]), g.joint[i],
                            float(g.tip_angle[i])))
    return rods


def solution_stability(mech, sol, load, N: int = 2 * DEFAULT_N, pose=None, **kw) -> StabilityResult:
    """Convenience: a flexkin-like ``Solution`` (pose, inputs, rods[i].tip_force / base_moment),
    e.g. an ``ik_oracle`` or ``fk_oracle`` solution; legs may be clamped to the platform."""
    if pose is not None or getattr(sol, "pose", None) is None:
        import types

        sol = types.SimpleNamespace(pose=pose, inputs=sol.inputs, rods=sol.rods)
    rods = mechanism_rods(mech, sol.inputs)
    return mechanism_stability(rods, np.asarray(mech.platform.attach, float), sol.pose, load,
                               [r.tip_force for r in sol.rods], [r.base_moment for r in sol.rods], N=N, **kw)


# ======================================================================================
# single rod
# ======================================================================================
def _single_problem(rod: RodSpec, tip: Tip, N: int, tip_target=None) -> _Problem:
    G, c0 = tip.rows()
    empty = np.zeros((0, 0))
    return _Problem([rod], [N], np.asarray(tip.load, float)[None], G[None], 0,
                    lambda q: c0, lambda q: np.zeros((len(c0), 0)), lambda q, lam: empty,
                    lambda q: 0.0, lambda q: np.zeros(0), lambda q: empty, q_mass=np.zeros(0),
                    L_ref=rod.length, EI_ref=rod.EI, tip_targets=[tip_target])


def single_rod_stability(rod: RodSpec, tip: Tip, state: ContinuousRod | None = None,
                         theta: Callable[[np.ndarray], np.ndarray] | None = None,
                         N: int = 2 * DEFAULT_N, n_low: int = 1, method: str = "banded") -> StabilityResult:
    """Stability of one equilibrium of one rod with tip condition ``tip``.

    The initial guess is the continuous ``state`` (total tip force n and base moment m0,
    integrated by ODE), or ``theta(s)`` (a callable angle profile, s in [0, L]), or, if neither
    is given, the straight rod theta = clamp_angle.  The multipliers (reactions) are obtained
    by least squares from the discrete stationarity conditions and refined by Newton.

    A tip with a prescribed tangent (``tip.angle``: :meth:`Tip.clamped`, :meth:`Tip.guided`) gets
    the half-cell Dirichlet term at the tip; the angle is taken modulo 2 pi nearest to the
    continuous state's tip tangent when ``state`` is given.
    """
    target = None
    if tip.angle is not None:
        target = float(tip.angle)
        if state is not None:
            thL = sample_rod(rod, state.tip_force, state.base_moment, 8)[2]
            target += 2 * math.pi * round((thL - target) / (2 * math.pi))

    def build(n):
        prob = _single_problem(rod, tip, n, target)
        if state is not None:
            th = sample_rod(rod, state.tip_force, state.base_moment, n)[0]
        elif theta is not None:
            th = np.asarray(theta((np.arange(n) + 0.5) * rod.length / n), float)
        else:
            th = np.full(n, float(rod.clamp_angle))
        return prob, prob.pack([th], np.zeros(0)), None

    return _evaluate(build, N, n_low=n_low, method=method)


# ---- continuous equilibria of a single rod by shooting -------------------------------------
def _rk4_m_tip(m0, n, alpha, L, EI, steps=400):
    """Vectorised RK4 of many rods (same n) with base moments m0: returns tip (x, y, th, m)."""
    m0 = np.asarray(m0, float)
    n = np.broadcast_to(np.asarray(n, float), m0.shape + (2,))
    nx, ny = n[..., 0], n[..., 1]
    z = np.stack([np.zeros_like(m0), np.zeros_like(m0), np.full_like(m0, alpha), m0])
    hs = L / steps

    def f(z):
        c, s = np.cos(z[2]), np.sin(z[2])
        return np.stack([c, s, z[3] / EI, nx * s - ny * c])

    for _ in range(steps):
        k1 = f(z)
        k2 = f(z + 0.5 * hs * k1)
        k3 = f(z + 0.5 * hs * k2)
        k4 = f(z + hs * k3)
        z = z + hs / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return z


def _tight(rod: RodSpec, n, m0, n_eval=2001):
    L = rod.length
    sol = solve_ivp(_ode(n, rod.EI), (0.0, L), [rod.clamp[0], rod.clamp[1], rod.clamp_angle, float(m0)],
                    method="DOP853", rtol=1e-12, atol=1e-13 * max(1.0, abs(m0)),
                    t_eval=np.linspace(0.0, L, n_eval))
    return sol.y


def _mode(ms, m_ref: float = 0.0) -> int:
    """d-mode from sampled moments: 1 + interior sign changes; 0 for a straight rod
    (max |m| <= 1e-9 m_ref, m_ref a moment scale such as sqrt(|n| EI) + EI/L)."""
    m = np.asarray(ms)[1:-1]
    scale = float(np.max(np.abs(ms)))
    if scale <= 1e-9 * m_ref or scale == 0.0:
        return 0
    sg = np.sign(m[np.abs(m) > 1e-9 * scale])
    return 1 + int(np.count_nonzero(sg[1:] != sg[:-1]))


def _mref(rod: RodSpec, n) -> float:
    return math.sqrt(float(np.hypot(*n)) * rod.EI) + rod.EI / rod.length


def single_rod_equilibria(rod: RodSpec, tip: Tip, n_grid: int = 4001, R_max: float = 200.0,
                          n_starts: int = 600) -> list[ContinuousRod]:
    """Continuous equilibria of one rod by ODE shooting (independent of flexkin).

    * ``free``: the tip force is the dead load; the base moment m0 is scanned over the
      first-integral bound |m0| <= 2 sqrt(|F| EI) and every sign change of m(L) is refined by
      Brent's method (straight solutions included);
    * ``slider``: unknowns (m0, mu) with n = F + mu d; damped Newton (RK4, finite-difference
      Jacobian) from a grid of about ``n_starts`` starts (|mu| L^2/EI <= R_max, m0 inside the
      first-integral bound), residuals m(L) = 0 and d.(r(L) - r0) = 0, deduplicated and
      polished on a DOP853 integration (a multi-start: completeness is not guaranteed);
    * ``pinned``: ``oracles.shooting_multistart`` (random-start shooting, independent of flexkin).

    Returns :class:`ContinuousRod` items sorted by (mode, |n|), with the residual tip moment;
    ``mode`` is the d-mode (1 + interior sign changes of the moment), 0 for a straight rod.
    """
    L, EI, al = rod.length, rod.EI, rod.clamp_angle
    out: list[ContinuousRod] = []
    if tip.kind == "free":
        F = np.asarray(tip.load, float)
        R = float(np.hypot(*F))
        mmax = 2.0 * math.sqrt(max(R, 1e-300) * EI) * (1.0 + 1e-9)
        grid = np.linspace(-mmax, mmax, n_grid + (n_grid + 1) % 2 + 1)  # even count: 0 not on the grid
        mt = _rk4_m_tip(grid, F, al, L, EI)[3]

        def fun(m0):
            return _tight(rod, F, m0, 2)[3, -1]

        roots = []
        for j in np.flatnonzero(np.sign(mt[:-1]) * np.sign(mt[1:]) <= 0):
            a, b = grid[j], grid[j + 1]
            fa, fb = fun(a), fun(b)
            if fa * fb > 0:
                continue
            roots.append(brentq(fun, a, b, xtol=1e-15 * max(1.0, mmax), rtol=1e-15, maxiter=200))
        for m0 in roots:
            y = _tight(rod, F, m0)
            out.append(ContinuousRod((float(F[0]), float(F[1])), float(m0), _mode(y[3], _mref(rod, F)),
                                     (float(y[0, -1]), float(y[1, -1])), float(y[2, -1]), float(y[3, -1])))
    elif tip.kind == "slider":
        out = _slider_equilibria(rod, tip, R_max, n_starts)
    elif tip.kind == "pinned":
        from oracles import shooting_multistart

        ca, sa = math.cos(al), math.sin(al)
        Rt = np.array([[ca, -sa], [sa, ca]])
        loc = Rt.T @ (np.asarray(tip.point, float) - np.asarray(rod.clamp, float)) / L
        for s in shooting_multistart(loc, 1.0, 1.0, max_mode=3, R_max=R_max):
            n = Rt @ np.asarray(s.force) * EI / L**2
            m0 = s.m0 * EI / L
            y = _tight(rod, n, m0)
            out.append(ContinuousRod((float(n[0]), float(n[1])), float(m0), _mode(y[3], _mref(rod, n)),
                                     (float(y[0, -1]), float(y[1, -1])), float(y[2, -1]), float(y[3, -1])))
    else:
        raise ValueError(tip.kind)
    out.sort(key=lambda c: (c.mode, float(np.hypot(*c.tip_force)), c.base_moment))
    return out


def _slider_equilibria(rod: RodSpec, tip: Tip, R_max, n_starts) -> list[ContinuousRod]:
    L, EI, al = rod.length, rod.EI, rod.clamp_angle
    F = np.asarray(tip.load, float)
    t = np.asarray(tip.direction, float)
    d = np.array([-t[1], t[0]])
    r0 = np.asarray(tip.point, float) - np.asarray(rod.clamp, float)
    fs = EI / L**2
    # starts: a grid in (mu, u) with m0 = u * 2 sqrt(|n| EI) (first-integral bound)
    nm = max(int(math.sqrt(n_starts / 2)), 4)
    v = np.linspace(-1.0, 1.0, 2 * nm + 1)
    mu_g = np.sign(v) * np.abs(v) ** 2 * R_max * fs
    u_g = np.linspace(-0.97, 0.97, nm)
    MU, U = np.meshgrid(mu_g, u_g, indexing="ij")
    mu, u = MU.ravel(), U.ravel()
    Rn = np.hypot(F[0] + mu * d[0], F[1] + mu * d[1])
    m0 = 2.0 * np.sqrt(Rn * EI) * u

    def res(m0, mu):
        n = F[None] + mu[:, None] * d[None]
        z = _rk4_m_tip(m0, n, al, L, EI, steps=120)
        return np.stack([z[3] * L / EI, ((z[0] - r0[0]) * d[0] + (z[1] - r0[1]) * d[1]) / L])

    p = np.stack([m0 * L / EI, mu / fs])  # scaled unknowns
    active = np.ones(p.shape[1], bool)
    for _ in range(30):
        ia = np.flatnonzero(active)
        if ia.size == 0:
            break
        pa = p[:, ia]
        r = res(pa[0] * EI / L, pa[1] * fs)
        J = np.empty((2, 2, ia.size))
        for k in range(2):
            e = 1e-7 * np.maximum(1.0, np.abs(pa[k]))
            pp = pa.copy()
            pp[k] += e
            J[:, k] = (res(pp[0] * EI / L, pp[1] * fs) - r) / e
        det = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
        with np.errstate(all="ignore"):
            s0 = -(J[1, 1] * r[0] - J[0, 1] * r[1]) / det
            s1 = -(-J[1, 0] * r[0] + J[0, 0] * r[1]) / det
        step = np.stack([s0, s1])
        bad = ~np.isfinite(step).all(axis=0)
        step[:, bad] = 0.0
        lim = np.maximum(np.abs(step[0]) / 2.0, np.abs(step[1]) / (0.3 * np.abs(pa[1]) + 2.0))
        p[:, ia] = pa + step / np.maximum(lim, 1.0)
        done = np.max(np.abs(r), axis=0) < 1e-9
        active[ia[done | bad | (np.abs(pa[1]) > 2 * R_max)]] = False
    r = res(p[0] * EI / L, p[1] * fs)
    ok = (np.max(np.abs(r), axis=0) < 1e-6) & (np.abs(p[1]) <= R_max)
    cands = p[:, ok].T
    from scipy.optimize import fsolve

    uniq: list[np.ndarray] = []
    for c in cands:
        if not any(np.max(np.abs(c - s)) < 1e-4 * (1 + np.max(np.abs(s))) for s in uniq):
            uniq.append(c)
    out: list[ContinuousRod] = []
    seen: list[np.ndarray] = []
    for c in uniq:

        def fr(x):
            n = F + x[1] * fs * d
            y = _tight(rod, n, x[0] * EI / L, 2)
            return [y[3, -1] * L / EI, ((y[0, -1] - tip.point[0]) * d[0] + (y[1, -1] - tip.point[1]) * d[1]) / L]

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            x = fsolve(fr, c, xtol=1e-13)
        if np.max(np.abs(fr(x))) > 1e-9:
            continue
        if any(np.max(np.abs(x - s)) < 1e-6 * (1 + np.max(np.abs(s))) for s in seen):
            continue
        seen.append(x)
        n = F + x[1] * fs * d
        y = _tight(rod, n, x[0] * EI / L)
        out.append(ContinuousRod((float(n[0]), float(n[1])), float(x[0] * EI / L), _mode(y[3], _mref(rod, n)),
                                 (float(y[0, -1]), float(y[1, -1])), float(y[2, -1]), float(y[3, -1])))
    return out


def cantilever_elastica(L: float, EI: float, P: float, mode: int, alpha: float = 0.0,
                        sign: int = 1) -> ContinuousRod:
    """Buckled cantilever (clamp at the origin, tangent alpha) under the axial compressive dead
    tip load P (along -e_alpha), d-mode ``mode``, deflecting to the side ``sign`` (base moment
    sign).  Found by :func:`single_rod_equilibria` (free tip); raises if it does not exist."""
    rod = RodSpec((0.0, 0.0), alpha, L, EI)
    F = -P * np.array([math.cos(alpha), math.sin(alpha)])
    sols = [s for s in single_rod_equilibria(rod, Tip.free(F))
            if s.mode == mode and abs(s.base_moment) > 1e-8 * math.sqrt(P * EI)
            and np.sign(s.base_moment) == sign]
    if not sols:
        raise ValueError(f"no mode-{mode} buckled cantilever at P = {P} (P L^2/EI = {P * L * L / EI:.4g})")
    return sols[0]


# ======================================================================================
# critical load of a straight rod by bracketing on the sign of min_eig
# ======================================================================================
def critical_load(make: Callable[[float], StabilityResult], p_lo: float, p_hi: float,
                  rtol: float = 1e-9, use: str = "min_eig") -> float:
    """Load p* in [p_lo, p_hi] where the straight (or given) equilibrium loses stability.

    ``use="min_eig"``: Brent's method on the sign of ``make(p).min_eig`` (the Richardson-
    extrapolated smallest eigenvalue); ``use="verdict"``: plain bisection on ``make(p).index > 0``
    (the raw verdict at the finest N, no extrapolation), to relative width ``rtol``.
    """
    if use == "min_eig":
        return brentq(lambda p: make(p).min_eig, p_lo, p_hi, rtol=max(rtol, 1e-15), xtol=1e-14)
    a, b = p_lo, p_hi
    if make(a).index > 0 or make(b).index == 0:
        raise ValueError("the verdict does not change over [p_lo, p_hi]")
    while b - a > rtol * abs(b):
        mid = 0.5 * (a + b)
        if make(mid).index > 0:
            b = mid
        else:
            a = mid
    return 0.5 * (a + b)
