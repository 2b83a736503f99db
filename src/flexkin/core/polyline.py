"""Planar polyline geometry, vectorised numpy: point-segment and segment-segment distances,
proper crossings, polyline-polyline and self crossings with a bounding-box prefilter, a
polyline against a triangle, and the truncation of a polyline sampled in arc length.

The feasibility checks (:mod:`flexkin.analysis.feasibility`) use it on the rods' centre lines.
Written here rather than taken from shapely (not a dependency): the checks need the count of
crossing segment pairs, touches within an absolute tolerance, self-crossings of segments at
least ``min_gap`` apart and a triangle's interior with a tolerance, which shapely's predicates
(``intersects``, ``distance``, ``is_simple``) do not give directly.

All geometry is vectorised numpy.  Segment pairs are found with a two-level bounding-box
prefilter (:func:`polyline_crossings`): blocks of 8 consecutive segments whose boxes are
further apart than an upper bound of the distance (or than the contact threshold) are never
compared segment by segment; the remaining pairs get the exact segment–segment distance
(the smallest of four point–segment distances, or 0 for a proper crossing by orientation
tests).  The result equals brute force.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "point_segment_distances",
    "polyline_crossings",
    "polyline_platform",
    "segment_distances",
    "self_crossings",
    "truncate",
]


def point_segment_distances(points: ArrayLike, starts: ArrayLike, ends: ArrayLike) -> NDArray[np.float64]:
    """Distances from every point to every segment.

    Parameters
    ----------
    points : array_like, shape (P, 2)
    starts, ends : array_like, shape (S, 2)
        Segment end points (a zero-length segment is a point).

    Returns
    -------
    ndarray, shape (P, S)
    """
    p = np.asarray(points, dtype=float)
    a = np.asarray(starts, dtype=float)
    d = np.asarray(ends, dtype=float) - a
    len2 = d[:, 0] ** 2 + d[:, 1] ** 2
    wx = p[:, None, 0] - a[None, :, 0]
    wy = p[:, None, 1] - a[None, :, 1]
    safe = np.where(len2 > 0.0, len2, 1.0)
    t = np.clip((wx * d[None, :, 0] + wy * d[None, :, 1]) / safe, 0.0, 1.0)
    t = np.where(len2 > 0.0, t, 0.0)
    return np.hypot(wx - t * d[None, :, 0], wy - t * d[None, :, 1])


def _proper_crossings(p1: NDArray, p2: NDArray, q1: NDArray, q2: NDArray, tol: float = 0.0) -> NDArray[np.bool_]:
    """Whether segments ``p1p2`` and ``q1q2`` (row-wise, shape (K, 2)) cross at one interior point.

    With ``tol > 0`` the end points of each segment must lie further than ``tol`` from the
    other segment's line (an end point lying on the other segment is a touch, not a crossing).
    """
    ex, ey = p2[:, 0] - p1[:, 0], p2[:, 1] - p1[:, 1]
    fx, fy = q2[:, 0] - q1[:, 0], q2[:, 1] - q1[:, 1]
    d1 = ex * (q1[:, 1] - p1[:, 1]) - ey * (q1[:, 0] - p1[:, 0])
    d2 = ex * (q2[:, 1] - p1[:, 1]) - ey * (q2[:, 0] - p1[:, 0])
    d3 = fx * (p1[:, 1] - q1[:, 1]) - fy * (p1[:, 0] - q1[:, 0])
    d4 = fx * (p2[:, 1] - q1[:, 1]) - fy * (p2[:, 0] - q1[:, 0])
    e = tol * np.hypot(ex, ey)  # |d1|, |d2| = |p2 - p1| * distance of q1, q2 to the line p1p2
    f = tol * np.hypot(fx, fy)
    return ((((d1 > e) & (d2 < -e)) | ((d1 < -e) & (d2 > e)))
            & (((d3 > f) & (d4 < -f)) | ((d3 < -f) & (d4 > f))))


def _bbox_overlap(P: NDArray, Q: NDArray, pad: float) -> NDArray[np.bool_]:
    """(n-1, m-1) mask of segment pairs of polylines P, Q whose bounding boxes (grown by ``pad``) overlap."""
    plo, phi = np.minimum(P[:-1], P[1:]) - pad, np.maximum(P[:-1], P[1:]) + pad
    qlo, qhi = np.minimum(Q[:-1], Q[1:]), np.maximum(Q[:-1], Q[1:])
    return ((plo[:, None, 0] <= qhi[None, :, 0]) & (qlo[None, :, 0] <= phi[:, None, 0])
            & (plo[:, None, 1] <= qhi[None, :, 1]) & (qlo[None, :, 1] <= phi[:, None, 1]))


def segment_distances(P: ArrayLike, Q: ArrayLike, *, tol: float = 0.0) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Distance between every segment of polyline ``P`` and every segment of polyline ``Q``.

    In the plane, two segments that do not cross are closest at an end point of one of them,
    so the distance is the smallest of four point–segment distances, or 0 for a proper
    crossing.  Proper crossings are tested only where the segments' bounding boxes overlap.

    Parameters
    ----------
    P : array_like, shape (n, 2)
    Q : array_like, shape (m, 2)
        Polyline vertices (n, m >= 2).
    tol : float, optional
        A crossing is proper only if every end point lies further than ``tol`` from the other
        segment's line (see :func:`_proper_crossings`).

    Returns
    -------
    dist : ndarray, shape (n-1, m-1)
        Segment–segment distances (0 where they cross).
    crossing : ndarray of bool, shape (n-1, m-1)
        Proper crossings (one common interior point).
    """
    P = np.asarray(P, dtype=float)
    Q = np.asarray(Q, dtype=float)
    dpq = point_segment_distances(P, Q[:-1], Q[1:])  # (n, m-1)
    dqp = point_segment_distances(Q, P[:-1], P[1:])  # (m, n-1)
    dist = np.minimum(np.minimum(dpq[:-1], dpq[1:]), np.minimum(dqp[:-1], dqp[1:]).T)
    ii, jj = np.nonzero(_bbox_overlap(P, Q, 0.0))
    crossing = np.zeros(dist.shape, dtype=bool)
    if ii.size:
        hit = _proper_crossings(P[ii], P[ii + 1], Q[jj], Q[jj + 1], tol)
        crossing[ii[hit], jj[hit]] = True
        dist[ii[hit], jj[hit]] = 0.0
    return dist, crossing


def _d2_point_segment(px: NDArray, py: NDArray, ax: NDArray, ay: NDArray,
                      bx: NDArray, by: NDArray) -> NDArray[np.float64]:
    """Squared distance from points (px, py) to segments (a, b), component arrays (broadcast)."""
    ux, uy = bx - ax, by - ay
    wx, wy = px - ax, py - ay
    l2 = ux * ux + uy * uy
    t = (wx * ux + wy * uy) / np.where(l2 > 0.0, l2, 1.0)  # numerator is 0 when l2 == 0
    np.clip(t, 0.0, 1.0, out=t)
    ex, ey = wx - t * ux, wy - t * uy
    return ex * ex + ey * ey


def _segment_pairs(P: NDArray, Q: NDArray, i: NDArray, j: NDArray) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Distances and proper crossings of segments ``P[i]P[i+1]`` and ``Q[j]Q[j+1]`` (1-D index arrays)."""
    ax, ay, bx, by = P[i, 0], P[i, 1], P[i + 1, 0], P[i + 1, 1]
    cx, cy, dx, dy = Q[j, 0], Q[j, 1], Q[j + 1, 0], Q[j + 1, 1]
    d2 = np.minimum(np.minimum(_d2_point_segment(ax, ay, cx, cy, dx, dy), _d2_point_segment(bx, by, cx, cy, dx, dy)),
                    np.minimum(_d2_point_segment(cx, cy, ax, ay, bx, by), _d2_point_segment(dx, dy, ax, ay, bx, by)))
    cross = _proper_crossings(np.stack([ax, ay], -1), np.stack([bx, by], -1),
                              np.stack([cx, cy], -1), np.stack([dx, dy], -1))
    return np.where(cross, 0.0, np.sqrt(d2)), cross


def _block_boxes(P: NDArray, block: int) -> tuple[NDArray, NDArray]:
    """Bounding boxes (lo, hi), each (n_blocks, 2), of consecutive runs of ``block`` segments."""
    starts = np.arange(0, len(P) - 1, block)
    lo = np.minimum.reduceat(np.minimum(P[:-1], P[1:]), starts, axis=0)
    hi = np.maximum.reduceat(np.maximum(P[:-1], P[1:]), starts, axis=0)
    return lo, hi


def _distance_bound(P: NDArray, Q: NDArray, *, same: bool, min_gap: int, block: int) -> float:
    """Upper bound of the (gap-restricted) polyline distance from a subsample of vertex pairs.

    Vertices ``k`` of P and ``l`` of Q lie on segments that may be compared (``j - i >=
    min_gap`` with ``i in {k-1, k}``, ``j in {l-1, l}`` when ``same``) iff ``l - k >= min_gap - 1``.
    """
    kp = np.unique(np.r_[np.arange(0, len(P), block), len(P) - 1])
    kq = np.unique(np.r_[np.arange(0, len(Q), block), len(Q) - 1])
    dv = np.hypot(P[kp, None, 0] - Q[None, kq, 0], P[kp, None, 1] - Q[None, kq, 1])
    if same:
        dv = np.where(kq[None, :] - kp[:, None] >= min_gap - 1, dv, np.inf)
    return float(dv.min()) if dv.size else math.inf


def _candidate_pairs(P: NDArray, Q: NDArray, *, same: bool, min_gap: int, within: float,
                     block: int = 8) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Segment pairs ``(i, j)`` that may be closer than ``within`` (bounding-box prefilter).

    Blocks of ``block`` consecutive segments whose bounding boxes are further apart than
    ``within`` are never compared segment by segment.  With ``same`` (one polyline), only
    ``i < j`` with ``j - i >= min_gap``.
    """
    nP, nQ = len(P) - 1, len(Q) - 1
    plo, phi = _block_boxes(P, block)
    qlo, qhi = _block_boxes(Q, block)
    gx = np.maximum(np.maximum(qlo[None, :, 0] - phi[:, None, 0], plo[:, None, 0] - qhi[None, :, 0]), 0.0)
    gy = np.maximum(np.maximum(qlo[None, :, 1] - phi[:, None, 1], plo[:, None, 1] - qhi[None, :, 1]), 0.0)
    cand = np.hypot(gx, gy) <= within * (1.0 + 1e-9)  # margin: the bound itself must pass
    if same:
        a0 = np.arange(len(plo)) * block
        b1 = np.minimum((np.arange(len(qlo)) + 1) * block, nQ) - 1
        cand &= (b1[None, :] - a0[:, None]) >= min_gap
    A, Bq = np.nonzero(cand)
    off = np.arange(block)
    i = np.broadcast_to((A[:, None] * block + off)[:, :, None], (len(A), block, block))
    j = np.broadcast_to((Bq[:, None] * block + off)[:, None, :], (len(A), block, block))
    valid = (i < nP) & (j < nQ)
    if same:
        valid &= (j - i) >= min_gap
    return i[valid], j[valid]


def polyline_crossings(P: ArrayLike, Q: ArrayLike, *, touch: float = 0.0) -> tuple[int, float]:
    """Number of crossing segment pairs and distance between two polylines.

    Bounding-box prefilter in two levels: an upper bound ``U`` of the distance from a
    subsample of vertex pairs, then only blocks of 8 consecutive segments whose bounding
    boxes are within ``max(U, touch)`` are compared segment by segment; they hold every
    crossing and the closest pair, so the result equals the brute-force one.

    Parameters
    ----------
    P, Q : array_like, shapes (n, 2), (m, 2)
        Polylines (n, m >= 2).
    touch : float
        Segment pairs closer than this (without a proper crossing) count as crossings too
        (T-contacts, collinear overlaps).

    Returns
    -------
    crossings : int
        Number of segment pairs that cross or touch.
    distance : float
        Smallest distance between the polylines (0 if they cross).
    """
    P = np.asarray(P, dtype=float)
    Q = np.asarray(Q, dtype=float)
    U = _distance_bound(P, Q, same=False, min_gap=0, block=8)
    i, j = _candidate_pairs(P, Q, same=False, min_gap=0, within=max(U, float(touch)))
    d, cross = _segment_pairs(P, Q, i, j)
    hits = cross | (d <= touch)
    return int(np.count_nonzero(hits)), (float(d.min()) if d.size else math.inf)


def self_crossings(P: ArrayLike, *, min_gap: int = 2, touch: float = 0.0,
                   within: float | None = None) -> tuple[int, float]:
    """Self-crossings of a polyline: segments ``i < j`` with ``j - i >= min_gap``.

    Parameters
    ----------
    P : array_like, shape (n, 2)
    min_gap : int
        Smallest index difference of compared segments (>= 2: adjacent segments share a
        vertex and are never compared).
    touch : float
        Distance below which two compared segments count as touching.
    within : float, optional
        Only distances up to this value are needed (faster: fewer pairs compared); by
        default the exact smallest distance is returned.

    Returns
    -------
    crossings : int
        Number of compared segment pairs that cross or touch (a simple loop gives 1).
    distance : float
        Smallest distance between compared segments (0 if two cross; ``inf`` if none are
        compared or, with ``within``, if none is within it).
    """
    P = np.asarray(P, dtype=float)
    gap = max(int(min_gap), 2)
    if within is None:
        within = _distance_bound(P, P, same=True, min_gap=gap, block=8)
    i, j = _candidate_pairs(P, P, same=True, min_gap=gap, within=max(float(within), float(touch)))
    d, cross = _segment_pairs(P, P, i, j)
    hits = cross | (d <= touch)
    return int(np.count_nonzero(hits)), (float(d.min()) if d.size else math.inf)


def polyline_platform(P: ArrayLike, triangle: ArrayLike, *, tol: float = 0.0) -> tuple[bool, float]:
    """Whether a polyline enters a triangle's interior, and its distance to the triangle.

    Parameters
    ----------
    P : array_like, shape (n, 2)
        Polyline (n >= 1).
    triangle : array_like, shape (3, 2)
        Vertices, either orientation.
    tol : float
        A vertex counts as inside only if it is further than ``tol`` from every edge, and a
        segment crosses an edge only if its end points are further than ``tol`` from the
        edge's line and vice versa (so a rod ending on the boundary does not cross it).

    Returns
    -------
    inside : bool
        A vertex of ``P`` strictly inside, or a segment properly crossing an edge (such a
        segment passes through the interior next to the crossing point).
    distance : float
        0 if ``inside``, else the distance between the polyline and the (closed) triangle.
    """
    P = np.asarray(P, dtype=float).reshape(-1, 2)
    T = np.asarray(triangle, dtype=float)
    e = np.roll(T, -1, axis=0) - T  # edges T_k -> T_k+1
    area2 = e[0, 0] * e[1, 1] - e[0, 1] * e[1, 0]
    sign = 1.0 if area2 > 0 else -1.0  # make the interior the left side of every edge
    elen = np.hypot(e[:, 0], e[:, 1])
    sd = sign * (e[None, :, 0] * (P[:, None, 1] - T[None, :, 1])
                 - e[None, :, 1] * (P[:, None, 0] - T[None, :, 0])) / elen[None, :]
    if np.any(np.min(sd, axis=1) > tol):
        return True, 0.0
    if len(P) >= 2:
        Tc = np.vstack([T, T[:1]])
        dist, crossing = segment_distances(P, Tc, tol=tol)
        if crossing.any():
            return True, 0.0
        return False, float(dist.min())
    return False, float(point_segment_distances(P, T, np.roll(T, -1, axis=0)).min())


def truncate(P: NDArray[np.float64], length: float, cut: float) -> NDArray[np.float64]:
    """The part ``s <= length - cut`` of a polyline sampled uniformly in arc length.

    Parameters
    ----------
    P : ndarray, shape (n, 2)
        Vertices at arc lengths ``linspace(0, length, n)``.
    length : float
        Arc length of the polyline.
    cut : float
        Arc length removed at the end.

    Returns
    -------
    ndarray, shape (k, 2)
        The vertices up to ``length - cut`` and the interpolated end point (the first vertex
        alone when nothing is left).
    """
    s_end = length - cut
    if s_end <= 0.0:
        return P[:1]
    s = np.linspace(0.0, length, len(P))
    k = int(np.searchsorted(s, s_end, side="right"))  # samples 0..k-1 have s <= s_end
    if k >= len(P):
        return P
    w = (s_end - s[k - 1]) / (s[k] - s[k - 1])
    end = (1.0 - w) * P[k - 1] + w * P[k]
    return np.vstack([P[:k], end[None]])
