"""Stability of an equilibrium with the actuators locked (paper §4.3): the smallest eigenvalue
of the whole second variation, with a guaranteed resolution.

The potential of the mechanism is

    V = sum_i (EI_i/2) int_0^{L_i} theta_i'(s)^2 ds  -  F . P  -  M theta_P

on configurations with every rod clamped at its base (actuators locked), its tip at
``B_i = P + Rot(theta_P) b_i`` and, for a clamped joint, its tip tangent at
``theta_P + tip_angle_i``.  With the tip forces ``n_i`` and tip moments as the Lagrange
multipliers of those constraints, the second variation on admissible perturbations
``(eta_i(s), dq)`` (``eta_i = d theta_i``, ``eta_i(0) = 0``, ``dq = (dP, d theta_P)``) is

    Q = sum_i int [ EI_i eta_i'^2 + (n_i . t_i) eta_i^2 ] ds  -  (sum_i n_i . (B_i - P)) d theta_P^2,

subject to ``int (-sin theta_i, cos theta_i) eta_i ds = dP + d theta_P perp(B_i - P)`` and, for a
clamped tip, ``eta_i(L_i) = d theta_P``.  The equilibrium is stable when ``Q`` is positive
definite there.

**Margin.**  ``stability_margin`` is the smallest eigenvalue of ``Q`` on the admissible
subspace with respect to the metric ``sum_i int eta_i^2 ds / L_ref + |dP / L_ref|^2 + d theta_P^2``,
in units of ``EI_ref / L_ref`` (``L_ref``: the mechanism's length scale, ``EI_ref``: the mean
bending stiffness).  It includes the rods' own modes (a rod that buckles with its tip held)
and the platform's (an FK singularity is where it crosses zero).  ``stability_index`` is the
number of negative eigenvalues (the Morse index).

**Discretisation.**  Each ``eta_i`` is expanded in integrated Legendre polynomials
(``phi_k' ~ P_{k-1}``, so ``phi_k(0) = 0``), orthonormalised in L^2; the integrals are
Gauss-Legendre quadratures of the closed-form tangent angle (:mod:`flexkin.rod.kernels`).  The
eigenvalues converge exponentially in the number of modes ``N`` per rod; ``N`` grows with the
rods' ``lambda L`` (the scale of their features) and every eigenvalue is computed at two
resolutions: their difference (with a round-off floor) is the **resolution**.

**Verdict.**  ``stable`` is ``True`` when ``margin > 3 resolution``, ``False`` when
``margin < -3 resolution`` and ``None`` (undecided, with a ``note``) otherwise, after refining
up to :data:`N_MAX` modes: a loop held in tension, whose smallest eigenvalue is exponentially
small (the loop almost translates freely along the rod), comes out ``None`` unless the
discretisation resolves it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.jit import njit
from ..core.linalg_threads import single_threaded_blas
from ..results import Stability
from ..rod.closed_form import seam_to_chart
from ..rod.kernels import CHART_SEAM, CHART_UNIFIED, PHI, tangents
from ..rod.state import RodState
from ..system import System

__all__ = ["StabilityArrays", "mechanism_stability", "rod_stability", "RodStability", "output_stiffness",
           "N_MIN", "N_MAX"]

#: modes per rod: the first resolution, and the most the refinement goes to
N_MIN, N_MAX = 16, 160
#: relative round-off floor of the resolution
ROUNDOFF = 1e-13
#: a constraint whose singular value is below this fraction of the largest is vacuous: to first
#: order a straight rod's axial constraint does not restrict its perturbations
RANK_RTOL = 1e-9


# ---- the basis: L2-orthonormal integrated Legendre polynomials on [0, 1] ------------------------
@dataclass(frozen=True)
class Basis:
    """``N`` modes on ``Nq`` Gauss-Legendre nodes of [0, 1]: values ``psi`` (N, Nq), weights
    ``w`` (Nq,), stiffness ``K = int psi' psi'^T`` (N, N) and tip values ``psi(1)`` (N,)."""

    N: int
    s: NDArray[np.float64]
    w: NDArray[np.float64]
    psi: NDArray[np.float64]
    K: NDArray[np.float64]
    tip: NDArray[np.float64]


@lru_cache(maxsize=32)
def basis(N: int) -> Basis:
    """The orthonormal basis with ``N`` modes (cached)."""
    nq = 2 * N + 8
    x, w = np.polynomial.legendre.leggauss(nq)
    s, w = 0.5 * (x + 1.0), 0.5 * w
    # phi_k(s) = sqrt(2k - 1) int_0^s P_{k-1}(2t - 1) dt, so int_0^1 phi_k' phi_l' ds = delta_kl
    P = np.polynomial.legendre.legvander(x, N)           # P_0 .. P_N at the nodes
    phi = np.empty((N, nq))
    phi[0] = s
    for k in range(2, N + 1):
        phi[k - 1] = np.sqrt(2 * k - 1) * 0.5 * (P[:, k] - P[:, k - 2]) / (2 * k - 1)
    tip_phi = np.zeros(N)
    tip_phi[0] = 1.0                                     # phi_k(1) = 0 for k >= 2
    M = (phi * w) @ phi.T
    G = np.linalg.cholesky(M)
    Gi = np.linalg.inv(G)                                 # psi = Gi phi: int psi psi^T = I
    psi = Gi @ phi
    K = Gi @ Gi.T
    for a in (s, w, psi, K):
        a.setflags(write=False)
    return Basis(N, s, w, psi, K, Gi @ tip_phi)


def _modes_for(Phi: float) -> int:
    """Modes per rod to start with for a rod with ``lambda L = Phi`` (features of width
    ~ 1/lambda; measured: about ``3 Phi`` modes give the smallest eigenvalue to 1e-4, and the
    refinement adds modes where the two resolutions disagree)."""
    n = max(N_MIN, 2 * int(math.ceil(Phi)) + 8)
    return int(min(N_MAX, 8 * math.ceil(n / 8)))


def _coarse(N: int) -> int:
    """The nested coarser resolution used to estimate the error at ``N`` modes."""
    return N - max(6, N // 5)


# ---- assembly (compiled) ------------------------------------------------------------------------
@njit
def _assemble(theta, force, ell, e, arm, clamped, psis, ws, Ks, tips, Q, C) -> None:
    """The second variation ``Q`` (p, p) and the constraints ``C`` (m, p) of one equilibrium in
    the metric-orthonormal coordinates (rod i's modes scaled by ``sqrt(ell_i)``, then the pose).

    ``theta`` (3, Nq) world tangent angles at the nodes (rod i: its first ``len(ws[i])``),
    ``force`` (3, 2) tip forces (in F_ref), ``ell``, ``e`` (3,) lengths (L_ref) and stiffnesses
    (EI_ref), ``arm`` (3, 2) ``B_i - P`` (L_ref); rod i in its own basis ``psis[i]``, ``ws[i]``,
    ``Ks[i]``, ``tips[i]`` (:func:`basis`).
    """
    Q[:, :] = 0.0
    C[:, :] = 0.0
    ip = psis[0].shape[0] + psis[1].shape[0] + psis[2].shape[0]
    row = 0
    c0 = 0
    for i in range(3):
        psi = psis[i]
        w = ws[i]
        K = Ks[i]
        tip = tips[i]
        N = psi.shape[0]
        nq = psi.shape[1]
        sl = math.sqrt(ell[i])
        kf = e[i] / (ell[i] * ell[i])
        for a in range(N):
            for b in range(N):
                Q[c0 + a, c0 + b] = kf * K[a, b]
        for j in range(nq):
            q = w[j] * (force[i, 0] * math.cos(theta[i, j]) + force[i, 1] * math.sin(theta[i, j]))
            for a in range(N):
                qa = q * psi[a, j]
                for b in range(a, N):
                    Q[c0 + a, c0 + b] += qa * psi[b, j]
        for a in range(N):
            for b in range(a + 1, N):
                Q[c0 + b, c0 + a] = Q[c0 + a, c0 + b]
        # tip position: ell int n_perp eta ds_hat = dP + dtheta perp(arm)
        for j in range(nq):
            nx = -math.sin(theta[i, j]) * w[j] * sl
            ny = math.cos(theta[i, j]) * w[j] * sl
            for a in range(N):
                C[row, c0 + a] += nx * psi[a, j]
                C[row + 1, c0 + a] += ny * psi[a, j]
        C[row, ip] = -1.0
        C[row + 1, ip + 1] = -1.0
        C[row, ip + 2] = arm[i, 1]       # -perp(arm)_x = +arm_y
        C[row + 1, ip + 2] = -arm[i, 0]  # -perp(arm)_y = -arm_x
        row += 2
        if clamped[i]:
            for a in range(N):
                C[row, c0 + a] = tip[a] / sl
            C[row, ip + 2] = -1.0
            row += 1
        Q[ip + 2, ip + 2] -= force[i, 0] * arm[i, 0] + force[i, 1] * arm[i, 1]
        c0 += N


@njit
def _angles(chart, z, alpha, s, out) -> None:
    """World tangent angles of rods (n, 3) at unit arc lengths ``s``: ``out`` (n, 3, len(s))."""
    th = np.empty(s.shape[0])
    for k in range(z.shape[0]):
        for i in range(3):
            tangents(chart[k, i], z[k, i], s, th)
            for j in range(s.shape[0]):
                out[k, i, j] = alpha[k, i] + th[j]


@njit(fastmath={"reassoc", "contract"})
def _project(Q, C, B) -> int:
    """``Q`` (p, p) restricted to the null space of ``C`` (m, p) in an orthonormal basis: written
    to ``B[:p - r, :p - r]``; returns the rank ``r`` of the constraints.  ``Q`` is overwritten.

    Rank-revealing: the constraints are the right singular vectors of ``C`` with singular
    value above ``RANK_RTOL`` times the largest (a vacuous constraint, such as a straight rod's
    axial one, is dropped).  Their orthogonal complement is spanned by the trailing columns of
    the Householder reflectors of their QR factorisation, so the projected matrix is the
    trailing block of ``H^T Q H``, updated in place at ``O(m p^2)`` cost.
    """
    m, p = C.shape
    _, sv, Vt = np.linalg.svd(C, full_matrices=False)
    r = 0
    for j in range(sv.shape[0]):
        if sv[j] > RANK_RTOL * sv[0]:
            r += 1
    V = np.ascontiguousarray(Vt[:r].T)        # (p, r) orthonormal constraint directions
    v = np.empty(p)
    wv = np.empty(p)
    for j in range(r):
        nrm = 0.0
        for a in range(j, p):
            nrm += V[a, j] * V[a, j]
        nrm = math.sqrt(nrm)
        alpha = -nrm if V[j, j] >= 0.0 else nrm
        for a in range(j, p):
            v[a] = V[a, j]
        v[j] -= alpha
        vv = 0.0
        for a in range(j, p):
            vv += v[a] * v[a]
        if vv == 0.0:
            continue
        tau = 2.0 / vv
        for c in range(j + 1, r):             # the remaining constraint columns
            t = 0.0
            for a in range(j, p):
                t += v[a] * V[a, c]
            t *= tau
            for a in range(j, p):
                V[a, c] -= t * v[a]
        # Q[j:, j:] <- P Q[j:, j:] P with P = I - tau v v^T: Q - v q^T - q v^T
        kk = 0.0
        for a in range(j, p):
            t = 0.0
            for b in range(j, p):
                t += Q[a, b] * v[b]
            wv[a] = tau * t
            kk += v[a] * wv[a]
        kk *= 0.5 * tau
        for a in range(j, p):
            wv[a] -= kk * v[a]
        for a in range(j, p):
            for b in range(j, p):
                Q[a, b] -= v[a] * wv[b] + wv[a] * v[b]
    for a in range(p - r):
        for b in range(a, p - r):
            t = 0.5 * (Q[r + a, r + b] + Q[r + b, r + a])
            B[a, b] = t
            B[b, a] = t
    return r




@njit
def _spectra(ch, z, alpha, force, ell, e, arm, clamped, psis, ws, Ks, tips, ss, coarse, ev, evc, scale) -> None:
    """Per equilibrium ``k``: the tangent angles at the quadrature
    nodes, the second variation and its constraints (:func:`_assemble`), and the lowest
    eigenvalues on the admissible subspace (:func:`_project`) with rod i in its basis of
    ``N_i`` modes (``ev[k]``) and in the nested first ``coarse[i]`` of them (``evc[k]``);
    ``scale[k]`` is the largest diagonal entry."""
    n = z.shape[0]
    nq = max(ss[0].shape[0], max(ss[1].shape[0], ss[2].shape[0]))
    p = psis[0].shape[0] + psis[1].shape[0] + psis[2].shape[0] + 3
    m = 6
    for i in range(3):
        if clamped[i]:
            m += 1
    pc = coarse[0] + coarse[1] + coarse[2] + 3
    keep = np.empty(pc, np.int64)
    a0 = 0
    f0 = 0
    for i in range(3):
        for a in range(coarse[i]):
            keep[a0 + a] = f0 + a
        a0 += coarse[i]
        f0 += psis[i].shape[0]
    for a in range(3):
        keep[pc - 3 + a] = p - 3 + a
    for k in range(n):
        theta = np.empty((3, nq))
        Q = np.empty((p, p))
        C = np.empty((m, p))
        Qc = np.empty((pc, pc))
        Cc = np.empty((m, pc))
        for i in range(3):
            th = np.empty(ss[i].shape[0])
            tangents(ch[k, i], z[k, i], ss[i], th)
            for j in range(th.shape[0]):
                theta[i, j] = alpha[k, i] + th[j]
        _assemble(theta, force[k], ell[k], e, arm[k], clamped, psis, ws, Ks, tips, Q, C)
        sc = 0.0
        for a in range(p):
            sc = max(sc, abs(Q[a, a]))
        scale[k] = sc
        for a in range(pc):
            for b in range(pc):
                Qc[a, b] = Q[keep[a], keep[b]]
            for r in range(m):
                Cc[r, a] = C[r, keep[a]]
        B = np.empty((p, p))
        r = _project(Q, C, B)
        e1 = np.linalg.eigvalsh(B[:p - r, :p - r].copy())
        ev[k, :] = e1[:p - m]
        r = _project(Qc, Cc, B)
        e2 = np.linalg.eigvalsh(B[:pc - r, :pc - r].copy())
        evc[k, :] = e2[:pc - m]


def _spectrum(system: System, X: NDArray, charts: NDArray, N: tuple[int, int, int], coarse: tuple[int, int, int]
              ) -> tuple[NDArray, NDArray, NDArray]:
    """Eigenvalues (n, p - m), ascending, of the discretised second variation with ``N[i]`` modes
    for rod i, the scale of its diagonal, and the eigenvalues with the first ``coarse[i]`` modes of
    each rod (a nested subspace: the same quadrature, a sub-basis); compiled per equilibrium
    (:func:`_spectra`)."""
    bs = [basis(int(v)) for v in N]
    n = len(X)
    lay = system.layout
    z = np.zeros((n, 3, 3))
    ch = np.array(charts, dtype=np.int64)
    for i in range(3):
        zi = X[:, lay.rod[i]]
        z[:, i, :zi.shape[1]] = zi
        seam = ch[:, i] == CHART_SEAM
        if np.any(seam):  # the profile is evaluated in the unified chart
            v, ph = seam_to_chart(zi[seam, 0], zi[seam, 1])
            z[seam, i, 0], z[seam, i, 1] = v, ph
            ch[seam, i] = CHART_UNIFIED
    _, alpha, L = system.clamps(X[:, lay.inputs])
    w = system.rod_world(X, charts)
    force = np.ascontiguousarray(w["force"] / system.F_ref)
    arm = (system.platform_points(X[:, lay.pose]) - X[:, None, lay.pose.start:lay.pose.start + 2]) / system.L_ref
    ell = L / system.L_ref
    e = system.EI / system.EI_ref
    clamped = np.asarray(system.clamped, dtype=np.bool_)
    m = 6 + int(np.count_nonzero(clamped))
    ev = np.empty((n, sum(N) + 3 - m))
    evc = np.empty((n, sum(coarse) + 3 - m))
    scale = np.empty(n)
    _spectra(ch, z, np.ascontiguousarray(alpha, dtype=float), force, np.ascontiguousarray(ell, dtype=float),
             np.ascontiguousarray(e, dtype=float), np.ascontiguousarray(arm), clamped,
             tuple(b.psi for b in bs), tuple(b.w for b in bs), tuple(b.K for b in bs), tuple(b.tip for b in bs),
             tuple(b.s for b in bs), np.array(coarse, dtype=np.int64), ev, evc, scale)
    return ev, scale, evc


@dataclass(frozen=True)
class StabilityArrays:
    """Stability of ``n`` equilibria (see the module docstring).

    Attributes
    ----------
    stable : (n,) int8: 1 stable, 0 unstable, -1 undecided.
    margin : (n,) smallest eigenvalue of the second variation (EI_ref / L_ref).
    resolution : (n,) its guaranteed resolution.
    index : (n,) number of negative eigenvalues, -1 where unresolved.
    modes : (n,) Legendre modes of the final resolution (of the rod with the most).
    """

    stable: NDArray[np.int8]
    margin: NDArray[np.float64]
    resolution: NDArray[np.float64]
    index: NDArray[np.int64]
    modes: NDArray[np.int64]

    def item(self, i: int) -> Stability:
        """The :class:`~flexkin.results.Stability` of equilibrium ``i``."""
        st = int(self.stable[i])
        note = ""
        if st < 0:
            note = (f"undecided: the smallest eigenvalue of the second variation, {self.margin[i]:.3g}, is below "
                    f"the resolution {self.resolution[i]:.2g} reached with {self.modes[i]} modes per rod (typical "
                    f"of a rod near the separatrix: a loop held in tension or a taut rod)")
        idx = int(self.index[i])
        return Stability(None if st < 0 else bool(st), float(self.margin[i]), None if idx < 0 else idx,
                         float(self.resolution[i]), note)


def mechanism_stability(system: System, X: NDArray, charts: NDArray) -> StabilityArrays:
    """Stability of equilibria ``X`` (n, n_unknowns) in ``charts`` (n, 3), actuators locked.

    Parameters
    ----------
    system : System
        The mechanism's equation system (:meth:`System.from_mechanism`).
    X : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.

    Returns
    -------
    StabilityArrays
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    charts = np.atleast_2d(np.asarray(charts, dtype=np.int64))
    n = len(X)
    out_m = np.zeros(n)
    out_r = np.full(n, np.inf)
    out_i = np.full(n, -1, np.int64)
    out_n = np.zeros(n, np.int64)
    if n == 0:
        return StabilityArrays(np.zeros(0, np.int8), out_m, out_r, out_i, out_n)
    q, _ = system.unit_rods(X, charts)
    # modes per rod from its own lambda L
    N = np.vectorize(lambda v: _modes_for(float(v)), otypes=[np.int64])(np.nan_to_num(q[:, :, PHI]))
    todo = np.arange(n)
    with single_threaded_blas():
        while todo.size:
            keys, inv = np.unique(N[todo], axis=0, return_inverse=True)
            for g, Nv in enumerate(keys):
                grp = todo[inv.ravel() == g]
                Nt = tuple(int(v) for v in Nv)
                ev2, sc2, ev1 = _spectrum(system, X[grp], charts[grp], Nt, tuple(_coarse(v) for v in Nt))
                k = min(ev1.shape[1], ev2.shape[1], 6)
                floor = ROUNDOFF * sc2
                err = 2.0 * np.abs(ev2[:, :k] - ev1[:, :k]) + floor[:, None]
                res = err[:, 0]
                mu = ev2[:, 0]
                out_m[grp], out_r[grp], out_n[grp] = mu, res, max(Nt)
                near = np.abs(ev2[:, :k]) <= 3.0 * err
                neg = np.sum(ev2 < 0.0, axis=1)
                out_i[grp] = np.where(np.any(near, axis=1), -1, neg)
            # refine where the verdict or the index is undecided, or the margin is not known to 1 %
            ok = ((np.abs(out_m[todo]) > 3.0 * out_r[todo]) & (out_r[todo] <= 1e-2 * (1.0 + np.abs(out_m[todo])))
                  & ((out_i[todo] >= 0) | (out_m[todo] > 3.0 * out_r[todo])))
            todo = todo[~ok & np.any(N[todo] < N_MAX, axis=1)]
            if todo.size:
                N[todo] = np.minimum(N_MAX, 8 * np.ceil(1.5 * N[todo] / 8)).astype(np.int64)
    stable = np.where(out_m > 3.0 * out_r, 1, np.where(out_m < -3.0 * out_r, 0, -1)).astype(np.int8)
    out_i = np.where(stable == 1, 0, out_i)
    return StabilityArrays(stable, out_m, out_r, out_i, out_n)


# ---- the platform's output stiffness ------------------------------------------------------------
def output_stiffness(system: System, X: NDArray, charts: NDArray, load: NDArray) -> NDArray[np.float64]:
    """The platform's stiffness with the actuators locked, ``K = dW/dq`` (n, 3, 3): the change of
    the load wrench ``W = (F_x, F_y, M_z)`` that holds the platform displaced by ``dq = (dx, dy,
    dtheta)`` at equilibrium.  It is the Hessian of the potential reduced to the pose; units N/m
    (force/translation), N (force/rotation and moment/translation), N m/rad (moment/rotation).

    Parameters
    ----------
    system : System
        The mechanism's equation system (:meth:`System.from_mechanism`).
    X : ndarray (n, n_unknowns)
        Equilibria.
    charts : ndarray (n, 3)
        Their rods' charts.
    load : ndarray (3,)
        Load wrench ``(F_x, F_y, M_z)`` on the platform (N, N, N m).

    Returns
    -------
    ndarray (n, 3, 3)
    """
    from .jacobian import system_blocks

    Gz, Gx, _ = system_blocks(system, X, charts, load)
    # residual rows of the equilibrium are (sum n - W) / scale: dR/dW = -1/scale on them
    lay = system.layout
    n, ne, nz = Gz.shape
    Gw = np.zeros((ne, 3))
    Gw[lay.force.start, 0] = Gw[lay.force.start + 1, 1] = -1.0
    Gw[lay.moment.start, 2] = -1.0
    A = np.concatenate([Gz, np.broadcast_to(Gw, (n, ne, 3))], axis=2)   # unknowns (dz, dW/wscale)
    sol = -np.linalg.solve(A, Gx)                                       # (n, nz + 3, 3) per unit pose
    dW = sol[:, nz:, :] * system.wrench_scale()[None, :, None]          # wrench per dimensionless pose
    return dW / np.array([system.L_ref, system.L_ref, 1.0])[None, None, :]


# ---- one rod: the classical cases ---------------------------------------------------------------
@dataclass(frozen=True)
class RodStability:
    """Stability of one clamped rod under a tip condition (see :func:`rod_stability`).

    Attributes
    ----------
    stable : bool or None
    index : int or None
        Number of unstable directions.
    margin : float
        Smallest eigenvalue of the second variation (EI / L units of the rod).
    resolution : float
    tip : str
    """

    stable: bool | None
    index: int | None
    margin: float
    resolution: float
    tip: str


def rod_stability(rod: RodState, tip: str = "pinned", slider_angle: float | None = None) -> RodStability:
    """Stability of one rod clamped at its base, with its tip

    * ``"free"``: a dead load on a free tip (the cantilever);
    * ``"pinned"``: held at a fixed point, free to turn;
    * ``"slider"``: sliding on a line of angle ``slider_angle`` (rad, world), free to turn;
    * ``"clamped"``: held at a fixed point with a fixed tangent.

    The rod must be an equilibrium of that problem (for ``"free"`` and ``"slider"`` the tip
    force is the dead load).  Same discretisation as :func:`mechanism_stability`, with the
    rod's own ``L`` and ``EI`` as units.

    Parameters
    ----------
    rod : RodState
        The rod (its clamp angle, chart coordinates, length, EI and tip force are used).
    tip : {"pinned", "slider", "free", "clamped"}
        The tip condition.
    slider_angle : float, optional
        Direction of the slider's line (rad, world); required for ``tip="slider"``.

    Returns
    -------
    RodStability
    """
    if tip not in ("pinned", "slider", "free", "clamped"):
        raise ValueError(f"tip must be 'free', 'pinned', 'slider' or 'clamped', got {tip!r}")
    if tip == "slider" and slider_angle is None:
        raise ValueError("tip='slider' needs slider_angle (rad)")
    z = np.zeros((1, 3, 3))
    ch = np.full((1, 3), rod.chart, dtype=np.int64)
    z[0, :, :len(rod.coords)] = rod.coords
    if rod.chart == CHART_SEAM:
        z[0, :, 0], z[0, :, 1] = seam_to_chart(rod.coords[0], rod.coords[1])
        ch[:] = CHART_UNIFIED
    Phi = np.sqrt(np.hypot(*rod.tip_force) * rod.length**2 / rod.EI)
    N = _modes_for(Phi)
    f = np.array(rod.tip_force) * rod.length**2 / rod.EI
    results = []
    with single_threaded_blas():
        while True:
            evs = []
            for n_ in (N, int(min(N_MAX, N + max(8, N // 4)))):
                bs = basis(n_)
                th = np.empty((1, 3, len(bs.s)))
                _angles(ch, z, np.full((1, 3), rod.clamp_angle), bs.s, th)
                th0 = th[0, 0]
                Q = bs.K + (bs.psi * (bs.w * (f[0] * np.cos(th0) + f[1] * np.sin(th0)))) @ bs.psi.T
                rows = []
                nperp = np.stack([-np.sin(th0), np.cos(th0)]) * bs.w
                if tip in ("pinned", "clamped"):
                    rows += list(nperp @ bs.psi.T)
                elif tip == "slider":
                    g = np.array([-np.sin(slider_angle), np.cos(slider_angle)])
                    rows.append(g @ nperp @ bs.psi.T)
                if tip == "clamped":
                    rows.append(bs.tip)
                if rows:
                    Cm = np.array(rows)
                    B = np.empty((len(Q), len(Q)))
                    r = _project(np.array(Q), Cm, B)
                    evs.append(np.linalg.eigvalsh(B[:len(Q) - r, :len(Q) - r]))
                else:
                    evs.append(np.linalg.eigvalsh(0.5 * (Q + Q.T)))
                results.append(n_)
            ev1, ev2 = evs
            k = min(len(ev1), len(ev2), 6)
            res = 2.0 * abs(ev2[0] - ev1[0]) + ROUNDOFF * np.max(np.abs(np.diag(bs.K))) * results[-1] ** 2
            mu = float(ev2[0])
            if abs(mu) > 3 * res or results[-1] >= N_MAX:
                break
            N = min(N_MAX, 2 * N)
    err = 2.0 * np.abs(ev2[:k] - ev1[:k]) + (res - 2.0 * abs(ev2[0] - ev1[0]))
    near = np.any(np.abs(ev2[:k]) <= 3 * err)
    stable = None if abs(mu) <= 3 * res else mu > 0
    index = 0 if stable else (None if near else int(np.sum(ev2 < 0)))
    return RodStability(stable, index, mu, float(res), tip)
