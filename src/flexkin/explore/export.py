"""Exports of the explorer's current state: the figure (PNG / SVG, drawn by the library's
matplotlib functions), the solution set (the SPEC §4 JSON object of the full solve) and the rod
shapes (CSV).  No web import."""

from __future__ import annotations

import csv
import io
import json
from typing import Any

import numpy as np

from .state import ExplorerState

__all__ = ["CSV_COLUMNS", "EXPORTS", "export", "figure_bytes", "rods_csv", "solutions_json"]

#: Columns of the rod-shape CSV: solution id, leg (1-3), arc length s (m), x, y (world, m),
#: tangent angle theta (deg, SPEC: degrees in files), bending moment (N m).
CSV_COLUMNS = ("solution", "leg", "s", "x", "y", "theta_deg", "moment")
#: Points per rod in the CSV.
CSV_POINTS = 101
#: file name -> media type of the downloads the app offers
EXPORTS = {
    "figure.png": "image/png",
    "figure.svg": "image/svg+xml",
    "solutions.json": "application/json",
    "rods.csv": "text/csv",
}


def _listed(state: ExplorerState) -> list[Any]:
    """The equilibria the user sees listed: the full solve's, or the tracked one during a drag."""
    if state.solutions:
        return list(state.solutions)
    if state.selected is not None:
        return [state.selected]
    return []


def solutions_json(state: ExplorerState) -> str:
    """The current solution set as the SPEC §4 JSON object (``res.to_dict(feasibility=True)``)
    of the last full solve; ``{"solutions": []}`` with a message when there is none."""
    res = state.result
    if res is None:
        d: dict[str, Any] = {"problem": state.mode, "mechanism": state.mech.name, "load": list(state.load),
                             "max_mode": state.max_mode, "complete": False, "message": state.error,
                             "solutions": []}
    else:
        d = res.to_dict(feasibility=True)
    return json.dumps(d, indent=2, allow_nan=False)


def rods_csv(state: ExplorerState, n: int = CSV_POINTS) -> str:
    """Rod shapes of the listed equilibria as CSV with :data:`CSV_COLUMNS`; ``n`` points per rod
    (:meth:`RodState.profile`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for s in _listed(state):
        for leg, r in enumerate(s.rods, 1):
            p = r.profile(n)
            th = np.degrees(p["theta"])
            for k in range(n):
                w.writerow((s.id, leg, repr(float(p["s"][k])), repr(float(p["x"][k])), repr(float(p["y"][k])),
                            repr(float(th[k])), repr(float(p["moment"][k]))))
    return buf.getvalue()


def figure_bytes(state: ExplorerState, fmt: str = "png", workspace: Any = None) -> bytes:
    """The current drawing as a matplotlib figure (``plot_mechanism`` for the selected, else
    the first, equilibrium; the other drawn equilibria thin in their d-mode colours; the
    workspace overlay when given), encoded as ``fmt`` (``"png"`` or ``"svg"``)."""
    if fmt not in ("png", "svg"):
        raise ValueError(f"figure format must be png or svg, got {fmt!r}")
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon

    from flexkin.plot.mechanism import plot_mechanism
    from flexkin.plot.style import mode_color

    fig = Figure(figsize=(7.0, 6.4), layout="constrained")
    ax = fig.add_subplot()
    vis = state.visible()
    main = next((s for s, sel in vis if sel), None) or (vis[0][0] if vis else None)
    if workspace is not None:
        _draw_workspace(ax, workspace)
    for s, _ in vis:
        if s is main:
            continue
        ls = "-" if s.stable is True else "--"
        for r in s.rods:
            xy = r.shape(60)
            ax.plot(xy[:, 0], xy[:, 1], color=mode_color(s.mode_label), lw=0.8, ls=ls, alpha=0.45, zorder=3)
        if state.mode == "fk":
            B = state.mech.platform.world(s.pose)
            ax.add_patch(Polygon(B, closed=True, fc="none", ec="#08519c", lw=0.8, alpha=0.4, zorder=3))
    where = state.where_display()
    if state.mode == "ik":
        what = f"IK at ({where[0]:.4g} m, {where[1]:.4g} m, {where[2]:.4g} deg)"
    else:
        what = "FK at (" + ", ".join(f"{v:.4g} {leg.input_unit}" for v, leg in zip(where, state.mech.legs)) + ")"
    n = len(_listed(state))
    if main is not None:
        st = {True: "stable", False: "unstable", None: "undecided"}[main.stable]
        title = (f"{state.mech.name}: {what}\n{n} equilibri{'um' if n == 1 else 'a'}; "
                 f"#{main.id} bold: d-modes {main.mode_label}, {st}")
        plot_mechanism(state.mech, pose=main.pose, rods=[r.shape(120) for r in main.rods], ax=ax,
                       inputs=main.inputs, title=title)
    else:
        pose = state.pose if state.mode == "ik" else None
        plot_mechanism(state.mech, pose=pose, ax=ax, title=f"{state.mech.name}: {what}\nno equilibrium here")
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=150)
    return buf.getvalue()


def _draw_workspace(ax, ws) -> None:
    from flexkin.plot.workspace import FK_COLOR, IK_COLOR

    mp = ws.maps[0]
    x, y = np.asarray(ws.x), np.asarray(ws.y)
    reached = np.asarray(mp.reached, dtype=float)
    ax.contourf(x, y, reached, levels=[0.5, 1.5], colors=["#9ecae1"], alpha=0.35, zorder=0.5)
    for grid, col in ((mp.boundary_ik, IK_COLOR), (mp.boundary_fk, FK_COLOR)):
        jj, ii = np.nonzero(np.asarray(grid))
        if len(ii):
            ax.plot(x[ii], y[jj], ls="none", marker="s", ms=1.5, color=col, zorder=0.8)


def export(state: ExplorerState, name: str, workspace: Any = None) -> tuple[bytes, str]:
    """``(content, media type)`` of the download ``name`` (a key of :data:`EXPORTS`)."""
    if name not in EXPORTS:
        raise KeyError(name)
    if name == "figure.png":
        data = figure_bytes(state, "png", workspace)
    elif name == "figure.svg":
        data = figure_bytes(state, "svg", workspace)
    elif name == "solutions.json":
        data = solutions_json(state).encode()
    else:
        data = rods_csv(state).encode()
    return data, EXPORTS[name]

