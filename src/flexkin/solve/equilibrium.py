"""Global search for platform equilibrium on three polylines (paper §4.2, Eq. 15).

Each leg's geometric-condition curve maps to a curve in wrench space,
``w_i = (n_i, (B_i - P) x n_i)`` (the rod's tip force and its moment about P).  An IK
equilibrium is a triple of points, one per curve, with ``w_1 + w_2 + w_3 = w_load``:
three equations in three curve parameters.

The curves are polylines.  On a triple of segments the equations are linear in the three
segment parameters, and a subdivision search finds every segment triple whose Minkowski
bounding box contains the load: binary trees of segment bounding boxes per leg, the
widest node of a surviving triple split at each level, all triples processed as arrays.
Each surviving leaf triple is solved exactly (3x3 linear system) and yields a starting
point for the Newton refinement.  Boxes are padded so that the chord approximation of
the curves cannot hide a solution near a segment end.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

__all__ = ["SegmentTree", "equilibrium_triples"]


class SegmentTree:
    """Implicit binary tree of bounding boxes over the segments of one polyline set.

    Parameters
    ----------
    p0, p1 : (N, d) segment end points.
    pad : relative padding of each leaf box (fraction of its extent) plus ``abs_pad``.
    """

    def __init__(self, p0: NDArray[np.float64], p1: NDArray[np.float64], pad: float = 0.25,
                 abs_pad: float = 1e-9) -> None:
        n, d = p0.shape
        self.n = n
        size = 1
        while size < max(n, 1):
            size *= 2
        self.size = size
        lo = np.full((2 * size, d), np.inf)
        hi = np.full((2 * size, d), -np.inf)
        if n:
            a, b = np.minimum(p0, p1), np.maximum(p0, p1)
            ext = (b - a).max(axis=1, keepdims=True) * pad + abs_pad
            lo[size:size + n] = a - ext
            hi[size:size + n] = b + ext
        for j in range(size - 1, 0, -1):
            lo[j] = np.minimum(lo[2 * j], lo[2 * j + 1])
            hi[j] = np.maximum(hi[2 * j], hi[2 * j + 1])
        self.lo, self.hi = lo, hi

    def is_leaf(self, node: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Whether nodes are leaves."""
        return node >= self.size

    def segment(self, node: NDArray[np.int64]) -> NDArray[np.int64]:
        """Segment index of leaf nodes."""
        return node - self.size


def equilibrium_triples(p0s: list[NDArray], p1s: list[NDArray], target: NDArray[np.float64],
                        max_nodes: int = 50_000_000, chunk: int = 100_000, deadline: float | None = None
                        ) -> tuple[NDArray[np.int64], NDArray[np.float64], bool]:
    """Segment triples and parameters where ``sum_i w_i(s_i) = target``.

    Parameters
    ----------
    p0s, p1s : three arrays (N_i, 3) of segment end points in (scaled) wrench space.
    target : (3,) the load wrench (scaled).
    max_nodes : budget of node triples examined; when it runs out the search stops and
        the result is flagged incomplete.
    deadline : ``time.perf_counter()`` value after which the search stops (incomplete).

    Returns
    -------
    seg : (M, 3) segment index per leg.
    s : (M, 3) segment parameters (approximately in [0, 1]).
    complete : bool, False if the node budget ran out.
    """
    trees = [SegmentTree(a, b) for a, b in zip(p0s, p1s)]
    if any(t.n == 0 for t in trees):
        return np.zeros((0, 3), np.int64), np.zeros((0, 3)), True
    stack = [np.ones((1, 3), dtype=np.int64)]
    leaves = []
    evaluated = 0
    complete = True
    while stack:  # depth-first over chunks: bounded memory
        active = stack.pop()
        evaluated += len(active)
        if evaluated > max_nodes or (deadline is not None and time.perf_counter() > deadline):
            complete = False
            break
        lo = sum(trees[i].lo[active[:, i]] for i in range(3))
        hi = sum(trees[i].hi[active[:, i]] for i in range(3))
        keep = np.all((lo <= target) & (hi >= target), axis=1)
        active = active[keep]
        if not active.size:
            continue
        leaf = np.stack([trees[i].is_leaf(active[:, i]) for i in range(3)], 1)
        done = np.all(leaf, axis=1)
        if np.any(done):
            leaves.append(active[done])
        active = active[~done]
        if not active.size:
            continue
        widths = np.stack([
            np.where(leaf[~done][:, i], -1.0,
                     np.max(trees[i].hi[active[:, i]] - trees[i].lo[active[:, i]], axis=1))
            for i in range(3)], 1)
        j = np.argmax(widths, axis=1)
        rows = np.arange(len(active))
        left = active.copy()
        right = active.copy()
        left[rows, j] = 2 * active[rows, j]
        right[rows, j] = 2 * active[rows, j] + 1
        nxt = np.concatenate([left, right])
        for k in range(0, len(nxt), chunk):
            stack.append(nxt[k:k + chunk])
    if not leaves:
        return np.zeros((0, 3), np.int64), np.zeros((0, 3)), complete
    L = np.concatenate(leaves)
    seg = np.stack([trees[i].segment(L[:, i]) for i in range(3)], 1)
    a = [p0s[i][seg[:, i]] for i in range(3)]
    d = [p1s[i][seg[:, i]] - a[i] for i in range(3)]
    M = np.stack(d, -1)  # (M, 3, 3): columns are the segment directions
    rhs = target - a[0] - a[1] - a[2]
    s = np.full((len(seg), 3), 0.5)
    det = np.linalg.det(M)
    scale = np.prod(np.linalg.norm(M, axis=1) + 1e-300, axis=1)
    good = np.abs(det) > 1e-12 * scale
    if np.any(good):
        s[good] = np.linalg.solve(M[good], rhs[good][..., None])[..., 0]
    ok = np.all((s > -0.3) & (s < 1.3), axis=1) | ~good
    return seg[ok], np.clip(s[ok], 0.0, 1.0), complete
