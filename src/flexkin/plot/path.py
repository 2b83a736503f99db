"""A followed path: inputs, singularity functions, Jacobian determinants and stability margin
against the path parameter.

The Jacobians ``J_IK`` (``dx = J_IK du``) and ``J_FK`` (``du = J_FK dx``) are dimensionless:
positions and prismatic/length inputs in units of the mechanism's length scale ``L_ref``
(:attr:`Mechanism.length_scale`, the mean rod length), angles in radians.  Their determinants
span many decades between designs (about -0.0014 for a real-scale prototype, O(1) for a
unit-size one) and diverge at singularities, so they are drawn on a symmetric-log axis whose
linear threshold adapts to the data (below the smallest magnitude drawn): nothing is flattened
onto zero.  The singularity measures ``sing_ik`` and ``sing_fk``
(:mod:`flexkin.analysis.jacobian`: dimensionless and scale-free, between -1 and 1, of order
0.1-1 at a well-conditioned pose of any design) are drawn on a linear axis: they cross zero at
IK and FK singularities.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .mechanism import LEG_COLORS
from .style import new_figure, save

__all__ = ["plot_path", "symlog_threshold"]

_EVENT_STYLE = {"ik_singularity": ("k", "-"), "continuation_failed": ("k", "--"), "fk_singularity": ("#ff7f0e", "-"),
                "stability_lost": ("#ff7f0e", ":"), "stability_regained": ("#2ca02c", ":"),
                "mode_change": ("#7f7f7f", ":"), "chart_seam": ("#bbbbbb", "-."),
                "infeasible": ("#9467bd", ":"), "feasible": ("#9467bd", "-.")}

#: at most this many decades below the largest magnitude are resolved logarithmically
MAX_DECADES = 10.0


def symlog_threshold(*series: np.ndarray) -> float:
    """Linear threshold for a symlog axis showing ``series``: half the smallest non-zero finite
    magnitude, but not more than :data:`MAX_DECADES` decades below the largest (1 if there is no
    data)."""
    v = np.abs(np.concatenate([np.asarray(s, dtype=float).ravel() for s in series] or [np.zeros(0)]))
    v = v[np.isfinite(v) & (v > 0)]
    if v.size == 0:
        return 1.0
    return float(max(0.5 * v.min(), v.max() * 10.0 ** (-MAX_DECADES)))


def plot_path(result, path: str | None = None) -> Any:
    """Four stacked panels against ``t``: the actuator inputs; the singularity measures
    ``sing_ik``, ``sing_fk`` (dimensionless, scale-free, linear axis, zero at a singularity); ``det J_IK`` and ``det J_FK``
    (dimensionless, symmetric-log axis with a threshold adapted to the data); the stability
    margin (unstable samples marked).  Events are vertical lines: black = IK singularity / end
    of the branch, orange = FK singularity / stability lost, grey = d-mode change.

    Parameters
    ----------
    result : PathResult
        A followed path (:func:`flexkin.follow_path`).
    path : str, optional
        Save the figure there.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(figsize=(7.5, 10.0), layout="constrained")
    ax1, ax2, ax3, ax4 = fig.subplots(4, 1, sharex=True)
    t = result.t
    u = result.inputs_display()
    L_ref = float(result.mechanism.length_scale)
    legs = result.mechanism.legs
    kinds = list(result.kinds)
    units = [leg.input_unit for leg in legs]
    mixed = len(set(units)) > 1
    ax_deg = ax1.twinx() if mixed else ax1  # angles on their own axis: m and deg never share a scale
    lines = []
    for i, (kind, unit) in enumerate(zip(kinds, units)):
        ax = ax_deg if unit == "deg" else ax1
        lines += ax.plot(t, u[:, i], "-o", ms=2.5, color=LEG_COLORS[i], label=f"u{i + 1} [{unit}] ({kind})")
    if mixed:
        ax1.set_ylabel("input [m]")
        ax_deg.set_ylabel("input [deg]")
    else:
        ax1.set_ylabel(f"input [{units[0]}]")
    ax1.legend(handles=lines, fontsize=8, loc="best")

    ax2.plot(t, result.sing_ik, "-o", ms=2.5, color="k", label="sing_ik (0: IK singularity)")
    ax2.plot(t, result.sing_fk, "-o", ms=2.5, color="#ff7f0e", label="sing_fk (0: FK singularity)")
    ax2.axhline(0.0, color="0.6", lw=0.8)
    ax2.set_ylabel("singularity measure\n(dimensionless, −1..1)\n0 = singularity", fontsize=8)
    ax2.legend(fontsize=8, loc="best")

    d_ik = np.where(np.isfinite(result.det_ik), result.det_ik, np.nan)
    d_fk = np.where(np.isfinite(result.det_fk), result.det_fk, np.nan)
    ax3.plot(t, d_ik, "-o", ms=2.5, color="k", label="det J_IK")
    ax3.plot(t, d_fk, "-o", ms=2.5, color="#ff7f0e", label="det J_FK = 1/det J_IK")
    thr = symlog_threshold(d_ik, d_fk)
    ax3.set_yscale("symlog", linthresh=thr)
    ax3.axhline(0.0, color="0.6", lw=0.8)
    ax3.set_ylabel(f"det, dimensionless: lengths\nin L_ref = {L_ref:.4g} m, angles in rad\n"
                   f"(symlog, linear within ±{thr:.2g})", fontsize=8)
    ax3.set_title(f"J_IK, J_FK dimensionless: lengths in L_ref = {L_ref:.4g} m (the mean rod length), "
                  "angles in rad", fontsize=8, loc="left")
    ax3.legend(fontsize=8, loc="best")

    ax4.plot(t, result.margin, "-", color="#1f77b4", lw=1.2, label="stability margin")
    bad = ~result.stable
    ax4.plot(t[~bad], result.margin[~bad], "o", ms=3, color="#2ca02c", label="stable")
    ax4.plot(t[bad], result.margin[bad], "x", ms=4, color="#d62728", label="unstable")
    ax4.axhline(0.0, color="0.6", lw=0.8)
    ax4.set_ylabel("margin (dimensionless)")
    ax4.set_xlabel("path parameter t (0 = start pose, 1 = end pose)")
    ax4.legend(fontsize=8, loc="best")
    seen: set[str] = set()
    for e in result.events:
        color, ls = _EVENT_STYLE.get(e.kind, ("0.5", ":"))
        tm = 0.5 * (e.t_lo + e.t_hi)
        for ax in (ax1, ax2, ax3, ax4):
            ax.axvline(tm, color=color, ls=ls, lw=1.0, label=None)
        if e.kind not in seen:
            ax1.text(tm, 1.01, e.kind.replace("_", " "), rotation=90, fontsize=7, va="bottom", ha="center",
                     transform=ax1.get_xaxis_transform(), color=color)
            seen.add(e.kind)
    ax1.set_xlim(0.0, 1.0)
    a, b = result.start, result.end
    sid = getattr(result.start_solution, "id", None)
    fig.suptitle(f"{result.mechanism.name}: ({a[0]:.3g}, {a[1]:.3g}, {np.degrees(a[2]):.3g}°) → "
                 f"({b[0]:.3g}, {b[1]:.3g}, {np.degrees(b[2]):.3g}°)"
                 + ("" if sid is None else f", solution #{sid} followed"), fontsize=10)
    if path:
        save(fig, path)
    return fig
