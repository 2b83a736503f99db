"""Kirchhoff solutions and their Cosserat refinements drawn over each other (``flexkin refine --plot``).

One panel per Kirchhoff solution (numbered with its id): the Kirchhoff rods and platform in the
leg colours, the refined rods (extension, shear, self-weight; :mod:`flexkin.cosserat`) dashed
black over them, the refined platform outlined dashed; the title gives the outcome (refined:
how far the platform moved; fold: the tau where the branch merged with another one).  Solutions
born at folds (they exist only in the refined model) get panels of their own.  Pages of at most
20 panels, as :func:`flexkin.plot.solutions.page_paths`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .mechanism import plot_mechanism
from .solutions import PANELS_PER_PAGE, page_paths, panel_page, style_panel
from .style import save

__all__ = ["plot_refinement", "refined_rod_shapes"]

REFINED_STYLE = dict(color="k", lw=1.2, ls="--")


def refined_rod_shapes(refined: Any, mech: Any, refine_result: Any, n_points: int = 121) -> list[np.ndarray]:
    """World-frame centre lines ``(n_points, 2)`` of the three rods of a reached
    :class:`~flexkin.cosserat.RefinedSolution` (integrated again from its clamps).

    Parameters
    ----------
    refined : RefinedSolution
        A refined solution with ``reached`` true.
    mech : Mechanism
        Its mechanism.
    refine_result : RefineResult
        The refinement it belongs to (per-leg parameters and line loads).
    n_points : int
        Points per rod.

    Returns
    -------
    list of ndarray
    """
    from ..cosserat import rod_shape

    out = []
    for i, r in enumerate(refined.rods):
        p = refine_result.params[i]
        shp = rod_shape(r.clamp, r.clamp_angle, r.length, mech.legs[i].rod.EI, r.base_force, r.base_moment,
                        axial_compliance=p.axial_compliance, shear_compliance=p.shear_compliance,
                        line_load=refine_result.line_loads[i], tau=1.0, n_points=n_points)
        out.append(np.asarray(shp.points, dtype=float).reshape(n_points, 2))
    return out


def _outcome(r: Any, problem: str, unit: str) -> str:
    """What happened to one solution: for IK (pose given) how far the inputs moved, for FK
    (inputs given) how far the platform moved; the refined stability verdict."""
    if r.status in ("refined", "born", "unlisted") and r.reached:
        st = ", stability undecided" if r.stable is None else (", stable" if r.stable else ", unstable")
        if r.status != "refined" or r.position_shift is None:
            return f"{r.status}{st}"
        if problem == "ik" and r.input_shift is not None:
            return f"refined: |du| ≤ {max(abs(v) for v in r.input_shift):.2g}{unit}{st}"
        return f"refined: moved {r.position_shift:.2g} m, {r.rotation_shift_deg:.2g}°{st}"
    if r.status == "fold":
        return f"fold at τ = {r.tau_end:.3g}: merged, gone"
    return f"{r.status} at τ = {r.tau_end:.3g}"


def plot_refinement(kirchhoff: Sequence[Any], refine_result: Any, path: str | Path | None = None,
                    per_page: int = PANELS_PER_PAGE) -> list[Any]:
    """Figures (pages) of the Kirchhoff solutions ``kirchhoff`` (the refined ones, in the order of
    ``refine_result.solutions``) with their refinements; saves every page when ``path`` is
    given (the files are ``page_paths(path, len(figs))``).

    Parameters
    ----------
    kirchhoff : sequence of Solution
        The Kirchhoff solutions that were refined.
    refine_result : RefineResult
        Their refinement (:func:`flexkin.cosserat.refine`).
    path : str or Path, optional
        File of the first page.
    per_page : int
        Most panels on a page.

    Returns
    -------
    list of matplotlib.figure.Figure
    """
    from matplotlib.patches import Polygon

    mech = refine_result.mechanism
    items: list[tuple[Any, Any]] = list(zip(kirchhoff, refine_result.solutions))
    items += [(None, b) for b in refine_result.born if b.reached]
    pages = [items[k:k + per_page] for k in range(0, len(items), per_page)] or [[]]
    g = refine_result.gravity
    head = (f"{mech.name}: Kirchhoff (colours) and Cosserat-refined (dashed black) equilibria"
            + ("" if g is None else f", gravity ({g[0]:g}, {g[1]:g}) m/s²"))
    units = {leg.input_unit for leg in mech.legs}
    unit = f" {units.pop()}" if len(units) == 1 else ""  # mixed legs: m and deg, as in the JSON
    figs = []
    for p, chunk in enumerate(pages, 1):
        fig, axes = panel_page(len(chunk), head + (f" (page {p} of {len(pages)})" if len(pages) > 1 else ""),
                               panel_height=3.3)
        for idx, ax in enumerate(axes.flat):
            if idx >= len(chunk):
                ax.set_axis_off()
                if not chunk and idx == 0:
                    ax.text(0.5, 0.5, refine_result.message or "nothing to refine", ha="center", va="center",
                            wrap=True, transform=ax.transAxes)
                continue
            k, r = chunk[idx]
            if k is not None:
                plot_mechanism(mech, pose=k.pose, rods=[rod.shape(121) for rod in k.rods], ax=ax, inputs=k.inputs)
                label = f"#{k.id} {k.mode_label}"
            else:
                plot_mechanism(mech, pose=r.pose, ax=ax, inputs=r.inputs)
                label = "born"
            if r.reached and r.rods:
                for xy in refined_rod_shapes(r, mech, refine_result):
                    ax.plot(xy[:, 0], xy[:, 1], zorder=6, **REFINED_STYLE)
                B = mech.platform.world(np.asarray(r.pose, dtype=float))
                ax.add_patch(Polygon(B, closed=True, fill=False, ec="k", ls="--", lw=1.0, zorder=6))
            ax.set_title(f"{label}: {_outcome(r, refine_result.problem, unit)}", fontsize=8)
            style_panel(ax)
        figs.append(fig)
    if path is not None:
        for fig, f in zip(figs, page_paths(path, len(figs))):
            save(fig, f, tight=False)
    return figs
