"""A followed path: inputs, Jacobian determinants and stability margin against the path parameter."""

from __future__ import annotations

from typing import Any

import numpy as np

from .mechanism import LEG_COLORS
from .style import new_figure, save

__all__ = ["plot_path"]

_EVENT_STYLE = {"ik_singularity": ("k", "-"), "continuation_failed": ("k", "--"), "fk_singularity": ("#ff7f0e", "-"),
                "stability_lost": ("#ff7f0e", ":"), "stability_regained": ("#2ca02c", ":"),
                "mode_change": ("#7f7f7f", ":"), "chart_seam": ("#bbbbbb", "-.")}


def _signed_log(v: np.ndarray) -> np.ndarray:
    """``sign(v) log10(1 + |v|)``: keeps the sign changes visible over many decades."""
    v = np.where(np.isfinite(v), v, np.nan)
    return np.sign(v) * np.log10(1.0 + np.abs(v))


def plot_path(result, path: str | None = None) -> Any:
    """Three stacked panels against ``t``: actuator inputs; ``det J_IK`` and ``det J_FK``
    (signed log scale); the stability margin (unstable samples marked).  Events are vertical
    lines: black = IK singularity / end of the branch, orange = FK singularity / stability
    lost, grey = d-mode change.  Returns the Figure; saves it if ``path``.
    """
    fig = new_figure(figsize=(7.5, 8.0), layout="constrained")
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    t = result.t
    u = result.inputs_display()
    for i, kind in enumerate(result.kinds):
        unit = "deg" if kind == "revolute" else "m"
        ax1.plot(t, u[:, i], "-o", ms=2.5, color=LEG_COLORS[i], label=f"u{i + 1} [{unit}] ({kind})")
    ax1.set_ylabel("input")
    ax1.legend(fontsize=8, loc="best")
    ax2.plot(t, _signed_log(result.det_ik), "-o", ms=2.5, color="k", label="det J_IK")
    ax2.plot(t, _signed_log(result.det_fk), "-o", ms=2.5, color="#ff7f0e", label="det J_FK")
    ax2.axhline(0.0, color="0.6", lw=0.8)
    ax2.set_ylabel("sign(d) log10(1+|d|)")
    ax2.legend(fontsize=8, loc="best")
    ax3.plot(t, result.margin, "-", color="#1f77b4", lw=1.2, label="stability margin")
    bad = ~result.stable
    ax3.plot(t[~bad], result.margin[~bad], "o", ms=3, color="#2ca02c", label="stable")
    ax3.plot(t[bad], result.margin[bad], "x", ms=4, color="#d62728", label="unstable")
    ax3.axhline(0.0, color="0.6", lw=0.8)
    ax3.set_ylabel("margin (dimensionless)")
    ax3.set_xlabel("path parameter t (0 = start pose, 1 = end pose)")
    ax3.legend(fontsize=8, loc="best")
    seen: set[str] = set()
    for e in result.events:
        color, ls = _EVENT_STYLE.get(e.kind, ("0.5", ":"))
        tm = 0.5 * (e.t_lo + e.t_hi)
        for ax in (ax1, ax2, ax3):
            ax.axvline(tm, color=color, ls=ls, lw=1.0, label=None)
        if e.kind not in seen:
            ax1.text(tm, 1.01, e.kind.replace("_", " "), rotation=90, fontsize=7, va="bottom", ha="center",
                     transform=ax1.get_xaxis_transform(), color=color)
            seen.add(e.kind)
    ax1.set_xlim(0.0, 1.0)
    a, b = result.start, result.end
    fig.suptitle(f"{result.mechanism.name}: ({a[0]:.3g}, {a[1]:.3g}, {np.degrees(a[2]):.3g}°) → "
                 f"({b[0]:.3g}, {b[1]:.3g}, {np.degrees(b[2]):.3g}°)", fontsize=10)
    if path:
        save(fig, path)
    return fig
