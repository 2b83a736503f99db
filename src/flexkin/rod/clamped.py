"""Every equilibrium of one rod clamped at both ends (unit rod, wrench chart), compiled.

Given the tip position ``(xt, yt)`` and tip tangent ``tht`` of a unit rod in its clamp frame,
the three equations ``x(z) = xt, y(z) = yt, theta(z) = tht (mod 2 pi)`` are solved globally
over the wrench chart ``z = (a, b, m0)`` (:mod:`flexkin.rod.wrench`):

1. every cell of the atlas (:mod:`flexkin.rod.wrench_atlas`) whose corner values, padded by a
   fraction of their spread, bracket the target in all three quantities gives a start (its
   centre);
2. damped Newton with the analytic 3x3 Jacobian refines every start;
3. converged roots in scope are de-duplicated by their wrench.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..core.geometry2d_kernels import wrap_angle
from ..core.jit import njit
from ..core.linalg import solve_into
from .slots import NQ, TH, X, Y
from .wrench import wrench_eval, wrench_mode, wrench_profile
from .wrench_atlas import get_wrench_atlas, in_wrench_scope

__all__ = ["clamped_rod_roots", "bracket_cells", "wrench_newton", "distinct_shapes"]

TWO_PI = 2.0 * math.pi


@njit
def bracket_cells(x, y, th, valid, xt, yt, tht, pad) -> np.ndarray:
    """Indices (n, 3) of the cells whose 8 corners (``psi`` periodic) bracket ``(xt, yt, tht)``,
    each quantity's interval grown by ``pad`` times its spread (and the angle taken modulo 2 pi
    about the cell's first corner)."""
    nl, npsi, nt = x.shape
    out = []
    for i in range(nl - 1):
        for j in range(npsi):
            jn = (j + 1) % npsi
            for k in range(nt - 1):
                ok = True
                for q in range(3):
                    lo = 1e300
                    hi = -1e300
                    ref = th[i, j, k]
                    for di in range(2):
                        for dj in range(2):
                            for dk in range(2):
                                jj = jn if dj else j
                                if not valid[i + di, jj, k + dk]:
                                    ok = False
                                if q == 0:
                                    v = x[i + di, jj, k + dk]
                                elif q == 1:
                                    v = y[i + di, jj, k + dk]
                                else:
                                    v = th[i + di, jj, k + dk]
                                lo = min(lo, v)
                                hi = max(hi, v)
                    if not ok:
                        break
                    ext = pad * (hi - lo) + 1e-9
                    if q == 0:
                        t = xt
                    elif q == 1:
                        t = yt
                    else:
                        t = ref + wrap_angle(tht - ref)  # the target's representative nearest the cell
                        if not (lo - ext <= t <= hi + ext):
                            t2 = t + TWO_PI if t < lo else t - TWO_PI
                            t = t2
                    if not (lo - ext <= t <= hi + ext):
                        ok = False
                        break
                if ok:
                    out.append((i, j, k))
    res = np.empty((len(out), 3), np.int64)
    for r in range(len(out)):
        res[r, 0], res[r, 1], res[r, 2] = out[r]
    return res


@njit
def wrench_newton(Z, xt, yt, tht, tol, max_iter, res) -> None:
    """Damped Newton on ``(x, y, wrap(theta - tht)) = (xt, yt, 0)`` from the rows of ``Z`` (in place)."""
    q = np.empty(NQ)
    g = np.empty((NQ, 3))
    A = np.empty((3, 3))
    b = np.empty(3)
    d = np.empty(3)
    w = np.empty((3, 4))
    zt = np.empty(3)
    for k in range(Z.shape[0]):
        z = Z[k]
        wrench_eval(z[0], z[1], z[2], q, g)
        r0, r1, r2 = q[X] - xt, q[Y] - yt, wrap_angle(q[TH] - tht)
        nrm = max(abs(r0), abs(r1), abs(r2))
        for _ in range(max_iter):
            if not nrm > tol:
                break
            for c in range(3):
                A[0, c], A[1, c], A[2, c] = g[X, c], g[Y, c], g[TH, c]
            b[0], b[1], b[2] = -r0, -r1, -r2
            solve_into(A, b, d, w)
            scale = math.sqrt(z[0] * z[0] + z[1] * z[1]) + abs(z[2]) + 1.0
            s = max(1.0, (abs(d[0]) + abs(d[1]) + abs(d[2])) / (0.5 * scale))
            alpha = 1.0 / s
            improved = False
            for _ls in range(10):
                for c in range(3):
                    zt[c] = z[c] + alpha * d[c]
                wrench_eval(zt[0], zt[1], zt[2], q, g)
                n0, n1, n2 = q[X] - xt, q[Y] - yt, wrap_angle(q[TH] - tht)
                nt = max(abs(n0), abs(n1), abs(n2))
                if nt < nrm:
                    z[0], z[1], z[2] = zt[0], zt[1], zt[2]
                    r0, r1, r2, nrm = n0, n1, n2, nt
                    improved = True
                    break
                alpha *= 0.5
            if not improved:
                break
            wrench_eval(z[0], z[1], z[2], q, g)
        res[k] = nrm if nrm == nrm else np.inf


def distinct_shapes(Z: NDArray, tol: float = 1e-7, samples: int = 9) -> NDArray[np.int64]:
    """Indices of the first of each group of rods (base wrenches ``Z``) with the same shape.

    Two rods are one configuration when their curvature agrees along their whole length
    (sampled at ``samples`` points, to ``tol`` relative): the curvature profile and the clamp
    determine the rod.  (Their forces may differ where the shape does not determine them: a
    rod straight along its whole length takes any axial force.)
    """
    s = np.linspace(0.0, 1.0, samples)
    prof = np.empty((samples, 4))
    keys = np.empty((len(Z), samples))
    for i, z in enumerate(Z):
        wrench_profile(z[0], z[1], z[2], s, prof)
        keys[i] = prof[:, 3]
    keep: list[int] = []
    for i in range(len(Z)):
        sc = 1.0 + np.max(np.abs(keys[i]))
        if not keep or np.min(np.max(np.abs(keys[keep] - keys[i]), axis=1)) > tol * sc:
            keep.append(i)
    return np.array(keep, dtype=np.int64)


def clamped_rod_roots(xt: float, yt: float, tht: float, max_mode: int, tol: float = 1e-12
                      ) -> tuple[NDArray[np.float64], dict[str, int]]:
    """Base wrenches (n, 3) of every unit rod of the atlas' scope with tip ``(xt, yt)`` and tip
    tangent ``tht`` (mod 2 pi), and counts of starts and convergences."""
    A = get_wrench_atlas(max_mode)
    cells = bracket_cells(A.x, A.y, A.th, A.valid, float(xt), float(yt), float(tht), 0.25)
    Z = A.wrench(cells[:, 0] + 0.5, cells[:, 1] + 0.5, cells[:, 2] + 0.5) if len(cells) else np.zeros((0, 3))
    Z = np.ascontiguousarray(Z)
    res = np.full(len(Z), np.inf)
    wrench_newton(Z, float(xt), float(yt), float(tht), tol, 50, res)
    ok = res <= 1e-11
    Z = Z[ok][np.argsort(res[ok], kind="stable")]
    if len(Z):
        q = np.empty((len(Z), NQ))
        g = np.empty((len(Z), NQ, 3))
        for r in range(len(Z)):
            wrench_eval(Z[r, 0], Z[r, 1], Z[r, 2], q[r], g[r])
        modes = np.array([wrench_mode(z[0], z[1], z[2], 1e-9)[0] for z in Z])
        Z = Z[in_wrench_scope(q[:, TH], modes, max_mode, 1)]
    Z = Z[distinct_shapes(Z)]
    return Z, {"starts": int(len(ok)), "converged": int(np.count_nonzero(ok))}
