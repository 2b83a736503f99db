"""Constant-orientation workspace maps (paper Fig. 17): every aspect, same axes, same colours.

One panel per aspect (the region reached by continuation from one stable IK solution at the
seed pose) and per orientation, one row of panels per orientation; every panel has the same
axes (the union of all regions) and the same colours (one per d-mode combination,
:func:`~flexkin.plot.style.mode_color`, or one colour scale for a quantity).  Figures with more
than ``per_page`` panels are split into pages (``name.png``, ``name_2.png``, ...).

Boundary cells: IK singularity (black), FK singularity / instability (orange), unresolved
(grey: a rod straight under tension), infeasible (purple: a neighbour is out of a leg's range,
over the strain limit or colliding, :attr:`WorkspaceMap.boundary_infeasible`) and grid edge
(blue: the region reaches the grid's bounds, so it is cut there, ``boundary_edge``).  Reached
cells that are themselves infeasible (``violations``, unconstrained maps) are hatched.  The
figure's title names the region measured (:attr:`Workspace.region`: all stable equilibria
reached, or feasible only) and every panel its area.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .solutions import page_paths
from .style import mode_color, new_figure, save

__all__ = ["plot_workspace", "plot_workspace_pages", "write_workspace_pages", "grid_edge_cells"]

IK_COLOR = "black"
FK_COLOR = "#ff7f0e"
SEAM_COLOR = "#9a9a9a"
INFEASIBLE_COLOR = "#7b2cbf"
EDGE_COLOR = "#1f5fbf"
#: most panels on one page
PANELS_PER_PAGE = 20
_NOTE = ("Each panel: one aspect = the region reached by continuation from one stable IK solution at the seed "
         "(ids as in 'flexkin ik' at the seed pose); same axes and colours in every panel.")


def _quantity(mp, color_by: str, kinds) -> tuple[np.ndarray, str]:
    if color_by == "margin":
        return mp.margin, "stability margin"
    if color_by == "cond":
        return np.log10(np.where(np.isfinite(mp.cond), mp.cond, np.nan)), "log10 cond(J)"
    if color_by.startswith("input"):
        i = int(color_by[5:]) - 1
        if not 0 <= i < 3:
            raise ValueError(f"color_by {color_by!r}: expected input1, input2 or input3")
        u = mp.inputs[..., i]
        if kinds[i] == "revolute":
            return np.degrees(u), f"u{i + 1} [deg]"
        return u, f"u{i + 1} [m]"
    raise ValueError(f"color_by must be 'modes', 'margin', 'cond' or 'inputN', got {color_by!r}")


def grid_edge_cells(mp) -> np.ndarray:
    """Reached cells on the grid's edge (the core's ``boundary_edge`` when the map has it)."""
    edge = getattr(mp, "boundary_edge", None)
    if edge is not None:
        return np.asarray(edge, dtype=bool)
    r = mp.reached
    out = np.zeros_like(r)
    out[0, :], out[-1, :], out[:, 0], out[:, -1] = r[0, :], r[-1, :], r[:, 0], r[:, -1]
    return out


def _labels(mp) -> np.ndarray:
    return np.array(["".join(map(str, q)) for q in mp.modes.reshape(-1, 3)]).reshape(mp.status.shape)


def _panels(workspaces: Sequence[Any], aspect: int | None, overlay: bool) -> list[tuple[int, Any, tuple[int, ...]]]:
    """(workspace index, workspace, map indices) per panel."""
    out = []
    for w, ws in enumerate(workspaces):
        n = len(ws.maps)
        if overlay or n == 0:
            out.append((w, ws, tuple(range(n))))
        elif aspect is not None:
            out.append((w, ws, (aspect,) if aspect < n else ()))
        else:
            out.extend((w, ws, (k,)) for k in range(n))
    return out


def _extent(workspaces) -> tuple[float, float, float, float]:
    """Common axes: the union of every reached cell, padded; the grids' box if none is reached."""
    xs, ys, hs = [], [], []
    for ws in workspaces:
        hs.append(ws.step or 1.0)
        u = ws.union()
        if u.any():
            jj, ii = np.nonzero(u)
            xs += [ws.x[ii].min(), ws.x[ii].max()]
            ys += [ws.y[jj].min(), ws.y[jj].max()]
    h = max(hs) if hs else 1.0
    if not xs:
        xs = [min(ws.x[0] for ws in workspaces), max(ws.x[-1] for ws in workspaces)]
        ys = [min(ws.y[0] for ws in workspaces), max(ws.y[-1] for ws in workspaces)]
    pad = 4 * h
    return min(xs) - pad, max(xs) + pad, min(ys) - pad, max(ys) + pad


def plot_workspace_pages(workspaces: Sequence[Any], color_by: str = "modes", ncols: int | None = None,
                         aspect: int | None = None, overlay: bool = False,
                         per_page: int = PANELS_PER_PAGE, notes: dict[tuple[int, int], str] | None = None) -> list[Any]:
    """The Figures (pages) of :func:`plot_workspace` (same parameters, without ``path``).

    Parameters
    ----------
    workspaces : sequence of Workspace
        One per orientation.
    color_by : str
        ``"modes"``, ``"margin"``, ``"cond"`` or ``"input1"``..``"input3"``.
    ncols : int, optional
        Panels per row.
    aspect : int, optional
        Draw only this aspect (0 = the largest) of each orientation.
    overlay : bool
        All aspects of an orientation in one panel.
    per_page : int
        Most panels on one page.
    notes : dict, optional
        ``notes[(w, k)]``: a line added to the title of aspect ``k`` of workspace ``w``.

    Returns
    -------
    list of matplotlib.figure.Figure
    """
    from matplotlib.colors import Normalize
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    workspaces = list(workspaces)
    panels = _panels(workspaces, aspect, overlay)
    if not panels:
        panels = [(0, workspaces[0], ())] if workspaces else []
    x0, x1, y0, y1 = _extent(workspaces) if workspaces else (0, 1, 0, 1)
    # one colour per d-mode combination, one scale for a quantity: the same in every panel
    labels = sorted({L for ws in workspaces for mp in ws.maps for L in _labels(mp)[mp.reached]})
    norm, qlabel = None, ""
    if color_by != "modes":
        vals = []
        for ws in workspaces:
            for mp in ws.maps:
                q, qlabel = _quantity(mp, color_by, ws.kinds)
                vals.append(q[mp.reached])
        v = np.concatenate(vals) if vals else np.zeros(0)
        v = v[np.isfinite(v)]
        norm = Normalize(*(float(v.min()), float(v.max())) if v.size else (0.0, 1.0))
    # pages: whole rows of one orientation
    per_orientation = [sum(1 for q in panels if q[0] == w) for w in {p[0] for p in panels}] or [1]
    ncols = ncols or min(max(per_orientation), 4)
    rows: list[list[tuple[int, Any, tuple[int, ...]]]] = []
    for w in sorted({p[0] for p in panels}):
        mine = [p for p in panels if p[0] == w]
        rows += [mine[k:k + ncols] for k in range(0, len(mine), ncols)]
    rows_per_page = max(1, per_page // ncols)
    pages = [rows[k:k + rows_per_page] for k in range(0, len(rows), rows_per_page)] or [[]]
    figs = []
    seen_kinds: set[str] = set()
    for pno, prow in enumerate(pages, 1):
        nrows = max(len(prow), 1)
        fig = new_figure(figsize=(4.6 * ncols, 4.6 * nrows + 1.4), layout="constrained")
        axes = np.asarray(fig.subplots(nrows, ncols, squeeze=False, sharex=True, sharey=True))
        for r in range(nrows):
            for c in range(ncols):
                ax = axes[r, c]
                if r >= len(prow) or c >= len(prow[r]):
                    ax.set_visible(False)
                    continue
                w, ws, ks = prow[r][c]
                _draw_panel(ax, w, ws, ks, color_by, labels, norm, seen_kinds, notes)
                ax.set_xlim(x0, x1)
                ax.set_ylim(y0, y1)
                ax.set_aspect("equal", adjustable="box")
                if r == nrows - 1 or r + 1 >= len(prow) or c >= len(prow[r + 1]):
                    ax.set_xlabel("x [m]")
                if c == 0:
                    ax.set_ylabel("y [m]")
        handles = []
        if color_by == "modes":
            handles += [Patch(color=mode_color(L), alpha=0.6, label=f"d-modes {L}") for L in labels]
        else:
            from matplotlib.cm import ScalarMappable

            fig.colorbar(ScalarMappable(norm=norm, cmap="viridis"), ax=axes.ravel().tolist(), shrink=0.6,
                         label=qlabel)
        handles += [Line2D([], [], marker="s", ls="none", color=IK_COLOR, label="IK singularity"),
                    Line2D([], [], marker="s", ls="none", color=FK_COLOR, label="FK singularity / instability")]
        extra = {"seam": (SEAM_COLOR, "unresolved: rod straight under tension"),
                 "infeasible": (INFEASIBLE_COLOR, "infeasible neighbour (range, strain, collision)"),
                 "edge": (EDGE_COLOR, "grid edge: region cut by the bounds")}
        for k, (col, lab) in extra.items():
            if k in seen_kinds:
                handles.append(Line2D([], [], marker="s", ls="none", color=col, label=lab))
        if "shaded" in seen_kinds:
            handles.append(Patch(facecolor="white", edgecolor="0.3", hatch="////",
                                 label="reached, infeasible (range, strain or collision)"))
        handles.append(Line2D([], [], marker="*", ls="none", color="k", mfc="w", label="seed"))
        fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 5), fontsize=8, frameon=False)
        name = workspaces[0].mechanism_name if workspaces else ""
        title = f"{name}: constant-orientation workspace"
        if len(pages) > 1:
            title += f" (page {pno} of {len(pages)})"
        import textwrap

        regions = sorted({ws.region for ws in workspaces if getattr(ws, "region", None)})
        text = _NOTE + "".join(f" Region (areas measure it): {r}." for r in regions)
        fig.suptitle(title + "\n" + textwrap.fill(text, max(60, int(15 * 4.6 * ncols))), fontsize=9)
        figs.append(fig)
    return figs


def _draw_panel(ax, w, ws, ks, color_by, labels, norm, seen_kinds, notes=None) -> None:
    from matplotlib.colors import ListedColormap

    X, Y = ws.x, ws.y
    h = ws.step
    ext = (X[0] - h / 2, X[-1] + h / 2, Y[0] - h / 2, Y[-1] + h / 2)
    maps = [ws.maps[k] for k in ks]
    img = np.full((len(Y), len(X)), np.nan)
    for mp in maps:
        if color_by == "modes":
            lab = _labels(mp)
            for k, L in enumerate(labels):
                img[mp.reached & (lab == L)] = k
        else:
            q, _ = _quantity(mp, color_by, ws.kinds)
            img[mp.reached] = q[mp.reached]
    if color_by == "modes":
        if labels:
            cmap = ListedColormap([mode_color(L) for L in labels])
            ax.imshow(img, origin="lower", extent=ext, cmap=cmap, vmin=-0.5, vmax=len(labels) - 0.5,
                      interpolation="nearest", alpha=0.6)
    else:
        ax.imshow(img, origin="lower", extent=ext, cmap="viridis", norm=norm, interpolation="nearest")
    ms = max(1.0, 180.0 / max(len(X), len(Y)))
    for k, mp in zip(ks, maps):
        viol = getattr(mp, "violations", None)
        if viol is not None:
            bad = (np.asarray(viol) != 0) & mp.reached
            if bad.any():
                seen_kinds.add("shaded")
                ax.contourf(X, Y, bad.astype(float), levels=[0.5, 1.5], colors="none", hatches=["////"])
        layers = [("seam", getattr(mp, "boundary_seam", None), SEAM_COLOR), ("ik", mp.boundary_ik, IK_COLOR),
                  ("fk", mp.boundary_fk, FK_COLOR), ("infeasible", getattr(mp, "boundary_infeasible", None),
                                                     INFEASIBLE_COLOR),
                  ("edge", grid_edge_cells(mp), EDGE_COLOR)]
        for kind, mask, col in layers:
            if mask is None:
                continue
            jj, ii = np.nonzero(np.asarray(mask, dtype=bool))
            if len(jj) and kind in ("seam", "infeasible", "edge"):
                seen_kinds.add(kind)
            ax.plot(X[ii], Y[jj], "s", ms=ms, color=col, mew=0, ls="none")
    ax.plot([ws.seed[0]], [ws.seed[1]], "*", color="k", ms=10, mfc="w")
    th = f"θ = {np.degrees(ws.theta):g}°"
    n = len(ws.maps)
    if not maps:
        sub = ws.message or "nothing reached"
    elif len(maps) == 1:
        mp = maps[0]
        seeds = ", ".join(f"#{s}" for s in mp.seeds)
        sub = (f"aspect {ks[0] + 1} of {n}: seed {seeds}; {mp.area_cells} cells, "
               f"{mp.area_cells * h * h:.3g} m²")
        if getattr(ws, "constraints", ()) and not getattr(ws, "constrained", False):
            sub += f" ({mp.feasible_cells * h * h:.3g} m² feasible)"
    else:
        sub = f"{len(maps)} aspects overlaid"
    for k in ks:
        if notes and (w, k) in notes:
            sub += f"\n{notes[(w, k)]}"
    ax.set_title(f"{th}, {sub}", fontsize=8)
    ax.grid(True, lw=0.3, alpha=0.4)


def write_workspace_pages(workspaces: Sequence[Any], path: str | Path, **kwargs: Any) -> list[Path]:
    """Draw and save the pages of :func:`plot_workspace_pages`; returns the files written."""
    figs = plot_workspace_pages(workspaces, **kwargs)
    files = page_paths(path, len(figs))
    for fig, f in zip(figs, files):
        save(fig, f)
    return files


def plot_workspace(workspaces: Sequence[Any], path: str | None = None, color_by: str = "modes",
                   ncols: int | None = None, aspect: int | None = None, overlay: bool = False,
                   per_page: int = PANELS_PER_PAGE, notes: dict[tuple[int, int], str] | None = None) -> Any:
    """Workspace figure (see the module docstring): one panel per aspect and orientation
    (``aspect`` = k: only the k-th aspect, 0 = the largest; ``overlay``: all aspects of an
    orientation in one panel), coloured by d-mode combination or ``color_by`` = ``"margin"``,
    ``"cond"``, ``"input1"``..``"input3"``.  Saves every page when ``path`` is given
    (:func:`write_workspace_pages` also returns the files written); returns the first page.

    Parameters
    ----------
    workspaces : sequence of Workspace
        One per orientation.
    path : str, optional
        File of the first page (``name_2.png``, ... for the others).
    color_by : str
        ``"modes"``, ``"margin"``, ``"cond"`` or ``"input1"``..``"input3"``.
    ncols : int, optional
        Panels per row.
    aspect : int, optional
        Draw only this aspect (0 = the largest) of each orientation.
    overlay : bool
        All aspects of an orientation in one panel.
    per_page : int
        Most panels on one page.
    notes : dict, optional
        ``notes[(w, k)]``: a line added to the title of aspect ``k`` of workspace ``w``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figs = plot_workspace_pages(workspaces, color_by=color_by, ncols=ncols, aspect=aspect, overlay=overlay,
                                per_page=per_page, notes=notes)
    if path:
        for fig, f in zip(figs, page_paths(path, len(figs))):
            save(fig, f)
    return figs[0]
