"""Forward kinematics of mechanisms with clamped legs: the legs' rod sheets on a pose lattice.

With the inputs fixed every clamp is known, and each leg's rods form a three-dimensional sheet
over the pose space ``(x, y, theta)``:

* a **clamped** rod (paper §8) fixes the platform completely: its tip is ``B_i`` and its tip
  tangent is ``theta + tip_angle``, so every unit rod ``z`` of the wrench atlas
  (:mod:`flexkin.rod.wrench_atlas`) is one pose;
* a **pinned** rod fixes ``B_i`` only (Eq. 11: zero tip moment, tangent free): every rod of the
  pinned atlas (:mod:`flexkin.rod.atlas`) is one pose per platform orientation.

The FK solutions are the poses where one rod of every leg balances the load (Eq. 15).  The
search finds every leg's rods at every pose of one regular pose lattice (spacing ``h`` in
``x, y`` and ``2 pi / n_theta`` in ``theta``, over the exact reach region: three disks per
orientation, :func:`pose_lattice`) and linearises the balance there:

1. **seeds**: every node of the leg's rod atlas is an exact rod, hence an exact pose (pinned:
   one per lattice orientation); it is continued (tangent predictor, Newton with the pose
   frozen: :func:`_rod_at`) to its nearest lattice pose, or for a clamped leg to the nearest
   lattice pose of the reach region within the pose extent of the node's grid cells
   (:func:`_cell_seeds`: a reach region smaller than the cells' images lies between nodes).
2. **flood fill**: every rod found at a lattice pose is continued to the six neighbouring
   poses, until no new rod appears.  A leg's rods so cover each sheet wherever the lattice
   resolves it, and rods linked by continuation form its *sheets* (connected components).
   The cost is proportional to the rods found, not to the atlas: no pose is searched.
3. **combinations**: at a lattice pose every triple of rods (one per leg) gives the pose step
   of the linearised balance, a 3 x 3 solve that is the Schur complement of one Newton step
   of the whole FK system; a triple whose step stays within :data:`S_MAX` lattice steps is a
   candidate, one per triple of sheets and cell of :data:`CLUSTER` steps of predicted pose.
4. **pose Newton**: each candidate is solved by Newton on the balance in the pose alone, every
   rod slaved to the pose (continued at every step, so that it never leaves its sheet; steps
   at most one lattice step and halved while a rod cannot follow): taut rods, whose force
   grows steeply near the reach boundary, converge where a Newton step on the whole system
   from the linear prediction does not.  Distinct results, and the linear predictions of the
   candidates whose pose Newton failed (a rod reaching a fold of its sheet, or too taut to
   follow) together with where it stopped, are refined by the FK Newton
   (:func:`flexkin.solve.finish.refine`).

Resolution, not exclusion: a solution is found when its rods' sheets are resolved at the
lattice spacing around it, which the tests measure against the independent multi-start oracle
(``tests/test_clamped_mechanism.py``).  Why not the branch-and-bound of
:mod:`flexkin.solve.fk_search`: with three 3-D clamped atlases it works in 9 dimensions, where
box bounds exclude too little (> 50 M node triples on the unit 3-PF without finishing).  A
nearly taut mechanism's reach region can be a few mm wide: the spacing is then refined so that
:data:`N_ACROSS` steps span it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d import platform_points, rotate
from ..core.jit import njit
from ..core.linalg import solve_into
from ..rod.atlas import KPRIME_MIN, get_atlas
from ..rod.slots import CHART_UNIFIED, CHART_WRENCH, FX, FY, ML, NQ, TH, X, Y
from ..rod.kernels import eval_rod
from ..rod.wrench_atlas import get_wrench_atlas, lambda_max, moment_scale, turning_max
from ..system import System

__all__ = ["lattice_starts", "pose_lattice", "LatticeStats", "S_MAX"]

TWO_PI = 2.0 * math.pi
#: largest predicted pose step (lattice steps, each coordinate) of a candidate
S_MAX = 3.0
#: cell of predicted poses (lattice steps) in which one start per triple of sheets is kept
CLUSTER = 0.25
#: the pose Newton's tolerance (scaled balance residual) and iterations
POSE_TOL, POSE_ITER = 1e-9, 30
#: Newton iterations and tip tolerance (unit rod) of a rod continued to a pose
NEWTON_ITER, NEWTON_TOL = 12, 1e-10
#: lattice offset (fraction of a step): irrational, so that symmetric mechanisms do not put
#: lattice poses exactly on their symmetry planes
OFFSET = (0.3819660112501051, 0.6180339887498949, 0.2360679774997897)
#: default lattice spacing (units of the mechanism's length scale) and orientations per turn
H, N_THETA = 0.05, 48
#: packing of the integer lattice coordinates into one int64 key
_BITS = 21
_BIAS = 1 << (_BITS - 1)


@dataclass(frozen=True)
class LatticeStats:
    """Counts of one lattice search: lattice spacing ``h`` (m) and ``n_theta``; rods (``hits``)
    per leg over the lattice; lattice poses reached by all legs (``poses``); ``combinations``
    examined; candidates (``starts``) and those kept for the pose Newton (``clustered``); whether
    a clamped rod beyond the grid's force limit sits at a pose every leg reaches
    (``force_limit``: the search may miss equilibria there)."""

    h: float
    n_theta: int
    hits: tuple[int, int, int]
    poses: int
    combinations: int
    starts: int
    clustered: int
    force_limit: bool = False


# ---- lattice -------------------------------------------------------------------------------
@njit(cache=True)
def _key(i: int, j: int, k: int) -> int:
    return ((i + _BIAS) << (2 * _BITS)) | ((j + _BIAS) << _BITS) | k


@njit(cache=True)
def _unkey(key: int) -> tuple[int, int, int]:
    mask = (1 << _BITS) - 1
    return ((key >> (2 * _BITS)) & mask) - _BIAS, ((key >> _BITS) & mask) - _BIAS, key & mask


@njit(cache=True)
def _reachable(x: float, y: float, th: float, A: np.ndarray, L: np.ndarray, b: np.ndarray) -> bool:
    """Whether every leg's tip ``B_j`` at the pose is within its rod length of its clamp."""
    c, s = math.cos(th), math.sin(th)
    for j in range(3):
        bx = x + c * b[j, 0] - s * b[j, 1] - A[j, 0]
        by = y + s * b[j, 0] + c * b[j, 1] - A[j, 1]
        if bx * bx + by * by > L[j] * L[j] * (1.0 + 1e-9):
            return False
    return True


# ---- the rods at lattice poses -------------------------------------------------------------
@njit(cache=True)
def _tip_target(x: float, y: float, th: float, Ai: np.ndarray, ca: float, sa: float, L: float, bi: np.ndarray,
                dT: np.ndarray) -> tuple[float, float, float, float]:
    """The unit rod's tip target ``(x_t, y_t)`` in its clamp frame for platform pose ``(x, y, th)``
    (``B_i = P + Rot(th) b_i``), its pose derivative ``dT`` (rows x_t, y_t, theta_t) and
    ``Rot(th) b_i``."""
    c, s = math.cos(th), math.sin(th)
    rbx, rby = c * bi[0] - s * bi[1], s * bi[0] + c * bi[1]
    wx, wy = x + rbx - Ai[0], y + rby - Ai[1]
    dT[0, 0], dT[0, 1], dT[0, 2] = ca / L, sa / L, (ca * -rby + sa * rbx) / L
    dT[1, 0], dT[1, 1], dT[1, 2] = -sa / L, ca / L, (-sa * -rby + ca * rbx) / L
    dT[2, 0], dT[2, 1], dT[2, 2] = 0.0, 0.0, 1.0
    return (ca * wx + sa * wy) / L, (-sa * wx + ca * wy) / L, rbx, rby


@njit(cache=True)
def _rod_at(z: np.ndarray, x: float, y: float, th: float, dp: np.ndarray, leg: np.ndarray, chart: int, dim: int,
            e0: np.ndarray, D: np.ndarray, G: np.ndarray) -> bool:
    """The rod ``z`` (in place), exact at the pose ``(x, y, th) - dp``, continued to the pose
    ``(x, y, th)``: the tangent predictor ``z + G dp`` (``G = M^-1 dT/dpose`` by the
    implicit-function theorem, ``M`` the chart gradient of the tip quantities ``T``: position
    and, clamped, angle; exact chart gradients of :func:`flexkin.rod.kernels.eval_rod`), then
    damped Newton with the pose frozen.  Outputs its ``G`` and the scaled platform-balance
    contribution (Eq. 15) ``e = (n_x, n_y, (B_i - P) x n + m_tip)`` linearised in the pose:
    ``e0`` and ``D = de/dpose`` (pose in physical units).  True when Newton converged to a
    finite rod with force ``R L^2/EI <= R_cap`` and, clamped, tip turning ``<= turn_cap``;
    pinned, ``|v| <= v_cap`` and ``phis >= phis_min`` (the pinned atlas' scope with a margin:
    without it a rod continued past the last d-mode walks on to ever higher d-modes, and the
    flood fill with it, hundreds of rods per pose).

    ``leg = (A_x, A_y, alpha, L, EI, tip_angle, b_x, b_y, F_ref, L_ref, R_cap, turn_cap, v_cap,
    phis_min)``."""
    q = np.empty(NQ)
    g = np.empty((NQ, 3))
    Mm = np.empty((dim, dim))
    rhs = np.empty(dim)
    sol = np.empty(dim)
    work = np.empty((dim, dim + 1))
    dT = np.empty((3, 3))
    Ai, bi = leg[0:2], leg[6:8]
    al, L, EI, beta = leg[2], leg[3], leg[4], leg[5]
    ca, sa = math.cos(al), math.sin(al)
    fs = EI / (L * L) / leg[8]
    ms = EI / L / (leg[8] * leg[9])
    rows = (X, Y, TH)
    if dp[0] != 0.0 or dp[1] != 0.0 or dp[2] != 0.0:  # tangent predictor
        _tip_target(x - dp[0], y - dp[1], th - dp[2], Ai, ca, sa, L, bi, dT)
        eval_rod(chart, z, q, g)
        for r in range(dim):
            for c in range(dim):
                Mm[r, c] = g[rows[r], c]
        for r in range(dim):
            rhs[r] = dT[r, 0] * dp[0] + dT[r, 1] * dp[1] + dT[r, 2] * dp[2]
        if solve_into(Mm, rhs, sol, work):
            for c in range(dim):
                z[c] += sol[c]
    tx, ty, rbx, rby = _tip_target(x, y, th, Ai, ca, sa, L, bi, dT)
    # Newton on the rod's tip equations with the pose frozen (damped like
    # flexkin.rod.clamped.wrench_newton: steps limited to half the chart coordinates' size)
    good = False
    for it in range(NEWTON_ITER + 1):
        eval_rod(chart, z, q, g)
        rhs[0], rhs[1] = tx - q[X], ty - q[Y]
        if dim == 3:
            d = th + beta - al - q[TH]
            rhs[2] = d - TWO_PI * math.floor(d / TWO_PI + 0.5)
        res = 0.0
        for r in range(dim):
            res = max(res, abs(rhs[r]))
        if res <= NEWTON_TOL:
            good = True
            break
        if it == NEWTON_ITER or not res == res:
            break
        for r in range(dim):
            for c in range(dim):
                Mm[r, c] = g[rows[r], c]
        solve_into(Mm, rhs, sol, work)
        size, step = 1.0, 0.0
        for c in range(dim):
            size += abs(z[c])
            step += abs(sol[c])
        damp = min(1.0, 0.5 * size / step) if step > 0 else 1.0
        for c in range(dim):
            z[c] += damp * sol[c]
    good &= math.hypot(q[FX], q[FY]) <= leg[10]
    if dim == 3:
        good &= abs(q[TH]) <= leg[11]
    else:
        good &= abs(z[0]) <= leg[12] and z[1] >= leg[13]
    for r in range(dim):
        for c in range(dim):
            Mm[r, c] = g[rows[r], c]
    for p in range(3):
        for r in range(dim):
            rhs[r] = dT[r, p]
        good &= solve_into(Mm, rhs, sol, work)
        for c in range(dim):
            G[c, p] = sol[c]
    # wrench and its pose derivative
    fxl, fyl, mt = q[FX], q[FY], q[ML]
    dfx, dfy, dmt = np.zeros(3), np.zeros(3), np.zeros(3)
    for c in range(dim):
        for p in range(3):
            dfx[p] += g[FX, c] * G[c, p]
            dfy[p] += g[FY, c] * G[c, p]
            dmt[p] += g[ML, c] * G[c, p]
    if dim == 2:  # a pinned tip carries no moment (Eq. 11)
        mt = 0.0
        dmt[:] = 0.0
    nx, ny = fs * (ca * fxl - sa * fyl), fs * (sa * fxl + ca * fyl)
    lx, ly = rbx / leg[9], rby / leg[9]  # lever B_i - P, scaled
    e0[0], e0[1], e0[2] = nx, ny, lx * ny - ly * nx + ms * mt
    for p in range(3):
        dnx = fs * (ca * dfx[p] - sa * dfy[p])
        dny = fs * (sa * dfx[p] + ca * dfy[p])
        D[0, p], D[1, p] = dnx, dny
        D[2, p] = lx * dny - ly * dnx + ms * dmt[p]
    D[2, 2] += -lx * nx - ly * ny  # d/dtheta of (Rot(theta) b_i) x n
    for r in range(3):
        good &= np.isfinite(e0[r])
        for p in range(3):
            good &= np.isfinite(D[r, p])
    return good


@njit(cache=True)
def _continue(keys: np.ndarray, zs: np.ndarray, dps: np.ndarray, lat: np.ndarray, leg: np.ndarray, chart: int,
              dim: int, e0: np.ndarray, D: np.ndarray, z1: np.ndarray, G: np.ndarray, ok: np.ndarray) -> None:
    """:func:`_rod_at` for every rod ``zs[n]`` continued by ``dps[n]`` to the lattice pose
    ``keys[n]``: the rods ``z1``, whether they are usable (``ok``), ``G``, ``e0`` and ``D``."""
    for n in range(keys.shape[0]):
        i, j, k = _unkey(keys[n])
        for c in range(3):
            z1[n, c] = zs[n, c]
        ok[n] = _rod_at(z1[n], lat[0] + i * lat[1], lat[2] + j * lat[1], lat[3] + k * lat[4], dps[n], leg, chart,
                        dim, e0[n], D[n], G[n])


@njit(cache=True)
def _pose_newton(P: np.ndarray, Z: np.ndarray, legs: np.ndarray, charts: np.ndarray, dims: np.ndarray,
                 target: np.ndarray, step: np.ndarray, tol: float, max_iter: int, ok: np.ndarray) -> None:
    """Newton on the platform balance (Eq. 15) in the pose alone, every rod slaved to the pose
    (continued by :func:`_rod_at` at every step, so that it never leaves its sheet): from the
    poses ``P`` (n, 3) with the rods ``Z`` (n, 3, 3) exact there (both in place).  Steps are
    limited to ``step`` per coordinate and halved while a rod cannot follow; ``ok`` when the
    scaled balance residual falls below ``tol``."""
    e0 = np.empty((3, 3))
    D = np.empty((3, 3, 3))
    G = np.empty((3, 3))
    J = np.empty((3, 3))
    rhs = np.empty(3)
    dp = np.empty(3)
    zero = np.zeros(3)
    work = np.empty((3, 4))
    zt = np.empty((3, 3))
    e0t = np.empty((3, 3))
    Dt = np.empty((3, 3, 3))
    for n in range(P.shape[0]):
        ok[n] = False
        good = True
        for i in range(3):
            good &= _rod_at(Z[n, i], P[n, 0], P[n, 1], P[n, 2], zero, legs[i], charts[i], dims[i], e0[i], D[i], G)
        if not good:
            continue
        for it in range(max_iter):
            res = 0.0
            for r in range(3):
                rhs[r] = target[r] - e0[0, r] - e0[1, r] - e0[2, r]
                res = max(res, abs(rhs[r]))
                for p in range(3):
                    J[r, p] = D[0, r, p] + D[1, r, p] + D[2, r, p]
            if res <= tol:
                ok[n] = True
                break
            if not solve_into(J, rhs, dp, work):
                break
            s = 1.0
            for p in range(3):
                s = max(s, abs(dp[p]) / step[p])
            for p in range(3):
                dp[p] /= s
            moved = False
            for _half in range(6):
                good = True
                for i in range(3):
                    for c in range(3):
                        zt[i, c] = Z[n, i, c]
                    good &= _rod_at(zt[i], P[n, 0] + dp[0], P[n, 1] + dp[1], P[n, 2] + dp[2], dp, legs[i], charts[i],
                                    dims[i], e0t[i], Dt[i], G)
                    if not good:
                        break
                if good:
                    moved = True
                    break
                for p in range(3):
                    dp[p] *= 0.5
            if not moved:
                break
            for p in range(3):
                P[n, p] += dp[p]
            for i in range(3):
                for c in range(3):
                    Z[n, i, c] = zt[i, c]
                    e0[i, c] = e0t[i, c]
                    for p in range(3):
                        D[i, c, p] = Dt[i, c, p]


@njit(cache=True)
def _neighbours(keys: np.ndarray, nth: int, kin: np.ndarray, box: np.ndarray, lat: np.ndarray, A: np.ndarray,
                L: np.ndarray, b: np.ndarray, out_src: np.ndarray, out_key: np.ndarray, out_dp: np.ndarray) -> int:
    """The six lattice neighbours of every lattice pose ``keys[n]`` inside the box (orientations:
    ``kin``) and the reach region: source index, key and pose step.  Returns their count."""
    m = 0
    for n in range(keys.shape[0]):
        i, j, k = _unkey(keys[n])
        for d in range(6):
            a = d // 2
            sgn = 1 if d % 2 == 0 else -1
            i2, j2, k2 = i + sgn * (a == 0), j + sgn * (a == 1), k + sgn * (a == 2)
            if i2 < box[0] or i2 > box[1] or j2 < box[2] or j2 > box[3]:
                continue
            k2 = k2 % nth  # orientations are periodic; kin: those in the box
            if not kin[k2]:
                continue
            if not _reachable(lat[0] + i2 * lat[1], lat[2] + j2 * lat[1], lat[3] + k2 * lat[4], A, L, b):
                continue
            out_src[m] = n
            out_key[m] = _key(i2, j2, k2)
            out_dp[m, 0] = sgn * lat[1] * (a == 0)
            out_dp[m, 1] = sgn * lat[1] * (a == 1)
            out_dp[m, 2] = sgn * lat[4] * (a == 2)
            m += 1
    return m


# ---- combinations ----------------------------------------------------------------------------
@njit(cache=True)
def _combinations(r0: np.ndarray, r1: np.ndarray, r2: np.ndarray, e0a: np.ndarray, Da: np.ndarray,
                  e0b: np.ndarray, Db: np.ndarray, e0c: np.ndarray, Dc: np.ndarray, target: np.ndarray,
                  scale: np.ndarray, s_max: float, out_idx: np.ndarray, out_dp: np.ndarray
                  ) -> tuple[int, int]:
    """Every triple of hits at each common lattice pose (hit ranges ``r0, r1, r2`` (m, 2)): the
    pose step ``dp`` of the linearised balance ``sum e = target``; kept when
    ``max |dp / scale| <= s_max``.  Returns (kept, examined)."""
    J = np.empty((3, 3))
    rhs = np.empty(3)
    dp = np.empty(3)
    work = np.empty((3, 4))
    n = 0
    ex = 0
    for m in range(r0.shape[0]):
        for a in range(r0[m, 0], r0[m, 1]):
            for b in range(r1[m, 0], r1[m, 1]):
                for c in range(r2[m, 0], r2[m, 1]):
                    ex += 1
                    for r in range(3):
                        rhs[r] = target[r] - e0a[a, r] - e0b[b, r] - e0c[c, r]
                        for p in range(3):
                            J[r, p] = Da[a, r, p] + Db[b, r, p] + Dc[c, r, p]
                    if not solve_into(J, rhs, dp, work):
                        continue
                    sc = 0.0
                    for p in range(3):
                        sc = max(sc, abs(dp[p]) / scale[p])
                    if not sc <= s_max:
                        continue
                    if n >= out_idx.shape[0]:
                        return n + 1, ex
                    out_idx[n, 0], out_idx[n, 1], out_idx[n, 2], out_idx[n, 3] = m, a, b, c
                    for p in range(3):
                        out_dp[n, p] = dp[p]
                    n += 1
    return n, ex


# ---- driver ----------------------------------------------------------------------------------
#: fewest lattice steps across the reach region in each coordinate
N_ACROSS = 16


def _disks_meet_box(cx: NDArray, cy: NDArray, r: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Bounding box ``(xlo, xhi, ylo, yhi)`` (each (n,)) of the intersection of three disks
    (centres ``cx, cy`` (n, 3), radii ``r`` (3,)); ``xlo > xhi`` when it is empty.

    Its extreme points are disks' extreme points or pairwise boundary intersections, whichever
    lie in all three disks."""
    px, py = [], []
    for j in range(3):
        for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            px.append(cx[:, j] + dx * r[j])
            py.append(cy[:, j] + dy * r[j])
    for i, j in ((0, 1), (0, 2), (1, 2)):
        dx, dy = cx[:, j] - cx[:, i], cy[:, j] - cy[:, i]
        d2 = dx * dx + dy * dy
        d = np.sqrt(d2)
        with np.errstate(divide="ignore", invalid="ignore"):
            a = (r[i] ** 2 - r[j] ** 2 + d2) / (2 * d)
            hh = np.sqrt(np.maximum(r[i] ** 2 - a * a, 0.0))
            mx, my = cx[:, i] + a * dx / d, cy[:, i] + a * dy / d
            for sg in (1.0, -1.0):
                px.append(np.where(d > 0, mx - sg * hh * dy / d, np.nan))
                py.append(np.where(d > 0, my + sg * hh * dx / d, np.nan))
    px, py = np.stack(px, 1), np.stack(py, 1)
    inside = np.ones(px.shape, bool)
    for j in range(3):
        inside &= np.hypot(px - cx[:, j:j + 1], py - cy[:, j:j + 1]) <= r[j] * (1 + 1e-9) + 1e-12
    inf = np.inf
    xlo = np.where(inside, px, inf).min(1)
    xhi = np.where(inside, px, -inf).max(1)
    ylo = np.where(inside, py, inf).min(1)
    yhi = np.where(inside, py, -inf).max(1)
    return xlo, xhi, ylo, yhi


def pose_lattice(A: NDArray, L: NDArray, b: NDArray, h: float, n_theta: int
                 ) -> tuple[NDArray[np.float64], int, NDArray[np.int64]]:
    """The pose lattice for clamps ``A`` (3, 2), rod lengths ``L`` and attach points ``b``.

    The reach region (every ``B_j`` within ``L_j`` of ``A_j``) is, per orientation, the
    intersection of three disks for ``P`` (:func:`_disks_meet_box`), sampled at 0.05 deg; its smallest covering
    arc of orientations and the union of the boxes give the lattice box.  The spacing is ``h``
    in ``x, y`` and ``2 pi / n_theta``, refined so that at least :data:`N_ACROSS` steps span the
    box in every coordinate (a nearly taut mechanism has a reach region of a few mm).

    Returns
    -------
    lat : (5,) array
        ``(x0, h, y0, theta0, h_theta)``: lattice pose ``(i, j, k)`` is
        ``(x0 + i h, y0 + j h, theta0 + k h_theta)``.
    nth : int
        Lattice orientations per turn (``h_theta = 2 pi / nth``).
    box : (6,) int array
        ``(i0, i1, j0, j1, k0, k1)``, inclusive; ``k`` counts from ``theta0`` and may exceed
        ``nth`` (periodic).
    """
    ts = np.linspace(-math.pi, math.pi, 7200, endpoint=False)
    rb = rotate(b, ts[:, None])  # (n_t, 3, 2)
    cx = A[None, :, 0] - rb[..., 0]  # P = A_j - Rot b_j + (|.| <= L_j)
    cy = A[None, :, 1] - rb[..., 1]
    xlo, xhi, ylo, yhi = _disks_meet_box(cx, cy, L)
    ok = (xlo <= xhi) & (ylo <= yhi)
    step = TWO_PI / len(ts)
    if not np.any(ok):
        return np.array([0.0, h, 0.0, 0.0, TWO_PI / n_theta]), int(n_theta), np.array([0, -1, 0, -1, 0, -1])
    if np.all(ok):
        t_lo, t_span = -math.pi, TWO_PI
    else:  # the smallest arc covering the reachable orientations: the complement of the largest gap
        idx = np.flatnonzero(ok)
        gaps = np.diff(np.concatenate([idx, idx[:1] + len(ts)]))
        g = int(np.argmax(gaps))
        first = idx[(g + 1) % len(idx)]
        t_span = (len(ts) - gaps[g] + 1) * step + 2 * step
        t_lo = ts[first] - 2 * step
    box_x = float(xlo[ok].min()), float(xhi[ok].max())
    box_y = float(ylo[ok].min()), float(yhi[ok].max())
    span = max(box_x[1] - box_x[0], box_y[1] - box_y[0])
    hx = min(h, span / N_ACROSS) if span > 0 else h
    nth = int(n_theta)
    if t_span < TWO_PI:
        nth = max(nth, int(math.ceil(TWO_PI / (t_span / N_ACROSS))))
    ht = TWO_PI / nth
    lat = np.array([box_x[0] + OFFSET[0] * hx, hx, box_y[0] + OFFSET[1] * hx, t_lo + OFFSET[2] * ht, ht])
    box = np.array([-1, int(math.ceil((box_x[1] - box_x[0]) / hx)) + 1, -1, int(math.ceil((box_y[1] - box_y[0]) / hx)) + 1,
                    -1, (nth - 1) if t_span >= TWO_PI else int(math.ceil(t_span / ht)) + 1], dtype=np.int64)
    if t_span >= TWO_PI:
        box[4] = 0
    return lat, nth, box


def _lattice_index(P: NDArray, lat: NDArray, nth: int, box: NDArray, kin: NDArray, A: NDArray, L: NDArray,
                   b: NDArray) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_]]:
    """Nearest lattice pose of poses ``P`` (n, 3), physical: its key, the step ``lattice - P``
    and whether it is in the box and the reach region."""
    fi = np.rint((P[:, 0] - lat[0]) / lat[1])
    fj = np.rint((P[:, 1] - lat[2]) / lat[1])
    fk = np.rint((P[:, 2] - lat[3]) / lat[4])
    dp = np.column_stack([lat[0] + fi * lat[1], lat[2] + fj * lat[1], lat[3] + fk * lat[4]]) - P
    k = np.mod(fk, nth).astype(np.int64)
    ok = (fi >= box[0]) & (fi <= box[1]) & (fj >= box[2]) & (fj <= box[3]) & kin[k]
    x, y, th = lat[0] + fi * lat[1], lat[2] + fj * lat[1], lat[3] + k * lat[4]
    d = platform_points(b, np.column_stack([x, y, th])) - A[None]  # B_j - A_j, (n, 3, 2)
    ok &= np.all(np.sum(d * d, axis=-1) <= L * L * (1.0 + 1e-9), axis=1)
    fi, fj = fi.astype(np.int64), fj.astype(np.int64)
    key = ((fi + _BIAS) << (2 * _BITS)) | ((fj + _BIAS) << _BITS) | k
    return key, dp, ok


def _reach_poses(lat: NDArray, nth: int, box: NDArray, kin: NDArray, A: NDArray, L: NDArray,
                 b: NDArray) -> NDArray[np.int64]:
    """Integer coordinates ``(i, j, k)`` (m, 3) of the lattice poses in the box and the reach
    region (``k`` unwrapped, in ``box[4] .. box[5]``)."""
    I, J, K = np.meshgrid(np.arange(box[0], box[1] + 1), np.arange(box[2], box[3] + 1),
                          np.arange(box[4], box[5] + 1), indexing="ij")
    ijk = np.column_stack([I.ravel(), J.ravel(), K.ravel()])
    ijk = ijk[kin[np.mod(ijk[:, 2], nth)]]
    pose = np.column_stack([lat[0] + ijk[:, 0] * lat[1], lat[2] + ijk[:, 1] * lat[1], lat[3] + ijk[:, 2] * lat[4]])
    d = platform_points(b, pose) - A[None]
    return ijk[np.all(np.sum(d * d, axis=-1) <= L * L * (1.0 + 1e-9), axis=1)]


def _cell_seeds(P: NDArray, valid: NDArray, lat: NDArray, nth: int, box: NDArray, kin: NDArray, A: NDArray,
                L: NDArray, b: NDArray) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_]]:
    """Seeds of a clamped leg from the poses ``P`` (n_lam, n_psi, n_t, 3) of its wrench-atlas
    nodes (``valid``): every node paired with the nearest lattice pose of the reach region
    within the pose extent of its grid cells (the tangent predictor of :func:`_rod_at` then
    crosses the cell).  A sheet that meets the reach region only between nodes -- a reach
    region smaller than the cells' images, as for a rod that must wind to reach it -- so has
    seeds; the node's own nearest lattice pose would lie outside the region.  Returns the key,
    the pose step and whether the node seeds (all flattened)."""
    from scipy.spatial import cKDTree  # imported here: only a clamped FK needs it

    shape = P.shape[:3]
    f = np.stack([(P[..., 0] - lat[0]) / lat[1], (P[..., 1] - lat[2]) / lat[1], (P[..., 2] - lat[3]) / lat[4]], -1)
    # the extent (lattice steps, each coordinate) of the cells around every node: the sum over
    # the grid axes of the larger step to a neighbour (psi periodic; theta steps wrapped)
    ext = np.zeros(f.shape)
    for ax in range(3):
        fwd = np.roll(f, -1, axis=ax) - f
        fwd[..., 2] -= nth * np.rint(fwd[..., 2] / nth)
        fwd = np.where(np.isfinite(fwd), np.abs(fwd), 0.0)  # a non-finite neighbour: no cell there
        if ax != 1:  # lambda and t are not periodic: no step past the grid's ends
            idx = [slice(None)] * 4
            idx[ax] = -1
            fwd[tuple(idx)] = 0.0
        ext += np.maximum(fwd, np.roll(fwd, 1, axis=ax))  # (the zeroed last step rolls to the first node)
    f, ext, ok = f.reshape(-1, 3), ext.reshape(-1, 3), valid.reshape(-1) & np.all(np.isfinite(f.reshape(-1, 3)), 1)
    reach = _reach_poses(lat, nth, box, kin, A, L, b)
    n = len(f)
    key, dp = np.zeros(n, np.int64), np.zeros((n, 3))
    if not len(reach) or not np.any(ok):
        return key, dp, np.zeros(n, bool)
    # orientations are periodic: the node's into [box[4], box[4] + nth), the lattice's repeated
    fk = f[:, 2].copy()
    fk[ok] = box[4] + np.mod(fk[ok] - box[4], nth)
    cell = np.max(ext, axis=1) + 0.5
    # only nodes whose cells reach the box of the reach region can seed (most nodes lie far from
    # a small reach region): the same seeds from a query of a few nodes (the query of every
    # node took 1.7 s per leg on the mixed example)
    lo, hi = reach.min(axis=0), reach.max(axis=0)
    ok &= (f[:, 0] >= lo[0] - cell) & (f[:, 0] <= hi[0] + cell) & (f[:, 1] >= lo[1] - cell) & (f[:, 1] <= hi[1] + cell)
    if hi[2] - lo[2] + 1 < nth:  # orientations: the box, or its copies one turn up or down
        ok &= (((fk >= lo[2] - cell) & (fk <= hi[2] + cell)) | (fk + nth <= hi[2] + cell)
               | (fk - nth >= lo[2] - cell))
    if not np.any(ok):
        return key, dp, np.zeros(n, bool)
    rep = np.concatenate([reach + [0, 0, s * nth] for s in (-1, 0, 1)])
    cell = cell[ok]
    dist, near = cKDTree(rep).query(np.column_stack([f[ok, :2], fk[ok]]), p=np.inf,
                                    distance_upper_bound=float(cell.max()) * (1.0 + 1e-12))
    hit = np.flatnonzero(ok)[dist <= cell]
    g = rep[near[dist <= cell]]
    key[hit] = ((g[:, 0] + _BIAS) << (2 * _BITS)) | ((g[:, 1] + _BIAS) << _BITS) | np.mod(g[:, 2], nth)
    dp[hit, 0] = (g[:, 0] - f[hit, 0]) * lat[1]
    dp[hit, 1] = (g[:, 1] - f[hit, 1]) * lat[1]
    dp[hit, 2] = (g[:, 2] - fk[hit]) * lat[4]
    seed = np.zeros(n, bool)
    seed[hit] = True
    return key, dp, seed


def _seeds(system: System, i: int, A: NDArray, al: NDArray, L: NDArray, lat: NDArray, nth: int, box: NDArray,
           kin: NDArray, max_mode: int, max_winding: int) -> tuple[NDArray, NDArray, NDArray, int, int, float]:
    """Leg ``i``'s seeds: every node of its rod atlas (an exact rod, hence an exact pose or, pinned,
    one per lattice orientation) with the nearest lattice pose (key, chart coordinates, pose
    step), and the chart code, chart dimension and force cap of the leg's rods."""
    b = np.asarray(system.attach, dtype=float)
    if system.clamped[i]:
        W = get_wrench_atlas(max_mode, max_winding)
        # the scope with a margin (rods at its edge are continued into it)
        valid = np.isfinite(W.x) & (W.mode <= max_mode + 1) & (np.abs(W.th) <= turning_max(max_winding) + 1.0)
        tip = A[i] + L[i] * rotate(np.stack([W.x, W.y], -1), al[i])
        th = al[i] + W.th - system.tip_angle[i]
        P = np.concatenate([tip - rotate(b[i], th), th[..., None]], -1)  # (n_lam, n_psi, n_t, 3)
        lam = np.broadcast_to(W.lam[:, None, None], W.x.shape)
        psi = np.broadcast_to((np.arange(W.x.shape[1]) * (TWO_PI / W.x.shape[1]))[None, :, None], W.x.shape)
        t = np.broadcast_to(W.t[None, None, :], W.x.shape)
        Z = np.stack([lam * lam * np.cos(psi), lam * lam * np.sin(psi), moment_scale(lam, max_winding) * t], -1)
        key, dp, ok = _cell_seeds(P, valid, lat, nth, box, kin, A, L, b)
        return key[ok], Z.reshape(-1, 3)[ok], dp[ok], CHART_WRENCH, 3, (1.2 * lambda_max(max_mode)) ** 2
    At = get_atlas(max_mode)
    tip = A[i] + L[i] * rotate(np.stack([At.x, At.y], -1), al[i])
    tx, ty = tip[..., 0].ravel(), tip[..., 1].ravel()
    Z2 = np.stack(np.broadcast_arrays(At.v[:, None], At.phis[None, :]), -1).reshape(-1, 2)
    fin = np.isfinite(tx) & np.isfinite(ty)
    tx, ty, Z2 = tx[fin], ty[fin], Z2[fin]
    keys, zs, dps = [], [], []
    for k in np.flatnonzero(kin):
        th = lat[3] + k * lat[4]
        rb = rotate(b[i], th)
        P = np.column_stack([tx - rb[0], ty - rb[1], np.full(len(tx), th)])
        key, dp, ok = _lattice_index(P, lat, nth, box, kin, A, L, b)
        keys.append(key[ok])
        zs.append(np.column_stack([Z2[ok], np.zeros(np.count_nonzero(ok))]))
        dps.append(dp[ok])
    return np.concatenate(keys), np.concatenate(zs), np.concatenate(dps), CHART_UNIFIED, 2, math.inf


def _leg_params(system: System, i: int, A: NDArray, al: NDArray, L: NDArray, R_cap: float, max_mode: int,
                max_winding: int) -> NDArray[np.float64]:
    """Leg ``i``'s parameters as :func:`_rod_at` reads them: the scopes with a margin (a pinned rod:
    |v| within the atlas' scope plus 1, one d-mode beyond ``max_mode``; a clamped one: turning
    within the winding's plus 1 rad)."""
    b = system.attach[i]
    v_cap = float(np.arccosh(2.0 / KPRIME_MIN)) + 1.0
    phis_min = get_atlas(max_mode).phis_min - math.pi
    return np.array([A[i, 0], A[i, 1], al[i], L[i], system.EI[i], system.tip_angle[i], b[0], b[1], system.F_ref,
                     system.L_ref, R_cap, turning_max(max_winding) + 1.0, v_cap, phis_min], dtype=float)


def _rod_hash(keys: NDArray, z: NDArray) -> NDArray[np.int64]:
    """One int64 per rod at a lattice pose: its key and its chart coordinates quantised to 1e-6
    of their size (Newton converges to 1e-10), hashed (wrapping integer arithmetic)."""
    q = np.floor(z / (1e-6 * (1.0 + np.abs(z)))).astype(np.int64)
    with np.errstate(over="ignore"):
        return (keys * np.int64(0x9E3779B97F4A7C15 - (1 << 64)) + q[:, 0] * np.int64(0x7FEB352D)
                + q[:, 1] * np.int64(0x846CA68B) + q[:, 2] * np.int64(0x5851F42D4C957F2D))


def _leg_sheet(system: System, i: int, A: NDArray, al: NDArray, L: NDArray, lat: NDArray, nth: int, box: NDArray,
               kin: NDArray, max_mode: int, max_winding: int, deadline: float | None
               ) -> tuple[dict[str, NDArray], bool, tuple]:
    """Every rod of leg ``i`` at every lattice pose it reaches (sorted by lattice pose), with
    its linearised balance contribution and its sheet (``"sheet"``: the connected component of
    the rods linked by continuation between neighbouring lattice poses).

    The atlas-node seeds are continued to their nearest lattice pose, then flood-filled over
    the lattice: every new rod found at a pose is continued to the six neighbouring poses until
    no new rod appears.  Also returns whether it finished before ``deadline`` and the leg's
    ``(parameters, chart, chart dimension)`` for :func:`_rod_at`."""
    keys, zs, dps, chart, dim, R_cap = _seeds(system, i, A, al, L, lat, nth, box, kin, max_mode, max_winding)
    src = np.full(len(keys), -1, np.int64)  # the rod each candidate was continued from
    b = np.ascontiguousarray(system.attach, dtype=float)
    leg = _leg_params(system, i, A, al, L, R_cap, max_mode, max_winding)
    parts: list[dict[str, NDArray]] = []
    known = np.zeros(0, np.int64)        # hashes of the rods found so far, sorted ...
    known_at = np.zeros(0, np.int64)     # ... and their indices
    edges: list[NDArray] = []
    total, complete = 0, True
    while len(keys):
        n = len(keys)
        e0, D, z1, G = np.empty((n, 3)), np.empty((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3))
        ok = np.empty(n, np.bool_)
        _continue(keys, np.ascontiguousarray(zs), np.ascontiguousarray(dps), lat, leg, chart, dim, e0, D, z1, G, ok)
        idx = np.flatnonzero(ok)
        hsh = _rod_hash(keys[idx], z1[idx])
        pos = np.minimum(np.searchsorted(known, hsh), max(len(known) - 1, 0))
        old = (known[pos] == hsh) if len(known) else np.zeros(len(idx), bool)
        uh, first = np.unique(hsh[~old], return_index=True)
        sel = idx[~old][first]                          # the new rods, numbered total, total + 1, ...
        parts.append({"keys": keys[sel], "e0": e0[sel], "D": D[sel], "z1": z1[sel], "G": G[sel]})
        new_at = total + np.arange(len(sel))
        known = np.concatenate([known, uh])
        known_at = np.concatenate([known_at, new_at])
        order = np.argsort(known, kind="stable")
        known, known_at = known[order], known_at[order]
        dst = known_at[np.searchsorted(known, hsh)]
        link = src[idx] >= 0
        edges.append(np.column_stack([src[idx][link], dst[link]]))
        total += len(sel)
        if deadline is not None and time.perf_counter() > deadline:
            complete = False
            break
        # the next wave: the new rods continued to the neighbouring lattice poses
        nb_src, nkeys, ndps = np.empty(6 * len(sel), np.int64), np.empty(6 * len(sel), np.int64), np.empty((6 * len(sel), 3))
        m = _neighbours(keys[sel], nth, kin, box, lat, A, L, b, nb_src, nkeys, ndps)
        keys, zs, dps, src = nkeys[:m], z1[sel][nb_src[:m]], ndps[:m], new_at[nb_src[:m]]
    if not parts:
        return {"keys": np.zeros(0, np.int64), "e0": np.zeros((0, 3)), "D": np.zeros((0, 3, 3)), "z1": np.zeros((0, 3)),
                "G": np.zeros((0, 3, 3)), "sheet": np.zeros(0, np.int64)}, complete, (leg, chart, dim)
    out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    e = np.concatenate(edges) if edges else np.zeros((0, 2), np.int64)
    from scipy.sparse import coo_matrix   # imported here: only a clamped FK needs it
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(total, total))
    out["sheet"] = connected_components(graph, directed=False)[1].astype(np.int64)
    order = np.argsort(out["keys"], kind="stable")
    return {k: v[order] for k, v in out.items()}, complete, (leg, chart, dim)


def lattice_starts(system: System, inputs: NDArray, load: NDArray, max_mode: int, *, max_winding: int = 1,
                   h: float = H,
                   n_theta: int = N_THETA, s_max: float = S_MAX, deadline: float | None = None,
                   progress: Callable[[float, str], None] | None = None
                   ) -> tuple[NDArray[np.float64], bool, LatticeStats]:
    """Starting points (n, n_unknowns) for the FK Newton of a mechanism with clamped legs,
    whether the search completed, and its counts.

    Parameters
    ----------
    system : System
        The mechanism's arrays.
    inputs : (3,) array
        Actuator inputs (SI; radians for revolute legs).
    load : (3,) array
        Load wrench ``(F_x, F_y, M_z)`` on the platform at P.
    max_mode : int
        Largest d-mode searched.
    max_winding : int
        Largest ``|winding|`` of a clamped rod searched.
    h : float
        Lattice spacing in ``x, y``, in units of the mechanism's length scale.
    n_theta : int
        Lattice orientations per turn.
    s_max : float
        Largest predicted pose step of a start, in lattice steps.
    deadline : float, optional
        ``time.perf_counter()`` value after which the search stops (``complete`` False).
    progress : callable, optional
        Called as ``progress(fraction, stage)`` before each leg's rods and before the
        combinations.
    """
    u = np.asarray(inputs, dtype=float)
    A, al, L = system.clamps(u[None])
    A, al, L = np.ascontiguousarray(A[0]), np.ascontiguousarray(al[0]), np.ascontiguousarray(L[0])
    b = np.asarray(system.attach, dtype=float)
    lat, nth, box = pose_lattice(A, L, b, float(h) * system.L_ref, n_theta)
    hx, ht = float(lat[1]), float(lat[4])
    kin = np.zeros(nth, np.bool_)
    kin[np.mod(np.arange(box[4], box[5] + 1), nth)] = True
    legs, rod_models, complete = [], [], True
    for i in range(3):
        if progress is not None:
            progress(0.25 * i, f"rods of leg {i + 1} on the pose lattice")
        leg, done, model = _leg_sheet(system, i, A, al, L, lat, nth, box, kin, max_mode, max_winding, deadline)
        legs.append(leg)
        rod_models.append(model)
        if not done:
            complete = False
            break
    n_rods = tuple(len(leg["keys"]) for leg in legs) + (0,) * (3 - len(legs))
    n_unknowns = system.layout.n_unknowns
    if not complete:
        return np.zeros((0, n_unknowns)), False, LatticeStats(hx, nth, n_rods, 0, 0, 0, 0)  # type: ignore[arg-type]
    if progress is not None:
        progress(0.75, "rod triples in platform equilibrium")
    common = np.intersect1d(np.intersect1d(legs[0]["keys"], legs[1]["keys"]), legs[2]["keys"])
    # a clamped rod beyond the grid's force limit at a pose every leg reaches: the sheets go on
    # where the search does not look
    lam2 = lambda_max(max_mode) ** 2
    force_limit = any(system.clamped[i] and np.any(np.isin(leg["keys"][np.hypot(leg["z1"][:, 0], leg["z1"][:, 1]) > lam2],
                                                           common)) for i, leg in enumerate(legs))
    ranges = [np.stack([np.searchsorted(leg["keys"], common, "left"), np.searchsorted(leg["keys"], common, "right")],
                       1).astype(np.int64) for leg in legs]
    target = np.asarray(load, dtype=float) / system.wrench_scale()
    scale = np.array([hx, hx, ht])
    cap = max(1024, 4 * len(common))
    while True:
        idx, dp = np.empty((cap, 4), np.int64), np.empty((cap, 3))
        n, examined = _combinations(*ranges, legs[0]["e0"], legs[0]["D"], legs[1]["e0"], legs[1]["D"],
                                    legs[2]["e0"], legs[2]["D"], target, scale, float(s_max), idx, dp)
        if n <= cap:
            break
        cap = 2 * n
    idx, dp = idx[:n], dp[:n]
    # the starts: one per triple of sheets and cell of predicted pose, from the lattice pose with
    # its exact rods, solved by Newton in the pose with the rods slaved
    ii, jj, kk = _unkey_np(common[idx[:, 0]])
    pose = np.column_stack([lat[0] + ii * hx, lat[2] + jj * hx, lat[3] + kk * ht])
    sheets = np.column_stack([legs[i]["sheet"][idx[:, 1 + i]] for i in range(3)])
    keep = _cluster(pose + dp, sheets, scale, np.max(np.abs(dp) / scale, axis=1) if n else np.zeros(0))
    P = np.ascontiguousarray(pose[keep])
    Z = np.ascontiguousarray(np.stack([legs[i]["z1"][idx[keep, 1 + i]] for i in range(3)], 1))
    ok = np.zeros(len(keep), np.bool_)
    _pose_newton(P, Z, np.stack([m[0] for m in rod_models]), np.array([m[1] for m in rod_models], np.int64),
                 np.array([m[2] for m in rod_models], np.int64), target, scale, POSE_TOL, POSE_ITER, ok)
    # where the pose Newton fails (a rod reaches a fold of its sheet, or a rod near taut whose
    # chart is so stretched that it cannot follow even small pose steps: the unit 3-PF's rods
    # at 0.99 L under 120 EI/L^2), the whole system's Newton starts both from the linear
    # prediction and from where the pose Newton stopped (exact rods, often mm from the solution
    # when the linear prediction is not within reach)
    bad = keep[~ok]
    P = np.concatenate([P, pose[bad] + dp[bad]])
    Z = np.concatenate([Z, np.stack([legs[i]["z1"][idx[bad, 1 + i]] + np.einsum(
        "nij,nj->ni", legs[i]["G"][idx[bad, 1 + i]], dp[bad]) for i in range(3)], 1)])
    X = np.zeros((len(P), n_unknowns))
    for i in range(3):
        sl = system.layout.rod[i]
        X[:, sl] = Z[:, i, :sl.stop - sl.start]
    X[:, system.layout.pose] = P
    X[:, system.layout.inputs] = u
    # one start per solution (equal poses and rods)
    _, first = np.unique(np.round(X / (1e-7 * (1.0 + np.abs(X)))), axis=0, return_index=True)
    X = X[np.sort(first)]
    stats = LatticeStats(hx, nth, n_rods, int(len(common)), int(examined), int(n), int(len(keep)),  # type: ignore[arg-type]
                         force_limit)
    return X, True, stats


def _unkey_np(keys: NDArray[np.int64]) -> tuple[NDArray, NDArray, NDArray]:
    """Integer lattice coordinates of packed keys (the array form of :func:`_unkey`)."""
    mask = (1 << _BITS) - 1
    return ((keys >> (2 * _BITS)) & mask) - _BIAS, ((keys >> _BITS) & mask) - _BIAS, keys & mask


def _cluster(pose: NDArray, sheets: NDArray, scale: NDArray, score: NDArray) -> NDArray[np.int64]:
    """One start (the best-scored) per triple of sheets and cell of predicted pose (CLUSTER
    lattice steps): the starts of one solution come from the lattice poses around it, with
    predictions that differ by the linearisation error."""
    if not len(pose):
        return np.zeros(0, np.int64)
    p = pose.copy()
    p[:, 2] = np.mod(p[:, 2], TWO_PI)
    q = np.column_stack([np.floor(p / (CLUSTER * scale)).astype(np.int64), sheets])
    order = np.argsort(score, kind="stable")
    _, first = np.unique(q[order], axis=0, return_index=True)
    return np.sort(order[first])
