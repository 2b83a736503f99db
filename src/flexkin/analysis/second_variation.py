"""The discretised second variation: banded p-version finite elements, Sylvester inertia and
shift-invert (the stability margin, and the fallback of the closed-form verdict).

**The problem** (see :mod:`flexkin.analysis.stability`, Eqs. S1-S3).  On admissible
perturbations ``v = (eta_1, eta_2, eta_3, dq)`` the smallest eigenvalue ``mu`` of

    Q[v] = mu |v|^2,   |v|^2 = sum_i int_0^{L_i} eta_i^2 ds / L_ref + |dP / L_ref|^2 + dtheta^2     (F1)

in units of ``EI_ref / L_ref`` is the **margin**.  Each rod ``i`` in its unit arc length
``s`` in [0, 1] contributes ``(e_i / l_i) int (eta'^2 + q_i eta^2) ds`` with ``q_i = f_i . t_i`` the
unit rod's tip force along its tangent, and the metric ``l_i int eta^2 ds`` (``l_i = L_i / L_ref``,
``e_i = EI_i / EI_ref``).

**Discretisation.**  Every rod is cut into ``E_i = max(2, ceil(lambda_i L_i / 2))`` equal
elements (features have the width ``1 / lambda``) carrying the hierarchical basis of the
p-version: the two vertex functions and the integrated Legendre bubbles of degree 2..p
(``int B_j' B_k' = delta_jk``), C0 across elements, ``eta(0) = 0``.  The element integrals are
Gauss-Legendre quadratures of the closed-form tangent angle, evaluated at ``p + 3`` nodes per
element.  Numbering the dofs element by element makes the stiffness ``K_i`` and the mass ``M_i``
of a rod banded with half-bandwidth ``p``; a rod couples to the platform only through its
tip constraints (S2, S3): two dense rows (and, for a clamped tip, the last dof) -- a low-rank
coupling.  The eigenvalues converge exponentially in ``p``: with ``p = 8`` they are within
~1e-8 (relative, median) of the converged values.

**Shift-invert.**  For a shift ``sigma`` the KKT matrix of the constrained pencil

    [[K_r - sigma M_r, 0, C^T], [0, P - sigma I, T^T], [C, T, 0]]                          (F2)

is factored rod by rod (banded ``L D L^T``, ``O(n p^2)``), and the Schur complement on the pose
and the multipliers, ``S = [[P - sigma I, T^T], [T, -C (K_r - sigma M_r)^-1 C^T]]`` (at most
12 x 12), closes the system.  Sylvester's law of inertia and Haynsworth's additivity give the
number of eigenvalues below ``sigma``:

    count(sigma) = sum_i neg(L D L^T)_i + neg(S) - m     (m constraint rows)                 (F3)

The smallest eigenvalue is isolated by bisection on ``count`` (or, when the index is known to
be 0, approached from ``sigma = 0``), refined by inverse iteration and Rayleigh-quotient
iteration, and confirmed by ``count(mu - 1e-9 |mu|) = 0``.  Along a continuation the previous
eigenvector (same elements) starts the Rayleigh-quotient iteration directly.

**Resolution.**  The same problem on the nested subspace of degree ``p - 2`` (the top bubbles
dropped) gives ``mu_c >= mu``; ``2 |mu - mu_c|`` plus a round-off floor is the resolution
(measured: always above the true error, by a factor > 30).  The discretised index is
``count(0)``, resolved when ``count(-3 res) = count(3 res)``.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.jit import njit
from ..rod.elliptic import rf
from ..rod.kernels import CHART_UNIFIED, tangents

__all__ = ["element_rule", "P_FINE", "P_COARSE", "ELEMENT_SPAN", "ROUNDOFF", "fe_stability", "pinned_tangents",
           "elements_for"]

#: element degree of the margin and of its nested coarse resolution
P_FINE, P_COARSE = 8, 6
#: lambda L per element
ELEMENT_SPAN = 2.0
#: round-off floor of the resolution, relative to the largest diagonal entry of M^-1 K
ROUNDOFF = 1e-13


@lru_cache(maxsize=4)
def element_rule(p: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Gauss-Legendre nodes ``xi`` and weights on [-1, 1] (``p + 3`` of them) and the shape
    functions there, ``(p + 1, ng)``: row 0 the first vertex, rows 1..p-1 the bubbles of degree
    2..p, ``(P_j - P_{j-2}) / sqrt(2 (2 j - 1))``, row p the last vertex (cached, read-only)."""
    ng = p + 3
    x, w = np.polynomial.legendre.leggauss(ng)
    P = np.polynomial.legendre.legvander(x, p)
    sh = np.empty((p + 1, ng))
    sh[0] = 0.5 * (1.0 - x)
    sh[p] = 0.5 * (1.0 + x)
    for j in range(2, p + 1):
        sh[j - 1] = (P[:, j] - P[:, j - 2]) / math.sqrt(2.0 * (2 * j - 1))
    for a in (x, w, sh):
        a.setflags(write=False)
    return x, w, sh


def elements_for(lam: NDArray) -> NDArray[np.int64]:
    """Elements per rod for rods with ``lambda L = lam``."""
    return np.maximum(2, np.ceil(np.nan_to_num(np.asarray(lam, dtype=float)) / ELEMENT_SPAN)).astype(np.int64)


# ---- the tangent angle at the quadrature nodes ------------------------------------------------------
@njit
def _F(phi: float, kp2: float, K: float) -> float:
    """``F(phi | 1 - kp2)`` at any real amplitude (Carlson, DLMF 19.25.5; ``kp2`` exact)."""
    n = math.floor(phi / math.pi + 0.5)
    r = phi - n * math.pi
    sr = math.sin(r)
    cr = math.cos(r)
    return sr * rf(cr * cr, cr * cr + kp2 * sr * sr, 1.0) + 2.0 * n * K


@njit
def pinned_tangents(v, phis, s, out) -> None:
    """Tangent angles ``theta(s)`` (clamp frame) of the pinned unit rod ``(v, phis)`` (unified
    chart) at increasing unit arc lengths ``s``: the amplitude ``phi(s) = am(F(phis) + lambda s)``
    by Newton on ``F`` (``k'`` exact), each node seeded by a second-order Taylor step of
    ``phi' = lambda Delta`` from the previous one; ``theta = psi + 2 atan2(-Delta, k sin phi)``.

    (:func:`flexkin.rod.kernels.unified_tangents` reduces the amplitude to one period first and
    restarts from a crude guess when a node crosses into the next period; along a rod the
    unreduced Newton from the neighbour converges in 2-3 steps.)
    """
    av = min(abs(v), 350.0)
    kp = 2.0 * math.exp(-av) / (1.0 + math.exp(-2.0 * av))
    ku = math.tanh(v)
    kp2 = kp * kp
    m = ku * ku
    K = rf(0.0, kp2, 1.0)
    Fs = _F(phis, kp2, K)
    Phi = K - Fs
    if not Phi > 0.0:
        out[:] = 0.0
        return
    ss, cs = math.sin(phis), math.cos(phis)
    d = math.sqrt(cs * cs + kp2 * ss * ss)
    psi = 2.0 * math.atan2(d, ku * ss)
    phi = phis
    s_prev = 0.0
    for j in range(s.shape[0]):
        h = Phi * (s[j] - s_prev)
        sp, cp = math.sin(phi), math.cos(phi)
        phi = phi + h * d - 0.5 * h * h * m * sp * cp
        u = Fs + Phi * s[j]
        for _ in range(40):
            sp, cp = math.sin(phi), math.cos(phi)
            d = math.sqrt(cp * cp + kp2 * sp * sp)
            step = min(max((_F(phi, kp2, K) - u) * d, -0.5), 0.5)
            phi -= step
            if abs(step) <= 1e-14 * (1.0 + abs(phi)):
                break
        sp, cp = math.sin(phi), math.cos(phi)
        d = math.sqrt(cp * cp + kp2 * sp * sp)
        out[j] = psi + 2.0 * math.atan2(-d, ku * sp)
        s_prev = s[j]


@njit
def rod_nodes(chart, z, E, xg, out) -> None:
    """Local tangent angles of one unit rod at the ``E * len(xg)`` quadrature nodes of its
    ``E`` elements (unified chart: :func:`pinned_tangents`; others: the rod's profile)."""
    ng = xg.shape[0]
    s = np.empty(E * ng)
    for k in range(E):
        for g in range(ng):
            s[k * ng + g] = (k + 0.5 * (xg[g] + 1.0)) / E
    if chart == CHART_UNIFIED:
        pinned_tangents(z[0], z[1], s, out)
    else:
        tangents(chart, z, s, out)


# ---- banded symmetric linear algebra ----------------------------------------------------------------
@njit
def _ldl_band(Kb, Mb, sigma, n, w, Lb, d) -> int:
    """``L D L^T`` of the banded ``K - sigma M`` (lower storage ``A[k, j] = A[j + k, j]``,
    half-bandwidth ``w``) without pivoting; returns the number of negative pivots (Sylvester).
    A pivot below 1e-15 of its diagonal entry is replaced by that (the count of a shift moved
    by as much; inverse iteration at an eigenvalue wants the large solution, not an overflow)."""
    neg = 0
    for j in range(n):
        s = Kb[0, j] - sigma * Mb[0, j]
        for k in range(max(0, j - w), j):
            lj = Lb[j - k, k]
            s -= lj * lj * d[k]
        tiny = 1e-15 * (abs(Kb[0, j]) + abs(sigma * Mb[0, j])) + 1e-300
        if abs(s) < tiny:
            s = tiny if s >= 0.0 else -tiny
        d[j] = s
        if s < 0.0:
            neg += 1
        inv = 1.0 / s
        for i in range(j + 1, min(n, j + w + 1)):
            t = Kb[i - j, j] - sigma * Mb[i - j, j]
            for k in range(max(0, i - w), j):
                t -= Lb[i - k, k] * Lb[j - k, k] * d[k]
            Lb[i - j, j] = t * inv
    return neg


@njit
def _solve_band(Lb, d, n, w, b) -> None:
    """``b <- (L D L^T)^-1 b`` in place."""
    for i in range(n):
        s = b[i]
        for k in range(max(0, i - w), i):
            s -= Lb[i - k, k] * b[k]
        b[i] = s
    for i in range(n):
        b[i] /= d[i]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, min(n, i + w + 1)):
            s -= Lb[k - i, i] * b[k]
        b[i] = s


@njit
def _bandmv(Ab, n, w, x, y) -> None:
    """``y = A x`` for a banded symmetric ``A``."""
    for i in range(n):
        y[i] = Ab[0, i] * x[i]
    for k in range(1, w + 1):
        for j in range(n - k):
            a = Ab[k, j]
            y[j + k] += a * x[j]
            y[j] += a * x[j + k]


@njit
def _lu_solve(S, n, b):
    """``S[:n, :n] x = b`` by LU with partial pivoting; a vanishing pivot is replaced by a tiny
    one (inverse iteration at an eigenvalue wants the large solution, not a failure)."""
    A = S[:n, :n].copy()
    x = b.copy()
    scale = 0.0
    for i in range(n):
        for j in range(n):
            scale = max(scale, abs(A[i, j]))
    tiny = 1e-150 + 1e-16 * scale
    for k in range(n):
        piv = k
        for i in range(k + 1, n):
            if abs(A[i, k]) > abs(A[piv, k]):
                piv = i
        if piv != k:
            for j in range(n):
                t = A[k, j]
                A[k, j] = A[piv, j]
                A[piv, j] = t
            t = x[k]
            x[k] = x[piv]
            x[piv] = t
        if abs(A[k, k]) < tiny:
            A[k, k] = tiny
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= f * A[k, j]
                x[i] -= f * x[k]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, n):
            s -= A[i, j] * x[j]
        x[i] = s / A[i, i]
    return x


@njit
def negative_eigenvalues(S, n) -> int:
    """Number of negative eigenvalues of the symmetric ``S[:n, :n]``: Sylvester's law on a
    symmetric ``L D L^T`` with Bunch-Parlett pivoting (1 x 1 pivots on the largest diagonal
    entry, 2 x 2 pivots on the largest off-diagonal one when the diagonal is too small)."""
    A = S[:n, :n].copy()
    alive = np.ones(n, np.bool_)
    neg = 0
    alpha = (1.0 + math.sqrt(17.0)) / 8.0
    left = n
    while left > 0:
        d0 = 0.0
        p = -1
        o1 = 0.0
        r = -1
        c = -1
        for i in range(n):
            if not alive[i]:
                continue
            if abs(A[i, i]) >= d0:
                d0 = abs(A[i, i])
                p = i
            for j in range(i + 1, n):
                if alive[j] and abs(A[i, j]) > o1:
                    o1 = abs(A[i, j])
                    r = i
                    c = j
        if d0 >= alpha * o1:
            piv = A[p, p]
            if piv < 0.0:
                neg += 1
            if piv == 0.0:
                alive[p] = False     # an exactly zero row and column: a zero eigenvalue
                left -= 1
                continue
            for i in range(n):
                if alive[i] and i != p:
                    f = A[i, p] / piv
                    for j in range(n):
                        if alive[j] and j != p:
                            A[i, j] -= f * A[p, j]
            alive[p] = False
            left -= 1
        else:
            a, b, dd = A[r, r], A[r, c], A[c, c]
            det = a * dd - b * b
            if det < 0.0:
                neg += 1
            elif a + dd < 0.0:
                neg += 2
            ia, ib, id_ = dd / det, -b / det, a / det
            for i in range(n):
                if alive[i] and i != r and i != c:
                    xr = A[i, r]
                    xc = A[i, c]
                    fr = xr * ia + xc * ib
                    fc = xr * ib + xc * id_
                    for j in range(n):
                        if alive[j] and j != r and j != c:
                            A[i, j] -= fr * A[r, j] + fc * A[c, j]
            alive[r] = False
            alive[c] = False
            left -= 2
    return neg


# ---- assembly -------------------------------------------------------------------------------------------
@njit
def _assemble(th, fx, fy, alpha, ell, e, E, pc, p, xg, wg, sh, Kb, Mb, C) -> int:
    """One rod's banded stiffness ``K`` (with the load term), mass ``M`` and tip-position rows
    ``C`` (2, n) at element degree ``pc <= p`` (``n = E pc`` dofs), from its local tangent angles
    ``th`` at the quadrature nodes (Eq. F1: ``K`` in EI_ref/L_ref, ``M`` and ``C`` in L_ref)."""
    ng = xg.shape[0]
    h = 1.0 / E
    Kb[:, :] = 0.0
    Mb[:, :] = 0.0
    C[:, :] = 0.0
    kf = e / ell
    qn = np.empty(ng)
    sn = np.empty(ng)
    cn = np.empty(ng)
    loc = np.empty(pc + 1, np.int64)
    for k in range(E):
        for g in range(ng):
            t = th[k * ng + g]
            qn[g] = wg[g] * (fx * math.cos(t) + fy * math.sin(t))
            sn[g] = wg[g] * math.sin(alpha + t)
            cn[g] = wg[g] * math.cos(alpha + t)
        loc[0] = k * pc - 1                  # the element's first vertex (none at s = 0)
        for j in range(1, pc):
            loc[j] = k * pc + j - 1          # its bubbles of degree 2 .. pc
        loc[pc] = k * pc + pc - 1            # its last vertex
        for a in range(pc + 1):
            ia = loc[a]
            if ia < 0:
                continue
            sa = a if a < pc else p
            cx = 0.0
            cy = 0.0
            for g in range(ng):
                cx -= sn[g] * sh[sa, g]
                cy += cn[g] * sh[sa, g]
            C[0, ia] += ell * 0.5 * h * cx
            C[1, ia] += ell * 0.5 * h * cy
            for b in range(a + 1):
                ib = loc[b]
                if ib < 0:
                    continue
                sb = b if b < pc else p
                kq = 0.0
                mm = 0.0
                for g in range(ng):
                    t = sh[sa, g] * sh[sb, g]
                    mm += wg[g] * t
                    kq += qn[g] * t
                ks = 0.0
                if (a == 0 or a == pc) and (b == 0 or b == pc):
                    ks = 1.0 if a == b else -1.0     # vertices: int N' N' = +-1 / h
                elif a == b:
                    ks = 2.0                         # bubbles: int B_j' B_j' = 2 / h
                Kb[ia - ib, ib] += kf * (ks / h + 0.5 * h * kq)
                Mb[ia - ib, ib] += ell * 0.5 * h * mm
    return E * pc


@njit
def _place_rows(Ct, code, gn, n, C) -> None:
    """A rod's constraint rows from its two tip-position rows ``Ct``: code 0 both; 1 both and
    the tip angle (the last dof); 2 none (a free tip); 3 one row ``gn . Ct`` (a slider with
    normal ``gn``)."""
    if code == 2:
        return
    if code == 3:
        for j in range(n):
            C[0, j] = gn[0] * Ct[0, j] + gn[1] * Ct[1, j]
        return
    for j in range(n):
        C[0, j] = Ct[0, j]
        C[1, j] = Ct[1, j]
    if code == 1:
        C[2, n - 1] = 1.0


# ---- the constrained pencil ----------------------------------------------------------------------------
@njit
def _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, sigma, Lb, dd, Z, S, count) -> tuple[int, int]:
    """Factor (Eq. F2) at the shift ``sigma``: ``L D L^T`` of every rod, ``Z_i = A_i^-1 C_i^T``
    and the Schur matrix ``S``.  Returns the number of eigenvalues below ``sigma`` (Eq. F3; 0
    without ``count``) and the size of ``S``."""
    m = 0
    for i in range(nrod):
        m += mi[i]
    nS = npose + m
    S[:nS, :nS] = 0.0
    for a in range(npose):
        for b in range(npose):
            S[a, b] = Pp[a, b]
        S[a, a] -= sigma
    neg = 0
    row = npose
    for i in range(nrod):
        n = ns[i]
        neg += _ldl_band(Kb[i], Mb[i], sigma, n, w, Lb[i], dd[i])
        for r in range(mi[i]):
            for j in range(n):
                Z[i, r, j] = C[i, r, j]
            _solve_band(Lb[i], dd[i], n, w, Z[i, r])
        for r in range(mi[i]):
            for c in range(mi[i]):
                t = 0.0
                for j in range(n):
                    t += C[i, r, j] * Z[i, c, j]
                S[row + r, row + c] = -t
            for c in range(npose):
                S[row + r, c] = T[i, r, c]
                S[c, row + r] = T[i, r, c]
        row += mi[i]
    if not count:
        return 0, nS
    return neg + negative_eigenvalues(S, nS) - m, nS


@njit
def _solve(Lb, dd, Z, C, mi, ns, nrod, npose, w, S, nS, br, bp, vr, vp) -> None:
    """Solve the factored KKT system (Eq. F2) for the right-hand side ``(br, bp, 0)``."""
    rhs = np.zeros(nS)
    for c in range(npose):
        rhs[c] = bp[c]
    row = npose
    for i in range(nrod):
        n = ns[i]
        for j in range(n):
            vr[i, j] = br[i, j]
        _solve_band(Lb[i], dd[i], n, w, vr[i])
        for r in range(mi[i]):
            t = 0.0
            for j in range(n):
                t += C[i, r, j] * vr[i, j]
            rhs[row + r] = -t
        row += mi[i]
    sol = _lu_solve(S, nS, rhs)
    for c in range(npose):
        vp[c] = sol[c]
    row = npose
    for i in range(nrod):
        n = ns[i]
        for r in range(mi[i]):
            lam = sol[row + r]
            for j in range(n):
                vr[i, j] -= Z[i, r, j] * lam
        row += mi[i]


@njit
def _rq(Kb, Mb, ns, nrod, npose, w, Pp, vr, vp, tmp) -> tuple[float, float]:
    """Rayleigh quotient ``v^T K v / v^T M v`` and the norm ``|v|_M``."""
    num = 0.0
    den = 0.0
    for a in range(npose):
        den += vp[a] * vp[a]
        for b in range(npose):
            num += vp[a] * Pp[a, b] * vp[b]
    for i in range(nrod):
        n = ns[i]
        _bandmv(Kb[i], n, w, vr[i], tmp)
        for j in range(n):
            num += vr[i, j] * tmp[j]
        _bandmv(Mb[i], n, w, vr[i], tmp)
        for j in range(n):
            den += vr[i, j] * tmp[j]
    return num / den, math.sqrt(den)


@njit
def _inverse_step(Kb, Mb, C, mi, ns, nrod, npose, w, Pp, Lb, dd, Z, S, nS, br, bp, vr, vp, tmp) -> float:
    """One step ``v <- (K - sigma M)^-1 M v`` on the constraints (factored), normalised; returns
    the new Rayleigh quotient."""
    for i in range(nrod):
        _bandmv(Mb[i], ns[i], w, vr[i], br[i])
    for c in range(npose):
        bp[c] = vp[c]
    _solve(Lb, dd, Z, C, mi, ns, nrod, npose, w, S, nS, br, bp, vr, vp)
    rho, nrm = _rq(Kb, Mb, ns, nrod, npose, w, Pp, vr, vp, tmp)
    vr /= nrm
    vp /= nrm
    return rho


@njit
def _lowest(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, L0, vr, vp, guess, c0, verify) -> tuple[float, int]:
    """The smallest eigenvalue of the constrained pencil and its eigenvector ``(vr, vp)`` (in:
    the guess when ``guess``); ``c0`` is the index when known (else -1), ``L0`` a lower bound.
    Returns the eigenvalue and the number of factorisations (module docstring)."""
    nmax = vr.shape[1]
    Lb = np.empty((3, w + 1, nmax))
    dd = np.empty((3, nmax))
    Z = np.empty((3, 3, nmax))
    S = np.empty((12, 12))
    br = np.zeros((3, nmax))
    bp = np.zeros(3)
    tmp = np.empty(nmax)
    nf = 0
    hi = np.inf
    if c0 < 0 and not guess:
        c0, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, 0.0, Lb, dd, Z, S, True)
        nf += 1
    if c0 >= 1:
        hi = 0.0
    rho = 0.0
    for attempt in range(4):
        if not guess or attempt > 0:
            seed = 12345 + attempt      # a start that is not orthogonal to the eigenvector
            for i in range(nrod):
                for j in range(ns[i]):
                    seed = (seed * 1103515245 + 12345) % 2147483648
                    vr[i, j] = seed / 2147483648.0 - 0.5
            for c in range(npose):
                vp[c] = 0.0
            if c0 == 0 and hi == np.inf:
                lo = 0.0                # stable: the lowest eigenvalue is the one nearest to 0
            else:
                # isolate it by Sylvester bisection: count(lo) = 0 < count(hi) = 1
                lo = L0
                for _ in range(60):
                    cl, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, lo, Lb, dd, Z, S, True)
                    nf += 1
                    if cl == 0:
                        break
                    hi = lo
                    lo = 2.0 * lo - 1.0
                if cl != 0:
                    return np.nan, nf
                ch = 0
                if hi < np.inf:
                    ch, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, hi, Lb, dd, Z, S, True)
                    nf += 1
                if ch == 0:
                    hi = max(1.0, 2.0 * abs(lo))
                    for _ in range(60):
                        ch, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, hi, Lb, dd, Z, S, True)
                        nf += 1
                        if ch >= 1:
                            break
                        lo = hi
                        hi *= 4.0
                    if ch < 1:
                        return np.nan, nf
                for _ in range(200):
                    if not (ch > 1 or (hi - lo > 0.05 * (hi - L0) + 1e-6 and hi - lo > 0.25 * abs(hi))):
                        break
                    mid = 0.5 * (lo + hi)
                    cm, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, mid, Lb, dd, Z, S, True)
                    nf += 1
                    if cm == 0:
                        lo = mid
                    else:
                        hi = mid
                        ch = cm
            # inverse iteration at lo: the lowest eigenvalue is the nearest above it
            cl, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, lo, Lb, dd, Z, S, False)
            nf += 1
            for _ in range(5):
                _inverse_step(Kb, Mb, C, mi, ns, nrod, npose, w, Pp, Lb, dd, Z, S, nS, br, bp, vr, vp, tmp)
        rho, nrm = _rq(Kb, Mb, ns, nrod, npose, w, Pp, vr, vp, tmp)
        vr /= nrm
        vp /= nrm
        # Rayleigh quotient iteration
        for _ in range(10):
            cr, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, rho, Lb, dd, Z, S, False)
            nf += 1
            r2 = _inverse_step(Kb, Mb, C, mi, ns, nrod, npose, w, Pp, Lb, dd, Z, S, nS, br, bp, vr, vp, tmp)
            done = abs(r2 - rho) <= 1e-12 * (1.0 + abs(r2))
            rho = r2
            if done:
                break
        if not verify:
            break
        # the lowest: no eigenvalue below it (Sylvester)
        cb, nS = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, rho - 1e-9 * (1.0 + abs(rho)), Lb, dd, Z, S,
                         True)
        nf += 1
        if cb == 0:
            break
        hi = min(hi, rho)
    return rho, nf


@njit
def _count(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, sigma) -> int:
    """Number of eigenvalues of the constrained pencil below ``sigma`` (Eq. F3)."""
    nmax = Kb.shape[2]
    Lb = np.empty((3, w + 1, nmax))
    dd = np.empty((3, nmax))
    Z = np.empty((3, 3, nmax))
    S = np.empty((12, 12))
    c, _ = _factor(Kb, Mb, C, T, mi, ns, nrod, npose, w, Pp, sigma, Lb, dd, Z, S, True)
    return c


#: a constraint row whose component independent of the others is below this fraction of the
#: largest is vacuous: to first order a straight rod's axial constraint does not restrict it
RANK_RTOL = 1e-9


@njit
def _independent_rows(C, Cc, T, mi, ns, nrod, npose) -> None:
    """Drop the constraint rows that depend on the others (pivoted Cholesky of their Gram
    matrix over the rods' dofs and the pose): the KKT inertia (Eq. F3) needs independent rows.
    ``C``, ``Cc`` (fine and coarse rows), ``T`` and ``mi`` are compacted in place."""
    m = 0
    for i in range(nrod):
        m += mi[i]
    rod = np.empty(m, np.int64)
    loc = np.empty(m, np.int64)
    r = 0
    for i in range(nrod):
        for a in range(mi[i]):
            rod[r] = i
            loc[r] = a
            r += 1
    G = np.zeros((m, m))
    for a in range(m):
        for b in range(m):
            t = 0.0
            if rod[a] == rod[b]:
                i = rod[a]
                for j in range(ns[i]):
                    t += C[i, loc[a], j] * C[i, loc[b], j]
            for c in range(npose):
                t += T[rod[a], loc[a], c] * T[rod[b], loc[b], c]
            G[a, b] = t
    keep = np.ones(m, np.bool_)
    top = 0.0
    for a in range(m):
        top = max(top, G[a, a])
    done = np.zeros(m, np.bool_)
    for _ in range(m):
        piv = -1
        best = -1.0
        for a in range(m):
            if not done[a] and G[a, a] > best:
                best = G[a, a]
                piv = a
        if best <= RANK_RTOL * RANK_RTOL * top:
            for a in range(m):
                if not done[a]:
                    keep[a] = False
            break
        done[piv] = True
        for a in range(m):
            if not done[a]:
                f = G[a, piv] / best
                for b in range(m):
                    if not done[b]:
                        G[a, b] -= f * G[piv, b]
    for i in range(nrod):
        k = 0
        for a in range(mi[i]):
            r = 0
            for q in range(m):
                if rod[q] == i and loc[q] == a:
                    r = q
            if keep[r]:
                if k != a:
                    C[i, k, :] = C[i, a, :]
                    Cc[i, k, :] = Cc[i, a, :]
                    T[i, k, :] = T[i, a, :]
                k += 1
        mi[i] = k


@njit
def fe_stability(th, fu, alpha, ell, e, E, mi, code, gn, T, Pp, nrod, npose, xg, wg, sh, L0, c0,
                 vr, vp, guess, want_index) -> tuple[float, float, int, int]:
    """Margin, resolution and (with ``want_index``) the discretised index of one equilibrium.

    ``th`` (3, nnode) local tangent angles at the quadrature nodes (:func:`rod_nodes`), ``fu``
    (3, 2) unit-rod tip forces (clamp frames), ``alpha``, ``ell``, ``e`` (3,) clamp angles,
    lengths and stiffnesses, ``E`` (3,) elements per rod, ``mi`` (3,) constraint rows per rod
    and ``code`` (3,) their kind (:func:`_place_rows`; ``gn`` (3, 2) a slider's normal), ``T``
    (3, 3, 3) their coupling to the ``npose`` (3 or 0) pose unknowns, ``Pp`` (3, 3) the pose's
    own form, ``L0`` a lower bound of the spectrum, ``c0`` the index if known (else -1);
    ``vr`` (3, E_max P_FINE), ``vp`` (3,): the eigenvector (in: the guess with ``guess``).
    Returns (margin, resolution, index or -1 when unresolved / not asked, factorisations).
    """
    p, pc = P_FINE, P_COARSE
    nmax = vr.shape[1]
    Kb = np.empty((3, p + 1, nmax))
    Mb = np.empty((3, p + 1, nmax))
    C = np.zeros((3, 3, nmax))
    Kc = np.empty((3, pc + 1, nmax))
    Mc = np.empty((3, pc + 1, nmax))
    Cc = np.zeros((3, 3, nmax))
    ns = np.zeros(3, np.int64)
    nc = np.zeros(3, np.int64)
    Ct = np.empty((2, nmax))
    for i in range(nrod):
        ns[i] = _assemble(th[i], fu[i, 0], fu[i, 1], alpha[i], ell[i], e[i], E[i], p, p, xg, wg, sh, Kb[i], Mb[i],
                          Ct)
        _place_rows(Ct, code[i], gn[i], ns[i], C[i])
        nc[i] = _assemble(th[i], fu[i, 0], fu[i, 1], alpha[i], ell[i], e[i], E[i], pc, p, xg, wg, sh, Kc[i],
                          Mc[i], Ct)
        _place_rows(Ct, code[i], gn[i], nc[i], Cc[i])
    scale = 0.0
    for i in range(nrod):
        for j in range(ns[i]):
            scale = max(scale, abs(Kb[i, 0, j]) / max(Mb[i, 0, j], 1e-300))
    _independent_rows(C, Cc, T, mi, ns, nrod, npose)
    mu, nf = _lowest(Kb, Mb, C, T, mi, ns, nrod, npose, p, Pp, L0, vr, vp, guess, c0, True)
    # the nested coarse subspace, from the fine eigenvector restricted to it
    wc = np.zeros((3, nmax))
    wp = vp.copy()
    for i in range(nrod):
        for k in range(E[i]):
            for j in range(pc - 1):
                wc[i, k * pc + j] = vr[i, k * p + j]
            wc[i, k * pc + pc - 1] = vr[i, k * p + p - 1]
    muc, nfc = _lowest(Kc, Mc, Cc, T, mi, nc, nrod, npose, pc, Pp, L0, wc, wp, True, c0, False)
    res = 2.0 * abs(mu - muc) + ROUNDOFF * scale
    idx = -1
    if want_index:
        delta = 3.0 * res
        clo = _count(Kb, Mb, C, T, mi, ns, nrod, npose, p, Pp, -delta)
        chi = _count(Kb, Mb, C, T, mi, ns, nrod, npose, p, Pp, delta)
        if clo == chi:
            idx = clo
        nf += 2
    return mu, res, idx, nf + nfc
