"""Global search for platform equilibrium on three polylines (paper §4.2, Eq. 15).

Each leg's geometric-condition curve maps to a curve in wrench space,
``w_i = (n_i, (B_i - P) x n_i)`` (the rod's tip force and its moment about P).  An IK
equilibrium is a triple of points, one per curve, with ``w_1 + w_2 + w_3 = w_load``:
three equations in three curve parameters.

The curves are polylines.  On a triple of segments the equations are linear in the three
segment parameters, and a subdivision search finds every segment triple whose Minkowski
bounding box contains the load: binary trees of segment bounding boxes per leg, the
widest node of a surviving triple split at each level (compiled, depth first, resumable so
that a deadline is checked between slices of work).  Each surviving leaf triple is solved
exactly (3x3 linear system) and yields a starting point for the Newton refinement.  Boxes
are padded so that the chord approximation of the curves cannot hide a solution near a
segment end.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from ..core.budget import Deadline, Rate
from ..core.jit import njit

__all__ = ["SegmentTree", "equilibrium_triples"]

#: node triples examined at most per compiled slice between two deadline checks (with a
#: budget the slices are sized from the measured rate, :mod:`flexkin.core.budget`)
SLICE = 200_000
#: seconds per node triple before anything is measured (a guess on the safe side)
NODE_COST = 2e-7


@njit(cache=True)
def _build_tree(p0, p1, pad, abs_pad, size, lo, hi) -> None:
    """Leaf boxes (padded segment boxes) at ``size + j`` and their unions up the tree."""
    n, d = p0.shape
    for j in range(n):
        ext = 0.0
        for c in range(d):
            ext = max(ext, abs(p1[j, c] - p0[j, c]))
        ext = ext * pad + abs_pad
        for c in range(d):
            lo[size + j, c] = min(p0[j, c], p1[j, c]) - ext
            hi[size + j, c] = max(p0[j, c], p1[j, c]) + ext
    for j in range(size - 1, 0, -1):
        for c in range(d):
            lo[j, c] = min(lo[2 * j, c], lo[2 * j + 1, c])
            hi[j, c] = max(hi[2 * j, c], hi[2 * j + 1, c])


class SegmentTree:
    """Implicit binary tree of bounding boxes over the segments of one polyline set.

    Parameters
    ----------
    p0, p1 : ndarray (N, d)
        Segment end points.
    pad : float
        Relative padding of each leaf box (fraction of its extent), plus ``abs_pad``.
    abs_pad : float
        Absolute padding of each leaf box.
    """

    def __init__(self, p0: NDArray[np.float64], p1: NDArray[np.float64], pad: float = 0.25,
                 abs_pad: float = 1e-9) -> None:
        n, d = p0.shape
        self.n = n
        size = 1
        while size < max(n, 1):
            size *= 2
        self.size = size
        self.lo = np.full((2 * size, d), np.inf)
        self.hi = np.full((2 * size, d), -np.inf)
        if n:
            _build_tree(np.ascontiguousarray(p0, dtype=float), np.ascontiguousarray(p1, dtype=float),
                        pad, abs_pad, size, self.lo, self.hi)


@njit(cache=True)
def _segment_solve(p0, p1, ia, ib, ic, target, s) -> bool:
    """The segment parameters ``s`` (3,) of a leaf triple where ``sum_i w_i(s_i) = target``
    (Eq. 15, linear on segments; Cramer's rule).  ``False`` when the solution lies outside
    ``(-0.3, 1.3)^3`` (no equilibrium near these segments); a (near) singular triple is kept
    with ``s = 1/2``."""
    idx = (ia, ib, ic)
    M = np.empty((3, 3))
    r = np.empty(3)
    for d in range(3):
        r[d] = target[d]
    scale = 1.0
    for i in range(3):
        nrm = 0.0
        for d in range(3):
            M[d, i] = p1[i, idx[i], d] - p0[i, idx[i], d]
            r[d] -= p0[i, idx[i], d]
            nrm += M[d, i] * M[d, i]
        scale *= np.sqrt(nrm) + 1e-300
    det = (M[0, 0] * (M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]) - M[0, 1] * (M[1, 0] * M[2, 2] - M[1, 2] * M[2, 0])
           + M[0, 2] * (M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]))
    if not abs(det) > 1e-12 * scale:
        s[:] = 0.5
        return True
    for i in range(3):
        Mi = M.copy()
        for d in range(3):
            Mi[d, i] = r[d]
        di = (Mi[0, 0] * (Mi[1, 1] * Mi[2, 2] - Mi[1, 2] * Mi[2, 1])
              - Mi[0, 1] * (Mi[1, 0] * Mi[2, 2] - Mi[1, 2] * Mi[2, 0])
              + Mi[0, 2] * (Mi[1, 0] * Mi[2, 1] - Mi[1, 1] * Mi[2, 0]))
        s[i] = di / det
        if not (s[i] > -0.3 and s[i] < 1.3):
            return False
    for i in range(3):
        s[i] = min(max(s[i], 0.0), 1.0)
    return True


@njit(cache=True)
def _search(lo0, hi0, lo1, hi1, lo2, hi2, sizes, p0, p1, target, stack, sp, budget, leaves, params, nleaf):
    """Depth-first subdivision from the ``sp`` node triples on ``stack`` (resumable).

    Examines at most ``budget`` node triples; leaf triples whose segments solve Eq. (15)
    (:func:`_segment_solve`) are appended to ``leaves`` and their parameters to ``params``
    from ``nleaf`` on (grown when full).  ``p0``, ``p1`` (3, N, 3): segment ends per leg,
    padded.  Returns ``(sp, nleaf, examined, leaves, params, stack)``.
    """
    examined = 0
    s = np.empty(3)
    while sp > 0 and examined < budget:
        sp -= 1
        a = stack[sp, 0]
        b = stack[sp, 1]
        c = stack[sp, 2]
        examined += 1
        inside = True
        for d in range(3):
            if lo0[a, d] + lo1[b, d] + lo2[c, d] > target[d] or hi0[a, d] + hi1[b, d] + hi2[c, d] < target[d]:
                inside = False
                break
        if not inside:
            continue
        la = a >= sizes[0]
        lb = b >= sizes[1]
        lc = c >= sizes[2]
        if la and lb and lc:
            ia, ib, ic = a - sizes[0], b - sizes[1], c - sizes[2]
            if not _segment_solve(p0, p1, ia, ib, ic, target, s):
                continue
            if nleaf == leaves.shape[0]:
                grown = np.empty((2 * nleaf, 3), np.int64)
                grown[:nleaf] = leaves
                leaves = grown
                grown_p = np.empty((2 * nleaf, 3))
                grown_p[:nleaf] = params
                params = grown_p
            leaves[nleaf, 0] = ia
            leaves[nleaf, 1] = ib
            leaves[nleaf, 2] = ic
            for d in range(3):
                params[nleaf, d] = s[d]
            nleaf += 1
            continue
        # split the widest non-leaf node of the triple
        wa = -1.0
        wb = -1.0
        wc = -1.0
        for d in range(3):
            if not la:
                wa = max(wa, hi0[a, d] - lo0[a, d])
            if not lb:
                wb = max(wb, hi1[b, d] - lo1[b, d])
            if not lc:
                wc = max(wc, hi2[c, d] - lo2[c, d])
        j = 0
        if wb > wa:
            j = 1
        if wc > max(wa, wb):
            j = 2
        if sp + 2 > stack.shape[0]:
            grown_s = np.empty((2 * stack.shape[0], 3), np.int64)
            grown_s[:sp] = stack[:sp]
            stack = grown_s
        for side in range(2):
            stack[sp, 0] = a
            stack[sp, 1] = b
            stack[sp, 2] = c
            stack[sp, j] = 2 * stack[sp, j] + (1 - side)
            sp += 1
    return sp, nleaf, examined, leaves, params, stack


def equilibrium_triples(p0s: list[NDArray], p1s: list[NDArray], target: NDArray[np.float64],
                        max_nodes: int = 50_000_000, deadline: Deadline | None = None, leaf_cost: float = 0.0
                        ) -> tuple[NDArray[np.int64], NDArray[np.float64], bool]:
    """Segment triples and parameters where ``sum_i w_i(s_i) = target``.

    Parameters
    ----------
    p0s, p1s : list of ndarray
        Three arrays (N_i, 3) of segment end points in (scaled) wrench space.
    target : ndarray (3,)
        The load wrench (scaled).
    max_nodes : int
        Budget of node triples examined; when it runs out the search stops and the result is
        flagged incomplete.
    deadline : Deadline, optional
        The caller's time budget: the search stops (incomplete) when the time left would not
        cover the refinement of the leaves found so far.
    leaf_cost : float
        Seconds the caller needs per leaf after the search (the refinement it reserves).

    Returns
    -------
    seg : ndarray (M, 3)
        Segment index per leg.
    s : ndarray (M, 3)
        Segment parameters (clipped to [0, 1]).
    complete : bool
        False if the node budget or the deadline ran out.
    """
    trees = [SegmentTree(a, b) for a, b in zip(p0s, p1s)]
    if any(t.n == 0 for t in trees):
        return np.zeros((0, 3), np.int64), np.zeros((0, 3)), True
    target = np.ascontiguousarray(target, dtype=float)
    sizes = np.array([t.size for t in trees], np.int64)
    nmax = max(t.n for t in trees)
    p0 = np.zeros((3, nmax, 3))
    p1 = np.zeros((3, nmax, 3))
    for i in range(3):
        p0[i, :trees[i].n] = p0s[i]
        p1[i, :trees[i].n] = p1s[i]
    stack = np.ones((256, 3), np.int64)
    leaves = np.empty((256, 3), np.int64)
    params = np.empty((256, 3))
    sp, nleaf, evaluated = 1, 0, 0
    complete = True
    dl = deadline if deadline is not None else Deadline()
    rate = Rate(NODE_COST)
    while sp:
        if evaluated >= max_nodes or dl.expired(leaf_cost * nleaf):
            complete = False
            break
        n = min(rate.units_for(dl.slice_seconds(), 1000, SLICE), max_nodes - evaluated)
        t = time.perf_counter()
        sp, nleaf, ex, leaves, params, stack = _search(
            trees[0].lo, trees[0].hi, trees[1].lo, trees[1].hi, trees[2].lo, trees[2].hi, sizes, p0, p1, target,
            stack, sp, n, leaves, params, nleaf)
        rate.add(ex, time.perf_counter() - t)
        evaluated += ex
    return leaves[:nleaf].copy(), params[:nleaf].copy(), complete
