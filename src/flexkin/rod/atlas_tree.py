"""Bounding-box tree over the atlas cells (for branch-and-bound searches).

Every node covers a rectangle of atlas cells and stores the bounds, over that rectangle,
of the unit-rod tip position ``(x, y)`` and tip force ``(fx, fy)`` (local frame,
dimensionless).  Leaves are single cells; their boxes are padded by a fraction of their
extent because the closed form varies between grid nodes.  The forward kinematics prunes
triples of nodes (one per rod) whose boxes cannot satisfy the closure and equilibrium
equations.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .atlas import get_atlas

__all__ = ["AtlasTree", "get_atlas_tree"]


@dataclass(frozen=True)
class AtlasTree:
    """Binary tree of atlas cells.

    Attributes
    ----------
    lo, hi : (n_nodes, 4) bounds of (x, y, fx, fy) of the unit rod over each node.
    child : (n_nodes, 2) child node ids (-1 for leaves).
    cell : (n_nodes, 2) the (i, j) atlas cell of a leaf (-1 otherwise).
    center : (n_nodes, 2) chart coordinates (v, phis) of the node's centre.
    half : (n_nodes, 2) half-widths of the node in (v, phis).
    value : (n_nodes, 4) bilinear model of (x, y, fx, fy) at a leaf's centre.
    grad : (n_nodes, 4, 2) its gradient with respect to (v, phis) (zero for inner nodes).
    """

    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    child: NDArray[np.int64]
    cell: NDArray[np.int64]
    center: NDArray[np.float64]
    half: NDArray[np.float64]
    value: NDArray[np.float64]
    grad: NDArray[np.float64]

    @property
    def is_leaf(self) -> NDArray[np.bool_]:
        """Whether each node is a single cell."""
        return self.child[:, 0] < 0


@lru_cache(maxsize=4)
def get_atlas_tree(max_mode: int, stride: int = 1, pad: float = 0.1) -> AtlasTree:
    """Tree over the atlas of d-modes <= ``max_mode`` (cached).

    ``stride`` > 1 uses every ``stride``-th atlas node (coarser leaves); the cell bounds
    are then taken over all the fine nodes the coarse cell covers, so they stay valid.
    """
    A = get_atlas(max_mode)
    feats = np.stack([A.x, A.y, A.R * np.cos(A.psi), A.R * np.sin(A.psi)], -1)  # (nv, np, 4)
    nv, nph = A.x.shape
    # per-cell bounds from the four corner nodes, padded
    corners = np.stack([feats[:-1, :-1], feats[1:, :-1], feats[:-1, 1:], feats[1:, 1:]], 0)
    clo, chi = corners.min(0), corners.max(0)
    vv, pp = A.v, A.phis
    if stride > 1:  # merge fine cells into coarse ones
        ii = np.arange(0, nv - 1, stride)
        jj = np.arange(0, nph - 1, stride)
        clo = np.minimum.reduceat(np.minimum.reduceat(clo, ii, axis=0), jj, axis=1)
        chi = np.maximum.reduceat(np.maximum.reduceat(chi, ii, axis=0), jj, axis=1)
        vv = np.append(A.v[ii], A.v[-1])
        pp = np.append(A.phis[jj], A.phis[-1])
        nv, nph = len(vv), len(pp)
    ext = (chi - clo) * pad
    ext[..., :2] += 1e-9
    clo, chi = clo - ext, chi + ext
    lo_l: list[NDArray] = []
    hi_l: list[NDArray] = []
    child_l: list[tuple[int, int]] = []
    cell_l: list[tuple[int, int]] = []
    cen_l: list[tuple[float, float]] = []
    half_l: list[tuple[float, float]] = []

    def build(i0: int, i1: int, j0: int, j1: int) -> int:  # cells [i0, i1) x [j0, j1)
        node = len(lo_l)
        lo_l.append(None)  # type: ignore[arg-type]
        hi_l.append(None)  # type: ignore[arg-type]
        child_l.append((-1, -1))
        cell_l.append((-1, -1))
        cen_l.append((0.5 * (vv[i0] + vv[i1]), 0.5 * (pp[j0] + pp[j1])))
        half_l.append((0.5 * abs(vv[i1] - vv[i0]), 0.5 * abs(pp[j1] - pp[j0])))
        if i1 - i0 == 1 and j1 - j0 == 1:
            lo_l[node], hi_l[node] = clo[i0, j0], chi[i0, j0]
            cell_l[node] = (i0, j0)
            return node
        if i1 - i0 >= j1 - j0:
            mid = (i0 + i1) // 2
            a, b = build(i0, mid, j0, j1), build(mid, i1, j0, j1)
        else:
            mid = (j0 + j1) // 2
            a, b = build(i0, i1, j0, mid), build(i0, i1, mid, j1)
        child_l[node] = (a, b)
        lo_l[node] = np.minimum(lo_l[a], lo_l[b])
        hi_l[node] = np.maximum(hi_l[a], hi_l[b])
        return node

    import sys

    old = sys.getrecursionlimit()
    sys.setrecursionlimit(max(old, 10000))
    try:
        build(0, nv - 1, 0, nph - 1)
    finally:
        sys.setrecursionlimit(old)
    cell = np.array(cell_l, dtype=np.int64)
    # bilinear model of every leaf cell: value and gradient at its centre
    fv = feats
    if stride > 1:
        ii = np.append(np.arange(0, A.x.shape[0] - 1, stride), A.x.shape[0] - 1)
        jj = np.append(np.arange(0, A.x.shape[1] - 1, stride), A.x.shape[1] - 1)
        fv = feats[np.ix_(ii, jj)]
    f00, f10, f01, f11 = fv[:-1, :-1], fv[1:, :-1], fv[:-1, 1:], fv[1:, 1:]
    dv = np.diff(vv)[:, None, None]
    dp = np.diff(pp)[None, :, None]
    val_c = 0.25 * (f00 + f10 + f01 + f11)
    gv = 0.5 * ((f10 + f11) - (f00 + f01)) / dv
    gp = 0.5 * ((f01 + f11) - (f00 + f10)) / dp
    leaf = cell[:, 0] >= 0
    value = np.zeros((len(cell), 4))
    grad = np.zeros((len(cell), 4, 2))
    ci, cj = cell[leaf, 0], cell[leaf, 1]
    value[leaf] = val_c[ci, cj]
    grad[leaf, :, 0] = gv[ci, cj]
    grad[leaf, :, 1] = gp[ci, cj]
    return AtlasTree(np.array(lo_l), np.array(hi_l), np.array(child_l, dtype=np.int64), cell,
                     np.array(cen_l), np.array(half_l), value, grad)
