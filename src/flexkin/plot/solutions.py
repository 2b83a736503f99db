"""All solutions of an IK/FK problem, one panel each (paper Figs. 10–16), split into pages.

Panels carry the solutions' ids (:attr:`Solution.id`: the same number as in the table, the
JSON and ``path --solution``), also when the result was filtered (``--stable-only``).  At most
:data:`PANELS_PER_PAGE` panels go on one page; further pages are written beside the first one
as ``name_2.png``, ``name_3.png``, ... (:func:`page_paths`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .mechanism import plot_mechanism
from .style import mode_color, new_figure, save

__all__ = ["plot_solutions", "plot_solution_pages", "write_solution_pages", "page_paths", "panel_page",
           "style_panel", "PANELS_PER_PAGE"]

#: most panels on one page (4 rows of 5: readable at 150 dpi)
PANELS_PER_PAGE = 20


def page_paths(path: str | Path, n_pages: int) -> list[Path]:
    """File names of ``n_pages`` pages: ``path`` itself, then ``stem_2.ext``, ``stem_3.ext``, ...

    Parameters
    ----------
    path : str or Path
        File of the first page.
    n_pages : int
        Number of pages.

    Returns
    -------
    list of Path
    """
    p = Path(path)
    return [p] + [p.with_name(f"{p.stem}_{k}{p.suffix}") for k in range(2, n_pages + 1)]


def panel_page(n_panels: int, title: str, ncols: int | None = None, panel_height: float = 3.2) -> tuple[Any, Any]:
    """A page for ``n_panels`` mechanism panels (at most 5 per row) on a fixed grid: no layout
    engine and no tight bounding box, so a page draws in one pass.

    Parameters
    ----------
    n_panels : int
        Panels on the page (an empty page gets one).
    title : str
        The page's title.
    ncols : int, optional
        Panels per row.
    panel_height : float
        Height of a panel (inches); panels are 3.2 inches wide.

    Returns
    -------
    fig : matplotlib.figure.Figure
    axes : ndarray of Axes
        ``(rows, columns)``.
    """
    n = max(int(n_panels), 1)
    nc = ncols or min(n, 5)
    nrows = math.ceil(n / nc)
    height = panel_height * nrows + 0.6
    fig = new_figure(figsize=(3.2 * nc, height))
    fig.subplots_adjust(left=0.7 / (3.2 * nc), right=0.98, bottom=0.5 / height, top=1.0 - 0.75 / height,
                        wspace=0.35, hspace=0.45)
    fig.suptitle(title, fontsize=10)
    return fig, fig.subplots(nrows, nc, squeeze=False)


def style_panel(ax: Any) -> None:
    """Small tick labels, at most 5 ticks per axis (labels of a narrow panel must not collide).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The panel.
    """
    ax.tick_params(labelsize=7)
    ax.locator_params(nbins=5)
    ax.xaxis.label.set_size(8)
    ax.yaxis.label.set_size(8)


def _what(result) -> str:
    if result.problem == "ik":
        g = result.given
        return "pose (%.4g m, %.4g m, %.4g°)" % (g[0], g[1], np.degrees(g[2]))
    legs = result.mechanism.legs
    return "inputs (" + ", ".join(f"{float(leg.to_display(v)):.4g} {leg.input_unit}"
                                  for v, leg in zip(result.given, legs)) + ")"


def _ids(sols) -> str:
    return f"#{sols[0].id}–#{sols[-1].id}" if len(sols) > 1 else f"#{sols[0].id}"


def plot_solution_pages(result, per_page: int | None = None, ncols: int | None = None,
                        zoom: bool = False) -> list[Any]:
    """One Figure per page of at most ``per_page`` panels (one page for an empty result).

    Parameters
    ----------
    result : KinematicsResult
        The solutions to draw.
    per_page : int, optional
        Most panels on a page (default :data:`PANELS_PER_PAGE`).
    ncols : int, optional
        Panels per row (default up to 5).
    zoom : bool
        Zoom each panel on its rods.

    Returns
    -------
    list of matplotlib.figure.Figure
    """
    per_page = PANELS_PER_PAGE if per_page is None else int(per_page)
    if per_page < 1:
        raise ValueError(f"per_page must be >= 1, got {per_page!r}")
    sols = list(result.solutions)
    pages = [sols[k:k + per_page] for k in range(0, len(sols), per_page)] or [[]]
    mech = result.mechanism
    figs = []
    for p, chunk in enumerate(pages, 1):
        title = f"{mech.name}: {result.problem.upper()} at {_what(result)} — {len(sols)} solution(s)"
        if len(pages) > 1:
            title += f", page {p} of {len(pages)} ({_ids(chunk)})"
        fig, axes = panel_page(len(chunk), title, ncols)
        for idx, ax in enumerate(axes.flat):
            if idx >= len(chunk):
                ax.set_axis_off()
                if not chunk and idx == 0:
                    ax.text(0.5, 0.5, result.message or "no solution", ha="center", va="center", wrap=True,
                            transform=ax.transAxes)
                continue
            s = chunk[idx]
            rods = [r.shape(121) for r in s.rods]
            plot_mechanism(mech, pose=s.pose, rods=rods, ax=ax, inputs=s.inputs)
            st = " undecided" if s.stable is None else (" stable" if s.stable else " unstable")
            ax.set_title(f"#{s.id}  modes {s.mode_label}{st}", fontsize=9, color=mode_color(s.mode_label))
            style_panel(ax)
            if zoom:
                pts = np.concatenate(rods)
                c = pts.mean(0)
                r = np.max(np.abs(pts - c)) * 1.1
                ax.set_xlim(c[0] - r, c[0] + r)
                ax.set_ylim(c[1] - r, c[1] + r)
        figs.append(fig)
    return figs


def write_solution_pages(result, path: str | Path, per_page: int | None = None, **kwargs: Any) -> list[Path]:
    """Draw every solution of ``result`` and save the pages (:func:`page_paths`).  Stale further
    pages of an earlier, longer run are not removed.

    Parameters
    ----------
    result : KinematicsResult
        The solutions to draw.
    path : str or Path
        File of the first page.
    per_page : int, optional
        Most panels on a page (default :data:`PANELS_PER_PAGE`).
    **kwargs
        Passed to :func:`plot_solution_pages` (``ncols``, ``zoom``).

    Returns
    -------
    list of Path
        The files written, first page first.
    """
    figs = plot_solution_pages(result, per_page=per_page, **kwargs)
    files = page_paths(path, len(figs))
    for fig, f in zip(figs, files):
        save(fig, f, tight=False)
    return files


def plot_solutions(result, path: str | None = None, per_page: int | None = None, ncols: int | None = None,
                   zoom: bool = False) -> Any:
    """Draw every solution of ``result`` (a :class:`~flexkin.results.KinematicsResult`).

    Panels are numbered with the solutions' ids, titled with the d-modes (coloured by
    combination) and the stability verdict.  With ``path`` every page is saved
    (:func:`write_solution_pages`).

    Parameters
    ----------
    result, per_page, ncols, zoom
        As in :func:`plot_solution_pages`.
    path : str, optional
        File of the first page.

    Returns
    -------
    matplotlib.figure.Figure
        The first page.
    """
    figs = plot_solution_pages(result, per_page=per_page, ncols=ncols, zoom=zoom)
    if path:
        for fig, f in zip(figs, page_paths(path, len(figs))):
            save(fig, f, tight=False)
    return figs[0]


