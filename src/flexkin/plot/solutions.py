"""All solutions of an IK/FK problem, one panel each (paper Figs. 10–16)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .mechanism import plot_mechanism
from .style import mode_color, new_figure, save

__all__ = ["plot_solutions"]


def plot_solutions(result, path: str | None = None, max_panels: int = 48, ncols: int | None = None,
                   zoom: bool = False) -> Any:
    """Draw every solution of ``result`` (a :class:`~flexkin.results.KinematicsResult`).

    Panels are numbered like ``result.table()`` and titled with the d-modes (coloured by
    combination) and the stability verdict.  Returns the Figure; saves it if ``path``.
    """
    sols = list(result.solutions)[:max_panels]
    n = max(len(sols), 1)
    ncols = ncols or min(n, 5)
    nrows = math.ceil(n / ncols)
    fig = new_figure(figsize=(3.2 * ncols, 3.2 * nrows + 0.6), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    mech = result.mechanism
    what = ("pose (%.4g m, %.4g m, %.4g°)" % (result.given[0], result.given[1], np.degrees(result.given[2]))
            if result.problem == "ik" else
            "inputs (" + ", ".join(f"{v:.4g}" for v in _display_inputs(result)) + ")")
    fig.suptitle(f"{mech.name}: {result.problem.upper()} at {what} — {len(result.solutions)} solution(s)"
                 + ("" if len(result.solutions) <= max_panels else f", first {max_panels} shown"), fontsize=10)
    for idx, ax in enumerate(axes.flat):
        if idx >= len(sols):
            ax.set_axis_off()
            if not sols and idx == 0:
                ax.text(0.5, 0.5, result.message or "no solution", ha="center", va="center", wrap=True,
                        transform=ax.transAxes)
            continue
        s = sols[idx]
        rods = [r.shape(121) for r in s.rods]
        plot_mechanism(mech, pose=s.pose, rods=rods, ax=ax, inputs=s.inputs)
        st = "" if s.stable is None else (" stable" if s.stable else " unstable")
        ax.set_title(f"#{idx + 1}  modes {s.mode_label}{st}", fontsize=9, color=mode_color(s.mode_label))
        ax.tick_params(labelsize=7)
        ax.xaxis.label.set_size(8)
        ax.yaxis.label.set_size(8)
        if zoom:
            pts = np.concatenate(rods)
            c = pts.mean(0)
            r = np.max(np.abs(pts - c)) * 1.1
            ax.set_xlim(c[0] - r, c[0] + r)
            ax.set_ylim(c[1] - r, c[1] + r)
    if path:
        save(fig, path)
    return fig


def _display_inputs(result) -> list[float]:
    return [float(np.degrees(u)) if k == "revolute" else float(u) for u, k in zip(result.given, result.kinds)]
