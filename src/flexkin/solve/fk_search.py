"""The forward kinematics' global search: a compiled branch-and-bound over the rods' atlases.

For mechanisms whose legs are all pinned at the platform (with any leg clamped, FK goes to the
pose lattice, :mod:`flexkin.solve.fk_lattice`, where these 9-D bounds exclude too little).
With the inputs fixed every clamp is known.  Each leg's rod is a point of the pinned rods'
``(v, phis)`` atlas (a :class:`~flexkin.rod.cell_tree.CellTree`); a triple of tree nodes, one
per leg, survives only if interval arithmetic on its boxes, mapped to the world by each leg's
clamp, admits

* the platform's three side lengths ``|B_i - B_j| = d_ij`` and its signed area (which rejects
  the mirror-image platform; paper Eq. 17);
* the force balance ``sum n_i = F`` and the moment balance about ``B_1``
  ``sum (B_i - B_1) x n_i + sum m_i(L) = M_z + (P - B_1) x F`` (Eq. 15, SPEC §2 sign; the last
  term bounded by ``|b_1| |F|``).

The largest node of a surviving triple is split (depth first, resumable: the stack is kept
between calls so a time budget can interrupt it) until all three are leaves or resolved in
physical terms; then one exact Newton step on the whole equation system (:mod:`flexkin.system`)
from the nodes' centres, with the pose fitted to the three tips, decides: the triple is kept as
a start when the step stays within the nodes (a solution inside a node has a step of at most
its half extent).
"""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from ..core.budget import Deadline, Rate
from ..core.jit import njit
from ..core.linalg import solve_into
from ..rod.cell_tree import pinned_tree
from ..rod.closed_form import SEAM_OFFSET, is_seam
from ..rod.slots import CHART_SEAM, NQ
from ..system import System, assemble

__all__ = ["fk_starts"]

TWO_PI = 2.0 * math.pi


@njit
def _imul(alo, ahi, blo, bhi):
    p1, p2, p3, p4 = alo * blo, alo * bhi, ahi * blo, ahi * bhi
    return min(p1, p2, p3, p4), max(p1, p2, p3, p4)


@njit
def _icross(ax, axh, ay, ayh, bx, bxh, by, byh):
    """Interval of ``a x b`` for boxes given by centre and half-width."""
    l1, h1 = _imul(ax - axh, ax + axh, by - byh, by + byh)
    l2, h2 = _imul(ay - ayh, ay + ayh, bx - bxh, bx + bxh)
    return l1 - h2, h1 - l2


@njit
def _dist_ok(dx, dy, hx, hy, d, tol) -> bool:
    nx = max(abs(dx) - hx, 0.0)
    ny = max(abs(dy) - hy, 0.0)
    near = math.sqrt(nx * nx + ny * ny)
    fx, fy = abs(dx) + hx, abs(dy) + hy
    far = math.sqrt(fx * fx + fy * fy)
    return near <= d + tol and far >= d - tol


@njit
def _fit_pose(tx, ty, b, out) -> None:
    """Least-squares rigid pose placing the attach points ``b`` (3, 2) on the tips."""
    bx = (b[0, 0] + b[1, 0] + b[2, 0]) / 3.0
    by = (b[0, 1] + b[1, 1] + b[2, 1]) / 3.0
    px = (tx[0] + tx[1] + tx[2]) / 3.0
    py = (ty[0] + ty[1] + ty[2]) / 3.0
    s = 0.0
    c = 0.0
    for i in range(3):
        ux, uy = b[i, 0] - bx, b[i, 1] - by
        vx, vy = tx[i] - px, ty[i] - py
        s += ux * vy - uy * vx
        c += ux * vx + uy * vy
    th = math.atan2(s, c)
    ct, st = math.cos(th), math.sin(th)
    out[0] = px - (ct * bx - st * by)
    out[1] = py - (st * bx + ct * by)
    out[2] = th


@njit
def bnb_kernel(lo, hi, child, zc, zh, nq, ng, charts, A, al, L, EI, b, w, L_ref, F_ref, eps_tip, eps_force, reach,
               c0, c1, EIs, attach, joint, tip_angle, rod_col, tip_row, cols, u,
               stack, n_stack, budget, starts, n_starts):
    """Process node triples from ``stack[:n_stack]`` until it empties, ``budget`` triples were
    examined or ``starts`` is full; returns ``(n_stack, n_starts, examined)``."""
    b01x, b01y = b[1, 0] - b[0, 0], b[1, 1] - b[0, 1]
    b02x, b02y = b[2, 0] - b[0, 0], b[2, 1] - b[0, 1]
    d01 = math.hypot(b01x, b01y)
    d02 = math.hypot(b02x, b02y)
    d12 = math.hypot(b[2, 0] - b[1, 0], b[2, 1] - b[1, 1])
    area = b01x * b02y - b01y * b02x
    tol = 1e-9 * L_ref
    mslack = math.hypot(b[0, 0], b[0, 1]) * math.hypot(w[0], w[1])
    ct = np.empty((3, 2))
    th_ = np.empty((3, 2))
    cf = np.empty((3, 2))
    hf = np.empty((3, 2))
    mlo = np.empty(3)
    mhi = np.empty(3)
    size = np.empty(3)
    nodes = np.empty(3, np.int64)
    nu = rod_col[2] + 2 + 6  # rod coordinates (2 per pinned rod), pose, inputs
    x = np.empty(nu)
    r = np.empty(nu - 3)
    J = np.empty((nu - 3, nu))
    q = np.empty((3, NQ))
    g = np.empty((3, NQ, 3))
    p = cols.shape[0]
    M = np.empty((p, p))
    rhs = np.empty(p)
    dx = np.empty(p)
    work = np.empty((p, p + 1))
    tipx = np.empty(3)
    tipy = np.empty(3)
    pose = np.empty(3)
    examined = 0
    while n_stack > 0 and examined < budget and n_starts < starts.shape[0]:
        n_stack -= 1
        nodes[0], nodes[1], nodes[2] = stack[n_stack, 0], stack[n_stack, 1], stack[n_stack, 2]
        examined += 1
        for i in range(3):
            nd = nodes[i]
            ca, sa = math.cos(al[i]), math.sin(al[i])
            xc, yc = 0.5 * (lo[nd, 0] + hi[nd, 0]), 0.5 * (lo[nd, 1] + hi[nd, 1])
            xh, yh = 0.5 * (hi[nd, 0] - lo[nd, 0]), 0.5 * (hi[nd, 1] - lo[nd, 1])
            ct[i, 0] = A[i, 0] + L[i] * (ca * xc - sa * yc)
            ct[i, 1] = A[i, 1] + L[i] * (sa * xc + ca * yc)
            th_[i, 0] = L[i] * (abs(ca) * xh + abs(sa) * yh)
            th_[i, 1] = L[i] * (abs(sa) * xh + abs(ca) * yh)
            s = EI[i] / (L[i] * L[i])
            fxc, fyc = 0.5 * (lo[nd, 2] + hi[nd, 2]), 0.5 * (lo[nd, 3] + hi[nd, 3])
            fxh, fyh = 0.5 * (hi[nd, 2] - lo[nd, 2]), 0.5 * (hi[nd, 3] - lo[nd, 3])
            cf[i, 0] = s * (ca * fxc - sa * fyc)
            cf[i, 1] = s * (sa * fxc + ca * fyc)
            hf[i, 0] = s * (abs(ca) * fxh + abs(sa) * fyh)
            hf[i, 1] = s * (abs(sa) * fxh + abs(ca) * fyh)
            sm = EI[i] / L[i]
            mlo[i] = sm * lo[nd, 5]
            mhi[i] = sm * hi[nd, 5]
            fmag = math.hypot(cf[i, 0], cf[i, 1])
            sz = max(th_[i, 0], th_[i, 1]) / (eps_tip * L_ref)
            sz = max(sz, max(hf[i, 0], hf[i, 1]) / (eps_force * (F_ref + fmag)))
            size[i] = -1.0 if (child[nd, 0] < 0 or sz < 1.0) else sz
        # ---- interval tests ------------------------------------------------------------
        if not _dist_ok(ct[1, 0] - ct[0, 0], ct[1, 1] - ct[0, 1], th_[0, 0] + th_[1, 0], th_[0, 1] + th_[1, 1], d01, tol):
            continue
        if not _dist_ok(ct[2, 0] - ct[0, 0], ct[2, 1] - ct[0, 1], th_[0, 0] + th_[2, 0], th_[0, 1] + th_[2, 1], d02, tol):
            continue
        if not _dist_ok(ct[2, 0] - ct[1, 0], ct[2, 1] - ct[1, 1], th_[1, 0] + th_[2, 0], th_[1, 1] + th_[2, 1], d12, tol):
            continue
        alo, ahi = _icross(ct[1, 0] - ct[0, 0], th_[0, 0] + th_[1, 0], ct[1, 1] - ct[0, 1], th_[0, 1] + th_[1, 1],
                           ct[2, 0] - ct[0, 0], th_[0, 0] + th_[2, 0], ct[2, 1] - ct[0, 1], th_[0, 1] + th_[2, 1])
        if not (alo <= area + tol * tol and ahi >= area - tol * tol):
            continue
        sfx = cf[0, 0] + cf[1, 0] + cf[2, 0]
        sfy = cf[0, 1] + cf[1, 1] + cf[2, 1]
        hfx = hf[0, 0] + hf[1, 0] + hf[2, 0]
        hfy = hf[0, 1] + hf[1, 1] + hf[2, 1]
        if abs(sfx - w[0]) > hfx + 1e-12 * F_ref or abs(sfy - w[1]) > hfy + 1e-12 * F_ref:
            continue
        m1 = _icross(ct[1, 0] - ct[0, 0], th_[0, 0] + th_[1, 0], ct[1, 1] - ct[0, 1], th_[0, 1] + th_[1, 1],
                     cf[1, 0], hf[1, 0], cf[1, 1], hf[1, 1])
        m2 = _icross(ct[2, 0] - ct[0, 0], th_[0, 0] + th_[2, 0], ct[2, 1] - ct[0, 1], th_[0, 1] + th_[2, 1],
                     cf[2, 0], hf[2, 0], cf[2, 1], hf[2, 1])
        mtl = m1[0] + m2[0] + mlo[0] + mlo[1] + mlo[2]
        mth = m1[1] + m2[1] + mhi[0] + mhi[1] + mhi[2]
        slack = mslack + 1e-12 * F_ref * L_ref
        if mtl > w[2] + slack or mth < w[2] - slack:
            continue
        # ---- split, or test the terminal triple ------------------------------------------
        k = 0
        if size[1] > size[k]:
            k = 1
        if size[2] > size[k]:
            k = 2
        if size[k] > 0.0:
            if n_stack + 2 > stack.shape[0]:
                n_stack += 1  # put it back: the stack is full
                stack[n_stack - 1, 0], stack[n_stack - 1, 1], stack[n_stack - 1, 2] = nodes[0], nodes[1], nodes[2]
                break
            for side in range(2):
                stack[n_stack, 0], stack[n_stack, 1], stack[n_stack, 2] = nodes[0], nodes[1], nodes[2]
                stack[n_stack, k] = child[nodes[k], side]
                n_stack += 1
            continue
        # one exact Newton step from the centres, pose fitted to the three tips
        for i in range(3):
            for c in range(2):
                x[rod_col[i] + c] = zc[nodes[i], c]
            tipx[i], tipy[i] = ct[i, 0], ct[i, 1]
        _fit_pose(tipx, tipy, b, pose)
        ip = nu - 6
        x[ip], x[ip + 1], x[ip + 2] = pose[0], pose[1], pose[2]
        x[nu - 3], x[nu - 2], x[nu - 1] = u[0], u[1], u[2]
        for i in range(3):  # the rods at the nodes' centres, evaluated once per node
            q[i, :] = nq[nodes[i]]
            g[i, :, :] = ng[nodes[i]]
        assemble(c0, c1, EIs, attach, joint, tip_angle, rod_col, tip_row, L_ref, F_ref, x, charts, w, r, J, True,
                 q, g)
        for a in range(p):
            rhs[a] = -r[a]
            for c in range(p):
                M[a, c] = J[a, cols[c]]
        solve_into(M, rhs, dx, work)
        keep = True
        for i in range(3):
            for c in range(2):
                v = dx[rod_col[i] + c]
                if not abs(v) <= (1.0 + reach) * zh[nodes[i], c] + 1e-12:
                    keep = False
        if keep:
            for c in range(nu):
                starts[n_starts, c] = x[c]
            for c in range(p):
                starts[n_starts, cols[c]] += dx[c]
            n_starts += 1
    return n_stack, n_starts, examined


def _tree(max_mode: int, stride: int):
    """The pinned rods' tree (arrays), its root node for each leg and each leg's chart."""
    t = pinned_tree(max_mode, stride)
    roots = np.zeros(3, dtype=np.int64)
    charts = np.full(3, t.chart, dtype=np.int64)
    arrays = (np.ascontiguousarray(a) for a in (t.lo, t.hi, t.child, t.zc, t.zh, t.q, t.g))
    return (*arrays, roots, charts)


#: estimated cost of refining one start (s): the FK Newton of a clamped rod's start, measured
#: ~0.6 ms on the unit 3-PF (pinned starts are ~20x cheaper); used to leave the refinement its
#: share of a time budget
REFINE_COST = 6e-4
#: node triples examined at most
MAX_NODES = 50_000_000
#: node triples per compiled slice at most (with a budget, slices are sized from the measured rate)
SLICE = 200_000
#: seconds per node triple before anything is measured (a guess on the safe side)
NODE_COST = 2e-6


def _node_shares(child: NDArray[np.int64], roots: NDArray[np.int64]) -> NDArray[np.float64]:
    """Each tree node's share of its tree: 1 at a root, half its parent's below (binary trees)."""
    share = np.zeros(len(child))
    level = np.unique(roots)
    share[level] = 1.0
    while level.size:
        kids = child[level]
        has = kids[:, 0] >= 0
        share[kids[has].ravel()] = np.repeat(0.5 * share[level[has]], 2)
        level = kids[has].ravel()
    return share


def fk_starts(system: System, inputs: NDArray, load: NDArray, max_mode: int, *, stride: int = 4,
              eps_tip: float = 0.01, eps_force: float = 0.05, reach: float = 1.0,
              max_nodes: int = MAX_NODES, deadline: Deadline | None = None, fallback: int = 20_000,
              progress: Callable[[float, str], None] | None = None
              ) -> tuple[NDArray[np.float64], NDArray[np.int64], bool, int]:
    """Starting points (n, n_unknowns) for the FK Newton, their rods' charts (n, 3), whether the
    search completed, and the number of node triples examined.

    Pinned rods come from the atlas (unified chart) or, near straight under tension, from the
    seam patch (seam chart; :func:`~flexkin.rod.cell_tree.pinned_tree`).

    When the node budget ``max_nodes`` runs out, the centres of up to ``fallback`` unresolved
    triples (a deterministic subsample) are returned as well.  With a ``deadline``
    (:class:`~flexkin.core.budget.Deadline`) the search runs in slices sized from the measured
    rate and stops early enough for the refinement of its starts (:data:`REFINE_COST` each) to
    end in time, and the unresolved centres are limited to what the remaining time can refine.
    ``progress(fraction, stage)`` is told the share of the search space resolved (the product
    of the three nodes' shares of their trees, summed over the triples still to examine, is
    what remains)."""
    if np.any(system.clamped):
        raise ValueError("fk_starts searches mechanisms with every leg pinned at the platform; "
                         "with a clamped leg use the pose lattice (flexkin.solve.fk_lattice)")
    lo, hi, child, zc, zh, nq, ng, roots, charts = _tree(max_mode, stride)
    u = np.asarray(inputs, dtype=float)
    A, al, L = system.clamps(u[None])
    A, al, L = np.ascontiguousarray(A[0]), np.ascontiguousarray(al[0]), np.ascontiguousarray(L[0])
    cols = system.layout.columns("inputs")
    stack = np.empty((200_000, 3), np.int64)
    stack[0] = roots
    n_stack = 1
    starts = np.empty((200_000, system.layout.n_unknowns))
    n_starts = 0
    examined = 0
    w = np.asarray(load, dtype=float)
    dl = deadline if deadline is not None else Deadline()
    rate = Rate(NODE_COST)
    share = None
    while n_stack > 0 and examined < max_nodes:
        if dl.expired(REFINE_COST * n_starts):
            break
        t = time.perf_counter()
        n_stack, n_starts, ex = bnb_kernel(lo, hi, child, zc, zh, nq, ng, charts, A, al, L, system.EI,
                                           system.attach, w, system.L_ref, system.F_ref, eps_tip, eps_force, reach, *system.args()[:8], cols, u, stack, n_stack,
                                           min(rate.units_for(dl.slice_seconds(), 100, SLICE), max_nodes - examined),
                                           starts, n_starts)
        rate.add(ex, time.perf_counter() - t)
        examined += ex
        if progress is not None:
            if share is None:
                share = _node_shares(child, roots)
            left = float(np.sum(np.prod(share[stack[:n_stack]], axis=1)))
            progress(1.0 - left, f"{examined:,} node triples examined")
        if n_starts >= len(starts):
            starts = np.concatenate([starts, np.empty_like(starts)])
        if n_stack + 2 > len(stack):
            stack = np.concatenate([stack, np.empty_like(stack)])
    complete = n_stack == 0
    out = [_decode(system, starts[:n_starts], charts)]
    if dl.limited:
        fallback = min(fallback, max(0, int(dl.remaining() / REFINE_COST) - n_starts))
    if not complete and fallback > 0:  # unresolved triples: their centres, fitted pose
        rest = stack[:n_stack]
        if len(rest) > fallback:
            rest = rest[np.random.default_rng(0).choice(len(rest), fallback, replace=False)]
        X = np.zeros((len(rest), system.layout.n_unknowns))
        for i in range(3):
            sl = system.layout.rod[i]
            X[:, sl] = zc[rest[:, i], :sl.stop - sl.start]
        X[:, system.layout.inputs] = u
        X, ch = _decode(system, X, charts)
        tips = system.rod_world(X, ch)["tip"]
        from ..core.geometry2d import fit_pose

        X[:, system.layout.pose] = fit_pose(system.attach, tips)
        out.append((X, ch))
    return (np.concatenate([x for x, _ in out]), np.concatenate([c for _, c in out]).astype(np.int64), complete,
            examined)


def _decode(system: System, X: NDArray, charts: NDArray) -> tuple[NDArray, NDArray]:
    """Rows ``X`` whose pinned rods may be offset-encoded seam pairs (nodes of the seam patch) ->
    raw coordinates and the charts (n, 3) they are in."""
    X = np.array(X, dtype=float)
    leg_charts = np.asarray(charts, dtype=np.int64)
    ch = np.broadcast_to(leg_charts, (len(X), 3)).copy()
    for i in range(3):
        c = system.layout.rod[i].start + 1
        seam = is_seam(X[:, c])
        X[seam, c] -= SEAM_OFFSET
        ch[seam, i] = CHART_SEAM
    return X, ch
