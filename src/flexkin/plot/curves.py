"""Geometric-condition curves of the inverse kinematics (paper Fig. 7).

Readability rules: the legend of every panel lists the d-modes drawn in that panel, in
increasing order, then the solutions' marker (no entry without a curve); solutions whose dots
fall within a few pixels of each other share one label listing their ids (``1, 4–9``); labels
are placed where they overlap no other label (and no dot), with a leader line when moved away
from their dot; a cluster that finds no free place is listed under the panel instead.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .style import mode_color, new_figure, save

__all__ = ["plot_curves", "id_ranges"]

_KIND = {"prismatic": "prismatic (y = h)", "revolute": "revolute (x² + y² = r²)", "length": "length (y/x = tan β)"}
#: dots closer than this (pixels) share one label
_CLUSTER_PX = 9.0
#: longer id lists are labelled with a key and listed under the panel
_MAX_LABEL = 22
#: candidate label offsets (points) tried in order: close around the dot first, then further out
_OFFSETS = [(dx * r, dy * r) for r in (6, 14, 24, 36, 50)
            for dx, dy in ((1, 1), (1, -1), (-1, 1), (-1, -1), (0, 1.2), (0, -1.2), (1.3, 0), (-1.3, 0))]


def id_ranges(ids: list[int], limit: int = 8) -> str:
    """``[1, 2, 3, 5, 9, 10]`` -> ``"1–3, 5, 9–10"``; more than ``limit`` runs end with ``"…"``.

    Parameters
    ----------
    ids : list of int
        Solution ids.
    limit : int
        Most runs shown.

    Returns
    -------
    str
    """
    ids = sorted(set(int(i) for i in ids))
    runs: list[tuple[int, int]] = []
    for i in ids:
        if runs and i == runs[-1][1] + 1:
            runs[-1] = (runs[-1][0], i)
        else:
            runs.append((i, i))
    parts = [str(a) if a == b else f"{a}–{b}" for a, b in runs]
    if len(parts) > limit:
        parts = parts[:limit] + ["…"]
    return ", ".join(parts)


def _clusters(px: np.ndarray) -> list[list[int]]:
    """Greedy single-linkage clusters of display points closer than ``_CLUSTER_PX``."""
    n = len(px)
    parent = list(range(n))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a in range(n):
        d = np.hypot(*(px[a + 1:] - px[a]).T) if a + 1 < n else np.zeros(0)
        for b in np.flatnonzero(d < _CLUSTER_PX) + a + 1:
            parent[find(int(b))] = find(a)
    groups: dict[int, list[int]] = {}
    for a in range(n):
        groups.setdefault(find(a), []).append(a)
    return list(groups.values())


def _overlaps(bb, boxes) -> bool:
    return any(bb.x0 < b.x1 and b.x0 < bb.x1 and bb.y0 < b.y1 and b.y0 < bb.y1 for b in boxes)


def _label_panel(fig, ax, pts: np.ndarray, ids: list[int]) -> list[str]:
    """Place one label per cluster of dots without overlaps; returns the footnotes: the full id
    lists of crowded clusters (labelled ``A (14)`` in the panel) and of clusters that found no
    free place."""
    from matplotlib.transforms import Bbox

    if not len(pts):
        return []
    renderer = fig.canvas.get_renderer()
    px = ax.transData.transform(pts)
    axbox = ax.get_window_extent(renderer)
    taken = [Bbox.from_extents(x - 3, y - 3, x + 3, y + 3) for x, y in px]  # the dots
    notes: list[str] = []
    order = sorted(_clusters(px), key=lambda c: (-len(c), min(ids[m] for m in c)))
    key = iter("ABCDEFGHIJKLMNOPQRSTUVWXYZ")
    for members in order:
        full = id_ranges([ids[m] for m in members], limit=10**6)
        text = full
        if len(full) > _MAX_LABEL:
            k = next(key, "*")
            text = f"{k} ({len(members)})"
            notes.append(f"{k}: {full}")
        anchor = pts[members].mean(axis=0)
        placed = False
        for dx, dy in _OFFSETS:
            ha = "left" if dx > 0 else ("right" if dx < 0 else "center")
            va = "bottom" if dy > 0 else ("top" if dy < 0 else "center")
            far = abs(dx) > 8 or abs(dy) > 8
            t = ax.annotate(text, anchor, xytext=(dx, dy), textcoords="offset points", fontsize=6.5, ha=ha, va=va,
                            arrowprops=dict(arrowstyle="-", lw=0.5, color="0.4", shrinkA=0, shrinkB=2) if far
                            else None, zorder=6)
            bb = t.get_window_extent(renderer).expanded(1.05, 1.15)
            inside = (bb.x0 >= axbox.x0 and bb.x1 <= axbox.x1 and bb.y0 >= axbox.y0 and bb.y1 <= axbox.y1)
            if inside and not _overlaps(bb, taken):
                taken.append(bb)
                placed = True
                break
            t.remove()
        if not placed and text == full:
            notes.append(f"at ({anchor[0]:.0f}°, {anchor[1]:.2f}): {full}")
        elif not placed:
            notes[-1] = f"{notes[-1]} (at ({anchor[0]:.0f}°, {anchor[1]:.2f}))"
    return notes


def plot_curves(result, path: str | None = None) -> Any:
    """Per leg, the curves in the rectangular ``(k_r, psi)`` space, coloured by d-mode.

    The IK solutions of ``result`` are marked on them and labelled with their ids (as in
    ``result.table()``; solutions at the same point share a label).

    Parameters
    ----------
    result : KinematicsResult
        An IK result (its legs' curves are computed again).
    path : str, optional
        Save the figure there.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.lines import Line2D

    from ..rod.closed_form import kr_from_k

    fig = new_figure(figsize=(13, 4.8), layout="constrained")
    axes = fig.subplots(1, 3, sharey=True)
    panels = []
    for leg, ax in zip(result.curves, axes):
        drawn: set[int] = set()
        for br in leg.branches:
            mode = br["mode"]
            psi_d, kr = np.degrees(br["psi"]), np.asarray(br["kr"])
            # split the polyline where the d-mode or the k_r side changes (k_r jumps across 0)
            cut = np.flatnonzero((np.diff(mode) != 0) | (np.diff(np.sign(kr)) != 0)) + 1
            for seg_idx in np.split(np.arange(len(mode)), cut):
                if len(seg_idx) < 2:
                    continue
                x, y = psi_d[seg_idx], kr[seg_idx]
                vis = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (x <= 360) & (np.abs(y) <= 1.02)
                if np.count_nonzero(vis) < 2:
                    continue
                q = int(mode[seg_idx[0]])
                drawn.add(q)
                ax.plot(x, y, color=mode_color(q), lw=1.4)
        pts, ids = [], []
        for s in result.solutions:
            r = s.rods[leg.leg]
            pts.append((float(np.degrees(r.psi)), float(kr_from_k(r.k, r.psi))))
            ids.append(int(s.id))
        pts_a = np.asarray(pts, dtype=float).reshape(-1, 2)
        if len(pts_a):
            ax.plot(pts_a[:, 0], pts_a[:, 1], "ko", ms=3.5, zorder=5)
        ax.set_xlim(0, 360)
        ax.set_ylim(-1.08, 1.08)
        ax.set_xlabel("ψ [deg]")
        ax.set_title(f"leg {leg.leg + 1}: {_KIND.get(leg.actuation, leg.actuation)}", fontsize=9)
        ax.grid(True, lw=0.4, alpha=0.5)
        handles = [Line2D([], [], color=mode_color(q), lw=1.4, label=f"d-mode {q}") for q in sorted(drawn)]
        if len(pts_a):
            handles.append(Line2D([], [], color="k", marker="o", ms=3.5, ls="none", label="IK solution (id)"))
        if handles:
            ax.legend(handles=handles, fontsize=7, loc="center left")
        panels.append((ax, pts_a, ids))
    axes[0].set_ylabel("k_r")
    g = result.given
    fig.suptitle(f"{result.mechanism.name}: geometric-condition curves at pose ({g[0]:.4g} m, {g[1]:.4g} m, "
                 f"{np.degrees(g[2]):.4g}°); dots: IK solutions, labelled with their ids", fontsize=10)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)  # a renderer to measure text with (the figure is not attached to pyplot)
    fig.canvas.draw()  # fix the layout before measuring the labels
    fig.set_layout_engine("none")
    import textwrap

    for ax, pts_a, ids in panels:
        notes = _label_panel(fig, ax, pts_a, ids)
        if notes:
            ax.text(0.0, -0.13, "\n".join(textwrap.fill(n, 95) for n in notes), transform=ax.transAxes,
                    fontsize=6, va="top", ha="left")
    if path:
        save(fig, path)
    return fig
