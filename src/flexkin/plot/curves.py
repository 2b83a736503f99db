"""Geometric-condition curves of the inverse kinematics (paper Fig. 7)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .style import mode_color, new_figure, save

__all__ = ["plot_curves"]

_KIND = {"prismatic": "prismatic (y = h)", "revolute": "revolute (x² + y² = r²)", "length": "length (y/x = tan β)"}


def plot_curves(result, path: str | None = None) -> Any:
    """Per leg, the curves in the rectangular ``(k_r, psi)`` space, coloured by d-mode.

    The IK solutions of ``result`` are marked on them (numbered as in ``result.table()``).
    """
    fig = new_figure(figsize=(12, 4.0), layout="constrained")
    axes = fig.subplots(1, 3, sharey=True)
    for leg, ax in zip(result.curves, axes):
        seen = set()
        for br in leg.branches:
            mode = br["mode"]
            # split the polyline where the d-mode or the k_r side changes (k_r jumps across 0)
            cut = np.flatnonzero((np.diff(mode) != 0) | (np.diff(np.sign(br["kr"])) != 0)) + 1
            for seg_idx in np.split(np.arange(len(mode)), cut):
                if len(seg_idx) < 2:
                    continue
                q = int(mode[seg_idx[0]])
                lab = f"d-mode {q}" if q not in seen else None
                seen.add(q)
                ax.plot(np.degrees(br["psi"][seg_idx]), br["kr"][seg_idx], color=mode_color(q), lw=1.4, label=lab)
        for i, s in enumerate(result.solutions, 1):
            r = s.rods[leg.leg]
            from ..rod.closed_form import kr_from_k

            ax.plot(np.degrees(r.psi), kr_from_k(r.k, r.psi), "ko", ms=4)
            ax.annotate(str(i), (np.degrees(r.psi), float(kr_from_k(r.k, r.psi))), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
        ax.set_xlim(0, 360)
        ax.set_ylim(-1.02, 1.02)
        ax.set_xlabel("ψ [deg]")
        ax.set_title(f"leg {leg.leg + 1}: {_KIND.get(leg.actuation, leg.actuation)}", fontsize=9)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_ylabel("k_r")
    g = result.given
    fig.suptitle(f"{result.mechanism.name}: geometric-condition curves at pose ({g[0]:.4g} m, {g[1]:.4g} m, "
                 f"{np.degrees(g[2]):.4g}°); dots: IK solutions", fontsize=10)
    if path:
        save(fig, path)
    return fig
