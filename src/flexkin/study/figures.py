"""Figures of a study: each metric over the first two grid parameters that vary.

* two or more varying parameters: a heat map (``pcolormesh``) over the first two, one panel per
  orientation; further parameters are held at their first value (said in the title);
* one varying parameter: the metric against it, one line per orientation;
* a single design: the metric against the orientation.

Files are ``DIR/fig_<metric>.png``.  matplotlib is imported here only (and without pyplot:
no global state, no display needed).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .evaluate import METRICS

__all__ = ["study_figures", "metric_figure"]


def _label(key: str) -> str:
    unit = METRICS[key].unit if key in METRICS else ""
    return f"{key} [{unit}]" if unit else key


def _value(v: Any) -> float:
    if v is None:
        return math.nan
    return float(v)


def _log_scale(values: np.ndarray, lines: bool = False) -> bool:
    """A logarithmic scale for positive values spanning more than two decades."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return bool(v.size and v.min() > 0 and v.max() / v.min() > 100.0)


def metric_figure(rows: Sequence[dict[str, Any]], spec: Any, metric: str, path: str | Path) -> Path:
    """Draw one metric of a study's rows into ``path``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.figure import Figure

    axes = [a for a in spec.grid if len(a.values) > 1]
    thetas = list(spec.orientations)
    fixed = {a.key: a.values[0] for a in spec.grid if a not in axes[:2]}
    sel = [r for r in rows if all(r.get(k) == v for k, v in fixed.items())]
    note = ", ".join(f"{k} = {v:g}" for k, v in fixed.items() if any(a.key == k for a in axes))
    if len(axes) >= 2:
        ax_x, ax_y = axes[0], axes[1]
        n = len(thetas)
        fig = Figure(figsize=(4.2 * n + 0.8, 3.8), layout="constrained")
        FigureCanvasAgg(fig)
        xs, ys = np.array(ax_x.values), np.array(ax_y.values)
        grids = []
        for th in thetas:
            C = np.full((len(ys), len(xs)), np.nan)
            for r in sel:
                if r.get("theta_deg") == th:
                    i = ax_x.values.index(r[ax_x.key])
                    j = ax_y.values.index(r[ax_y.key])
                    C[j, i] = _value(r.get(metric))
            grids.append(C)
        finite = np.concatenate([g[np.isfinite(g)] for g in grids]) if grids else np.array([])
        vmin, vmax = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        if vmin == vmax:
            vmin, vmax = vmin - 0.5, vmax + 0.5
        log = _log_scale(finite)
        norm = LogNorm(vmin=vmin, vmax=vmax) if log else Normalize(vmin=vmin, vmax=vmax)
        mesh = None
        for k, (th, C) in enumerate(zip(thetas, grids)):
            ax = fig.add_subplot(1, n, k + 1)
            mesh = ax.pcolormesh(xs, ys, np.ma.masked_invalid(C), shading="nearest", norm=norm, cmap="viridis")
            if len(xs) * len(ys) <= 64:  # small grids: the values in the cells
                for j in range(len(ys)):
                    for i in range(len(xs)):
                        if np.isfinite(C[j, i]):
                            light = float(norm(C[j, i])) > 0.6
                            ax.text(xs[i], ys[j], f"{C[j, i]:.3g}", ha="center", va="center", fontsize=7,
                                    color="black" if light else "white")
                        else:
                            ax.text(xs[i], ys[j], "n/a", ha="center", va="center", fontsize=7, color="0.4")
            if len(xs) <= 12:
                ax.set_xticks(xs)
            if len(ys) <= 12:
                ax.set_yticks(ys)
            ax.set_title(f"theta = {th:g} deg", fontsize=10)
            ax.set_xlabel(ax_x.key)
            if k == 0:
                ax.set_ylabel(ax_y.key)
        if mesh is not None:
            fig.colorbar(mesh, ax=fig.axes, label=_label(metric))
    else:
        fig = Figure(figsize=(6.0, 4.0), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
        if axes:
            a = axes[0]
            for th in thetas:
                pts = sorted((r[a.key], _value(r.get(metric))) for r in sel if r.get("theta_deg") == th)
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=f"theta = {th:g} deg")
            ax.set_xlabel(a.key)
            ax.legend(fontsize=8)
        else:
            pts = sorted((r["theta_deg"], _value(r.get(metric))) for r in sel)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o")
            ax.set_xlabel("theta [deg]")
        ax.set_ylabel(_label(metric))
        if _log_scale(np.array([_value(r.get(metric)) for r in sel]), lines=True):
            ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{spec.name}: {metric}" + (f" ({note})" if note else ""), fontsize=11)
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def study_figures(rows: Sequence[dict[str, Any]], spec: Any, out: str | Path) -> tuple[list[Path], list[str]]:
    """One figure per metric of ``spec`` that has a value in some row; returns the paths and
    messages about metrics without any value."""
    paths, messages = [], []
    empty = []
    for m in spec.metrics:
        if m in METRICS and (METRICS[m].dtype == "str" or not METRICS[m].figure):
            continue  # lists (aspect_areas) and coordinates (seed_x) are in the table only
        if not any(r.get(m) is not None for r in rows):
            empty.append(m)
            continue
        paths.append(metric_figure(rows, spec, m, Path(out) / f"fig_{m}.png"))
    if empty:
        messages.append(f"no figure for {', '.join(empty)}: no row has a value")
    return paths, messages
