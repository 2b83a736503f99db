"""Bounding-box trees over the rods' atlases, for the branch-and-bound searches.

Every node covers a block of atlas cells and stores the bounds, over that block, of six
quantities of the unit rod in its clamp frame: tip position ``(x, y)``, tip force
``(fx, fy)``, tip angle and tip moment (:mod:`flexkin.rod.slots`).  Leaves are small blocks of
cells; their boxes are padded by a fraction of their extent because the closed form varies
between grid nodes.  Each node also carries the chart coordinates of its centre and its half
extent in the chart, for the leaf test of the searches.

The tree is over the pinned rods' atlas (:mod:`flexkin.rod.atlas`, chart ``(v, phis)``), with
the seam patch of :mod:`flexkin.rod.seam_atlas` for the rods near straight under tension; it is
cached on disk.  (Clamped rods are searched on the pose lattice, :mod:`flexkin.solve.fk_lattice`.)
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.cache import cached_arrays
from .atlas import MODE_MARGIN, get_atlas
from .closed_form import SEAM_OFFSET, is_seam
from .seam_atlas import T_MAX, get_seam_atlas
from .slots import CHART_SEAM, CHART_UNIFIED, NQ

__all__ = ["CellTree", "pinned_tree"]

#: relative padding of a leaf's bounds
PAD = 0.1
#: the pinned tree takes the seam patch's blocks that meet |psi_s| < SEAM_TREE_PSI (about 1.5
#: cells of the atlas next to its corner), the atlas' blocks for the rest
SEAM_TREE_PSI = 0.05


@dataclass(frozen=True)
class CellTree:
    """A binary tree of atlas blocks (arrays indexed by node; the root is node 0).

    Attributes
    ----------
    chart : int
        The rods' chart.
    lo, hi : (n, 6) bounds of (x, y, fx, fy, theta, m_L) of the unit rod over each node.
    child : (n, 2) child nodes (-1 for leaves).
    zc : (n, 3) chart coordinates of the node's centre.
    zh : (n, 3) half extent of the node in chart coordinates.
    q, g : (n, NQ), (n, NQ, 3) the unit rod at the node's centre and its chart gradient
        (evaluated once: a search tests each leaf against many others).
    """

    chart: int
    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    child: NDArray[np.int64]
    zc: NDArray[np.float64]
    zh: NDArray[np.float64]
    q: NDArray[np.float64]
    g: NDArray[np.float64]


def _centre_rods(chart: int, zc: NDArray) -> dict[str, NDArray]:
    from .kernels import eval_rods

    q = np.empty((len(zc), NQ))
    g = np.empty((len(zc), NQ, 3))
    eval_rods(np.full(len(zc), chart, dtype=np.int64), np.ascontiguousarray(zc), q, g)
    return {"q": q, "g": g}


def _build(blo: NDArray, bhi: NDArray, bzc: NDArray, bzh: NDArray, keep: NDArray) -> dict[str, NDArray]:
    """A tree over blocks given by their bounds (nb0, nb1, nb2, 6), centres and half extents
    (nb0, nb1, nb2, 3); blocks with ``keep`` False are left out.

    A node is split in the middle of its longest index range."""
    nb = blo.shape[:3]
    lo_l, hi_l, ch_l, zc_l, zh_l = [], [], [], [], []

    def node(box) -> int:
        (i0, i1), (j0, j1), (k0, k1) = box
        sel = keep[i0:i1, j0:j1, k0:k1]
        if not sel.any():
            return -1
        idx = len(lo_l)
        lo_l.append(None)
        hi_l.append(None)
        ch_l.append((-1, -1))
        zc_l.append(None)
        zh_l.append(None)
        sizes = [i1 - i0, j1 - j0, k1 - k0]
        if max(sizes) == 1:
            lo_l[idx], hi_l[idx] = blo[i0, j0, k0], bhi[i0, j0, k0]
            zc_l[idx], zh_l[idx] = bzc[i0, j0, k0], bzh[i0, j0, k0]
            return idx
        d = int(np.argmax(sizes))
        mid = [(i0 + i1) // 2, (j0 + j1) // 2, (k0 + k1) // 2][d]
        left, right = [list(b) for b in box], [list(b) for b in box]
        left[d][1] = mid
        right[d][0] = mid
        a, b = node(left), node(right)
        kids = [c for c in (a, b) if c >= 0]
        if len(kids) == 1:  # a single child: this node is that child's box
            c = kids[0]
            lo_l[idx], hi_l[idx], zc_l[idx], zh_l[idx], ch_l[idx] = lo_l[c], hi_l[c], zc_l[c], zh_l[c], ch_l[c]
            return idx
        ch_l[idx] = (a, b)
        lo_l[idx] = np.minimum(lo_l[a], lo_l[b])
        hi_l[idx] = np.maximum(hi_l[a], hi_l[b])
        zlo = np.minimum(zc_l[a] - zh_l[a], zc_l[b] - zh_l[b])
        zhi = np.maximum(zc_l[a] + zh_l[a], zc_l[b] + zh_l[b])
        zc_l[idx], zh_l[idx] = 0.5 * (zlo + zhi), 0.5 * (zhi - zlo)
        return idx

    old = sys.getrecursionlimit()
    sys.setrecursionlimit(max(old, 20000))
    try:
        node(((0, nb[0]), (0, nb[1]), (0, nb[2])))
    finally:
        sys.setrecursionlimit(old)
    return {"lo": np.array(lo_l), "hi": np.array(hi_l), "child": np.array(ch_l, dtype=np.int64),
            "zc": np.array(zc_l), "zh": np.array(zh_l)}


def _pad(lo: NDArray, hi: NDArray) -> tuple[NDArray, NDArray]:
    ext = (hi - lo) * PAD + 1e-9
    return lo - ext, hi + ext


def _blocks2(feats: NDArray, z0: NDArray, z1: NDArray, stride: int, skip: NDArray | None = None):
    """Block bounds, chart centres/extents and ``keep`` flags (blocks not wholly ``skip``ped; a
    node of the block kept is enough) of a 2-D grid of rods ``feats`` (n0, n1, 6) with chart
    coordinates ``z0`` (n0,), ``z1`` (n1,), in blocks of ``stride`` x ``stride`` cells."""
    n0, n1 = feats.shape[:2]
    ii = np.arange(0, n0 - 1, stride)
    jj = np.arange(0, n1 - 1, stride)
    blo = np.empty((len(ii), len(jj), 1, 6))
    bhi = np.empty_like(blo)
    bzc = np.zeros((len(ii), len(jj), 1, 3))
    bzh = np.zeros_like(bzc)
    keep = np.ones(blo.shape[:3], bool)
    for a, i in enumerate(ii):
        i1 = min(i + stride, n0 - 1)
        for b, j in enumerate(jj):
            j1 = min(j + stride, n1 - 1)
            block = feats[i:i1 + 1, j:j1 + 1].reshape(-1, 6)
            blo[a, b, 0], bhi[a, b, 0] = _pad(block.min(0), block.max(0))
            bzc[a, b, 0, :2] = 0.5 * (z0[i] + z0[i1]), 0.5 * (z1[j] + z1[j1])
            bzh[a, b, 0, :2] = 0.5 * abs(z0[i1] - z0[i]), 0.5 * abs(z1[j1] - z1[j])
            if skip is not None and np.all(skip[i:i1 + 1, j:j1 + 1]):
                keep[a, b, 0] = False
    return blo, bhi, bzc, bzh, keep


@lru_cache(maxsize=4)
def pinned_tree(max_mode: int, stride: int = 4) -> CellTree:
    """Tree over the pinned rods with leaves of ``stride`` x ``stride`` cells: the atlas (chart
    ``(v, phis)``) and, for the rods near straight under tension it has no nodes for, the seam
    patch (:mod:`flexkin.rod.seam_atlas`) near the taut line (:data:`SEAM_TREE_PSI`).  The seam
    nodes' centres are stored offset-encoded, ``(psi_s, chi + SEAM_OFFSET)``
    (:func:`~flexkin.rod.closed_form.is_seam`), so that one array holds both charts; their rods
    ``q``, ``g`` are in the seam chart."""
    def build():
        A = get_atlas(max_mode)
        feats = np.stack([A.x, A.y, A.R * np.cos(A.psi), A.R * np.sin(A.psi), A.theta, np.zeros_like(A.x)], -1)
        t_uni = _build(*_blocks2(feats, A.v, A.phis, stride))
        S = get_seam_atlas()
        feats = np.stack([S.x, S.y, S.fx, S.fy, S.theta, np.zeros_like(S.x)], -1)
        # only the blocks that meet |psi_s| < SEAM_TREE_PSI: the atlas' leaf boxes bound its rods
        # down to there, not to the taut line (its nodes stop at phis = pi/2 - 1e-3, k' = 1e-6)
        outside = np.broadcast_to((np.abs(S.psi_s) >= SEAM_TREE_PSI)[:, None], S.x.shape)
        t_seam = _build(*_blocks2(feats, S.psi_s, S.chi + SEAM_OFFSET, stride, outside))
        return _merge(t_uni, t_seam)

    def build_all():
        t = build()
        seam = is_seam(t["zc"][:, 1])
        zc = t["zc"].copy()
        zc[seam, 1] -= SEAM_OFFSET
        q = np.empty((len(zc), NQ))
        g = np.empty((len(zc), NQ, 3))
        for chart, sel in ((CHART_UNIFIED, ~seam), (CHART_SEAM, seam)):
            r = _centre_rods(chart, zc[sel])
            q[sel], g[sel] = r["q"], r["g"]
        t.update(q=q, g=g)
        return t

    key = (max_mode, stride, PAD, "q", "seam", SEAM_TREE_PSI, T_MAX, "margin", MODE_MARGIN)
    t = cached_arrays("pinned-tree", key, build_all)
    return CellTree(CHART_UNIFIED, t["lo"], t["hi"], t["child"], t["zc"], t["zh"], t["q"], t["g"])


def _merge(t1: dict[str, NDArray], t2: dict[str, NDArray]) -> dict[str, NDArray]:
    """Two trees under one new root."""
    n1 = len(t1["lo"])
    child2 = np.where(t2["child"] >= 0, t2["child"] + n1 + 1, -1)
    child1 = np.where(t1["child"] >= 0, t1["child"] + 1, -1)
    zlo = np.minimum(t1["zc"][0] - t1["zh"][0], t2["zc"][0] - t2["zh"][0])
    zhi = np.maximum(t1["zc"][0] + t1["zh"][0], t2["zc"][0] + t2["zh"][0])
    return {"lo": np.concatenate([np.minimum(t1["lo"][:1], t2["lo"][:1]), t1["lo"], t2["lo"]]),
            "hi": np.concatenate([np.maximum(t1["hi"][:1], t2["hi"][:1]), t1["hi"], t2["hi"]]),
            "child": np.concatenate([[[1, n1 + 1]], child1, child2]).astype(np.int64),
            "zc": np.concatenate([[0.5 * (zlo + zhi)], t1["zc"], t2["zc"]]),
            "zh": np.concatenate([[0.5 * (zhi - zlo)], t1["zh"], t2["zh"]])}
