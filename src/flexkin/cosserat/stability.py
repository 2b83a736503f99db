"""Stability of a mechanism equilibrium in the Cosserat model: the discretised second variation.

With the actuators locked (clamps fixed), the potential of the mechanism is

    V = sum_i int_0^{L_i} [ EI th'^2/2 + (v - e1)^T C (v - e1)/2 - f . p ] ds - F . P - M_z th_P,

``v = R(th)^T p'``, ``C = diag(EA, kappa G A)``, with the tips tied to the platform
(``p_i(L) = B_i(pose)``; a clamped tip also ``th_i(L) = th_P + beta_i``).  At an equilibrium
its second variation in the perturbations ``(dp, dth)`` of the rods and ``dq`` of the pose is

    d2V = sum_i int EI dth'^2 + e^T C e - 2 dth (J^T n) . dp' - (n . p') dth^2 ds
          - sum_i n_i(L) . (B_i - P) dth_P^2,           e = R^T dp' - J v dth,

(``J`` the rotation by +90 deg, ``n`` the internal force, world frame; the last term is the
curvature of the constraint ``B_i(th_P)``; dead loads contribute nothing).  It is discretised
with linear finite elements in ``(dx, dy, dth)`` and one-point (midpoint) quadrature —
the locking-free Timoshenko element — using the equilibrium fields sampled at the element
midpoints from the shooting solution.

The smallest eigenvalue of ``H phi = lambda M phi`` is found by bisection on the inertia of
``H - sigma M`` (Sylvester's law), counted by a block LDL^T elimination along each rod whose
Schur complements meet in the 3x3 platform block, O(elements) per count.  Units: positions
in units of the mean rod length ``Lref``, energies in ``EIref / Lref``; the metric ``M`` gives
each rod node its length share ``h / Lref`` in ``(dx, dy, dth)`` and each platform coordinate
weight 1.  Computed on two meshes (``M`` and ``2M`` elements per rod; the caller chooses ``M``,
:func:`flexkin.cosserat.refine` takes at least 32 and 8 per unit of ``L sqrt(R/EI)``, the wave
number of a rod under force ``R``); the difference estimates the O(h^2) discretisation error,
and the verdict is ``None`` when the Richardson-extrapolated eigenvalue is not separated from 0
by twice that error.  A rigid direction (zero compliance) is given the stiffness
``1e8 EIref / Lref^2`` (penalty), which changes the eigenvalues by ~1e-8 relative.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import prange

from ..core.jit import njit

__all__ = ["StabilityVerdict", "smallest_eigenvalue_batch", "verdict"]

#: stiffness used for a rigid (zero-compliance) direction, in units of EIref / Lref^2
_RIGID = 1e8


@njit(cache=True, inline="always")
def _elem(th, nx, ny, EI, Ca, Cs, ce, cs, h, K):
    """6x6 element matrix (SI) for dofs (dx_a, dy_a, dth_a, dx_b, dy_b, dth_b)."""
    c = math.cos(th)
    s = math.sin(th)
    nt = nx * c + ny * s
    nn = -nx * s + ny * c
    vx = 1.0 + ce * nt
    vy = cs * nn
    ax = vx * c - vy * s
    ay = vx * s + vy * c
    # P = [R^T | -J v] : rows (material 1, 2), cols (da_x, da_y, dthbar); -J v = (vy, -vx)
    P = np.empty((2, 3))
    P[0, 0] = c
    P[0, 1] = s
    P[0, 2] = vy
    P[1, 0] = -s
    P[1, 1] = c
    P[1, 2] = -vx
    D = np.zeros((4, 4))  # (dth', da_x, da_y, dthbar)
    D[0, 0] = EI
    for i in range(3):
        for j in range(3):
            D[1 + i, 1 + j] = Ca * P[0, i] * P[0, j] + Cs * P[1, i] * P[1, j]
    # -2 dthbar (J^T n) . da, J^T n = (ny, -nx)
    D[1, 3] -= ny
    D[3, 1] -= ny
    D[2, 3] += nx
    D[3, 2] += nx
    D[3, 3] -= nx * ax + ny * ay
    # B: w = Bm @ (dx_a, dy_a, dth_a, dx_b, dy_b, dth_b)
    Bm = np.zeros((4, 6))
    Bm[0, 2] = -1.0 / h
    Bm[0, 5] = 1.0 / h
    Bm[1, 0] = -1.0 / h
    Bm[1, 3] = 1.0 / h
    Bm[2, 1] = -1.0 / h
    Bm[2, 4] = 1.0 / h
    Bm[3, 2] = 0.5
    Bm[3, 5] = 0.5
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for k in range(4):
                bk = Bm[k, i]
                if bk != 0.0:
                    for l in range(4):
                        acc += bk * D[k, l] * Bm[l, j]
            K[i, j] = h * acc


@njit(cache=True, inline="always")
def _inv3(A, out):
    a, b, c = A[0, 0], A[0, 1], A[0, 2]
    d, e, f = A[1, 0], A[1, 1], A[1, 2]
    g, hh, i = A[2, 0], A[2, 1], A[2, 2]
    c00 = e * i - f * hh
    c01 = -(d * i - f * g)
    c02 = d * hh - e * g
    det = a * c00 + b * c01 + c * c02
    if det == 0.0:
        det = 1e-300
    out[0, 0] = c00 / det
    out[1, 0] = c01 / det
    out[2, 0] = c02 / det
    out[0, 1] = -(b * i - c * hh) / det
    out[1, 1] = (a * i - c * g) / det
    out[2, 1] = -(a * hh - b * g) / det
    out[0, 2] = (b * f - c * e) / det
    out[1, 2] = -(a * f - c * d) / det
    out[2, 2] = (a * e - b * d) / det


@njit(cache=True)
def _neg_pivots(A, n):
    """Negative pivots of the symmetric n x n matrix A (copied) by LDL^T without pivoting."""
    W = A[:n, :n].copy()
    cnt = 0
    for k in range(n):
        d = W[k, k]
        if d == 0.0:
            d = -1e-300
        if d < 0.0:
            cnt += 1
        for i in range(k + 1, n):
            f = W[i, k] / d
            for j in range(k + 1, n):
                W[i, j] -= f * W[k, j]
    return cnt


@njit(cache=True)
def _assemble(mid, nel, rod, Lref, EIref):
    """Scaled element matrices (nel, 6, 6) of rod ``rod`` (position dofs in Lref, energy in EIref/Lref)."""
    EI, ce, cs, Lr = rod[0], rod[1], rod[2], rod[3]
    h = Lr / nel
    Ca = 1.0 / ce if ce > 0.0 else _RIGID * EIref / (Lref * Lref)
    Cs = 1.0 / cs if cs > 0.0 else _RIGID * EIref / (Lref * Lref)
    ce_ = ce if ce > 0.0 else 1.0 / Ca
    cs_ = cs if cs > 0.0 else 1.0 / Cs
    K = np.empty((nel, 6, 6))
    scale = np.array([Lref, Lref, 1.0, Lref, Lref, 1.0])
    for e in range(nel):
        _elem(mid[e, 0], mid[e, 1], mid[e, 2], EI, Ca, Cs, ce_, cs_, h, K[e])
        for i in range(6):
            for j in range(6):
                K[e, i, j] *= scale[i] * scale[j] * Lref / EIref
    return K


@njit(cache=True)
def _count(sigma, Ks, nel, wnode, tails, ntail, geo):
    """Number of generalised eigenvalues below ``sigma`` (three rods + platform)."""
    cnt = 0
    Ptot = np.zeros((3, 3))
    Ptot[0, 0] = -sigma * geo[0]
    Ptot[1, 1] = -sigma * geo[1]
    Ptot[2, 2] = geo[3] - sigma * geo[2]
    S = np.empty((3, 3))
    Si = np.empty((3, 3))
    U = np.empty((3, 3))
    for r in range(3):
        K = Ks[r]
        T = tails[r]
        nt = ntail[r]
        w = wnode[r]
        # interior nodes 1..nel-1
        for j in range(1, nel):
            # node j: element j-1 (as node b) + element j (as node a)
            for a in range(3):
                for b in range(3):
                    S[a, b] = K[j - 1, 3 + a, 3 + b] + K[j, a, b]
            for a in range(3):
                S[a, a] -= sigma * w
            if j >= 2:
                # S -= U^T Si U with U = K[j-1][node a (j-1), node b (j)]; Si = inverse of previous S
                for a in range(3):
                    for b in range(3):
                        acc = 0.0
                        for k in range(3):
                            for l in range(3):
                                acc += U[k, a] * Si[k, l] * U[l, b]
                        S[a, b] -= acc
            cnt += _neg_pivots(S, 3)
            _inv3(S, Si)
            for a in range(3):
                for b in range(3):
                    U[a, b] = K[j, a, 3 + b]
        # tail: last element's node b mapped by T (3 x nt)
        Tail = np.zeros((4, 4))
        for a in range(nt):
            for b in range(nt):
                acc = 0.0
                for k in range(3):
                    for l in range(3):
                        acc += T[k, a] * K[nel - 1, 3 + k, 3 + l] * T[l, b]
                Tail[a, b] = acc
        C = np.zeros((3, 4))  # coupling node nel-1 -> tail: U @ T
        for a in range(3):
            for b in range(nt):
                acc = 0.0
                for k in range(3):
                    acc += U[a, k] * T[k, b]
                C[a, b] = acc
        for a in range(nt):
            for b in range(nt):
                acc = 0.0
                for k in range(3):
                    for l in range(3):
                        acc += C[k, a] * Si[k, l] * C[l, b]
                Tail[a, b] -= acc
        if nt == 4:  # pinned: eliminate the tip rotation dth_L
            d = Tail[0, 0] - sigma * 0.5 * w
            if d == 0.0:
                d = -1e-300
            if d < 0.0:
                cnt += 1
            for a in range(3):
                for b in range(3):
                    Ptot[a, b] += Tail[1 + a, 1 + b] - Tail[1 + a, 0] * Tail[0, 1 + b] / d
        else:
            for a in range(3):
                for b in range(3):
                    Ptot[a, b] += Tail[a, b]
    cnt += _neg_pivots(Ptot, 3)
    return cnt


@njit(cache=True)
def _lambda_min(Ks, nel, wnode, tails, ntail, geo):
    n0 = _count(0.0, Ks, nel, wnode, tails, ntail, geo)
    if n0 == 0:
        lo = 0.0
        hi = 1.0
        it = 0
        while _count(hi, Ks, nel, wnode, tails, ntail, geo) == 0 and it < 80:
            lo = hi
            hi *= 4.0
            it += 1
    else:
        hi = 0.0
        lo = -1.0
        it = 0
        while _count(lo, Ks, nel, wnode, tails, ntail, geo) > 0 and it < 80:
            hi = lo
            lo *= 4.0
            it += 1
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if _count(mid, Ks, nel, wnode, tails, ntail, geo) == 0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-7 * max(abs(lo), abs(hi)) + 1e-12:
            break
    return 0.5 * (lo + hi), n0


@njit(cache=True, parallel=True)
def smallest_eigenvalue_batch(mid, nel, rods, tails, ntail, geo, Lref, EIref):
    """Smallest eigenvalue and Morse index for a batch of mechanisms.

    Parameters
    ----------
    mid : (S, 3, nel, 3) midpoint fields (th, nx, ny) of every element of every rod.
    nel : elements per rod.
    rods : (S, 3, 4) rows (EI, ce, cs, L) with the compliances as used (times tau).
    tails : (S, 3, 3, 4) maps from the tail unknowns to the tip node's (dx, dy, dth) (scaled).
    ntail : (S, 3) int, 4 for a pinned tip (dth_L, dq), 3 for a clamped tip (dq).
    geo : (S, 4) platform block: metric weights (3) and the geometric term of dth_P (scaled).
    """
    ns = mid.shape[0]
    lam = np.empty(ns)
    idx = np.empty(ns, dtype=np.int64)
    for i in prange(ns):
        Ks = np.empty((3, nel, 6, 6))
        wnode = np.empty(3)
        for r in range(3):
            Ks[r] = _assemble(mid[i, r], nel, rods[i, r], Lref, EIref)
            wnode[r] = rods[i, r, 3] / nel / Lref
        lam[i], idx[i] = _lambda_min(Ks, nel, wnode, tails[i], ntail[i], geo[i])
    return lam, idx


# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StabilityVerdict:
    """Stability of one equilibrium with the actuators locked.

    Attributes
    ----------
    stable : True / False, or None when the smallest eigenvalue is not resolved.
    margin : Richardson-extrapolated smallest eigenvalue (dimensionless, see module doc).
    error : its estimated discretisation error.
    index : number of negative eigenvalues (Morse index) on the finer mesh.
    note : why the verdict is None (empty otherwise).
    """

    stable: bool | None
    margin: float
    error: float
    index: int
    note: str = ""


def verdict(lam_coarse: float, lam_fine: float, idx_fine: int, floor: float = 1e-9) -> StabilityVerdict:
    """Tri-state verdict from the eigenvalue on two meshes (h and h/2, O(h^2) convergence)."""
    if not (math.isfinite(lam_coarse) and math.isfinite(lam_fine)):
        return StabilityVerdict(None, 0.0, 0.0, int(idx_fine), "eigenvalue not finite")
    ext = lam_fine + (lam_fine - lam_coarse) / 3.0
    err = abs(lam_fine - lam_coarse) / 3.0 + floor * max(1.0, abs(lam_fine))
    if (lam_coarse > 0) == (lam_fine > 0) and abs(ext) > 2.0 * err:
        return StabilityVerdict(bool(ext > 0), float(ext), float(err), int(idx_fine))
    return StabilityVerdict(None, float(ext), float(err), int(idx_fine),
                            f"smallest eigenvalue {ext:.3g} not separated from 0 by its discretisation "
                            f"error {err:.2g}")
