"""Constant-orientation workspace maps (paper Fig. 17)."""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from .style import mode_color, new_figure, save

__all__ = ["plot_workspace"]

IK_COLOR = "black"
FK_COLOR = "#ff7f0e"
SEAM_COLOR = "#9a9a9a"


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


def plot_workspace(workspaces: Sequence[Any], path: str | None = None, color_by: str = "modes",
                   ncols: int | None = None, aspect: int | None = 0) -> Any:
    """One panel per workspace (orientation): the reached cells coloured by d-mode
    combination (or ``color_by`` = ``"margin"``, ``"cond"``, ``"input1"``..``"input3"``), the
    IK-singularity boundary cells in black and the FK-singularity / instability boundary cells
    in orange, cells next to unresolved ones (a rod straight under tension, the seam of the
    elliptic chart) in grey, the seed as a star.  ``aspect``: which aspect (0 = the largest)
    to draw in each panel, or ``None`` for all of them on top of each other.  Several aspects are drawn with their own outlines."""
    from matplotlib.colors import ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    n = len(workspaces)
    ncols = ncols or min(n, 3)
    nrows = math.ceil(n / ncols)
    fig = new_figure(figsize=(5.0 * ncols, 5.4 * nrows), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    for ax, ws_full in zip(axes, workspaces):
        ws = ws_full
        if aspect is not None and len(ws_full.maps) > aspect:
            import dataclasses

            ws = dataclasses.replace(ws_full, maps=(ws_full.maps[aspect],))
        X, Y = ws.x, ws.y
        h = ws.step
        ext = (X[0] - h / 2, X[-1] + h / 2, Y[0] - h / 2, Y[-1] + h / 2)
        handles = []
        if color_by == "modes":
            labels = sorted({"".join(map(str, q)) for mp in ws.maps for q in mp.modes[mp.reached]})
            img = np.full((len(Y), len(X)), np.nan)
            for mp in ws.maps:
                lab = np.array(["".join(map(str, q)) for q in mp.modes.reshape(-1, 3)]).reshape(mp.status.shape)
                for k, L in enumerate(labels):
                    img[mp.reached & (lab == L)] = k
            if labels:
                cmap = ListedColormap([mode_color(L) for L in labels])
                ax.imshow(img, origin="lower", extent=ext, cmap=cmap, vmin=-0.5, vmax=len(labels) - 0.5,
                          interpolation="nearest", alpha=0.55)
            handles += [Patch(color=mode_color(L), alpha=0.55, label=f"d-modes {L}") for L in labels]
        else:
            img = np.full((len(Y), len(X)), np.nan)
            for mp in ws.maps:
                q, label = _quantity(mp, color_by, ws.kinds)
                img[mp.reached] = q[mp.reached]
            im = ax.imshow(img, origin="lower", extent=ext, cmap="viridis", interpolation="nearest")
            fig.colorbar(im, ax=ax, shrink=0.8, label=label)
        for mp in ws.maps:
            for mask, col in ((mp.boundary_seam, SEAM_COLOR), (mp.boundary_ik, IK_COLOR), (mp.boundary_fk, FK_COLOR)):
                jj, ii = np.nonzero(mask)
                ax.plot(X[ii], Y[jj], "s", ms=max(1.0, 180.0 / max(len(X), len(Y))), color=col, mew=0, ls="none")
        ax.plot([ws.seed[0]], [ws.seed[1]], "*", color="k", ms=10, mfc="w")
        handles += [Line2D([], [], marker="s", ls="none", color=IK_COLOR, label="IK singularity"),
                    Line2D([], [], marker="s", ls="none", color=FK_COLOR, label="FK singularity / instability"),
                    Line2D([], [], marker="*", ls="none", color="k", mfc="w", label="seed")]
        if any(mp.boundary_seam is not None and mp.boundary_seam.any() for mp in ws.maps):
            handles.append(Line2D([], [], marker="s", ls="none", color=SEAM_COLOR,
                                  label="unresolved: rod straight under tension"))
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        reached = ws.union()
        if reached.any():
            jj, ii = np.nonzero(reached)
            pad = 4 * h
            ax.set_xlim(X[ii].min() - pad, X[ii].max() + pad)
            ax.set_ylim(Y[jj].min() - pad, Y[jj].max() + pad)
        n_asp = len(ws_full.maps)
        which = "" if n_asp <= 1 else (f" (aspect {aspect + 1} of {n_asp})" if aspect is not None
                                       else f" ({n_asp} aspects)")
        ax.set_title(f"{ws.mechanism_name}, θ = {np.degrees(ws.theta):g}°{which}", fontsize=10)
        ax.legend(handles=handles, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3,
                  frameon=False)
    if path:
        save(fig, path)
    return fig
